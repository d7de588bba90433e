#!/usr/bin/env bash
# Build the Java reference parser of the BML community (saiba/OpenBMLParser)
# and the harness benchmarks/java/OpenBmlBench.java, for `realizer bench parser`.
#
#   bash scripts/build_openbml.sh [CHECKOUT] [OUT]
#
# CHECKOUT: a checkout of https://github.com/saiba/OpenBMLParser (cloned into
# a temporary folder when omitted; needs git and the network). OUT: where the
# classes go (default .cache/openbml, which git ignores); the bench finds it
# there, or wherever REALIZER_OPENBML names. Needs a JDK (javac, java 11+).
# Nothing of the reference is committed: it is built here from its own source.
# Its three uses of Lombok (a logger and one getter/setter pair) are written
# out by hand first, as the Lombok jar it ships predates current JDKs.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
checkout="${1:-}"
out="${2:-$root/.cache/openbml}"
if [ -z "$checkout" ]; then
    checkout="$(mktemp -d)/OpenBMLParser"
    git clone --depth 1 https://github.com/saiba/OpenBMLParser "$checkout"
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cp -r "$checkout/src" "$work/src"
python3 - "$work/src" <<'PY'
import pathlib, re, sys
for path in pathlib.Path(sys.argv[1]).rglob("*.java"):
    text = path.read_text(encoding="utf-8")
    if "lombok" not in text:
        continue
    name = path.stem
    text = re.sub(r"import lombok[^\n]*\n", "", text).replace("@Slf4j\n", "")
    text = text.replace(
        "    @Setter\n    @Getter\n    private String characterId = null;",
        "    private String characterId = null;\n"
        "    public String getCharacterId() { return characterId; }\n"
        "    public void setCharacterId(String c) { characterId = c; }",
    )
    head = re.search(r"class " + name + r"[^{]*\{", text)
    logger = ("\n    private static final org.slf4j.Logger log = "
              f"org.slf4j.LoggerFactory.getLogger({name}.class);\n")
    text = text[: head.end()] + logger + text[head.end():]
    path.write_text(text, encoding="utf-8")
PY
rm -rf "$out"
mkdir -p "$out/classes" "$out/lib"
cp "$checkout"/lib/*.jar "$out/lib/"
jars="$(find "$out/lib" -name '*.jar' ! -name 'lombok*' | sort | tr '\n' ':')"
# -implicit:none -sourcepath: the jars carry sources javac must not rebuild
javac -nowarn -encoding UTF-8 -implicit:none -sourcepath "$work/src" -d "$out/classes" \
    -cp "$jars" $(find "$work/src" -name '*.java') 2>&1 | grep -v '^Note:' || true
javac -nowarn -implicit:none -sourcepath /nonexistent -d "$out/classes" \
    -cp "$out/classes:$jars" "$root/benchmarks/java/OpenBmlBench.java"
echo "$out/classes:$jars" > "$out/classpath"
echo "built the reference parser in $out"
