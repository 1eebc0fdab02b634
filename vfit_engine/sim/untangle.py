"""Untangle a garment from the body before the drape: move inside vertices out as a sheet.

MakeHuman clothes fitted to a body start partly inside it (~1 cm in the armpit crease on the
default body, more on a wider one). Pushing each such vertex out along its own closest-point
direction splits a crease: one vertex goes to the arm, its neighbour to the torso, and the
edge between them is torn open. Here the garment instead moves out along its *own* vertex
normal (the sheet's outward direction, smooth across the crease), a little per iteration,
with Provot strain-limit sweeps (Provot 1995) after each move so the neighbours follow
(the moved vertices are made heavier so the limiter drags the cloth after them rather
than pulling them back). No gravity, no velocity: the drape then starts at rest from the
result.
"""
from __future__ import annotations

import numpy as np
from scipy import sparse

from vfit_engine.geometry import PolygonNormals
from vfit_engine.kernels.strain_limit import limit_strain


def untangle(pos, face_verts, face_offsets, collider, spring_indices, max_len, skin, pinned=None,
             step=0.0005, sweeps=4, heavy=8.0, spread=8, decay=0.9, max_iterations=400):
    """Move garment vertices out of the body, keeping structural edges within their limit.

    Parameters
    ----------
    pos : (n, 3) float64, m
        Garment positions (not modified).
    face_verts : (k,) int64;  face_offsets : (m + 1,) int64
    collider : MeshCollider
        The body.
    spring_indices : (s, 2) int64;  max_len : (s,) float64, m
        Springs the limiter keeps at most ``max_len`` long.
    skin : float, m
        Clearance to reach.
    pinned : (p,) int64 or None
        Vertices that do not move.
    step : float, m
        Longest move of a vertex per iteration.
    sweeps : int
        Strain-limit sweeps per iteration.
    heavy : float
        Mass factor of the vertices being pushed (the limiter moves them ``heavy`` times less).
    spread, decay : int, float
        The pushes are diffused ``spread`` edges into the cloth around them (Jacobi passes of
        ``D <- decay * mean of the neighbours' D``, the pushed vertices held at their push), so a
        patch moves as a sheet instead of one vertex being torn from its neighbours.
    max_iterations : int

    Returns
    -------
    pos : (n, 3) float64, m
        Untangled positions.
    info : dict
        ``iterations``, ``inside_before`` / ``inside_after`` (vertices closer than ``skin``),
        ``flip`` (True: the polygons wind inward, so the outward normal is minus
        :func:`vfit_engine.geometry.vertex_normals`).
    """
    x = np.array(pos, dtype=np.float64, order="C")
    n = x.shape[0]
    free = np.ones(n, dtype=bool)
    if pinned is not None and len(pinned):
        free[np.asarray(pinned, dtype=np.int64)] = False
    idx = np.ascontiguousarray(spring_indices, dtype=np.int64)
    max_len = np.ascontiguousarray(max_len, dtype=np.float64)
    adj = sparse.coo_matrix((np.ones(2 * len(idx)), (np.r_[idx[:, 0], idx[:, 1]], np.r_[idx[:, 1], idx[:, 0]])),
                            shape=(n, n)).tocsr()
    deg = np.asarray(adj.sum(axis=1)).ravel()
    mean_op = sparse.diags(np.divide(decay, deg, out=np.zeros(n), where=deg > 0)) @ adj
    normals = PolygonNormals(face_verts, face_offsets)  # the topology once, not per iteration
    inside_before = None
    it = 0
    flip = None
    n_in = 0
    for it in range(max_iterations + 1):
        d, _, cn, _ = collider.query(x, max_out=skin, max_in=np.inf)
        # the relative tolerance keeps vertices already at the skin (to rounding) from counting
        inside = (d < skin * (1.0 - 1e-9)) & free
        n_in = int(np.count_nonzero(inside))
        if inside_before is None:
            inside_before = n_in
        if n_in == 0 or it == max_iterations:
            break
        gn = normals(x)
        if flip is None:
            # garments may be wound either way: orient by the vertices near the body
            near = np.isfinite(d) & (np.abs(d) < 0.05)
            flip = float(np.sum(np.einsum("ij,ij->i", gn[near], cn[near]))) < 0.0
        if flip:
            gn = -gn
        dirs = gn[inside]
        # where the sheet's normal points into the body (a fold) use the closest-point direction
        bad = np.einsum("ij,ij->i", dirs, cn[inside]) < 0.2
        dirs[bad] = cn[inside][bad]
        push = np.zeros((n, 3))
        push[inside] = np.minimum(step, skin - d[inside])[:, None] * dirs
        disp = push.copy()
        for _ in range(spread):
            disp = mean_op @ disp
            disp[inside] = push[inside]
        disp[~free] = 0.0
        x += disp
        w = np.where(free, 1.0, 0.0)
        w[inside] = 1.0 / heavy
        limit_strain(x, w, idx, max_len, iterations=sweeps, omega=1.0)
    if flip is None:
        d, _, cn, _ = collider.query(x, max_out=0.05, max_in=0.05)
        near = np.isfinite(d)
        flip = float(np.sum(np.einsum("ij,ij->i", normals(x)[near], cn[near]))) < 0
    return x, dict(iterations=it, inside_before=inside_before, inside_after=n_in, flip=bool(flip))
