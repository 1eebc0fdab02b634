"""Numba kernels: the local step of projective dynamics for cloth, its Chebyshev update and the contact targets.

One time step ``h`` of projective dynamics (Liu, Bargteil, O'Brien & Kavan 2013; Bouaziz et al. 2014) minimises
``|x - y|^2_M / (2 h^2) + sum_e w_e |S_e x - p_e|^2 / 2`` with ``y`` the inertial prediction and ``p_e`` the
projection of element ``e`` onto its allowed set. Alternating the local step (every ``p_e`` at the current
iterate) and the global step (``A x = b``, ``A = M / h^2 + sum_e w_e S_e^T S_e`` constant) decreases it
monotonically. :func:`pd_rhs` is the local step: it builds ``b`` for the global solve
(:mod:`vfit_engine.sim.solver_pd` factors ``A`` once), and returns that function's value at the iterate, which the
quasi-Newton iterations' line search takes (:mod:`vfit_engine.kernels.lbfgs`; :func:`contact_friction` returns its
friction's part).

Elements in ``A`` (``S_e`` the difference of two vertices, so ``A`` has the sparsity of the cloth's edges):

* a **distance band**: the pair's vector projected onto lengths ``[lo, hi]`` (yarns free within their band,
  stiffness ``w`` beyond it; a shear diagonal has ``lo = hi``);
* a **corner angle band**: the two arms of a polygon corner, each turned in the corner's plane by half the excess
  when the angle leaves ``[t_lo, t_hi]`` (lengths kept): Provot's shear limit as two vector elements on the
  polygon's own edges.

Elements outside ``A`` (their pairs would add fill to its factor: the bend limits join second neighbours, the
hinges four vertices) act as forces ``f(x)`` evaluated at the iterate, with a diagonal ``D`` in ``A`` and
``D x`` in ``b``: the fixed point is the same (``A x = b + f(x)``), and the iteration contracts as long as ``D``
bounds their stiffness (Gershgorin's bound: ``2 w`` a vertex for a spring, ``k |g_m| sum_l |g_l|`` for a hinge).

Contacts (soft in the iterations, exact after them): every free vertex has a constant weight ``w_c`` in ``A``;
its target is the iterate itself, moved by the mean push its contact half-spaces ask for (the contact points'
pushes spread over their vertices as :mod:`.contact_solve` spreads them), with the slip along the body since the
step began held back by Coulomb friction (:func:`contact_friction`, at most ``friction`` times the normal force).
A constant weight keeps the factor fixed; the push is what the cloth's elements feel of the body during the step,
so a cloth pulled tight over it is not projected against its own elements after every solve (that locked the
stretch at 27 % in a prototype). What holds the cloth out is the contact forces (:func:`contact_forces`, Uzawa's
method): normal only, so they do not hold the cloth where it lies as a strong weight would. An exact projection
of the contact points after the iterations (``PDSettings.contact_sweeps``) is off: it and the forces undid each
other in a 2-frame cycle.

Pinned vertices are rows of the identity in ``A`` (their position given), and their couplings to free vertices
move to ``b``: ``b_i += w_ip x_p`` (``pin_ptr``, ``pin_nbr``, ``pin_w`` in CSR form over the free vertices).
"""
import math

from vfit_engine._jit import njit
from vfit_engine.kernels.bending import add_elastic_hinge_forces
from vfit_engine.kernels.contact_make import contact_point

#: Relative margin of the quick test that finds a corner clearly inside its band of angles (one root, no division;
#: 95 % of a garment's corners are): far above the rounding of the cosine (~1e-16), so that every corner it passes
#: is one the full test (:func:`_corner_targets`) leaves as it is. (The same quick test on the distance bands,
#: without their root, was slower: the bands inside and outside alternate too often for the branch.)
_MARGIN = 1e-12


@njit(inline="always")
def _scatter(b, i, j, w, px, py, pz):
    """b_j += w p, b_i -= w p: the term ``w S^T p`` of a pair element ``S = e_j - e_i``."""
    b[j, 0] += w * px
    b[j, 1] += w * py
    b[j, 2] += w * pz
    b[i, 0] -= w * px
    b[i, 1] -= w * py
    b[i, 2] -= w * pz


