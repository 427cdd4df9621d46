"""Blender cloth baseline: drape an OBJ garment with Blender's own cloth solver and measure it.

Run inside Blender 3.4 (Debian's `blender`), with a clean environment:

    env -u PYTHONPATH -u PYTHONHOME PATH=/usr/sbin:/usr/bin:/sbin:/bin \\
        blender -b --factory-startup --python-exit-code 1 --python benches/blender_cloth.py -- \\
        MESH.obj [--pin-box X0,Y0,Z0,X1,Y1,Z1] --frames N --out result.json \\
        [--translate X,Y,Z] [--collider-sphere X,Y,Z,R] [--collider-obj FILE.obj]
        [--collider-sequence 'PATTERN%d.obj' [--collider-start N] [--collider-fps F]]
        [--mass KG | --mass-per-area D] [--quality STEPS] [--tension K] [--fps F]
        [--self-collision [--self-distance M]] [--snapshots 0,5,10,20,30] [--pc2-out cloth.pc2]

What it does:
- imports MESH.obj with Blender's OBJ importer, with forward axis +Y and up axis +Z, which keeps
  the file's coordinates unchanged (the default, forward -Z / up Y, would turn the Y-up file into
  Blender's Z-up frame); scene gravity is then set to (0, -9.81, 0) so that the file's -Y is down.
  The imported vertex positions are compared with the file's `v` lines, one by one: the vertex
  order and coordinates must match the file (exit status 1 if not), so every position written
  below is in the OBJ's frame and vertex order;
- --translate X,Y,Z then moves the garment by that offset (metres) before anything else; pins,
  colliders and every position written are in the moved coordinates (as scenebake's
  --translate);
- pins every vertex inside the --pin-box (bounds inclusive, the OBJ's coordinates, after
  --translate: the same test as scenebake's `--pin box:`) through a vertex group used as the
  cloth's pin group;
- adds a cloth modifier with Blender's default settings (quality 5 steps per frame, vertex mass
  0.3 kg, tension and compression 15, shear 5, bending 0.5, tension damping 5, air damping 1),
  at 30 frames per second, self-collision off, object collision on; --mass or --mass-per-area
  (kg/m², spread evenly over the vertices, as Blender's vertex mass is one value for all) and
  --quality/--tension override them;
- optional static colliders (collision modifier, default settings unless --collider-thickness):
  a UV sphere (64 x 32 segments) and/or an OBJ imported the same way (its objects joined into
  one; its bounding box checked against the file's); --collision-distance sets the cloth's
  minimum distance to them. The garment OBJ must hold one object (`o`), as its vertex order
  is kept;
- optional moving collider, --collider-sequence PATTERN: a printf-style pattern with one %d
  (e.g. bodies/kick/shell%d.obj), numbered from --collider-start (default 0). That frame is
  imported as above (its vertex count and order checked against the file's `v` lines); the
  following frames' `v` lines are read until a file is missing or the bake's time span is
  covered (--frames + 1 body frames when --collider-fps equals --fps); all must have the same
  vertex count. They are written to a PC2 file in a temporary directory, read by a Mesh Cache
  modifier (linear interpolation) followed by a collision modifier (same settings as
  --collider-obj). The body runs at --collider-fps frames per second (default --fps): Blender
  frame f shows body time (f - 1) / --fps, i.e. file frame start + (f - 1) * collider_fps / fps,
  interpolated linearly between files and held at the last one after it. (The Mesh Cache's
  time mode is FRAME with frame_scale = collider_fps / fps and frame_start = frame_scale: it
  plays sample frame_scale * f - frame_start and ignores the PC2 header's start and rate.)
  The mapping is checked before the bake by evaluating the body at a few Blender frames
  (exit status 1 if off by more than 1e-5 m from the files), and again at every frame read;
- bakes the cloth cache with bpy.ops.ptcache.bake_all (what the Bake button does), timing the whole
  bake and each frame (a frame_change_post handler stamps the clock as each frame is done), then
  reads the cached frames (Blender frame 1 is the rest state, our frame 0; our frame k is Blender
  frame k+1). With --step it instead calls scene.frame_set frame by frame, which simulates the
  same frames (identical positions) and times each call;
- writes JSON: the settings, the import check, the machine load, the wall time of the bake and
  per frame, and per frame the lowest vertex height (min y), the hem drop (min y at frame 0 minus
  min y now), the mean drop of the hem vertices (those within 1 mm of the lowest height at frame
  0), the 1-minute load average, the largest edge stretch and compression (edge length over rest
  length, minus 1; edges from the OBJ's faces, rest = frame 0), how many edges are stretched or
  shrunk by more than 10 %, and the vertex positions at the snapshot frames;
- with --pc2-out FILE, writes the cloth's positions (OBJ vertex order, the moved frame) at every
  frame 0..--frames (Blender frames 1..N+1) as a PC2 point cache: little-endian, header
  b"POINTCACHE2\\0", version 1, points, start frame 0.0, sample rate 1.0, samples N + 1, then
  float32 x, y, z per point per sample.

Exit status: 0 on success, 1 on a failure (named on stderr), 2 on bad options.
"""

