"""Read a bake's USD layer (`--usd`) with Pixar's USD (`pxr`, PyPI `usd-core`) and compare it
with an independent numpy reading of the glTF the same bake wrote (scripts/blender/gltf_eval.py).

For every Mesh prim under the default prim, the glTF mesh node of the same name:
- the glTF's vertices are matched to the USD points at the first time code by position (within
  --tolerance; where several points coincide, the one of the same index), and the glTF's triangles mapped through that match
  must be the USD's faces (same corners, same winding);
- at every checked frame f (time code start + f, glTF time = time code / fps) each glTF vertex
  is within --tolerance of its USD point (largest distance reported);
- extent is the points' bounds at each checked time; normals are unit, one per point,
  interpolation "vertex".
Stage: defaultPrim, upAxis Y, metersPerUnit 1, timeCodesPerSecond = framesPerSecond = the
glTF's fps (asset.extras.scenebake), startTimeCode/endTimeCode the glTF's first and last key,
and no error from USD's validators (UsdValidation, what usdchecker runs).

    python3 scripts/usd_check.py FILE.usda FILE.glb [--frames 0 5 20] [--tolerance 1e-6]
        [--json OUT.json]

Exit status 0 when everything holds, 1 otherwise (the figures say what), 2 on bad options.
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender"))
from gltf_eval import Gltf  # noqa: E402

from pxr import Usd, UsdGeom, UsdValidation  # noqa: E402


def validation_errors(stage):
    registry = UsdValidation.ValidationRegistry()
    context = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    return [f"{e.GetName()}: {e.GetMessage()}" for e in context.Validate(stage)
            if e.GetType() == UsdValidation.ValidationErrorType.Error]


def canonical(tris):
    """Triangles as tuples rotated to start at their smallest corner (winding kept), sorted."""
    out = []
    for t in tris:
        i = int(np.argmin(t))
        out.append(tuple(int(t[(i + k) % 3]) for k in range(3)))
    return sorted(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("usd")
    ap.add_argument("gltf")
    ap.add_argument("--frames", type=int, nargs="*", help="frames to compare (default: all)")
    ap.add_argument("--tolerance", type=float, default=1e-6)
    ap.add_argument("--json")
    a = ap.parse_args()

    problems = []
    figures = {"usd": a.usd, "gltf": a.gltf, "prims": {}}
    stage = Usd.Stage.Open(a.usd)
    g = Gltf(a.gltf)
    playback = g.playback() or {}
    fps = playback.get("fps")
    anim = 0 if g.doc.get("animations") else None
    times = None
    if anim is not None:
        times = sorted({float(t) for ch in g.doc["animations"][0]["samplers"]
                        for t in g.accessor(ch["input"])[:, 0]})

    start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    figures.update(
        timeCodesPerSecond=stage.GetTimeCodesPerSecond(),
        framesPerSecond=stage.GetFramesPerSecond(),
        startTimeCode=start, endTimeCode=end,
        upAxis=UsdGeom.GetStageUpAxis(stage),
        metersPerUnit=UsdGeom.GetStageMetersPerUnit(stage),
        gltf_fps=fps)
    if not stage.HasAuthoredTimeCodeRange():
        problems.append("no startTimeCode/endTimeCode")
    if fps is None or stage.GetTimeCodesPerSecond() != fps or stage.GetFramesPerSecond() != fps:
        problems.append(f"time codes per second {stage.GetTimeCodesPerSecond()}, frames per "
                        f"second {stage.GetFramesPerSecond()}, the glTF's fps {fps}")
    if UsdGeom.GetStageUpAxis(stage) != "Y" or UsdGeom.GetStageMetersPerUnit(stage) != 1.0:
        problems.append("upAxis or metersPerUnit")
    if times is not None and fps:
        # glTF key times are float32: a key is as exact as one float32 step at its time.
        def slack(t):
            return max(1e-6, 2.0 * fps * float(np.spacing(np.float32(t))))
        if (abs(start - times[0] * fps) > slack(times[0])
                or abs(end - times[-1] * fps) > slack(times[-1])):
            problems.append(f"time codes {start}..{end} against the glTF's keys "
                            f"{times[0] * fps}..{times[-1] * fps} (frames)")
    frame_count = int(round(end - start)) + 1
    frames = a.frames if a.frames else list(range(frame_count))
    frames = [f for f in frames if f < frame_count]
    figures["frames"] = frames
    errors = validation_errors(stage)
    figures["validation_errors"] = errors
    problems.extend(errors)

    root = stage.GetDefaultPrim()
    if not root:
        problems.append("no defaultPrim")
        meshes = []
    else:
        meshes = [p for p in Usd.PrimRange(root) if p.IsA(UsdGeom.Mesh)]
    nodes = {g.doc["nodes"][i].get("name"): i for i in g.mesh_nodes()}
    worst_all = 0.0
    for prim in meshes:
        name = prim.GetName()
        mesh = UsdGeom.Mesh(prim)
        fig = {}
        figures["prims"][str(prim.GetPath())] = fig
        if name not in nodes:
            problems.append(f"{prim.GetPath()}: no glTF mesh node named {name}")
            continue
        node = nodes[name]
        counts = np.array(mesh.GetFaceVertexCountsAttr().Get())
        indices = np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
        if not (counts == 3).all():
            problems.append(f"{name}: faces other than triangles")
        def usd_points(tc):
            p = np.array(mesh.GetPointsAttr().Get(tc), dtype=np.float64)
            m = np.array(UsdGeom.XformCache(tc).GetLocalToWorldTransform(prim)).T
            return (np.c_[p, np.ones(len(p))] @ m.T)[:, :3]

        p0 = usd_points(start)
        g0, gtris = g.evaluate(node, anim, start / fps if fps else 0.0)
        d = np.linalg.norm(g0[:, None, :] - p0[None, :, :], axis=2)
        hits = d <= a.tolerance
        found = hits.any(axis=1)
        if not found.all():
            problems.append(f"{name}: {int((~found).sum())} glTF vertices match no USD point at "
                            f"time code {start}")
            continue
        # Where several points coincide (a flat-shaded collider's corners), the same index.
        point_of = np.argmax(hits, axis=1)
        same = np.arange(len(g0))
        same_hit = same < len(p0)
        same_hit[same_hit] = hits[same[same_hit], same[same_hit]]
        point_of[same_hit] = same[same_hit]
        if canonical(point_of[gtris]) != canonical(indices):
            problems.append(f"{name}: the glTF's triangles mapped onto the USD points are not "
                            f"the USD faces")
        fig.update(points=len(p0), gltf_vertices=len(g0), triangles=len(indices),
                   animated=mesh.GetPointsAttr().GetNumTimeSamples() > 0,
                   normals_interpolation=mesh.GetNormalsInterpolation())
        if mesh.GetNormalsInterpolation() != "vertex":
            problems.append(f"{name}: normals interpolation {mesh.GetNormalsInterpolation()}")
        worst = 0.0
        for f in frames:
            tc = start + f
            p = usd_points(tc)
            gp, _ = g.evaluate(node, anim, tc / fps)
            dist = float(np.linalg.norm(p[point_of] - gp, axis=1).max())
            worst = max(worst, dist)
            if dist > a.tolerance:
                problems.append(f"{name}: frame {f}: a glTF vertex is {dist:.3e} m from its USD "
                                f"point")
            raw = np.array(mesh.GetPointsAttr().Get(tc), dtype=np.float64)
            ext = np.array(mesh.GetExtentAttr().Get(tc), dtype=np.float64)
            if not np.array_equal(ext, np.array([raw.min(axis=0), raw.max(axis=0)])):
                problems.append(f"{name}: frame {f}: extent {ext.tolist()} is not the bounds")
            n = np.array(mesh.GetNormalsAttr().Get(tc), dtype=np.float64)
            if len(n) != len(raw) or np.abs(np.linalg.norm(n, axis=1) - 1).max() > 1e-5:
                problems.append(f"{name}: frame {f}: normals not one unit vector per point")
        fig["max_distance_m"] = worst
        worst_all = max(worst_all, worst)
    if not meshes:
        problems.append("no Mesh prims")
    figures["max_distance_m"] = worst_all
    figures["problems"] = problems
    text = json.dumps(figures, indent=1)
    print(text)
    if a.json:
        with open(a.json, "w") as f:
            f.write(text)
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