@njit(inline="always")
def _band(x, i, j, lo, hi):
    """The vector x_j - x_i projected onto lengths [lo, hi] (the vector itself inside the band)."""
    dx, dy, dz = x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    if length <= 0.0:
        return 0.0, lo, 0.0
    t = min(max(length, lo), hi)
    s = t / length
    return s * dx, s * dy, s * dz


@njit
def _corners(x, b, ci, cj, ck, cos_lo, cos_hi, w, want):
    """The corner angle elements (module docstring) into ``b``; ``cos_lo``, ``cos_hi`` are the cosines of the
    band's smallest and largest angle. Returns their energy ``w (|u - u'|^2 + |v - v'|^2) / 2``, J, if ``want``
    (else 0)."""
    energy = 0.0
    for c in range(ci.shape[0]):
        i, j, k = ci[c], cj[c], ck[c]
        ux, uy, uz = x[i, 0] - x[k, 0], x[i, 1] - x[k, 1], x[i, 2] - x[k, 2]
        vx, vy, vz = x[j, 0] - x[k, 0], x[j, 1] - x[k, 1], x[j, 2] - x[k, 2]
        qu = ux * ux + uy * uy + uz * uz
        qv = vx * vx + vy * vy + vz * vz
        dot = ux * vx + uy * vy + uz * vz
        ll = math.sqrt(qu * qv)
        # clearly inside the band (cos_hi < cos < cos_lo by _MARGIN): the arms as they are; else the full test
        lm = ll * _MARGIN
        if not (cos_hi[c] * ll + lm < dot < cos_lo[c] * ll - lm):
            tx, ty, tz, sx, sy, sz = _corner_targets(ux, uy, uz, vx, vy, vz, qu, qv, dot, ll, cos_lo[c], cos_hi[c])
            if want:
                energy += 0.5 * w[c] * ((ux - tx) ** 2 + (uy - ty) ** 2 + (uz - tz) ** 2
                                        + (vx - sx) ** 2 + (vy - sy) ** 2 + (vz - sz) ** 2)
            ux, uy, uz, vx, vy, vz = tx, ty, tz, sx, sy, sz
        _scatter(b, k, i, w[c], ux, uy, uz)
        _scatter(b, k, j, w[c], vx, vy, vz)
    return energy


@njit(inline="always")
def _corner_targets(ux, uy, uz, vx, vy, vz, qu, qv, dot, ll, cos_lo, cos_hi):
    """The arms ``u``, ``v`` of a corner (their squared lengths ``qu``, ``qv``, dot product ``dot`` and product of
    lengths ``ll``) projected onto its band of angles, whose ends have cosines ``cos_lo`` (the smallest angle) and
    ``cos_hi`` (module docstring): both turned in their plane by half the excess, lengths kept; as they are inside
    the band.

    Without trigonometry, three roots and two divisions (the sphere drape's corners, half of them out of their
    band: 1.0 ms against 1.9 with ``acos``, ``cos`` and ``sin``): the excess ``d = angle - end`` by its cosine and
    sine from the angle's (the sine from the arms' cross product, exact at small angles) and the end's, the half
    angle by ``cos(d/2) = sqrt((1 + cos d) / 2)``, ``sin(d/2) = sin d / (2 cos(d/2))``; an arm turns by it towards
    the other's component normal to it (``|u| (v/|v| - cos u/|u|)``, of length ``|u| sin angle``)."""
    if ll > 0.0:
        il = 1.0 / ll
        cosa = dot * il
        if cosa < cos_hi or cosa > cos_lo:
            ct = cos_hi if cosa < cos_hi else cos_lo
            st = math.sqrt(max(1.0 - ct * ct, 0.0))  # the end's angle is in [0, pi]
            wx, wy, wz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
            sa = math.sqrt(wx * wx + wy * wy + wz * wz) * il
            if sa <= 1e-12:
                return ux, uy, uz, vx, vy, vz  # no plane to turn in
            ca = min(max(cosa, -1.0), 1.0)
            cd, sd = ca * ct + sa * st, sa * ct - ca * st
            ch = math.sqrt(max(0.5 * (1.0 + cd), 0.0))
            # u' = |u| (ch u/|u| + sh (v/|v| - ca u/|u|) / sa) = cu u + sq |u|/|v| v, and v' likewise
            sq = 0.5 * sd / (ch * sa) if ch > 0.0 else (1.0 if sd >= 0.0 else -1.0) / sa
            cu, su, sv = ch - sq * ca, sq * qu * il, sq * qv * il
            return (cu * ux + su * vx, cu * uy + su * vy, cu * uz + su * vz,
                    cu * vx + sv * ux, cu * vy + sv * uy, cu * vz + sv * uz)
    return ux, uy, uz, vx, vy, vz


