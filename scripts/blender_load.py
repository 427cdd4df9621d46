"""Load time, playback time and memory of one bake in Blender (for docs/caches.md).

    env -u PYTHONPATH -u PYTHONHOME PATH=/usr/sbin:/usr/bin:/sbin:/bin blender -b \
        --factory-startup --python scripts/blender_load.py -- FILE.glb
    /work/bpy5/bin/python scripts/blender_load.py -- FILE.glb      # Blender 5.x (PyPI bpy)
    ... -- FILE.usda                       # USD import (Blender builds with USD: 5.x)
    ... -- INPUT.obj FILE.pc2|FILE.mdd     # the input OBJ with a Mesh Cache modifier

Imports FILE (glTF importer; USD importer; or the Wavefront importer and a Mesh Cache modifier
reading the point cache, frames from 0 at the scene's rate), then evaluates the first mesh at
every frame of the scene's range (the cache's frame count for a point cache: what playing it
costs), and prints the import and playback seconds and the process's peak resident memory,
also as its growth over the empty scene. One file per process: peak RSS only grows. Without
FILE, the empty scene alone.
"""

import os
import resource
import struct
import sys
import time

import numpy

if "bool" not in numpy.__dict__:
    numpy.bool = bool  # Blender 3.4's importer still uses numpy.bool

import bpy  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
bpy.ops.wm.read_factory_settings(use_empty=True)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = t1 = t2 = time.perf_counter()
frames = 0
if argv:
    scene = bpy.context.scene
    ext = os.path.splitext(argv[0])[1].lower()
    if ext == ".obj":
        bpy.ops.wm.obj_import(filepath=argv[0])
        obj = next(o for o in scene.objects if o.type == "MESH")
        cache = argv[1]
        mod = obj.modifiers.new("cache", "MESH_CACHE")
        mod.cache_format = os.path.splitext(cache)[1][1:].upper()
        mod.filepath = os.path.abspath(cache)
        mod.time_mode = "FRAME"
        mod.play_mode = "SCENE"
        mod.frame_start = 0.0
        mod.interpolation = "LINEAR"
        # The cache's frame count: int32 at byte 28 (PC2, little-endian) or 0 (MDD, big-endian).
        with open(cache, "rb") as f:
            head = f.read(32)
        count = (struct.unpack_from("<i", head, 28)[0] if mod.cache_format == "PC2"
                 else struct.unpack_from(">i", head, 0)[0])
        scene.frame_start, scene.frame_end = 0, count - 1
    elif ext in (".usd", ".usda", ".usdc"):
        bpy.ops.wm.usd_import(filepath=os.path.abspath(argv[0]))
    else:
        bpy.ops.import_scene.gltf(filepath=argv[0])
    t1 = time.perf_counter()
    obj = next(o for o in scene.objects if o.type == "MESH")
    for f in range(scene.frame_start, scene.frame_end + 1):
        scene.frame_set(f)
        ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        ev.to_mesh()
        ev.to_mesh_clear()
        frames += 1
    t2 = time.perf_counter()
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print("LOAD %s (Blender %s): import %.2f s, playback %d frames %.2f s, peak RSS %.0f MB "
      "(+%.0f MB over the empty scene)"
      % (argv[0] if argv else "-", bpy.app.version_string, t1 - t0, frames, t2 - t1,
         after / 1024, (after - before) / 1024))
