#!/usr/bin/env bash
# Installs three.js (npm package `three`, MIT) for the browser viewer into the
# gitignored folder realizer/service/static/vendor/three/, which the service
# serves and the wheel includes (hatch artifacts). Only the minified core and
# the few example modules the viewer imports are copied, with the licence.
# Nothing is fetched at run time: the viewer loads these files from the server.
#
#   bash scripts/vendor_three.sh      (scripts/setup.sh runs it)
set -euo pipefail
cd "$(dirname "$0")/.."
THREE_VERSION="${THREE_VERSION:-0.181.0}"
DEST=realizer/service/static/vendor/three
if [ -f "$DEST/VERSION" ] && [ "$(cat "$DEST/VERSION")" = "$THREE_VERSION" ]; then
    exit 0
fi
if ! command -v npm >/dev/null 2>&1; then
    echo "setup: npm is missing; the browser viewer needs three.js (apt-get install npm)" >&2
    exit 1
fi
WORK=.cache/npm-three
mkdir -p "$WORK"
npm install --prefix "$WORK" --no-audit --no-fund --ignore-scripts --silent "three@$THREE_VERSION"
SRC="$WORK/node_modules/three"
mkdir -p "$DEST"
cp "$SRC/build/three.module.min.js" "$SRC/build/three.core.min.js" "$SRC/LICENSE" "$DEST/"
cp "$SRC/examples/jsm/controls/OrbitControls.js" \
   "$SRC/examples/jsm/loaders/GLTFLoader.js" \
   "$SRC/examples/jsm/utils/BufferGeometryUtils.js" "$DEST/"
# the example modules import '../utils/BufferGeometryUtils.js'; served flat
sed -i "s#'../utils/BufferGeometryUtils.js'#'./BufferGeometryUtils.js'#" "$DEST/GLTFLoader.js"
echo "$THREE_VERSION" > "$DEST/VERSION"
echo "setup: three.js $THREE_VERSION in $DEST"