@njit(inline="always")
def _depth(x, inv_mass, pt_v, pt_b, p, nx, ny, nz, h):
    """Contact point ``p``'s depth (m) below the half-space ``n . x >= h`` and the sum of its free vertices'
    squared weights."""
    px, py, pz = contact_point(x, pt_v, pt_b, p)
    den = 0.0
    for k in range(3):
        if inv_mass[pt_v[p, k]] > 0.0:
            den += pt_b[p, k] * pt_b[p, k]
    return h - (nx * px + ny * py + nz * pz), den


# The kernels below walk the contact points' half-spaces as "the plane, then the crease's second one if the point
# has one" (c_nq2 not NaN), each through an inlined helper. Written as a loop over the two sides that breaks at a
# missing one, Numba compiled the same walk about ten times slower (0.85 ms against 0.09 ms for the suit's 5.9 k
# points).

@njit(inline="always")
def _add_push(x, inv_mass, pt_v, pt_b, p, nx, ny, nz, h, gap, count):
    """Contact point ``p``'s push out of the half-space ``n . x >= h`` spread over its free vertices into ``gap``
    (their sum) and ``count`` (how many pushes each)."""
    g, den = _depth(x, inv_mass, pt_v, pt_b, p, nx, ny, nz, h)
    if g <= 0.0 or den <= 0.0:
        return
    for k in range(3):
        v = pt_v[p, k]
        if inv_mass[v] <= 0.0 or pt_b[p, k] == 0.0:
            continue
        s = pt_b[p, k] * g / den
        gap[v, 0] += s * nx
        gap[v, 1] += s * ny
        gap[v, 2] += s * nz
        count[v] += 1.0


@njit
def _contact_targets(x, inv_mass, pt_v, pt_b, c_n, c_h, c_n2, c_nq2, c_h2, c_list, n_c, w_c, b, gap, count, want):
    """Add ``w_c t`` (module docstring, contacts) of every free vertex into ``b``; ``gap`` (n, 3) m keeps each
    vertex's push (its target less the iterate), ``count`` (n,) is scratch. Returns the pushes' energy
    ``sum w_c |gap|^2 / 2``, J, if ``want`` (else 0)."""
    energy = 0.0
    n = x.shape[0]
    for i in range(n):
        gap[i, 0] = gap[i, 1] = gap[i, 2] = 0.0
        count[i] = 0.0
    for m in range(n_c):
        p = c_list[m]
        _add_push(x, inv_mass, pt_v, pt_b, p, c_n[p, 0], c_n[p, 1], c_n[p, 2], c_h[p], gap, count)
        if c_nq2[p] == c_nq2[p]:
            _add_push(x, inv_mass, pt_v, pt_b, p, c_n2[p, 0], c_n2[p, 1], c_n2[p, 2], c_h2[p], gap, count)
    for i in range(n):
        if inv_mass[i] <= 0.0:
            continue
        if count[i] > 0.0:
            gap[i, 0] /= count[i]
            gap[i, 1] /= count[i]
            gap[i, 2] /= count[i]
        b[i, 0] += w_c[i] * (x[i, 0] + gap[i, 0])
        b[i, 1] += w_c[i] * (x[i, 1] + gap[i, 1])
        b[i, 2] += w_c[i] * (x[i, 2] + gap[i, 2])
        if want:
            energy += 0.5 * w_c[i] * (gap[i, 0] * gap[i, 0] + gap[i, 1] * gap[i, 1] + gap[i, 2] * gap[i, 2])
    return energy


