"""An independent tape measure for tests: trimesh's plane section + scipy's convex hull.

It shares no code with vfit's kernels: the section comes from ``trimesh``, the
hull from ``scipy.spatial.ConvexHull``, the bands are re-derived here from
MEASUREMENTS.md and the ruler vertex lists; the bust points from the rig's skin
weights read straight from ``data/hm08.npz`` (README, "Measurement definitions").
"""
import json
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, cKDTree

DATA = Path(__file__).resolve().parents[1] / "data"
RULERS = DATA / "rulers.json"
BANDS = {  # name: (ruler, below, above, max|min) in metres, from shared/reference/MEASUREMENTS.md
    "underbust": ("underbust-circ", 0.02, 0.02, "min"),
    "hips": ("hips-circ", 0.04, 0.04, "max"),
}


def breast_vertices():
    """Per side, the body vertices whose largest skin weight (> 0.5) is the breast.L / breast.R bone."""
    with np.load(DATA / "hm08.npz") as d:
        names = [str(b) for b in d["bone_names"]]
        bone, vert, w = d["skin_bone"].astype(int), d["skin_vertex"].astype(int), d["skin_weight"].astype(float)
    out = []
    for side in ("breast.L", "breast.R"):
        b = names.index(side)
        best = {}
        for bb, vv, ww in zip(bone, vert, w):
            if vv < 13380 and ww > best.get(vv, (0.0, -1))[0]:
                best[vv] = (ww, bb)
        out.append(np.array(sorted(v for v, (ww, bb) in best.items() if bb == b and ww > 0.5)))
    return out


def _apart(mesh, y):
    """Torso and both arms apart: one loop across x = 0, and another loop wholly on each side of it."""
    path = mesh.section(plane_origin=[0, y, 0], plane_normal=[0, 1, 0])
    if path is None:
        return False
    xs = [(float(np.min(d[:, 0])), float(np.max(d[:, 0]))) for d in map(np.asarray, path.discrete)]
    torso = [r for r in xs if r[0] <= 0.0 <= r[1]]
    return len(torso) == 1 and any(r[1] < torso[0][0] for r in xs) and any(r[0] > torso[0][1] for r in xs)


def bust_band(mesh, verts, breasts, chest=False):
    """(lo, hi) m: from the bust points' mean height (most anterior breast vertex per side, 10 um below)
    up, in 1 mm steps, to the last plane whose section shows the torso and both arms apart, at most 3 cm
    up (a man's ``chest``: 15 cm, just under his armpits); where they are not apart there, the one plane
    just under the armpits (the first apart plane going down)."""
    y = np.mean([verts[idx[np.argmax(verts[idx, 2])], 1] for idx in breasts]) - 1e-5
    steps = np.arange(1, 151) * 0.001
    if _apart(mesh, y):
        top = y
        for d in steps if chest else steps[:30]:  # at most 3 cm above the bust points (a bust)
            if not _apart(mesh, y + d):
                break
            top = y + d
        return float(y), float(top)
    for d in steps:
        if _apart(mesh, y - d):
            return float(y - d), float(y - d)
    return float(y), float(y)


def torso_hull_girth(mesh: trimesh.Trimesh, y: float) -> float:
    """Convex-hull perimeter (m) of the torso loop of the section at height y (x = 0 inside its x-range)."""
    path = mesh.section(plane_origin=[0, y, 0], plane_normal=[0, 1, 0])
    if path is None:
        return float("nan")
    loops = [np.asarray(d)[:, [0, 2]] for d in path.discrete]
    holding = [p for p in loops if p[:, 0].min() <= 0.0 <= p[:, 0].max()]
    if not holding:
        return float("nan")

    def area(p):
        return 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))

    pts = max(holding, key=area)
    hull = pts[ConvexHull(pts).vertices]
    return float(np.linalg.norm(np.roll(hull, -1, axis=0) - hull, axis=1).sum())


