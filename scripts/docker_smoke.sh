#!/usr/bin/env bash
# Builds docker/Dockerfile with podman (daemonless: no Docker engine needed)
# and runs the image as docker/README.md tells a user to:
#
#   1. the image builds (the time is printed) and its size is printed;
#   2. `serve --port P` (not the default 8765) answers /health from the host,
#      and the image's own HEALTHCHECK (`podman healthcheck run`) passes on P;
#   3. the browser viewer's three.js is served from the image;
#   4. `realizer send examples/bml/01_smile.xml` from the host gets feedback
#      through to the block's end;
#   5. `podman stop` (SIGTERM) ends the service with exit status 0;
#   6. the README's render example (`--user "$(id -u):$(id -g)"`, the folder
#      mounted at /data) writes a video with a sound track where it says;
#   7. `realizer bench --list` and `bench convert --quick` work in the image.
#
#   bash scripts/docker_smoke.sh
#
# Takes 5-15 minutes (a pip install of the `all` extra and a Debian
# package install inside the build, then a render); tests/test_docker.py
# runs it (marked slow) where podman is installed.
#
# Environment:
#   REALIZER_SMOKE_BASE   the base image, passed as PYTHON_IMAGE (default:
#                         the Dockerfile's own, python:3.11.11-slim-bookworm
#                         from Docker Hub). `debian` makes one from Debian
#                         packages with mmdebstrap (python3, python3-venv)
#                         for machines that reach a Debian mirror but not
#                         Docker Hub; it trusts the CAs this host added in
#                         /usr/local/share/ca-certificates (a TLS proxy's).
#   REALIZER_SMOKE_SANDBOX  1 when podman runs inside a container that
#                         gives it no cgroup delegation, no CAP_SYS_RESOURCE
#                         and no bridge network (detected: /.dockerenv or
#                         /run/.containerenv): its own overlay storage under
#                         ~/.cache/realizer-docker-smoke, cgroupfs, runc, chroot build
#                         isolation, host network, lowered ulimits. 0: the
#                         podman defaults.
#   REALIZER_SMOKE_WORK   its folder (default ~/.cache/realizer-docker-smoke)
#   REALIZER_SMOKE_PORT   the service's port (default 9876)
#   PYTHON                the host's Python with the realizer (default
#                         .venv/bin/python), for `realizer send`
#   REALIZER_SMOKE_KEEP   1 keeps the image (localhost/realizer:smoke)
set -euo pipefail
cd "$(dirname "$0")/.."

command -v podman >/dev/null || { echo "smoke: podman is not installed" >&2; exit 2; }
# outside the checkout, which is the build context
WORK="${REALIZER_SMOKE_WORK:-${XDG_CACHE_HOME:-$HOME/.cache}/realizer-docker-smoke}"
mkdir -p "$WORK"
IMAGE=localhost/realizer:smoke
PORT="${REALIZER_SMOKE_PORT:-9876}"
PYTHON="${PYTHON:-.venv/bin/python}"
TOKEN="smoke-$RANDOM$RANDOM"
NAME="realizer-smoke-$$"

SANDBOX="${REALIZER_SMOKE_SANDBOX:-}"
if [ -z "$SANDBOX" ]; then
    if [ -e /.dockerenv ] || [ -e /run/.containerenv ]; then SANDBOX=1; else SANDBOX=0; fi
fi
PODMAN=(podman)
BUILD=()
RUN=()
if [ "$SANDBOX" = 1 ]; then
    PODMAN+=(--root "$WORK/storage" --runroot "$WORK/run" --storage-driver overlay
             --cgroup-manager cgroupfs --runtime runc)
    BUILD+=(--isolation chroot --network host)
    # crun and runc may lower resource limits here but not set the defaults
    RUN+=(--network host --ulimit nofile=4096:4096 --ulimit nproc=4096:4096)
    PUBLISH=()
else
    PUBLISH=(-p "127.0.0.1:$PORT:$PORT")
fi

say() { echo "smoke: $*"; }
cleanup() {
    "${PODMAN[@]}" rm -f "$NAME" >/dev/null 2>&1 || true
    if [ "${REALIZER_SMOKE_KEEP:-0}" != 1 ]; then
        "${PODMAN[@]}" rmi -f "$IMAGE" >/dev/null 2>&1 || true
    fi
}
trap cleanup EXIT

