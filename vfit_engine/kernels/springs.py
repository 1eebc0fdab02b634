"""Numba kernels: damped Hooke spring forces of a mass-spring cloth.

For a spring (i, j) with rest length ``l0``, stiffness ``k`` and damping ``kd``::

    d = x_j - x_i,   l = |d|,   u = d / l
    v = (x - x_prev) / dt                       (Verlet backward-difference velocity)
    f_i = [k (l - l0) + kd ((v_j - v_i) . u)] u,    f_j = -f_i

(Provot 1995, "Deformation constraints in a mass-spring model to describe rigid
cloth behavior"; Baraff & Witkin 1998 for the damping along the spring.) The pair
of forces sums to zero and acts along the spring axis.

Two forms: a serial scatter over springs (:func:`eval_spring_forces`) and a
race-free gather over each vertex's springs in CSR order
(:func:`_vertex_spring_force`, used by the fused substep kernel in
:mod:`vfit_engine.kernels.integrate`, which may run it under ``prange``).
"""
import math

import numpy as np

from vfit_engine._jit import njit


@njit
def _vertex_spring_force(x, xp, inv_dt, i, adj_off, adj_j, adj_rest, adj_k, adj_kd):
    """Sum of the spring forces on vertex ``i`` over its CSR entries; returns (fx, fy, fz), N."""
    xi0 = x[i, 0]
    xi1 = x[i, 1]
    xi2 = x[i, 2]
    vi0 = (xi0 - xp[i, 0]) * inv_dt
    vi1 = (xi1 - xp[i, 1]) * inv_dt
    vi2 = (xi2 - xp[i, 2]) * inv_dt
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    for a in range(adj_off[i], adj_off[i + 1]):
        j = adj_j[a]
        d0 = x[j, 0] - xi0
        d1 = x[j, 1] - xi1
        d2 = x[j, 2] - xi2
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if length <= 0.0:
            continue  # coincident ends: no direction, no force
        inv_l = 1.0 / length
        u0 = d0 * inv_l
        u1 = d1 * inv_l
        u2 = d2 * inv_l
        vr = (((x[j, 0] - xp[j, 0]) * inv_dt - vi0) * u0
              + ((x[j, 1] - xp[j, 1]) * inv_dt - vi1) * u1
              + ((x[j, 2] - xp[j, 2]) * inv_dt - vi2) * u2)
        fs = adj_k[a] * (length - adj_rest[a]) + adj_kd[a] * vr
        f0 += fs * u0
        f1 += fs * u1
        f2 += fs * u2
    return f0, f1, f2


@njit
def _spring_forces(x, xp, inv_dt, si, sj, rest, k, kd, f_out):
    """Scatter the forces of every spring onto both ends (serial), N.

    ``f_out`` (n, 3) is overwritten.
    """
    f_out[:] = 0.0
    for s in range(si.shape[0]):
        i = si[s]
        j = sj[s]
        d0 = x[j, 0] - x[i, 0]
        d1 = x[j, 1] - x[i, 1]
        d2 = x[j, 2] - x[i, 2]
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if length <= 0.0:
            continue
        inv_l = 1.0 / length
        u0 = d0 * inv_l
        u1 = d1 * inv_l
        u2 = d2 * inv_l
        vr = (((x[j, 0] - xp[j, 0]) - (x[i, 0] - xp[i, 0])) * u0
              + ((x[j, 1] - xp[j, 1]) - (x[i, 1] - xp[i, 1])) * u1
              + ((x[j, 2] - xp[j, 2]) - (x[i, 2] - xp[i, 2])) * u2) * inv_dt
        fs = k[s] * (length - rest[s]) + kd[s] * vr
        f_out[i, 0] += fs * u0
        f_out[i, 1] += fs * u1
        f_out[i, 2] += fs * u2
        f_out[j, 0] -= fs * u0
        f_out[j, 1] -= fs * u1
        f_out[j, 2] -= fs * u2


@njit
def _spring_forces_gather(x, xp, inv_dt, adj_off, adj_j, adj_rest, adj_k, adj_kd, f_out):
    """The same forces gathered per vertex from a CSR adjacency, N."""
    for i in range(x.shape[0]):
        f0, f1, f2 = _vertex_spring_force(x, xp, inv_dt, i, adj_off, adj_j, adj_rest, adj_k, adj_kd)
        f_out[i, 0] = f0
        f_out[i, 1] = f1
        f_out[i, 2] = f2


def eval_spring_forces(pos, pos_prev, dt, spring_indices, rest, k, kd):
    """Spring forces on every particle (scatter form).

    Parameters
    ----------
    pos, pos_prev : (n, 3) float64, m
        Current and previous positions; velocity is ``(pos - pos_prev) / dt``.
    dt : float, s
    spring_indices : (s, 2) int64
    rest : (s,) float64, m
    k : (s,) float64, N/m
    kd : (s,) float64, N s/m

    Returns
    -------
    (n, 3) float64, N
    """
    x = np.ascontiguousarray(pos, dtype=np.float64)
    xp = np.ascontiguousarray(pos_prev, dtype=np.float64)
    idx = np.ascontiguousarray(spring_indices, dtype=np.int64).reshape(-1, 2)
    out = np.zeros_like(x)
    _spring_forces(x, xp, 1.0 / float(dt), np.ascontiguousarray(idx[:, 0]), np.ascontiguousarray(idx[:, 1]),
                   np.ascontiguousarray(rest, dtype=np.float64), np.ascontiguousarray(k, dtype=np.float64),
                   np.ascontiguousarray(kd, dtype=np.float64), out)
    return out


def eval_spring_forces_gather(pos, pos_prev, dt, adj_offsets, adj_other, adj_rest, adj_k, adj_kd):
    """Spring forces gathered per vertex from CSR arrays (see
    :func:`vfit_engine.garment.springs.vertex_spring_adjacency`); per-entry
    ``adj_rest``, ``adj_k``, ``adj_kd`` are the spring values repeated per end.

    Returns
    -------
    (n, 3) float64, N
    """
    x = np.ascontiguousarray(pos, dtype=np.float64)
    xp = np.ascontiguousarray(pos_prev, dtype=np.float64)
    out = np.zeros_like(x)
    _spring_forces_gather(x, xp, 1.0 / float(dt), np.ascontiguousarray(adj_offsets, dtype=np.int64),
                          np.ascontiguousarray(adj_other, dtype=np.int64),
                          np.ascontiguousarray(adj_rest, dtype=np.float64),
                          np.ascontiguousarray(adj_k, dtype=np.float64),
                          np.ascontiguousarray(adj_kd, dtype=np.float64), out)
    return out
