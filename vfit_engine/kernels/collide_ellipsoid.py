"""Numba kernels: particles against a set of solid (possibly overlapping) ellipsoids.

An ellipsoid has centre ``c``, rotation ``R`` (3 x 3, rows = its unit axes) and semi-axes
``a`` (3,). A point ``p`` has local coordinates ``y = R (p - c)`` and *level*
``L(p) = sum_i (y_i / a_i)^2``: inside when ``L < 1``.

Surface point of an inside point (two methods):

* radial (default; the seed's): along the ray from the centre through ``p``,
  ``q = c + R^T y / sqrt(L)``, i.e. scale ``y`` so that ``|A^-1 y| = 1``;
* closest: the true closest surface point ``q_i = a_i^2 y_i / (a_i^2 + t)``, ``t`` the root
  of ``sum_i (a_i y_i / (a_i^2 + t))^2 = 1`` with ``t > -min a_i^2``, found by bisection
  with Eberly's robust bracketing and degenerate-case handling (D. Eberly, "Distance from a
  point to an ellipse, an ellipsoid, or a hyperellipsoid", Geometric Tools, 2013).

Outward normal at ``q``: ``n = R^T (y_q / a^2)`` normalised (gradient of the level).

Overlapping ellipsoids (the seed's two-phase handling), per free particle ``x``:

1. collect every ellipsoid containing the current point ``p`` (first ``p = x``) and the
   candidate surface point on each;
2. keep the candidate nearest to ``p`` that is not inside any *other* ellipsoid. If every
   candidate is inside another one, move ``p`` to the nearest candidate and repeat (at most
   ``max_rounds`` rounds). If that still fails, the farthest-out option: walk the ray from
   ``x`` through ``p`` until it leaves every ellipsoid (the union of the ray's
   entry/exit intervals), which always succeeds.

Velocity, with ``n`` the outward normal where the particle lands, like the sphere kernel::

    v = x - x_prev,  v_n = (v . n) n,  v_t = v - v_n
    v_n' = -Cr v_n  if v . n < 0  else  v_n
    x_prev = x_new - ((1 - Cf) v_t + v_n')

(Jakobsen 2001 for projection with Verlet; Bridson et al. 2002 for the split.)
"""
import math

import numpy as np

from vfit_engine._jit import njit
from vfit_engine.kernels.collide_sphere import place_on_surface

#: A candidate counts as inside another ellipsoid when that level is below 1 - LEVEL_TOL.
LEVEL_TOL = 1e-12
#: Bisection steps of the closest-point root (doubles converge in far fewer).
_MAX_BISECT = 200


@njit
def _local(p0, p1, p2, c, rot, e):
    """Local coordinates y = R (p - c) of a point in ellipsoid ``e``."""
    d0 = p0 - c[e, 0]
    d1 = p1 - c[e, 1]
    d2 = p2 - c[e, 2]
    y0 = rot[e, 0, 0] * d0 + rot[e, 0, 1] * d1 + rot[e, 0, 2] * d2
    y1 = rot[e, 1, 0] * d0 + rot[e, 1, 1] * d1 + rot[e, 1, 2] * d2
    y2 = rot[e, 2, 0] * d0 + rot[e, 2, 1] * d1 + rot[e, 2, 2] * d2
    return y0, y1, y2


@njit
def _world(y0, y1, y2, c, rot, e):
    """World point c + R^T y."""
    return (c[e, 0] + rot[e, 0, 0] * y0 + rot[e, 1, 0] * y1 + rot[e, 2, 0] * y2,
            c[e, 1] + rot[e, 0, 1] * y0 + rot[e, 1, 1] * y1 + rot[e, 2, 1] * y2,
            c[e, 2] + rot[e, 0, 2] * y0 + rot[e, 1, 2] * y1 + rot[e, 2, 2] * y2)


@njit
def _level(p0, p1, p2, c, rot, axes, e):
    """Level sum_i (y_i / a_i)^2 of a point in ellipsoid e (< 1 inside)."""
    y0, y1, y2 = _local(p0, p1, p2, c, rot, e)
    u0 = y0 / axes[e, 0]
    u1 = y1 / axes[e, 1]
    u2 = y2 / axes[e, 2]
    return u0 * u0 + u1 * u1 + u2 * u2


@njit
def _robust_length3(v0, v1, v2):
    m = max(abs(v0), abs(v1), abs(v2))
    if m == 0.0:
        return 0.0
    return m * math.sqrt((v0 / m) ** 2 + (v1 / m) ** 2 + (v2 / m) ** 2)


