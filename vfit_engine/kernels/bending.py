"""Numba kernel: the bending forces of dihedral hinges (discrete shells).

A hinge is two triangles sharing the edge ``x0 -> x1``, with ``x2`` opposite it in the first and ``x3`` in
the second. Its bend angle ``theta`` (0 flat, signed, in (-pi, pi]) comes from the triangles' normals
``n0 = e x (x2 - x0)``, ``n1 = (x3 - x0) x e`` (``e = x1 - x0``)::

    theta = atan2((n0 x n1) . e / |e|, n0 . n1)

and its gradient (Bridson, Marino & Fedkiw 2003; Wardetzky et al. 2007)::

    d theta/d x2 = -|e| n0 / |n0|^2,   d theta/d x3 = -|e| n1 / |n1|^2
    d theta/d x1 = t2 |e| n0 / (|e| |n0|^2) + t3 |e| n1 / (|e| |n1|^2),   t_k = (x_k - x0) . e / |e|
    d theta/d x0 = -(the other three)

The energy ``k (theta - theta0)^2 / 2`` gives ``f_m = -(k (theta - theta0) + kd dtheta/dt) d theta/d x_m``,
with ``dtheta/dt = sum_m d theta/d x_m . v_m`` and ``v = (x - x-) / dt`` (the step's backward difference). The
four forces sum to zero and exert no torque. :mod:`vfit_engine.sim.bending` gives ``k`` from a bending
rigidity; :func:`eval_hinge_forces` is the callers' entry, the cloth kernel inlines
:func:`add_hinge_forces` over its segments. A hinge too stiff for the explicit step is solved instead as
a compliant constraint on ``theta`` with the same gradient (:func:`project_hinge_range`, the cloth kernel's
sweeps; :func:`project_hinges` is the callers' entry).
"""
import math

import numpy as np

from vfit_engine._jit import njit


@njit(inline="always")
def _bend(x, i0, i1, i2, i3, rest):
    """The hinge's bend away from ``rest`` (rad, in (-pi, pi]) and its gradient (module docstring) as
    ``(ok, d, g0x, g0y, g0z, ..., g3z)``; ``ok`` False for a collapsed triangle (no normal, no bend)."""
    ex, ey, ez = x[i1, 0] - x[i0, 0], x[i1, 1] - x[i0, 1], x[i1, 2] - x[i0, 2]
    le = math.sqrt(ex * ex + ey * ey + ez * ez)
    ax, ay, az = x[i2, 0] - x[i0, 0], x[i2, 1] - x[i0, 1], x[i2, 2] - x[i0, 2]
    bx, by, bz = x[i3, 0] - x[i0, 0], x[i3, 1] - x[i0, 1], x[i3, 2] - x[i0, 2]
    # n0 = e x a, n1 = b x e
    n0x, n0y, n0z = ey * az - ez * ay, ez * ax - ex * az, ex * ay - ey * ax
    n1x, n1y, n1z = by * ez - bz * ey, bz * ex - bx * ez, bx * ey - by * ex
    q0 = n0x * n0x + n0y * n0y + n0z * n0z
    q1 = n1x * n1x + n1y * n1y + n1z * n1z
    if le <= 0.0 or q0 <= 0.0 or q1 <= 0.0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    cx, cy, cz = n0y * n1z - n0z * n1y, n0z * n1x - n0x * n1z, n0x * n1y - n0y * n1x
    d = math.atan2((cx * ex + cy * ey + cz * ez) / le, n0x * n1x + n0y * n1y + n0z * n1z) - rest
    if d > math.pi:
        d -= 2.0 * math.pi
    elif d < -math.pi:
        d += 2.0 * math.pi
    s0, s1 = le / q0, le / q1
    t2 = (ax * ex + ay * ey + az * ez) / (le * le)
    t3 = (bx * ex + by * ey + bz * ez) / (le * le)
    # the gradient: g2 = -s0 n0, g3 = -s1 n1, g1 = -t2 g2 - t3 g3, g0 = -(g1 + g2 + g3)
    g2x, g2y, g2z = -s0 * n0x, -s0 * n0y, -s0 * n0z
    g3x, g3y, g3z = -s1 * n1x, -s1 * n1y, -s1 * n1z
    g1x, g1y, g1z = -t2 * g2x - t3 * g3x, -t2 * g2y - t3 * g3y, -t2 * g2z - t3 * g3z
    g0x, g0y, g0z = -(g1x + g2x + g3x), -(g1y + g2y + g3y), -(g1z + g2z + g3z)
    return True, d, g0x, g0y, g0z, g1x, g1y, g1z, g2x, g2y, g2z, g3x, g3y, g3z


