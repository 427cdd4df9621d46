"""Import a bake's USD layer (`--usd`) in Blender and compare what it plays with the glTF.

What a user does: File > Import > Universal Scene Description of the `.usda`, default settings,
then play. This script does the same headless (`wm.usd_import`) and compares every imported mesh
object (evaluated, world space, turned back from Blender's Z-up to the bake's Y-up) at several
frames with an independent numpy reading of the glTF the same bake wrote
(scripts/blender/gltf_eval.py), the glTF mesh node of the same name: glTF vertices are matched to
Blender's vertices by position at the first frame (several coinciding: the same index), then the
largest distance at every checked frame must be <= --tolerance (1e-6 m). Blender's scene frame F
is compared with the glTF at time F / fps. The importer sets the scene's frame range from the
layer but leaves its rate (24 fps); the script sets the layer's rate, or with --keep-fps leaves
it, which plays the same frames (Blender 5.0.1 shows time code F at scene frame F).

Runs in Blender 5.x's PyPI `bpy` module (Debian's Blender 3.4 is built without USD:
bpy.app.build_options.usd is False and it has no wm.usd_import):

    VENV/bin/python scripts/blender_usd_check.py -- --usd OUT.usda --gltf OUT.glb [--frames 0 5 12]

Exit status 0 when every mesh plays the glTF's positions; 1 otherwise.
"""

import argparse
import os
import sys

import numpy as np

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender"))
import gltf_eval  # noqa: E402

PROG = "blender_usd_check"


def log(msg):
    print(f"{PROG}: {msg}", flush=True)


def world_positions(obj):
    """Evaluated world vertex positions at the current frame, in the bake's Y-up frame."""
    deps = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(deps)
    mesh = ev.to_mesh()
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    m = np.array(ev.matrix_world, dtype=np.float64)
    ev.to_mesh_clear()
    p = co.reshape(-1, 3).astype(np.float64)
    w = (np.c_[p, np.ones(len(p))] @ m.T)[:, :3]
    # Blender's Z-up (x, y, z) is the bake's Y-up (x, z, -y).
    return np.c_[w[:, 0], w[:, 2], -w[:, 1]]


def main():
    argv = sys.argv
    argv = argv[argv.index("--") + 1:] if "--" in argv else argv[1:]
    ap = argparse.ArgumentParser(prog=PROG)
    ap.add_argument("--usd", required=True)
    ap.add_argument("--gltf", required=True)
    ap.add_argument("--frames", type=int, nargs="*")
    ap.add_argument("--tolerance", type=float, default=1e-6)
    ap.add_argument("--keep-fps", action="store_true",
                    help="leave the scene's frame rate as the import left it")
    args = ap.parse_args(argv)

    g = gltf_eval.Gltf(args.gltf)
    fps = (g.playback() or {}).get("fps")
    anim = 0 if g.doc.get("animations") else None
    nodes = {g.doc["nodes"][i].get("name"): i for i in g.mesh_nodes()}

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=os.path.abspath(args.usd))
    scene = bpy.context.scene
    log(f"Blender {bpy.app.version_string}: scene frames {scene.frame_start}..{scene.frame_end}, "
        f"{scene.render.fps} fps after import; the layer's {fps}")
    if not args.keep_fps:
        scene.render.fps = int(round(fps))
        scene.render.fps_base = scene.render.fps / fps
    frames = args.frames if args.frames else list(range(scene.frame_start, scene.frame_end + 1))
    objects = [o for o in bpy.data.objects if o.type == "MESH"]
    problems = []
    if len(objects) != len(nodes):
        problems.append(f"{len(objects)} mesh objects {[o.name for o in objects]} for "
                        f"{len(nodes)} glTF mesh nodes {list(nodes)}")
    worst_all = 0.0
    for obj in objects:
        # Blender names the object after the prim (3.4: the mesh prim's name; 4.x+ too).
        name = obj.name if obj.name in nodes else obj.data.name
        if name not in nodes:
            problems.append(f"{obj.name}: no glTF mesh node of that name")
            continue
        node = nodes[name]
        scene.frame_set(frames[0])
        b0 = world_positions(obj)
        g0, _ = g.evaluate(node, anim, frames[0] / fps)
        hits = np.linalg.norm(g0[:, None, :] - b0[None, :, :], axis=2) <= args.tolerance
        if not hits.any(axis=1).all():
            problems.append(f"{name}: {int((~hits.any(axis=1)).sum())} glTF vertices match no "
                            f"Blender vertex at frame {frames[0]}")
            continue
        point_of = np.argmax(hits, axis=1)
        same = np.arange(len(g0))
        ok = same < len(b0)
        ok[ok] = hits[same[ok], same[ok]]
        point_of[ok] = same[ok]
        worst = 0.0
        for f in frames:
            scene.frame_set(f)
            b = world_positions(obj)
            gp, _ = g.evaluate(node, anim, f / fps)
            d = float(np.linalg.norm(b[point_of] - gp, axis=1).max())
            worst = max(worst, d)
            if d > args.tolerance:
                problems.append(f"{name}: frame {f}: {d:.3e} m from the glTF")
        log(f"{name}: {len(b0)} vertices, frames {frames}: largest distance {worst:.3e} m")
        worst_all = max(worst_all, worst)
    for p in problems:
        log(f"FAIL {p}")
    log(f"{'FAIL' if problems else 'ok'}: largest distance {worst_all:.3e} m "
        f"(tolerance {args.tolerance:g})")
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
