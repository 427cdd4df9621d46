#!/usr/bin/env python3
"""Copy a triangle/polygon OBJ's `v` and `f` lines, scaled and moved, keeping vertex order.

    python3 scripts/place_obj.py IN.obj OUT.obj [--scale S] [--translate X,Y,Z]
                                 [--swap-yz] [--header TEXT]...

Positions become S * p + T (after --swap-yz, which turns a Z-up file into Y-up: (x, y, z) ->
(x, z, -y)). Only `v` and `f` lines are kept (face corners reduced to their position index; groups,
materials, normals and texture coordinates are dropped), so vertex indices and the order of
positions are unchanged. Each --header line is written as a `#` comment at the top. The output is
written to a temporary file and renamed.
"""
import argparse
import os
import sys


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--translate", default="0,0,0")
    ap.add_argument("--swap-yz", action="store_true")
    ap.add_argument("--header", action="append", default=[])
    a = ap.parse_args()
    t = [float(x) for x in a.translate.split(",")]
    if len(t) != 3:
        ap.error("--translate needs X,Y,Z")
    nv = nf = 0
    tmp = a.dst + ".tmp"
    with open(a.src) as src, open(tmp, "w") as out:
        for h in a.header:
            out.write(f"# {h}\n")
        for n, line in enumerate(src, 1):
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                try:
                    x, y, z = (float(w) for w in p[1:4])
                except ValueError:
                    sys.exit(f"{a.src}:{n}: bad vertex line: {line.strip()}")
                if a.swap_yz:
                    x, y, z = x, z, -y
                x, y, z = (a.scale * c + d for c, d in zip((x, y, z), t))
                out.write(f"v {x:.6f} {y:.6f} {z:.6f}\n")
                nv += 1
            elif p[0] == "f":
                out.write("f " + " ".join(w.split("/")[0] for w in p[1:]) + "\n")
                nf += 1
    os.replace(tmp, a.dst)
    print(f"{a.dst}: {nv} vertices, {nf} faces")


if __name__ == "__main__":
    main()