@njit(inline="always")
def _add_share(x, inv_mass, pt_v, pt_b, p, nx, ny, nz, h, acc_g, acc_n, acc_w):
    """Contact point ``p``'s signed depth below the half-space ``n . x >= h`` shared among its free vertices
    (:func:`contact_forces`): the deepest share into ``acc_g``, the weights and weighted normals summed."""
    g, den = _depth(x, inv_mass, pt_v, pt_b, p, nx, ny, nz, h)
    if den <= 0.0:
        return
    for k in range(3):
        v = pt_v[p, k]
        w = pt_b[p, k]
        if w <= 0.0 or inv_mass[v] <= 0.0:
            continue
        # the vertex's share of the point's depth (its move in the point's projection, PBD's); the deepest
        # share decides: a point cutting in between vertices must not be cancelled by clear ones
        share = w * g / den
        if acc_w[v] == 0.0 or share > acc_g[v]:
            acc_g[v] = share
        acc_w[v] += w
        acc_n[v, 0] += w * nx
        acc_n[v, 1] += w * ny
        acc_n[v, 2] += w * nz


@njit
def contact_forces(x, inv_mass, pt_v, pt_b, c_n, c_h, c_n2, c_nq2, c_h2, c_list, n_c, rho, lam, nrm, plane, acc_g,
                   acc_n, acc_w, release):
    """Update the contact forces ``lam`` (n,) N along ``nrm`` (n, 3) at the iterate ``x`` (Uzawa: each touching
    vertex's force grows by ``rho`` times its depth below its half-spaces -- the deepest share of its contact
    points' signed depths -- and never pulls: ``lam >= 0``). A vertex keeps its plane
    (``nrm`` and a point of it, ``plane`` (n, 3) m) while it has a force: pushed beyond the reach of the contact
    search it is still held by it, and lets go only as its force falls to 0 (else it would fall back at once,
    and a cloth pressed to the skin by its own tension chattered in and out at 1.8 mm a frame) -- unless
    ``release``: on a moving body a kept plane is where the skin was, not where it is, and holding the cloth there
    dragged a walking suit's trouser legs up the shins (strain p99 88 % by frame 30), so a vertex with no contact
    point lets go at once. ``acc_g`` (n,), ``acc_n`` (n, 3), ``acc_w`` (n,) are scratch."""
    n = x.shape[0]
    for i in range(n):
        acc_g[i] = acc_w[i] = 0.0
        acc_n[i, 0] = acc_n[i, 1] = acc_n[i, 2] = 0.0
    for m in range(n_c):
        p = c_list[m]
        _add_share(x, inv_mass, pt_v, pt_b, p, c_n[p, 0], c_n[p, 1], c_n[p, 2], c_h[p], acc_g, acc_n, acc_w)
        if c_nq2[p] == c_nq2[p]:
            _add_share(x, inv_mass, pt_v, pt_b, p, c_n2[p, 0], c_n2[p, 1], c_n2[p, 2], c_h2[p], acc_g, acc_n, acc_w)
    for i in range(n):
        if acc_w[i] > 0.0:
            q = math.sqrt(acc_n[i, 0] * acc_n[i, 0] + acc_n[i, 1] * acc_n[i, 1] + acc_n[i, 2] * acc_n[i, 2])
            if q <= 0.0:
                continue
            g = acc_g[i]
            for c in range(3):
                nrm[i, c] = acc_n[i, c] / q
                plane[i, c] = x[i, c] + g * nrm[i, c]
        elif lam[i] > 0.0 and release:
            lam[i] = 0.0
            continue
        elif lam[i] > 0.0:
            g = (nrm[i, 0] * (plane[i, 0] - x[i, 0]) + nrm[i, 1] * (plane[i, 1] - x[i, 1])
                 + nrm[i, 2] * (plane[i, 2] - x[i, 2]))
        else:
            continue
        lam[i] = max(lam[i] + rho[i] * g, 0.0)