@njit
def _root2(r0, z0, z1, g):
    """Eberly's GetRoot for an ellipse: s with (r0 z0/(s+r0))^2 + (z1/(s+1))^2 = 1."""
    n0 = r0 * z0
    s0 = z1 - 1.0
    s1 = 0.0 if g < 0.0 else _robust_length3(n0, z1, 0.0) - 1.0
    s = 0.0
    for _ in range(_MAX_BISECT):
        s = 0.5 * (s0 + s1)
        if s == s0 or s == s1:
            break
        q0 = n0 / (s + r0)
        q1 = z1 / (s + 1.0)
        g = q0 * q0 + q1 * q1 - 1.0
        if g > 0.0:
            s0 = s
        elif g < 0.0:
            s1 = s
        else:
            break
    return s


@njit
def _root3(r0, r1, z0, z1, z2, g):
    """Eberly's GetRoot for an ellipsoid (see module docstring)."""
    n0 = r0 * z0
    n1 = r1 * z1
    s0 = z2 - 1.0
    s1 = 0.0 if g < 0.0 else _robust_length3(n0, n1, z2) - 1.0
    s = 0.0
    for _ in range(_MAX_BISECT):
        s = 0.5 * (s0 + s1)
        if s == s0 or s == s1:
            break
        q0 = n0 / (s + r0)
        q1 = n1 / (s + r1)
        q2 = z2 / (s + 1.0)
        g = q0 * q0 + q1 * q1 + q2 * q2 - 1.0
        if g > 0.0:
            s0 = s
        elif g < 0.0:
            s1 = s
        else:
            break
    return s


@njit
def _closest_ellipse(e0, e1, y0, y1):
    """Closest point on the ellipse e0 >= e1 > 0 to (y0, y1), y >= 0 (Eberly 2013)."""
    if y1 > 0.0:
        if y0 > 0.0:
            z0 = y0 / e0
            z1 = y1 / e1
            g = z0 * z0 + z1 * z1 - 1.0
            if g != 0.0:
                r0 = (e0 / e1) ** 2
                s = _root2(r0, z0, z1, g)
                return r0 * y0 / (s + r0), y1 / (s + 1.0)
            return y0, y1
        return 0.0, e1
    num0 = e0 * y0
    den0 = e0 * e0 - e1 * e1
    if num0 < den0:
        xd = num0 / den0
        return e0 * xd, e1 * math.sqrt(max(0.0, 1.0 - xd * xd))
    return e0, 0.0


@njit
def _closest_sorted(e0, e1, e2, y0, y1, y2):
    """Closest point on the ellipsoid e0 >= e1 >= e2 > 0 to y >= 0 (Eberly 2013)."""
    if y2 > 0.0:
        if y1 > 0.0:
            if y0 > 0.0:
                z0 = y0 / e0
                z1 = y1 / e1
                z2 = y2 / e2
                g = z0 * z0 + z1 * z1 + z2 * z2 - 1.0
                if g != 0.0:
                    r0 = (e0 / e2) ** 2
                    r1 = (e1 / e2) ** 2
                    s = _root3(r0, r1, z0, z1, z2, g)
                    return r0 * y0 / (s + r0), r1 * y1 / (s + r1), y2 / (s + 1.0)
                return y0, y1, y2
            x1, x2 = _closest_ellipse(e1, e2, y1, y2)
            return 0.0, x1, x2
        if y0 > 0.0:
            x0, x2 = _closest_ellipse(e0, e2, y0, y2)
            return x0, 0.0, x2
        return 0.0, 0.0, e2
    den0 = e0 * e0 - e2 * e2
    den1 = e1 * e1 - e2 * e2
    n0 = e0 * y0
    n1 = e1 * y1
    if n0 < den0 and n1 < den1:
        a0 = n0 / den0
        a1 = n1 / den1
        disc = 1.0 - a0 * a0 - a1 * a1
        if disc > 0.0:
            return e0 * a0, e1 * a1, e2 * math.sqrt(disc)
    x0, x1 = _closest_ellipse(e0, e1, y0, y1)
    return x0, x1, 0.0


