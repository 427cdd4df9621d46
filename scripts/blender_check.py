"""Import glTF files into headless Blender and check what Blender made of them.

Run inside Blender (3.4 from Debian is what CI uses), with a PATH on which no
pyenv python comes first:

    env PATH=/usr/bin:/bin blender -b --factory-startup --python-exit-code 1 \
        --python scripts/blender_check.py -- [options] FILE...

For each FILE the scene is reset to empty, the file is imported with
bpy.ops.import_scene.gltf, the expectations given by the options are checked
and one summary line is printed: objects, meshes with vertex and shape-key
counts, armatures with bone counts, actions with frame ranges.

Options (after the `--`):
  --auto                    derive expectations from the file's own glTF JSON:
                            a mesh with N morph targets -> a mesh object with
                            exactly N + 1 shape keys (Blender's "Basis" plus
                            one per target) and at least one action; a skin ->
                            an armature holding a bone for every joint node of
                            that skin (by name); any animation -> an action.
                            Shape keys must also carry the names given in
                            mesh.extras.targetNames, when there are any.
                            A node whose mesh has no morph targets and no
                            skin (a static mesh, e.g. a collider written
                            beside the cloth) -> a mesh object named after
                            the node, without shape keys, with as many
                            vertices as its POSITION accessors hold.
  --expect-shape-keys N     some mesh object has exactly N shape keys,
                            counting "Basis" (cloth bakes: frames + 1)
  --expect-bones A,B,...    one armature object has bones with all these names
  --expect-action           bpy.data.actions is not empty
  --render OUT.png          render a still with the Workbench engine, camera
                            framing every mesh object from a 3/4 view; with
                            several FILEs, "{stem}" in OUT is replaced by the
                            file's stem (otherwise "_<stem>" is added; a stem
                            shared by two files gets "_<ext>" as well)
  --resolution WxH          render size (default 480x270)
  --frame F                 frame to evaluate and render (default: the middle
                            of the scene's frame range, which is fitted to the
                            union of the imported actions' frame ranges)
  --playback                compare what Blender evaluates at --check-frames N
                            frames (default 5) with an independent numpy
                            reading of the file playing its first animation
                            (scripts/blender/playback_check.py): largest
                            distance <= --tolerance (2e-3); morph meshes:
                            >= 99 % smooth faces, shading normals p95 <= 3°
  --switch-actions          with --playback: play a rig's other actions, switch
                            back to the bake's and check again
  --helper                  import with scripts/blender/scenebake_import.py
                            and check the fps, frame range, smooth shading and
                            active action it set against asset.extras
  --no-shim                 import as plain File > Import does, without the
                            numpy.bool alias Debian's Blender 3.4 needs

Exit status: 0 if every file imported and met every expectation; 1 otherwise
(the failures are listed, naming the file and what failed); 2 on bad options.
"""

import argparse
import json
import math
import os
import struct
import sys
import time

# Blender 3.4's glTF importer still uses `np.bool`, which numpy 1.24 removed.
# Restore the alias before the importer is loaded, unless --no-shim asks for the
# plain File > Import path a user without the helper takes.
import numpy

if "bool" not in numpy.__dict__ and "--no-shim" not in sys.argv:
    numpy.bool = bool

import bpy  # noqa: E402  (must come after the numpy shim)
from mathutils import Vector  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender"))
import playback_check  # noqa: E402
import scenebake_import  # noqa: E402

PROG = "blender_check"


class CheckFailed(Exception):
    """An expectation about one file was not met."""


def log(msg):
    print(f"{PROG}: {msg}", flush=True)


# --------------------------------------------------------------------------
# Arguments


def script_args():
    argv = sys.argv
    return argv[argv.index("--") + 1:] if "--" in argv else []


def parse_resolution(text):
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH, e.g. 480x270, got {text!r}")
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"resolution must be positive, got {text!r}")
    return w, h


def parse_names(text):
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise argparse.ArgumentTypeError("expected a comma-separated list of bone names")
    return names