@njit(inline="always")
def _add(a, i, c, gx, gy, gz):
    a[i, 0] += c * gx
    a[i, 1] += c * gy
    a[i, 2] += c * gz


@njit
def add_hinge_forces(x, xp, inv_dt, hi, hk, hkd, hrest, f_out, h0, h1):
    """Add the forces of hinges ``h0 .. h1 - 1`` (module docstring) into ``f_out`` (n, 3), N."""
    for h in range(h0, h1):
        i0, i1, i2, i3 = hi[h, 0], hi[h, 1], hi[h, 2], hi[h, 3]
        ok, d, g0x, g0y, g0z, g1x, g1y, g1z, g2x, g2y, g2z, g3x, g3y, g3z = _bend(x, i0, i1, i2, i3, hrest[h])
        if not ok:
            continue  # a collapsed triangle has no normal: no bending force this step
        mag = hk[h] * d
        if hkd[h] != 0.0:
            rate = (g0x * (x[i0, 0] - xp[i0, 0]) + g0y * (x[i0, 1] - xp[i0, 1]) + g0z * (x[i0, 2] - xp[i0, 2])
                    + g1x * (x[i1, 0] - xp[i1, 0]) + g1y * (x[i1, 1] - xp[i1, 1]) + g1z * (x[i1, 2] - xp[i1, 2])
                    + g2x * (x[i2, 0] - xp[i2, 0]) + g2y * (x[i2, 1] - xp[i2, 1]) + g2z * (x[i2, 2] - xp[i2, 2])
                    + g3x * (x[i3, 0] - xp[i3, 0]) + g3y * (x[i3, 1] - xp[i3, 1]) + g3z * (x[i3, 2] - xp[i3, 2]))
            mag += hkd[h] * rate * inv_dt
        _add(f_out, i0, -mag, g0x, g0y, g0z)
        _add(f_out, i1, -mag, g1x, g1y, g1z)
        _add(f_out, i2, -mag, g2x, g2y, g2z)
        _add(f_out, i3, -mag, g3x, g3y, g3z)


#: Hinges :func:`add_elastic_hinge_forces` takes at once: their geometry gathered one by one, then their roots,
#: divisions and angles in one loop over the block that compiles to vector instructions, then their forces added.
HINGE_BLOCK = 64

# Cephes' atan (Moshier): atan t = t + t z P(z) / Q(z), z = t^2, on |t| <= 0.66
_P0, _P1, _P2, _P3, _P4 = (-8.750608600031904122785e-1, -1.615753718733365076637e1, -7.500855792314704667340e1,
                           -1.228866684490136173410e2, -6.485021904942025371773e1)
_Q0, _Q1, _Q2, _Q3, _Q4 = (2.485846490142306297962e1, 1.650270098316988542046e2, 4.328810604912902668951e2,
                           4.853903996359136964868e2, 1.945506571482613964425e2)
_MOREBITS = 6.123233995736765886130e-17  # pi/2 - float(pi/2)


@njit(inline="always")
def atan2_select(y, x):
    """``atan2(y, x)`` in (-pi, pi] (``atan2(-0, x < 0)`` is pi), within 2 ulp of ``math.atan2``, with selects in
    place of branches: a loop of them compiles to vector instructions where ``math.atan2`` is a call a value
    (40 % of a hinge's cost in :func:`add_hinge_forces`). ``atan2(0, 0)`` is 0."""
    ay, ax = abs(y), abs(x)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax
    t = num / den if den > 0.0 else 0.0  # in [0, 1]
    big = t > 0.66
    t = (t - 1.0) / (t + 1.0) if big else t  # atan t = pi/4 + atan((t - 1) / (t + 1))
    z = t * t
    r = z * ((((_P0 * z + _P1) * z + _P2) * z + _P3) * z + _P4) / (((((z + _Q0) * z + _Q1) * z + _Q2) * z + _Q3) * z
                                                                   + _Q4)
    a = t * r + t
    a = 0.25 * math.pi + (a + 0.5 * _MOREBITS) if big else a
    a = 0.5 * math.pi - a + _MOREBITS if swap else a
    a = math.pi - a if x < 0.0 else a
    return -a if y < 0.0 else a


