"""Numba kernels for horizontal plane sections of a triangle mesh.

A plane ``y = h`` cuts the mesh along the edges whose end points lie on opposite
sides; a vertex with ``y == h`` counts as *above*, so every cut triangle has exactly
two cut edges and the section is a set of segments that chain through shared
edges. The kernels walk that chain over the triangle adjacency built once per
topology by :func:`build_topology` (plain NumPy), so a section costs one pass over
the candidate edges plus the length of the loops.

Loop orientation: the walk enters a triangle through one cut edge and leaves
through the other, chosen from the triangle's winding (the marching-triangles
rule: with the lone vertex ``k`` on its own side, enter through edge ``k - 1`` and
leave through edge ``k`` when the lone vertex is above, the reverse when below).
On a consistently wound mesh every loop therefore has the same orientation; for an
outward-wound closed surface (trimesh's convention) the outer loops have positive
area in :func:`vfit_engine.kernels.girth.loop_area_centroid_xrange`.

:func:`scan_girths` calls kernels of ``girth.py``; its cache is stamped with that file too, so an
edit there recompiles it (:mod:`vfit_engine._jit`).
"""
import numpy as np

from vfit_engine._jit import njit
from vfit_engine.kernels.girth import loop_girth, select_torso_loop


def build_topology(tris):
    """Edge tables of a triangle mesh (NumPy; once per topology).

    Parameters
    ----------
    tris : (T, 3) int64
        Triangles; triangles with a repeated vertex must be removed beforehand.

    Returns
    -------
    edges : (E, 2) int64
        Unique undirected edges, ``edges[:, 0] < edges[:, 1]``.
    tri_edges : (T, 3) int64
        ``tri_edges[t, k]`` is the edge from ``tris[t, k]`` to ``tris[t, (k + 1) % 3]``.
    edge_tris : (E, 2) int64
        The (up to) two triangles of each edge, ``-1`` on a boundary.
    edge_tri_count : (E,) int64
        Number of triangles using each edge (> 2 means non-manifold).
    """
    tris = np.ascontiguousarray(tris, dtype=np.int64)
    n_tri = tris.shape[0]
    half = np.stack([tris, np.roll(tris, -1, axis=1)], axis=2).reshape(-1, 2)
    half = np.sort(half, axis=1)
    # unique rows through one int64 key a * span + b (same lexicographic order as np.unique(axis=0),
    # which sorts a structured view and cost ~0.1 s on the body against ~5 ms for the keys)
    lo = int(half.min()) if half.size else 0
    span = int(half.max()) - lo + 1 if half.size else 1
    keys, inverse, counts = np.unique((half[:, 0] - lo) * span + (half[:, 1] - lo), return_inverse=True,
                                      return_counts=True)
    edges = np.stack([keys // span + lo, keys % span + lo], axis=1)
    inverse = inverse.reshape(-1)
    tri_edges = inverse.reshape(n_tri, 3).astype(np.int64)
    edge_tris = np.full((edges.shape[0], 2), -1, dtype=np.int64)
    tri_of_half = np.repeat(np.arange(n_tri, dtype=np.int64), 3)
    order = np.argsort(inverse, kind="stable")
    sorted_edges = inverse[order]
    first = np.ones(sorted_edges.shape[0], dtype=bool)
    first[1:] = sorted_edges[1:] != sorted_edges[:-1]
    # rank of each half-edge within its edge: 0 for the first triangle, 1 for the second ...
    starts = np.flatnonzero(first)
    rank = np.arange(sorted_edges.shape[0]) - np.repeat(starts, np.diff(np.append(starts, sorted_edges.shape[0])))
    keep = rank < 2
    edge_tris[sorted_edges[keep], rank[keep]] = tri_of_half[order][keep]
    return (np.ascontiguousarray(edges, dtype=np.int64), np.ascontiguousarray(tri_edges),
            edge_tris, counts.astype(np.int64))


@njit
def select_band_edges(verts, edges, y_lo, y_hi, cand_out):
    """Indices of the edges that any plane ``y_lo <= h <= y_hi`` can cut.

    An edge with end heights ``lo <= hi`` is cut by ``y = h`` iff ``lo < h <= hi``
    (a vertex on the plane counts as above), so the band needs ``lo < y_hi`` and
    ``hi >= y_lo``.

    Parameters
    ----------
    verts : (N, 3) float64, m
    edges : (E, 2) int64
    y_lo, y_hi : float, m
    cand_out : (>= E,) int64
        Receives the edge indices, ascending.

    Returns
    -------
    int
        Number of candidate edges written.
    """
    n = 0
    for e in range(edges.shape[0]):
        ya = verts[edges[e, 0], 1]
        yb = verts[edges[e, 1], 1]
        lo = min(ya, yb)
        hi = max(ya, yb)
        if lo < y_hi and hi >= y_lo:
            cand_out[n] = e
            n += 1
    return n


@njit
def is_cut(verts, edges, e, h):
    return (verts[edges[e, 0], 1] >= h) != (verts[edges[e, 1], 1] >= h)


@njit
def _entry_edge(verts, tris, tri_edges, t, h):
    """The cut edge through which the oriented walk enters triangle ``t``."""
    a0 = verts[tris[t, 0], 1] >= h
    a1 = verts[tris[t, 1], 1] >= h
    a2 = verts[tris[t, 2], 1] >= h
    if a1 == a2:
        k = 0
        above = a0
    elif a0 == a2:
        k = 1
        above = a1
    else:
        k = 2
        above = a2
    if above:
        return tri_edges[t, (k + 2) % 3]
    return tri_edges[t, k]


@njit
def _other_cut_edge(verts, edges, tri_edges, t, e, h):
    for k in range(3):
        f = tri_edges[t, k]
        if f != e and is_cut(verts, edges, f, h):
            return f
    return -1


@njit
def _write_point(verts, edges, e, h, pts_out, i):
    """Intersection of edge ``e`` with ``y = h``, interpolated from its lower-index end
    so that both triangles of the edge produce bit-identical points."""
    a = edges[e, 0]
    b = edges[e, 1]
    s = (h - verts[a, 1]) / (verts[b, 1] - verts[a, 1])
    pts_out[i, 0] = verts[a, 0] + s * (verts[b, 0] - verts[a, 0])
    pts_out[i, 1] = verts[a, 2] + s * (verts[b, 2] - verts[a, 2])


@njit
def section_loops(verts, tris, edges, tri_edges, edge_tris, cand, n_cand, h,
                  visited, cut, pts_out, loop_start_out, loop_closed_out):
    """Ordered section loops of the mesh with the plane ``y = h``.

    Open chains (the plane crossing a mesh boundary) are walked first, each from
    one of its boundary edges; every remaining cut edge lies on a closed loop.

    Parameters
    ----------
    verts : (N, 3) float64, m
    tris : (T, 3) int64
    edges, tri_edges, edge_tris : int64 tables from :func:`build_topology`
    cand : (>= n_cand,) int64
        Edges to test (all edges, or those from :func:`select_band_edges`).
    n_cand : int
    h : float, m
    visited : (E,) int64
        Scratch, all zero on entry; left all zero on return.
    cut : (>= n_cand,) int64
        Scratch.
    pts_out : (>= n_cand, 2) float64, m
        Receives the (x, z) loop points, loop after loop.
    loop_start_out : (>= n_cand + 1,) int64
        Loop ``i`` is ``pts_out[loop_start_out[i]:loop_start_out[i + 1]]``.
    loop_closed_out : (>= n_cand,) int64
        1 for a closed loop, 0 for an open chain.

    Returns
    -------
    n_pts, n_loops : int
    """
    n_cut = 0
    for ii in range(n_cand):
        e = cand[ii]
        if is_cut(verts, edges, e, h):
            cut[n_cut] = e
            n_cut += 1
    n_pts = 0
    n_loops = 0
    loop_start_out[0] = 0
    for boundary_pass in range(2):
        for ii in range(n_cut):
            e0 = cut[ii]
            if visited[e0] != 0:
                continue
            on_boundary = edge_tris[e0, 1] < 0
            if boundary_pass == 0 and not on_boundary:
                continue
            t = edge_tris[e0, 0]
            reverse = False
            if on_boundary:
                reverse = _entry_edge(verts, tris, tri_edges, t, h) != e0
            elif _entry_edge(verts, tris, tri_edges, t, h) != e0:
                t = edge_tris[e0, 1]
            start = n_pts
            visited[e0] = 1
            _write_point(verts, edges, e0, h, pts_out, n_pts)
            n_pts += 1
            closed = 0
            e = e0
            while True:
                f = _other_cut_edge(verts, edges, tri_edges, t, e, h)
                if f == e0:
                    closed = 1
                    break
                if f < 0 or visited[f] != 0:
                    break
                visited[f] = 1
                _write_point(verts, edges, f, h, pts_out, n_pts)
                n_pts += 1
                t_next = edge_tris[f, 0]
                if t_next == t:
                    t_next = edge_tris[f, 1]
                if t_next < 0:
                    break
                t = t_next
                e = f
            if reverse:
                i = start
                j = n_pts - 1
                while i < j:
                    for c in range(2):
                        tmp = pts_out[i, c]
                        pts_out[i, c] = pts_out[j, c]
                        pts_out[j, c] = tmp
                    i += 1
                    j -= 1
            loop_closed_out[n_loops] = closed
            n_loops += 1
            loop_start_out[n_loops] = n_pts
    for ii in range(n_cut):
        visited[cut[ii]] = 0
    return n_pts, n_loops


@njit
def section_at(verts, tris, edges, tri_edges, edge_tris, h,
               cand, visited, cut, pts_out, loop_start_out, loop_closed_out):
    """All loops at ``y = h``: :func:`select_band_edges` for the single plane, then
    :func:`section_loops`. Arguments as there; returns ``(n_pts, n_loops)``."""
    n_cand = select_band_edges(verts, edges, h, h, cand)
    return section_loops(verts, tris, edges, tri_edges, edge_tris, cand, n_cand, h,
                         visited, cut, pts_out, loop_start_out, loop_closed_out)


@njit
def _select_planes_edges(verts, edges, ys, cand):
    """:func:`select_band_edges` for the band ``[min(ys), max(ys)]`` (``ys`` non-empty)."""
    y_lo = ys[0]
    y_hi = ys[0]
    for i in range(1, ys.shape[0]):
        y_lo = min(y_lo, ys[i])
        y_hi = max(y_hi, ys[i])
    return select_band_edges(verts, edges, y_lo, y_hi, cand)


@njit
def _x_range(pts, start, end):
    """(min, max) of ``pts[start:end, 0]``."""
    lo = np.inf
    hi = -np.inf
    for p in range(start, end):
        lo = min(lo, pts[p, 0])
        hi = max(hi, pts[p, 0])
    return lo, hi


@njit
def plane_girth(verts, tris, edges, tri_edges, edge_tris, cand, n_cand, h, method, samples, x0,
                visited, cut, pts_out, loop_start_out, loop_closed_out, order, hull, work):
    """Torso girth at ``y = h`` from the candidate edges ``cand[:n_cand]`` (NaN without a loop)."""
    n_pts, n_loops = section_loops(verts, tris, edges, tri_edges, edge_tris, cand, n_cand, h,
                                   visited, cut, pts_out, loop_start_out, loop_closed_out)
    best = select_torso_loop(pts_out, loop_start_out, n_loops, x0)
    if best < 0:
        return np.nan
    lp = pts_out[loop_start_out[best]:loop_start_out[best + 1]]
    return loop_girth(lp, method, samples, order, hull, work)


@njit
def scan_girths(verts, tris, edges, tri_edges, edge_tris, ys, method, samples, x0,
                cand, visited, cut, pts_out, loop_start_out, loop_closed_out,
                order, hull, work, girth_out):
    """Torso girth at every plane ``y = ys[i]`` in one call.

    The edges that can meet the band ``[min(ys), max(ys)]`` are selected once;
    each plane then tests only those, assembles its loops, picks the torso loop
    (:func:`vfit_engine.kernels.girth.select_torso_loop` with ``x0``) and measures
    it (:func:`vfit_engine.kernels.girth.loop_girth` with ``method``, ``samples``).

    Parameters
    ----------
    verts, tris, edges, tri_edges, edge_tris : as :func:`section_loops`
    ys : (k,) float64, m
    method : int
        METHOD_HULL, METHOD_SPLINE or METHOD_POLYLINE.
    samples : int
        Spline evaluations per interval.
    x0 : float, m
    cand, visited, cut, pts_out, loop_start_out, loop_closed_out : scratch as
        :func:`section_loops`
    order, hull, work : scratch as :func:`vfit_engine.kernels.girth.loop_girth`
    girth_out : (k,) float64, m
        Receives the girths; NaN where the plane misses the mesh.
    """
    k = ys.shape[0]
    if k == 0:
        return
    n_cand = _select_planes_edges(verts, edges, ys, cand)
    for i in range(k):
        girth_out[i] = plane_girth(verts, tris, edges, tri_edges, edge_tris, cand, n_cand, ys[i], method,
                                   samples, x0, visited, cut, pts_out, loop_start_out, loop_closed_out,
                                   order, hull, work)


@njit
def _first_above(ys, y, guess):
    """The first index ``i`` with ``ys[i] > y`` in the ascending ``ys`` (``np.searchsorted(ys, y, 'right')``),
    walked from ``guess``: O(1) for the evenly spaced planes of a scan, correct for any."""
    k = ys.shape[0]
    i = min(max(guess, 0), k)
    while i < k and ys[i] <= y:
        i += 1
    while i > 0 and ys[i - 1] > y:
        i -= 1
    return i


@njit
def bucket_plane_edges(verts, edges, cand, n_cand, ys, plane_start, plane_edges, first_out, last_out):
    """Per plane of the ascending ``ys``, the candidate edges it cuts, in ascending edge order.

    Edge ``e`` (end heights ``lo <= hi``) is cut by ``y = h`` iff ``lo < h <= hi``
    (:func:`is_cut`), i.e. by the planes ``i0 <= i < i1`` with ``i0`` the first with
    ``ys[i] > lo`` and ``i1`` the first with ``ys[i] > hi``. Plane ``i``'s edges are
    ``plane_edges[plane_start[i]:plane_start[i + 1]]``; ``cand`` is walked in order, so each
    list keeps ``cand``'s order and :func:`section_loops` given it finds the same cut edges in
    the same order as given all of ``cand``. ``first_out``, ``last_out`` (>= n_cand,) int64:
    scratch for every edge's ``i0``, ``i1``.

    Returns the number of entries, or -1 when ``plane_edges`` is too short (nothing usable).
    """
    k = ys.shape[0]
    for i in range(k + 1):
        plane_start[i] = 0
    # the index guess for evenly spaced planes; _first_above corrects it
    inv = (k - 1) / (ys[k - 1] - ys[0]) if k > 1 and ys[k - 1] > ys[0] else 0.0
    # counts go to plane_start[i + 1]; a first pass sizes the lists
    for ii in range(n_cand):
        e = cand[ii]
        ya = verts[edges[e, 0], 1]
        yb = verts[edges[e, 1], 1]
        lo = min(ya, yb)
        hi = max(ya, yb)
        i0 = _first_above(ys, lo, int((lo - ys[0]) * inv) + 1)
        i1 = _first_above(ys, hi, int((hi - ys[0]) * inv) + 1)
        first_out[ii] = i0
        last_out[ii] = i1
        for i in range(i0, i1):
            plane_start[i + 1] += 1
    for i in range(k):
        plane_start[i + 1] += plane_start[i]
    total = plane_start[k]
    if total > plane_edges.shape[0]:
        return -1
    # fill: plane_start[i] serves as plane i's write cursor, then is shifted back
    for ii in range(n_cand):
        e = cand[ii]
        for i in range(first_out[ii], last_out[ii]):
            plane_edges[plane_start[i]] = e
            plane_start[i] += 1
    for i in range(k, 0, -1):
        plane_start[i] = plane_start[i - 1]
    plane_start[0] = 0
    return total


@njit
def scan_girths_sorted(verts, tris, edges, tri_edges, edge_tris, ys, method, samples, x0,
                       cand, visited, cut, pts_out, loop_start_out, loop_closed_out,
                       order, hull, work, plane_start, plane_edges, girth_out):
    """:func:`scan_girths` with the same results, faster on many ascending planes: instead of testing
    every edge of the band at every plane, each plane tests only the edges it cuts
    (:func:`bucket_plane_edges`). Unsorted ``ys``, or lists longer than ``plane_edges``, fall back to
    :func:`scan_girths`.

    Extra parameters: ``plane_start`` (>= k + 1,) int64 and ``plane_edges`` (any length) int64, scratch.
    """
    k = ys.shape[0]
    if k == 0:
        return
    ascending = True
    for i in range(1, k):
        if ys[i] < ys[i - 1]:
            ascending = False
    n_cand = select_band_edges(verts, edges, ys[0], ys[k - 1], cand) if ascending else 0
    # cut and order are free until the planes are cut: they hold the edges' plane ranges meanwhile
    if not ascending or bucket_plane_edges(verts, edges, cand, n_cand, ys, plane_start, plane_edges,
                                           cut, order) < 0:
        scan_girths(verts, tris, edges, tri_edges, edge_tris, ys, method, samples, x0, cand, visited, cut,
                    pts_out, loop_start_out, loop_closed_out, order, hull, work, girth_out)
        return
    for i in range(k):
        s = plane_start[i]
        girth_out[i] = plane_girth(verts, tris, edges, tri_edges, edge_tris, plane_edges[s:],
                                   plane_start[i + 1] - s, ys[i], method, samples, x0, visited, cut,
                                   pts_out, loop_start_out, loop_closed_out, order, hull, work)


@njit
def apart_planes(verts, tris, edges, tri_edges, edge_tris, ys,
                 cand, visited, cut, pts_out, loop_start_out, loop_closed_out, apart_out):
    """Whether the torso and both arms are apart at every plane ``y = ys[i]``: its section has exactly one
    loop whose x-range holds x = 0 (the torso) and, wholly to either side of that loop's x-range, at least
    one other loop (an arm). The edges that can meet ``[min(ys), max(ys)]`` are selected once.

    Arguments as :func:`scan_girths`; ``apart_out`` : (k,) int64 receives 1 or 0 per plane.
    """
    k = ys.shape[0]
    if k == 0:
        return
    n_cand = _select_planes_edges(verts, edges, ys, cand)
    for i in range(k):
        n_pts, n_loops = section_loops(verts, tris, edges, tri_edges, edge_tris, cand, n_cand, ys[i],
                                       visited, cut, pts_out, loop_start_out, loop_closed_out)
        n_torso = 0
        t_lo = 0.0
        t_hi = 0.0
        for j in range(n_loops):
            lo, hi = _x_range(pts_out, loop_start_out[j], loop_start_out[j + 1])
            if lo <= 0.0 <= hi:
                n_torso += 1
                t_lo = lo
                t_hi = hi
        left = False
        right = False
        if n_torso == 1:
            for j in range(n_loops):
                lo, hi = _x_range(pts_out, loop_start_out[j], loop_start_out[j + 1])
                left = left or hi < t_lo
                right = right or lo > t_hi
        apart_out[i] = 1 if (left and right) else 0
