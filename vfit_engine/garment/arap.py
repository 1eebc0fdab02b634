"""Per-vertex rigid frames between two poses of one mesh (ARAP local step).

``arap_rotations`` finds, for every vertex of a mesh seen in a source and a target pose, the
rotation that maps its 1-ring edges as rigidly as possible (Sorkine & Alexa 2007, the local step
of "As-Rigid-As-Possible Surface Modeling", with cotangent weights). The (dual) quaternions that
blend them are in :mod:`vfit_engine.rotations`.

Everything is batched NumPy (one ``np.linalg.svd`` over (n, 3, 3)); on the hm08 body
(13,380 vertices) the rotations take ~30 ms, so no Numba kernel is needed.
"""
from __future__ import annotations

import numpy as np
from scipy import sparse

from vfit_engine.errors import InputError

#: Floor of the cotangent weights: obtuse triangles give negative cotangents, which would make the
#: weighted covariance indefinite; a small positive floor keeps every 1-ring edge in play.
MIN_COT_WEIGHT = 1e-3


def mesh_edges(tris):
    """Unique undirected edges of a triangle mesh.

    Parameters
    ----------
    tris : (t, 3) int64

    Returns
    -------
    edges : (e, 2) int64
        ``i < j``, sorted.
    tri_edges : (t, 3) int64
        Edge index of the edge opposite corner 0, 1, 2 of each triangle: (v1 v2), (v2 v0), (v0 v1).
    """
    tris = np.asarray(tris, dtype=np.int64)
    opp = np.stack([tris[:, [1, 2]], tris[:, [2, 0]], tris[:, [0, 1]]], axis=1).reshape(-1, 2)
    opp = np.sort(opp, axis=1)
    edges, inverse = np.unique(opp, axis=0, return_inverse=True)
    return edges, inverse.reshape(-1, 3).astype(np.int64)


def cotangent_weights(verts, tris, min_weight=MIN_COT_WEIGHT):
    """Cotangent edge weights ``w_ij = (cot a_ij + cot b_ij) / 2``, clamped to ``>= min_weight``.

    ``a_ij`` and ``b_ij`` are the angles opposite edge ij in its (one or two) triangles
    (Pinkall & Polthier 1993). Boundary edges have one term.

    Parameters
    ----------
    verts : (v, 3) float64, m
    tris : (t, 3) int64
    min_weight : float

    Returns
    -------
    edges : (e, 2) int64
    weights : (e,) float64, unit-free
    """
    verts = np.asarray(verts, dtype=np.float64)
    edges, tri_edges = mesh_edges(tris)
    p = verts[tris]  # (t, 3 corners, 3)
    cot = np.empty(tri_edges.shape)
    for k in range(3):
        u = p[:, (k + 1) % 3] - p[:, k]
        w = p[:, (k + 2) % 3] - p[:, k]
        cross = np.linalg.norm(np.cross(u, w), axis=1)
        # a zero-area triangle has no defined angle: give it no say (the floor keeps the edge)
        cot[:, k] = np.divide(np.einsum("ij,ij->i", u, w), cross, out=np.zeros(len(u)), where=cross > 0)
    weights = 0.5 * np.bincount(tri_edges.ravel(), weights=cot.ravel(), minlength=len(edges))
    return edges, np.maximum(weights, min_weight)


def edge_incidence(edges, n_verts):
    """Sparse (n_verts, e) matrix with a 1 at both ends of every edge."""
    e = len(edges)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([np.arange(e), np.arange(e)])
    return sparse.csr_matrix((np.ones(2 * e), (rows, cols)), shape=(n_verts, e))


def arap_rotations(source, target, edges, weights, incidence=None):
    """Best rotation of every vertex's 1-ring from ``source`` to ``target`` (ARAP local step).

    ``S_i = sum_j w_ij (p_j - p_i)(q_j - q_i)^T``; with ``S_i = U s V^T`` the rotation is
    ``R_i = V diag(1, 1, det(V U^T)) U^T`` (Sorkine & Alexa 2007; the last column's sign fixed so
    that ``det R_i = +1``), minimising ``sum_j w_ij |(q_j - q_i) - R_i (p_j - p_i)|^2``.

    Parameters
    ----------
    source, target : (v, 3) float64, m
        The same mesh in two shapes/poses.
    edges : (e, 2) int64
    weights : (e,) float64
        Edge weights (``cotangent_weights`` of the source).
    incidence : scipy.sparse matrix or None
        ``edge_incidence(edges, v)``, to reuse between calls.

    Returns
    -------
    (v, 3, 3) float64
        Rotation matrices, ``target edge ~= R @ source edge``. A vertex on no edge gets the identity.
    """
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    n = source.shape[0]
    if incidence is None:
        incidence = edge_incidence(edges, n)
    e_src = source[edges[:, 1]] - source[edges[:, 0]]
    e_dst = target[edges[:, 1]] - target[edges[:, 0]]
    # the edge seen from either end is (-e)(-e')^T = e e'^T: one outer product serves both ends
    outer = (weights[:, None, None] * e_src[:, :, None] * e_dst[:, None, :]).reshape(-1, 9)
    cov = np.asarray(incidence @ outer).reshape(n, 3, 3)
    u, _, vt = np.linalg.svd(cov)
    v = np.swapaxes(vt, 1, 2)
    ut = np.swapaxes(u, 1, 2)
    rot = v @ ut
    flip = np.linalg.det(rot) < 0
    if flip.any():
        v[flip, :, 2] *= -1.0
        rot[flip] = v[flip] @ ut[flip]
    lonely = np.asarray(incidence.sum(axis=1)).ravel() == 0
    rot[lonely] = np.eye(3)
    return rot


def check_points(a, name, n_rows=None):
    """(n, 3) finite float64 C-contiguous copy-or-view of ``a``, else InputError."""
    try:
        a = np.ascontiguousarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an (n, 3) array of numbers") from None
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"{name} must be an (n, 3) array, got shape {a.shape}")
    if n_rows is not None and a.shape[0] not in np.atleast_1d(n_rows):
        want = " or ".join(str(int(r)) for r in np.atleast_1d(n_rows))
        raise InputError(f"{name} must have {want} rows, got {a.shape[0]}")
    if not np.isfinite(a).all():
        raise InputError(f"{name} contains NaN or infinite values")
    return a
