#!/usr/bin/env bash
# The browser viewer in headless Chromium, compared with independent readers of the files.
#
#   bash scripts/viewer_check.sh [SCENEBAKE] [EXTRA_FILE...]
#
# Bakes one small cloth (the lab cloth, 30 frames) several ways into a temporary folder: a glTF
# morph cache with its VAT (absolute positions), the same bake with an offset VAT, with a VAT
# wrapped onto 3 rows a frame (--vat-max-width 50), as a quantised morph basis, and compressed
# with EXT_meshopt_compression (checked against the uncompressed file); plus an IK rig (the Fox,
# skinned). `scenebake view` serves them; viewer/scripts/capture.mjs opens
# index.html?file=F&frame=N in Debian's chromium (puppeteer-core) at several frames and records
# the positions the viewer evaluates and the picture it draws; scripts/viewer_check.py compares
# them with gltf_eval.py (numpy) and its own EXR reader, and each VAT with its glTF.
#
# EXTRA_FILE: more .glb/.gltf/VAT .json files of one folder (e.g. the demo's exports), checked
# the same way at frames 0, 60 and 120 (those they have).
#
# Needs node_modules in viewer/ (`npm ci --prefix viewer`), /usr/bin/chromium (Debian's
# `chromium`) and python3 with numpy and PIL (Debian's python3-pil). Without chromium it exits 1 under CI=true; elsewhere it
# prints why it skipped and exits 0.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

scenebake="${1:-${CARGO_TARGET_DIR:-target}/release/scenebake}"
shift || true
chromium="${CHROMIUM:-/usr/bin/chromium}"
if [ ! -x "$chromium" ] || [ ! -d viewer/node_modules/puppeteer-core ]; then
    reason="needs $chromium (apt-get install chromium) and viewer/node_modules (npm ci --prefix viewer)"
    if [ "${CI:-}" = "true" ]; then
        echo "error: the viewer check $reason" >&2
        exit 1
    fi
    echo "viewer check skipped: it $reason"
    exit 0
fi
python=/usr/bin/python3
[ -x "$python" ] || python=python3

dir="$(mktemp -d)"
server=""
cleanup() {
    if [ -n "$server" ]; then kill "$server" 2>/dev/null || true; fi
    rm -rf "$dir"
}
trap cleanup EXIT

SECONDS=0
lab=(--preset lab-cloth --frames 30 -q)
"$scenebake" cloth "${lab[@]}" -o "$dir/lab.glb" --vat "$dir/lab.exr"
"$scenebake" cloth "${lab[@]}" -o "$dir/lab_offset.glb" --vat "$dir/lab_offset.exr" --vat-mode offset
"$scenebake" cloth "${lab[@]}" -o "$dir/lab_wrap.glb" --vat "$dir/lab_wrap.exr" --vat-max-width 50
"$scenebake" cloth "${lab[@]}" -o "$dir/lab_basis.glb" --basis auto --quantize on
"$scenebake" cloth "${lab[@]}" -o "$dir/lab_meshopt.glb" --compress meshopt
"$scenebake" ik -q --rig meshes/Fox.glb --chain b_Spine01_02..b_Head_05 --curve heart \
    -o "$dir/fox.glb"

# Serves FILE's folder with `scenebake view`; sets $base to the viewer's URL.
serve() {
    rm -f "$dir/url.txt"
    "$scenebake" view "$1" --no-open > "$dir/url.txt" &
    server=$!
    for _ in $(seq 100); do [ -s "$dir/url.txt" ] && break; sleep 0.1; done
    url="$(head -n 1 "$dir/url.txt")"
    base="${url%%\?*}"
    echo "viewer at $base, serving $(dirname "$1")"
}

serve "$dir/lab.glb"
node viewer/scripts/capture.mjs --base "$base" --out "$dir/capture.json" --frames 0,7,15,30 \
    file/lab.glb file/lab.json file/lab_offset.glb file/lab_offset.json \
    file/lab_wrap.glb file/lab_wrap.json file/lab_basis.glb file/lab_meshopt.glb file/fox.glb
"$python" scripts/viewer_check.py "$dir/capture.json" --dir "$dir" \
    --reference lab_meshopt.glb=lab.glb

# `scenebake view FILE --frame N` as a user screenshots it, with Chromium's own --screenshot (no
# script waits for the page): the paused frame must be drawn after the window's last resize. At
# least 2 % of the canvas (above the 44-pixel control bar) off its background (#e8e8e8).
"$chromium" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
    --disable-background-networking --disable-component-update --disable-sync \
    --user-data-dir="$dir/chromium" --window-size=640,480 --virtual-time-budget=10000 \
    --screenshot="$dir/frame.png" "$base?file=file/lab.glb&frame=15" 2>/dev/null
"$python" - "$dir/frame.png" <<'PY'
import sys
from PIL import Image
img = Image.open(sys.argv[1]).convert("RGB")
w, h = img.size
px = img.load()
drawn = sum(1 for y in range(30, h - 44) for x in range(w)
            if max(abs(c - 0xE8) for c in px[x, y]) > 8)
share = drawn / (w * (h - 74))
print(f"viewer screenshot: {drawn} pixels of the bake ({100 * share:.1f} % of the canvas)")
sys.exit(0 if share >= 0.02 else f"error: {sys.argv[1]}: the paused frame is not drawn")
PY
kill "$server"
server=""

# More files (the demo's exports), all in one folder, at frames 0, 60 and 120 where they have them.
if [ "$#" -gt 0 ]; then
    folder="$(dirname "$1")"
    names=()
    for extra in "$@"; do
        if [ "$(dirname "$extra")" != "$folder" ]; then
            echo "error: $extra: the extra files must share one folder ($folder)" >&2
            exit 1
        fi
        names+=("file/$(basename "$extra")")
    done
    serve "$1"
    node viewer/scripts/capture.mjs --base "$base" --out "$dir/extra.json" --frames 0,60,120 \
        "${names[@]}"
    "$python" scripts/viewer_check.py "$dir/extra.json" --dir "$folder"
    kill "$server"
    server=""
fi
echo "viewer check: passed in ${SECONDS} s"
