"""Check that Blender plays a compact cache at the same positions as a reference cache.

Run inside Blender (3.4 from Debian):

    env -u PYTHONPATH -u PYTHONHOME PATH=/usr/sbin:/usr/bin:/sbin:/bin blender -b \
        --factory-startup --python-exit-code 1 --python scripts/blender_positions.py -- \
        COMPACT.glb REFERENCE.glb [--tolerance M] [--every N]

REFERENCE is a full cache (one morph target per frame, float deltas, as `scenebake cloth`
writes without --basis). It is decoded here with numpy, independently of Blender and of
scenebake: frame k is base + delta_k. COMPACT (e.g. --basis auto --quantize auto) is imported
with Blender's glTF importer, and at every N-th frame (default every frame) the evaluated mesh
(shape keys blended by the imported weight animation, object transform applied, converted back
from Blender's Z-up to glTF's Y-up) is compared vertex by vertex with the reference frame.

Prints the largest distance per checked frame and overall; exit status 1 if it exceeds the
tolerance (default 0.001 m).
"""

import json
import struct
import sys

import numpy

if "bool" not in numpy.__dict__:
    numpy.bool = bool

import bpy  # noqa: E402

COMPONENT = {5120: ("b", 127.0), 5121: ("B", 255.0), 5122: ("h", 32767.0),
             5123: ("H", 65535.0), 5125: ("I", None), 5126: ("f", None)}


def read_glb(path):
    data = open(path, "rb").read()
    assert data[:4] == b"glTF", path
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + n])
    off = 20 + n
    bin_len = struct.unpack_from("<I", data, off)[0]
    return doc, data[off + 8:off + 8 + bin_len]


def accessor(doc, blob, index):
    """Decodes a VEC3 accessor (dense or sparse, any component type) to float64 (count, 3)."""
    a = doc["accessors"][index]
    fmt, norm = COMPONENT[a["componentType"]]
    size = struct.calcsize(fmt)
    count = a["count"]
    out = numpy.zeros((count, 3))
    if "bufferView" in a:
        v = doc["bufferViews"][a["bufferView"]]
        stride = v.get("byteStride", 3 * size)
        start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
        for i in range(count):
            out[i] = struct.unpack_from("<3" + fmt, blob, start + i * stride)
    if "sparse" in a:
        s = a["sparse"]
        iv = doc["bufferViews"][s["indices"]["bufferView"]]
        ifmt = COMPONENT[s["indices"]["componentType"]][0]
        idx = struct.unpack_from("<%d%s" % (s["count"], ifmt), blob,
                                 iv.get("byteOffset", 0) + s["indices"].get("byteOffset", 0))
        vv = doc["bufferViews"][s["values"]["bufferView"]]
        vals = struct.unpack_from("<%d%s" % (3 * s["count"], fmt), blob,
                                  vv.get("byteOffset", 0) + s["values"].get("byteOffset", 0))
        out[list(idx)] = numpy.array(vals).reshape(-1, 3)
    if a.get("normalized") and norm:
        out = numpy.maximum(out / norm, -1.0)
    return out


def key_times(path):
    doc, blob = read_glb(path)
    a = doc["accessors"][doc["animations"][0]["samplers"][0]["input"]]
    v = doc["bufferViews"][a["bufferView"]]
    return struct.unpack_from("<%df" % a["count"], blob, v.get("byteOffset", 0) + a.get("byteOffset", 0))


def reference_frames(path):
    doc, blob = read_glb(path)
    prim = doc["meshes"][0]["primitives"][0]
    base = accessor(doc, blob, prim["attributes"]["POSITION"])
    frames = [base]
    for t in prim["targets"]:
        frames.append(base + accessor(doc, blob, t["POSITION"]))
    return frames


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    tolerance, every, files = 1e-3, 1, []
    i = 0
    while i < len(argv):
        if argv[i] == "--tolerance":
            tolerance = float(argv[i + 1])
            i += 2
        elif argv[i] == "--every":
            every = int(argv[i + 1])
            i += 2
        else:
            files.append(argv[i])
            i += 1
    compact, reference = files
    ref = reference_frames(reference)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=compact)
    obj = next(o for o in bpy.context.scene.objects if o.type == "MESH" and o.data.shape_keys)
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    worst, worst_frame = 0.0, 0
    # Frame k of the bake is keyed at times[k] in the reference; the importer maps glTF seconds
    # to scene frames at the scene's fps, from frame 0 (Blender 3.4's importer), so sample there.
    times = key_times(reference)
    for k in range(0, len(ref), every):
        frame_float = times[k] * fps
        scene.frame_set(int(frame_float), subframe=frame_float - int(frame_float))
        dg = bpy.context.evaluated_depsgraph_get()
        ev = obj.evaluated_get(dg)
        mesh = ev.to_mesh()
        co = numpy.zeros(len(mesh.vertices) * 3)
        mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        m = numpy.array(ev.matrix_world)
        world = co @ m[:3, :3].T + m[:3, 3]
        ev.to_mesh_clear()
        # Blender Z-up (x, y, z) = glTF (x, -z, y).
        gl = numpy.stack([world[:, 0], world[:, 2], -world[:, 1]], axis=1)
        if len(gl) != len(ref[k]):
            print("vertex count differs: blender %d, reference %d" % (len(gl), len(ref[k])))
            sys.exit(1)
        d = numpy.linalg.norm(gl - ref[k], axis=1).max()
        if d > worst:
            worst, worst_frame = d, k
        print("frame %d: %.6f m" % (k, d))
    print("blender vs reference: max %.6f m at frame %d over %d frames (tolerance %g)"
          % (worst, worst_frame, len(range(0, len(ref), every)), tolerance))
    sys.exit(0 if worst <= tolerance else 1)


main()