@njit
def pd_rhs(x, y, mh2, inv_mass, d_off, e_i, e_j, e_lo, e_hi, e_w, a_i, a_j, a_k, a_cos_lo, a_cos_hi, a_w, s_i, s_j,
           s_lo, s_hi, s_w, h_i, h_k, h_rest, pin_idx, pin_ptr, pin_nbr, pin_w, pts_v, pts_b, c_n, c_h, c_n2, c_nq2,
           c_h2, c_list, n_c, w_c, b, gap, count, f_lag, lag, lam, nrm, hinge_work):
    """The local step (module docstring): ``b`` (n, 3) for the global solve at the iterate ``x`` (n, 3) m.

    Parameters
    ----------
    y : (n, 3) m
        The step's inertial prediction.
    mh2 : (n,) kg/s^2
        ``m / h^2`` of the free vertices (0 at pins).
    inv_mass : (n,) 1/kg
        0 at pins.
    d_off : (n,) N/m
        The diagonal that carries the forces outside ``A``.
    e_i, e_j, e_lo, e_hi, e_w : (E,)
        Distance bands in ``A``: ends, band (m) and weight (N/m).
    a_i, a_j, a_k, a_cos_lo, a_cos_hi, a_w : (K,)
        Corner angle bands: arms' ends, corner, the cosines of the band's smallest and largest angle and weight
        (N/m).
    s_i, s_j, s_lo, s_hi, s_w : (F,)
        One-sided springs outside ``A`` (bend limits, explicit springs): ends, band (m), stiffness (N/m).
    h_i, h_k, h_rest : (H, 4), (H,), (H,)
        Bending hinges: vertices, stiffness (N m / rad^2), rest angle (rad).
    pin_idx : (P,) int64;  pin_ptr (n + 1,), pin_nbr, pin_w
        Pinned vertices (their rows the identity) and the free vertices' couplings to them.
    pts_v, pts_b, c_n, c_h, c_n2, c_nq2, c_h2, c_list, n_c
        The contact points and the half-spaces of the ``n_c`` listed in ``c_list``
        (:func:`vfit_engine.kernels.contact_make.make_contacts`).
    w_c : (n,) N/m
        Each vertex's contact weight (its diagonal in ``A``).
    b : (n, 3) out;  gap : (n, 3) out, m (each vertex's contact push);  count : (n,) scratch
    f_lag : (n, 3) N;  lag : bool
        The forces outside ``A`` and their diagonal's ``D x`` (the hinges' and the springs'): with ``lag`` those
        kept in ``f_lag`` at an earlier iterate of the step are used (the hinges cost about as much as the rest of
        the local step, and are soft: every other iteration is enough), else they are evaluated here and kept
        there.
    hinge_work : (14, HINGE_BLOCK)
        Scratch of the hinges (:func:`vfit_engine.kernels.bending.hinge_scratch`).

    Returns
    -------
    float, J
        The step's energy at ``x`` less the contact forces' (the function whose gradient is ``A x - b``,
        :mod:`vfit_engine.kernels.lbfgs`): the inertia ``m |x - y|^2 / (2 h^2)``, every element's
        ``w |S x - p|^2 / 2`` at its projection, the hinges' ``k (theta - theta0)^2 / 2`` and the pushes'
        ``w_c |gap|^2 / 2``; NaN with ``lag`` (the forces outside ``A`` are not evaluated).
    """
    n = x.shape[0]
    energy = math.nan
    if not lag:
        energy = _forces_outside(x, d_off, s_i, s_j, s_lo, s_hi, s_w, h_i, h_k, h_rest, f_lag, hinge_work)
    for i in range(n):
        for c in range(3):
            b[i, c] = mh2[i] * y[i, c] + f_lag[i, c]
    if lag:  # the plain iterations' every other call: no energy to give, none summed (they are the hot path)
        for e in range(e_i.shape[0]):
            px, py, pz = _band(x, e_i[e], e_j[e], e_lo[e], e_hi[e])
            _scatter(b, e_i[e], e_j[e], e_w[e], px, py, pz)
    else:
        energy += _inertia(x, y, mh2) + _bands(x, b, e_i, e_j, e_lo, e_hi, e_w)
    energy += _corners(x, b, a_i, a_j, a_k, a_cos_lo, a_cos_hi, a_w, not lag)
    energy += _contact_targets(x, inv_mass, pts_v, pts_b, c_n, c_h, c_n2, c_nq2, c_h2, c_list, n_c, w_c, b, gap,
                               count, not lag)
    for i in range(n):
        if lam[i] > 0.0:
            b[i, 0] += lam[i] * nrm[i, 0]
            b[i, 1] += lam[i] * nrm[i, 1]
            b[i, 2] += lam[i] * nrm[i, 2]
    for i in range(n):
        for q in range(pin_ptr[i], pin_ptr[i + 1]):
            p = pin_nbr[q]
            b[i, 0] += pin_w[q] * x[p, 0]
            b[i, 1] += pin_w[q] * x[p, 1]
            b[i, 2] += pin_w[q] * x[p, 2]
    for q in range(pin_idx.shape[0]):
        p = pin_idx[q]
        b[p, 0], b[p, 1], b[p, 2] = x[p, 0], x[p, 1], x[p, 2]
    return energy


