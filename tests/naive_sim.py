"""Slow, obvious NumPy/Python versions of the cloth kernels, for tests only.

Each function copies its inputs and returns the results; the formulas are the ones the kernels'
docstrings give (:mod:`vfit_engine.kernels.cloth`, :mod:`.springs`, :mod:`.integrate`,
:mod:`.strain_limit`, :mod:`.collide_sphere`), written out vertex by vertex and constraint by
constraint.
"""
import math

import numpy as np


def spring_forces(x, xp, dt, idx, rest, k, kd):
    """Damped Hooke forces, N: f_i = [k (l - l0) + kd (v_j - v_i).u] u, f_j = -f_i."""
    v = (x - xp) / dt
    d = x[idx[:, 1]] - x[idx[:, 0]]
    length = np.linalg.norm(d, axis=1)
    u = d / length[:, None]
    vr = np.sum((v[idx[:, 1]] - v[idx[:, 0]]) * u, axis=1)
    fs = (k * (length - rest) + kd * vr)[:, None] * u
    f = np.zeros_like(x)
    np.add.at(f, idx[:, 0], fs)
    np.add.at(f, idx[:, 1], -fs)
    return f


def hinge_forces(x, xp, dt, idx, k, kd, rest, eps=1e-7):
    """Bending forces of dihedral hinges, N: f = -(k (theta - theta0) + kd dtheta/dt) grad theta, the gradient
    by central differences of the angle (:func:`vfit_engine.sim.bending.hinge_angles`)."""
    from vfit_engine.sim.bending import hinge_angles

    v = (x - xp) / dt
    f = np.zeros_like(x)
    for h in range(idx.shape[0]):
        one = idx[h:h + 1]
        grad = np.zeros((4, 3))
        for m in range(4):
            for c in range(3):
                a, b = x.copy(), x.copy()
                a[one[0, m], c] += eps
                b[one[0, m], c] -= eps
                grad[m, c] = (hinge_angles(one, a)[0] - hinge_angles(one, b)[0]) / (2 * eps)
        d = (hinge_angles(one, x)[0] - rest[h] + np.pi) % (2 * np.pi) - np.pi
        f[one[0]] -= (k[h] * d + kd[h] * np.sum(grad * v[one[0]])) * grad
    return f


def hinge_sweep(x, w, idx, compliance, rest, lam, at_scale, visit=None, eps=1e-7, moved=None):
    """One Gauss-Seidel sweep of hinges as compliant angle constraints (XPBD): hinge by hinge, C = theta -
    theta0 and its gradient by central differences of the angle; compliance 0 skips a hinge. Returns
    (x, lam) (copies); with a list ``moved``, appends the hinges that moved a vertex by more than the kernel's
    ``HINGE_ACTIVE``."""
    from vfit_engine.kernels.bending import HINGE_ACTIVE
    from vfit_engine.sim.bending import hinge_angles

    x, lam = x.copy(), lam.copy()
    for h in range(idx.shape[0]) if visit is None else visit:
        if compliance[h] <= 0:
            continue
        ids, one = idx[h], idx[h:h + 1]
        grad = np.zeros((4, 3))
        for m in range(4):
            for c in range(3):
                a, b = x.copy(), x.copy()
                a[ids[m], c] += eps
                b[ids[m], c] -= eps
                grad[m, c] = (hinge_angles(one, a)[0] - hinge_angles(one, b)[0]) / (2 * eps)
        d = (hinge_angles(one, x)[0] - rest[h] + np.pi) % (2 * np.pi) - np.pi
        at = compliance[h] * at_scale
        dlam = (-d - at * lam[h]) / (np.sum(w[ids] * np.sum(grad ** 2, axis=1)) + at)
        lam[h] += dlam
        x[ids] += w[ids, None] * grad * dlam
        if moved is not None and np.max(w[ids] * np.linalg.norm(grad, axis=1)) * abs(dlam) > HINGE_ACTIVE:
            moved.append(h)
    return x, lam


def integrate(x, xp, inv_mass, f, gravity, dt, c):
    """x+ = x + (1 - c)(x - x-) + (w f + g) dt^2 for free particles; pinned keep x."""
    a = inv_mass[:, None] * f + np.asarray(gravity)[None, :]
    out = x + (1.0 - c) * (x - xp) + a * dt * dt
    pinned = inv_mass == 0
    out[pinned] = x[pinned]
    return out


