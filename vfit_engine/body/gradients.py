"""Exact gradients of body measurements with respect to the vertex positions.

The morph solver's body is linear in its channel weights (``v = v0 + sum x_j D_j``),
so the Jacobian of a measurement ``g`` is ``dg/dx_j = grad_v g . D_j``: one
gradient per measurement replaces a finite difference per channel.

* tape girth at a fixed plane ``y = h``: the hull perimeter
  ``P = sum_k |q_k+1 - q_k|`` has ``dP/dq_k = u_k-1,k - u_k,k+1`` (unit hull
  edges); each hull point is the cut of a mesh edge (a, b),
  ``q = a + s (b - a)`` with ``s = (h - a_y) / (b_y - a_y)``, whose (x, z)
  depend on a and b directly and through ``s`` on their heights;
* ruler: ``L = sum |v_i+1 - v_i|``;
* stature: the highest and the lowest vertex;
* enclosed volume: ``V = sum a . (b x c) / 6`` over triangles.

Each gradient is sparse: (vertex indices (k,), d/dv (k, 3)).
"""
from __future__ import annotations

import numpy as np

from vfit_engine.kernels.girth_grad import girth_gradient as kernel
from vfit_engine.kernels.section import select_band_edges


def _unit(d):
    n = np.sqrt((d ** 2).sum(axis=1))
    return d / np.where(n > 0, n, 1.0)[:, None]


def girth_gradient(sections, verts, h, x0=0.0):
    """Gradient of the torso tape girth (convex hull perimeter) at the plane ``y = h``: the Numba
    kernel :func:`vfit_engine.kernels.girth_grad.girth_gradient` (one band selection and one section
    walk; the per-girth cost of the morph's Jacobian). Arguments and result as
    :func:`girth_gradient_reference`, its rows a rotation of the reference's (the hull starts at
    another point).
    """
    return girth_gradient_dy(sections, verts, h, 0.0, x0)[:2]


def girth_gradient_dy(sections, verts, h, eps, x0=0.0):
    """:func:`girth_gradient` and ``(g(h - eps), g(h + eps))``, the tape girths (m) beside the plane, from
    the same kernel call (the morph's ``dg/dy``). Returns (idx, grad, (g_lo, g_hi))."""
    verts = np.ascontiguousarray(verts, dtype=np.float64)
    s = sections
    rows = 2 * s.edge_count  # at most 2 per cut edge; np.empty touches only the pages written
    idx, grad, g = np.empty(rows, dtype=np.int64), np.empty((rows, 3)), np.empty(2)
    n = kernel(verts, s.tris, s.edges, s.tri_edges, s.edge_tris, float(h), float(x0), float(eps), *s.scratch,
               idx, grad, g)
    if n < 0:  # no loop, or several, across x0: the reference's tie-breaks (the kernel's docstring)
        return (*girth_gradient_reference(sections, verts, h, x0), (g[0], g[1]))
    return idx[:n].copy(), grad[:n].copy(), (g[0], g[1])


def girth_gradient_reference(sections, verts, h, x0=0.0):
    """Gradient of the torso tape girth (convex hull perimeter) at the plane ``y = h`` (NumPy and
    SciPy's ConvexHull: the slow reference of :func:`girth_gradient`).

    Parameters
    ----------
    sections : vfit_engine.section.MeshSections
    verts : (n, 3) float64, m
    h : float, m

    Returns
    -------
    idx : (k,) int64, grad : (k, 3) float64 (m per m)
    """
    loops = sections.loops(verts, h)
    if not loops:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    # the same torso rule as the kernel: largest loop whose x-range holds x0, else nearest centroid
    def area(p):
        return 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))
    holding = [i for i, p in enumerate(loops) if p[:, 0].min() <= x0 <= p[:, 0].max()]
    if holding:
        pts = loops[max(holding, key=lambda i: area(loops[i]))]
    else:
        pts = loops[int(np.argmin([abs(p[:, 0].mean() - x0) for p in loops]))]
    if pts.shape[0] < 3:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    from scipy.spatial import ConvexHull  # local: ~0.2 s at every vfit morph's start, for this rare fallback

    q_idx = ConvexHull(pts).vertices  # counter-clockwise
    q = pts[q_idx]
    d_out = _unit(np.roll(q, -1, axis=0) - q)
    d_in = _unit(q - np.roll(q, 1, axis=0))
    dq = d_in - d_out  # (m, 2): dP/d(x, z) of each hull point

    # match every hull point to the mesh edge it was cut from

    cand = sections.scratch.cand
    n_cut = select_band_edges(verts, sections.edges, h, h, cand)  # the edges y = h cuts
    cut = cand[:n_cut]
    a, b = sections.edges[cut, 0], sections.edges[cut, 1]
    s = (h - verts[a, 1]) / (verts[b, 1] - verts[a, 1])
    px = verts[a, 0] + s * (verts[b, 0] - verts[a, 0])
    pz = verts[a, 2] + s * (verts[b, 2] - verts[a, 2])
    dist = (px[None, :] - q[:, 0:1]) ** 2 + (pz[None, :] - q[:, 1:2]) ** 2
    k = np.argmin(dist, axis=1)
    a, b, s = a[k], b[k], s[k]
    va, vb = verts[a], verts[b]
    dy = vb[:, 1] - va[:, 1]
    # q_xz = a_xz + s (b_xz - a_xz): direct terms, then s's dependence on a_y and b_y
    ds_day = (s - 1.0) / dy
    ds_dby = -s / dy
    dxz = vb[:, [0, 2]] - va[:, [0, 2]]
    chain = (dq * dxz).sum(axis=1)  # dP/ds
    ga = np.zeros((len(k), 3))
    gb = np.zeros((len(k), 3))
    ga[:, 0], ga[:, 2] = (1.0 - s) * dq[:, 0], (1.0 - s) * dq[:, 1]
    gb[:, 0], gb[:, 2] = s * dq[:, 0], s * dq[:, 1]
    ga[:, 1] = chain * ds_day
    gb[:, 1] = chain * ds_dby
    return np.concatenate([a, b]), np.concatenate([ga, gb])


def ruler_gradient(verts, indices):
    """Gradient of the polyline length through ``verts[indices]``."""
    idx = np.asarray(indices, dtype=np.int64)
    u = _unit(verts[idx[1:]] - verts[idx[:-1]])
    return np.concatenate([idx[1:], idx[:-1]]), np.concatenate([u, -u])


def stature_gradient(verts, n_body):
    """Gradient of max Y - min Y over the first ``n_body`` vertices."""
    y = verts[:n_body, 1]
    return np.array([int(np.argmax(y)), int(np.argmin(y))]), np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])


def volume_gradient(verts, tris):
    """Gradient of the enclosed volume (m^3 per m) over all vertices touched by ``tris``."""
    a, b, c = (verts[tris[:, k]] for k in range(3))
    g = np.zeros_like(verts)
    np.add.at(g, tris[:, 0], np.cross(b, c) / 6.0)
    np.add.at(g, tris[:, 1], np.cross(c, a) / 6.0)
    np.add.at(g, tris[:, 2], np.cross(a, b) / 6.0)
    idx = np.unique(tris)
    return idx, g[idx]