@njit
def closest_local(y0, y1, y2, a0, a1, a2):
    """Closest point on the axis-aligned ellipsoid (a0, a1, a2) to local point y (any signs).

    Sorts the axes, folds y into the first octant, calls Eberly's solver and undoes both.
    """
    a = (a0, a1, a2)
    y = (abs(y0), abs(y1), abs(y2))
    # descending order of the semi-axes
    i0, i1, i2 = 0, 1, 2
    if a[i0] < a[i1]:
        i0, i1 = i1, i0
    if a[i1] < a[i2]:
        i1, i2 = i2, i1
    if a[i0] < a[i1]:
        i0, i1 = i1, i0
    x0s, x1s, x2s = _closest_sorted(a[i0], a[i1], a[i2], y[i0], y[i1], y[i2])
    o0 = x0s if i0 == 0 else (x1s if i1 == 0 else x2s)
    o1 = x0s if i0 == 1 else (x1s if i1 == 1 else x2s)
    o2 = x0s if i0 == 2 else (x1s if i1 == 2 else x2s)
    return math.copysign(o0, y0), math.copysign(o1, y1), math.copysign(o2, y2)


@njit
def _surface_local(y0, y1, y2, a0, a1, a2, closest):
    """Candidate surface point (local) of an inside point: radial or closest."""
    if closest:
        return closest_local(y0, y1, y2, a0, a1, a2)
    lev = (y0 / a0) ** 2 + (y1 / a1) ** 2 + (y2 / a2) ** 2
    if lev == 0.0:
        # the centre itself: no radial direction, the nearest surface point is as good as any
        return closest_local(y0, y1, y2, a0, a1, a2)
    k = 1.0 / math.sqrt(lev)
    return y0 * k, y1 * k, y2 * k


@njit
def _normal(y0, y1, y2, rot, axes, e):
    """Outward unit normal (world) at local surface point y of ellipsoid e."""
    g0 = y0 / (axes[e, 0] * axes[e, 0])
    g1 = y1 / (axes[e, 1] * axes[e, 1])
    g2 = y2 / (axes[e, 2] * axes[e, 2])
    n0 = rot[e, 0, 0] * g0 + rot[e, 1, 0] * g1 + rot[e, 2, 0] * g2
    n1 = rot[e, 0, 1] * g0 + rot[e, 1, 1] * g1 + rot[e, 2, 1] * g2
    n2 = rot[e, 0, 2] * g0 + rot[e, 1, 2] * g1 + rot[e, 2, 2] * g2
    m = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if m == 0.0:
        return 0.0, 1.0, 0.0
    return n0 / m, n1 / m, n2 / m


@njit
def _inside(p0, p1, p2, c, rot, axes, bound2, e):
    """Is the point strictly inside ellipsoid e (level < 1 - LEVEL_TOL)?"""
    d0 = p0 - c[e, 0]
    d1 = p1 - c[e, 1]
    d2 = p2 - c[e, 2]
    if d0 * d0 + d1 * d1 + d2 * d2 >= bound2[e]:
        return False
    return _level(p0, p1, p2, c, rot, axes, e) < 1.0 - LEVEL_TOL


@njit
def _inside_other(q0, q1, q2, c, rot, axes, bound2, skip):
    for f in range(axes.shape[0]):
        if f != skip and _inside(q0, q1, q2, c, rot, axes, bound2, f):
            return True
    return False


@njit
def _ray_exit(x0, x1, x2, d0, d1, d2, c, rot, axes, e):
    """Entry and exit parameters (s_in, s_out) of the line x + s d through ellipsoid e;
    (inf, -inf) when it misses (roots of a quadratic in s)."""
    y0, y1, y2 = _local(x0, x1, x2, c, rot, e)
    w0 = rot[e, 0, 0] * d0 + rot[e, 0, 1] * d1 + rot[e, 0, 2] * d2
    w1 = rot[e, 1, 0] * d0 + rot[e, 1, 1] * d1 + rot[e, 1, 2] * d2
    w2 = rot[e, 2, 0] * d0 + rot[e, 2, 1] * d1 + rot[e, 2, 2] * d2
    i0 = 1.0 / (axes[e, 0] * axes[e, 0])
    i1 = 1.0 / (axes[e, 1] * axes[e, 1])
    i2 = 1.0 / (axes[e, 2] * axes[e, 2])
    qa = w0 * w0 * i0 + w1 * w1 * i1 + w2 * w2 * i2
    qb = y0 * w0 * i0 + y1 * w1 * i1 + y2 * w2 * i2
    qc = y0 * y0 * i0 + y1 * y1 * i1 + y2 * y2 * i2 - 1.0
    disc = qb * qb - qa * qc
    if qa <= 0.0 or disc <= 0.0:
        return math.inf, -math.inf
    r = math.sqrt(disc)
    return (-qb - r) / qa, (-qb + r) / qa


