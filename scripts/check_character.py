#!/usr/bin/env python3
"""Checks a garment baked on a character (`scenebake cloth --rig`) from the file alone.

    python3 scripts/check_character.py FILE.glb --garment NAME --body NAME [NAME...] --rest GARMENT.obj
        --units M --pin X0,Y0,Z0,X1,Y1,Z1 [--thickness M] [--exclude-joint NODE...] [--json OUT]

Everything is evaluated by scripts/blender/gltf_eval.py (plain numpy, not scenebake's code):
the character's skinned body and the garment's morph cache are played from the file's first
animation at every baked frame (asset.extras.scenebake: fps and frame range). Lengths are
converted to metres with --units (metres per document unit). --exclude-joint leaves out of the
body what the bake's `--body-exclude` with a joint left out of its collider: every triangle with
a corner that carries more than half its skin weight (the file's JOINTS_n/WEIGHTS_n) on that
node or the nodes below it. Checked, printing each figure:

- pins ride the body: each pinned garment vertex (rest position inside the --pin box of the rest
  OBJ, metres) keeps its distance from the body's surface: at every frame it differs from frame
  0's by at most 5 mm; and it slides along the skin by at most 2 cm: bound at frame 0 to the
  nearest body point (its triangle and barycentric coordinates), its distance from that same
  body point, transported by the skinning, differs from frame 0's by at most that (scenebake
  averages the pins' skin weights over the band, `--pin-smooth`, so a pin need not follow the
  one body point under it exactly);
- no garment vertex is more than --thickness inside the body (inside by the generalised winding
  number of the closed body, depth = distance to its surface);
- no edge is stretched or compressed past --max-strain (10 %) of its rest length (rest OBJ);
- the loop seam: the largest vertex distance between the first and the last frame is at most 1 cm.

Exits 1 when a check fails.
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender"))
import gltf_eval  # noqa: E402

PIN_TOLERANCE = 5e-3
# How far a pin may slide along the skin from the body point it started on, m.
PIN_SLIDE = 2e-2
STRAIN_LIMIT = 0.10
SEAM_LIMIT = 1e-2


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                verts.append([float(x) for x in w[1:4]])
            elif w[0] == "f":
                idx = [int(x.split("/")[0]) - 1 for x in w[1:]]
                for k in range(1, len(idx) - 1):
                    faces.append([idx[0], idx[k], idx[k + 1]])
    return np.array(verts), np.array(faces)


def closest_on_triangles(p, a, b, c):
    """Closest points of point p on triangles (a, b, c) (arrays (T, 3)), with barycentrics."""
    ab, ac, ap = b - a, c - a, p - a
    d00 = np.einsum("ij,ij->i", ab, ab)
    d01 = np.einsum("ij,ij->i", ab, ac)
    d11 = np.einsum("ij,ij->i", ac, ac)
    d20 = np.einsum("ij,ij->i", ap, ab)
    d21 = np.einsum("ij,ij->i", ap, ac)
    den = d00 * d11 - d01 * d01
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    u = 1 - v - w
    inside = (u >= 0) & (v >= 0) & (w >= 0)
    best = np.where(inside[:, None], u[:, None] * a + v[:, None] * b + w[:, None] * c, np.nan)
    bary = np.stack([u, v, w], axis=1)
    # Outside the face: the closest point on the three edges.
    for (x, y, i, j) in ((a, b, 0, 1), (b, c, 1, 2), (c, a, 2, 0)):
        e = y - x
        t = np.clip(np.einsum("ij,ij->i", p - x, e) / np.einsum("ij,ij->i", e, e), 0, 1)
        q = x + t[:, None] * e
        dq = np.linalg.norm(p - q, axis=1)
        db = np.linalg.norm(p - best, axis=1)
        take = ~inside & (np.isnan(db) | (dq < db))
        best[take] = q[take]
        bb = np.zeros((len(t), 3))
        bb[:, i] = 1 - t
        bb[:, j] = t
        bary[take] = bb[take]
    return best, bary


def nearest(p, pos, tris):
    a, b, c = pos[tris[:, 0]], pos[tris[:, 1]], pos[tris[:, 2]]
    q, bary = closest_on_triangles(p, a, b, c)
    d = np.linalg.norm(q - p, axis=1)
    k = int(np.argmin(d))
    return k, bary[k], d[k]


def winding(points, pos, tris):
    """Generalised winding number of each point w.r.t. the triangle soup (1 inside, 0 out)."""
    a = pos[tris[:, 0]][None] - points[:, None]
    b = pos[tris[:, 1]][None] - points[:, None]
    c = pos[tris[:, 2]][None] - points[:, None]
    la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
    det = np.einsum("pti,pti->pt", a, np.cross(b, c))
    dot = (la * lb * lc + np.einsum("pti,pti->pt", a, b) * lc
           + np.einsum("pti,pti->pt", b, c) * la + np.einsum("pti,pti->pt", c, a) * lb)
    return (2 * np.arctan2(det, dot)).sum(axis=1) / (4 * np.pi)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--garment", required=True, help="the garment's mesh node: name or #N")
    ap.add_argument("--body", required=True, nargs="+",
                    help="the body's mesh nodes, names or #N (several: their triangles together)")
    ap.add_argument("--rest", required=True)
    ap.add_argument("--units", type=float, default=1.0)
    ap.add_argument("--pin", required=True)
    ap.add_argument("--thickness", type=float, default=0.0)
    ap.add_argument("--max-strain", type=float, default=STRAIN_LIMIT,
                    help="largest edge strain accepted (default 0.10)")
    ap.add_argument("--exclude-joint", nargs="+", default=[],
                    help="skin joints (names or #N) whose part of the body is left out, as the "
                         "bake's --body-exclude leaves it out of the collider")
    ap.add_argument("--json")
    a = ap.parse_args()

    g = gltf_eval.Gltf(a.file)
    nodes = g.doc["nodes"]

    def mesh_node(name):
        """A mesh node by name, or by index as `#N` (unnamed nodes, as `scenebake inspect`
        lists them)."""
        if name.startswith("#"):
            try:
                i = int(name[1:])
            except ValueError:
                sys.exit(f"check_character: {name!r}: expected #N, a node index")
            if not 0 <= i < len(nodes) or "mesh" not in nodes[i]:
                sys.exit(f"check_character: {name}: no mesh node with that index "
                         f"({len(nodes)} nodes)")
            return i
        found = [i for i, n in enumerate(nodes) if n.get("name") == name and "mesh" in n]
        if not found:
            sys.exit(f"check_character: no mesh node named {name} (unnamed nodes: #N)")
        return found[0]

    garment = mesh_node(a.garment)
    bodies = [mesh_node(name) for name in a.body]

    def node_index(name):
        if name.startswith("#"):
            return int(name[1:])
        found = [i for i, n in enumerate(nodes) if n.get("name") == name]
        if not found:
            sys.exit(f"check_character: no node named {name}")
        return found[0]

    below = set()
    stack = [node_index(j) for j in a.exclude_joint]
    while stack:
        n = stack.pop()
        below.add(n)
        stack.extend(nodes[n].get("children", []))

    def kept(b, tris):
        """Body node b's triangles `tris` less those with a corner more than half on `below`."""
        if not below or "skin" not in nodes[b]:
            return tris
        joints = g.doc["skins"][nodes[b]["skin"]]["joints"]
        on = np.array([j in below for j in joints])
        part, total = [], []
        for prim in g.doc["meshes"][nodes[b]["mesh"]]["primitives"]:
            sets = [k for k in prim["attributes"] if k.startswith("JOINTS_")]
            n = len(g.accessor(prim["attributes"]["POSITION"]))
            pp, tt = np.zeros(n), np.zeros(n)
            for js in sets:
                J = g.accessor(prim["attributes"][js]).astype(np.int64)
                W = g.accessor(prim["attributes"]["WEIGHTS_" + js.split("_")[1]])
                pp += (W * on[J]).sum(axis=1)
                tt += W.sum(axis=1)
            part.append(pp)
            total.append(tt)
        held = np.concatenate(part) > 0.5 * np.concatenate(total)
        return tris[~held[tris].any(axis=1)]

    def body_at(t):
        pos, tris, base = [], [], 0
        for b in bodies:
            p, tr = g.evaluate(b, 0, t)
            pos.append(p)
            tris.append(kept(b, tr) + base)
            base += len(p)
        return np.concatenate(pos), np.concatenate(tris)

    rec = g.playback()
    fps, first, last = rec["fps"], rec["frame_start"], rec["frame_end"]
    rest, faces = read_obj(a.rest)
    box = np.array([float(x) for x in a.pin.split(",")]).reshape(2, 3)
    lo, hi = box.min(axis=0), box.max(axis=0)

    # The file's vertex order is its own (first use by its triangles); its triangles are the
    # OBJ's faces in order, which maps each file vertex to its OBJ vertex.
    _, file_tris = g.evaluate(garment, 0, first / fps)
    if file_tris.shape != faces.shape:
        sys.exit(f"check_character: {len(file_tris)} triangles in the file, {len(faces)} in the OBJ")
    to_obj = np.full(file_tris.max() + 1, -1)
    for ft, of in zip(file_tris, faces):
        for k in range(3):
            if to_obj[ft[k]] not in (-1, of[k]):
                sys.exit("check_character: the file's triangles do not follow the OBJ's faces")
            to_obj[ft[k]] = of[k]
    rest = rest[to_obj]
    pinned = np.where(np.all((rest >= lo) & (rest <= hi), axis=1))[0]
    edges = np.unique(np.sort(np.concatenate([file_tris[:, [0, 1]], file_tris[:, [1, 2]],
                                              file_tris[:, [2, 0]]]), axis=1), axis=0)
    rest_len = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)

    bindings = None
    worst_pin = worst_slide = worst_depth = worst_strain = 0.0
    stretch = compression = 0.0
    frames = []
    for f in range(first, last + 1):
        t = f / fps
        x, _ = g.evaluate(garment, 0, t)
        bpos, btris = body_at(t)
        x, bpos = x * a.units, bpos * a.units
        if len(x) != len(rest):
            sys.exit(f"check_character: the garment has {len(x)} vertices, the rest OBJ {len(rest)}")
        frames.append(x)
        if bindings is None:
            bindings = []
            for v in pinned:
                k, bary, d = nearest(x[v], bpos, btris)
                bindings.append((v, k, bary, d))
        for v, k, bary, d0 in bindings:
            q = bary @ bpos[btris[k]]
            worst_slide = max(worst_slide, abs(np.linalg.norm(x[v] - q) - d0))
            _, _, d = nearest(x[v], bpos, btris)
            worst_pin = max(worst_pin, abs(d - d0))
        w = winding(x, bpos, btris)
        for v in np.where(w > 0.5)[0]:
            _, _, d = nearest(x[v], bpos, btris)
            worst_depth = max(worst_depth, d)
        length = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
        strain = length / rest_len - 1
        stretch, compression = max(stretch, float(strain.max())), min(compression, float(strain.min()))
        worst_strain = max(stretch, -compression)
    seam = float(np.linalg.norm(frames[0] - frames[-1], axis=1).max())
    figures = {
        "frames": len(frames),
        "pinned": len(pinned),
        "pin_drift_m": float(worst_pin),
        "pin_slide_m": float(worst_slide),
        "deepest_inside_m": float(worst_depth),
        "thickness_m": a.thickness,
        "worst_strain": worst_strain,
        "stretch": stretch,
        "compression": compression,
        "loop_seam_m": seam,
    }
    print("check_character:", json.dumps(figures))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(figures, f, indent=1)
    failures = []
    if len(pinned) == 0:
        failures.append("no pinned vertex in the --pin box")
    if worst_pin > PIN_TOLERANCE:
        failures.append(f"a pin drifts {worst_pin * 1e3:.2f} mm off the body's surface")
    if worst_slide > PIN_SLIDE:
        failures.append(f"a pin slides {worst_slide * 1e3:.2f} mm from its body point")
    if worst_depth > a.thickness:
        failures.append(f"a vertex is {worst_depth * 1e3:.2f} mm inside the body")
    if worst_strain > a.max_strain:
        failures.append(f"an edge is strained {100 * worst_strain:.1f} %")
    if seam > SEAM_LIMIT:
        failures.append(f"the loop seam is {seam * 1e3:.1f} mm")
    for m in failures:
        print("check_character: FAIL:", m)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
