"""An independent glTF 2.0 reader and evaluator in plain numpy (no Blender, no scenebake code).

It reads a .glb or .gltf (external, base64 and GLB buffers; sparse accessors; normalised
integer components), samples one animation at a time t (STEP, LINEAR with quaternion slerp,
CUBICSPLINE) and evaluates every mesh node the way the glTF specification defines it: nodes
the animation does not key sit at their node transforms; morph weights come from the animation
or mesh.weights; skinned vertices are sum_j w_j * world(joint_j) * IBM_j * p, with the mesh
node's own transform ignored.

Used by scripts/blender_check.py (inside Blender) to compare what Blender evaluates with what
the file says; runs with any python3 that has numpy:

    python3 scripts/blender/gltf_eval.py FILE [TIME]   # prints each mesh node's bounds at TIME
    python3 scripts/blender/gltf_eval.py --positions FILE T1 [T2 ...]

`--positions` prints JSON for scripts/three_check.mjs: every mesh node's world positions
(all primitives concatenated, x y z flattened) at each time T of the first animation:
`{"times": [...], "nodes": [{"node": i, "name": ..., "positions": [[...], ...]}]}`.
"""

import base64
import json
import math
import os
import struct
import sys

import numpy as np

COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
          5126: np.float32}
NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}


