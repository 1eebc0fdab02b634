"""Numba kernels for 2-D girth measures of horizontal section loops.

All functions work on the ``(x, z)`` coordinates of one loop, ``pts`` a C-contiguous
``(n, 2) float64`` array in metres, the points in walk order. A loop is treated as
closed (its last point joins its first), which is what a tape does across an open
chain as well. Scratch buffers are passed in so that scanning many planes never
allocates.

Importing this module imports numba; only measurement code imports it.
"""
import math

import numpy as np

from vfit_engine._jit import njit

#: Girth method codes shared with :mod:`vfit_engine.kernels.section`.
METHOD_HULL = 0
METHOD_SPLINE = 1
METHOD_POLYLINE = 2

#: Number of rows of the float scratch buffer ``work`` used by :func:`spline_length`.
SPLINE_WORK_ROWS = 6


@njit
def _dist(x1, z1, x0, z0):
    """Distance between (x0, z0) and (x1, z1); plain sqrt (np.hypot is slow to compile)."""
    dx = x1 - x0
    dz = z1 - z0
    return math.sqrt(dx * dx + dz * dz)


@njit
def _lex_less(pts, i, j):
    """True when point ``i`` sorts before point ``j`` by (x, then z)."""
    if pts[i, 0] < pts[j, 0]:
        return True
    if pts[i, 0] > pts[j, 0]:
        return False
    return pts[i, 1] < pts[j, 1]


@njit
def _heapsort_lex(pts, n, order):
    """Sort ``order[:n] = 0..n-1`` in place so that ``pts[order]`` is lexicographic.

    Heapsort (Williams 1964): O(n log n), in place, no allocation.
    """
    for i in range(n):
        order[i] = i
    # heapify: sift down every parent
    start = n // 2 - 1
    while start >= 0:
        root = start
        while True:
            child = 2 * root + 1
            if child >= n:
                break
            if child + 1 < n and _lex_less(pts, order[child], order[child + 1]):
                child += 1
            if _lex_less(pts, order[root], order[child]):
                order[root], order[child] = order[child], order[root]
                root = child
            else:
                break
        start -= 1
    end = n - 1
    while end > 0:
        order[0], order[end] = order[end], order[0]
        root = 0
        while True:
            child = 2 * root + 1
            if child >= end:
                break
            if child + 1 < end and _lex_less(pts, order[child], order[child + 1]):
                child += 1
            if _lex_less(pts, order[root], order[child]):
                order[root], order[child] = order[child], order[root]
                root = child
            else:
                break
        end -= 1


@njit
def _cross(pts, o, a, b):
    """z-component of (a - o) x (b - o) for point indices into ``pts``."""
    return ((pts[a, 0] - pts[o, 0]) * (pts[b, 1] - pts[o, 1])
            - (pts[a, 1] - pts[o, 1]) * (pts[b, 0] - pts[o, 0]))


@njit
def hull_ccw(pts, order, hull):
    """Andrew's monotone chain: writes the hull's point indices counter-clockwise into ``hull`` and returns
    their count ``m``; ``hull[m]`` repeats ``hull[0]``; collinear and repeated points are left out."""
    n = pts.shape[0]
    _heapsort_lex(pts, n, order)
    k = 0
    for ii in range(n):
        i = order[ii]
        while k >= 2 and _cross(pts, hull[k - 2], hull[k - 1], i) <= 0.0:
            k -= 1
        hull[k] = i
        k += 1
    lower = k + 1
    for ii in range(n - 2, -1, -1):
        i = order[ii]
        while k >= lower and _cross(pts, hull[k - 2], hull[k - 1], i) <= 0.0:
            k -= 1
        hull[k] = i
        k += 1
    return k - 1


@njit
def hull_perimeter(pts, order, hull):
    """Perimeter of the convex hull of 2-D points (a tape around them).

    Andrew's monotone chain (Andrew 1979): sort by (x, z), build the lower and the
    upper chain keeping only strict left turns, then sum the hull edge lengths.

    Parameters
    ----------
    pts : (n, 2) float64, m
        Points (x, z).
    order : (>= n,) int64
        Scratch for the sort permutation.
    hull : (>= 2 n + 1,) int64
        Scratch for the hull vertex indices.

    Returns
    -------
    float
        Hull perimeter, m. Two distinct points give twice their distance (a
        degenerate hull), one or none give 0.
    """
    if pts.shape[0] < 2:
        return 0.0
    m = hull_ccw(pts, order, hull)
    # hull[m] repeats hull[0], so the m edges close the polygon
    per = 0.0
    for j in range(m):
        a = hull[j]
        b = hull[j + 1]
        per += _dist(pts[b, 0], pts[b, 1], pts[a, 0], pts[a, 1])
    return per