@njit(inline="always")
def _inertia(x, y, mh2):
    """``sum m |x - y|^2 / (2 h^2)``, J (``mh2`` is ``m / h^2``)."""
    energy = 0.0
    for i in range(x.shape[0]):
        dx, dy, dz = x[i, 0] - y[i, 0], x[i, 1] - y[i, 1], x[i, 2] - y[i, 2]
        energy += 0.5 * mh2[i] * (dx * dx + dy * dy + dz * dz)
    return energy


@njit(inline="always")
def _bands(x, b, e_i, e_j, e_lo, e_hi, e_w):
    """The distance bands in ``A`` into ``b`` (``w S^T p``); returns their energy ``w |S x - p|^2 / 2``, J."""
    energy = 0.0
    for e in range(e_i.shape[0]):
        i, j = e_i[e], e_j[e]
        px, py, pz = _band(x, i, j, e_lo[e], e_hi[e])
        dx, dy, dz = x[j, 0] - x[i, 0] - px, x[j, 1] - x[i, 1] - py, x[j, 2] - x[i, 2] - pz
        energy += 0.5 * e_w[e] * (dx * dx + dy * dy + dz * dz)
        _scatter(b, i, j, e_w[e], px, py, pz)
    return energy


@njit
def _forces_outside(x, d_off, s_i, s_j, s_lo, s_hi, s_w, h_i, h_k, h_rest, f, hinge_work):
    """``f`` (n, 3) N: ``D x`` plus the forces of the elements outside ``A`` at ``x`` (module docstring);
    returns their energy, J."""
    for i in range(x.shape[0]):
        for c in range(3):
            f[i, c] = d_off[i] * x[i, c]
    energy = 0.0
    for e in range(s_i.shape[0]):
        i, j = s_i[e], s_j[e]
        px, py, pz = _band(x, i, j, s_lo[e], s_hi[e])
        # the spring's force at the iterate: w (p - d) on j, its opposite on i
        dx, dy, dz = px - (x[j, 0] - x[i, 0]), py - (x[j, 1] - x[i, 1]), pz - (x[j, 2] - x[i, 2])
        energy += 0.5 * s_w[e] * (dx * dx + dy * dy + dz * dz)
        _scatter(f, i, j, s_w[e], dx, dy, dz)
    return energy + add_elastic_hinge_forces(x, h_i, h_k, h_rest, f, 0, h_i.shape[0], hinge_work)


@njit
def chebyshev(x, x_new, x_prev, k, delay, rho, omega):
    """The iterate after ``x_new`` (the global solve's), Chebyshev semi-iterative (Wang 2015), in place: on return
    ``x`` is the next iterate and ``x_prev`` the one before it; returns the weight ``omega`` for the next call.
    Iterations before ``delay`` take ``x_new`` as it is."""
    if k < delay:
        om = 1.0
    elif k == delay:
        om = 2.0 / (2.0 - rho * rho)
    else:
        om = 4.0 / (4.0 - rho * rho * omega)
    for i in range(x.shape[0]):
        for c in range(3):
            xo = x[i, c]
            x[i, c] = om * (x_new[i, c] - x_prev[i, c]) + x_prev[i, c]
            x_prev[i, c] = xo
    return om


@njit
def soft_push(gap, inv_mass, w_c, h2, push, lam, nrm):
    """``push`` (n, 3) m: the normal displacement the soft contacts gave each vertex over the step, ``w_c h^2 / m``
    times its push at the last iterate (the contact force ``w_c gap`` over the step; cloth resting on the skin:
    ``g h^2``); the exact projection adds its own moves after
    (:func:`vfit_engine.kernels.contact_solve.solve_contacts`)."""
    for i in range(gap.shape[0]):
        s = w_c[i] * h2 * inv_mass[i]
        f = lam[i] * h2 * inv_mass[i]
        push[i, 0] = s * gap[i, 0] + f * nrm[i, 0]
        push[i, 1] = s * gap[i, 1] + f * nrm[i, 1]
        push[i, 2] = s * gap[i, 2] + f * nrm[i, 2]


