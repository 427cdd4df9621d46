"""Load time, playback time and memory of one glTF in Blender (for docs/caches.md).

    env -u PYTHONPATH -u PYTHONHOME PATH=/usr/sbin:/usr/bin:/sbin:/bin blender -b \
        --factory-startup --python scripts/blender_load.py -- FILE.glb
    /work/bpy5/bin/python scripts/blender_load.py -- FILE.glb      # Blender 5.x (PyPI bpy)

Imports FILE with Blender's glTF importer, then evaluates the first mesh at every frame of the
scene's range (what playing it costs; shape keys blended by the imported animation), and prints
the import and playback seconds and the process's peak resident memory, also as its growth over
the empty scene. One file per process: peak RSS only grows. Without FILE, the empty scene alone.
"""

import resource
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
    bpy.ops.import_scene.gltf(filepath=argv[0])
    t1 = time.perf_counter()
    scene = bpy.context.scene
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