class Gltf:
    """A loaded document: `doc` (the JSON) and its buffers."""

    def __init__(self, path):
        self.path = path
        with open(path, "rb") as f:
            data = f.read()
        glb_bin = None
        if data[:4] == b"glTF":
            length = struct.unpack_from("<I", data, 8)[0]
            off = 12
            text = None
            while off < length:
                clen, ctype = struct.unpack_from("<I4s", data, off)
                chunk = data[off + 8:off + 8 + clen]
                if ctype == b"JSON":
                    text = chunk
                elif ctype == b"BIN\x00":
                    glb_bin = chunk
                off += 8 + clen
            self.doc = json.loads(text.decode("utf-8"))
        else:
            self.doc = json.loads(data.decode("utf-8-sig"))
        self.buffers = []
        for b in self.doc.get("buffers", []):
            uri = b.get("uri")
            if uri is None:
                self.buffers.append(glb_bin)
            elif uri.startswith("data:"):
                self.buffers.append(base64.b64decode(uri.split(",", 1)[1]))
            else:
                from urllib.parse import unquote
                with open(os.path.join(os.path.dirname(path), unquote(uri)), "rb") as f:
                    self.buffers.append(f.read())
        self._cache = {}
        self.parents = [None] * len(self.doc.get("nodes", []))
        for i, n in enumerate(self.doc.get("nodes", [])):
            for c in n.get("children", []):
                self.parents[c] = i

    # ---------------------------------------------------------------- accessors

    def _view_elements(self, view_index, offset, ctype, ncomp, count):
        view = self.doc["bufferViews"][view_index]
        buf = self.buffers[view["buffer"]]
        dtype = np.dtype(DTYPES[ctype]).newbyteorder("<")
        esize = dtype.itemsize * ncomp
        stride = view.get("byteStride") or esize
        start = view.get("byteOffset", 0) + offset
        if count == 0:
            return np.zeros((0, ncomp), dtype=dtype)
        if stride == esize:
            return np.frombuffer(buf, dtype=dtype, count=count * ncomp,
                                 offset=start).reshape(count, ncomp)
        raw = np.frombuffer(buf, dtype=np.uint8, count=stride * (count - 1) + esize, offset=start)
        rows = np.lib.stride_tricks.as_strided(raw, shape=(count, esize), strides=(stride, 1))
        out = np.ascontiguousarray(rows).view(dtype).reshape(count, ncomp)
        return out

    def accessor(self, index):
        """Accessor `index` as float64 (count, components), normalised components scaled."""
        if index in self._cache:
            return self._cache[index]
        acc = self.doc["accessors"][index]
        ctype, ncomp, count = acc["componentType"], COMPONENTS[acc["type"]], acc["count"]
        if "bufferView" in acc:
            data = self._view_elements(acc["bufferView"], acc.get("byteOffset", 0), ctype, ncomp,
                                       count)
        else:
            data = np.zeros((count, ncomp), dtype=DTYPES[ctype])
        data = data.astype(np.float64)
        sparse = acc.get("sparse")
        if sparse:
            n = sparse["count"]
            idx = self._view_elements(sparse["indices"]["bufferView"],
                                      sparse["indices"].get("byteOffset", 0),
                                      sparse["indices"]["componentType"], 1, n)[:, 0]
            vals = self._view_elements(sparse["values"]["bufferView"],
                                       sparse["values"].get("byteOffset", 0), ctype, ncomp, n)
            data[idx.astype(np.int64)] = vals.astype(np.float64)
        if acc.get("normalized") and ctype in NORM:
            data = np.maximum(data / NORM[ctype], -1.0)
        self._cache[index] = data
        return data

    # ---------------------------------------------------------------- animation

    def sample(self, anim_index, t):
        """{(node, path): value} for every channel of animation `anim_index` at time t."""
        out = {}
        if anim_index is None:
            return out
        anim = self.doc["animations"][anim_index]
        for ch in anim["channels"]:
            target = ch["target"]
            if "node" not in target:
                continue
            s = anim["samplers"][ch["sampler"]]
            times = self.accessor(s["input"])[:, 0]
            values = self.accessor(s["output"])
            interp = s.get("interpolation", "LINEAR")
            path = target["path"]
            if path == "weights":
                nw = values.size // (len(times) * (3 if interp == "CUBICSPLINE" else 1))
                values = values.reshape(-1, nw)
            out[(target["node"], path)] = sample_curve(times, values, interp, t,
                                                       path == "rotation")
        return out

    # ---------------------------------------------------------------- nodes

    def local(self, i, pose):
        n = self.doc["nodes"][i]
        if "matrix" in n:
            m = np.array(n["matrix"], dtype=np.float64).reshape(4, 4).T
            if not any(k[0] == i for k in pose):
                return m
            t, r, s = decompose(m)
        else:
            t = np.array(n.get("translation", [0, 0, 0]), dtype=np.float64)
            r = np.array(n.get("rotation", [0, 0, 0, 1]), dtype=np.float64)
            s = np.array(n.get("scale", [1, 1, 1]), dtype=np.float64)
        t = pose.get((i, "translation"), t)
        r = pose.get((i, "rotation"), r)
        s = pose.get((i, "scale"), s)
        return trs(t, r, s)

    def world(self, i, pose, memo):
        if i in memo:
            return memo[i]
        chain, cur, seen = [], i, set()
        while cur is not None and cur not in seen:
            seen.add(cur)
            chain.append(cur)
            cur = self.parents[cur]
        m = np.eye(4)
        for j in reversed(chain):
            m = m @ self.local(j, pose)
        memo[i] = m
        return m

    def mesh_nodes(self):
        return [i for i, n in enumerate(self.doc.get("nodes", [])) if "mesh" in n]

    def evaluate(self, node, anim_index, t):
        """World positions (V, 3) of mesh node `node`'s vertices (all primitives concatenated)
        at time t of animation `anim_index` (None: the rest pose), and the triangle index array
        (T, 3) over those vertices."""
        pose = self.sample(anim_index, t)
        memo = {}
        n = self.doc["nodes"][node]
        mesh = self.doc["meshes"][n["mesh"]]
        weights = pose.get((node, "weights"))
        if weights is None:
            weights = np.array(mesh.get("weights", []), dtype=np.float64)
        skin = self.doc["skins"][n["skin"]] if "skin" in n else None
        if skin is not None:
            joints = [self.world(j, pose, memo) for j in skin["joints"]]
            if "inverseBindMatrices" in skin:
                ibm = self.accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
            else:
                ibm = np.repeat(np.eye(4)[None], len(joints), axis=0)
            jm = np.array([j @ b for j, b in zip(joints, ibm)])
        else:
            node_m = self.world(node, pose, memo)
        positions, tris, base = [], [], 0
        for prim in mesh["primitives"]:
            p = self.accessor(prim["attributes"]["POSITION"]).copy()
            for w, target in zip(weights, prim.get("targets", [])):
                if w != 0.0 and "POSITION" in target:
                    p += w * self.accessor(target["POSITION"])
            if skin is not None:
                sets = sorted(k for k in prim["attributes"] if k.startswith("JOINTS_"))
                acc = np.zeros((len(p), 4, 4))
                ph = np.c_[p, np.ones(len(p))]
                for js in sets:
                    ws = "WEIGHTS_" + js.split("_")[1]
                    J = self.accessor(prim["attributes"][js]).astype(np.int64)
                    W = self.accessor(prim["attributes"][ws])
                    for c in range(4):
                        acc += W[:, c, None, None] * jm[J[:, c]]
                world = np.einsum("vij,vj->vi", acc, ph)[:, :3]
            else:
                world = (np.c_[p, np.ones(len(p))] @ node_m.T)[:, :3]
            positions.append(world)
            mode = prim.get("mode", 4)
            if mode == 4:
                if "indices" in prim:
                    idx = self.accessor(prim["indices"])[:, 0].astype(np.int64).reshape(-1, 3)
                else:
                    idx = np.arange(len(p)).reshape(-1, 3)
                tris.append(idx + base)
            base += len(p)
        return np.concatenate(positions), (np.concatenate(tris) if tris else np.zeros((0, 3), int))

    # ---------------------------------------------------------------- asset.extras

    def playback(self):
        """asset.extras.scenebake, or None."""
        return ((self.doc.get("asset") or {}).get("extras") or {}).get("scenebake")


