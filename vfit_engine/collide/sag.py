"""How far the body's small bumps rise between a cloth's contact points (:func:`convex_sag`).

The cloth is held out of the body at contact points a lattice spacing ``s`` apart
(:mod:`vfit_engine.sim.contact_points`), so a flat stretch of cloth rests on points up to ``r = s / sqrt(3)``
(the farthest a point of a triangular lattice is from its nearest node) from any feature under it. Where the
body is gently curved, the points' clearance covers the rise between them (``r^2 / (2 R)``: 0.4 mm on a
10 cm radius at r = 8.7 mm). A small bump is higher: a nipple rises 5-7 mm above the points round it, and a
taut top resting on them cuts into its tip (2.1 mm on a size-up bust at 15 mm spacing). The contacts
therefore treat the body as thicker there: a point whose closest body point is on such a bump keeps its
clearance from the bump's tip, not from the slope under it.

    rise_i,k = max over vertices j within r of i, on the same side of the body (n_i . n_j > SAME_SIDE),
               in the k-th of SECTORS directions round n_i:  (v_i - v_j) . n_i
    need_i   = max(0, min_k rise_i,k - allowance)
    sag_i    = min(cap, max over the same neighbours and i itself: need_j)

``rise_i,k`` is how far vertex i stands above neighbours up to r away in direction k (for a sphere of
radius R the cap height ``R - sqrt(R^2 - r^2)`` in every direction). Only a bump that falls away in every
direction counts (the smallest over the directions): along a ridge (an armpit's fold, a finger, a shin) the
cloth lies on points on the ridge itself, and thickening ridges tented every tight sleeve round the armpit
(strain up 0.4 points where the garment is tightest). The need is spread over the neighbours because a
contact point near a bump touches the body on its slope, up to r from its tip, and must keep the tip's
clearance there. The normals' test leaves out other sheets within r (the thigh across a crotch, a
neighbouring finger, the arm against the torso), whose points lie behind or beside the vertex, not under
it. ``allowance`` is what the contact points' own clearance already covers.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from vfit_engine.collide.body_mesh import mesh_normals

#: The depth (m) a bump may still cut into a cloth resting on the worst-placed lattice, beyond the points'
#: clearance: half the drape's 2 mm bar.
SAG_TOLERANCE = 0.001
#: The most (m) the body is thickened anywhere. A nipple rises 5-7 mm over 8.7 mm; thickened by all of it, a
#: top stands off the bust in a 5 mm tent. The worst-placed lattice is rare: at 15 mm spacing the measured cut
#: on a size-up bust was 2.1 mm where the rise predicts 6, and 2 mm of thickness holds it out entirely.
SAG_CAP = 0.002
#: Neighbours whose normals differ by more than ~72 degrees belong to another sheet of the body.
SAME_SIDE = 0.3
#: Directions round a vertex's normal a bump must fall away in.
SECTORS = 6


def convex_sag(verts, tris, radius, allowance, cap=SAG_CAP):
    """Per vertex, the extra clearance a cloth resting on points ``radius`` apart needs there (module docstring).

    Parameters
    ----------
    verts : (v, 3) float64, m
    tris : (t, 3) int64
    radius : float, m
        The farthest a body point lies from the nearest contact point (``spacing / sqrt(3)``).
    allowance : float, m
        The rise the contact points' clearance covers already.
    cap : float, m
        The most any vertex gets.

    Returns
    -------
    (v,) float64, m, >= 0
    """
    verts = np.ascontiguousarray(verts, dtype=np.float64)
    normals = mesh_normals(verts, tris)[3]
    sag = np.zeros(verts.shape[0])
    if not radius > 0:
        return sag
    pairs = cKDTree(verts).query_pairs(float(radius), output_type="ndarray")
    if not pairs.size:
        return sag
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    same = np.einsum("kd,kd->k", normals[i], normals[j]) > SAME_SIDE
    i, j = i[same], j[same]
    d = verts[j] - verts[i]
    n = normals[i]
    u, w = _tangents(normals)
    angle = np.arctan2(np.einsum("kd,kd->k", d, w[i]), np.einsum("kd,kd->k", d, u[i]))
    sector = np.minimum((angle + np.pi) * (SECTORS / (2 * np.pi)), SECTORS - 1).astype(np.int64)
    rise = np.full((verts.shape[0], SECTORS), -np.inf)
    np.maximum.at(rise, (i, sector), -np.einsum("kd,kd->k", d, n))
    need = np.maximum(rise.min(axis=1) - allowance, 0.0)  # no neighbour in some direction: -inf, no need
    sag = need.copy()
    np.maximum.at(sag, i, need[j])
    return np.minimum(sag, cap, out=sag)


def _tangents(normals):
    """Two unit tangents (u, w) per normal, u x w = n."""
    axis = np.zeros_like(normals)
    axis[np.arange(len(normals)), np.argmin(np.abs(normals), axis=1)] = 1.0
    u = np.cross(normals, axis)
    u /= np.maximum(np.linalg.norm(u, axis=1), 1e-300)[:, None]
    return u, np.cross(normals, u)