@njit
def _block_angles(le2, q0, q1, ce, cs, ae, be, ang, nb):
    """The branch-free part of :func:`_bend` for ``nb`` hinges, in place: from the squared edge length ``le2``,
    the squared normals ``q0``, ``q1``, ``ce = (n0 x n1) . e``, ``cs = n0 . n1``, ``ae = a . e``, ``be = b . e`` to
    ``le2``: the edge length (0 for a collapsed triangle), ``q0``, ``q1``: ``s0``, ``s1``, ``ae``, ``be``: ``t2``,
    ``t3`` and ``ang`` the angle -- the same operations as :func:`_bend`, but the angle's (:func:`atan2_select`)."""
    for m in range(nb):
        le = math.sqrt(le2[m])
        ang[m] = atan2_select(ce[m] / le, cs[m])
        ae[m] = ae[m] / (le * le)
        be[m] = be[m] / (le * le)
        collapsed = le <= 0.0 or q0[m] <= 0.0 or q1[m] <= 0.0
        le2[m] = 0.0 if collapsed else le
        q0[m] = le / q0[m]
        q1[m] = le / q1[m]


def hinge_scratch():
    """The scratch :func:`add_elastic_hinge_forces` takes: (14, :data:`HINGE_BLOCK`) float64, allocated once by
    its caller (no allocation in a step loop)."""
    return np.empty((14, HINGE_BLOCK))


@njit
def add_elastic_hinge_forces(x, hi, hk, hrest, f_out, h0, h1, work):
    """Add the elastic forces ``-k (theta - theta0) d theta / d x_m`` of hinges ``h0 .. h1 - 1`` into ``f_out``
    (n, 3), N: :func:`add_hinge_forces` without damping (the projective-dynamics local step evaluates the hinges at
    an iterate, with no velocity), without its rate and with the hinges taken in blocks of :data:`HINGE_BLOCK`
    whose roots, divisions and angles vectorise (:func:`_block_angles`): the sphere drape's 58 k hinges in 1.7 ms
    against 3.9 (3.2 with ``kd = 0``), the suit's 12.5 k in 0.55 against 1.1. The forces are
    :func:`add_hinge_forces`' but for its angle's rounding (within 2 ulp). ``work``: :func:`hinge_scratch`.
    Returns their energy ``sum k (theta - theta0)^2 / 2``, J."""
    energy = 0.0
    le2, q0, q1, ce, cs, ae, be, ang = work[0], work[1], work[2], work[3], work[4], work[5], work[6], work[7]
    for start in range(h0, h1, HINGE_BLOCK):
        nb = min(HINGE_BLOCK, h1 - start)
        for m in range(nb):
            i0, i1, i2, i3 = hi[start + m, 0], hi[start + m, 1], hi[start + m, 2], hi[start + m, 3]
            ex, ey, ez = x[i1, 0] - x[i0, 0], x[i1, 1] - x[i0, 1], x[i1, 2] - x[i0, 2]
            ax, ay, az = x[i2, 0] - x[i0, 0], x[i2, 1] - x[i0, 1], x[i2, 2] - x[i0, 2]
            bx, by, bz = x[i3, 0] - x[i0, 0], x[i3, 1] - x[i0, 1], x[i3, 2] - x[i0, 2]
            # n0 = e x a, n1 = b x e (as _bend)
            n0x, n0y, n0z = ey * az - ez * ay, ez * ax - ex * az, ex * ay - ey * ax
            n1x, n1y, n1z = by * ez - bz * ey, bz * ex - bx * ez, bx * ey - by * ex
            cx, cy, cz = n0y * n1z - n0z * n1y, n0z * n1x - n0x * n1z, n0x * n1y - n0y * n1x
            le2[m] = ex * ex + ey * ey + ez * ez
            q0[m] = n0x * n0x + n0y * n0y + n0z * n0z
            q1[m] = n1x * n1x + n1y * n1y + n1z * n1z
            ce[m] = cx * ex + cy * ey + cz * ez
            cs[m] = n0x * n1x + n0y * n1y + n0z * n1z
            ae[m] = ax * ex + ay * ey + az * ez
            be[m] = bx * ex + by * ey + bz * ez
            work[8, m], work[9, m], work[10, m], work[11, m], work[12, m], work[13, m] = n0x, n0y, n0z, n1x, n1y, n1z
        _block_angles(le2, q0, q1, ce, cs, ae, be, ang, nb)
        for m in range(nb):
            if le2[m] == 0.0:
                continue  # a collapsed triangle has no normal: no bending force
            h = start + m
            d = ang[m] - hrest[h]
            if d > math.pi:
                d -= 2.0 * math.pi
            elif d < -math.pi:
                d += 2.0 * math.pi
            s0, s1, t2, t3 = q0[m], q1[m], ae[m], be[m]
            g2x, g2y, g2z = -s0 * work[8, m], -s0 * work[9, m], -s0 * work[10, m]
            g3x, g3y, g3z = -s1 * work[11, m], -s1 * work[12, m], -s1 * work[13, m]
            g1x, g1y, g1z = -t2 * g2x - t3 * g3x, -t2 * g2y - t3 * g3y, -t2 * g2z - t3 * g3z
            g0x, g0y, g0z = -(g1x + g2x + g3x), -(g1y + g2y + g3y), -(g1z + g2z + g3z)
            mag = hk[h] * d
            energy += 0.5 * mag * d
            _add(f_out, hi[h, 0], -mag, g0x, g0y, g0z)
            _add(f_out, hi[h, 1], -mag, g1x, g1y, g1z)
            _add(f_out, hi[h, 2], -mag, g2x, g2y, g2z)
            _add(f_out, hi[h, 3], -mag, g3x, g3y, g3z)
    return energy