@njit
def _ray_escape(x0, x1, x2, d0, d1, d2, c, rot, axes):
    """Smallest s >= 0 with x + s d outside every ellipsoid, and the ellipsoid left last (-1: none)."""
    s = 0.0
    last = -1
    for _ in range(axes.shape[0] + 1):
        moved = False
        for e in range(axes.shape[0]):
            s_in, s_out = _ray_exit(x0, x1, x2, d0, d1, d2, c, rot, axes, e)
            if s_in <= s < s_out:
                s = s_out
                last = e
                moved = True
        if not moved:
            break
    return s, last


@njit
def _project_particle(x, xp, i, c, rot, axes, bound2, friction, restitution, closest, max_rounds):
    """Two-phase projection of particle i out of the ellipsoid set (in place); True if moved."""
    ne = axes.shape[0]
    p0 = x[i, 0]
    p1 = x[i, 1]
    p2 = x[i, 2]
    hit = -1
    q0 = q1 = q2 = 0.0
    ql0 = ql1 = ql2 = 0.0
    done = False
    for _ in range(max_rounds + 1):
        best_ok = math.inf
        best_any = math.inf
        any_e = -1
        a0 = a1 = a2 = 0.0
        inside_any = False
        for e in range(ne):
            if not _inside(p0, p1, p2, c, rot, axes, bound2, e):
                continue
            inside_any = True
            y0, y1, y2 = _local(p0, p1, p2, c, rot, e)
            s0, s1, s2 = _surface_local(y0, y1, y2, axes[e, 0], axes[e, 1], axes[e, 2], closest)
            w0, w1, w2 = _world(s0, s1, s2, c, rot, e)
            dist2 = (w0 - p0) ** 2 + (w1 - p1) ** 2 + (w2 - p2) ** 2
            if dist2 < best_any:
                best_any = dist2
                any_e = e
                a0, a1, a2 = w0, w1, w2
            if dist2 < best_ok and not _inside_other(w0, w1, w2, c, rot, axes, bound2, e):
                best_ok = dist2
                hit = e
                q0, q1, q2 = w0, w1, w2
                ql0, ql1, ql2 = s0, s1, s2
        if not inside_any:
            if hit < 0:
                return False  # the particle was outside to begin with
            done = True  # previous round's point already lies outside every ellipsoid
            break
        if best_ok < math.inf:
            done = True
            break
        # every candidate is buried in another ellipsoid: start again from the nearest one
        p0, p1, p2 = a0, a1, a2
        hit = any_e
        q0, q1, q2 = a0, a1, a2
        ql0, ql1, ql2 = _local(a0, a1, a2, c, rot, any_e)
    if not done:
        d0 = p0 - x[i, 0]
        d1 = p1 - x[i, 1]
        d2 = p2 - x[i, 2]
        m = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if m == 0.0:
            d0, d1, d2 = 0.0, 1.0, 0.0
        else:
            d0, d1, d2 = d0 / m, d1 / m, d2 / m
        s, last = _ray_escape(x[i, 0], x[i, 1], x[i, 2], d0, d1, d2, c, rot, axes)
        q0 = x[i, 0] + s * d0
        q1 = x[i, 1] + s * d1
        q2 = x[i, 2] + s * d2
        if last < 0:
            return False
        hit = last
        ql0, ql1, ql2 = _local(q0, q1, q2, c, rot, hit)
    n0, n1, n2 = _normal(ql0, ql1, ql2, rot, axes, hit)
    place_on_surface(x, xp, i, q0, q1, q2, n0, n1, n2, friction[hit], restitution[hit])
    return True


@njit
def _collide_ellipsoids(x, xp, inv_mass, centres, rot, axes, friction, restitution, closest, max_rounds,
                        bound2_out):
    """Project every free particle out of the ellipsoid set, serially; returns the count moved.

    ``bound2_out`` (e,) receives the squared bounding radius (largest semi-axis) of each
    ellipsoid, a cheap reject before the 3 x 3 transform.
    """
    for e in range(axes.shape[0]):
        m = max(axes[e, 0], axes[e, 1], axes[e, 2])
        bound2_out[e] = m * m * (1.0 + 1e-9)
    moved = 0
    for i in range(x.shape[0]):
        if inv_mass[i] > 0.0:
            if _project_particle(x, xp, i, centres, rot, axes, bound2_out, friction, restitution,
                                 closest, max_rounds):
                moved += 1
    return moved


