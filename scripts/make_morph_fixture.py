#!/usr/bin/env python3
"""Write a tiny glTF 2.0 fixture shaped like a scenebake cloth export.

A 1 m sheet (by default a single quad: 4 vertices, 2 triangles; --grid G
makes it G x G vertices) with N morph targets (one per "baked
frame"), POSITION min/max on the base and on every target, target names in
mesh.extras.targetNames, and a weights animation with LINEAR keys that turns
on target k at key k+1 (key 0 is the rest pose).

It exists to exercise the tooling without the Rust side:
    python3 scripts/make_morph_fixture.py /tmp/quad.gltf      # + /tmp/quad.bin
    python3 scripts/make_morph_fixture.py /tmp/quad.glb --targets 5
    node scripts/validate_gltf.mjs /tmp/quad.gltf /tmp/quad.glb
    blender -b --factory-startup --python-exit-code 1 \
        --python scripts/blender_check.py -- --auto /tmp/quad.gltf /tmp/quad.glb

Only the Python standard library is used.
"""

import argparse
import json
import math
import os
import struct
import sys


def pad4(data: bytes, fill: bytes = b"\0") -> bytes:
    return data + fill * (-len(data) % 4)


def build(n_targets: int, fps: float, grid: int = 2):
    # A grid x grid sheet in the y=0 plane, +Y up (glTF convention), 1 m side.
    # grid=2 is a single quad.
    g = grid
    base = [(-0.5 + i / (g - 1), 0.0, -0.5 + j / (g - 1)) for j in range(g) for i in range(g)]
    indices = []
    for j in range(g - 1):
        for i in range(g - 1):
            a, b, c, d = j * g + i, j * g + i + 1, (j + 1) * g + i + 1, (j + 1) * g + i
            indices += [a, c, b, a, d, c]  # counter-clockwise seen from +Y
    # Target k: the sheet, pinned along its z=-0.5 edge, sags and swings more
    # with every frame, like a baked cloth.
    targets = []
    for k in range(n_targets):
        t = (k + 1) / n_targets
        d = []
        for (x, _y, z) in base:
            w = (z + 0.5) ** 2  # 0 on the pinned edge, 1 on the far edge
            d.append((0.1 * w * math.sin(3 * t + x), -0.4 * t * w, -0.1 * t * w))
        targets.append(d)

    blob = bytearray()
    views, accessors = [], []

    def add_view(data: bytes, target=None):
        blob.extend(b"\0" * (-len(blob) % 4))
        view = {"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        blob.extend(data)
        views.append(view)
        return len(views) - 1

    def add_vec3(points, target=34962):
        data = b"".join(struct.pack("<3f", *p) for p in points)
        # min/max computed from the float32 values actually stored.
        stored = [struct.unpack("<3f", struct.pack("<3f", *p)) for p in points]
        accessors.append({
            "bufferView": add_view(data, target),
            "componentType": 5126, "count": len(points), "type": "VEC3",
            "min": [min(p[i] for p in stored) for i in range(3)],
            "max": [max(p[i] for p in stored) for i in range(3)],
        })
        return len(accessors) - 1

    def add_scalars(values, with_bounds):
        data = struct.pack(f"<{len(values)}f", *values)
        acc = {"bufferView": add_view(data), "componentType": 5126,
               "count": len(values), "type": "SCALAR"}
        if with_bounds:
            stored = struct.unpack(f"<{len(values)}f", data)
            acc["min"], acc["max"] = [min(stored)], [max(stored)]
        accessors.append(acc)
        return len(accessors) - 1

    pos = add_vec3(base)
    normals = [(0.0, 1.0, 0.0)] * len(base)
    nrm_data = b"".join(struct.pack("<3f", *n) for n in normals)
    accessors.append({"bufferView": add_view(nrm_data, 34962), "componentType": 5126,
                      "count": len(base), "type": "VEC3"})
    nrm = len(accessors) - 1
    wide = len(base) > 65535
    idx_data = struct.pack(f"<{len(indices)}{'I' if wide else 'H'}", *indices)
    accessors.append({"bufferView": add_view(idx_data, 34963),
                      "componentType": 5125 if wide else 5123,
                      "count": len(indices), "type": "SCALAR"})
    idx = len(accessors) - 1
    target_accs = [add_vec3(d) for d in targets]

    # Keys 0..n: key 0 = rest, key k = target k-1 fully on, others off.
    n_keys = n_targets + 1
    times = [k / fps for k in range(n_keys)]
    weights = []
    for k in range(n_keys):
        weights += [1.0 if k > 0 and j == k - 1 else 0.0 for j in range(n_targets)]
    t_acc = add_scalars(times, with_bounds=True)
    w_acc = add_scalars(weights, with_bounds=False)

    names = [f"frame_{k + 1:03d}" for k in range(n_targets)]
    doc = {
        "asset": {"version": "2.0", "generator": "scenebake scripts/make_morph_fixture.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "cloth", "mesh": 0}],
        "meshes": [{
            "name": "cloth",
            "primitives": [{
                "attributes": {"POSITION": pos, "NORMAL": nrm},
                "indices": idx,
                "mode": 4,
                "targets": [{"POSITION": a} for a in target_accs],
            }],
            "weights": [0.0] * n_targets,
            "extras": {"targetNames": names},
        }],
        "animations": [{
            "name": "bake",
            "samplers": [{"input": t_acc, "output": w_acc, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
        }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(pad4(bytes(blob)))}],
    }
    return doc, pad4(bytes(blob))


def write(path: str, n_targets: int, fps: float, grid: int) -> None:
    doc, blob = build(n_targets, fps, grid)
    if path.lower().endswith(".glb"):
        json_chunk = pad4(json.dumps(doc, separators=(",", ":")).encode(), b" ")
        total = 12 + 8 + len(json_chunk) + 8 + len(blob)
        with open(path, "wb") as f:
            f.write(struct.pack("<4sII", b"glTF", 2, total))
            f.write(struct.pack("<I4s", len(json_chunk), b"JSON") + json_chunk)
            f.write(struct.pack("<I4s", len(blob), b"BIN\0") + blob)
    elif path.lower().endswith(".gltf"):
        bin_path = os.path.splitext(path)[0] + ".bin"
        doc["buffers"][0]["uri"] = os.path.basename(bin_path)
        with open(bin_path, "wb") as f:
            f.write(blob)
        with open(path, "w") as f:
            json.dump(doc, f, indent=1)
            f.write("\n")
    else:
        sys.exit(f"make_morph_fixture: {path}: expected a .gltf or .glb name")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="+", help="output .gltf (writes a .bin beside it) or .glb")
    ap.add_argument("--targets", type=int, default=3, help="number of morph targets (default 3)")
    ap.add_argument("--fps", type=float, default=24.0, help="key rate of the weights animation")
    ap.add_argument("--grid", type=int, default=2,
                    help="vertices per side of the sheet (default 2: a single quad)")
    args = ap.parse_args()
    if args.targets < 1:
        ap.error("--targets must be at least 1")
    if args.grid < 2:
        ap.error("--grid must be at least 2")
    for path in args.out:
        write(path, args.targets, args.fps, args.grid)
        print(f"wrote {path} ({args.grid ** 2} vertices, {args.targets} morph targets, "
              f"{args.targets + 1} keys)")


if __name__ == "__main__":
    main()