@njit
def polyline_length(pts, closed):
    """Length of the polyline through ``pts`` (m), with the closing segment if ``closed``."""
    n = pts.shape[0]
    total = 0.0
    for i in range(n - 1):
        total += _dist(pts[i + 1, 0], pts[i + 1, 1], pts[i, 0], pts[i, 1])
    if closed and n > 2:
        total += _dist(pts[0, 0], pts[0, 1], pts[n - 1, 0], pts[n - 1, 1])
    return total


@njit
def loop_area_centroid_xrange(pts):
    """Signed area, centroid x and x-range of a closed loop.

    Shoelace formula: ``A = 1/2 sum(x_i z_{i+1} - x_{i+1} z_i)`` and the
    polygon centroid ``cx = 1/(6A) sum((x_i + x_{i+1})(x_i z_{i+1} - x_{i+1} z_i))``;
    when ``|A|`` is negligible (a sliver) the mean of the points is used instead.

    Parameters
    ----------
    pts : (n, 2) float64, m

    Returns
    -------
    area : float, m^2
        Positive when the loop turns from +x towards +z.
    cx, xmin, xmax : float, m
    """
    n = pts.shape[0]
    if n == 0:
        return 0.0, np.nan, np.nan, np.nan
    a2 = 0.0
    cxs = 0.0
    xmin = pts[0, 0]
    xmax = pts[0, 0]
    xsum = 0.0
    for i in range(n):
        j = i + 1
        if j == n:
            j = 0
        x0 = pts[i, 0]
        c = x0 * pts[j, 1] - pts[j, 0] * pts[i, 1]
        a2 += c
        cxs += (x0 + pts[j, 0]) * c
        xsum += x0
        if x0 < xmin:
            xmin = x0
        if x0 > xmax:
            xmax = x0
    area = 0.5 * a2
    span = xmax - xmin
    if abs(area) > 1e-12 * (span * span + 1e-300):
        cx = cxs / (3.0 * a2)
    else:
        cx = xsum / n
    return area, cx, xmin, xmax


@njit
def _spline_half(pts, i_from, count, samples, work):
    """Length of a natural cubic spline through ``count`` consecutive loop points.

    Points are ``pts[(i_from + j) % n]``; repeats closer than 1e-12 m are dropped
    (a plane through a mesh vertex yields coincident points, and a zero chord
    would make the parameter degenerate). The curve is parametric in cumulative
    chord length ``t`` (Ahlberg, Nilson & Walsh 1967), so vertical tangents in
    (x, z) are harmless; each coordinate is the natural spline with second
    derivatives ``M`` solving

        h_{j-1} M_{j-1} + 2 (h_{j-1} + h_j) M_j + h_j M_{j+1}
            = 6 ((y_{j+1} - y_j) / h_j - (y_j - y_{j-1}) / h_{j-1}),  M_0 = M_{m-1} = 0

    by the Thomas algorithm, and the length is the polyline through ``samples``
    evaluations per interval.
    """
    n = pts.shape[0]
    xs = work[0]
    zs = work[1]
    ts = work[2]
    mx = work[3]
    mz = work[4]
    cp = work[5]
    m = 0
    for j in range(count):
        k = (i_from + j) % n
        x = pts[k, 0]
        z = pts[k, 1]
        if m > 0:
            d = _dist(x, z, xs[m - 1], zs[m - 1])
            if d <= 1e-12:
                continue
            ts[m] = ts[m - 1] + d
        else:
            ts[0] = 0.0
        xs[m] = x
        zs[m] = z
        m += 1
    if m < 2:
        return 0.0
    if m == 2:
        return ts[1]
    # Thomas algorithm for the interior unknowns 1..m-2; both coordinates share
    # the matrix. mx/mz hold the eliminated right-hand sides, then the solution.
    mx[0] = 0.0
    mz[0] = 0.0
    mx[m - 1] = 0.0
    mz[m - 1] = 0.0
    for j in range(1, m - 1):
        h0 = ts[j] - ts[j - 1]
        h1 = ts[j + 1] - ts[j]
        rx = 6.0 * ((xs[j + 1] - xs[j]) / h1 - (xs[j] - xs[j - 1]) / h0)
        rz = 6.0 * ((zs[j + 1] - zs[j]) / h1 - (zs[j] - zs[j - 1]) / h0)
        diag = 2.0 * (h0 + h1)
        if j > 1:
            diag -= h0 * cp[j - 1]
            rx -= h0 * mx[j - 1]
            rz -= h0 * mz[j - 1]
        cp[j] = h1 / diag
        mx[j] = rx / diag
        mz[j] = rz / diag
    for j in range(m - 3, 0, -1):
        mx[j] -= cp[j] * mx[j + 1]
        mz[j] -= cp[j] * mz[j + 1]
    total = 0.0
    for j in range(m - 1):
        h = ts[j + 1] - ts[j]
        px = xs[j]
        pz = zs[j]
        for s in range(1, samples + 1):
            u = s / samples
            a = 1.0 - u
            # S = a y_j + u y_{j+1} + h^2/6 ((a^3 - a) M_j + (u^3 - u) M_{j+1})
            c0 = (a * a * a - a) * h * h / 6.0
            c1 = (u * u * u - u) * h * h / 6.0
            qx = a * xs[j] + u * xs[j + 1] + c0 * mx[j] + c1 * mx[j + 1]
            qz = a * zs[j] + u * zs[j + 1] + c0 * mz[j] + c1 * mz[j + 1]
            total += _dist(qx, qz, px, pz)
            px = qx
            pz = qz
    return total


