"""The cloth in two halves, for the two threads of the cloth kernel.

The kernel (:mod:`vfit_engine.kernels.cloth`, "Two threads") runs what lies in one half of the
cloth on one thread and what lies in the other on the second, then what spans both. It needs the
vertices numbered half by half (two threads writing vertices that share a cache line slow each other
down: a sweep ran 2.0x faster than on one thread with the halves apart in memory, 1.3x with them
interleaved) and every item -- spring, constraint, contact point -- ordered by segment.

Shapes::

    halves(rest (n, 3))                      -> order (n,) int64, rank (n,) int64, half (n,) int8
    segment_of(half, (m,) int64, ...)        -> (m,) int8 in {0, 1, 2}
    segments((m,) segment)                   -> order (m,) int64, bounds (4,) int64
"""
from __future__ import annotations

import numpy as np

#: Cloths with fewer vertices run in one segment (threads would cost more than they save).
MIN_SPLIT = 256


def halves(rest):
    """Split the vertices at the median of the horizontal coordinate of the larger extent: x, the body's
    left and right, for a garment (wider than deep), z for cloth that hangs in the y-z plane.

    A garment is about symmetric and pinned on both sides, so each half holds its own pins and
    the sweeps from them; the cut is short. Ties go by index, so the halves differ by at most one.

    Parameters
    ----------
    rest : (n, 3) float64

    Returns
    -------
    order : (n,) int64
        The vertices in the kernel's numbering (first half, then second; each in its given order).
    rank : (n,) int64
        The kernel's number of vertex ``i`` (``rank[order] = arange(n)``).
    half : (n,) int8
        0 or 1 for each vertex (all 0 below ``MIN_SPLIT`` vertices).
    """
    rest = np.asarray(rest, dtype=np.float64)
    n = rest.shape[0]
    half = np.zeros(n, dtype=np.int8)
    if n >= MIN_SPLIT:
        axis = 0 if np.ptp(rest[:, 0]) >= np.ptp(rest[:, 2]) else 2
        along = np.argsort(rest[:, axis], kind="stable")
        half[along[n // 2:]] = 1
    order = np.argsort(half, kind="stable").astype(np.int64)
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    return order, rank, half


def segment_of(half, *vertex_arrays):
    """Segment of each item from the halves of its vertices: 0 or 1 when all lie in that half, else 2.

    ``vertex_arrays``: (m,) int64 arrays of the items' vertices (-1: none, as a distance constraint's
    corner).
    """
    lo = np.full(vertex_arrays[0].shape[0], 1, dtype=np.int8)
    hi = np.zeros(vertex_arrays[0].shape[0], dtype=np.int8)
    for v in vertex_arrays:
        h = half[np.maximum(v, 0)]
        has = v >= 0
        lo = np.where(has, np.minimum(lo, h), lo)
        hi = np.where(has, np.maximum(hi, h), hi)
    return np.where(lo == hi, lo, 2).astype(np.int8)


def segments(segment):
    """Order items by segment, keeping their order within each.

    Returns
    -------
    order : (m,) int64
    bounds : (4,) int64
        Segment ``g`` is ``order[bounds[g]:bounds[g + 1]]``.
    """
    segment = np.asarray(segment)
    order = np.argsort(segment, kind="stable").astype(np.int64)
    bounds = np.zeros(4, dtype=np.int64)
    bounds[1:] = np.cumsum(np.bincount(segment.astype(np.int64), minlength=3)[:3])
    return order, bounds
