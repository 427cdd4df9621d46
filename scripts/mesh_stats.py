#!/usr/bin/env python3
"""Print a triangle OBJ's counts, bounds, edge lengths, boundary loops, manifoldness,
orientation consistency, and how many vertices each --pin box selects.

    python3 scripts/mesh_stats.py MESH.obj [--pin box:X0,Y0,Z0,X1,Y1,Z1 ...]

Only `v` and `f` lines are read (faces with more than 3 corners are fanned). Counts are of the
positions that faces use, like scenebake's particles. The box test is inclusive, like --pin.
"""
import argparse
import collections
import math
import sys


def load(path):
    verts, faces = [], []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                verts.append(tuple(float(x) for x in p[1:4]))
            elif p[0] == "f":
                idx = []
                for w in p[1:]:
                    i = int(w.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                for k in range(1, len(idx) - 1):
                    faces.append((idx[0], idx[k], idx[k + 1]))
    return verts, faces


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh")
    ap.add_argument("--pin", action="append", default=[])
    a = ap.parse_args()
    verts, faces = load(a.mesh)
    used = sorted({v for f in faces for v in f})
    print(f"{a.mesh}: {len(verts)} v ({len(used)} used by faces), {len(faces)} triangles")
    for k, name in enumerate("xyz"):
        vals = [verts[i][k] for i in used]
        print(f"  {name}: {min(vals):.4f} .. {max(vals):.4f}")
    count = collections.Counter()
    directed = collections.Counter()
    for f in faces:
        for i in range(3):
            a0, b0 = f[i], f[(i + 1) % 3]
            count[(min(a0, b0), max(a0, b0))] += 1
            directed[(a0, b0)] += 1
    lens = sorted(math.dist(verts[e[0]], verts[e[1]]) for e in count)
    print(f"  edges: {len(lens)}, length min {lens[0]*1e3:.2f} mm, median {lens[len(lens)//2]*1e3:.2f} mm, "
          f"max {lens[-1]*1e3:.2f} mm")
    boundary = [e for e, c in count.items() if c == 1]
    nonman = sum(1 for c in count.values() if c > 2)
    flipped = sum(1 for (x, y), c in directed.items() if c > 1 or False)
    print(f"  boundary edges {len(boundary)}, non-manifold edges {nonman}, "
          f"edges used twice in the same direction (inconsistent orientation) {flipped}")
    # boundary loops
    adj = collections.defaultdict(list)
    for x, y in boundary:
        adj[x].append(y)
        adj[y].append(x)
    seen, loops = set(), []
    for s in adj:
        if s in seen:
            continue
        stack, comp = [s], []
        seen.add(s)
        while stack:
            v = stack.pop()
            comp.append(v)
            for w in adj[v]:
                if w not in seen:
                    seen.add(w)
                    stack.append(w)
        ys = [verts[v][1] for v in comp]
        loops.append((len(comp), min(ys), max(ys)))
    for n, y0, y1 in sorted(loops, key=lambda t: -t[2]):
        print(f"  boundary loop: {n} vertices, y {y0:.4f} .. {y1:.4f}")
    for spec in a.pin:
        kind, _, rest = spec.partition(":")
        c = [float(x) for x in rest.split(",")]
        lo = [min(c[i], c[i + 3]) for i in range(3)]
        hi = [max(c[i], c[i + 3]) for i in range(3)]
        inside = [i for i in used if all(lo[k] <= verts[i][k] <= hi[k] for k in range(3))]
        print(f"  --pin {spec}: {len(inside)} vertices")
    return 0


if __name__ == "__main__":
    sys.exit(main())
