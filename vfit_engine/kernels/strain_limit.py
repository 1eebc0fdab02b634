"""Numba kernels: Provot strain limiting.

Provot (1995), "Deformation constraints in a mass-spring model to describe rigid
cloth behavior", Graphics Interface: after integration, every spring longer than
``l_max = (1 + limit) l0`` is shortened back to ``l_max`` by moving its ends
along the spring in proportion to their inverse masses::

    d = x_j - x_i,  l = |d|,  c = (l - l_max) / l,  W = w_i + w_j
    x_i += (w_i / W) c d,     x_j -= (w_j / W) c d

A pinned end (w = 0) stays put; a spring with both ends pinned is skipped. In
Verlet form only ``x`` moves (``x_prev`` does not), so the correction also
removes the velocity that overstretched the spring (Jakobsen 2001).

The untangling (:mod:`vfit_engine.sim.untangle`) uses it; the cloth kernel's distance constraints
(:mod:`vfit_engine.kernels.cloth`) generalise it (bands, compliance).
"""
import math

import numpy as np

from vfit_engine._jit import njit


@njit
def _limit_spring(x, inv_mass, i, j, max_len, omega):
    """Shorten spring (i, j) to ``max_len`` (m) if longer, the correction scaled
    by the relaxation factor ``omega`` (1: exactly to ``max_len``); in place on ``x``."""
    wi = inv_mass[i]
    wj = inv_mass[j]
    wsum = wi + wj
    if wsum <= 0.0:
        return
    d0 = x[j, 0] - x[i, 0]
    d1 = x[j, 1] - x[i, 1]
    d2 = x[j, 2] - x[i, 2]
    len2 = d0 * d0 + d1 * d1 + d2 * d2
    if len2 <= max_len * max_len:
        return  # most springs are within the limit: skip the square root
    length = math.sqrt(len2)
    c = omega * (length - max_len) / (length * wsum)
    ci = c * wi
    cj = c * wj
    x[i, 0] += ci * d0
    x[i, 1] += ci * d1
    x[i, 2] += ci * d2
    x[j, 0] -= cj * d0
    x[j, 1] -= cj * d1
    x[j, 2] -= cj * d2


@njit
def _strain_limit(x, inv_mass, si, sj, max_len, iterations, omega):
    """``iterations`` Gauss-Seidel sweeps over the springs in the given order."""
    for _ in range(iterations):
        for s in range(si.shape[0]):
            _limit_spring(x, inv_mass, si[s], sj[s], max_len[s], omega)


def limit_strain(pos, inv_mass, spring_indices, max_len, iterations=3, omega=1.0):
    """Provot strain limiting in place, springs taken in the given order.

    Parameters
    ----------
    pos : (n, 3) float64, m
        C-contiguous float64, modified in place.
    inv_mass : (n,) float64, 1/kg
        0 for pinned particles.
    spring_indices : (s, 2) int64
    max_len : (s,) float64, m
        ``(1 + limit) * rest``.
    iterations : int
    omega : float
        Over-relaxation of each correction (1 = Provot; 1 < omega < 2 converges faster).
    """
    if not (isinstance(pos, np.ndarray) and pos.dtype == np.float64 and pos.flags.c_contiguous):
        raise TypeError("pos must be a C-contiguous float64 array (it is modified in place)")
    idx = np.ascontiguousarray(spring_indices, dtype=np.int64).reshape(-1, 2)
    _strain_limit(pos, np.ascontiguousarray(inv_mass, dtype=np.float64), np.ascontiguousarray(idx[:, 0]),
                  np.ascontiguousarray(idx[:, 1]), np.ascontiguousarray(max_len, dtype=np.float64),
                  int(iterations), float(omega))
