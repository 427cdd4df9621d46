"""What Blender plays, compared with an independent reading of the file (scripts/blender/gltf_eval.py).

Imported by scripts/blender_check.py (`--playback`); runs inside Blender after a file was
imported (with plain File > Import, or with scenebake_import.py). For each glTF node with a
mesh, it finds the Blender object made from it and, at several frames of the scene's range:

- evaluates the object as Blender shows it (shape keys, armature) in world space, and the
  node as the glTF specification defines it, playing the file's FIRST animation (what a viewer
  plays), at the time the importer maps that frame to (t = frame / the scene fps at import);
- matches Blender's vertices to the file's once (nearest file vertex at the first checked
  frame: the importer merges and reorders vertices) and reports the largest distance at every
  checked frame;
- for meshes whose morph weights the first animation plays: the share of faces Blender shades
  smooth, and the angle
  between Blender's shading normals (loop normals) and the normals of the file's evaluated
  shape (corner-angle weighted, seams welded), 95th percentile and largest; and, for
  information, the same angle for the NORMAL the file itself carries at that time (what
  three.js and engines shade with).

With `switch_actions`, every other action of an armature is played for a frame before the
bake's action is made active again, and the bake is checked once more: a bake that leaves a
bone unkeyed would keep that bone in the other action's pose.
"""

import math
import os
import sys

import numpy as np

import bpy
from mathutils import kdtree

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gltf_eval  # noqa: E402


def to_blender(p):
    """glTF (Y up) to Blender (Z up) coordinates: (x, y, z) -> (x, -z, y)."""
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)


def object_for_node(g, node, objects):
    n = g.doc["nodes"][node]
    mesh = g.doc["meshes"][n["mesh"]]
    names = [nm for nm in (n.get("name"), mesh.get("name"), f"Mesh_{n['mesh']}", f"Node_{node}")
             if nm]
    for nm in names:
        for o in objects:
            if o.type == "MESH" and (o.name == nm or (o.name.startswith(nm + ".")
                                                      and o.name[len(nm) + 1:].isdigit())):
                return o
    return None


def blender_positions(obj, depsgraph):
    ev = obj.evaluated_get(depsgraph)
    me = ev.to_mesh()
    co = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    m = np.array(ev.matrix_world)
    world = co @ m[:3, :3].T + m[:3, 3]
    return ev, me, world


def blender_loop_normals(ev, me):
    """Loop normals in world space and each loop's vertex index."""
    if hasattr(me, "calc_normals_split"):
        me.calc_normals_split()
    n = np.empty(len(me.loops) * 3)
    me.loops.foreach_get("normal", n)
    if hasattr(me, "corner_normals") and not n.any():
        me.corner_normals.foreach_get("vector", n)
    n = n.reshape(-1, 3)
    vi = np.empty(len(me.loops), dtype=np.int64)
    me.loops.foreach_get("vertex_index", vi)
    m = np.array(ev.matrix_world)[:3, :3]
    n = n @ np.linalg.inv(m)  # normals transform by the inverse transpose
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    return n, vi


