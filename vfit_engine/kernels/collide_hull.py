"""Numba kernels: particles against convex hulls (half-space sets) and spheres.

Shapes
    Hull ``h`` is the polytope ``{x : n_j . x <= b_j}`` over its planes
    ``j in [hull_start[h], hull_start[h + 1])`` (unit outward ``n_j``, offsets ``b_j``,
    skin included). Its depth at ``x`` is ``m_h(x) = max_j (n_j . x - b_j)``: negative
    inside, and then ``-m_h`` is the exact distance to the boundary (for a point inside a
    convex polytope the nearest boundary point lies on the nearest facet plane). Sphere
    ``s`` (centre ``c_s``, radius ``R_s``) has depth ``|x - c_s| - R_s``.

Projection (:func:`collide_hulls`), per free particle at ``x``::

    for each shape k containing x (depth < -INSIDE_TOL), a candidate direction d_k:
        hull:   d = n_j, j the plane of least penetration b_j - n_j . x
                (the minimum translation out of one convex polytope)
        sphere: d = (x - c) / |x - c|   (+Y when x == c)
    march from x along d_k: while x + t d_k is inside any shape o, t += the distance
    along d_k to o's boundary; keep the candidate with the least final t.
    if that candidate was blocked (its march went past its own shape), march along every
    face normal of every hull containing x too, and keep the least t overall.

This is the two-phase rule for overlapping shapes (candidates, then the nearest one
outside every other shape) in the form that cannot fail: a candidate point blocked by
another shape is carried on along the same direction through it instead of being dropped
or retried. A particle inside one shape only gets the least-penetration push. Each shape is convex, so a ray meets it in one interval and the
march ends after at most one advance per shape, outside every shape.

Then the step's displacement ``v = x - x_prev`` (taken before projection) is split about
the outward normal ``n`` where the particle leaves the last shape, as
:mod:`vfit_engine.kernels.collide_sphere` does::

    v_n = (v . n) n,  v_t = v - v_n,  v_n' = -Cr v_n if v . n < 0 else v_n
    x_prev = x - ((1 - Cf) v_t + v_n')

Jakobsen (2001), "Advanced character physics" (projection with Verlet); Bridson et al.
(2002) (normal/tangential split); Ericson (2005), "Real-Time Collision Detection" 5.1.5
(closest point on a triangle, used by :func:`hull_signed_distance`).

Each hull also carries a bounding sphere (``hull_centres``, ``hull_reach``) so that
particles far from a hull skip its planes.
"""
import math

import numpy as np

from vfit_engine._jit import njit
from vfit_engine.kernels.collide_mesh import closest_on_triangle
from vfit_engine.kernels.collide_sphere import place_on_surface, radial_exit

#: A point counts as inside a shape when its depth is below -INSIDE_TOL (m): a particle just
#: projected onto a face must not count as inside that face's hull through rounding.
INSIDE_TOL = 1e-12


@njit
def _hull_depth(x0, x1, x2, normals, offsets, start, end):
    """``max_j (n_j . x - b_j)`` over planes ``start..end-1`` and the plane reaching it."""
    best = -np.inf
    arg = start
    for j in range(start, end):
        d = normals[j, 0] * x0 + normals[j, 1] * x1 + normals[j, 2] * x2 - offsets[j]
        if d > best:
            best = d
            arg = j
    return best, arg


@njit
def _shape_depth(k, x0, x1, x2, normals, offsets, hull_start, hull_centres, hull_reach,
                 sphere_centres, sphere_radii):
    """Depth of shape ``k`` (hulls first, then spheres) at x, with the hull's plane index
    (-1 for spheres); far from a hull's bounding sphere returns +1 without reading planes."""
    h = hull_start.shape[0] - 1
    if k < h:
        e0 = x0 - hull_centres[k, 0]
        e1 = x1 - hull_centres[k, 1]
        e2 = x2 - hull_centres[k, 2]
        if e0 * e0 + e1 * e1 + e2 * e2 > hull_reach[k] * hull_reach[k]:
            return 1.0, -1
        return _hull_depth(x0, x1, x2, normals, offsets, hull_start[k], hull_start[k + 1])
    s = k - h
    e0 = x0 - sphere_centres[s, 0]
    e1 = x1 - sphere_centres[s, 1]
    e2 = x2 - sphere_centres[s, 2]
    return math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) - sphere_radii[s], -1


