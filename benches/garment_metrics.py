#!/usr/bin/env python3
"""Measure a scenebake cloth bake (glTF) the way benches/blender_cloth.py measures Blender's.

    python3 benches/garment_metrics.py BAKE.glb [--blender RESULT.json[.gz]] [--json OUT.json]

Reads the baked mesh (the first mesh with morph targets): frame 0 is the base POSITION, frame k
is the base plus the target named `frame_NNNN` (scenebake names its targets so; with
--keyframe-tolerance only kept frames are present). Sparse accessors and buffers in the .glb or
in external .bin files are supported. For each frame present it prints and records the lowest
height (min y), the hem drop (min y at frame 0 minus min y now), the mean drop of the hem vertices
(those within 1 mm of the lowest height at frame 0), the largest edge stretch and compression
(length / rest − 1 over the triangles' edges, rest = frame 0) and the number of edges strained
past 10 %: the same definitions as blender_cloth.py.

With --blender, also compares with a blender_cloth.py result on the same OBJ: side by side hem
drops, and for frames that both have positions, the RMS and largest vertex distance. Vertices
are matched by index if frame 0 agrees (within 0.1 mm), otherwise by their frame-0 position
(both keep the OBJ's coordinates); without a one-to-one match the distances are skipped.

Exit status: 0 on success, 1 if a file cannot be read or has no morph targets, 2 on bad options.
"""
import argparse
import gzip
import json
import math
import os
import struct
import sys

COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
FORMATS = {5120: "b", 5121: "B", 5122: "h", 5123: "H", 5125: "I", 5126: "f"}


class Gltf:
    def __init__(self, path):
        self.path = path
        with open(path, "rb") as f:
            data = f.read()
        self.glb_bin = None
        if data[:4] == b"glTF":
            _, _, length = struct.unpack_from("<III", data, 0)
            off = 12
            self.json = None
            while off < length:
                clen, ctype = struct.unpack_from("<II", data, off)
                chunk = data[off + 8 : off + 8 + clen]
                if ctype == 0x4E4F534A:
                    self.json = json.loads(chunk)
                elif ctype == 0x004E4942:
                    self.glb_bin = chunk
                off += 8 + clen
            if self.json is None:
                raise ValueError("no JSON chunk")
        else:
            self.json = json.loads(data)
        self._buffers = {}

    def buffer(self, i):
        if i not in self._buffers:
            b = self.json["buffers"][i]
            uri = b.get("uri")
            if uri is None:
                self._buffers[i] = self.glb_bin
            elif uri.startswith("data:"):
                import base64

                self._buffers[i] = base64.b64decode(uri.split(",", 1)[1])
            else:
                with open(os.path.join(os.path.dirname(self.path), uri), "rb") as f:
                    self._buffers[i] = f.read()
        return self._buffers[i]

    def _read(self, view_index, byte_offset, count, ncomp, ctype):
        view = self.json["bufferViews"][view_index]
        buf = self.buffer(view["buffer"])
        fmt = FORMATS[ctype]
        size = struct.calcsize(fmt)
        stride = view.get("byteStride") or size * ncomp
        start = view.get("byteOffset", 0) + byte_offset
        out = []
        for k in range(count):
            vals = struct.unpack_from("<" + fmt * ncomp, buf, start + k * stride)
            out.append(vals if ncomp > 1 else vals[0])
        return out

    def accessor(self, i):
        a = self.json["accessors"][i]
        ncomp = COMPONENTS[a["type"]]
        if "bufferView" in a:
            vals = self._read(a["bufferView"], a.get("byteOffset", 0), a["count"], ncomp,
                              a["componentType"])
        else:
            vals = [tuple([0.0] * ncomp) if ncomp > 1 else 0.0] * a["count"]
        sp = a.get("sparse")
        if sp:
            vals = list(vals)
            idx = self._read(sp["indices"]["bufferView"], sp["indices"].get("byteOffset", 0),
                             sp["count"], 1, sp["indices"]["componentType"])
            new = self._read(sp["values"]["bufferView"], sp["values"].get("byteOffset", 0),
                             sp["count"], ncomp, a["componentType"])
            for k, v in zip(idx, new):
                vals[k] = v
        return vals


def measure_frames(frames, tris):
    """frames: {frame: positions}; returns per-frame dicts (blender_cloth.py's definitions)."""
    edges = sorted({(min(i, j), max(i, j)) for t in tris for i, j in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))})
    p0 = frames[0]
    rest = [math.dist(p0[i], p0[j]) for i, j in edges]
    min_y0 = min(p[1] for p in p0)
    hem = [i for i, p in enumerate(p0) if p[1] <= min_y0 + 1e-3]
    hem_y0 = sum(p0[i][1] for i in hem) / len(hem)
    out = []
    for f in sorted(frames):
        pos = frames[f]
        stretch = compress = 0.0
        over = 0
        for (i, j), r0 in zip(edges, rest):
            if r0 <= 0:
                continue
            s = math.dist(pos[i], pos[j]) / r0 - 1.0
            stretch = max(stretch, s)
            compress = min(compress, s)
            over += abs(s) > 0.1
        min_y = min(p[1] for p in pos)
        out.append({
            "frame": f,
            "min_y": min_y,
            "hem_drop_m": min_y0 - min_y,
            "hem_mean_drop_m": hem_y0 - sum(pos[i][1] for i in hem) / len(hem),
            "max_edge_stretch": stretch,
            "max_edge_compression": compress,
            "edges_beyond_10_percent": over,
        })
    return out, len(hem), len(edges)


