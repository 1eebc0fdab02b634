"""Numba kernels: damped Hooke spring forces of a mass-spring cloth.

For a spring (i, j) with rest length ``l0``, stiffness ``k`` and damping ``kd``::

    d = x_j - x_i,   l = |d|,   u = d / l
    v = (x - x_prev) / dt                       (Verlet backward-difference velocity)
    f_i = [k (l - l0) + kd ((v_j - v_i) . u)] u,    f_j = -f_i

(Provot 1995, "Deformation constraints in a mass-spring model to describe rigid
cloth behavior"; Baraff & Witkin 1998 for the damping along the spring.) The pair
of forces sums to zero and acts along the spring axis.

The forces are scattered spring by spring onto both ends (:func:`_spring_forces`; the cloth kernel
:mod:`vfit_engine.kernels.cloth` runs :func:`add_spring_forces` over its springs' segments;
:func:`eval_spring_forces` for callers).
"""
import math

import numpy as np

from vfit_engine._jit import njit


@njit
def _spring_forces(x, xp, inv_dt, si, sj, rest, k, kd, f_out):
    """Scatter the forces of every spring onto both ends (serial), N.

    ``f_out`` (n, 3) is overwritten.
    """
    f_out[:] = 0.0
    add_spring_forces(x, xp, inv_dt, si, sj, rest, k, kd, f_out, 0, si.shape[0])


@njit
def add_spring_forces(x, xp, inv_dt, si, sj, rest, k, kd, f_out, s0, s1):
    """Add the forces of springs ``s0 .. s1 - 1`` onto both ends, N (``f_out`` (n, 3) accumulates)."""
    for s in range(s0, s1):
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
