"""Rotations as quaternions and rigid transforms as dual quaternions (Kavan et al. 2008).

Shared by skinning (:mod:`vfit_engine.body.skinning`) and garment transfer (:mod:`vfit_engine.garment.transfer`),
so it lives below both. Quaternions are (w, x, y, z), unit, Hamilton convention; batched NumPy.
The dual-quaternion helpers follow Kavan et al. 2008, "Geometric Skinning with Approximate Dual Quaternion
Blending".
"""
from __future__ import annotations

import numpy as np


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
