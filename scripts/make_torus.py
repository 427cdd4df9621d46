#!/usr/bin/env python3
"""Writes a closed torus as an OBJ: a collider with a thin part for cloth to fall over.

Ring radius R, tube radius r, U segments around the ring and V around the tube. Standing on its
rim (the default; axis +Z), centred at (0, R + r, 0) so it rests on y = 0, vertex (i, j) is at
((R + r cos b) cos a, R + r + (R + r cos b) sin a, -r sin b) for a = 2πi/U, b = 2πj/V; with
--flat it lies on its side instead (axis +Y), centred at (0, r, 0): ((R + r cos b) cos a,
r + r sin b, (R + r cos b) sin a). Each quad (i, j)-(i+1, j)-(i+1, j+1)-(i, j+1) is split into
two triangles wound outwards (a positive volume). The shipped meshes/ring.obj is the default:

    python3 scripts/make_torus.py --out meshes/ring.obj
"""
import argparse
import math


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ring", type=float, default=0.2, help="ring radius R, metres (0.2)")
    ap.add_argument("--tube", type=float, default=0.008, help="tube radius r, metres (0.008)")
    ap.add_argument("--flat", action="store_true", help="lie on its side (axis +Y)")
    ap.add_argument("--u", type=int, default=64, help="segments around the ring (64)")
    ap.add_argument("--v", type=int, default=8, help="segments around the tube (8)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    cy = a.tube if a.flat else a.ring + a.tube
    lines = [
        f"# A torus: ring radius {a.ring} m, tube radius {a.tube} m, centre (0, {cy}, 0), "
        f"axis {'+Y' if a.flat else '+Z'}, {a.u} x {a.v} segments, metres, y up "
        "(scripts/make_torus.py)",
        "o ring",
    ]
    for i in range(a.u):
        al = 2 * math.pi * i / a.u
        for j in range(a.v):
            b = 2 * math.pi * j / a.v
            rr = a.ring + a.tube * math.cos(b)
            x, y, z = rr * math.cos(al), a.tube * math.sin(b), rr * math.sin(al)
            if not a.flat:
                # A quarter turn about X (a rotation: the winding stays outward).
                y, z = z, -y
            lines.append(f"v {x:.6f} {cy + y:.6f} {z:.6f}")

    def k(i, j):
        return (i % a.u) * a.v + (j % a.v) + 1

    for i in range(a.u):
        for j in range(a.v):
            p, q, r, s = k(i, j), k(i + 1, j), k(i + 1, j + 1), k(i, j + 1)
            lines.append(f"f {p} {s} {r}")
            lines.append(f"f {p} {r} {q}")
    with open(a.out, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
