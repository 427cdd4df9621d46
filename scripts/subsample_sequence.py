#!/usr/bin/env python3
"""Copy every Nth frame of an OBJ sequence, renumbered from 0, with positions rounded.

    python3 scripts/subsample_sequence.py SRC_DIR/shell%d.obj DST_DIR/shell%d.obj
                                          [--every N] [--last K] [--decimals D]
                                          [--header TEXT]...

Reads frames 0, N, 2N, ... up to K of the source pattern and writes them as frames 0, 1, 2, ...
of the destination pattern (so they play at the source's rate divided by N). `v` lines keep
D decimals (trailing zeros dropped); every other line is copied as it is, so vertex order and
faces are unchanged. Each --header line is written as a `#` comment at the top of every file,
`{frame}` in it replaced by the source frame's number. Each file is written to a temporary file and renamed.
"""
import argparse
import os


def number(x, decimals):
    s = f"{float(x):.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if s in ("", "-0") else s


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--last", type=int, required=True)
    ap.add_argument("--decimals", type=int, default=4)
    ap.add_argument("--header", action="append", default=[])
    a = ap.parse_args()
    os.makedirs(os.path.dirname(a.dst) or ".", exist_ok=True)
    for out, frame in enumerate(range(0, a.last + 1, a.every)):
        lines = [f"# {h.replace('{frame}', str(frame))}\n" for h in a.header]
        with open(a.src % frame) as f:
            for line in f:
                if line.startswith("v "):
                    xyz = line.split()[1:4]
                    line = "v " + " ".join(number(x, a.decimals) for x in xyz) + "\n"
                lines.append(line)
        dst = a.dst % out
        with open(dst + ".tmp", "w") as f:
            f.writelines(lines)
        os.replace(dst + ".tmp", dst)
        print(f"{a.src % frame} -> {dst}")


if __name__ == "__main__":
    main()