@njit
def _hinge_forces(x, xp, inv_dt, hi, hk, hkd, hrest, f_out):
    f_out[:] = 0.0
    add_hinge_forces(x, xp, inv_dt, hi, hk, hkd, hrest, f_out, 0, hi.shape[0])


def eval_hinge_forces(pos, pos_prev, dt, hinge_indices, k, kd, rest_angle):
    """Bending forces of hinges on every particle.

    Parameters
    ----------
    pos, pos_prev : (n, 3) float64, m
    dt : float, s
    hinge_indices : (h, 4) int64
        Edge ends, then the vertex opposite the edge in each triangle (module docstring).
    k : (h,) float64, N m / rad^2
    kd : (h,) float64, N m s / rad^2
    rest_angle : (h,) float64, rad

    Returns
    -------
    (n, 3) float64, N
    """
    x = np.ascontiguousarray(pos, dtype=np.float64)
    out = np.zeros_like(x)
    _hinge_forces(x, np.ascontiguousarray(pos_prev, dtype=np.float64), 1.0 / float(dt),
                  np.ascontiguousarray(hinge_indices, dtype=np.int64).reshape(-1, 4),
                  np.ascontiguousarray(k, dtype=np.float64), np.ascontiguousarray(kd, dtype=np.float64),
                  np.ascontiguousarray(rest_angle, dtype=np.float64), out)
    return out


#: A hinge constraint whose listing pass in a substep (the cloth kernel's second) moved a vertex by more than this
#: (m) is solved in that substep's middle passes too; the others wait for the last (:func:`project_hinge_range`).
#: Measured on a resting suit (male_casualsuit06, 14.7 k hinge constraints): half are listed, the drape's cost
#: falls by a tenth and its result, and the cantilever's at a drape's step, do not change (to 0.01 points).
HINGE_ACTIVE = 2e-7
#: Passes of :func:`project_hinge_range`: every hinge; every hinge, listing those that moved a vertex by more than
#: ``HINGE_ACTIVE``; the listed ones only.
PASS_ALL, PASS_LIST, PASS_LISTED = 0, 1, 2


