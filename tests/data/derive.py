"""Make the derived test meshes of ``tests/data`` from the COMPAS samples in ``tests/data/compas``.

Run once by hand (``python tests/data/derive.py``); the suite reads the written OBJ files and never
runs this. Every step is deterministic; see ``tests/data/README.md`` for what each file is.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SRC = HERE / "compas"


def read_obj(path: Path) -> tuple[np.ndarray, list[list[int]]]:
    v, f = [], []
    for line in path.read_text().splitlines():
        p = line.split()
        if p and p[0] == "v":
            v.append([float(t) for t in p[1:4]])
        elif p and p[0] == "f":
            f.append([int(t.split("/")[0]) - 1 for t in p[1:]])
    return np.array(v), f


def write_obj(path: Path, v: np.ndarray, faces: list[list[int]], note: str) -> None:
    lines = [f"# {note}", "# unit: mm"]
    lines += [f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in v]
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")


def catmull_clark(v: np.ndarray, polys: list[list[int]]) -> tuple[np.ndarray, list[list[int]]]:
    """One Catmull–Clark step (boundary edges and vertices: the cubic B-spline rules)."""
    n = len(v)
    fp = np.array([v[p].mean(axis=0) for p in polys])
    edge_faces: dict[tuple[int, int], list[int]] = {}
    for fi, p in enumerate(polys):
        for k in range(len(p)):
            a, b = p[k], p[(k + 1) % len(p)]
            edge_faces.setdefault((min(a, b), max(a, b)), []).append(fi)
    edges = sorted(edge_faces)
    eid = {e: i for i, e in enumerate(edges)}
    ep = np.empty((len(edges), 3))
    for i, (a, b) in enumerate(edges):
        fs = edge_faces[(a, b)]
        ep[i] = (v[a] + v[b] + fp[fs].sum(axis=0)) / 4 if len(fs) == 2 else (v[a] + v[b]) / 2
    nv = v.copy()
    vf: list[list[int]] = [[] for _ in range(n)]
    ve: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    for fi, p in enumerate(polys):
        for a in p:
            vf[a].append(fi)
    for e in edges:
        ve[e[0]].append(e)
        ve[e[1]].append(e)
    for i in range(n):
        bnd = [e for e in ve[i] if len(edge_faces[e]) == 1]
        if bnd:
            if len(bnd) == 2:
                o = [e[0] + e[1] - i for e in bnd]
                nv[i] = 0.75 * v[i] + 0.125 * (v[o[0]] + v[o[1]])
            continue
        k = len(ve[i])
        F = fp[vf[i]].mean(axis=0)
        R = np.mean([(v[a] + v[b]) / 2 for a, b in ve[i]], axis=0)
        nv[i] = (F + 2 * R + (k - 3) * v[i]) / k
    out_v = np.vstack([nv, ep, fp])
    quads = []
    for fi, p in enumerate(polys):
        k = len(p)
        for j in range(k):
            a, prev, nxt = p[j], p[(j - 1) % k], p[(j + 1) % k]
            quads.append([a, n + eid[(min(a, nxt), max(a, nxt))], n + len(edges) + fi,
                          n + eid[(min(a, prev), max(a, prev))]])
    return out_v, quads


def main() -> None:
    # closed organic: the COMPAS cube, Catmull–Clark three times (a rounded box, 8 valence-3 poles)
    lines = (SRC / "cube.off").read_text().split("\n")
    nv_, nf_ = (int(t) for t in lines[1].split()[:2])
    v = np.array([[float(t) for t in lines[2 + i].split()] for i in range(nv_)]) * 1000.0
    polys = [[int(t) for t in lines[2 + nv_ + i].split()[1:]] for i in range(nf_)]
    for _ in range(3):
        v, polys = catmull_clark(v, polys)
    write_obj(HERE / "rounded_box.obj", v, polys, "COMPAS cube.off (MIT), scaled to 1000 mm, Catmull-Clark x3")
    # extraordinary vertices: the COMPAS 100-face polygon mesh, one Catmull–Clark step (all quads)
    d = json.loads((SRC / "mesh_100_faces.json").read_text())
    d = d.get("data", d)
    keys = sorted(d["vertex"], key=int)
    index = {k: i for i, k in enumerate(keys)}
    v = np.array([[d["vertex"][k][c] for c in "xyz"] for k in keys])
    polys = [[index[str(x)] for x in d["face"][f]] for f in sorted(d["face"], key=int)]
    used = sorted({i for p in polys for i in p})
    remap = {o: i for i, o in enumerate(used)}
    v, polys = v[used], [[remap[i] for i in p] for p in polys]

    def area(p: list[int]) -> float:  # signed, in the xy plane (the sample is flat)
        q = v[p, :2]
        return float(np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1]))

    polys = [p if area(p) > 0 else p[::-1] for p in polys]  # the sample mixes orientations
    v, polys = catmull_clark(v, polys)
    c = v[:, :2].mean(axis=0)
    r2 = ((v[:, :2] - c) ** 2).sum(axis=1)
    v[:, 2] = 60.0 * np.exp(-r2 / r2.max() * 2.0)  # a gentle dome, so it is not flat
    write_obj(HERE / "polygon_quads.obj", v, polys,
              "COMPAS mesh_100_faces.json (MIT), Catmull-Clark x1, lifted to a dome z = 60 exp(-2 r^2/R^2)")
    # a hole: the COMPAS quadmesh (an unordered 10 x 10 grid) without the 2 x 2 quads at its centre
    v, polys = read_obj(SRC / "quadmesh.obj")
    centre = v.mean(axis=0)
    fc = np.array([v[p].mean(axis=0) for p in polys])
    d2 = np.linalg.norm(fc[:, :2] - centre[:, None][:2, 0], axis=1)
    keep = np.argsort(d2)[4:]
    polys = [polys[i] for i in sorted(keep)]
    used = sorted({i for p in polys for i in p})
    remap = {o: i for i, o in enumerate(used)}
    write_obj(HERE / "quadmesh_hole.obj", v[used], [[remap[i] for i in p] for p in polys],
              "COMPAS quadmesh.obj (MIT) without its 4 central quads")
    # MIQ-like staircase boundary: a 24 x 24 grid on the COMPAS hypar's saddle, cut to a disc of quads
    hv, _ = read_obj(SRC / "hypar.obj")
    lo, hi = hv.min(axis=0), hv.max(axis=0)
    n = 24
    s, t = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    x = lo[0] + s * (hi[0] - lo[0])
    y = lo[1] + t * (hi[1] - lo[1])
    z = (hi[2] - lo[2]) * (2 * s - 1) * (2 * t - 1) + 0.05 * (hi[0] - lo[0]) * np.sin(5 * s) * np.cos(4 * t)
    gv = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    polys = []
    for i in range(n - 1):
        for j in range(n - 1):
            cs, ct = (i + 0.5) / (n - 1) - 0.5, (j + 0.5) / (n - 1) - 0.5
            if cs * cs / 0.23 + ct * ct / 0.16 < 1.0:  # an ellipse, rotated by the cell staircase
                polys.append([i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1])
    used = sorted({i for p in polys for i in p})
    remap = {o: i for i, o in enumerate(used)}
    write_obj(HERE / "staircase_saddle.obj", gv[used], [[remap[i] for i in p] for p in polys],
              "a 24 x 24 grid over the bounding box of COMPAS hypar.obj (MIT) on a wavy saddle, "
              "cut to the quads inside an ellipse: a staircase boundary")


if __name__ == "__main__":
    main()
