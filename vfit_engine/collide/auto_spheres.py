"""Spheres fitted automatically to a body, for the fast approximate ``--collider spheres``.

Method (a greedy medial-sphere cover, in the spirit of sphere-tree construction from medial
samples, Bradshaw & O'Sullivan 2004):

1. candidate centres: a regular grid (``spacing``) over the body's bounding box, plus points along
   the skeleton's bones when joint centres are given; each candidate inside the body gets the
   largest inscribed radius there, ``r = -d`` (``d`` the exact signed distance to the body mesh),
   so every sphere lies inside the body;
2. a body vertex is *covered* by a sphere when it is within ``r + tolerance`` of its centre;
3. spheres are chosen greedily, each time the candidate covering the most still-uncovered
   vertices, until ``coverage`` of the vertices is covered or ``max_spheres`` are chosen.

Nothing is placed by hand: the same code fits a morphed body. Spheres underestimate the body
between them (by up to ``tolerance``), which the collider's relative skin makes up for.
"""
from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from vfit_engine.collide.body_mesh import MeshCollider
from vfit_engine.errors import InputError

#: Candidate grid spacing, m.
SPACING = 0.02
#: A vertex within r + TOLERANCE of a centre counts as covered, m.
TOLERANCE = 0.006
#: Smallest sphere kept, m (fingers and toes are thinner; garments rarely reach them).
MIN_RADIUS = 0.008


def bone_points(model, verts, step=0.02):
    """Points along the default rig's bones of a shaped body (m), ``(k, 3)`` float64.

    Bone ends are placed like MakeHuman does: the centre of a joint cube (``CUBE``), one vertex
    (``VERTEX``) or the mean of vertices (``MEAN``).

    Parameters
    ----------
    model : BodyModel
    verts : (19158, 3) float64, m
        All vertices, helpers included (joint cubes are helpers).
    step : float, m
    """
    joints = model.joint_centres(verts)

    def place(spec):
        s = spec.get("strategy")
        if s == "CUBE":
            return joints.get(spec.get("cube_name"))
        if s == "VERTEX":
            return verts[int(spec["vertex_index"])]
        if s == "MEAN":
            return verts[np.asarray(spec["vertex_indices"], dtype=np.int64)].mean(axis=0)
        return None

    pts = []
    for bone in model.rig.values():
        a, b = place(bone["head"]), place(bone["tail"])
        if a is None or b is None:
            continue
        n = max(int(np.linalg.norm(b - a) / step), 1)
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        pts.append(a + t * (b - a))
    return np.concatenate(pts) if pts else np.zeros((0, 3))


def fit_spheres(body_verts, body_tris, collider=None, extra_points=None, spacing=SPACING, tolerance=TOLERANCE,
                coverage=0.995, max_spheres=400, min_radius=MIN_RADIUS):
    """Fit inscribed spheres covering a body (module docstring).

    Parameters
    ----------
    body_verts : (N, 3) float64, m
    body_tris : (T, 3) int64
        Closed, outward-wound body surface.
    collider : MeshCollider or None
        An exact collider on the same body (built when None).
    extra_points : (k, 3) float64 m or None
        More candidate centres (e.g. :func:`bone_points`).
    spacing, tolerance, min_radius : float, m
    coverage : float
        Fraction of surface vertices to cover before stopping.
    max_spheres : int

    Returns
    -------
    centres : (s, 3) float64, m
    radii : (s,) float64, m
    """
    v = np.ascontiguousarray(body_verts, dtype=np.float64)
    tris = np.ascontiguousarray(body_tris, dtype=np.int64)
    if collider is None:
        collider = MeshCollider(v, tris)
    surf = v[np.unique(tris)]
    lo, hi = surf.min(axis=0), surf.max(axis=0)
    axes = [np.arange(lo[k] + 0.5 * spacing, hi[k], spacing) for k in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    if extra_points is not None and len(extra_points):
        grid = np.concatenate([grid, np.asarray(extra_points, dtype=np.float64).reshape(-1, 3)])
    d, _, _, _ = collider.query(grid, max_out=0.0, max_in=float(np.max(hi - lo)))
    keep = np.isfinite(d) & (-d >= min_radius)
    centres, radii = grid[keep], -d[keep]
    if centres.shape[0] == 0:
        raise InputError("cannot fit spheres: the body has no interior thicker than "
                         f"{2 * min_radius * 1000:.0f} mm")
    tree = cKDTree(surf)
    rows, cols = [], []
    for i, hits in enumerate(tree.query_ball_point(centres, radii + tolerance)):
        rows.append(np.full(len(hits), i, dtype=np.int64))
        cols.append(np.asarray(hits, dtype=np.int64))
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    cover = sparse.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(centres.shape[0], surf.shape[0]))
    uncovered = np.ones(surf.shape[0])
    chosen = []
    target = (1.0 - coverage) * surf.shape[0]
    while uncovered.sum() > target and len(chosen) < max_spheres:
        gain = cover @ uncovered
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        chosen.append(best)
        uncovered[cover.indices[cover.indptr[best]:cover.indptr[best + 1]]] = 0.0
    chosen = np.array(chosen, dtype=np.int64)
    return np.ascontiguousarray(centres[chosen]), np.ascontiguousarray(radii[chosen])
