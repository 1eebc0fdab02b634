"""Slow, obvious NumPy/SciPy references for the section and girth kernels.

Each function does the same job as a kernel in ``vfit_engine/kernels/section.py`` or
``vfit_engine/kernels/girth.py`` in the plainest way available, for tests only.
"""
import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial import ConvexHull


def section_segments(verts, tris, h):
    """Per-triangle section segments with the plane ``y = h``.

    A vertex with ``y >= h`` is above. Each edge's point is interpolated from its
    lower-index vertex, as the kernel does, so points compare bit for bit.

    Returns
    -------
    (S, 2, 2) float64
        One (x, z) segment per cut triangle.
    """
    segs = []
    for tri in tris:
        pts = []
        for k in range(3):
            a, b = int(tri[k]), int(tri[(k + 1) % 3])
            if (verts[a, 1] >= h) != (verts[b, 1] >= h):
                a, b = min(a, b), max(a, b)
                s = (h - verts[a, 1]) / (verts[b, 1] - verts[a, 1])
                p = verts[a] + s * (verts[b] - verts[a])
                pts.append((p[0], p[2]))
        assert len(pts) in (0, 2)
        if pts:
            segs.append(pts)
    return np.array(segs, dtype=np.float64).reshape(-1, 2, 2)


def hull_perimeter(pts):
    """Convex hull perimeter by SciPy (Qhull); needs >= 3 non-collinear points."""
    return float(ConvexHull(pts).area)


def polyline_length(pts, closed=True):
    """Length of the polyline, closed by its last segment if ``closed``."""
    if closed and len(pts) > 2:
        pts = np.vstack([pts, pts[:1]])
    return float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))


def signed_area(pts):
    """Shoelace area, positive when turning from +x towards +z."""
    x, z = pts[:, 0], pts[:, 1]
    return 0.5 * float(np.sum(x * np.roll(z, -1) - np.roll(x, -1) * z))


def centroid_x(pts):
    """x of the polygon centroid."""
    x, z = pts[:, 0], pts[:, 1]
    c = x * np.roll(z, -1) - np.roll(x, -1) * z
    return float(np.sum((x + np.roll(x, -1)) * c) / (3.0 * np.sum(c)))


def torso_index(loops, x0=0.0):
    """Largest-|area| loop whose x-range contains ``x0``, else nearest centroid; -1 if none."""
    inside = [i for i, lp in enumerate(loops) if lp[:, 0].min() <= x0 <= lp[:, 0].max()]
    if inside:
        return max(inside, key=lambda i: abs(signed_area(loops[i])))
    if not loops:
        return -1
    return int(np.argmin([abs(centroid_x(lp) - x0) for lp in loops]))


def spline_length(pts, samples=8):
    """Profile-spline girth with SciPy's natural CubicSpline.

    Split the loop at its min-x and max-x points, fit a natural cubic spline in
    cumulative chord length through each half (coincident points dropped), sample
    ``samples`` points per interval and sum the polyline lengths.
    """
    n = len(pts)
    i0, i1 = int(np.argmin(pts[:, 0])), int(np.argmax(pts[:, 0]))
    total = 0.0
    for a, b in ((i0, i1), (i1, i0)):
        idx = [(a + j) % n for j in range((b - a) % n + 1)]
        half = [pts[idx[0]]]
        for k in idx[1:]:
            if np.hypot(*(pts[k] - half[-1])) > 1e-12:
                half.append(pts[k])
        half = np.array(half)
        if len(half) < 2:
            continue
        t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(half, axis=0), axis=1))])
        if len(half) == 2:
            total += t[1]
            continue
        cs = CubicSpline(t, half, bc_type="natural")
        tt = np.concatenate([np.linspace(t[j], t[j + 1], samples + 1)[:-1] for j in range(len(t) - 1)] + [t[-1:]])
        total += polyline_length(cs(tt), closed=False)
    return total


def edge_tables(tris):
    """``build_topology``'s tables the plain way: a dict of sorted vertex pairs, edges in sorted order.

    Returns (edges (E, 2), tri_edges (T, 3), edge_tris (E, 2), counts (E,)), all int64.
    """
    users = {}
    for t, tri in enumerate(tris.tolist()):
        for k in range(3):
            users.setdefault(tuple(sorted((tri[k], tri[(k + 1) % 3]))), []).append(t)
    keys = sorted(users)
    index = {e: i for i, e in enumerate(keys)}
    tri_edges = [[index[tuple(sorted((tri[k], tri[(k + 1) % 3])))] for k in range(3)] for tri in tris.tolist()]
    edge_tris = [(users[e] + [-1, -1])[:2] for e in keys]
    return (np.array(keys, dtype=np.int64).reshape(-1, 2), np.array(tri_edges, dtype=np.int64).reshape(-1, 3),
            np.array(edge_tris, dtype=np.int64).reshape(-1, 2), np.array([len(users[e]) for e in keys]))