import argparse
import array
import json
import math
import os
import shutil
import struct
import sys
import tempfile
import time

import bpy


def parse_floats(text, n, what):
    try:
        vals = [float(w) for w in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != n:
        raise SystemExit(f"blender_cloth.py: {what} needs {n} comma-separated numbers, got `{text}`")
    return vals


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    # Values such as -0.2,0.99,... start with '-': glue them to their option for argparse.
    valued = {"--pin-box", "--collider-sphere", "--translate"}
    glued = []
    for w in argv:
        if glued and glued[-1] in valued:
            glued[-1] = glued[-1] + "=" + w
        else:
            glued.append(w)
    argv = glued
    ap = argparse.ArgumentParser(prog="blender_cloth.py", description="Blender cloth baseline")
    ap.add_argument("mesh", help="garment OBJ (metres, Y up)")
    ap.add_argument("--pin-box", default=None, metavar="X0,Y0,Z0,X1,Y1,Z1",
                    help="pin the vertices inside this box (default: no pins, e.g. a dress that "
                         "hangs on a collider)")
    ap.add_argument("--frames", type=int, required=True, help="frames to simulate after frame 0")
    ap.add_argument("--out", required=True, help="result JSON")
    ap.add_argument("--collider-sphere", action="append", default=[], metavar="X,Y,Z,R")
    ap.add_argument("--collider-obj", action="append", default=[], metavar="FILE.obj")
    ap.add_argument("--collider-sequence", default=None, metavar="PATTERN",
                    help="moving collider: OBJ frames named by a printf-style pattern with %%d")
    ap.add_argument("--collider-start", type=int, default=0, metavar="N",
                    help="number of the sequence's first frame [0]")
    ap.add_argument("--collider-fps", type=float, default=None, metavar="F",
                    help="frames per second of the collider sequence [--fps]")
    ap.add_argument("--translate", default=None, metavar="X,Y,Z",
                    help="move the garment by this offset (metres) after import")
    ap.add_argument("--pc2-out", default=None, metavar="FILE",
                    help="write the cloth's positions at every frame 0..--frames as a PC2 file")
    ap.add_argument("--fps", type=int, default=30)
    ap.add_argument("--quality", type=int, default=None, help="steps per frame [Blender: 5]")
    ap.add_argument("--tension", type=float, default=None,
                    help="tension and compression stiffness [Blender: 15]")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--mass", type=float, default=None, help="vertex mass in kg [Blender: 0.3]")
    g.add_argument("--mass-per-area", type=float, default=None, metavar="KG_PER_M2",
                   help="areal density; vertex mass = density * area / vertices")
    ap.add_argument("--self-collision", action="store_true")
    ap.add_argument("--self-distance", type=float, default=None, metavar="M",
                    help="self-collision distance [Blender: 0.015 m]")
    ap.add_argument("--collision-distance", type=float, default=None, metavar="M",
                    help="cloth's minimum distance to colliders [Blender: 0.015 m]")
    ap.add_argument("--collider-thickness", type=float, default=None, metavar="M",
                    help="colliders' outer thickness [Blender: 0.02 m]")
    ap.add_argument("--step", action="store_true",
                    help="simulate by scene.frame_set frame by frame, timing each call (default: "
                         "bpy.ops.ptcache.bake_all, then read the cached frames)")
    ap.add_argument("--snapshots", default=None,
                    help="frames whose positions are written [0,5,10,20,30,... up to --frames]")
    try:
        a = ap.parse_args(argv)
    except SystemExit as e:
        sys.exit(2 if e.code else 0)
    if a.frames < 1:
        print("blender_cloth.py: --frames must be at least 1", file=sys.stderr)
        sys.exit(2)
    if a.pin_box is not None:
        a.pin_box = parse_floats(a.pin_box, 6, "--pin-box")
    a.collider_sphere = [parse_floats(s, 4, "--collider-sphere") for s in a.collider_sphere]
    if a.translate is not None:
        a.translate = parse_floats(a.translate, 3, "--translate")
    if a.collider_sequence is not None:
        try:
            a.collider_sequence % a.collider_start
        except (TypeError, ValueError):
            print(f"blender_cloth.py: --collider-sequence needs one %d in its pattern, got "
                  f"`{a.collider_sequence}`", file=sys.stderr)
            sys.exit(2)
    if a.collider_fps is None:
        a.collider_fps = float(a.fps)
    if not a.collider_fps > 0:
        print("blender_cloth.py: --collider-fps must be positive", file=sys.stderr)
        sys.exit(2)
    if a.snapshots is None:
        snaps = [0, 5] + list(range(10, a.frames + 1, 10))
    else:
        snaps = [int(w) for w in a.snapshots.split(",")]
    a.snapshots = sorted({f for f in snaps if 0 <= f <= a.frames} | {0, a.frames})
    return a


def read_obj(path):
    """Positions and triangles (fanned) from an OBJ's `v` and `f` lines, zero-based."""
    verts, tris = [], []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                verts.append(tuple(float(w) for w in p[1:4]))
            elif p[0] == "f":
                idx = []
                for w in p[1:]:
                    i = int(w.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                for k in range(1, len(idx) - 1):
                    tris.append((idx[0], idx[k], idx[k + 1]))
    if not verts or not tris:
        raise SystemExit(f"blender_cloth.py: {path}: no vertices or no faces")
    return verts, tris


def import_obj(path, join=False):
    """Import with the identity axis mapping; return the new mesh object.

    The importer makes one object per `o` in the file; with join=True (colliders) they are
    joined into one, otherwise (the garment, whose vertex order matters) there must be one.
    """
    before = set(bpy.data.objects)
    # forward +Y, up +Z: Blender's own frame, so the file's (x, y, z) is kept as is.
    bpy.ops.wm.obj_import(filepath=path, forward_axis="Y", up_axis="Z")
    new = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    if not new or (len(new) > 1 and not join):
        raise SystemExit(f"blender_cloth.py: {path}: expected one mesh object, the importer made {len(new)}")
    for o in new:
        # Bake any object transform into the mesh (the importer leaves it at identity here).
        o.data.transform(o.matrix_world)
        o.matrix_world.identity()
    obj = new[0]
    if len(new) > 1:
        with bpy.context.temp_override(active_object=obj, selected_editable_objects=new):
            bpy.ops.object.join()
    return obj


def write_pc2(path, frames, start=0.0, rate=1.0):
    """Write `frames` (a list of equally long lists of (x, y, z)) as a little-endian PC2 file."""
    points = len(frames[0])
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<12siiffi", b"POINTCACHE2\0", 1, points, start, rate, len(frames)))
        for pos in frames:
            if len(pos) != points:
                raise SystemExit(f"blender_cloth.py: {path}: a sample has {len(pos)} points, not {points}")
            buf = array.array("f", [c for p in pos for c in p])
            if sys.byteorder != "little":
                buf.byteswap()
            f.write(buf.tobytes())
    os.replace(tmp, path)


def sample_sequence(seq, s):
    """Body positions at (fractional) sample s of `seq`: linear between samples, clamped."""
    s = min(max(s, 0.0), len(seq) - 1.0)
    i = int(math.floor(s))
    t = s - i
    if t < 1e-9 or i + 1 >= len(seq):
        return seq[i]
    return [tuple(p + t * (q - p) for p, q in zip(u, v)) for u, v in zip(seq[i], seq[i + 1])]


def setup_collider_sequence(a, scene, tmpdir):
    """The moving collider of --collider-sequence: frame `start` imported, every frame in a PC2
    file read by a Mesh Cache modifier, then a collision modifier; returns (object, frames read,
    info for the JSON)."""
    first = a.collider_sequence % a.collider_start
    if not os.path.exists(first):
        raise SystemExit(f"blender_cloth.py: --collider-sequence: first frame {first} does not exist")
    ratio = a.collider_fps / a.fps  # body frames per cloth frame
    # body frames needed to cover Blender frames 1..N+1 (== --frames + 1 at equal rates)
    needed = math.ceil(a.frames * ratio - 1e-9) + 1
    seq = []
    files = []
    n = a.collider_start
    while len(seq) < needed:
        path = a.collider_sequence % n
        if not os.path.exists(path):
            break
        verts = read_obj(path)[0]
        if seq and len(verts) != len(seq[0]):
            raise SystemExit(f"blender_cloth.py: --collider-sequence: {path} has {len(verts)} vertices, "
                             f"{files[0]} has {len(seq[0])}")
        seq.append(verts)
        files.append(path)
        n += 1
    body = import_obj(first, join=True)
    body.name = "collider_sequence"
    imported = [tuple(v.co) for v in body.data.vertices]
    if len(imported) != len(seq[0]):
        raise SystemExit(
            f"blender_cloth.py: {first}: the file has {len(seq[0])} vertices, Blender imported "
            f"{len(imported)} (unused vertices dropped, or several objects joined?); the body's point "
            f"cache could not be matched to its vertex order")
    dev = max(max(abs(p - q) for p, q in zip(u, v)) for u, v in zip(imported, seq[0]))
    if dev > 1e-5:
        raise SystemExit(f"blender_cloth.py: {first}: imported vertex positions differ from the file's "
                         f"(largest difference {dev:.3g} m): axis conversion or vertex order changed")
    cache = os.path.join(tmpdir, "collider_sequence.pc2")
    write_pc2(cache, seq)
    mc = body.modifiers.new("MeshCache", "MESH_CACHE")
    mc.cache_format = "PC2"
    mc.filepath = cache
    mc.deform_mode = "OVERWRITE"
    mc.interpolation = "LINEAR"
    mc.forward_axis = "POS_Y"  # identity axes
    mc.up_axis = "POS_Z"
    mc.play_mode = "SCENE"
    # FRAME mode: the sample read at Blender frame f is frame_scale * f - frame_start (0-based,
    # linear between samples, clamped to the file); the PC2 header's start and rate are ignored.
    mc.time_mode = "FRAME"
    mc.frame_scale = ratio
    mc.frame_start = ratio  # Blender frame 1 -> sample 0
    body.modifiers.new("Collision", "COLLISION")  # after the Mesh Cache: the deformed mesh collides
    if a.collider_thickness is not None:
        body.collision.thickness_outer = a.collider_thickness
    if [m.type for m in body.modifiers] != ["MESH_CACHE", "COLLISION"]:
        raise SystemExit(f"blender_cloth.py: collider modifier stack is {[m.type for m in body.modifiers]}")

    # --- the frame mapping: evaluate the body at a few Blender frames, compare with the files
    last = a.frames + 1
    # whole frames, plus Blender frame 1.5 (a sub-frame: tests the linear interpolation)
    check_frames = sorted({1, 1.5, 2, min(3, last), (last + 1) // 2 + 1, last})
    checks = []
    for f in check_frames:
        scene.frame_set(int(f), subframe=f - int(f))
        got = positions(body, bpy.context.evaluated_depsgraph_get())
        s = (f - 1) * ratio
        want = sample_sequence(seq, s)
        if len(got) != len(want):
            raise SystemExit(f"blender_cloth.py: --collider-sequence: Blender frame {f}: the body has "
                             f"{len(got)} vertices, the cache {len(want)} (Mesh Cache not applied?)")
        d = max(max(abs(p - q) for p, q in zip(u, v)) for u, v in zip(got, want))
        # how far the body moves over that stretch, to show the check can tell frames apart
        moved = max(max(abs(p - q) for p, q in zip(u, v)) for u, v in zip(seq[0], want))
        checks.append({"blender_frame": f, "body_sample": s, "max_abs_difference_m": d,
                       "max_motion_from_sample_0_m": moved})
        if d > 1e-5:
            raise SystemExit(f"blender_cloth.py: --collider-sequence: at Blender frame {f} the body should "
                             f"show sample {s:.4f} (file frame {a.collider_start + s:.4f}) but differs from "
                             f"it by {d:.3g} m: the Mesh Cache's time mapping is off")
    scene.frame_set(1)
    span = (len(seq) - 1) / ratio + 1  # last Blender frame the body still moves at
    if span < last:
        print(f"blender_cloth.py: warning: --collider-sequence has {len(seq)} frames, the body holds its "
              f"last pose after Blender frame {span:.2f} (of {last})", file=sys.stderr)
    info = {
        "sequence": a.collider_sequence, "start": a.collider_start, "files_read": len(seq),
        "first_file": files[0], "last_file": files[-1], "vertices": len(imported),
        "import_max_abs_difference_m": dev, "collider_fps": a.collider_fps,
        "mesh_cache": {"cache_format": mc.cache_format, "time_mode": mc.time_mode,
                       "play_mode": mc.play_mode, "frame_scale": mc.frame_scale,
                       "frame_start": mc.frame_start, "interpolation": mc.interpolation},
        "modifiers": [m.type for m in body.modifiers],
        "body_moves_until_blender_frame": span,
        "mapping_check": checks,
        "thickness_outer": body.collision.thickness_outer,
    }
    return body, seq, info


def bounds(points):
    return [[min(p[k] for p in points) for k in range(3)], [max(p[k] for p in points) for k in range(3)]]


def positions(obj, depsgraph):
    ev = obj.evaluated_get(depsgraph)
    me = ev.data
    flat = [0.0] * (3 * len(me.vertices))
    me.vertices.foreach_get("co", flat)
    m = ev.matrix_world
    if m != m.Identity(4):
        out = []
        for i in range(0, len(flat), 3):
            v = m @ __import__("mathutils").Vector(flat[i : i + 3])
            out.append((v.x, v.y, v.z))
        return out
    return [tuple(flat[i : i + 3]) for i in range(0, len(flat), 3)]


def cpu_jiffies():
    """(busy, total) clock ticks of all cores from /proc/stat, or None."""
    try:
        with open("/proc/stat") as f:
            vals = [int(w) for w in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    idle = vals[3] + (vals[4] if len(vals) > 4 else 0)
    return sum(vals) - idle, sum(vals)


def busy_cores(start, wall):
    """Average number of busy cores (every process) since `start`, over `wall` seconds."""
    end = cpu_jiffies()
    if start is None or end is None or wall <= 0:
        return None
    hz = os.sysconf("SC_CLK_TCK")
    return (end[0] - start[0]) / hz / wall


def loadavg():
    try:
        return list(os.getloadavg())
    except OSError:
        return None


def main():
    a = parse_args()
    tmpdir = tempfile.mkdtemp(prefix="blender_cloth_")
    try:
        run(a, tmpdir)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)


def run(a, tmpdir):
    file_verts, tris = read_obj(a.mesh)
    load_before = loadavg()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = a.fps
    scene.render.fps_base = 1.0
    scene.use_gravity = True
    scene.gravity = (0.0, -9.81, 0.0)  # the OBJ's -Y is down
    scene.frame_start = 1
    scene.frame_end = a.frames + 1

    obj = import_obj(a.mesh)
    me = obj.data
    # --- import check: coordinates and vertex order as in the file
    imported = [tuple(v.co) for v in me.vertices]
    if len(imported) != len(file_verts):
        raise SystemExit(
            f"blender_cloth.py: {a.mesh}: the file has {len(file_verts)} vertices, Blender imported "
            f"{len(imported)} (unused vertices dropped?); positions could not be matched to file order")
    dev = max(max(abs(p - q) for p, q in zip(u, v)) for u, v in zip(imported, file_verts))
    if dev > 1e-5:
        raise SystemExit(f"blender_cloth.py: {a.mesh}: imported vertex positions differ from the file's "
                         f"(largest difference {dev:.3g} m): axis conversion or vertex order changed")
    import_check = {
        "vertices": len(imported),
        "max_abs_difference_m": dev,
        "vertex_0_file": list(file_verts[0]),
        "vertex_0_blender": list(imported[0]),
        "order": "file order (every vertex compared)",
    }
    if a.translate is not None:
        # move the garment (mesh data, so the object stays at identity) and the reference positions
        import mathutils
        me.transform(mathutils.Matrix.Translation(a.translate))
        me.update()
        tx, ty, tz = a.translate
        file_verts = [(x + tx, y + ty, z + tz) for x, y, z in file_verts]
        import_check["translate"] = list(a.translate)

    # --- moving collider (set up and checked before the cloth exists, so that evaluating the
    # scene at other frames for the check simulates nothing)
    seq_body = seq_frames = seq_info = None
    if a.collider_sequence is not None:
        seq_body, seq_frames, seq_info = setup_collider_sequence(a, scene, tmpdir)

    # --- pins
    pinned = []
    if a.pin_box is not None:
        lo = [min(a.pin_box[i], a.pin_box[i + 3]) for i in range(3)]
        hi = [max(a.pin_box[i], a.pin_box[i + 3]) for i in range(3)]
        pinned = [i for i, p in enumerate(file_verts) if all(lo[k] <= p[k] <= hi[k] for k in range(3))]
        if not pinned:
            raise SystemExit(f"blender_cloth.py: --pin-box {a.pin_box} selects no vertex of {a.mesh}")
        group = obj.vertex_groups.new(name="pin")
        group.add(pinned, 1.0, "REPLACE")

    # --- cloth
    area = 0.0
    for i, j, k in tris:
        p, q, r = file_verts[i], file_verts[j], file_verts[k]
        u = [q[d] - p[d] for d in range(3)]
        w = [r[d] - p[d] for d in range(3)]
        c = (u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0])
        area += 0.5 * math.sqrt(c[0] ** 2 + c[1] ** 2 + c[2] ** 2)
    mod = obj.modifiers.new("Cloth", "CLOTH")
    cs = mod.settings
    if a.quality is not None:
        cs.quality = a.quality
    if a.tension is not None:
        cs.tension_stiffness = a.tension
        cs.compression_stiffness = a.tension
    if a.mass is not None:
        cs.mass = a.mass
    elif a.mass_per_area is not None:
        cs.mass = a.mass_per_area * area / len(file_verts)
    if pinned:
        cs.vertex_group_mass = "pin"
    mod.collision_settings.use_self_collision = a.self_collision
    if a.collision_distance is not None:
        mod.collision_settings.distance_min = a.collision_distance
    if a.self_distance is not None:
        mod.collision_settings.self_distance_min = a.self_distance
    mod.point_cache.frame_start = 1
    mod.point_cache.frame_end = a.frames + 1
    settings = {
        k: getattr(cs, k)
        for k in ("quality", "mass", "tension_stiffness", "compression_stiffness", "shear_stiffness",
                  "bending_stiffness", "tension_damping", "compression_damping", "shear_damping",
                  "bending_damping", "air_damping", "pin_stiffness", "time_scale")
    }
    settings["bending_model"] = cs.bending_model
    settings["use_collision"] = mod.collision_settings.use_collision
    settings["use_self_collision"] = mod.collision_settings.use_self_collision
    settings["collision_distance_min"] = mod.collision_settings.distance_min
    settings["collision_quality"] = mod.collision_settings.collision_quality
    settings["self_distance_min"] = mod.collision_settings.self_distance_min
    settings["fps"] = a.fps
    settings["translate"] = a.translate
    settings["gravity"] = list(scene.gravity)
    settings["total_mass_kg"] = cs.mass * len(file_verts)
    settings["mass_per_area_kg_m2"] = cs.mass * len(file_verts) / area

    # --- colliders
    colliders = []
    for x, y, z, r in a.collider_sphere:
        bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=r, location=(x, y, z))
        s = bpy.context.active_object
        s.modifiers.new("Collision", "COLLISION")
        if a.collider_thickness is not None:
            s.collision.thickness_outer = a.collider_thickness
        colliders.append({"sphere": [x, y, z, r], "thickness_outer": s.collision.thickness_outer})
    for path in a.collider_obj:
        c = import_obj(path, join=True)
        c.modifiers.new("Collision", "COLLISION")
        if a.collider_thickness is not None:
            c.collision.thickness_outer = a.collider_thickness
        # The collider must sit where the file puts it: compare bounding boxes.
        file_b = bounds(read_obj(path)[0])
        blender_b = bounds([tuple(v.co) for v in c.data.vertices])
        dev = max(abs(x - y) for u, v in zip(file_b, blender_b) for x, y in zip(u, v))
        if dev > 1e-5:
            raise SystemExit(f"blender_cloth.py: {path}: the imported collider's bounds {blender_b} "
                             f"differ from the file's {file_b}")
        colliders.append({"obj": path, "vertices": len(c.data.vertices), "bounds": blender_b,
                          "bounds_max_abs_difference_m": dev,
                          "thickness_outer": c.collision.thickness_outer})

    if seq_info is not None:
        colliders.append(seq_info)

    # --- edges (from the OBJ's faces) and their rest lengths (frame 0)
    edges = sorted({(min(i, j), max(i, j)) for t in tris for i, j in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))})
    rest = [math.dist(file_verts[i], file_verts[j]) for i, j in edges]

    def measure(pos):
        ys = [p[1] for p in pos]
        stretch = compress = 0.0
        over = 0
        for (i, j), r0 in zip(edges, rest):
            s = math.dist(pos[i], pos[j]) / r0 - 1.0
            if s > stretch:
                stretch = s
            if s < compress:
                compress = s
            if abs(s) > 0.1:
                over += 1
        return min(ys), stretch, compress, over

    # --- simulate, frame by frame (Blender frame f + 1 is our frame f)
    frames = []
    snapshots = {}
    step_times = []
    step_cpu = []
    bake_op = None
    scene.frame_set(1)
    cpu_others_start = cpu_jiffies()
    if not a.step:
        stamps = []

        def stamp(scn, *_):
            stamps.append((scn.frame_current, time.perf_counter(), time.process_time(), loadavg()))

        bpy.app.handlers.frame_change_post.append(stamp)
        c0, t0 = time.process_time(), time.perf_counter()
        with bpy.context.temp_override(scene=scene):
            bpy.ops.ptcache.bake_all(bake=True)
        bake_op = {"wall_seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0}
        bpy.app.handlers.frame_change_post.remove(stamp)
        # frame_change_post runs once per baked frame (Blender frames 2..N+1): time between stamps
        marks = [(0.0, 0.0)] + [(w - t0, c - c0) for f, w, c, _ in stamps if 2 <= f <= a.frames + 1]
        bake_load = {f: la[0] for f, _, _, la in stamps if la}
        if len(marks) == a.frames + 1:
            bake_op["per_frame_seconds"] = [marks[k + 1][0] - marks[k][0] for k in range(a.frames)]
            bake_op["per_frame_cpu_seconds"] = [marks[k + 1][1] - marks[k][1] for k in range(a.frames)]
        else:
            bake_op["per_frame_seconds"] = bake_op["per_frame_cpu_seconds"] = None
        bake_op["frame_change_stamps"] = [f for f, _, _, _ in stamps]
        bake_op["seconds_per_frame"] = bake_op["wall_seconds"] / a.frames
        bake_op["busy_cores"] = busy_cores(cpu_others_start, bake_op["wall_seconds"])
        if not mod.point_cache.is_baked:
            raise SystemExit("blender_cloth.py: bpy.ops.ptcache.bake_all did not bake the cloth cache")
    t_all = time.perf_counter()
    cpu_loop_start = cpu_jiffies()
    all_pos = []
    body_dev = []
    for f in range(0, a.frames + 1):
        c0, t0 = time.process_time(), time.perf_counter()
        scene.frame_set(f + 1)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        pos = positions(obj, depsgraph)
        t1 = time.perf_counter()
        if f > 0:
            step_times.append(t1 - t0)
            step_cpu.append(time.process_time() - c0)
        if len(pos) != len(file_verts):
            raise SystemExit(f"blender_cloth.py: frame {f}: cloth has {len(pos)} vertices, file {len(file_verts)}")
        if f == 0:
            d0 = max(max(abs(p - q) for p, q in zip(u, v)) for u, v in zip(pos, file_verts))
            import_check["frame_0_max_abs_difference_m"] = d0
        min_y, stretch, compress, over = measure(pos)
        if f == 0:
            min_y0 = min_y
            # the hem: the vertices within 1 mm of the lowest height at frame 0
            hem = [i for i, p in enumerate(pos) if p[1] <= min_y + 1e-3]
            hem_y0 = sum(pos[i][1] for i in hem) / len(hem)
        hem_mean_drop = hem_y0 - sum(pos[i][1] for i in hem) / len(hem)
        pin_dev = max((math.dist(pos[i], file_verts[i]) for i in pinned), default=0.0)
        frames.append({
            "frame": f,
            "seconds": None if f == 0 else t1 - t0,
            "min_y": min_y,
            "hem_drop_m": min_y0 - min_y,
            "hem_mean_drop_m": hem_mean_drop,
            "max_edge_stretch": stretch,
            "max_edge_compression": compress,
            "edges_beyond_10_percent": over,
            "max_pin_displacement_m": pin_dev,
            # the 1-minute load average when this frame was simulated
            "loadavg_1min": bake_load.get(f + 1) if bake_op else (loadavg() or [None])[0],
        })
        if f in a.snapshots:
            snapshots[str(f)] = [[round(c, 6) for c in p] for p in pos]
        if a.pc2_out is not None:
            all_pos.append(pos)
        if seq_body is not None:
            # (after the frame's timing) the body as the cloth saw it, against the files
            got = positions(seq_body, depsgraph)
            want = sample_sequence(seq_frames, f * a.collider_fps / a.fps)
            d = max(max(abs(p - q) for p, q in zip(u, v)) for u, v in zip(got, want))
            body_dev.append(d)
            frames[-1]["body_max_abs_difference_m"] = d
        print(f"frame {f:3d}: {0 if f == 0 else t1 - t0:7.3f} s  min y {min_y:.4f}  drop {min_y0 - min_y:.4f} m  "
              f"stretch {100 * stretch:6.2f} %  compression {100 * compress:6.2f} %", flush=True)
    wall = time.perf_counter() - t_all
    loop_busy = busy_cores(cpu_loop_start, wall)
    if seq_info is not None:
        seq_info["max_abs_difference_every_frame_m"] = max(body_dev)
        if max(body_dev) > 1e-5:
            raise SystemExit(f"blender_cloth.py: --collider-sequence: the body differed from its files by "
                             f"{max(body_dev):.3g} m at frame {body_dev.index(max(body_dev))}")
    if a.pc2_out is not None:
        write_pc2(a.pc2_out, all_pos, start=0.0, rate=1.0)

    finite = all(math.isfinite(c) for p in pos for c in p)
    step_sorted = sorted(step_times)
    if bake_op:
        timing = {
            "mode": "bpy.ops.ptcache.bake_all, then cached frames read",
            "seconds_per_frame": bake_op["seconds_per_frame"],
            "cpu_seconds_per_frame": bake_op["cpu_seconds"] / a.frames,
            "bake_wall_seconds": bake_op["wall_seconds"],
            "bake_cpu_seconds": bake_op["cpu_seconds"],
            "per_frame_seconds": bake_op["per_frame_seconds"],
            "per_frame_cpu_seconds": bake_op["per_frame_cpu_seconds"],
            "busy_cores": bake_op["busy_cores"],
            "cache_read_seconds": step_times,
        }
    else:
        timing = {
            "mode": "scene.frame_set per frame (one cloth frame each, filling the cache as a bake does)",
            "seconds_per_frame": sum(step_times) / len(step_times),
            "cpu_seconds_per_frame": sum(step_cpu) / len(step_cpu),
            "bake_wall_seconds": sum(step_times),
            "bake_cpu_seconds": sum(step_cpu),
            "median_seconds_per_frame": step_sorted[len(step_sorted) // 2],
            "min_seconds_per_frame": step_sorted[0],
            "max_seconds_per_frame": step_sorted[-1],
            "per_frame_seconds": step_times,
            "per_frame_cpu_seconds": step_cpu,
            "busy_cores": loop_busy,
        }
    timing["note"] = ("wall = elapsed time (includes waiting for the CPU on a loaded machine); cpu = "
                      "process time of all of Blender's threads; busy_cores = how many of the "
                      "machine's cores were busy (all processes, from /proc/stat) during the timed "
                      "part, of machine.cpus. With --step, frame times include reading the "
                      "evaluated positions (a few ms).")
    timing["loop_wall_seconds"] = wall
    result = {
        "tool": "benches/blender_cloth.py",
        "blender": bpy.app.version_string,
        "mesh": a.mesh,
        "vertices": len(file_verts),
        "triangles": len(tris),
        "edges": len(edges),
        "area_m2": area,
        "pin_box": a.pin_box,
        "pinned_vertices": len(pinned),
        "hem_vertices": len(hem),
        "frames": a.frames,
        "settings": settings,
        "colliders": colliders,
        "import_check": import_check,
        "machine": {"cpus": os.cpu_count(), "loadavg_before": load_before, "loadavg_after": loadavg(),
                    "threads": bpy.context.scene.render.threads},
        "timing": timing,
        "finite": finite,
        "per_frame": frames,
        "positions": snapshots,
        "pc2_out": a.pc2_out,
    }
    tmp = a.out + ".tmp"
    with open(tmp, "w") as f:
        json.dump(result, f)
    os.replace(tmp, a.out)
    t = result["timing"]
    print(f"{a.mesh}: {len(file_verts)} v, {len(pinned)} pinned, {a.frames} frames: "
          f"{t['seconds_per_frame']:.3f} s/frame wall, {t['cpu_seconds_per_frame']:.3f} s/frame cpu, "
          f"hem drop {frames[min(5, a.frames)]['hem_drop_m']:.4f} m at frame {min(5, a.frames)}, "
          f"{frames[min(10, a.frames)]['hem_drop_m']:.4f} m at frame {min(10, a.frames)}; "
          f"max stretch {100 * max(fr['max_edge_stretch'] for fr in frames):.2f} %; wrote {a.out}")
    if not finite:
        print("blender_cloth.py: the simulation produced non-finite positions", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    try:
        main()
    except SystemExit as e:
        if isinstance(e.code, str):
            print(e.code, file=sys.stderr)
            sys.exit(1)
        raise