def parse_args(argv):
    ap = argparse.ArgumentParser(
        prog="blender ... --python scripts/blender_check.py --",
        description="Import glTF files into Blender and check the result.",
    )
    ap.add_argument("files", nargs="+", metavar="FILE", help=".gltf or .glb file")
    ap.add_argument("--auto", action="store_true",
                    help="derive expectations from the file's glTF JSON")
    ap.add_argument("--expect-shape-keys", type=int, metavar="N",
                    help="some mesh object has exactly N shape keys (incl. Basis)")
    ap.add_argument("--expect-bones", type=parse_names, metavar="NAME,...",
                    help="an armature has bones with all these names")
    ap.add_argument("--expect-action", action="store_true",
                    help="at least one action exists")
    ap.add_argument("--render", metavar="OUT.png", help="render a Workbench still to OUT.png")
    ap.add_argument("--resolution", type=parse_resolution, default=(480, 270), metavar="WxH",
                    help="render resolution (default 480x270)")
    ap.add_argument("--frame", type=int, metavar="F",
                    help="frame to render (default: middle of the scene frame range)")
    ap.add_argument("--helper", action="store_true",
                    help="import with scripts/blender/scenebake_import.py (fps, frame range, "
                         "smooth shading, the bake's action) instead of plain File > Import, "
                         "and check what it set against the file's asset.extras.scenebake")
    ap.add_argument("--playback", action="store_true",
                    help="compare what Blender evaluates at several frames with an independent "
                         "reading of the file (scripts/blender/playback_check.py)")
    ap.add_argument("--check-frames", type=int, default=5, metavar="N",
                    help="frames checked by --playback (default 5, spread over the range)")
    ap.add_argument("--tolerance", type=float, default=2e-3, metavar="D",
                    help="--playback: largest distance accepted, scene units (default 2e-3)")
    ap.add_argument("--switch-actions", action="store_true",
                    help="--playback: also play every other action of an armature, switch back "
                         "and check the bake again")
    ap.add_argument("--no-shim", action="store_true",
                    help="import as plain File > Import does: no numpy.bool alias "
                    "(Debian's Blender 3.4 with numpy 1.24 then fails)")
    ap.add_argument("--skip-node", action="append", default=[], metavar="NAME",
                    help="--playback: leave mesh nodes of this name out of the comparison (a "
                         "known importer defect; each skip is printed)")
    return ap.parse_args(argv)


# --------------------------------------------------------------------------
# Reading the glTF JSON ourselves (for --auto)


