"""Compare what the browser viewer shows with an independent reading of the files.

    python3 scripts/viewer_check.py CAPTURE.json --dir DIR [--tolerance M] [--pixels P]

CAPTURE.json is written by viewer/scripts/capture.mjs (headless Chromium over the viewer): for
each file /file/NAME (NAME in DIR) and frame N, the world-space positions the viewer evaluated
(three.js's morph/skin evaluation for a glTF; for a VAT, the VAT vertex shader's own output read
back from a float render target) and the drawn picture. Three checks, all against readers that
share no code with scenebake or the viewer:

1. glTF: every mesh node's positions at frame N against scripts/blender/gltf_eval.py (numpy),
   playing the bake's animation (asset.extras.scenebake) at t = N / fps;
2. VAT: the VAT mesh's positions against the EXR decoded here (a small OpenEXR reader: scan
   lines, uncompressed or ZIP, FLOAT/HALF channels; zlib and numpy only), addressed as
   FILE.json's layout says (frame f, vertex v -> row f * rows_per_frame + v // width, column
   v % width, row 0 at the top), plus the base mesh (frame 0) in offset mode;
   A glTF compressed with EXT_meshopt_compression is compared with the numpy reading of the
   same bake written uncompressed (--reference NAME=OTHER): three.js's MeshoptDecoder must
   restore what the uncompressed file holds;
3. VAT against its glTF (FILE.json's "gltf") at the same frame, when both were captured: the
   positions, and the pictures (share of pixels whose colour differs by more than 8/255 in any
   channel, at most --pixels).

Prints the largest distance per file and frame; exit status 1 when one exceeds the tolerance:
--tolerance (default 1e-5 scene units) plus --relative (default 1e-6) times the mesh's
bounding-box diagonal (both sides are float32 data evaluated in float32 or float64; a skinned rig
in centimetres rounds more than a 2 m cloth in metres).
"""

import argparse
import base64
import json
import math
import os
import struct
import sys
import zlib

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender"))
import gltf_eval  # noqa: E402


# ------------------------------------------------------------------------------- OpenEXR

EXR_MAGIC = 20000630
EXR_PIXEL = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}
EXR_LINES = {0: 1, 2: 1, 3: 16}  # NONE, ZIPS, ZIP: scan lines per chunk


def read_exr(path):
    """A single-part scan-line OpenEXR as {channel: float64 array (height, width)}, row 0 at the
    top (the file's first line)."""
    data = open(path, "rb").read()
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != EXR_MAGIC:
        raise ValueError(f"{path}: not an OpenEXR file")
    if version & 0x1200:
        raise ValueError(f"{path}: tiled or multi-part OpenEXR is not read here")
    off, attrs = 8, {}
    while data[off] != 0:
        name_end = data.index(b"\0", off)
        type_end = data.index(b"\0", name_end + 1)
        name = data[off:name_end].decode()
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        attrs[name] = data[type_end + 5:type_end + 5 + size]
        off = type_end + 5 + size
    off += 1
    channels, c = [], 0
    chlist = attrs["channels"]
    while chlist[c] != 0:
        end = chlist.index(b"\0", c)
        pixel_type, _, _, xs, ys = struct.unpack_from("<iB3sii", chlist, end + 1)
        if (xs, ys) != (1, 1):
            raise ValueError(f"{path}: subsampled channels are not read here")
        channels.append((chlist[c:end].decode(), EXR_PIXEL[pixel_type]))
        c = end + 17
    compression = attrs["compression"][0]
    if compression not in EXR_LINES:
        raise ValueError(f"{path}: compression {compression} is not read here")
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"])
    width, height = x1 - x0 + 1, y1 - y0 + 1
    lines = EXR_LINES[compression]
    chunks = math.ceil(height / lines)
    offsets = struct.unpack_from(f"<{chunks}Q", data, off)
    out = {name: np.zeros((height, width)) for name, _ in channels}
    line_bytes = sum(width * dt.itemsize for _, dt in channels)
    for chunk_off in offsets:
        y, size = struct.unpack_from("<ii", data, chunk_off)
        raw = data[chunk_off + 8:chunk_off + 8 + size]
        n_lines = min(lines, y1 - y + 1)
        expected = n_lines * line_bytes
        if compression != 0 and size < expected:
            t = np.frombuffer(zlib.decompress(raw), dtype=np.uint8).astype(np.int64)
            t[1:] -= 128  # undo the predictor: each byte was stored as a difference + 128
            t = (np.cumsum(t) & 0xFF).astype(np.uint8)
            half = (len(t) + 1) // 2  # undo the interleaving: even bytes first, then odd
            raw = np.empty_like(t)
            raw[0::2] = t[:half]
            raw[1::2] = t[half:]
            raw = raw.tobytes()
        pos = 0
        for line in range(n_lines):
            for name, dt in channels:
                row = np.frombuffer(raw, dtype=dt, count=width, offset=pos)
                out[name][y - y0 + line] = row.astype(np.float64)
                pos += width * dt.itemsize
    return out


