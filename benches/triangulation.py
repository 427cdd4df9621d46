#!/usr/bin/env python3
"""The same 1 m cotton sheet on five triangulations, hung by two adjacent corners for 2 s.

Meshes: regular grids of 21x21, 61x61 and 119x119 vertices, the 61x61 grid with every interior
vertex jittered by 0.3 cells, and meshes/tableCloth.obj (Codim-IPC's irregular, Delaunay-style
triangulation, 14,161 vertices) scaled to the same square. Each is baked with the given membrane
(`--membrane triangles` or `springs`), 60 frames at 30 fps, one thread, and read back from its PC2
point cache. Printed: each mesh's area-weighted centroid path against the regular 61x61's and
21x21's (RMS and largest distance over the frames), the largest distance between the midpoints
of the free edges at the end, and the stepping time per vertex and frame from the reports.

    python3 benches/triangulation.py target/release/scenebake triangles OUTDIR
"""

import json
import math
import os
import struct
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PINS = ["box:-0.001,0.99,-0.001,0.001,1.01,0.001", "box:0.999,0.99,-0.001,1.001,1.01,0.001"]


def write(path, verts, faces):
    with open(path, "w") as f:
        f.writelines("v %.7f %.7f %.7f\n" % tuple(p) for p in verts)
        f.writelines("f %d %d %d\n" % (a + 1, b + 1, c + 1) for a, b, c in faces)


def grid(path, cells, jitter):
    n, h = cells + 1, 1.0 / cells
    verts = []
    for i in range(n):
        for j in range(n):
            t = float(i * 7919 + j * 104729)
            inside = 0 < i < cells and 0 < j < cells
            dx, dz = (jitter * h * math.sin(t * 0.37), jitter * h * math.cos(t * 0.73)) if inside else (0, 0)
            verts.append((j * h + dx, 1.0, i * h + dz))
    v = lambda a, b: a * n + b
    faces = [f for i in range(cells) for j in range(cells)
             for f in ((v(i, j), v(i + 1, j), v(i + 1, j + 1)), (v(i, j), v(i + 1, j + 1), v(i, j + 1)))]
    write(path, verts, faces)


def table_cloth(path):
    verts, faces = [], []
    for line in open(os.path.join(ROOT, "meshes/tableCloth.obj")):
        if line.startswith("v "):
            x, _, z = (float(s) for s in line.split()[1:4])
            verts.append(((x + 0.48) / 0.7, 1.0, (z + 0.35) / 0.7))
        elif line.startswith("f "):
            faces.append(tuple(int(s.split("/")[0]) - 1 for s in line.split()[1:4]))
    write(path, verts, faces)


def pc2(path):
    b = open(path, "rb").read()
    points, samples = struct.unpack("<i", b[16:20])[0], struct.unpack("<i", b[28:32])[0]
    return np.frombuffer(b[32:], np.float32).reshape(samples, points, 3).astype(np.float64)


def main():
    binary, membrane, out = sys.argv[1], sys.argv[2], sys.argv[3]
    os.makedirs(out, exist_ok=True)
    meshes = {"regular 21x21": lambda p: grid(p, 20, 0.0), "regular 61x61": lambda p: grid(p, 60, 0.0),
              "jittered 61x61": lambda p: grid(p, 60, 0.3), "regular 119x119": lambda p: grid(p, 118, 0.0),
              "tableCloth": table_cloth}
    runs = {}
    for k, (name, make) in enumerate(meshes.items()):
        obj, stem = os.path.join(out, f"{k}.obj"), os.path.join(out, f"{k}_{membrane}")
        make(obj)
        cmd = [binary, "cloth", obj, "--membrane", membrane, "--frames", "60", "--fps", "30", "--threads", "1",
               "-o", stem + ".glb", "--pc2", stem + ".pc2", "--report", stem + ".json", "-q"]
        for pin in PINS:
            cmd += ["--pin", pin]
        subprocess.run(cmd, check=True)
        x = pc2(stem + ".pc2")
        faces = np.array([[int(s) - 1 for s in l.split()[1:4]] for l in open(obj) if l.startswith("f ")])
        x0 = x[0]
        area = 0.5 * np.linalg.norm(np.cross(x0[faces[:, 1]] - x0[faces[:, 0]], x0[faces[:, 2]] - x0[faces[:, 0]]), axis=1)
        centroid = np.array([(area[:, None] * f[faces].mean(1)).sum(0) / area.sum() for f in x])
        mids = [x[-1, np.linalg.norm(x0[:, [0, 2]] - q, axis=1).argmin()] for q in ((0, 0.5), (1, 0.5), (0.5, 1))]
        report = json.load(open(stem + ".json"))
        assert not report["unconverged_frames"], name
        runs[name] = (centroid, mids, 1000 * report["ms_per_frame"] / report["particles"], report["particles"])
    for ref in ("regular 61x61", "regular 21x21"):
        for name, (c, mids, _, _) in runs.items():
            if name == ref:
                continue
            d = np.linalg.norm(c - runs[ref][0], axis=1)
            edge = max(np.linalg.norm(a - b) for a, b in zip(mids, runs[ref][1]))
            print(f"{membrane}: {name} against {ref}: centroid paths {100 * np.sqrt((d * d).mean()):.2f} cm RMS, "
                  f"{100 * d.max():.2f} cm at most; free-edge midpoints {100 * edge:.2f} cm apart at the end")
    for name, (_, _, us, n) in runs.items():
        print(f"{membrane}: {name}: {n} vertices, {us:.1f} us a vertex and frame")


if __name__ == "__main__":
    main()