def read_gltf_json(path):
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] == b"glTF":
        if len(data) < 20:
            raise CheckFailed("GLB shorter than its header")
        _magic, version, _length = struct.unpack_from("<4sII", data, 0)
        if version != 2:
            raise CheckFailed(f"GLB container version {version}, expected 2")
        chunk_len, chunk_type = struct.unpack_from("<I4s", data, 12)
        if chunk_type != b"JSON":
            raise CheckFailed(f"first GLB chunk is {chunk_type!r}, expected JSON")
        text = data[20:20 + chunk_len]
    else:
        text = data
    try:
        return json.loads(text.decode("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CheckFailed(f"cannot parse glTF JSON: {e}")


BLENDER_NAME_MAX = 63  # bytes; Blender truncates longer ID and bone names


def blender_name(name):
    raw = name.encode("utf-8")
    if len(raw) <= BLENDER_NAME_MAX:
        return name
    return raw[:BLENDER_NAME_MAX].decode("utf-8", errors="ignore")


def auto_expectations(doc):
    """Expectations implied by a glTF document.

    Returns a dict with
      shape_keys: sorted list of distinct shape-key counts (targets + 1), one
                  per node-referenced mesh that has morph targets
      key_names:  list of (mesh label, [target names]) from mesh.extras.targetNames
      skins:      list of (skin label, [joint names], unnamed joint count)
      action:     True if an action is expected
      meshes:     True if at least one mesh object is expected
      statics:    list of (node label, Blender object name or None when the
                  node has no name, vertex count) for nodes whose mesh has no
                  morph targets and that carry no skin
    """
    nodes = doc.get("nodes", [])
    meshes = doc.get("meshes", [])
    used_meshes = sorted({n["mesh"] for n in nodes if "mesh" in n})
    shape_keys = set()
    key_names = []
    for mi in used_meshes:
        mesh = meshes[mi]
        counts = {len(p.get("targets", [])) for p in mesh.get("primitives", [])}
        n_targets = max(counts, default=0)
        if n_targets > 0:
            shape_keys.add(n_targets + 1)
            # The importer names shape keys after mesh.extras.targetNames;
            # only check names that Blender can keep as they are.
            names = (mesh.get("extras") or {}).get("targetNames")
            if (isinstance(names, list) and len(names) == n_targets
                    and all(isinstance(n, str) and n and n == blender_name(n) for n in names)
                    and len(set(names)) == len(names) and "Basis" not in names):
                key_names.append((mesh.get("name") or f"meshes[{mi}]", names))
    accessors = doc.get("accessors", [])
    statics = []
    for ni, node in enumerate(nodes):
        if "mesh" not in node or "skin" in node:
            continue
        prims = meshes[node["mesh"]].get("primitives", [])
        if any(p.get("targets") for p in prims):
            continue
        vertices = sum(accessors[p["attributes"]["POSITION"]]["count"]
                       for p in prims if "POSITION" in p.get("attributes", {}))
        name = node.get("name")
        statics.append((f"nodes[{ni}] ({name})" if name else f"nodes[{ni}]",
                        blender_name(name) if name else None, vertices))
    skins = []
    for si, skin in enumerate(doc.get("skins", [])):
        names, unnamed = [], 0
        for j in skin.get("joints", []):
            name = nodes[j].get("name") if j < len(nodes) else None
            if name:
                names.append(blender_name(name))
            else:
                unnamed += 1
        skins.append((skin.get("name") or f"skins[{si}]", names, unnamed))
    return {
        "shape_keys": sorted(shape_keys),
        "key_names": key_names,
        "skins": skins,
        "action": bool(doc.get("animations")) or bool(shape_keys),
        "meshes": bool(used_meshes),
        "statics": statics,
    }


# --------------------------------------------------------------------------
# Inspecting the Blender scene


def frame_range(action):
    start, end = action.frame_range
    return f"{start:g}-{end:g}"


def shape_key_count(obj):
    keys = obj.data.shape_keys if obj.type == "MESH" else None
    return len(keys.key_blocks) if keys else 0


def summarize(objects):
    by_type = {}
    for o in objects:
        by_type[o.type] = by_type.get(o.type, 0) + 1
    parts = [f"{len(objects)} objects ("
             + ", ".join(f"{n} {t.lower()}" for t, n in sorted(by_type.items())) + ")"]
    mesh_objs = [o for o in objects if o.type == "MESH"]
    if mesh_objs:
        parts.append("meshes: " + ", ".join(
            f"{o.name}[{len(o.data.vertices)} v, {shape_key_count(o)} shape keys]"
            for o in mesh_objs))
    arms = [o for o in objects if o.type == "ARMATURE"]
    if arms:
        parts.append("armatures: " + ", ".join(
            f"{o.name}[{len(o.data.bones)} bones]" for o in arms))
    if bpy.data.actions:
        parts.append("actions: " + ", ".join(
            f"{a.name}[{frame_range(a)}]" for a in bpy.data.actions))
    else:
        parts.append("actions: none")
    return "; ".join(parts)


def check_expectations(objects, args, auto):
    """Return a list of human-readable failures (empty when all is well)."""
    failures = []
    mesh_objs = [o for o in objects if o.type == "MESH"]
    arms = [o for o in objects if o.type == "ARMATURE"]
    counts = sorted(shape_key_count(o) for o in mesh_objs)

    wanted_keys = list(auto["shape_keys"]) if auto else []
    if args.expect_shape_keys is not None and args.expect_shape_keys not in wanted_keys:
        wanted_keys.append(args.expect_shape_keys)
    for n in wanted_keys:
        if n not in counts:
            failures.append(
                f"expected a mesh object with exactly {n} shape keys (incl. Basis), "
                f"found shape-key counts {counts or 'none (no mesh objects)'}")

    if auto:
        key_lists = [[k.name for k in o.data.shape_keys.key_blocks[1:]]
                     for o in mesh_objs if o.data.shape_keys]
        for label, names in auto["key_names"]:
            if names in key_lists:
                continue
            same_len = [k for k in key_lists if len(k) == len(names)]
            if same_len:
                k = same_len[0]
                i = next(i for i, (a, b) in enumerate(zip(names, k)) if a != b)
                found = f"shape key {i + 1} is named {k[i]!r}, not {names[i]!r}"
            else:
                found = f"no mesh object has {len(names)} non-Basis shape keys"
            failures.append(f"{label}: shape keys do not carry extras.targetNames: {found}")

    bone_sets = []
    if auto:
        bone_sets += [(label, names, unnamed) for label, names, unnamed in auto["skins"]]
    if args.expect_bones:
        bone_sets.append(("--expect-bones", args.expect_bones, 0))
    for label, names, unnamed in bone_sets:
        if not arms:
            failures.append(f"{label}: expected an armature, none was imported")
            continue
        # One armature must hold every named joint, and enough bones overall
        # to also cover joints that have no name in the glTF.
        fewest_missing = None
        for arm in arms:
            bone_names = {b.name for b in arm.data.bones}
            missing = [n for n in names if n not in bone_names]
            if not missing and len(bone_names) >= len(names) + unnamed:
                fewest_missing = None
                break
            if fewest_missing is None or len(missing) < len(fewest_missing):
                fewest_missing = missing
        else:
            if fewest_missing:
                shown = ", ".join(fewest_missing[:10])
                if len(fewest_missing) > 10:
                    shown += ", ..."
                failures.append(
                    f"{label}: no armature has all {len(names)} expected bones; "
                    f"the closest misses {len(fewest_missing)}: {shown}")
            else:
                failures.append(
                    f"{label}: expected an armature with at least {len(names) + unnamed} "
                    f"bones, found {[len(a.data.bones) for a in arms]}")

    if (args.expect_action or (auto and auto["action"])) and not bpy.data.actions:
        failures.append("expected at least one action, bpy.data.actions is empty")

    if auto:
        # Static meshes: by object name (Blender appends ".001"... to a name
        # already taken), else by vertex count among objects without shape keys.
        plain = [o for o in mesh_objs if not o.data.shape_keys]
        for label, name, vertices in auto["statics"]:
            if name is not None:
                named = [o for o in plain
                         if o.name == name or (o.name.startswith(name + ".")
                                               and o.name[len(name) + 1:].isdigit())]
                if not named:
                    failures.append(f"{label}: static mesh: no mesh object named {name!r} "
                                    f"without shape keys")
                elif not any(len(o.data.vertices) == vertices for o in named):
                    failures.append(f"{label}: static mesh {name!r} has "
                                    f"{[len(o.data.vertices) for o in named]} vertices, "
                                    f"expected {vertices}")
            elif not any(len(o.data.vertices) == vertices for o in plain):
                failures.append(f"{label}: static mesh: no mesh object without shape keys "
                                f"has {vertices} vertices")

    if auto and auto["meshes"] and not mesh_objs:
        failures.append("the glTF has meshes but no mesh object was imported")
    return failures


# --------------------------------------------------------------------------
# Rendering


def world_points(mesh_objs, depsgraph):
    """World-space vertex positions of the evaluated (deformed) mesh objects."""
    chunks = []
    for obj in mesh_objs:
        ev = obj.evaluated_get(depsgraph)
        me = ev.to_mesh()
        try:
            co = numpy.empty(len(me.vertices) * 3, dtype=numpy.float64)
            me.vertices.foreach_get("co", co)
        finally:
            ev.to_mesh_clear()
        co = co.reshape(-1, 3)
        m = numpy.array(ev.matrix_world, dtype=numpy.float64)
        chunks.append(co @ m[:3, :3].T + m[:3, 3])
    pts = numpy.concatenate(chunks) if chunks else numpy.zeros((0, 3))
    pts = pts[numpy.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        raise CheckFailed("--render: the mesh objects have no finite vertices to frame")
    return pts


def add_framing_camera(scene, mesh_objs, width, height):
    """Add a camera that sees every vertex of the mesh objects from a 3/4 view.

    Works at any scale (metre-sized cloth, a 150-unit fox): the distance is
    solved from the vertices' positions, not assumed.
    """
    pts = world_points(mesh_objs, bpy.context.evaluated_depsgraph_get())
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    size = float(numpy.linalg.norm(hi - lo))
    if not math.isfinite(size) or size < 1e-6:
        size = 1.0

    cam_data = bpy.data.cameras.new("blender_check_camera")
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.lens = 50.0
    cam = bpy.data.objects.new("blender_check_camera", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam

    # Blender is +Z up; the glTF importer maps glTF's front (+Z) to Blender's
    # -Y. Look from front-right and above: azimuth 35 deg, elevation 22 deg.
    az, el = math.radians(35.0), math.radians(22.0)
    view_dir = Vector((math.cos(el) * math.sin(az), -math.cos(el) * math.cos(az), math.sin(el)))
    # The camera looks along -view_dir with world +Z up on screen.
    rot = (-view_dir).to_track_quat("-Z", "Y")
    right, up = rot @ Vector((1, 0, 0)), rot @ Vector((0, 1, 0))
    basis = numpy.array([right, up, view_dir], dtype=numpy.float64)  # rows

    tan_h = cam_data.sensor_width / (2 * cam_data.lens)
    tan_v = tan_h * height / width
    margin = 0.9  # keep the object inside 90% of the frame

    # Camera at target + D * view_dir. A point q (relative to the target, in
    # camera axes x, y, z) is at depth D - z and inside the frame when
    # |x| <= (D - z) tan_h margin and |y| <= (D - z) tan_v margin; solve for the
    # smallest D, then re-centre the target on the projected extents.
    target = (lo + hi) / 2
    for _ in range(3):
        q = (pts - target) @ basis.T
        need = numpy.maximum(numpy.abs(q[:, 0]) / (tan_h * margin),
                             numpy.abs(q[:, 1]) / (tan_v * margin))
        dist = max(float((q[:, 2] + need).max()), 1e-3 * size, 1e-4)
        depth = dist - q[:, 2]
        sx, sy = q[:, 0] / depth, q[:, 1] / depth  # tangent of the view angle
        shift_x = (sx.min() + sx.max()) / 2 * dist
        shift_y = (sy.min() + sy.max()) / 2 * dist
        target = target + shift_x * basis[0] + shift_y * basis[1]
    q = (pts - target) @ basis.T
    need = numpy.maximum(numpy.abs(q[:, 0]) / (tan_h * margin),
                         numpy.abs(q[:, 1]) / (tan_v * margin))
    dist = max(float((q[:, 2] + need).max()), 1e-3 * size, 1e-4)

    cam.location = Vector(target) + dist * view_dir
    cam.rotation_mode = "QUATERNION"
    cam.rotation_quaternion = rot
    cam_data.clip_start = max(dist - size, dist * 1e-3) * 0.5
    cam_data.clip_end = dist + 2 * size
    return Vector(target), Vector(hi - lo), dist


def thicken_lines(mesh_objs, radius):
    """Give edge-only meshes (glTF LINES: IK target paths) a round bevel, since
    renderers draw no loose edges. Object transforms and their animation are kept."""
    for obj in mesh_objs:
        if len(obj.data.polygons) == 0 and len(obj.data.edges) > 0:
            bpy.ops.object.select_all(action="DESELECT")
            obj.select_set(True)
            bpy.context.view_layer.objects.active = obj
            bpy.ops.object.convert(target="CURVE")
            obj.data.bevel_depth = radius


def render_still(path, width, height, mesh_objs):
    scene = bpy.context.scene
    if not mesh_objs:
        raise CheckFailed("--render: no mesh object to frame")
    centre, extent, dist = add_framing_camera(scene, mesh_objs, width, height)
    thicken_lines(mesh_objs, 0.004 * extent.length)

    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.filepath = os.path.abspath(path)
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "TEXTURE"  # image texture if any, else material colour
    shading.show_cavity = True
    shading.show_shadows = False
    if scene.world is None:
        scene.world = bpy.data.worlds.new("blender_check_world")
    scene.world.color = (0.05, 0.055, 0.07)  # dark, so light-grey cloth stands out

    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    bpy.ops.render.render(write_still=True)
    if not os.path.isfile(path):
        raise CheckFailed(f"--render: Blender did not write {path}")
    return (f"rendered {path} ({width}x{height}, frame {scene.frame_current}, "
            f"looking at ({centre.x:.3g}, {centre.y:.3g}, {centre.z:.3g}) "
            f"bbox size ({extent.x:.3g}, {extent.y:.3g}, {extent.z:.3g}), camera distance {dist:.3g})")


def helper_summary(info):
    return (f"{info['fps']:g} fps, frames {info['frame_start']}-{info['frame_end']}, "
            f"active actions {', '.join(info['actions']) or 'none'} ({info['fcurves']} fcurves), "
            f"{info['smooth_faces']} of {info['faces']} faces smooth")


def helper_failures(path, info, objects):
    """What scenebake_import.py set, checked against the file's own record."""
    failures = []
    doc = read_gltf_json(path)
    rec = scenebake_import.read_playback(doc)
    if rec is None:
        return ["--helper: the file has no asset.extras.scenebake (fps, frame range)"]
    fps, start, end, name = rec
    scene = bpy.context.scene
    if abs(scene.render.fps / scene.render.fps_base - fps) > 1e-6 * fps:
        failures.append(f"--helper: scene fps {scene.render.fps / scene.render.fps_base:g}, "
                        f"the bake's is {fps:g}")
    # The importer keys frame f of the bake at Blender frame f / fps × round(fps) (the same
    # frame at an integer fps); the range must be the whole frames that hold the first and last.
    fps_int = max(1, round(fps))
    want = (math.floor(start / fps * fps_int + 1e-6), math.ceil(end / fps * fps_int - 1e-6))
    if (scene.frame_start, scene.frame_end) != want:
        failures.append(f"--helper: scene frames {scene.frame_start}-{scene.frame_end}, "
                        f"the bake's frames {start}-{end} at {fps:g} fps are {want[0]}-{want[1]}")
    if scene.render.fps != fps_int:
        failures.append(f"--helper: scene fps {scene.render.fps} / {scene.render.fps_base:g}, "
                        f"not {fps_int} / base")
    if info["actions"] and info["fcurves"] == 0:
        failures.append("--helper: the bake's actions hold no fcurves")
    if info["smooth_faces"] != info["faces"]:
        failures.append(f"--helper: {info['faces'] - info['smooth_faces']} faces left flat")
    # Every object the bake animates has the bake's action active.
    anims = doc.get("animations") or []
    if anims:
        wanted = name or anims[0].get("name")
        owners = scenebake_import.animated_ids(objects)
        playing = [ad.action.name if ad.action else None for _o, ad in owners
                   if any(t.name == wanted for t in ad.nla_tracks)]
        if not playing:
            failures.append(f"--helper: no object has an NLA track for animation {wanted!r}")
        for _o, ad in owners:
            tracks = {t.name: t for t in ad.nla_tracks}
            if wanted in tracks and tracks[wanted].strips and \
                    ad.action != tracks[wanted].strips[0].action:
                failures.append(f"--helper: {_o.name}: active action "
                                f"{ad.action.name if ad.action else None!r}, not the bake's "
                                f"{tracks[wanted].strips[0].action.name!r}")
    return failures


def render_paths(template, files):
    """Output path per input file for --render.

    One file: `template` as given. Several: "{stem}" in `template` is replaced
    by each file's stem, or "_<stem>" is added before the extension; stems
    shared by several files (cloth.glb, cloth.gltf) get their extension too.
    """
    stems = [os.path.splitext(os.path.basename(f)) for f in files]
    counts = {}
    for stem, _ext in stems:
        counts[stem] = counts.get(stem, 0) + 1
    out = []
    for stem, ext in stems:
        tag = stem if counts[stem] == 1 else f"{stem}_{ext.lstrip('.')}"
        if "{stem}" in template:
            out.append(template.replace("{stem}", tag))
        elif len(files) == 1:
            out.append(template)
        else:
            base, png = os.path.splitext(template)
            out.append(f"{base}_{tag}{png or '.png'}")
    return out


# --------------------------------------------------------------------------
# Main


def check_file(path, args, render_out):
    """Import one file and check it; returns (summary, failures)."""
    if not os.path.isfile(path):
        return None, ["file not found"]
    auto = None
    if args.auto:
        try:
            auto = auto_expectations(read_gltf_json(path))
        except CheckFailed as e:
            return None, [f"--auto: {e}"]
        except (LookupError, TypeError, AttributeError, ValueError) as e:
            return None, [f"--auto: malformed glTF JSON ({type(e).__name__}: {e})"]

    bpy.ops.wm.read_factory_settings(use_empty=True)
    helper_info = None
    try:
        if args.helper:
            helper_info = scenebake_import.import_bake(path, camera=False)
            result = {"FINISHED"}
        else:
            result = bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))
    except Exception as e:  # the importer raises RuntimeError on bad files
        return None, [f"import failed: {e}"]
    if "FINISHED" not in result:
        return None, [f"import did not finish: {sorted(result)}"]

    scene = bpy.context.scene
    fps_import = scene.render.fps
    objects = list(scene.objects)
    if not objects:
        return None, ["import produced no objects"]

    # Blender 3.4's importer leaves the scene at frames 1-250 whatever the
    # animations span; fit the scene range to the imported actions, as a
    # user would, so that the default --frame lands inside the animation.
    # (The helper sets the range from the bake itself.)
    if bpy.data.actions and not args.helper:
        starts, ends = zip(*(a.frame_range for a in bpy.data.actions))
        scene.frame_start = math.floor(min(starts) + 1e-3)
        scene.frame_end = max(math.ceil(max(ends) - 1e-3), scene.frame_start)

    frame = args.frame
    if frame is None:
        frame = (scene.frame_start + scene.frame_end) // 2
    scene.frame_set(frame)

    summary = summarize(objects)
    summary += f"; scene frames {scene.frame_start}-{scene.frame_end}, at frame {frame}"
    failures = check_expectations(objects, args, auto)
    if helper_info is not None:
        summary += "\n    helper: " + helper_summary(helper_info)
        failures += helper_failures(path, helper_info, objects)
    if args.playback:
        lines, bad = playback_check.check(path, objects, fps_import, frames=args.check_frames,
                                          tolerance=args.tolerance,
                                          switch_actions=args.switch_actions,
                                          skip=args.skip_node)
        summary += "".join("\n    " + line for line in lines)
        failures += bad
        scene.frame_set(frame)
    if render_out:
        try:
            summary += "\n    " + render_still(render_out, *args.resolution,
                                               [o for o in objects if o.type == "MESH"])
        except Exception as e:
            failures.append(f"render failed: {e}")
    return summary, failures


def main():
    args = parse_args(script_args())
    log(f"Blender {bpy.app.version_string}, numpy {numpy.__version__}, "
        f"{len(args.files)} file(s)")
    outs = render_paths(args.render, args.files) if args.render else [None] * len(args.files)
    bad = []
    for path, render_out in zip(args.files, outs):
        t0 = time.monotonic()
        summary, failures = check_file(path, args, render_out)
        secs = time.monotonic() - t0
        status = "FAIL" if failures else "ok"
        log(f"{status} {path} ({secs:.1f} s): {summary or 'not imported'}")
        for f in failures:
            log(f"FAIL {path}: {f}")
        if failures:
            bad.append(path)
    log(f"{len(args.files) - len(bad)} of {len(args.files)} files met every expectation")
    if bad:
        log("failed: " + ", ".join(bad))
        raise SystemExit(1)


if __name__ == "__main__":
    main()