def vat_frame(manifest, image, frame):
    """Vertex values of `frame` (vertex_count, 3) from an EXR image as FILE.json lays it out."""
    layout, n = manifest["layout"], manifest["vertex_count"]
    v = np.arange(n)
    rows = frame * layout["rows_per_frame"] + v // layout["width"]
    cols = v % layout["width"]
    return np.stack([image[ch][rows, cols] for ch in ("R", "G", "B")], axis=1)


# ------------------------------------------------------------------------------- glTF

def animation_and_fps(g):
    """The bake's animation index (asset.extras.scenebake.animation, else the first) and its
    frame rate (asset.extras.scenebake.fps, else one over the smallest key interval)."""
    anims = g.doc.get("animations", [])
    extras = g.playback() or {}
    index = next((i for i, a in enumerate(anims) if a.get("name") == extras.get("animation")),
                 0 if anims else None)
    fps = extras.get("fps")
    if fps is None and index is not None:
        times = g.accessor(anims[index]["samplers"][0]["input"])[:, 0]
        fps = 1.0 / np.min(np.diff(times)) if len(times) > 1 else 30.0
        fps = float(round(fps))
    return index, fps or 30.0


def vat_mesh_node(g, manifest):
    """The mesh node the VAT animates: its vertex count, morph targets preferred."""
    nodes = [i for i in g.mesh_nodes()
             if sum(g.doc["accessors"][p["attributes"]["POSITION"]]["count"]
                    for p in g.doc["meshes"][g.doc["nodes"][i]["mesh"]]["primitives"])
             == manifest["vertex_count"]]
    nodes.sort(key=lambda i: not any("targets" in p for p in
                                     g.doc["meshes"][g.doc["nodes"][i]["mesh"]]["primitives"]))
    if not nodes:
        raise ValueError(f"{manifest['gltf']}: no mesh with {manifest['vertex_count']} vertices")
    return nodes[0]


def rest_positions(g, node):
    """The base mesh of an offset VAT, frame 0: the mesh at its default weights (mesh.weights,
    frame 0's in a scenebake cache) through the node's world matrix, no animation."""
    return g.evaluate(node, None, 0.0)[0]


# ------------------------------------------------------------------------------- checks