@njit
def contact_body_velocity(inv_mass, pt_v, pt_b, c_list, n_c, c_u, push_u, push_w):
    """The moving body's velocity under each free vertex its listed contact points touch: ``push_u`` (n, 3) the sum
    of the points' body velocities ``c_u`` (P, 3) m/s weighed by the vertex's barycentric weight in each point,
    ``push_w`` (n,) the sum of those weights (so ``push_u / push_w`` is the mean velocity, m/s; 0 and 0 for a vertex
    no point touches). The Gauss-Seidel solver weighs each point's push instead
    (:func:`vfit_engine.kernels.contact_solve.push_point`); here the contacts push through the global solve, and
    a point within reach of the skin is the cloth the skin carries."""
    for i in range(inv_mass.shape[0]):
        push_u[i, 0] = push_u[i, 1] = push_u[i, 2] = 0.0
        push_w[i] = 0.0
    for m in range(n_c):
        p = c_list[m]
        for k in range(3):
            v = pt_v[p, k]
            w = pt_b[p, k]
            if w <= 0.0 or inv_mass[v] <= 0.0:
                continue
            push_u[v, 0] += w * c_u[p, 0]
            push_u[v, 1] += w * c_u[p, 1]
            push_u[v, 2] += w * c_u[p, 2]
            push_w[v] += w


@njit
def contact_friction(x, x0, inv_mass, w_c, gap, lam, nrm, friction, push_u, push_w, dt, b):
    """Coulomb friction in the global step: add to ``b`` (n, 3), for every free vertex the body pushes, the pull
    ``w_c`` back towards where it lay at the step's start ``x0`` along the body (its slip ``d_t``, the move
    ``x - x0`` less its part along the push's normal), at most ``friction`` times its normal force (``w_c |gap|``
    of the soft push plus the Uzawa force ``lam``): ``b -= w_c s d_t``, ``s = min(1, friction f_n / (w_c |d_t|))``.

    On a moving body (``push_w`` not empty, :func:`contact_body_velocity`) the slip is relative to the skin under
    the vertex: ``d = x - x0 - u dt``, ``u = push_u / push_w`` (m/s) over the step ``dt`` (s), so within the cone the
    vertex goes where the skin takes it (a sheet on a moving slab is carried at the slab's speed).

    Within the cone the vertex's target is where it lay (it sticks); beyond it, it slides by the excess. Friction
    taken on the velocity alone after the step lets cloth held by friction creep downhill by its tangential
    gravity ``g sin(theta) h^2`` every step (a shirt on the shoulders drifted 0.1 mm a frame and never settled).

    Returns the pull's energy, J: ``w_c huber(|d_t|, c)``, quadratic within the cone's ``c = friction f_n / w_c``,
    linear beyond (for :mod:`vfit_engine.kernels.lbfgs`' line search; with the normal force held)."""
    energy = 0.0
    if friction <= 0.0:
        return energy
    moving = push_w.shape[0] > 0
    for i in range(x.shape[0]):
        w = w_c[i]
        if inv_mass[i] <= 0.0 or w <= 0.0:
            continue
        g = math.sqrt(gap[i, 0] * gap[i, 0] + gap[i, 1] * gap[i, 1] + gap[i, 2] * gap[i, 2])
        force = w * g + max(lam[i], 0.0)
        if force <= 0.0:
            continue
        if lam[i] > 0.0:
            nx, ny, nz = nrm[i, 0], nrm[i, 1], nrm[i, 2]
        else:
            nx, ny, nz = gap[i, 0] / g, gap[i, 1] / g, gap[i, 2] / g
        dx, dy, dz = x[i, 0] - x0[i, 0], x[i, 1] - x0[i, 1], x[i, 2] - x0[i, 2]
        if moving and push_w[i] > 0.0:
            s = dt / push_w[i]
            dx -= push_u[i, 0] * s
            dy -= push_u[i, 1] * s
            dz -= push_u[i, 2] * s
        dn = dx * nx + dy * ny + dz * nz
        tx, ty, tz = dx - dn * nx, dy - dn * ny, dz - dn * nz
        t = math.sqrt(tx * tx + ty * ty + tz * tz)
        if t <= 0.0:
            continue
        s = min(1.0, friction * force / (w * t))  # (as it was: the drapes' bits hang on its rounding)
        cone = friction * force / w
        energy += w * (0.5 * t * t if t <= cone else cone * (t - 0.5 * cone))
        b[i, 0] -= w * s * tx
        b[i, 1] -= w * s * ty
        b[i, 2] -= w * s * tz
    return energy
