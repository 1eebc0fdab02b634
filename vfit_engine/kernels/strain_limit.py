"""Numba kernels: Provot strain limiting and the spring colouring that orders it.

Provot (1995), "Deformation constraints in a mass-spring model to describe rigid
cloth behavior", Graphics Interface: after integration, every spring longer than
``l_max = (1 + limit) l0`` is shortened back to ``l_max`` by moving its ends
along the spring in proportion to their inverse masses::

    d = x_j - x_i,  l = |d|,  c = (l - l_max) / l,  W = w_i + w_j
    x_i += (w_i / W) c d,     x_j -= (w_j / W) c d

A pinned end (w = 0) stays put; a spring with both ends pinned is skipped. In
Verlet form only ``x`` moves (``x_prev`` does not), so the correction also
removes the velocity that overstretched the spring (Jakobsen 2001).

Springs are processed Gauss-Seidel in *colour order*: the springs are grouped so
that no two springs of one colour share a vertex, colour after colour. The
result is the same whether a colour's springs run serially or in parallel, so
the parallel fused kernel is race-free and bit-identical to the serial one.
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


@njit
def _greedy_edge_colours(si, sj, vertex_count, max_colours, colour_out):
    """Greedy edge colouring in spring order; returns the colour count, or -1
    if ``max_colours`` is not enough (it never is below 2 * max degree - 1)."""
    used = np.zeros((vertex_count, max_colours), dtype=np.bool_)
    n_colours = 0
    for s in range(si.shape[0]):
        i = si[s]
        j = sj[s]
        c = 0
        while c < max_colours and (used[i, c] or used[j, c]):
            c += 1
        if c == max_colours:
            return -1
        used[i, c] = True
        used[j, c] = True
        colour_out[s] = c
        if c + 1 > n_colours:
            n_colours = c + 1
    return n_colours


def colour_springs(spring_indices, vertex_count):
    """Order springs so that no two of one colour share a vertex.

    Parameters
    ----------
    spring_indices : (s, 2) int64
    vertex_count : int

    Returns
    -------
    order : (s,) int64
        Spring indices sorted by colour (stable within a colour).
    colour_offsets : (c + 1,) int64
        Colour ``q`` is ``order[colour_offsets[q]:colour_offsets[q + 1]]``.
    """
    idx = np.ascontiguousarray(spring_indices, dtype=np.int64).reshape(-1, 2)
    if idx.shape[0] == 0:
        return np.zeros(0, np.int64), np.zeros(1, np.int64)
    degree = np.bincount(idx.ravel(), minlength=vertex_count)
    max_colours = int(2 * degree.max())
    colour = np.empty(idx.shape[0], dtype=np.int64)
    n_colours = _greedy_edge_colours(np.ascontiguousarray(idx[:, 0]), np.ascontiguousarray(idx[:, 1]),
                                     int(vertex_count), max_colours, colour)
    if n_colours < 0:  # pragma: no cover - greedy needs at most 2 * degree - 1 colours
        raise RuntimeError("spring colouring failed")
    order = np.argsort(colour, kind="stable").astype(np.int64)
    offsets = np.zeros(n_colours + 1, dtype=np.int64)
    np.cumsum(np.bincount(colour, minlength=n_colours), out=offsets[1:])
    return order, offsets


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
