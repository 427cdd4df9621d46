"""Check that an IK bake's drawn trail renders in Blender.

Run inside Blender (3.4 from Debian is what CI uses), with a PATH on which no pyenv python
comes first:

    env PATH=/usr/bin:/bin blender -b --factory-startup --python-exit-code 1 \
        --python scripts/blender_trail_check.py -- [--min-pixels N] [--resolution WxH] \
        [--save DIR] FILE...

For each FILE (a `scenebake ik` output) and each of two imports, (a) plain
bpy.ops.import_scene.gltf (File > Import > glTF; the scene's frame range fitted to the
imported actions, and a camera added here that looks at the trail's bounding box along the
drawing's normal, from whichever side of the drawing shows more of it: the pen hand may hide it
from one) and (b) scripts/blender/scenebake_import.py (what `scenebake open` runs, with the
camera it adds, framing the whole animation), the scene is rendered with the Workbench engine
at its last frame twice: with the trail (the `trail` node's objects) hidden and shown. The
pixels that differ are the trail's; there must be at least --min-pixels of them (default 200)
after a plain import, --min-helper-pixels (default 50; the helper's camera frames the whole
rig, where a thin tube is a pixel wide) with the helper. A trail of lines, which Workbench does
not draw, gives none.

Exit status: 0 if every file's trail showed in every import; 1 otherwise; 2 on bad options.
"""

import argparse
import math
import os
import sys
import tempfile

# Blender 3.4's glTF importer still uses `np.bool`, which numpy 1.24 removed.
import numpy

if "bool" not in numpy.__dict__:
    numpy.bool = bool

import bpy  # noqa: E402  (must come after the numpy shim)
from mathutils import Vector  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender"))
import scenebake_import  # noqa: E402

PROG = "blender_trail_check"


def log(msg):
    print(f"{PROG}: {msg}", flush=True)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog=PROG)
    ap.add_argument("--min-pixels", type=int, default=200)
    ap.add_argument("--min-helper-pixels", type=int, default=50)
    ap.add_argument("--resolution", default="320x240")
    ap.add_argument("--save", metavar="DIR",
                    help="keep the renders with the trail shown: DIR/<stem>_plain.png, _helper.png")
    ap.add_argument("files", nargs="+")
    args = ap.parse_args(argv)
    try:
        w, h = (int(v) for v in args.resolution.lower().split("x"))
    except ValueError:
        ap.error(f"--resolution {args.resolution}: expected WxH")
    args.size = (w, h)
    return args


def trail_objects():
    """The objects of the `trail` node: its empty and the pieces under it."""
    roots = [o for o in bpy.context.scene.objects
             if o.name.split(".")[0] == "trail" and o.type == "EMPTY"]
    out = []
    for r in roots:
        out.append(r)
        out.extend(r.children_recursive)
    return out


def trail_points(objects):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    chunks = []
    for obj in objects:
        if obj.type != "MESH":
            continue
        ev = obj.evaluated_get(depsgraph)
        m = ev.matrix_world
        chunks.extend(m @ v.co for v in ev.data.vertices)
    return numpy.array([tuple(p) for p in chunks], dtype=numpy.float64)


def add_trail_camera(scene, objects, side):
    """A camera looking at the trail's bounding box along the drawing's normal (the direction
    of least spread of its vertices), from the side `side` (+1 or -1) of the drawing, the box
    filling most of the frame."""
    pts = trail_points(objects)
    if len(pts) == 0:
        raise RuntimeError("the trail has no vertices")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2
    radius = max(float(numpy.linalg.norm(hi - lo)) / 2, 1e-4)
    _, vecs = numpy.linalg.eigh(numpy.cov((pts - centre).T))
    normal = Vector(vecs[:, 0]).normalized() * side
    # Tilt a little so a perfectly flat view is not required.
    side = normal.orthogonal().normalized()
    view = (normal + 0.2 * side).normalized()
    old = bpy.data.objects.get("trail_check_camera")
    if old is not None:
        bpy.data.objects.remove(old)
    cam_data = bpy.data.cameras.new("trail_check_camera")
    cam = bpy.data.objects.new("trail_check_camera", cam_data)
    scene.collection.objects.link(cam)
    dist = radius / math.tan(min(cam_data.angle_x, cam_data.angle_y) / 2) * 1.1
    cam.location = Vector(centre) + view * dist
    cam.rotation_euler = (-view).to_track_quat("-Z", "Y").to_euler()
    cam_data.clip_start = max(dist - 2 * radius, dist * 1e-3)
    cam_data.clip_end = dist + 2 * radius
    scene.camera = cam


