"""Open a scenebake bake in Blender, set up to play exactly what was baked.

    blender --python scripts/blender/scenebake_import.py -- FILE.glb [--no-camera]
    scenebake open FILE.glb            # the same, finding blender on PATH

It works in Blender 3.4 to 5.x, in the UI or in the background (-b), and:

1. reads the bake's frame rate and frame range from the file's asset.extras.scenebake
   (written by every scenebake export; files without it get the animations' own range);
2. sets the scene's frame rate before importing (Blender's importer turns key times into frames
   with the scene's rate), imports the file with Blender's own glTF importer, and sets the
   scene's frame range so frame f is baked frame f;
3. shades every imported mesh smooth (the baked normals are what the importer keeps);
4. makes the bake's animation the active action of every object it animates (in Blender 3.4
   actions hold fcurves directly; in 4.4+ they are layered: layers[].strips[].channelbags[]);
5. adds a camera framing the bake over its whole frame range and makes it the scene camera.

Used as a module (scripts/blender_check.py does), `import_bake(path)` does the same and returns
a summary dict.
"""

import json
import math
import os
import struct
import sys


def restore_numpy_bool():
    """Blender 3.4's glTF importer uses numpy.bool, which numpy 1.24 removed (Debian 12's
    Blender 3.4 with its numpy 1.24 fails every import without it): restore the alias."""
    try:
        import numpy
    except ImportError:  # pragma: no cover - Blender always ships numpy
        return
    if "bool" not in numpy.__dict__:
        numpy.bool = bool

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

PROG = "scenebake_import"


