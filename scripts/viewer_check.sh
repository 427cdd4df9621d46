#!/usr/bin/env bash
# The browser viewer in headless Chromium, compared with independent readers of the files.
#
#   bash scripts/viewer_check.sh [SCENEBAKE] [EXTRA_FILE...]
#
# Bakes one small cloth (the lab cloth, 30 frames) several ways into a temporary folder: a glTF
# morph cache with its VAT (absolute positions), the same bake with an offset VAT, with a VAT
# wrapped onto 3 rows a frame (--vat-max-width 50), and as a quantised morph basis; plus an IK
# rig (the Fox, skinned). `scenebake view` serves them; viewer/scripts/capture.mjs opens
# index.html?file=F&frame=N in Debian's chromium (puppeteer-core) at several frames and records
# the positions the viewer evaluates and the picture it draws; scripts/viewer_check.py compares
# them with gltf_eval.py (numpy) and its own EXR reader, and each VAT with its glTF.
#
# EXTRA_FILE: more .glb/.gltf/VAT .json files (e.g. the demo's exports) checked at frame 0 and
# at their middle frame against the numpy reader.
#
# Needs node_modules in viewer/ (`npm ci --prefix viewer`), /usr/bin/chromium (Debian's
# `chromium`) and python3 with numpy. Without chromium it exits 1 under CI=true; elsewhere it
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
"$scenebake" ik -q --rig meshes/Fox.glb --chain b_Spine01_02..b_Head_05 --curve heart \
    -o "$dir/fox.glb"

"$scenebake" view "$dir/lab.glb" --no-open > "$dir/url.txt" &
server=$!
for _ in $(seq 50); do [ -s "$dir/url.txt" ] && break; sleep 0.1; done
url="$(head -n 1 "$dir/url.txt")"
base="${url%%\?*}"
echo "viewer at $base"

node viewer/scripts/capture.mjs --base "$base" --out "$dir/capture.json" --frames 0,7,15,30 \
    file/lab.glb file/lab.json file/lab_offset.glb file/lab_offset.json \
    file/lab_wrap.glb file/lab_wrap.json file/lab_basis.glb
node viewer/scripts/capture.mjs --base "$base" --out "$dir/capture_fox.json" --frames 0,20,40 \
    file/fox.glb
"$python" scripts/viewer_check.py "$dir/capture.json" --dir "$dir"
"$python" scripts/viewer_check.py "$dir/capture_fox.json" --dir "$dir" --tolerance 1e-4
kill "$server"
server=""

# More files (the demo's exports), each served from its own folder.
for extra in "$@"; do
    "$scenebake" view "$extra" --no-open > "$dir/url.txt" &
    server=$!
    for _ in $(seq 50); do [ -s "$dir/url.txt" ] && break; sleep 0.1; done
    url="$(head -n 1 "$dir/url.txt")"
    name="$(basename "$extra")"
    frames="$(python3 -c '
import json, struct, sys
p = sys.argv[1]
if p.endswith(".json"):
    n = json.load(open(p))["frames"] - 1
else:
    d = open(p, "rb").read()
    doc = json.loads(d[20:20 + struct.unpack_from("<I", d, 12)[0]]) if d[:4] == b"glTF" else json.loads(d)
    n = ((doc.get("asset", {}).get("extras") or {}).get("scenebake") or {}).get("frame_end", 0)
print(f"0,{n // 2}")' "$extra")"
    node viewer/scripts/capture.mjs --base "${url%%\?*}" --out "$dir/extra.json" --frames "$frames" "file/$name"
    "$python" scripts/viewer_check.py "$dir/extra.json" --dir "$(dirname "$extra")" --tolerance 1e-4
    kill "$server"
    server=""
    rm -f "$dir/url.txt"
done
echo "viewer check: passed in ${SECONDS} s"
