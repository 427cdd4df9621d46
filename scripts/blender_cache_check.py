"""Play a bake's point caches (PC2, MDD) in Blender on the input OBJ and compare with the glTF.

What a user does: File > Import > Wavefront (.obj) of the bake's input (Blender keeps the
file's vertex order), a Mesh Cache modifier reading the `--pc2`/`--mdd` file, then play. This
script does the same headless and compares what Blender evaluates at several frames (and one
half frame) with an independent numpy reading of the glTF the same bake wrote
(scripts/blender/gltf_eval.py), vertex by vertex: largest distance <= --tolerance (1e-5 m).

The glTF's vertices are matched to the imported mesh's vertices by the rest positions alone:
each imported vertex placed as the bake placed the input (--up, --scale, --translate, given
here as they were given to the bake) must be one glTF vertex position at frame 0. So a cache in
another vertex order, at another rate or in other coordinates fails.

Runs in Debian's Blender 3.4 and in Blender 5.x's PyPI `bpy` module:

    env PATH=/usr/bin:/bin blender -b --factory-startup --python-exit-code 1 \
        --python scripts/blender_cache_check.py -- --obj IN.obj --gltf OUT.glb \
        --pc2 OUT.pc2 --mdd OUT.mdd [--scale S] [--translate X,Y,Z] [--up z] [--object NAME]
    VENV/bin/python scripts/blender_cache_check.py -- (the same options)

--rest-at-start: frame 0 of the bake is its rest pose (a cloth bake; not a `--rig` bake, whose
written loop starts in motion): the mapping is then checked against frame 0 as above. Without
it (a `--rig` bake), glTF vertices are matched to the imported vertices at frame 0 as Blender
plays the cache, and only the later frames are compared.

Exit status 0 when every cache plays the glTF's positions; 1 otherwise; 2 on bad options.
"""

import argparse
import os
import struct
import sys

import numpy as np

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender"))
import gltf_eval  # noqa: E402

PROG = "blender_cache_check"


def log(msg):
    print(f"{PROG}: {msg}", flush=True)


def parse_args():
    argv = sys.argv
    argv = argv[argv.index("--") + 1:] if "--" in argv else argv[1:]
    ap = argparse.ArgumentParser(prog=PROG)
    ap.add_argument("--obj", required=True, help="the bake's input OBJ")
    ap.add_argument("--gltf", required=True, help="the glTF the same bake wrote")
    ap.add_argument("--pc2", help="the bake's --pc2 file")
    ap.add_argument("--mdd", help="the bake's --mdd file")
    ap.add_argument("--node", help="the glTF node of the bake (default: the one morph mesh)")
    ap.add_argument("--object", help="the bake's --object: the imported object of that name")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--translate", default="0,0,0")
    ap.add_argument("--up", choices=["y", "z"], default="y")
    ap.add_argument("--rest-at-start", action="store_true",
                    help="frame 0 is the input's rest pose as placed (cloth bakes)")
    ap.add_argument("--tolerance", type=float, default=1e-5)
    args = ap.parse_args(argv)
    if not args.pc2 and not args.mdd:
        ap.error("give --pc2 and/or --mdd")
    return args


