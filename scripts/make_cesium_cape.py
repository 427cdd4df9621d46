#!/usr/bin/env python3
"""Write a cape for the Khronos CesiumMan (meshes/CesiumMan.glb, metres, faces +x): a vertical
0.3 x 0.6 m sheet 2 cm behind its back, its top edge across the back at shoulder height, to pin
there and let hang as it walks.

    python3 scripts/make_cesium_cape.py [--out cape.obj] [--n 31]

Geometry (metres, Y up): x = -0.12, y from 1.1 down to 0.5, z from -0.15 to 0.15; an n x n
grid, each cell split along the same diagonal. Deterministic.

Pin the top edge with --pin box:-1,1.099,-1,1,1.101,1.
"""

import argparse


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="cape.obj")
    ap.add_argument("--n", type=int, default=31)
    a = ap.parse_args()
    n = a.n
    lines = ["# A cape for CesiumMan.glb; scripts/make_cesium_cape.py (CC0)"]
    for j in range(n):
        for i in range(n):
            lines.append(f"v -0.12 {1.1 - 0.6 * j / (n - 1):.6f} {-0.15 + 0.3 * i / (n - 1):.6f}")
    for j in range(n - 1):
        for i in range(n - 1):
            a_ = j * n + i + 1
            b_, c_ = a_ + 1, a_ + n
            lines += [f"f {a_} {c_} {b_}", f"f {b_} {c_} {c_ + 1}"]
    with open(a.out, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
