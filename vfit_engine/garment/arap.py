"""Per-vertex rigid frames between two poses of one mesh (ARAP local step) and dual quaternions.

``arap_rotations`` finds, for every vertex of a mesh seen in a source and a target pose, the
rotation that maps its 1-ring edges as rigidly as possible (Sorkine & Alexa 2007, the local step
of "As-Rigid-As-Possible Surface Modeling", with cotangent weights). The dual-quaternion helpers
follow Kavan et al. 2008, "Geometric Skinning with Approximate Dual Quaternion Blending".

Everything is batched NumPy (one ``np.linalg.svd`` over (n, 3, 3)); on the hm08 body
(13,380 vertices) the rotations take ~30 ms, so no Numba kernel is needed.
Quaternions are (w, x, y, z), unit, Hamilton convention.
"""
from __future__ import annotations

import numpy as np

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
    from scipy import sparse

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


# ---------------------------------------------------------------------- quaternions
def rotation_to_quat(rot):
    """Unit quaternions (w, x, y, z) of rotation matrices (Shepperd 1978: the best-conditioned branch).

    Parameters
    ----------
    rot : (n, 3, 3) float64

    Returns
    -------
    (n, 4) float64
        With ``w >= 0`` on the w branch; otherwise the sign the branch gives.
    """
    rot = np.asarray(rot, dtype=np.float64)
    m = rot.reshape(-1, 3, 3)
    tr = np.trace(m, axis1=1, axis2=2)
    diag = np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    choice = np.argmax(np.concatenate([tr[:, None], diag], axis=1), axis=1)
    q = np.empty((len(m), 4))
    a = choice == 0
    s = np.sqrt(np.maximum(1.0 + tr[a], 0.0)) * 2.0
    q[a] = np.stack([0.25 * s, (m[a, 2, 1] - m[a, 1, 2]) / s, (m[a, 0, 2] - m[a, 2, 0]) / s,
                     (m[a, 1, 0] - m[a, 0, 1]) / s], axis=1)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        b = choice == i + 1
        if not b.any():
            continue
        mb = m[b]
        s = np.sqrt(np.maximum(1.0 + mb[:, i, i] - mb[:, j, j] - mb[:, k, k], 0.0)) * 2.0
        qb = np.empty((len(mb), 4))
        qb[:, 0] = (mb[:, k, j] - mb[:, j, k]) / s
        qb[:, 1 + i] = 0.25 * s
        qb[:, 1 + j] = (mb[:, j, i] + mb[:, i, j]) / s
        qb[:, 1 + k] = (mb[:, k, i] + mb[:, i, k]) / s
        q[b] = qb
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(rot.shape[:-2] + (4,))


def quat_to_rotation(q):
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) (w, x, y, z); ``q`` need not be unit."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def quat_mul(a, b):
    """Hamilton product ``a b`` of quaternions (..., 4) (w, x, y, z)."""
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    w = aw * bw - np.sum(av * bv, axis=-1, keepdims=True)
    v = aw * bv + bw * av + np.cross(av, bv)
    return np.concatenate([w, v], axis=-1)


def rigid_to_dual_quat(rot, trans):
    """Unit dual quaternions of rigid transforms ``x -> R x + t`` (Kavan et al. 2008).

    Parameters
    ----------
    rot : (n, 3, 3) float64
    trans : (n, 3) float64, m

    Returns
    -------
    real, dual : (n, 4) float64
        ``real`` the rotation quaternion r, ``dual = 0.5 (0, t) r``.
    """
    real = rotation_to_quat(rot)
    t = np.concatenate([np.zeros(trans.shape[:-1] + (1,)), trans], axis=-1)
    return real, 0.5 * quat_mul(t, real)


def dual_quat_to_rigid(real, dual):
    """Rotation and translation of (not necessarily unit) dual quaternions (Kavan et al. 2008, DLB).

    Both parts are divided by ``|real|``; ``t = 2 (w_r d_v - w_d r_v + r_v x d_v)`` is the vector part
    of ``2 d r*``, which ignores the component of ``d`` that breaks the unit condition.

    Parameters
    ----------
    real, dual : (..., 4) float64

    Returns
    -------
    rot : (..., 3, 3) float64
    trans : (..., 3) float64, m
    """
    norm = np.linalg.norm(real, axis=-1, keepdims=True)
    r = real / norm
    d = dual / norm
    trans = 2.0 * (r[..., :1] * d[..., 1:] - d[..., :1] * r[..., 1:] + np.cross(r[..., 1:], d[..., 1:]))
    return quat_to_rotation(r), trans


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