@njit
def _next_inside(k0, x0, x1, x2, normals, offsets, hull_start, hull_centres, hull_reach,
                 sphere_centres, sphere_radii):
    """First shape ``k >= k0`` (hulls first, then spheres) with ``depth_k(x) < -INSIDE_TOL``, or -1.

    This is the hot test (most particles are outside every shape), so it loops over the shapes
    itself: one call per query rather than one per shape, and a hull is left at the first
    plane the point is not inside.
    """
    h = hull_start.shape[0] - 1
    for k in range(k0, h):
        e0 = x0 - hull_centres[k, 0]
        e1 = x1 - hull_centres[k, 1]
        e2 = x2 - hull_centres[k, 2]
        if e0 * e0 + e1 * e1 + e2 * e2 > hull_reach[k] * hull_reach[k]:
            continue
        inside = True
        for j in range(hull_start[k], hull_start[k + 1]):
            if normals[j, 0] * x0 + normals[j, 1] * x1 + normals[j, 2] * x2 - offsets[j] >= -INSIDE_TOL:
                inside = False
                break
        if inside:
            return k
    for s in range(max(k0 - h, 0), sphere_radii.shape[0]):
        e0 = x0 - sphere_centres[s, 0]
        e1 = x1 - sphere_centres[s, 1]
        e2 = x2 - sphere_centres[s, 2]
        if math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) - sphere_radii[s] < -INSIDE_TOL:
            return h + s
    return -1


@njit
def _candidate(k, x0, x1, x2, normals, offsets, hull_start, sphere_centres, sphere_radii, plane):
    """Exit point of shape ``k`` for a point inside it and the outward normal there."""
    h = hull_start.shape[0] - 1
    if k < h:
        n0 = normals[plane, 0]
        n1 = normals[plane, 1]
        n2 = normals[plane, 2]
        pen = offsets[plane] - (n0 * x0 + n1 * x1 + n2 * x2)
        return x0 + pen * n0, x1 + pen * n1, x2 + pen * n2, n0, n1, n2
    s = k - h
    return radial_exit(x0, x1, x2, sphere_centres[s, 0], sphere_centres[s, 1], sphere_centres[s, 2],
                       sphere_radii[s])


@njit
def _exit_along(k, p0, p1, p2, d0, d1, d2, normals, offsets, hull_start, sphere_centres, sphere_radii):
    """Distance along unit ``d`` from ``p`` (inside shape ``k``) to its boundary, and the
    outward normal there."""
    h = hull_start.shape[0] - 1
    if k < h:
        t = np.inf
        n0 = d0
        n1 = d1
        n2 = d2
        for j in range(hull_start[k], hull_start[k + 1]):
            nd = normals[j, 0] * d0 + normals[j, 1] * d1 + normals[j, 2] * d2
            if nd > 0.0:
                tj = (offsets[j] - (normals[j, 0] * p0 + normals[j, 1] * p1 + normals[j, 2] * p2)) / nd
                if tj < t:
                    t = tj
                    n0 = normals[j, 0]
                    n1 = normals[j, 1]
                    n2 = normals[j, 2]
        return max(t, 0.0), n0, n1, n2
    s = k - h
    e0 = p0 - sphere_centres[s, 0]
    e1 = p1 - sphere_centres[s, 1]
    e2 = p2 - sphere_centres[s, 2]
    ed = e0 * d0 + e1 * d1 + e2 * d2
    ee = e0 * e0 + e1 * e1 + e2 * e2
    big_r = sphere_radii[s]
    t = max(-ed + math.sqrt(max(ed * ed - ee + big_r * big_r, 0.0)), 0.0)
    n0 = (e0 + t * d0) / big_r
    n1 = (e1 + t * d1) / big_r
    n2 = (e2 + t * d2) / big_r
    return t, n0, n1, n2


@njit
def _march(x0, x1, x2, d0, d1, d2, t, best, normals, offsets, hull_start, hull_centres, hull_reach,
           sphere_centres, sphere_radii):
    """Carry ``x + t d`` on along unit ``d`` until it is inside no shape (or ``t >= best``).

    Returns the final ``t`` and the outward normal where it left the last shape (``d`` when it
    left none). Along a ray each convex shape is one open interval and an advance jumps to the
    end of one holding ``t``, so whatever the order the march stops at the first uncovered
    ``t`` after at most one advance per shape.
    """
    n_shapes = hull_start.shape[0] - 1 + sphere_radii.shape[0]
    g0 = d0
    g1 = d1
    g2 = d2
    for _ in range(n_shapes + 1):
        p0 = x0 + t * d0
        p1 = x1 + t * d1
        p2 = x2 + t * d2
        o = _next_inside(0, p0, p1, p2, normals, offsets, hull_start, hull_centres, hull_reach,
                         sphere_centres, sphere_radii)
        if o < 0 or t >= best:
            break
        dt, g0, g1, g2 = _exit_along(o, p0, p1, p2, d0, d1, d2, normals, offsets, hull_start,
                                     sphere_centres, sphere_radii)
        t += dt
    return t, g0, g1, g2