@njit
def spline_length(pts, samples, work):
    """Length of the feature-profile spline girth of a closed loop.

    The loop is split at its min-x and max-x points into a front and a back half
    (both halves include the two split points); each half gets a natural cubic
    spline parametric in chord length, densified to ``samples`` points per
    interval, and the two lengths are summed (the seed's profile-curve girth).

    Parameters
    ----------
    pts : (n, 2) float64, m
        Loop points in walk order.
    samples : int
        Evaluations per spline interval, >= 1 (8 is plenty at body resolution).
    work : (SPLINE_WORK_ROWS, >= n + 1) float64
        Scratch.

    Returns
    -------
    float
        Length, m; 0 for fewer than two distinct points.
    """
    n = pts.shape[0]
    if n < 2:
        return 0.0
    i0 = 0
    i1 = 0
    for i in range(1, n):
        if pts[i, 0] < pts[i0, 0]:
            i0 = i
        if pts[i, 0] > pts[i1, 0]:
            i1 = i
    if i0 == i1:
        # all x equal: no front/back split exists; the loop is a vertical sliver
        return polyline_length(pts, True)
    c01 = (i1 - i0) % n + 1
    c10 = (i0 - i1) % n + 1
    return (_spline_half(pts, i0, c01, samples, work)
            + _spline_half(pts, i1, c10, samples, work))


@njit
def loop_girth(pts, method, samples, order, hull, work):
    """Girth of one loop by ``method`` (METHOD_HULL, METHOD_SPLINE or METHOD_POLYLINE), m.

    Scratch ``order``, ``hull`` and ``work`` as for :func:`hull_perimeter` and
    :func:`spline_length`; an unknown method returns NaN.
    """
    if method == METHOD_HULL:
        return hull_perimeter(pts, order, hull)
    if method == METHOD_SPLINE:
        return spline_length(pts, samples, work)
    if method == METHOD_POLYLINE:
        return polyline_length(pts, True)
    return np.nan


@njit
def select_torso_loop(pts, loop_start, n_loops, x0):
    """Index of the torso loop among ``n_loops`` loops, or -1 if there is none.

    The torso is the loop of largest ``|area|`` among those whose x-range contains
    the mid-sagittal plane ``x = x0``; if no loop contains it, the loop whose
    centroid x is nearest ``x0``. Arm and hand loops cut by the same plane lie to
    the side, so they never contain ``x0``.

    Parameters
    ----------
    pts : (P, 2) float64, m
        All loop points; loop ``i`` is ``pts[loop_start[i]:loop_start[i + 1]]``.
    loop_start : (>= n_loops + 1,) int64
    n_loops : int
    x0 : float, m
    """
    best = -1
    best_area = -1.0
    near = -1
    near_d = np.inf
    for i in range(n_loops):
        lp = pts[loop_start[i]:loop_start[i + 1]]
        if lp.shape[0] == 0:
            continue
        area, cx, xmin, xmax = loop_area_centroid_xrange(lp)
        if xmin <= x0 <= xmax:
            if abs(area) > best_area:
                best_area = abs(area)
                best = i
        d = abs(cx - x0)
        if d < near_d:
            near_d = d
            near = i
    if best >= 0:
        return best
    return near