def tape_measure(verts, quads, breasts=None, chest=False, planes=False):
    """ISO-style girths (m) of a body: bust, underbust, waist, hips, height, at 1 mm plane steps.

    ``breasts``: :func:`breast_vertices` (read once and passed in by callers measuring many bodies).
    ``chest``: a man's body, whose ``bust`` is his chest girth (ISO 8559-1 / EN 13402-1): the tape under the
    armpits, in the one plane at the top of his band. ``planes``: also return the height (m) of each girth's
    plane (the 1 mm step where it was found).
    """
    rulers = json.loads(RULERS.read_text())["rulers"]
    verts = np.asarray(verts)[:13380]
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    mesh = trimesh.Trimesh(verts, tris, process=False)
    bust_lo, bust_hi = bust_band(mesh, verts, breast_vertices() if breasts is None else breasts, chest)
    mean_y = {k: verts[rulers[k]["vertex_indices"], 1].mean() for k in ("underbust-circ", "hips-circ")}
    bands = {n: (mean_y[r] - lo, mean_y[r] + hi, mode) for n, (r, lo, hi, mode) in BANDS.items()}
    lo, hi, mode = bands["underbust"]
    hi = min(hi, bust_lo - 0.01)  # below the bust points by 1 cm, and 4 cm long at least
    bands["underbust"] = (min(lo, hi - 0.04), hi, mode)
    bands["waist"] = (*sorted((mean_y["hips-circ"], mean_y["underbust-circ"])), "min")
    bands["bust"] = (bust_hi if chest else bust_lo, bust_hi, "max")
    out, at = {"height": float(verts[:, 1].max() - verts[:, 1].min())}, {}
    for name, (lo, hi, mode) in bands.items():
        ys = np.linspace(lo, hi, int(np.ceil((hi - lo) / 0.001 - 1e-9)) + 1)
        g = np.array([torso_hull_girth(mesh, y) for y in ys])
        i = int(np.nanargmax(g) if mode == "max" else np.nanargmin(g))
        out[name], at[name] = float(g[i]), float(ys[i])
    return (out, at) if planes else out


def _inside(poly, p):
    """Is the point ``p`` (2,) inside the closed polygon ``poly`` (k, 2)? (even-odd rule)"""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (a[:, 1] > p[1]) != (b[:, 1] > p[1])
    x = a[:, 0] + (p[1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / np.where(cross, b[:, 1] - a[:, 1], 1.0)
    return bool(np.count_nonzero(cross & (x > p[0])) % 2)


def _dense(loop, step=0.0005):
    """The closed polygon ``loop`` (k, 2) resampled to points at most ``step`` (m) apart along it."""
    b = np.roll(loop, -1, axis=0)
    n = np.maximum(np.ceil(np.linalg.norm(b - loop, axis=1) / step).astype(int), 1)
    return np.concatenate([a + np.outer(np.arange(k) / k, e - a) for a, e, k in zip(loop, b, n)])


def cloth_torso_tape(cloth: trimesh.Trimesh, body: trimesh.Trimesh, y: float) -> float:
    """Tape (m) round a draped garment's torso loop at height ``y``, over the cloth.

    The body's section there (trimesh): its torso loop (the largest across x = 0) and its other loops
    (arms, hands). The cloth's section (trimesh): its loops round the torso's centre and its open chains (a
    shirt whose sleeves are pieces of their own, cut through its armholes); of their points, those
    nearer the torso loop than any other body loop (where the plane runs through a shirt's armholes its loop
    goes round the sleeves too); the perimeter of their convex hull (scipy). NaN where the cloth does not go
    round the torso.
    """
    def section(mesh):
        """(points (k, 2), closed) of every closed curve and open chain of the section."""
        path = mesh.section(plane_origin=[0, y, 0], plane_normal=[0, 1, 0])
        if path is None:
            return []
        out = [(np.asarray(d)[:, [0, 2]], True) for d in path.discrete]
        in_paths = {i for p in path.paths for i in p}
        for i, ent in enumerate(path.entities):  # the open chains (a sleeve that is its own piece)
            if i not in in_paths:
                out.append((np.asarray(path.vertices[ent.points])[:, [0, 2]], False))
        return out

    def area(p):
        return 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))

    body_loops = [p for p, _ in section(body)]
    holding = [i for i, p in enumerate(body_loops) if p[:, 0].min() <= 0.0 <= p[:, 0].max()]
    if not holding:
        return float("nan")
    t = max(holding, key=lambda i: area(body_loops[i]))
    torso = body_loops[t]
    centre = torso[ConvexHull(torso).vertices].mean(axis=0)
    near_torso = cKDTree(_dense(torso))
    others = [p for i, p in enumerate(body_loops) if i != t]
    near_other = cKDTree(np.concatenate([_dense(p) for p in others])) if others else None
    kept = []
    for loop, closed in section(cloth):
        if closed and (len(loop) < 3 or not _inside(loop, centre)):
            continue
        if near_other is not None:
            loop = loop[near_torso.query(loop)[0] <= near_other.query(loop)[0]]
        kept.append(loop)
    if not kept:
        return float("nan")
    return float(ConvexHull(np.concatenate(kept)).area)  # a 2-D hull's "area" is its perimeter


def ruler_lengths(verts):
    rulers = json.loads(RULERS.read_text())["rulers"]
    return {k: float(np.linalg.norm(np.diff(np.asarray(verts)[r["vertex_indices"]], axis=0), axis=1).sum())
            for k, r in rulers.items()}