@njit
def _signed_distance(points, centres, rot, axes, out):
    """out[i] = min_e signed distance of points[i] to ellipsoid e (exact, negative inside)."""
    for i in range(points.shape[0]):
        best = math.inf
        for e in range(axes.shape[0]):
            y0, y1, y2 = _local(points[i, 0], points[i, 1], points[i, 2], centres, rot, e)
            q0, q1, q2 = closest_local(y0, y1, y2, axes[e, 0], axes[e, 1], axes[e, 2])
            d = math.sqrt((q0 - y0) ** 2 + (q1 - y1) ** 2 + (q2 - y2) ** 2)
            if (y0 / axes[e, 0]) ** 2 + (y1 / axes[e, 1]) ** 2 + (y2 / axes[e, 2]) ** 2 < 1.0:
                d = -d
            if d < best:
                best = d
        out[i] = best


@njit
def _surface_points(points, centres, rot, axes, part, closest, out):
    """out[i] = radial (closest=False) or closest surface point of points[i] on ellipsoid part[i]."""
    for i in range(points.shape[0]):
        e = part[i]
        y0, y1, y2 = _local(points[i, 0], points[i, 1], points[i, 2], centres, rot, e)
        s0, s1, s2 = _surface_local(y0, y1, y2, axes[e, 0], axes[e, 1], axes[e, 2], closest)
        w0, w1, w2 = _world(s0, s1, s2, centres, rot, e)
        out[i, 0] = w0
        out[i, 1] = w1
        out[i, 2] = w2


def _f64(a, shape):
    return np.ascontiguousarray(a, dtype=np.float64).reshape(shape)


def collide_ellipsoids(pos, pos_prev, inv_mass, centres, rotations, axes, friction, restitution,
                       closest=False, max_rounds=4):
    """Project particles out of a set of ellipsoids in place (see module docstring).

    Parameters
    ----------
    pos, pos_prev : (n, 3) float64, m
        C-contiguous float64, modified in place.
    inv_mass : (n,) float64, 1/kg
        Pinned particles (0) are left alone.
    centres : (e, 3) float64, m
    rotations : (e, 3, 3) float64
        Rows are the unit axes of each ellipsoid.
    axes : (e, 3) float64, m
        Effective semi-axes (skin included), > 0.
    friction, restitution : (e,) float64
        Per-ellipsoid Cf and Cr in [0, 1].
    closest : bool
        True: true closest surface point; False: radial projection from the centre.
    max_rounds : int
        Re-projection rounds when every candidate lies inside another ellipsoid.

    Returns
    -------
    int
        Number of particles moved.
    """
    for a in (pos, pos_prev):
        if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and a.ndim == 2):
            raise TypeError("pos and pos_prev must be C-contiguous float64 (n, 3) arrays (modified in place)")
    axes = _f64(axes, (-1, 3))
    e = axes.shape[0]
    return int(_collide_ellipsoids(pos, pos_prev, _f64(inv_mass, (-1,)), _f64(centres, (e, 3)),
                                   _f64(rotations, (e, 3, 3)), axes, _f64(friction, (e,)),
                                   _f64(restitution, (e,)), bool(closest), int(max_rounds),
                                   np.empty(e, dtype=np.float64)))


def ellipsoid_signed_distance(points, centres, rotations, axes):
    """Exact signed distance to the union of ellipsoids, m, negative inside: (n, 3) -> (n,)."""
    points = _f64(points, (-1, 3))
    axes = _f64(axes, (-1, 3))
    e = axes.shape[0]
    out = np.empty(points.shape[0], dtype=np.float64)
    _signed_distance(points, _f64(centres, (e, 3)), _f64(rotations, (e, 3, 3)), axes, out)
    return out


def ellipsoid_surface_points(points, centres, rotations, axes, part, closest=False):
    """Radial or closest surface point of each point on the ellipsoid ``part[i]``: (n, 3) m."""
    points = _f64(points, (-1, 3))
    axes = _f64(axes, (-1, 3))
    e = axes.shape[0]
    out = np.empty_like(points)
    _surface_points(points, _f64(centres, (e, 3)), _f64(rotations, (e, 3, 3)), axes,
                    np.ascontiguousarray(part, dtype=np.int64).ravel(), bool(closest), out)
    return out