@njit
def project_hinge_range(x, w, hi, h_alpha, hrest, lam, at_scale, h0, h1, active, n_active, mode):
    """One Gauss-Seidel pass over hinges ``h0 .. h1 - 1`` as compliant angle constraints (XPBD, Macklin et al.
    2016): ``C = theta - theta0``, compliance ``alpha = 1 / k`` (rad^2 / (N m)), ``at = alpha at_scale``::

        dlam = (-C - at lam) / (sum_m w_m |g_m|^2 + at),   x_m += w_m g_m dlam

    -- the implicit counterpart of :func:`add_hinge_forces` for hinges stiffer than an explicit step can
    carry (stable at any step; the same static balance ``k C = lam / dt^2``). Hinges with ``h_alpha`` 0
    are explicit only and skipped.

    ``mode`` (:data:`PASS_ALL`, :data:`PASS_LIST`, :data:`PASS_LISTED`): visit every hinge; every hinge, listing
    in ``active`` (from index ``h0``) those that moved a vertex by more than :data:`HINGE_ACTIVE`; or only the
    ``n_active`` listed. Returns the number listed (``PASS_LIST``), else ``n_active``."""
    count = h1 - h0 if mode != PASS_LISTED else n_active
    n = 0
    eps2 = HINGE_ACTIVE * HINGE_ACTIVE
    for a in range(count):
        h = active[h0 + a] if mode == PASS_LISTED else h0 + a
        alpha = h_alpha[h]
        if alpha <= 0.0:
            continue
        i0, i1, i2, i3 = hi[h, 0], hi[h, 1], hi[h, 2], hi[h, 3]
        ok, d, g0x, g0y, g0z, g1x, g1y, g1z, g2x, g2y, g2z, g3x, g3y, g3z = _bend(x, i0, i1, i2, i3, hrest[h])
        if not ok:
            continue
        w0, w1, w2, w3 = w[i0], w[i1], w[i2], w[i3]
        q0 = g0x * g0x + g0y * g0y + g0z * g0z
        q1 = g1x * g1x + g1y * g1y + g1z * g1z
        q2 = g2x * g2x + g2y * g2y + g2z * g2z
        q3 = g3x * g3x + g3y * g3y + g3z * g3z
        den = w0 * q0 + w1 * q1 + w2 * q2 + w3 * q3
        at = alpha * at_scale
        dl = (-d - at * lam[h]) / (den + at)
        lam[h] += dl
        _add(x, i0, w0 * dl, g0x, g0y, g0z)
        _add(x, i1, w1 * dl, g1x, g1y, g1z)
        _add(x, i2, w2 * dl, g2x, g2y, g2z)
        _add(x, i3, w3 * dl, g3x, g3y, g3z)
        if mode == PASS_LIST:
            move2 = dl * dl * max(max(w0 * w0 * q0, w1 * w1 * q1), max(w2 * w2 * q2, w3 * w3 * q3))
            if move2 > eps2:
                active[h0 + n] = h
                n += 1
    return n if mode == PASS_LIST else n_active


def project_hinges(pos, inv_mass, hinge_indices, compliance, rest_angle, lam, dt):
    """One Gauss-Seidel sweep of the hinges as compliant angle constraints (:func:`project_hinge_range`).

    Parameters
    ----------
    pos : (n, 3) float64, m
        Moved in place.
    inv_mass : (n,) float64, 1/kg
    hinge_indices : (h, 4) int64
    compliance : (h,) float64, 1 / (N m)
        ``1 / k``; 0 skips the hinge.
    rest_angle : (h,) float64, rad
    lam : (h,) float64
        The multipliers, accumulated in place (0 at a step's first sweep).
    dt : float, s
    """
    count = int(np.asarray(hinge_indices).reshape(-1, 4).shape[0])
    project_hinge_range(pos, np.ascontiguousarray(inv_mass, dtype=np.float64),
                        np.ascontiguousarray(hinge_indices, dtype=np.int64).reshape(-1, 4),
                        np.ascontiguousarray(compliance, dtype=np.float64),
                        np.ascontiguousarray(rest_angle, dtype=np.float64), lam, 1.0 / (float(dt) * float(dt)), 0,
                        count, np.zeros(0, np.int64), 0, PASS_ALL)