def strain_limit_sweep(x, inv_mass, idx, max_len, omega=1.0):
    """One Gauss-Seidel sweep of Provot strain limiting, springs in the given order (copy)."""
    x = x.copy()
    for (i, j), lmax in zip(idx, max_len):
        wi, wj = inv_mass[i], inv_mass[j]
        if wi + wj == 0:
            continue
        d = x[j] - x[i]
        length = np.sqrt(d @ d)
        if length > lmax:
            corr = omega * (length - lmax) / length * d / (wi + wj)
            x[i] = x[i] + wi * corr
            x[j] = x[j] - wj * corr
    return x


def collide_spheres(x, xp, inv_mass, centres, radii, friction, restitution):
    """Project free particles out of spheres, friction/restitution on x - x_prev (copies)."""
    x = x.copy()
    xp = xp.copy()
    for i in range(x.shape[0]):
        if inv_mass[i] == 0:
            continue
        for c, r, cf, cr in zip(centres, radii, friction, restitution):
            d = x[i] - c
            dist = np.linalg.norm(d)
            if dist >= r:
                continue
            n = d / dist if dist > 0 else np.array([0.0, 1.0, 0.0])
            v = x[i] - xp[i]
            vn = v @ n
            vt = v - vn * n
            vn_new = -cr * vn if vn < 0 else vn
            x[i] = c + r * n
            xp[i] = x[i] - ((1 - cf) * vt + vn_new * n)
    return x, xp


# -- the cloth kernel (vfit_engine.kernels.cloth) -------------------------------------------------

def corner_angle(x, i, j, k):
    """The angle at ``k`` between ``i`` and ``j``, radians."""
    u, v = x[i] - x[k], x[j] - x[k]
    return math.atan2(np.linalg.norm(np.cross(u, v)), float(u @ v))


def project_angle(x, w, i, j, k, cos_lo, cos_hi, relax):
    """PBD angle constraint: the angle theta at ``k`` kept in [acos(cos_lo), acos(cos_hi)] (copy).

    Outside the band, C = theta - (the nearer end) and every vertex moves by
    ``-relax C w_a grad_a theta / sum_b w_b |grad_b theta|^2`` with, for u = x_i - x_k, v = x_j - x_k,
    grad_i theta = -(v^ - cos u^) / (|u| sin), grad_j theta = -(u^ - cos v^) / (|v| sin),
    grad_k theta = -(grad_i + grad_j) (a rotation of the whole corner leaves theta unchanged).
    Returns (x, moved); ``moved``: outside the band, or inside within ``margin`` of an end in cosine.
    """
    from vfit_engine.kernels.cloth import ACTIVE_BAND

    x = x.copy()
    u, v = x[i] - x[k], x[j] - x[k]
    lu, lv = np.linalg.norm(u), np.linalg.norm(v)
    if lu <= 0 or lv <= 0:
        return x, False
    uh, vh = u / lu, v / lv
    c = min(max(float(uh @ vh), -1.0), 1.0)
    if cos_hi <= c <= cos_lo:
        return x, bool(c - cos_hi < ACTIVE_BAND or cos_lo - c < ACTIVE_BAND)
    target = math.acos(cos_hi) if c < cos_hi else math.acos(cos_lo)
    s = math.sqrt(max(1.0 - c * c, 0.0))
    if s < 1e-6:
        return x, True
    gi = -(vh - c * uh) / (lu * s)
    gj = -(uh - c * vh) / (lv * s)
    gk = -(gi + gj)
    den = w[i] * gi @ gi + w[j] * gj @ gj + w[k] * gk @ gk
    if den <= 0:
        return x, True
    lam = -relax * (math.acos(c) - target) / den
    x[i] += w[i] * lam * gi
    x[j] += w[j] * lam * gj
    x[k] += w[k] * lam * gk
    return x, True


