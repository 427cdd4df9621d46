#!/usr/bin/env python3
"""Write a small cape for Fox.glb (meshes/Fox.glb, at --rig-scale 0.01): a flat rectangle above
the fox's back, to pin along its front edge and let drape over the back as it walks.

    python3 scripts/make_cape.py [--out meshes/garments/fox_cape.obj] [--spacing 0.02]

Geometry (metres, Y up, the fox's frame scaled by 0.01: it faces +Z, its back top is at
y = 0.64-0.67 m between z = -0.2 and 0.3): x in [-0.14, 0.14], z in [-0.16, 0.24], at
y = 0.70 m. A regular grid with each cell split along alternating diagonals; faces
counter-clockwise seen from above. Deterministic.

Pin the front edge with --pin box:-1,0.69,0.235,1,0.71,0.245.
"""

import argparse


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="meshes/garments/fox_cape.obj")
    ap.add_argument("--spacing", type=float, default=0.02)
    a = ap.parse_args()
    x0, x1, z0, z1, y = -0.14, 0.14, -0.16, 0.24, 0.70
    nx = round((x1 - x0) / a.spacing)
    nz = round((z1 - z0) / a.spacing)
    lines = ["# A cape for Fox.glb at --rig-scale 0.01; scripts/make_cape.py (CC0)"]
    for j in range(nz + 1):
        for i in range(nx + 1):
            lines.append(f"v {x0 + (x1 - x0) * i / nx:.6f} {y:.6f} {z0 + (z1 - z0) * j / nz:.6f}")
    for j in range(nz):
        for i in range(nx):
            a_, b_ = j * (nx + 1) + i + 1, j * (nx + 1) + i + 2
            c_, d_ = a_ + nx + 1, b_ + nx + 1
            # Normals (c - a) x (b - a) point to +y for a = (x, z) = (0, 0), b = (1, 0), c = (0, 1).
            if (i + j) % 2 == 0:
                lines += [f"f {a_} {c_} {b_}", f"f {b_} {c_} {d_}"]
            else:
                lines += [f"f {a_} {d_} {b_}", f"f {a_} {c_} {d_}"]
    with open(a.out, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