@njit
def _project_particle(x, xp, i, normals, offsets, hull_start, hull_centres, hull_reach,
                      sphere_centres, sphere_radii, friction, restitution):
    """Nearest exit of the union along the candidate directions (module docstring), in place."""
    h = hull_start.shape[0] - 1
    x0 = x[i, 0]
    x1 = x[i, 1]
    x2 = x[i, 2]
    best = np.inf
    blocked = False
    q0 = q1 = q2 = 0.0
    m0 = m1 = m2 = 0.0
    k = -1
    while True:
        k = _next_inside(k + 1, x0, x1, x2, normals, offsets, hull_start, hull_centres, hull_reach,
                         sphere_centres, sphere_radii)
        if k < 0:
            break
        _depth, plane = _shape_depth(k, x0, x1, x2, normals, offsets, hull_start, hull_centres, hull_reach,
                                     sphere_centres, sphere_radii)
        c0, c1, c2, d0, d1, d2 = _candidate(k, x0, x1, x2, normals, offsets, hull_start,
                                            sphere_centres, sphere_radii, plane)
        t0 = math.sqrt((c0 - x0) ** 2 + (c1 - x1) ** 2 + (c2 - x2) ** 2)
        if t0 >= best:
            continue
        t, g0, g1, g2 = _march(x0, x1, x2, d0, d1, d2, t0, best, normals, offsets, hull_start, hull_centres,
                               hull_reach, sphere_centres, sphere_radii)
        if t < best:
            best = t
            blocked = t > t0
            q0 = x0 + t * d0
            q1 = x1 + t * d1
            q2 = x2 + t * d2
            m0 = g0
            m1 = g1
            m2 = g2
    if blocked:
        # the nearest exit was blocked by an overlapping shape: try every face of every hull
        # holding the particle, since a face other than the least-penetration one may lead out
        # sooner (the overlap of two boxes is left fastest sideways)
        k = -1
        while True:
            k = _next_inside(k + 1, x0, x1, x2, normals, offsets, hull_start, hull_centres, hull_reach,
                             sphere_centres, sphere_radii)
            if k < 0 or k >= h:
                break
            for j in range(hull_start[k], hull_start[k + 1]):
                d0 = normals[j, 0]
                d1 = normals[j, 1]
                d2 = normals[j, 2]
                t0 = offsets[j] - (d0 * x0 + d1 * x1 + d2 * x2)
                if t0 >= best:
                    continue
                t, g0, g1, g2 = _march(x0, x1, x2, d0, d1, d2, t0, best, normals, offsets, hull_start,
                                       hull_centres, hull_reach, sphere_centres, sphere_radii)
                if t < best:
                    best = t
                    q0 = x0 + t * d0
                    q1 = x1 + t * d1
                    q2 = x2 + t * d2
                    m0 = g0
                    m1 = g1
                    m2 = g2
    if best == np.inf:
        return
    place_on_surface(x, xp, i, q0, q1, q2, m0, m1, m2, friction, restitution)


@njit
def _collide_hulls(x, xp, inv_mass, normals, offsets, hull_start, hull_centres, hull_reach,
                   sphere_centres, sphere_radii, friction, restitution):
    """Project every free particle (inv_mass > 0), serially."""
    for i in range(x.shape[0]):
        if inv_mass[i] > 0.0:
            _project_particle(x, xp, i, normals, offsets, hull_start, hull_centres, hull_reach,
                              sphere_centres, sphere_radii, friction, restitution)