def distance_sweep(x, w, c, lam, at_scale, visit=None, hot=None):
    """One Gauss-Seidel sweep over the constraints ``visit`` (default: all, in order) (copies).

    ``c`` is a dict of the constraint arrays (``i j lo hi alpha relax corner cos_lo cos_hi once``). A
    distance constraint outside its band ``[lo, hi]`` (or holding a force: lam != 0) takes the XPBD
    step ``dlam = relax (-C - at lam) / (w_i + w_j + at)`` with C = l - hi (or l - lo) and
    ``at = alpha at_scale``, its lam clamped to its side (<= 0 pulling in, >= 0 pushing out), the ends
    moved by ``-+ w dlam u``. A constraint with a corner is an angle constraint (:func:`project_angle`).

    Returns
    -------
    x, lam, active
        ``active``: the constraints visited that acted, were outside their band, or lie within
        ``ACTIVE_BAND`` of an end, or with a vertex marked in ``hot`` (n,) bool (what the kernel's later
        sweeps visit), in visit order; never those marked ``once`` (solved in the full sweeps only).
    """
    from vfit_engine.kernels.cloth import ACTIVE_BAND

    x, lam = x.copy(), lam.copy()
    once = c.get("once", np.zeros(len(c["i"]), dtype=bool))
    hot = np.zeros(x.shape[0], dtype=bool) if hot is None else hot
    active = []
    for a in (range(len(c["i"])) if visit is None else visit):
        i, j = c["i"][a], c["j"][a]
        if w[i] + w[j] <= 0:
            continue
        if c["corner"][a] >= 0:
            x, moved = project_angle(x, w, i, j, c["corner"][a], c["cos_lo"][a], c["cos_hi"][a], c["relax"][a])
            if moved or hot[i] or hot[j] or hot[c["corner"][a]]:
                active.append(a)
            continue
        d = x[j] - x[i]
        length = math.sqrt(d @ d)
        lo, hi, at = c["lo"][a], c["hi"][a], c["alpha"][a] * at_scale
        if lam[a] < 0 or length > hi:  # pulling in: lam <= 0
            new = min(lam[a] + c["relax"][a] * (hi - length - at * lam[a]) / (w[i] + w[j] + at), 0.0)
        elif lam[a] > 0 or length < lo:  # pushing out: lam >= 0
            new = max(lam[a] + c["relax"][a] * (lo - length - at * lam[a]) / (w[i] + w[j] + at), 0.0)
        else:
            if not once[a] and (hi - length < ACTIVE_BAND * hi or length - lo < ACTIVE_BAND * hi or hot[i] or hot[j]):
                active.append(a)
            continue
        if not once[a]:
            active.append(a)
        if length <= 0:
            continue
        u = d / length
        x[i] -= w[i] * (new - lam[a]) * u
        x[j] += w[j] * (new - lam[a]) * u
        lam[a] = new
    return x, lam, active


def contact_point(x, v, b, p):
    """Position of contact point ``p``: sum_k b_k x_{v_k}."""
    return b[p, 0] * x[v[p, 0]] + b[p, 1] * x[v[p, 1]] + b[p, 2] * x[v[p, 2]]


def push_points(x, w, v, b, planes, push=None, live=False, only=None, carry=None):
    """Each contact point p onto its half-space n . p >= h, in order (copies).

    ``planes`` is a list of (p, n (3,), h). A point below by g > 0 moves its vertices by
    ``dx_k = w_k b_k g n / sum_j w_j b_j^2`` (PBD point-triangle constraint: the point itself moves by g).
    ``push`` (n, 3) sums every vertex's moves. ``only``: the points to visit (None: all). Returns
    (x, push), and with ``live`` also the points (in order, once each) that had a plane with gap
    above -ACTIVE_GAP. ``carry``: (u (P, 3), push_u (n, 3), push_w (n,)) -- the body's velocity at each point
    and every vertex's sums of |dx_k| u and |dx_k| (added to in place).
    """
    from vfit_engine.kernels.contact_solve import ACTIVE_GAP

    x = x.copy()
    push = np.zeros_like(x) if push is None else push.copy()
    gaps = {}
    for p, n, h in planes:
        if only is not None and p not in only:
            continue
        n = np.asarray(n, dtype=np.float64)
        gap = h - n @ contact_point(x, v, b, p)
        gaps[p] = max(gaps.get(p, -np.inf), gap)
        if gap <= 0:
            continue
        den = sum(w[v[p, k]] * b[p, k] ** 2 for k in range(3))
        if den <= 0:
            continue
        for k in range(3):
            dk = w[v[p, k]] * b[p, k] * gap / den
            x[v[p, k]] += dk * n
            push[v[p, k]] += dk * n
            if carry is not None and dk != 0:
                carry[1][v[p, k]] += dk * carry[0][p]
                carry[2][v[p, k]] += dk
    if live:
        return x, push, [int(p) for p, g in gaps.items() if g > -ACTIVE_GAP]
    return x, push


