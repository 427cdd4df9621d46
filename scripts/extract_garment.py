#!/usr/bin/env python3
"""Extract connected pieces of a triangle OBJ and weld their touching boundaries into one mesh.

    python3 scripts/extract_garment.py IN.obj OUT.obj --pieces 4,5 [--weld 0.0005] [--header TEXT]...
    python3 scripts/extract_garment.py IN.obj --list

Pieces are the connected components of the faces (sharing a vertex index), numbered from 0 in the
order of their lowest vertex index; --list prints each piece's vertex and triangle counts, boundary
edges and bounds. With --pieces, the chosen pieces' faces are kept and every boundary vertex that
lies within --weld metres of a boundary vertex of an earlier-numbered kept vertex is merged into it
(sewing-pattern panels stored apart but touching along their seams, as in garment-simulation
outputs). The kept vertices are written in their original relative order, coordinates unchanged;
only `v` and `f` lines are written. Prints how many vertices were welded and checks that the
result is edge-manifold.
"""
import argparse
import collections
import math
import os
import sys


def load(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                verts.append(tuple(float(w) for w in p[1:4]))
            elif p[0] == "f":
                idx = [int(w.split("/")[0]) for w in p[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                for k in range(1, len(idx) - 1):
                    faces.append((idx[0], idx[k], idx[k + 1]))
    return verts, faces


def pieces(verts, faces):
    parent = list(range(len(verts)))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for f in faces:
        for v in f[1:]:
            a, b = find(f[0]), find(v)
            if a != b:
                parent[a] = b
    groups = collections.defaultdict(list)
    for fi, f in enumerate(faces):
        groups[find(f[0])].append(fi)
    out = []
    for fl in groups.values():
        vs = sorted({v for fi in fl for v in faces[fi]})
        out.append((vs, fl))
    out.sort(key=lambda t: t[0][0])
    return out


def boundary_vertices(faces, face_ids):
    count = collections.Counter()
    for fi in face_ids:
        f = faces[fi]
        for i in range(3):
            a, b = f[i], f[(i + 1) % 3]
            count[(min(a, b), max(a, b))] += 1
    return count, {v for e, c in count.items() if c == 1 for v in e}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("src")
    ap.add_argument("dst", nargs="?")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--pieces", default=None)
    ap.add_argument("--weld", type=float, default=0.0005)
    ap.add_argument("--header", action="append", default=[])
    a = ap.parse_args()
    verts, faces = load(a.src)
    ps = pieces(verts, faces)
    if a.list or not a.pieces:
        for n, (vs, fl) in enumerate(ps):
            _, bd = boundary_vertices(faces, fl)
            b = [(min(verts[v][k] for v in vs), max(verts[v][k] for v in vs)) for k in range(3)]
            print(f"piece {n}: {len(vs)} v, {len(fl)} triangles, {len(bd)} boundary v, "
                  + ", ".join(f"{c} {lo:.3f}..{hi:.3f}" for c, (lo, hi) in zip("xyz", b)))
        return 0
    if not a.dst:
        ap.error("OUT.obj is needed with --pieces")
    chosen = [int(w) for w in a.pieces.split(",")]
    for c in chosen:
        if not 0 <= c < len(ps):
            ap.error(f"--pieces: {c} is not a piece of {a.src} (it has {len(ps)})")
    face_ids = sorted(fi for c in chosen for fi in ps[c][1])
    _, bd = boundary_vertices(faces, face_ids)
    # Weld boundary vertices: each maps to the lowest-indexed boundary vertex within --weld.
    cell = a.weld if a.weld > 0 else 1.0
    grid = collections.defaultdict(list)
    for v in sorted(bd):
        grid[tuple(int(math.floor(c / cell)) for c in verts[v])].append(v)
    target = {}
    for v in sorted(bd):
        key = tuple(int(math.floor(c / cell)) for c in verts[v])
        best = v
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    for w in grid.get((key[0] + dx, key[1] + dy, key[2] + dz), ()):
                        if w < best and math.dist(verts[v], verts[w]) <= a.weld:
                            best = w
        target[v] = target.get(best, best)
    welded = sum(1 for v, t in target.items() if t != v)
    new_faces = []
    for fi in face_ids:
        f = tuple(target.get(v, v) for v in faces[fi])
        if len(set(f)) == 3:
            new_faces.append(f)
    used = sorted({v for f in new_faces for v in f})
    remap = {v: i for i, v in enumerate(used)}
    count, _ = boundary_vertices(new_faces, range(len(new_faces)))
    nonmanifold = sum(1 for c in count.values() if c > 2)
    tmp = a.dst + ".tmp"
    with open(tmp, "w") as out:
        for h in a.header:
            out.write(f"# {h}\n")
        for v in used:
            out.write("v {:.6f} {:.6f} {:.6f}\n".format(*verts[v]))
        for f in new_faces:
            out.write("f {} {} {}\n".format(*(remap[v] + 1 for v in f)))
    os.replace(tmp, a.dst)
    print(f"{a.dst}: pieces {chosen}: {len(used)} v ({welded} welded at {a.weld} m), "
          f"{len(new_faces)} triangles ({len(face_ids) - len(new_faces)} dropped as degenerate), "
          f"{sum(1 for c in count.values() if c == 1)} boundary edges, {nonmanifold} non-manifold edges")
    return 1 if nonmanifold else 0


if __name__ == "__main__":
    sys.exit(main())
