#!/usr/bin/env python3
"""Summarise benches/blender_cloth.py results as Markdown tables.

    python3 benches/blender_summary.py benches/blender_results/*.json[.gz]

One row per file: the garment, vertices, pinned vertices, vertex mass, how it was timed, wall
seconds per frame (mean, and median/min/max over frames when known), CPU seconds per frame, busy
cores on the machine (of its cpus), hem drop (lowest vertex) at frames 5, 10 and the last, mean
drop of the hem vertices at frame 10, and the largest edge stretch and compression over all frames.
"""
import gzip
import json
import statistics
import sys


def load(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return json.load(f)


def mm(x):
    return f"{1000 * x:.1f}"


def main(paths):
    print("| result | garment | v | pinned | vertex mass (kg) | colliders | timed | s/frame wall: mean (median, min–max) | s/frame CPU | busy cores | hem drop f5 / f10 / last (mm) | hem ring mean drop f10 (mm) | max stretch / compression |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for p in paths:
        d = load(p)
        t = d["timing"]
        pf = d["per_frame"]
        last = pf[-1]
        per = t.get("per_frame_seconds")
        if per:
            spread = f"{t['seconds_per_frame']:.2f} ({statistics.median(per):.2f}, {min(per):.2f}–{max(per):.2f})"
        else:
            spread = f"{t['seconds_per_frame']:.2f}"
        busy = t.get("busy_cores")
        busy_text = "" if busy is None else f"{busy:.2f} of {d['machine']['cpus']}"
        cols = ", ".join(
            ("sphere r " + str(c["sphere"][3])) if "sphere" in c else c["obj"].split("/")[-1]
            for c in d["colliders"]) or "none"
        timed = "bake" if t["mode"].startswith("bpy.ops") else "frame_set"
        f5, f10 = pf[min(5, len(pf) - 1)], pf[min(10, len(pf) - 1)]
        stretch = max(r["max_edge_stretch"] for r in pf)
        comp = min(r["max_edge_compression"] for r in pf)
        hem10 = f10.get("hem_mean_drop_m")
        hem10_text = "" if hem10 is None else mm(hem10)
        print(f"| {p.split('/')[-1]} | {d['mesh'].split('/')[-1]} | {d['vertices']} | {d['pinned_vertices']} | "
              f"{d['settings']['mass']:.3g} | {cols} | {timed} | {spread} | {t['cpu_seconds_per_frame']:.2f} | "
              f"{busy_text} | "
              f"{mm(f5['hem_drop_m'])} / {mm(f10['hem_drop_m'])} / {mm(last['hem_drop_m'])} (f{last['frame']}) | "
              f"{hem10_text} | {100 * stretch:.1f} % / {100 * comp:.1f} % |")


if __name__ == "__main__":
    main(sys.argv[1:])