@njit
def _signed_distance(points, normals, offsets, hull_start, tri_verts, tris, tri_start,
                     sphere_centres, sphere_radii, depth_scratch, out):
    """min over shapes of the exact signed distance (module docstring), into ``out``.

    Outside a hull the distance is the least distance to its triangles; the depth
    ``m_h > 0`` is a lower bound of it, so hulls are visited by increasing ``m_h`` and
    those with ``m_h`` above the best so far are skipped without changing the result.
    ``depth_scratch`` (h,) float64 holds the depths of one point.
    """
    h = hull_start.shape[0] - 1
    for i in range(points.shape[0]):
        p0 = points[i, 0]
        p1 = points[i, 1]
        p2 = points[i, 2]
        best = np.inf
        for s in range(sphere_radii.shape[0]):
            e0 = p0 - sphere_centres[s, 0]
            e1 = p1 - sphere_centres[s, 1]
            e2 = p2 - sphere_centres[s, 2]
            d = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) - sphere_radii[s]
            if d < best:
                best = d
        for k in range(h):
            m = -np.inf
            for j in range(hull_start[k], hull_start[k + 1]):
                d = normals[j, 0] * p0 + normals[j, 1] * p1 + normals[j, 2] * p2 - offsets[j]
                if d > m:
                    m = d
            depth_scratch[k] = m
            if m <= 0.0 and m < best:
                best = m
        while best > 0.0:
            k = -1
            m = best
            for kk in range(h):
                if depth_scratch[kk] < m:
                    m = depth_scratch[kk]
                    k = kk
            if k < 0:
                break
            depth_scratch[k] = np.inf
            dd = np.inf
            for t in range(tri_start[k], tri_start[k + 1]):
                a = tris[t, 0]
                b = tris[t, 1]
                c = tris[t, 2]
                q0, q1, q2, _f = closest_on_triangle(
                    p0, p1, p2, tri_verts[a, 0], tri_verts[a, 1], tri_verts[a, 2],
                    tri_verts[b, 0], tri_verts[b, 1], tri_verts[b, 2],
                    tri_verts[c, 0], tri_verts[c, 1], tri_verts[c, 2])
                e = (p0 - q0) ** 2 + (p1 - q1) ** 2 + (p2 - q2) ** 2
                if e < dd:
                    dd = e
            d = math.sqrt(dd)
            if d < best:
                best = d
        out[i] = best


def _c(a, shape_tail=None, dtype=np.float64):
    a = np.ascontiguousarray(a, dtype=dtype)
    return a.reshape((-1,) + shape_tail) if shape_tail else a.ravel()


def collide_hulls(pos, pos_prev, inv_mass, normals, offsets, hull_start, hull_centres, hull_reach,
                  sphere_centres, sphere_radii, friction, restitution):
    """Project particles out of hulls and spheres in place (see module docstring).

    Parameters
    ----------
    pos, pos_prev : (n, 3) float64, m
        C-contiguous float64, modified in place.
    inv_mass : (n,) float64, 1/kg
        Pinned particles (0) are left alone.
    normals : (H, 3) float64
        Unit outward plane normals of all hulls.
    offsets : (H,) float64, m
        Plane offsets ``b`` (skin included).
    hull_start : (h + 1,) int64
        Hull ``k`` owns planes ``hull_start[k]:hull_start[k + 1]``.
    hull_centres : (h, 3) float64, m
    hull_reach : (h,) float64, m
        A bounding sphere of each hull (skin included).
    sphere_centres : (s, 3) float64, m
    sphere_radii : (s,) float64, m
        Skin included.
    friction, restitution : float
        Cf and Cr in [0, 1].
    """
    for a in (pos, pos_prev):
        if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and a.ndim == 2):
            raise TypeError("pos and pos_prev must be C-contiguous float64 (n, 3) arrays (modified in place)")
    _collide_hulls(pos, pos_prev, _c(inv_mass), _c(normals, (3,)), _c(offsets), _c(hull_start, dtype=np.int64),
                   _c(hull_centres, (3,)), _c(hull_reach), _c(sphere_centres, (3,)), _c(sphere_radii),
                   float(friction), float(restitution))


def hull_signed_distance(points, normals, offsets, hull_start, tri_verts, tris, tri_start,
                         sphere_centres, sphere_radii):
    """Signed distance of points to the union of hulls and spheres, m (negative inside).

    Parameters
    ----------
    points : (n, 3) float, m
    normals, offsets, hull_start
        As in :func:`collide_hulls` (offsets without skin).
    tri_verts : (V, 3) float64, m
        Vertices of the hulls' boundary triangles.
    tris : (T, 3) int64
        Triangles into ``tri_verts``; hull ``k`` owns ``tris[tri_start[k]:tri_start[k + 1]]``.
    tri_start : (h + 1,) int64
    sphere_centres : (s, 3) float64, m
    sphere_radii : (s,) float64, m

    Returns
    -------
    (n,) float64, m
        ``+inf`` when there are no shapes.
    """
    p = _c(points, (3,))
    out = np.empty(p.shape[0])
    _signed_distance(p, _c(normals, (3,)), _c(offsets), _c(hull_start, dtype=np.int64), _c(tri_verts, (3,)),
                     _c(tris, (3,), dtype=np.int64), _c(tri_start, dtype=np.int64), _c(sphere_centres, (3,)),
                     _c(sphere_radii), np.empty(max(len(hull_start) - 1, 0)), out)
    return out