def match_order(reference, base, tol=1e-4):
    """order[i] = index in `reference` of glTF vertex i, matched by frame-0 position (identity if
    they already agree within tol); None if some vertex has no unique match."""
    if all(max(abs(x - y) for x, y in zip(p, q)) < tol for p, q in zip(reference, base)):
        return list(range(len(base)))
    cell = {}
    for k, p in enumerate(reference):
        cell.setdefault(tuple(round(c / tol) for c in p), []).append(k)
    order, used = [], set()
    for q in base:
        key = tuple(round(c / tol) for c in q)
        cands = [k for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                 for k in cell.get((key[0] + dx, key[1] + dy, key[2] + dz), ())
                 if math.dist(reference[k], q) < tol]
        if len(cands) != 1 or cands[0] in used:
            return None
        used.add(cands[0])
        order.append(cands[0])
    return order


def load_json(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return json.load(f)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bake")
    ap.add_argument("--blender", default=None)
    ap.add_argument("--json", default=None)
    try:
        a = ap.parse_args()
    except SystemExit as e:
        sys.exit(2 if e.code else 0)
    try:
        g = Gltf(a.bake)
    except (OSError, ValueError, KeyError, struct.error) as e:
        sys.exit(f"garment_metrics.py: {a.bake}: cannot read: {e}")
    mesh = next((m for m in g.json.get("meshes", []) if m["primitives"][0].get("targets")), None)
    if mesh is None:
        sys.exit(f"garment_metrics.py: {a.bake}: no mesh with morph targets")
    prim = mesh["primitives"][0]
    base = g.accessor(prim["attributes"]["POSITION"])
    idx = g.accessor(prim["indices"]) if "indices" in prim else list(range(len(base)))
    tris = [tuple(idx[k : k + 3]) for k in range(0, len(idx) - 2, 3)]
    names = (mesh.get("extras") or {}).get("targetNames") or []
    frames = {0: base}
    for k, t in enumerate(prim["targets"]):
        name = names[k] if k < len(names) else f"frame_{k + 1:04d}"
        try:
            f = int(name.rsplit("_", 1)[1])
        except (IndexError, ValueError):
            f = k + 1
        d = g.accessor(t["POSITION"])
        frames[f] = [(p[0] + q[0], p[1] + q[1], p[2] + q[2]) for p, q in zip(base, d)]
    rows, n_hem, n_edges = measure_frames(frames, tris)
    result = {"bake": a.bake, "vertices": len(base), "triangles": len(tris), "edges": n_edges,
              "hem_vertices": n_hem, "per_frame": rows}

    blender = load_json(a.blender) if a.blender else None
    bl_rows = {r["frame"]: r for r in blender["per_frame"]} if blender else {}
    if blender:
        snaps = blender.get("positions") or {}
        compare = {}
        if "0" in snaps and len(snaps["0"]) == len(base):
            order = match_order(snaps["0"], base)
            if order is None:
                compare["note"] = "frame 0 differs and no one-to-one match by position: distances skipped"
            else:
                compare["vertex_order"] = ("same as Blender's (the OBJ's)" if order == list(range(len(base)))
                                           else "different: matched by frame-0 position")
                compare["frame_0_max_abs_difference_m"] = max(
                    math.dist(snaps["0"][order[i]], base[i]) for i in range(len(base)))
                for fs, pos in snaps.items():
                    f = int(fs)
                    if f in frames and f > 0:
                        dist = [math.dist(pos[order[i]], q) for i, q in enumerate(frames[f])]
                        compare[fs] = {"rms_m": math.sqrt(sum(x * x for x in dist) / len(dist)),
                                       "max_m": max(dist)}
        else:
            compare["note"] = "no frame-0 positions of the same vertex count: distances skipped"
        result["blender"] = {"file": a.blender, "compare": compare}

    print(f"{a.bake}: {len(base)} v, {len(tris)} triangles, {len(frames) - 1} frames, {n_hem} hem vertices")
    head = "frame  min y     hem drop  hem mean  stretch  compr.  >10%"
    if blender:
        head += "  | Blender: hem drop  stretch"
    print(head)
    for r in rows:
        line = (f"{r['frame']:5d}  {r['min_y']:.4f}  {1000 * r['hem_drop_m']:7.1f}mm {1000 * r['hem_mean_drop_m']:7.1f}mm "
                f"{100 * r['max_edge_stretch']:6.2f}%  {100 * r['max_edge_compression']:6.2f}%  {r['edges_beyond_10_percent']:4d}")
        b = bl_rows.get(r["frame"])
        if b:
            line += f"  |        {1000 * b['hem_drop_m']:7.1f}mm  {100 * b['max_edge_stretch']:6.2f}%"
        print(line)
    if blender:
        for fs, c in sorted(result["blender"]["compare"].items(), key=lambda kv: (len(kv[0]), kv[0])):
            if isinstance(c, dict):
                print(f"frame {fs}: distance to Blender's positions RMS {1000 * c['rms_m']:.1f} mm, "
                      f"max {1000 * c['max_m']:.1f} mm")
            else:
                print(f"{fs}: {c}")
    if a.json:
        with open(a.json + ".tmp", "w") as f:
            json.dump(result, f)
        os.replace(a.json + ".tmp", a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