# --- the base image ---------------------------------------------------------
BASE="${REALIZER_SMOKE_BASE:-}"
if [ "$BASE" = debian ]; then
    BASE=localhost/realizer-smoke-base:bookworm
    if ! "${PODMAN[@]}" image exists "$BASE"; then
        command -v mmdebstrap >/dev/null || { echo "smoke: mmdebstrap is missing" >&2; exit 2; }
        say "making $BASE from Debian packages (mmdebstrap)"
        hooks=()
        for ca in /usr/local/share/ca-certificates/*.crt; do
            [ -e "$ca" ] || continue
            hooks+=(--customize-hook="copy-in $ca /usr/local/share/ca-certificates")
        done
        mmdebstrap --quiet --variant=minbase --include=python3,python3-venv,ca-certificates \
            "${hooks[@]}" --customize-hook='chroot "$1" update-ca-certificates' \
            --customize-hook='rm -rf "$1"/var/lib/apt/lists/* "$1"/var/cache/apt/*' \
            bookworm "$WORK/base.tar" http://deb.debian.org/debian
        # pip in a venv and npm use their own CA bundles unless told to use
        # the system's (npm runs when the checkout lacks three.js)
        "${PODMAN[@]}" import --change 'CMD ["python3"]' \
            --change 'ENV PIP_CERT=/etc/ssl/certs/ca-certificates.crt' \
            --change 'ENV NODE_EXTRA_CA_CERTS=/etc/ssl/certs/ca-certificates.crt' \
            "$WORK/base.tar" "$BASE" >/dev/null
        rm -f "$WORK/base.tar"
    fi
fi
BASE_ARG=()
[ -n "$BASE" ] && BASE_ARG=(--build-arg "PYTHON_IMAGE=$BASE")

# --- 1. build -----------------------------------------------------------------
# --format docker keeps the HEALTHCHECK (the OCI image format has none).
say "building $IMAGE${BASE:+ on $BASE}"
started=$(date +%s)
"${PODMAN[@]}" build "${BUILD[@]}" "${BASE_ARG[@]}" --format docker \
    -f docker/Dockerfile --ignorefile docker/Dockerfile.dockerignore -t "$IMAGE" . \
    >"$WORK/build.log" 2>&1 || { tail -40 "$WORK/build.log" >&2; say "build FAILED"; exit 1; }
build_s=$(( $(date +%s) - started ))
size=$("${PODMAN[@]}" image inspect --format '{{.Size}}' "$IMAGE")
base_size=""
[ -n "$BASE" ] && base_size=$("${PODMAN[@]}" image inspect --format '{{.Size}}' "$BASE")
say "built in ${build_s} s; image $(( size / 1000000 )) MB${base_size:+ (base $(( base_size / 1000000 )) MB)}"

# --- 2-5. the service on another port -------------------------------------------
"${PODMAN[@]}" run -d --name "$NAME" "${RUN[@]}" "${PUBLISH[@]}" \
    -e REALIZER_SUBMIT_TOKEN="$TOKEN" "$IMAGE" \
    serve --host 0.0.0.0 --port "$PORT" --fps 25 >/dev/null 2>"$WORK/run.log" \
    || { cat "$WORK/run.log" >&2; say "the container did not start"; exit 1; }
# (without systemd, podman says it cannot schedule the health check's timer:
# `podman healthcheck run` below runs the check itself)
health=""
for _ in $(seq 1 60); do
    if health=$("$PYTHON" -c "import urllib.request, sys; print(urllib.request.urlopen(sys.argv[1], timeout=2).read().decode())" "http://127.0.0.1:$PORT/health" 2>/dev/null); then
        break
    fi
    sleep 1
done
[ -n "$health" ] || { "${PODMAN[@]}" logs "$NAME" >&2; say "/health did not answer on $PORT"; exit 1; }
say "/health on port $PORT: $(echo "$health" | head -c 120)"
"${PODMAN[@]}" healthcheck run "$NAME" >/dev/null \
    || { "${PODMAN[@]}" logs "$NAME" >&2; say "the image's HEALTHCHECK failed on port $PORT"; exit 1; }
say "the image's HEALTHCHECK passes on port $PORT (not 8765)"
"$PYTHON" -c "import urllib.request, sys; assert urllib.request.urlopen(sys.argv[1], timeout=5).status == 200" \
    "http://127.0.0.1:$PORT/static/vendor/three/three.module.min.js" \
    || { say "the viewer's three.js is missing from the image"; exit 1; }
say "the viewer's three.js is served"
feedback=$("$PYTHON" -m realizer send examples/bml/01_smile.xml --port "$PORT" --token "$TOKEN" --timeout 30) \
    || { echo "$feedback" >&2; "${PODMAN[@]}" logs "$NAME" >&2; say "realizer send failed"; exit 1; }
say "realizer send: $(echo "$feedback" | wc -l) feedback messages, the last: $(echo "$feedback" | tail -1 | head -c 160)"
"${PODMAN[@]}" stop -t 10 "$NAME" >/dev/null
code=$("${PODMAN[@]}" inspect --format '{{.State.ExitCode}}' "$NAME")
[ "$code" = 0 ] || { "${PODMAN[@]}" logs "$NAME" >&2; say "the service exited $code on SIGTERM"; exit 1; }
say "podman stop: exit status 0"
log_lines=$("${PODMAN[@]}" logs "$NAME" 2>&1 | wc -l)
say "service log: $log_lines lines, none a traceback: $("${PODMAN[@]}" logs "$NAME" 2>&1 | grep -c Traceback || true) tracebacks"
"${PODMAN[@]}" rm "$NAME" >/dev/null

# --- 6. render as in docker/README.md --------------------------------------------
OUTDIR="$WORK/render"
rm -rf "$OUTDIR" && mkdir -p "$OUTDIR"
cp examples/bml/20_talking_face.xml "$OUTDIR/"
started=$(date +%s)
"${PODMAN[@]}" run --rm "${RUN[@]}" --user "$(id -u):$(id -g)" -v "$OUTDIR:/data" -w /data "$IMAGE" \
    render 20_talking_face.xml -o talking.mp4 --size 320x320 --fps 25 >"$WORK/render.log" 2>&1 \
    || { tail -20 "$WORK/render.log" >&2; say "render FAILED"; exit 1; }
render_s=$(( $(date +%s) - started ))
[ -s "$OUTDIR/talking.mp4" ] || { say "render wrote no $OUTDIR/talking.mp4"; exit 1; }
owner=$(stat -c %u "$OUTDIR/talking.mp4")
[ "$owner" = "$(id -u)" ] || { say "the video belongs to uid $owner, not $(id -u)"; exit 1; }
streams=""
if command -v ffprobe >/dev/null; then
    streams=$(ffprobe -v error -show_entries stream=codec_type -of csv=p=0 "$OUTDIR/talking.mp4" | sort | tr '\n' ' ')
    case "$streams" in *audio*video*) ;; *) say "the video has streams '$streams', not audio and video"; exit 1 ;; esac
fi
say "render: $OUTDIR/talking.mp4, $(stat -c %s "$OUTDIR/talking.mp4") bytes, streams: ${streams:-not probed}, ${render_s} s, feedback lines on stdout: $(grep -c '<' "$WORK/render.log" || true)"

# --- 7. bench ---------------------------------------------------------------------
benches=$("${PODMAN[@]}" run --rm "${RUN[@]}" "$IMAGE" bench --list | wc -l)
[ "$benches" -gt 0 ] || { say "bench --list found nothing"; exit 1; }
# one real benchmark as the image's user (no home: matplotlib's and the
# caches' folders are in /tmp)
"${PODMAN[@]}" run --rm "${RUN[@]}" "$IMAGE" bench convert --quick >"$WORK/bench.log" 2>&1 \
    || { tail -20 "$WORK/bench.log" >&2; say "bench convert --quick FAILED"; exit 1; }
warned=$(grep -ci "warning" "$WORK/bench.log" || true)
say "bench --list: $benches lines; bench convert --quick ran ($warned warning lines)"
say "ok: build ${build_s} s, image $(( size / 1000000 )) MB, health on port $PORT"