def read_gltf_json(path):
    """The glTF JSON of a .glb or .gltf file."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] == b"glTF":
        chunk_len, chunk_type = struct.unpack_from("<I4s", data, 12)
        if chunk_type != b"JSON":
            raise ValueError(f"{path}: the first GLB chunk is not JSON")
        data = data[20:20 + chunk_len]
    return json.loads(data.decode("utf-8-sig"))


def read_playback(doc):
    """asset.extras.scenebake as (fps, frame_start, frame_end, animation name), or None."""
    rec = ((doc.get("asset") or {}).get("extras") or {}).get("scenebake")
    if not isinstance(rec, dict):
        return None
    try:
        return (float(rec["fps"]), int(rec["frame_start"]), int(rec["frame_end"]),
                rec.get("animation"))
    except (KeyError, TypeError, ValueError):
        return None


def action_fcurves(action):
    """Every fcurve of an action: action.fcurves (Blender < 5), or the channelbags of a
    layered action (4.4+; the only kind in 5.x)."""
    curves = []
    for layer in getattr(action, "layers", []) or []:
        for strip in layer.strips:
            for bag in getattr(strip, "channelbags", []) or []:
                curves.extend(bag.fcurves)
    if not curves and hasattr(action, "fcurves"):
        try:
            curves = list(action.fcurves)
        except (AttributeError, RuntimeError):
            curves = []
    return curves


def animated_ids(objects):
    """(owner, animation_data) for each imported object and shape-key block with animation."""
    out = []
    for obj in objects:
        if obj.animation_data:
            out.append((obj, obj.animation_data))
        keys = getattr(obj.data, "shape_keys", None) if obj.data is not None else None
        if keys is not None and keys.animation_data:
            out.append((keys, keys.animation_data))
    return out


def activate(animation_data, action):
    """Make `action` the active action (with a slot on 4.4+, where actions are slotted)."""
    animation_data.action = action
    slots = getattr(action, "slots", None)
    if slots is not None and hasattr(animation_data, "action_slot"):
        if animation_data.action_slot is None and len(slots):
            try:
                animation_data.action_slot = slots[0]
            except (AttributeError, TypeError, RuntimeError):
                pass


def bake_actions(objects, name):
    """Make the NLA strip actions named after glTF animation `name` active, per object; the
    importer keeps each animation in an NLA track of that name. Returns the actions made
    active."""
    made = []
    for _owner, ad in animated_ids(objects):
        for track in ad.nla_tracks:
            if track.name == name and track.strips:
                activate(ad, track.strips[0].action)
                made.append(track.strips[0].action)
                break
    return made


def frame_range(playback, fps_import):
    """The scene frames covering the bake's first and last frame, whose keys the importer put at
    t × fps_import (the same frames when the bake's fps is an integer)."""
    fps, first, last = playback[0], playback[1], playback[2]
    return (int(math.floor(first / fps * fps_import + 1e-6)),
            int(math.ceil(last / fps * fps_import - 1e-6)))


def set_fps(scene, fps):
    """The scene plays `fps` frames per second: Blender's integer fps over fps_base. Returns
    the integer fps the importer should place keys with (import with fps_base 1, then call
    set_fps_base): Blender 3.4's importer puts a key at t × fps, 5.x's at t × fps × fps_base, so
    a non-integer rate (e.g. 29.65 for a walk's loop) imported under its fps_base would play
    off by the base in 5.x."""
    scene.render.fps = max(1, int(round(fps)))
    scene.render.fps_base = 1.0
    return scene.render.fps


def set_fps_base(scene, fps):
    """After the import: fps_base so that the scene plays exactly `fps` frames per second."""
    scene.render.fps_base = scene.render.fps / fps


def frame_camera(scene, objects, frames):
    """A camera seeing every mesh at every frame in `frames`, from a 3/4 view above."""
    lo = Vector((math.inf,) * 3)
    hi = Vector((-math.inf,) * 3)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    meshes = [o for o in objects if o.type == "MESH"]
    for f in frames:
        scene.frame_set(f)
        for obj in meshes:
            ev = obj.evaluated_get(depsgraph)
            for corner in ev.bound_box:
                p = ev.matrix_world @ Vector(corner)
                lo = Vector(map(min, lo, p))
                hi = Vector(map(max, hi, p))
    if not meshes or lo.x == math.inf:
        return None
    centre = (lo + hi) / 2
    radius = max((hi - lo).length / 2, 1e-3)
    cam_data = bpy.data.cameras.new("scenebake_camera")
    cam = bpy.data.objects.new("scenebake_camera", cam_data)
    scene.collection.objects.link(cam)
    fov = cam_data.angle
    dist = radius / math.sin(fov / 2) * 1.05
    direction = Vector((1.0, -1.4, 0.8)).normalized()
    cam.location = centre + direction * dist
    cam.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
    cam_data.clip_start = max(dist - radius * 2, dist * 1e-3)
    cam_data.clip_end = dist + radius * 2
    scene.camera = cam
    return cam


def shade_smooth(objects):
    """Every polygon of every imported mesh smooth; counts (smooth, total) polygons."""
    smooth = total = 0
    for obj in objects:
        if obj.type != "MESH":
            continue
        polys = obj.data.polygons
        polys.foreach_set("use_smooth", [True] * len(polys))
        obj.data.update()
        smooth += sum(p.use_smooth for p in polys)
        total += len(polys)
    return smooth, total


def import_bake(path, camera=True):
    """Imports `path` into the current scene and sets it up (see the module docs)."""
    restore_numpy_bool()
    doc = read_gltf_json(path)
    playback = read_playback(doc)
    scene = bpy.context.scene
    if playback:
        set_fps(scene, playback[0])
    before = set(bpy.data.objects)
    result = bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))
    if "FINISHED" not in result:
        raise RuntimeError(f"{path}: Blender's glTF importer did not finish ({sorted(result)})")
    objects = [o for o in bpy.data.objects if o not in before]
    fps_import = scene.render.fps
    anims = doc.get("animations") or []
    name = (playback[3] if playback and playback[3] else None) or (
        anims[0].get("name") if anims else None)
    actions = []
    if name is not None:
        # The importer names a track after the animation (or "Animation_N" without a name).
        track = name or "Animation_0"
        actions = bake_actions(objects, track)
    if playback:
        set_fps_base(scene, playback[0])
        start, end = frame_range(playback, fps_import)
    else:
        ranges = [a.frame_range for a in actions] or [a.frame_range for a in bpy.data.actions]
        start = int(math.floor(min((r[0] for r in ranges), default=1)))
        end = int(math.ceil(max((r[1] for r in ranges), default=250)))
    scene.frame_start = start
    scene.frame_end = max(end, start)
    smooth, total = shade_smooth(objects)
    cam = None
    if camera:
        frames = sorted({start, (start + end) // 2, end, start + (end - start) // 4,
                         start + 3 * (end - start) // 4})
        cam = frame_camera(scene, objects, frames)
    scene.frame_set(start)
    return {
        "fcurves": sum(len(action_fcurves(a)) for a in set(actions)),
        "fps": scene.render.fps / scene.render.fps_base,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "actions": sorted({a.name for a in actions}),
        "smooth_faces": smooth,
        "faces": total,
        "camera": cam.name if cam else None,
        "objects": [o.name for o in objects],
    }


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    camera = "--no-camera" not in argv
    files = [a for a in argv if a != "--no-camera"]
    if len(files) != 1:
        print(f"{PROG}: usage: blender --python scenebake_import.py -- FILE.glb [--no-camera]",
              file=sys.stderr)
        raise SystemExit(2)
    path = files[0]
    if not os.path.isfile(path):
        print(f"{PROG}: {path}: no such file", file=sys.stderr)
        raise SystemExit(1)
    # A fresh scene holds a cube, a light and a camera: keep the light, drop the rest.
    for obj in list(bpy.context.scene.objects):
        if obj.type in ("MESH", "CAMERA"):
            bpy.data.objects.remove(obj)
    info = import_bake(path, camera=camera)
    print(f"{PROG}: {path}: {info['fps']:g} fps, frames {info['frame_start']}-{info['frame_end']}, "
          f"active actions {', '.join(info['actions']) or 'none'} ({info['fcurves']} fcurves), "
          f"{info['smooth_faces']} of {info['faces']} faces smooth, camera {info['camera']}",
          flush=True)


if __name__ == "__main__":
    main()
