"""An independent tape measure for tests: trimesh's plane section + scipy's convex hull.

It shares no code with vfit's kernels: the section comes from ``trimesh``, the
hull from ``scipy.spatial.ConvexHull``, the bands are re-derived here from
MEASUREMENTS.md and the ruler vertex lists.
"""
import json
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

RULERS = Path(__file__).resolve().parents[1] / "data" / "rulers.json"
BANDS = {  # name: (ruler, below, above, max|min) in metres, from shared/reference/MEASUREMENTS.md
    "bust": ("bust-circ", 0.03, 0.03, "max"),
    "underbust": ("underbust-circ", 0.02, 0.02, "min"),
    "hips": ("hips-circ", 0.04, 0.04, "max"),
}


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


def tape_measure(verts, quads):
    """ISO-style girths (m) of a body: bust, underbust, waist, hips, height, at 1 mm plane steps."""
    rulers = json.loads(RULERS.read_text())["rulers"]
    verts = np.asarray(verts)[:13380]
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    mesh = trimesh.Trimesh(verts, tris, process=False)
    mean_y = {k: verts[rulers[k]["vertex_indices"], 1].mean() for k in ("bust-circ", "underbust-circ", "hips-circ")}
    bands = {n: (mean_y[r] - lo, mean_y[r] + hi, mode) for n, (r, lo, hi, mode) in BANDS.items()}
    bands["waist"] = (*sorted((mean_y["hips-circ"], mean_y["underbust-circ"])), "min")
    out = {"height": float(verts[:, 1].max() - verts[:, 1].min())}
    for name, (lo, hi, mode) in bands.items():
        ys = np.linspace(lo, hi, int(np.ceil((hi - lo) / 0.001 - 1e-9)) + 1)
        g = np.array([torso_hull_girth(mesh, y) for y in ys])
        out[name] = float(np.nanmax(g) if mode == "max" else np.nanmin(g))
    return out


def ruler_lengths(verts):
    rulers = json.loads(RULERS.read_text())["rulers"]
    return {k: float(np.linalg.norm(np.diff(np.asarray(verts)[r["vertex_indices"]], axis=0), axis=1).sum())
            for k, r in rulers.items()}