def contact_velocity(x, xp, w, push, friction, keep_t, body=None, stick=False):
    """The step's motion of every pushed free vertex, re-expressed through ``xp`` (copies: returns (x, xp)).

    With n the direction of its push (amount |push|) and u the body's own motion in the step under it
    (``body`` (n, 3), m per step; None: a still body), v = x - xp - u: the normal velocity before the push
    was vn - |push|; an approaching one becomes 0 (inelastic; a receding one is kept), the pushes add
    none; the tangential part shrinks by ``friction`` times the normal change (never reversing) and
    then by the factor ``keep_t``; the vertex moves on with u plus that. With ``stick`` the tangential
    motion friction took off is taken off the position too (the vertex slips only by what is left).
    """
    x, xp = x.copy(), xp.copy()
    for i in range(x.shape[0]):
        amount = np.linalg.norm(push[i])
        if amount <= 0 or w[i] <= 0:
            continue
        u = np.zeros(3) if body is None else body[i]
        n = push[i] / amount
        vel = x[i] - xp[i] - u
        vn = vel @ n
        vt = vel - vn * n
        vn_in = vn - amount
        vn_new = max(vn_in, 0.0)
        t = np.linalg.norm(vt)
        slide = max(0.0, t - friction * (vn_new - vn_in))
        scale = keep_t * slide / t if t > 0 else 0.0
        if stick and t > 0:
            x[i] -= (1.0 - slide / t) * vt
        xp[i] = x[i] - (u + vn_new * n + scale * vt)
    return x, xp


def sphere_contacts(x, w, v, b, skin, spheres, reach, max_push, velocity=None, ground=None):
    """Contact half-spaces of the points near the spheres (fresh: every point queried).

    A point whose free vertices carry less than half its weight is skipped. Its nearest sphere (by
    signed distance d = |p - c| - r; at the centre the normal is +Y) gives the closest point q and
    normal n; a point with ``d < skin + reach`` gets the half-space
    ``n . p >= n . q + min(skin, d + max_push)``. Returns [(p, n, h)] in point order; given the spheres'
    ``velocity`` (S, 3), also (P, 3) the velocity of each point's nearest sphere. ``ground`` (m): a still
    plane y = ground, normal +Y, nearer than the spheres where p_y - ground is smaller.
    """
    planes = []
    u = np.zeros((v.shape[0], 3))
    for p in range(v.shape[0]):
        if sum(b[p, k] for k in range(3) if w[v[p, k]] > 0) < 0.5:
            continue
        pt = contact_point(x, v, b, p)
        best = None
        for s, (cx, cy, cz, r) in enumerate(spheres):
            d = pt - [cx, cy, cz]
            dist = np.linalg.norm(d)
            n = d / dist if dist > 0 else np.array([0.0, 1.0, 0.0])
            if best is None or dist - r < best[0]:
                best = (dist - r, n, np.array([cx, cy, cz]) + r * n, s)
        if ground is not None and (best is None or pt[1] - ground < best[0]):
            best = (pt[1] - ground, np.array([0.0, 1.0, 0.0]), np.array([pt[0], ground, pt[2]]), -1)
        if best is None or not best[0] < skin[p] + reach:
            continue
        d, n, q, s = best
        if velocity is not None:
            u[p] = velocity[s] if s >= 0 else 0.0
        planes.append((p, n, n @ q + min(skin[p], d + max_push)))
    return planes if velocity is None else (planes, u)


