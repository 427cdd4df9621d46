#!/usr/bin/env python3
"""Write a circle skirt: a lampshade-shaped annular sheet to pin at its waist and let fall.

    python3 scripts/make_skirt.py [--out meshes/garments/circle_skirt.obj] [--vertices 8000]
                                  [--seed 12]

Geometry (metres, Y up): the waist ring has radius 0.156 m at y = 1.0 and the hem ring radius
0.45 m at y = 0.65 (0.35 m lower). The surface between them is the cone through both rings, so
the sheet is a frustum ("lampshade") that is far from its draped shape: pinned at the waist it
has to fall and fold under gravity.

Triangulation: rings of vertices from waist to hem, each with a vertex count proportional to
its circumference (so triangles are near-equilateral), every interior vertex jittered along and
across the rings by up to 20–25 % of the spacing, and each strip between two rings zipped into
triangles (each step adds the triangle whose new edge across the strip is the shorter). The result
is irregular (ring counts differ; interior vertices have 4–8 triangles) but manifold, with no
slivers. The waist and hem rings are not jittered: the waist ring lies exactly at y = 1.0, the hem
ring exactly at y = 0.65.

Defaults (seed 12) give 8,156 vertices and 15,973 triangles: edges 5.7–18.6 mm (median 11.5 mm),
triangle quality 4√3·A/Σl² at least 0.45 (median 0.93), 87 waist and 252 hem vertices. The output is
deterministic for a given seed. Faces are counter-clockwise seen from outside the cone.

Pin the waist with --pin box:-0.2,0.999,-0.2,0.2,1.001,0.2 (the waist ring only).
"""

import argparse
import math
import os
import random
import sys

WAIST_R = 0.156
WAIST_Y = 1.0
HEM_R = 0.45
HEM_Y = 0.65


def build(target_vertices, seed):
    rng = random.Random(seed)
    slant = math.hypot(HEM_R - WAIST_R, WAIST_Y - HEM_Y)
    area = math.pi * (WAIST_R + HEM_R) * slant
    # A near-equilateral mesh with spacing h has about area / (h^2 sqrt(3)/2) vertices.
    h = math.sqrt(area / (target_vertices * math.sqrt(3) / 2))
    n_rings = max(2, round(slant / (h * math.sqrt(3) / 2)) + 1)
    dt = 1.0 / (n_rings - 1)

    rings = []  # per ring: list of (angle, vertex index)
    verts = []
    for k in range(n_rings):
        t = k * dt
        r_mid = WAIST_R + t * (HEM_R - WAIST_R)
        n = max(3, round(2 * math.pi * r_mid / h))
        phase = rng.uniform(0, 2 * math.pi / n)
        ring = []
        for j in range(n):
            a = phase + 2 * math.pi * j / n
            tt = t
            if 0 < k < n_rings - 1:
                a += rng.uniform(-0.25, 0.25) * 2 * math.pi / n
                tt += rng.uniform(-0.2, 0.2) * dt
            r = WAIST_R + tt * (HEM_R - WAIST_R)
            y = WAIST_Y + tt * (HEM_Y - WAIST_Y)
            ring.append((a, len(verts)))
            verts.append((r * math.cos(a), y, r * math.sin(a)))
        ring.sort()
        rings.append(ring)

    faces = []
    for k in range(n_rings - 1):
        faces.extend(zip_strip(rings[k], rings[k + 1], verts))
    return verts, faces


def zip_strip(upper, lower, verts):
    """Triangulate the strip between two closed rings of (angle, index), sorted by angle.

    Walks both rings once; each step adds the triangle whose new edge across the strip is the
    shorter (the "shortest diagonal" rule, which avoids slivers), with counter-clockwise
    orientation seen from outside the cone."""
    two_pi = 2 * math.pi

    def unwrap(ring, start_angle):
        # ring is a rotation of an angle-sorted ring: angles made increasing from start_angle
        # over one full turn, closed by repeating the first vertex.
        first = ring[0][0]
        out = [(start_angle + (a - first) % two_pi, v) for a, v in ring]
        out.append((start_angle + two_pi, ring[0][1]))
        return out

    a0 = upper[0][0]
    u = unwrap(upper, a0)
    # Start the lower ring at its vertex nearest in angle to u[0].
    j0 = min(range(len(lower)), key=lambda j: abs(math.remainder(lower[j][0] - a0, two_pi)))
    lo = lower[j0:] + lower[:j0]
    # Its angles start within half a spacing of a0 (before or after it), one full turn.
    base = a0 + math.remainder(lo[0][0] - a0, two_pi)
    l = unwrap(lo, base)
    faces = []
    i = j = 0
    while i < len(u) - 1 or j < len(l) - 1:
        if j == len(l) - 1:
            adv_upper = True
        elif i == len(u) - 1:
            adv_upper = False
        else:
            d_upper = math.dist(verts[u[i + 1][1]], verts[l[j][1]])
            d_lower = math.dist(verts[u[i][1]], verts[l[j + 1][1]])
            adv_upper = d_upper < d_lower
        if adv_upper:
            faces.append((u[i][1], u[i + 1][1], l[j][1]))
            i += 1
        else:
            faces.append((u[i][1], l[j + 1][1], l[j][1]))
            j += 1
    return faces


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="meshes/garments/circle_skirt.obj")
    ap.add_argument("--vertices", type=int, default=8000, help="target vertex count")
    ap.add_argument("--seed", type=int, default=12)
    ap.add_argument("--waist-radius", type=float, default=WAIST_R, help="metres (default 0.156)")
    ap.add_argument("--waist-y", type=float, default=WAIST_Y, help="metres (default 1.0)")
    ap.add_argument("--hem-radius", type=float, default=HEM_R, help="metres (default 0.45)")
    ap.add_argument("--hem-y", type=float, default=HEM_Y, help="metres (default 0.65)")
    args = ap.parse_args(argv)
    globals().update(WAIST_R=args.waist_radius, WAIST_Y=args.waist_y, HEM_R=args.hem_radius,
                     HEM_Y=args.hem_y)
    if args.vertices < 100:
        ap.error("--vertices must be at least 100")
    verts, faces = build(args.vertices, args.seed)
    tmp = args.out + ".tmp"
    with open(tmp, "w") as f:
        f.write("# Circle skirt made by scripts/make_skirt.py (scenebake, CC0 1.0).\n")
        f.write(
            f"# --vertices {args.vertices} --seed {args.seed}: {len(verts)} v, {len(faces)} triangles. "
            f"Metres, Y up: waist ring r = {args.waist_radius} at y = {args.waist_y}, "
            f"hem ring r = {args.hem_radius} at y = {args.hem_y}.\n"
        )
        f.write("o circle_skirt\n")
        for x, y, z in verts:
            f.write(f"v {x:.6f} {y:.6f} {z:.6f}\n")
        for a, b, c in faces:
            f.write(f"f {a + 1} {b + 1} {c + 1}\n")
    os.replace(tmp, args.out)
    print(f"{args.out}: {len(verts)} vertices, {len(faces)} triangles")
    return 0


if __name__ == "__main__":
    sys.exit(main())