def import_obj(path, name):
    """The imported mesh object: Blender's Wavefront importer, which keeps the file's vertex
    order (positions no face uses are left out)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=path)
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    if name is not None:
        meshes = [o for o in meshes if o.name == name]
    if len(meshes) != 1:
        raise SystemExit(f"{PROG}: {path}: expected one mesh object"
                         f"{' named ' + name if name else ''}, found "
                         f"{[o.name for o in bpy.data.objects]}")
    return meshes[0]


def vertex_positions(obj):
    """Evaluated local vertex positions (modifiers applied) at the current frame."""
    deps = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(deps)
    mesh = ev.to_mesh()
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    ev.to_mesh_clear()
    return co.reshape(-1, 3).astype(np.float64)


def cache_header(fmt, path):
    """(points, frames) from the file's header, read per the format's definition."""
    with open(path, "rb") as f:
        head = f.read(32)
    if fmt == "PC2":
        assert head[:12] == b"POINTCACHE2\0", f"{path}: not a PC2 file"
        _version, points, _start, _rate, samples = struct.unpack_from("<iiffi", head, 12)
        return points, samples
    frames, points = struct.unpack_from(">ii", head, 0)
    return points, frames


def node_matrix(node):
    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T
    return gltf_eval.trs(node.get("translation", [0, 0, 0]), node.get("rotation", [0, 0, 0, 1]),
                         node.get("scale", [1, 1, 1]))


def main():
    args = parse_args()
    g = gltf_eval.Gltf(args.gltf)
    nodes = g.doc["nodes"]
    if args.node is not None:
        node = next(i for i, n in enumerate(nodes) if n.get("name") == args.node)
    else:
        morph = [i for i in g.mesh_nodes()
                 if any("targets" in p for p in g.doc["meshes"][nodes[i]["mesh"]]["primitives"])]
        if len(morph) != 1:
            raise SystemExit(f"{PROG}: {args.gltf}: {len(morph)} morph meshes; name one with --node")
        node = morph[0]
    # The glTF's key times of the bake (first animation), and the mesh's positions in its own
    # node's frame (a --rig garment's node scales metres to the document's units).
    anim = 0
    animation = g.doc["animations"][anim]
    channel = next(c for c in animation["channels"]
                   if c["target"].get("node") == node and c["target"]["path"] == "weights")
    sampler = animation["samplers"][channel["sampler"]]
    times = g.accessor(sampler["input"])[:, 0].astype(np.float64)
    fps = (len(times) - 1) / (times[-1] - times[0])
    inverse = np.linalg.inv(node_matrix(nodes[node]))

    def gltf_at(t):
        world = g.evaluate(node, anim, t)[0]
        return world @ inverse[:3, :3].T + inverse[:3, 3]

    obj = import_obj(os.path.abspath(args.obj), args.object)
    scene = bpy.context.scene
    scene.render.fps = max(1, round(fps))
    scene.render.fps_base = scene.render.fps / fps
    rest = np.array([v.co for v in obj.data.vertices], dtype=np.float64)
    log(f"Blender {bpy.app.version_string}: {args.obj} imported as {obj.name!r} with "
        f"{len(rest)} vertices; {args.gltf} node {nodes[node].get('name')!r}: "
        f"{len(times)} frames at {fps:.4f} fps")

    first = gltf_at(times[0])
    failures = []
    checked = 0
    for fmt, path in (("PC2", args.pc2), ("MDD", args.mdd)):
        if not path:
            continue
        points, frames = cache_header(fmt, path)
        if points != len(rest) or frames != len(times):
            failures.append(f"{path}: {points} points x {frames} frames; the imported mesh has "
                            f"{len(rest)} vertices and the glTF {len(times)} frames")
            continue
        for m in list(obj.modifiers):
            obj.modifiers.remove(m)
        mod = obj.modifiers.new("cache", "MESH_CACHE")
        mod.cache_format = fmt
        mod.filepath = os.path.abspath(path)
        mod.time_mode = "FRAME"
        mod.play_mode = "SCENE"
        mod.frame_start = 0.0
        mod.frame_scale = 1.0
        mod.interpolation = "LINEAR"
        scene.frame_set(0)
        played0 = vertex_positions(obj)
        if args.rest_at_start:
            # Where the bake placed each imported vertex: it must be a glTF vertex at frame 0.
            placed = rest.copy()
            if args.up == "z":
                placed = np.stack([placed[:, 0], placed[:, 2], -placed[:, 1]], axis=1)
            placed = placed * args.scale + np.array([float(c) for c in args.translate.split(",")])
            keys = placed
        else:
            keys = played0
        # Each glTF vertex -> the imported vertex at its frame-0 position.
        d = np.linalg.norm(first[:, None, :] - keys[None, :, :], axis=2)
        match = d.argmin(axis=1)
        off = d[np.arange(len(first)), match].max()
        if off > args.tolerance or len(set(match.tolist())) != len(rest):
            failures.append(f"{path}: the glTF's frame-0 vertices are not the imported vertices "
                            f"(as placed) one for one (largest distance {off:.3g} m)")
            continue
        last = len(times) - 1
        # The most any vertex moves from frame 0 over the frames checked (a character's loop
        # ends where it began, so the last frame alone may not have moved).
        moved = 0.0
        for f in sorted({0, 1, last // 3, last // 2 + 0.5, last - 1, last}):
            whole, sub = int(f), f - int(f)
            scene.frame_set(whole, subframe=sub)
            played = vertex_positions(obj)
            moved = max(moved, np.linalg.norm(played - played0, axis=1).max())
            expect = gltf_at(times[0] + f / fps)
            err = np.linalg.norm(played[match] - expect, axis=1).max()
            checked += 1
            log(f"{fmt} frame {f:g}: largest distance to the glTF {err:.3g} m")
            if not err <= args.tolerance:
                failures.append(f"{path}: frame {f:g} is {err:.3g} m off the glTF "
                                f"(tolerance {args.tolerance:g})")
        if moved < 1e-3:
            failures.append(f"{path}: nothing moves in Blender ({moved:.3g} m)")
    if failures:
        for f in failures:
            log(f"FAILED: {f}")
        sys.exit(1)
    log(f"ok: {checked} frames played within {args.tolerance:g} m of the glTF")


if __name__ == "__main__":
    main()