def cloth_substep(x, xp, cl, pins, pts, dt, c_air, iterations, reach, friction, max_push, c_contact, alpha_pins,
                  segments=None, hinge_every=2, sphere_velocity=None, stick=False, ground=None):
    """One substep of the cloth kernel against sphere colliders, fresh contact memory (copies).

    ``cl``: dict with ``inv_mass gravity sp_i sp_j sp_rest sp_k sp_kd`` (and optionally the force hinges' ``h_i
    h_k h_kd h_rest`` and the constraint hinges' ``hc_i hc_alpha hc_rest hc_seg``, :func:`hinge_sweep`, first in
    each segment's sweep, in every ``hinge_every``-th sweep and the last: the first and last visit every hinge,
    the others those the first found moving) and the constraint arrays of
    :func:`distance_sweep`; ``pins``: (idx, from, to) with the pins at ``alpha_pins`` of the way;
    ``pts``: (verts, bary, skin, spheres). Steps (the kernel's module docstring): explicit springs and
    gravity, Verlet with air damping; pins; contact half-spaces; ``iterations`` x {constraint sweep,
    contacts} (the first and last sweeps visit every constraint and contact, the others those the
    first found active or live); the contact velocity. ``segments``: (c_seg, p_seg), each (4,): every
    sweep visits segment 0's constraints then its contacts, then segment 1's, then segment 2's (the
    kernel's "Two threads"); None: one segment. ``sphere_velocity`` (S, 3) m/s: the spheres move, and each
    pushed vertex's contact velocity is taken relative to the push-weighted mean velocity of the spheres that
    pushed it (:func:`contact_velocity`); ``stick``: position-level friction; ``ground`` (m): a still ground
    plane (:func:`sphere_contacts`). Returns (x, xp).
    """
    w = cl["inv_mass"]
    idx = np.stack([cl["sp_i"], cl["sp_j"]], axis=1)
    f = spring_forces(x, xp, dt, idx, cl["sp_rest"], cl["sp_k"], cl["sp_kd"])
    if "h_i" in cl:
        f += hinge_forces(x, xp, dt, cl["h_i"], cl["h_k"], cl["h_kd"], cl["h_rest"])
    x_new = integrate(x, xp, w, f, cl["gravity"], dt, c_air)
    xp_new = x.copy()
    pin_idx, pin_from, pin_to = pins
    x_new[pin_idx] = pin_from + alpha_pins * (pin_to - pin_from)
    v, b, skin, spheres = pts
    carry = None
    if sphere_velocity is not None:
        planes, u = sphere_contacts(x_new, w, v, b, skin, spheres, reach, max_push, velocity=sphere_velocity,
                                    ground=ground)
        carry = (u, np.zeros_like(x_new), np.zeros(len(x_new)))
    else:
        planes = sphere_contacts(x_new, w, v, b, skin, spheres, reach, max_push, ground=ground)
    n_c, n_p = len(cl["i"]), len(v)
    c_seg, p_seg = segments if segments is not None else ([0, n_c, n_c, n_c], [0, n_p, n_p, n_p])
    lam = np.zeros(len(cl["i"]))
    h_lam = np.zeros(len(cl.get("hc_alpha", ())))
    push = np.zeros_like(x_new)
    active, live, h_active = {}, {}, {}
    for it in range(iterations):
        every = it == 0 or it == iterations - 1
        for g in range(3):
            if h_lam.size and (it % hinge_every == 0 or it == iterations - 1):
                # the first pass lists the hinges that moved a vertex, the middle ones visit those, the last all
                hinges = range(cl["hc_seg"][g], cl["hc_seg"][g + 1])
                if it == 0:
                    h_active[g] = []
                x_new, h_lam = hinge_sweep(x_new, w, cl["hc_i"], cl["hc_alpha"], cl["hc_rest"], h_lam, 1.0 / dt ** 2,
                                           hinges if every else h_active[g], moved=h_active[g] if it == 0 else None)
            visit = range(c_seg[g], c_seg[g + 1]) if every else active[g]
            x_new, lam, found = distance_sweep(x_new, w, cl, lam, 1.0 / dt ** 2, visit)
            if it == 0:
                active[g] = found
            mine = [pl for pl in planes if p_seg[g] <= pl[0] < p_seg[g + 1]]
            if it == 0:
                x_new, push, live[g] = push_points(x_new, w, v, b, mine, push, live=True, carry=carry)
            else:
                x_new, push = push_points(x_new, w, v, b, mine, push, only=None if every else set(live[g]),
                                          carry=carry)
    body = None
    if carry is not None:
        held = carry[2] > 0
        body = np.zeros_like(x_new)
        body[held] = carry[1][held] / carry[2][held, None] * dt
    return contact_velocity(x_new, xp_new, w, push, friction, 1.0 - c_contact, body=body, stick=stick)