def render(scene, path):
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path)
    try:
        px = numpy.array(img.pixels[:], dtype=numpy.float32).reshape(-1, img.channels)[:, :3]
    finally:
        bpy.data.images.remove(img)
    return px


def trail_pixels(size, tmp, keep=None):
    """Renders the scene with the trail hidden, then shown; counts the pixels that differ."""
    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.display.shading.light = "STUDIO"
    scene.display.shading.color_type = "MATERIAL"
    if scene.world is None:
        scene.world = bpy.data.worlds.new("trail_check_world")
    scene.world.color = (0.8, 0.8, 0.8)  # paper, so the dark ink stands out
    objects = trail_objects()
    for obj in objects:
        obj.hide_render = True
    without = render(scene, os.path.join(tmp, "without.png"))
    for obj in objects:
        obj.hide_render = False
    with_trail = render(scene, keep or os.path.join(tmp, "with.png"))
    return int((numpy.abs(with_trail - without).max(axis=1) > 0.02).sum())


def check(path, helper, args, tmp):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if helper:
        info = scenebake_import.import_bake(path, camera=True)
        if info["camera"] is None:
            raise RuntimeError("the helper added no camera")
    else:
        result = bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))
        if "FINISHED" not in result:
            raise RuntimeError(f"import did not finish: {sorted(result)}")
        # Blender 3.4 leaves frames 1-250 whatever the animations span: fit them, as a user would.
        if bpy.data.actions:
            starts, ends = zip(*(a.frame_range for a in bpy.data.actions))
            scene.frame_start = math.floor(min(starts) + 1e-3)
            scene.frame_end = max(math.ceil(max(ends) - 1e-3), scene.frame_start)
    scene.frame_set(scene.frame_end)
    objects = trail_objects()
    meshes = [o for o in objects if o.type == "MESH"]
    if not meshes:
        raise RuntimeError("no trail mesh objects were imported")
    faces = sum(len(o.data.polygons) for o in meshes)
    keep = None
    if args.save:
        os.makedirs(args.save, exist_ok=True)
        stem = os.path.splitext(os.path.basename(path))[0]
        keep = os.path.abspath(os.path.join(args.save, f"{stem}_{'helper' if helper else 'plain'}.png"))
    if helper:
        return trail_pixels(args.size, tmp, keep), len(meshes), faces, scene.frame_end
    # Seen from both sides of the drawing (the pen hand may hide it from one): the larger count.
    best = 0
    for side in (1.0, -1.0):
        add_trail_camera(scene, objects, side)
        pixels = trail_pixels(args.size, tmp)
        if pixels > best:
            best = pixels
            if keep:
                trail_pixels(args.size, tmp, keep)
    return best, len(meshes), faces, scene.frame_end


def main():
    args = parse_args()
    log(f"Blender {bpy.app.version_string}, {len(args.files)} file(s), "
        f"{args.size[0]}x{args.size[1]}, at least {args.min_pixels} trail pixels "
        f"({args.min_helper_pixels} with the helper's camera)")
    bad = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in args.files:
            for helper in (False, True):
                how = "helper" if helper else "plain import"
                try:
                    pixels, pieces, faces, frame = check(path, helper, args, tmp)
                except Exception as e:  # noqa: BLE001 - report and go on
                    log(f"FAIL {path} ({how}): {e}")
                    bad.append(f"{path} ({how})")
                    continue
                ok = pixels >= (args.min_helper_pixels if helper else args.min_pixels)
                log(f"{'ok' if ok else 'FAIL'} {path} ({how}): {pixels} trail pixels at frame "
                    f"{frame} ({pieces} pieces, {faces} faces)")
                if not ok:
                    bad.append(f"{path} ({how})")
    if bad:
        log("failed: " + ", ".join(bad))
        raise SystemExit(1)
    log("every trail rendered")


if __name__ == "__main__":
    main()