def check(path, objects, fps_import, frames=5, tolerance=2e-3, max_angle=3.0, min_smooth=0.99,
          switch_actions=False, skip=()):
    """Returns (lines, failures) for the file at `path`, imported into the current scene."""
    g = gltf_eval.Gltf(path)
    anims = g.doc.get("animations") or []
    anim = 0 if anims else None
    scene = bpy.context.scene
    lines, failures = [], []
    playback = g.playback()
    if playback is not None and anims and playback.get("animation") != anims[0].get("name"):
        failures.append(f"asset.extras.scenebake names animation {playback.get('animation')!r}, "
                        f"but the first animation is {anims[0].get('name')!r}")
    start, end = scene.frame_start, scene.frame_end
    checked = sorted({int(round(start + (end - start) * k / max(frames - 1, 1)))
                      for k in range(frames)})
    depsgraph = bpy.context.evaluated_depsgraph_get()
    file_angles = []

    def compare(node, obj, match, label_frames, tag=""):
        worst = 0.0
        angles = []
        file_angles.clear()
        for f in label_frames:
            scene.frame_set(f)
            t = f / fps_import
            ref, tris = g.evaluate(node, anim, t)
            ref = to_blender(ref)
            ev, me, got = blender_positions(obj, depsgraph)
            d = float(np.max(np.linalg.norm(got - ref[match], axis=1))) if len(got) else 0.0
            worst = max(worst, d)
            if morph:
                n_ref = gltf_eval.vertex_normals(g.evaluate(node, anim, t)[0], tris)
                n_got, vi = blender_loop_normals(ev, me)
                dots = np.sum(n_got * to_blender(n_ref)[match[vi]], axis=1)
                angles.append(np.degrees(np.arccos(np.clip(dots, -1, 1))))
                n_file = gltf_eval.file_normals(g, node, anim, t)
                if n_file is not None:
                    used = np.unique(tris)  # vertices no triangle uses are never shaded
                    d = np.degrees(np.arccos(np.clip(
                        np.sum(n_file[used] * n_ref[used], axis=1), -1, 1)))
                    file_angles.append(d)
            ev.to_mesh_clear()
        return worst, (np.concatenate(angles) if angles else None)

    for node in g.mesh_nodes():
        n = g.doc["nodes"][node]
        mesh = g.doc["meshes"][n["mesh"]]
        has_targets = any(p.get("targets") for p in mesh["primitives"])
        # Shading is checked on shapes the bake plays (cloth bakes); a rig's own morph targets
        # (a face's expressions), which the first animation leaves alone or repeats from the
        # character's animations (`cloth --rig` carries the driving animation's weights), are
        # the input's business: their positions are compared, their shading is not.
        def keys_weights(a):
            return any(ch["target"].get("node") == node and ch["target"].get("path") == "weights"
                       for ch in a["channels"])
        morph = (has_targets and any(keys_weights(a) for a in anims[:1])
                 and not any(keys_weights(a) for a in anims[1:]))
        animated = has_targets or "skin" in n or any(
            ch["target"].get("node") == node for a in anims[:1] for ch in a["channels"])
        if not animated and not morph:
            continue
        if n.get("name") in skip:
            lines.append(f"nodes[{node}] ({n.get('name')}): skipped (--skip-node)")
            continue
        label = f"nodes[{node}] ({n.get('name') or mesh.get('name') or 'unnamed'})"
        obj = object_for_node(g, node, objects)
        if obj is None:
            failures.append(f"{label}: no Blender mesh object for it")
            continue
        # Which file vertex each Blender vertex is (the importer merges and reorders them):
        # unskinned meshes by their own undeformed coordinates (the base shape of a morphed
        # mesh), skinned ones by position at the first checked frame.
        scene.frame_set(checked[0])
        ref0, _ = g.evaluate(node, anim, checked[0] / fps_import)
        ref0 = to_blender(ref0)
        if "skin" in n:
            key_ref = ref0
            ev, me, key_got = blender_positions(obj, depsgraph)
            ev.to_mesh_clear()
        else:
            key_ref = to_blender(np.concatenate([
                g.accessor(p["attributes"]["POSITION"]) for p in mesh["primitives"]]))
            key_got = np.empty(len(obj.data.vertices) * 3)
            obj.data.vertices.foreach_get("co", key_got)
            key_got = key_got.reshape(-1, 3)
        tree = kdtree.KDTree(len(key_ref))
        for i, p in enumerate(key_ref):
            tree.insert(p, i)
        tree.balance()
        match = np.array([tree.find(p)[1] for p in key_got], dtype=np.int64)
        worst, angles = compare(node, obj, match, checked)
        extent = float(np.max(np.ptp(ref0, axis=0))) if len(ref0) else 0.0
        line = (f"{label} -> {obj.name}: frames {checked[0]}-{checked[-1]} ({len(checked)} checked, "
                f"t = frame / {fps_import} fps): largest distance {worst:.2e} (size {extent:.3g})")
        if worst > tolerance:
            failures.append(f"{label}: Blender's {obj.name} is {worst:.3g} from the file's "
                            f"first animation (tolerance {tolerance:g})")
        if morph:
            polys = obj.data.polygons
            smooth = sum(p.use_smooth for p in polys) / max(len(polys), 1)
            p95 = float(np.percentile(angles, 95)) if angles is not None and len(angles) else 0.0
            amax = float(np.max(angles)) if angles is not None and len(angles) else 0.0
            line += (f"; {100 * smooth:.1f} % of {len(polys)} faces smooth; shading normals vs "
                     f"the evaluated shape's: p95 {p95:.2f}°, max {amax:.2f}°")
            if file_angles:
                fa = np.concatenate(file_angles)
                line += (f"; the file's own NORMAL (what engines apply) vs the same: p95 "
                         f"{np.percentile(fa, 95):.2f}°, max {fa.max():.2f}°")
            if smooth < min_smooth:
                failures.append(f"{label}: {100 * smooth:.1f} % of faces smooth "
                                f"(want >= {100 * min_smooth:g} %)")
            if p95 > max_angle:
                failures.append(f"{label}: shading normals p95 {p95:.2f}° off the evaluated "
                                f"shape's (want <= {max_angle:g}°)")
        lines.append(line)
        if switch_actions and "skin" in n:
            arms = [o for o in objects if o.type == "ARMATURE" and o.animation_data]
            for arm in arms:
                bake = arm.animation_data.action
                # The armature's actions of the file's other animations (the importer keeps
                # each in an NLA track named after its animation).
                first = anims[0].get("name") if anims else None
                others = [t.strips[0].action for t in arm.animation_data.nla_tracks
                          if t.strips and t.name != first and t.strips[0].action != bake]
                for other in others:
                    arm.animation_data.action = other
                    scene.frame_set(int(other.frame_range[0] + other.frame_range[1]) // 2)
                    arm.animation_data.action = bake
                    w, _ = compare(node, obj, match, [checked[len(checked) // 2]])
                    if w > tolerance:
                        failures.append(f"{label}: after playing action {other.name!r}, "
                                        f"{bake.name if bake else None!r} leaves the mesh "
                                        f"{w:.3g} off the file")
                    lines.append(f"{label}: after playing {other.name!r} and switching back to "
                                 f"{bake.name if bake else None!r}: largest distance {w:.2e}")
    return lines, failures