def picture(rec):
    pic = rec["picture"]
    rgba = np.frombuffer(base64.b64decode(pic["rgba"]), dtype=np.uint8)
    return rgba.reshape(pic["height"], pic["width"], 4)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("capture")
    ap.add_argument("--dir", required=True, help="the folder the captured /file/NAME are in")
    ap.add_argument("--tolerance", type=float, default=1e-5)
    ap.add_argument("--relative", type=float, default=1e-6)
    ap.add_argument("--reference", action="append", default=[], metavar="NAME=OTHER",
                    help="read glTF NAME's expected positions from OTHER (NAME is compressed "
                         "with EXT_meshopt_compression, which the numpy reader does not decode; "
                         "OTHER is the same bake uncompressed)")
    ap.add_argument("--pixels", type=float, default=0.01,
                    help="largest share of differing pixels between a VAT and its glTF")
    args = ap.parse_args()
    records = json.load(open(args.capture))
    failures, worst, checked = [], 0.0, 0
    by_key = {(os.path.basename(r["file"]), r["frame"]): r for r in records}
    references = dict(r.split("=", 1) for r in args.reference)

    def report(label, dist, ref):
        nonlocal worst, checked
        worst = max(worst, dist)
        checked += 1
        diagonal = float(np.linalg.norm(np.ptp(ref, axis=0))) if len(ref) else 0.0
        tolerance = args.tolerance + args.relative * diagonal
        ok = dist <= tolerance
        print(f"{'ok  ' if ok else 'FAIL'} {label}: max distance {dist:.3g} "
              f"(tolerance {tolerance:.3g})")
        if not ok:
            failures.append(label)

    for rec in records:
        name, frame = os.path.basename(rec["file"]), rec["frame"]
        path = os.path.join(args.dir, name)
        shown = {m["node"]: np.array(m["positions"]).reshape(-1, 3) for m in rec["meshes"]}
        if rec["kind"] == "gltf":
            g = gltf_eval.Gltf(os.path.join(args.dir, references.get(name, name)))
            if name in references:
                name = f"{name} (expected from {references[name]})"
            anim, fps = animation_and_fps(g)
            for node in g.mesh_nodes():
                mode = g.doc["meshes"][g.doc["nodes"][node]["mesh"]]["primitives"][0].get("mode", 4)
                if mode != 4:
                    continue  # lines and points: the viewer reports triangle meshes only
                ref = g.evaluate(node, anim, frame / fps)[0]
                if node not in shown or shown[node].shape != ref.shape:
                    failures.append(f"{name} frame {frame}: node {node} missing or mis-sized")
                    continue
                report(f"{name} frame {frame} node {node} (glTF vs numpy reader)",
                       float(np.max(np.linalg.norm(shown[node] - ref, axis=1), initial=0.0)), ref)
        else:
            manifest = json.load(open(path))
            image = read_exr(os.path.join(args.dir, manifest["positions"]))
            g = gltf_eval.Gltf(os.path.join(args.dir, manifest["gltf"]))
            node = vat_mesh_node(g, manifest)
            ref = vat_frame(manifest, image, frame)
            if manifest["mode"] == "offset":
                ref = ref + rest_positions(g, node)
            report(f"{name} frame {frame} (VAT shader vs EXR reader)",
                   float(np.max(np.linalg.norm(shown[node] - ref, axis=1))), ref)
            twin = by_key.get((manifest["gltf"], frame))
            if twin is not None:
                other = {m["node"]: np.array(m["positions"]).reshape(-1, 3) for m in twin["meshes"]}
                report(f"{name} frame {frame} (VAT vs {manifest['gltf']} in the viewer)",
                       float(np.max(np.linalg.norm(shown[node] - other[node], axis=1))), ref)
                a, b = picture(rec).astype(int), picture(twin).astype(int)
                differ = float(np.mean(np.max(np.abs(a - b), axis=2) > 8))
                ok = differ <= args.pixels
                print(f"{'ok  ' if ok else 'FAIL'} {name} frame {frame}: {100 * differ:.3f} % of "
                      f"{a.shape[1]}×{a.shape[0]} pixels differ from {manifest['gltf']}'s by more "
                      f"than 8/255 (largest difference {int(np.max(np.abs(a - b)))}/255, "
                      f"{100 * float(np.mean(np.any(a != b, axis=2))):.3f} % not identical)")
                if not ok:
                    failures.append(f"{name} frame {frame} picture")

    print(f"{checked} comparisons over {len(records)} captured frames; largest distance "
          f"{worst:.3g} (tolerance {args.tolerance:g} + {args.relative:g} × mesh diagonal)")
    if not records:
        failures.append("nothing was captured")
    if failures:
        print(f"{len(failures)} failed: " + "; ".join(failures))
        sys.exit(1)


if __name__ == "__main__":
    main()