def sample_curve(times, values, interp, t, rotation):
    n = len(times)
    cubic = interp == "CUBICSPLINE"
    val = (lambda k: values[3 * k + 1]) if cubic else (lambda k: values[k])
    if t <= times[0] or n == 1:
        return val(0)
    if t >= times[-1]:
        return val(n - 1)
    k = int(np.searchsorted(times, t, side="right")) - 1
    t0, t1 = times[k], times[k + 1]
    u = (t - t0) / (t1 - t0)
    if interp == "STEP":
        return val(k)
    if cubic:
        d = t1 - t0
        p0, m0 = values[3 * k + 1], values[3 * k + 2] * d
        p1, m1 = values[3 * (k + 1) + 1], values[3 * (k + 1)] * d
        u2, u3 = u * u, u * u * u
        v = (2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1
        return v / np.linalg.norm(v) if rotation else v
    a, b = val(k), val(k + 1)
    if rotation:
        return slerp(a, b, u)
    return a * (1 - u) + b * u


def slerp(a, b, u):
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    d = float(np.dot(a, b))
    if d < 0:
        b, d = -b, -d
    if d > 0.9995:
        q = a + u * (b - a)
        return q / np.linalg.norm(q)
    th = math.acos(min(d, 1.0))
    return (math.sin((1 - u) * th) * a + math.sin(u * th) * b) / math.sin(th)


def quat_matrix(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def trs(t, r, s):
    m = np.eye(4)
    m[:3, :3] = quat_matrix(np.asarray(r, dtype=np.float64)) * np.asarray(s, dtype=np.float64)
    m[:3, 3] = t
    return m


def decompose(m):
    t = m[:3, 3].copy()
    s = np.linalg.norm(m[:3, :3], axis=0)
    r3 = m[:3, :3] / s
    if np.linalg.det(r3) < 0:
        s[0], r3[:, 0] = -s[0], -r3[:, 0]
    w = math.sqrt(max(0.0, 1 + r3[0, 0] + r3[1, 1] + r3[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + r3[0, 0] - r3[1, 1] - r3[2, 2])) / 2, r3[2, 1] - r3[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - r3[0, 0] + r3[1, 1] - r3[2, 2])) / 2, r3[0, 2] - r3[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - r3[0, 0] - r3[1, 1] + r3[2, 2])) / 2, r3[1, 0] - r3[0, 1])
    return t, np.array([x, y, z, w]), s


def vertex_normals(positions, tris):
    """Unit vertex normals, each face's unit normal weighted by its corner angle at the vertex
    (as Blender computes them), welding vertices at the same position (UV seams)."""
    key = np.round(positions * 1e6).astype(np.int64)
    _, weld = np.unique(key, axis=0, return_inverse=True)
    weld = weld.reshape(-1)
    p = [positions[tris[:, k]] for k in range(3)]
    fn = np.cross(p[1] - p[0], p[2] - p[0])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    acc = np.zeros((weld.max() + 1, 3))
    for k in range(3):
        a = p[(k + 1) % 3] - p[k]
        b = p[(k + 2) % 3] - p[k]
        a /= np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-300)
        b /= np.maximum(np.linalg.norm(b, axis=1, keepdims=True), 1e-300)
        angle = np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))
        np.add.at(acc, weld[tris[:, k]], fn * angle[:, None])
    n = acc[weld]
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)


def file_normals(g, node, anim, t):
    """The NORMAL a viewer applies at time t (base + weighted NORMAL deltas), normalised, or
    None when the mesh has no NORMAL."""
    n = g.doc["nodes"][node]
    mesh = g.doc["meshes"][n["mesh"]]
    weights = g.sample(anim, t).get((node, "weights"))
    if weights is None:
        weights = np.array(mesh.get("weights", []), dtype=np.float64)
    out = []
    for prim in mesh["primitives"]:
        if "NORMAL" not in prim["attributes"]:
            return None
        v = g.accessor(prim["attributes"]["NORMAL"]).copy()
        for w, target in zip(weights, prim.get("targets", [])):
            if w != 0.0 and "NORMAL" in target:
                v += w * g.accessor(target["NORMAL"])
        out.append(v)
    v = np.concatenate(out)
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)


def positions_json(path, times):
    """`--positions`: what the file says every mesh node shows at each time (first animation)."""
    g = Gltf(path)
    anim = 0 if g.doc.get("animations") else None
    nodes = []
    for node in g.mesh_nodes():
        frames = [g.evaluate(node, anim, t)[0].reshape(-1).tolist() for t in times]
        nodes.append({"node": node, "name": g.doc["nodes"][node].get("name"), "positions": frames})
    json.dump({"times": times, "nodes": nodes}, sys.stdout)


def main():
    if sys.argv[1] == "--positions":
        positions_json(sys.argv[2], [float(t) for t in sys.argv[3:]])
        return
    g = Gltf(sys.argv[1])
    t = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
    anim = 0 if g.doc.get("animations") else None
    print("playback:", g.playback())
    for node in g.mesh_nodes():
        p, tris = g.evaluate(node, anim, t)
        print(f"node {node} ({g.doc['nodes'][node].get('name')}): {len(p)} vertices, "
              f"{len(tris)} triangles, min {p.min(axis=0).round(4)}, max {p.max(axis=0).round(4)}")


if __name__ == "__main__":
    main()
