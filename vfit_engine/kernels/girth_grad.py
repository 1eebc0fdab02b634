"""Numba kernel for the exact gradient of a torso tape girth (the hull perimeter of the section at
``y = h``) with respect to the mesh vertices.

:func:`vfit_engine.body.gradients.girth_gradient_reference` is its NumPy/SciPy reference (the
formulas are documented in :mod:`vfit_engine.body.gradients`); this kernel does the same in one
band selection and one section walk, with the monotone-chain hull of
:mod:`vfit_engine.kernels.girth` instead of SciPy's Qhull. The hull's points come out
counter-clockwise from the lowest-x point (Qhull starts elsewhere), so the rows are a rotation of
the reference's.

Caching caveat: this module calls kernels of ``girth.py`` and ``section.py``; Numba's on-disk cache
checks only this file, so after editing those delete the cached ``girth_grad.*`` files.
"""
import math

import numpy as np

from vfit_engine._jit import njit
from vfit_engine.kernels.girth import hull_ccw
from vfit_engine.kernels.section import is_cut, plane_girth, section_loops, select_band_edges


@njit
def _torso_loop(pts, loop_start, n_loops, x0):
    """The loop whose x-range holds ``x0`` when exactly one does, else -1: the reference then picks among
    several by area, or among none by the nearest mean x, and mirror-image legs tie on the mean up to
    the order of summation, so those rare planes are left to it."""
    found = -1
    for i in range(n_loops):
        xmin = np.inf
        xmax = -np.inf
        for p in range(loop_start[i], loop_start[i + 1]):
            xmin = min(xmin, pts[p, 0])
            xmax = max(xmax, pts[p, 0])
        if xmin <= x0 <= xmax:
            if found >= 0:
                return -1
            found = i
    return found


@njit
def _unit_xz(x, z):
    n = math.sqrt(x * x + z * z)
    if n > 0.0:
        return x / n, z / n
    return x, z


@njit
def girth_gradient(verts, tris, edges, tri_edges, edge_tris, h, x0, eps, cand, visited, cut, pts_out,
                   loop_start_out, loop_closed_out, order, hull, work, idx_out, grad_out, girth_out):
    """Gradient of the torso tape girth at ``y = h``, and the girths at ``h -+ eps`` (the band's own
    motion: ``dg/dy`` by a central difference), all from one band selection.

    Parameters
    ----------
    verts, tris, edges, tri_edges, edge_tris : as :func:`vfit_engine.kernels.section.section_loops`
    h, x0, eps : float, m
    cand, visited, cut, pts_out, loop_start_out, loop_closed_out : scratch as ``section_loops``
    order, hull, work : scratch as :func:`vfit_engine.kernels.girth.loop_girth`
    idx_out : (>= 2 m,) int64
        Receives the vertex indices: the lower-index end ``a`` of each hull point's edge, then the
        upper ``b`` (m hull points).
    grad_out : (>= 2 m, 3) float64
        Receives d girth / d vertex for the rows of ``idx_out``, m per m.
    girth_out : (2,) float64
        Receives the hull girths at ``h - eps`` and ``h + eps`` (m), the same bit for bit as
        :func:`vfit_engine.kernels.section.scan_girths` there (always written).

    Returns
    -------
    int
        ``2 m`` rows written (0 when the plane misses the mesh or its torso loop has < 3 points); -1
        when not exactly one loop holds ``x0`` (nothing written: use the reference).
    """
    n_cand = select_band_edges(verts, edges, h - eps, h + eps, cand)  # ascending
    for i in range(2):  # a superset of each plane's cut edges, in order: scan_girths's loops and girths
        girth_out[i] = plane_girth(verts, tris, edges, tri_edges, edge_tris, cand, n_cand, h + (2 * i - 1) * eps,
                                   0, 1, x0, visited, cut, pts_out, loop_start_out, loop_closed_out,
                                   order, hull, work)
    n_cut = 0  # the edges y = h cuts, ascending, moved to the front of cand
    for c in range(n_cand):
        if is_cut(verts, edges, cand[c], h):
            cand[n_cut] = cand[c]
            n_cut += 1
    n_pts, n_loops = section_loops(verts, tris, edges, tri_edges, edge_tris, cand, n_cut, h,
                                   visited, cut, pts_out, loop_start_out, loop_closed_out)
    if n_loops == 0:
        return 0
    t = _torso_loop(pts_out, loop_start_out, n_loops, x0)
    if t < 0:
        return -1
    lp = pts_out[loop_start_out[t]:loop_start_out[t + 1]]
    if lp.shape[0] < 3:
        return 0
    m = hull_ccw(lp, order, hull)
    for j in range(m):
        q = hull[j]
        qn = hull[(j + 1) % m]
        qp = hull[(j - 1) % m]
        ox, oz = _unit_xz(lp[qn, 0] - lp[q, 0], lp[qn, 1] - lp[q, 1])
        ix, iz = _unit_xz(lp[q, 0] - lp[qp, 0], lp[q, 1] - lp[qp, 1])
        dqx = ix - ox  # dP/d(x, z) of the hull point
        dqz = iz - oz
        # the cut edge the hull point came from: nearest cut point, the first on a tie (as np.argmin)
        best = 0
        best_d = np.inf
        for c in range(n_cut):
            e = cand[c]
            a = edges[e, 0]
            b = edges[e, 1]
            s = (h - verts[a, 1]) / (verts[b, 1] - verts[a, 1])
            px = verts[a, 0] + s * (verts[b, 0] - verts[a, 0])
            pz = verts[a, 2] + s * (verts[b, 2] - verts[a, 2])
            d = (px - lp[q, 0]) ** 2 + (pz - lp[q, 1]) ** 2
            if d < best_d:
                best_d = d
                best = e
        a = edges[best, 0]
        b = edges[best, 1]
        s = (h - verts[a, 1]) / (verts[b, 1] - verts[a, 1])
        dy = verts[b, 1] - verts[a, 1]
        chain = dqx * (verts[b, 0] - verts[a, 0]) + dqz * (verts[b, 2] - verts[a, 2])  # dP/ds
        idx_out[j] = a
        idx_out[m + j] = b
        grad_out[j, 0] = (1.0 - s) * dqx
        grad_out[j, 1] = chain * ((s - 1.0) / dy)
        grad_out[j, 2] = (1.0 - s) * dqz
        grad_out[m + j, 0] = s * dqx
        grad_out[m + j, 1] = chain * (-s / dy)
        grad_out[m + j, 2] = s * dqz
    return 2 * m
