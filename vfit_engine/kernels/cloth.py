"""Numba kernel: cloth substeps -- position Verlet, constraints with bands and compliance, surface contacts.

One substep (Verlet 1967 / Jakobsen 2001 for the integration; Provot 1995 and XPBD, Macklin,
Mueller & Chentanez 2016, for the constraints; contacts as inequality constraints solved in
the same Gauss-Seidel loop, as in position based dynamics, Mueller et al. 2007)::

    1. explicit forces: damped Hooke springs, bending hinges and gravity; position Verlet with air damping:
       x+ = x + (1 - c)(x - x-) + (w f + g) dt^2
    2. pinned particles follow their targets
    3. contact generation: every contact point p -- a cloth vertex, or a point of a cloth
       triangle p = sum_k b_k x_k -- that may be within ``skin_p + reach`` of the body (or the ground) gets
       the nearer one's closest point q and outward normal n, and the half-space
           n . p >= n . q + min(skin_p, d + max_push)        (d its signed distance now)
       (a point inside comes out by at most ``max_push`` per substep)
    4. ``iterations`` x { every hinge too stiff for step 1 (an angle constraint of compliance 1 / k:
       :func:`vfit_engine.kernels.bending.project_hinge_range`; every ``hinge_every``-th sweep and the last: the
       first and last of these passes visit every such hinge, the second lists those that still moved a vertex
       by more than ``HINGE_ACTIVE`` and the others visit only those -- after two passes half of a resting
       garment's hinges are within a fraction of a micrometre of their balance); every distance constraint
       (below); every contact half-space } -- the distance constraints' and contacts' first
       and last of them; the middle ones visit only the constraints near or beyond their bands' ends
       after the first (``ACTIVE_BAND``) or at a vertex the contacts pushed hard in the last substep
       (``PUSH_HOT``), and the contacts near or below their half-spaces (``ACTIVE_GAP``): most cloth lies
       well inside its bands and clear of the body
    5. contact velocity, relative to the body's own velocity u at the contact (a moving body carries the
       cloth it touches; u = 0 on a still body): the pushes add no velocity; the approaching normal
       velocity of a pushed vertex is removed (inelastic), its tangential velocity shrinks by ``friction``
       times the normal change (Coulomb, never reversing) and by the contact damping. With ``stick`` the
       friction acts on the step's tangential slip too (position-level friction, Macklin, Mueller,
       Chentanez & Kim 2014, "Unified particle physics", section 6.1): the slip is taken back by as much
       as the velocity loses, so cloth within the friction cone does not move on the skin at all; without
       it, cloth resting on a slope slides g sin(theta) dt^2 every substep however large the friction
       (velocity-level friction only stops what the step had gained).

A distance constraint keeps the length l = |x_j - x_i| of a vertex pair inside a band
``[lo, hi]``: outside it C = l - hi (or l - lo) and, with compliance alpha (m/N, the inverse of a
spring stiffness) and ``at = alpha / dt^2``::

    dlam = relax (-C - at lam) / (w_i + w_j + at),   x_i -= w_i dlam u,   x_j += w_j dlam u   (u = d / l)

``lam`` accumulates over a substep's iterations (XPBD) and is clamped to its side of the band
(projected Gauss-Seidel: a constraint pulls only to keep l <= hi, pushes only to keep l >= lo).
With alpha = 0 and lo = 0 this is Provot's strain limit; with a band of width 0 a spring of
stiffness 1/alpha. ``relax`` weighs constraints against each other where they cannot all hold (a
garment the body forces wider): Gauss-Seidel settles where each vertex's pulls balance,
sum relax_e C_e u_e = 0, so relax proportional to stiffness shares the stretch as an elastic sheet
would, instead of short stiff edges taking it all.

A contact point below its half-space is pushed out over its vertices as :mod:`.contact_solve` says (a triangle
that spans a body bump between its vertices is pushed out as a whole).

Contact generation skips points proven clear: the signed distance is 1-Lipschitz, so a point whose
last query found ``d_last`` (at ``p_last``) is still at least ``d_last - |p - p_last|`` from the
body. A point in contact that moved less than ``reuse`` since its last query keeps that query's
tangent plane (cloth resting on the skin barely moves, and the exact query is most of the cost).

Two threads: the caller numbers the cloth's vertices in two halves and orders every spring,
constraint and contact point by segment -- 0: all its vertices in the first half, 1: all in the
second, 2: across -- with the bounds in ``sp_seg``, ``c_seg``, ``p_seg`` (``seg[g] .. seg[g + 1] - 1``).
Segments 0 and 1 share no vertex, so each pass (spring forces, contact generation, each sweep of
constraints then contacts) runs them on two threads and segment 2 after them: the result is that of
one thread visiting the segments in order, whatever the number of threads. Each segment keeps its
active constraints and its contacts in its own part of ``active``, ``c_list`` and ``c_live`` (from its
first index), and its counts in ``counts``.

The helpers take plain arrays: the entry kernel unpacks the argument tuples once, since Numba
re-reads (and reference-counts) a tuple's arrays at every use inside a called function.
The cached kernel is stamped with the helpers it inlines from other modules too (:mod:`.bending`, :mod:`.contact_solve`,
:mod:`.springs`, :mod:`.integrate`, :mod:`.contact_make`, :mod:`.collide_mesh`): after an edit to any of
them the next run compiles afresh (:mod:`vfit_engine._jit`).
"""
import math
from collections import namedtuple

from vfit_engine._jit import njit, prange
from vfit_engine.kernels.bending import PASS_ALL, PASS_LIST, PASS_LISTED, add_hinge_forces, project_hinge_range
from vfit_engine.kernels.contact_make import make_contacts
from vfit_engine.kernels.contact_solve import contact_velocity, solve_contacts
from vfit_engine.kernels.integrate import advance_in_place, move_pins
from vfit_engine.kernels.springs import add_spring_forces

#: The cloth as the kernel sees it (fixed during a drape): inv_mass (n,) 1/kg; gravity (3,) m/s^2;
#: explicit springs sp_i, sp_j (s,) int64, sp_rest (s,) m, sp_k (s,) N/m, sp_kd (s,) N s/m;
#: distance constraints in sweep order c_i, c_j (C,) int64, c_lo, c_hi (C,) m, c_alpha (C,) m/N,
#: c_relax (C,); c_corner (C,) int64 (a shear limit's corner, else -1) and c_cos_lo, c_cos_hi (C,): the
#: cosines of its corner's smallest and largest angle (an angle constraint instead of a distance); c_once
#: (C,) bool: solved in the full sweeps only (weak restoring springs, never in the active set); sp_seg,
#: c_seg (4,) int64: the springs' and constraints' segments (module docstring, "Two threads"); the bending
#: hinges that act as explicit forces, h_i (H, 4) int64, h_k (H,) N m, h_kd (H,) N m s, h_rest (H,) rad and their
#: segments h_seg (4,) (:mod:`.bending`); and those solved as compliant angle constraints (too stiff for the
#: explicit step), hc_i (K, 4) int64, hc_alpha (K,) rad^2/(N m), hc_rest (K,) rad, hc_seg (4,)
#: (:func:`vfit_engine.kernels.bending.project_hinge_range`). The two sets are apart so that neither pass computes
#: a hinge's angle for nothing (a drape's garment has 2-3 times as many constraint hinges as force hinges).
ClothArrays = namedtuple("ClothArrays", ["inv_mass", "gravity", "sp_i", "sp_j", "sp_rest", "sp_k", "sp_kd",
                                         "c_i", "c_j", "c_lo", "c_hi", "c_alpha", "c_relax", "c_corner", "c_cos_lo",
                                         "c_cos_hi", "c_once", "sp_seg", "c_seg", "h_i", "h_k", "h_kd", "h_rest",
                                         "h_seg", "hc_i", "hc_alpha", "hc_rest", "hc_seg"])

#: Contact points: pt_v (P, 3) int64 vertices and pt_b (P, 3) float64 barycentric weights (cloth
#: vertex i is (i, i, i) with (1, 0, 0)); pt_skin (P,) m, the clearance each keeps; spheres (S, 4)
#: float64: sphere colliders (centre, radius), m; p_seg (4,) int64: the points' segments; body_vel (V, 3)
#: m/s: the velocity of the body grid's vertices (``grid.tris`` numbering) and sphere_vel (S, 3) m/s the
#: spheres' (their centres'), during the substeps; both (0, 3) for a still body (nothing to carry); body_sag
#: (V,) m: the body's extra thickness at each grid vertex (its small bumps,
#: :func:`vfit_engine.collide.sag.convex_sag`; (0,): none) and sag_max m its largest value; ground m: the height of
#: a still ground plane under the body (``-inf``: none; :func:`vfit_engine.kernels.contact_make.make_contacts`).
ContactPoints = namedtuple("ContactPoints", ["pt_v", "pt_b", "pt_skin", "spheres", "p_seg", "body_vel",
                                             "sphere_vel", "body_sag", "sag_max", "ground"])

#: Per-point contact memory (in/out): p_last (P, 3) m and d_last (P,) m (position and a lower bound
#: of the signed distance at the last query; ``-inf`` forces one), c_n (P, 3) and c_nq (P,) m (the
#: plane of the last query); scratch: c_h (P,) m, c_list (P,) int64, push (n, 3) m, f (n, 3) N,
#: lam (C,) m kg, active (C,) int64; c_n2 (P, 3), c_nq2 (P,) m (a second plane in a crease, NaN: none)
#: and c_h2 (P,) m; c_live (P,) int64 (the contacts a substep's middle sweeps solve); counts (3, 5) int64:
#: per segment its contacts, live contacts, active constraints, queries and active hinge constraints; hot (n,)
#: bool: the vertices the contacts pushed more than ``PUSH_HOT`` in the last substep; h_lam (K,): the hinge
#: constraints' multipliers; h_active (K,) int64: the hinge constraints a substep's middle passes solve; for a
#: moving body (``body_vel`` or ``sphere_vel`` given): c_u (P, 3) m/s, the body's velocity at each contact's
#: closest point (at its last query), and scratch push_u (n, 3) m^2/s, push_w (n,) m: each vertex's pushes'
#: sum of |move| u and of |move| (the body's velocity under it is their ratio).
ContactState = namedtuple("ContactState", ["p_last", "d_last", "c_n", "c_nq", "c_h", "c_list", "push", "f", "lam",
                                           "active", "c_n2", "c_nq2", "c_h2", "c_live", "counts", "hot", "h_lam",
                                           "h_active", "c_u", "push_u", "push_w"])

#: Scalars of a substep: dt s, c_air (per step), iterations, reach m, friction, max_push m,
#: c_contact (per step), reuse m, use_grid (query the body grid), hinge_every (the hinge constraints are
#: solved in every hinge_every-th sweep and the last), stick (friction on the slip too: step 5).
StepParams = namedtuple("StepParams", ["dt", "c_air", "iterations", "reach", "friction", "max_push",
                                       "c_contact", "reuse", "use_grid", "hinge_every", "stick"])

#: A constraint within this fraction of its band's ends after a substep's first sweep (or holding a
#: force) stays in that substep's later sweeps; the others are skipped (most cloth lies well inside
#: its bands).
ACTIVE_BAND = 0.003
SYMMETRIC = False


@njit(inline="always")
def _project_angle(x, w, i, j, k, cos_lo, cos_hi, relax):
    """Keep the angle at ``k`` between ``i`` and ``j`` within the band whose cosines are ``cos_lo``
    (the smallest angle) and ``cos_hi`` (the largest): a PBD angle constraint (its gradient turns the
    sides about the corner; scaling the quad is not shear). Returns True when it was, or came near
    being, outside the band (so the later sweeps keep it)."""
    ux, uy, uz = x[i, 0] - x[k, 0], x[i, 1] - x[k, 1], x[i, 2] - x[k, 2]
    vx, vy, vz = x[j, 0] - x[k, 0], x[j, 1] - x[k, 1], x[j, 2] - x[k, 2]
    lu = math.sqrt(ux * ux + uy * uy + uz * uz)
    lv = math.sqrt(vx * vx + vy * vy + vz * vz)
    if lu <= 0.0 or lv <= 0.0:
        return False
    ux, uy, uz = ux / lu, uy / lu, uz / lu
    vx, vy, vz = vx / lv, vy / lv, vz / lv
    cosa = min(max(ux * vx + uy * vy + uz * vz, -1.0), 1.0)
    # outside the band by cosines (cos falls as the angle grows); a small margin keeps it active
    if cosa < cos_hi:
        target = math.acos(cos_hi)
    elif cosa > cos_lo:
        target = math.acos(cos_lo)
    else:
        return cosa - cos_hi < ACTIVE_BAND or cos_lo - cosa < ACTIVE_BAND
    sina = math.sqrt(max(1.0 - cosa * cosa, 0.0))
    if sina < 1e-6:
        return True
    cval = math.acos(cosa) - target
    # d(angle)/d x_i = -(v - cos u) / (|u| sin), d/d x_j = -(u - cos v) / (|v| sin), d/d x_k = -(both)
    gix, giy, giz = -(vx - cosa * ux) / (lu * sina), -(vy - cosa * uy) / (lu * sina), -(vz - cosa * uz) / (lu * sina)
    gjx, gjy, gjz = -(ux - cosa * vx) / (lv * sina), -(uy - cosa * vy) / (lv * sina), -(uz - cosa * vz) / (lv * sina)
    gkx, gky, gkz = -(gix + gjx), -(giy + gjy), -(giz + gjz)
    den = (w[i] * (gix * gix + giy * giy + giz * giz) + w[j] * (gjx * gjx + gjy * gjy + gjz * gjz)
           + w[k] * (gkx * gkx + gky * gky + gkz * gkz))
    if den <= 0.0:
        return True
    s = -relax * cval / den
    x[i, 0] += w[i] * s * gix
    x[i, 1] += w[i] * s * giy
    x[i, 2] += w[i] * s * giz
    x[j, 0] += w[j] * s * gjx
    x[j, 1] += w[j] * s * gjy
    x[j, 2] += w[j] * s * gjz
    x[k, 0] += w[k] * s * gkx
    x[k, 1] += w[k] * s * gky
    x[k, 2] += w[k] * s * gkz
    return True


@njit
def _solve_distances(x, w, ci, cj, c_lo, c_hi, c_alpha, c_relax, c_corner, c_cos_lo, c_cos_hi, c_once, lam, at_scale,
                     active, hot, c0, c1, n_active, first, backward):
    """One Gauss-Seidel sweep over the constraints ``c0 .. c1 - 1`` (module docstring); returns the
    active count.

    The ``first`` sweep of a substep visits every one and lists in ``active`` (from index ``c0``) those
    holding a force or within ``ACTIVE_BAND`` of their band's ends afterwards; later sweeps visit only
    the ``n_active`` listed.
    """
    n_c = c1 - c0 if first else n_active
    n = 0
    for a0 in range(n_c):
        a = c0 + (n_c - 1 - a0 if backward else a0)
        c = a if first else active[a]
        i = ci[c]
        j = cj[c]
        wi = w[i]
        wj = w[j]
        wsum = wi + wj
        if wsum <= 0.0:
            continue
        d0 = x[j, 0] - x[i, 0]
        d1 = x[j, 1] - x[i, 1]
        d2 = x[j, 2] - x[i, 2]
        k = c_corner[c]
        if k >= 0:
            moved = _project_angle(x, w, i, j, k, c_cos_lo[c], c_cos_hi[c], c_relax[c])
            if first and (moved or hot[i] or hot[j] or hot[k]):
                active[c0 + n] = c
                n += 1
            continue
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        hi = c_hi[c]
        lo = c_lo[c]
        lc = lam[c]
        if lc < 0.0 or length > hi:
            at = c_alpha[c] * at_scale
            new = min(lc + c_relax[c] * (hi - length - at * lc) / (wsum + at), 0.0)
        elif lc > 0.0 or length < lo:
            at = c_alpha[c] * at_scale
            new = max(lc + c_relax[c] * (lo - length - at * lc) / (wsum + at), 0.0)
        else:
            if first and not c_once[c] and (hi - length < ACTIVE_BAND * hi or length - lo < ACTIVE_BAND * hi
                                            or hot[i] or hot[j]):
                active[c0 + n] = c
                n += 1
            continue
        if first and not c_once[c]:
            active[c0 + n] = c
            n += 1
        if length <= 0.0:
            continue
        lam[c] = new
        s = (new - lc) / length
        x[i, 0] -= wi * s * d0
        x[i, 1] -= wi * s * d1
        x[i, 2] -= wi * s * d2
        x[j, 0] += wj * s * d0
        x[j, 1] += wj * s * d1
        x[j, 2] += wj * s * d2
    return n if first else n_active


@njit(parallel=True)
def cloth_substeps(x, xp, cl, pin_idx, pin_from, pin_to, pts, grid, prm, st, sub_begin, sub_end, sub_total):
    """Substeps ``sub_begin .. sub_end - 1`` of ``sub_total`` (module docstring); returns the queries made.

    Parameters
    ----------
    x, xp : (n, 3) float64, m
        Positions now / one step ago (in place), numbered in two halves (module docstring).
    cl : ClothArrays
    pin_idx : (P,) int64;  pin_from, pin_to : (P, 3) float64, m
        Pinned particles move linearly from ``pin_from`` (start of substep 0) to ``pin_to`` (end of
        substep ``sub_total - 1``).
    pts : ContactPoints
    grid : BodyGrid
        The body (:mod:`vfit_engine.kernels.collide_mesh`); ignored unless ``prm.use_grid``.
    prm : StepParams
    st : ContactState
        In/out (the contact memory) and scratch.
    """
    w, gravity = cl.inv_mass, cl.gravity
    dt = prm.dt
    keep = 1.0 - prm.c_air
    counts = st.counts
    queries = 0
    for s in range(sub_begin, sub_end):
        st.f[:] = 0.0
        for g in prange(2):
            add_spring_forces(x, xp, 1.0 / dt, cl.sp_i, cl.sp_j, cl.sp_rest, cl.sp_k, cl.sp_kd, st.f, cl.sp_seg[g],
                              cl.sp_seg[g + 1])
        add_spring_forces(x, xp, 1.0 / dt, cl.sp_i, cl.sp_j, cl.sp_rest, cl.sp_k, cl.sp_kd, st.f, cl.sp_seg[2],
                          cl.sp_seg[3])
        for g in prange(2):
            add_hinge_forces(x, xp, 1.0 / dt, cl.h_i, cl.h_k, cl.h_kd, cl.h_rest, st.f, cl.h_seg[g], cl.h_seg[g + 1])
        add_hinge_forces(x, xp, 1.0 / dt, cl.h_i, cl.h_k, cl.h_kd, cl.h_rest, st.f, cl.h_seg[2], cl.h_seg[3])
        advance_in_place(x, xp, w, st.f, gravity, keep, dt * dt)
        move_pins(x, pin_idx, pin_from, pin_to, (s + 1.0) / sub_total)
        for g in prange(2):
            _contacts_of_segment(x, w, pts, grid, prm, st, g)
        _contacts_of_segment(x, w, pts, grid, prm, st, 2)
        queries += counts[0, 3] + counts[1, 3] + counts[2, 3]
        st.lam[:] = 0.0
        st.h_lam[:] = 0.0
        st.push[:] = 0.0
        st.push_u[:] = 0.0
        st.push_w[:] = 0.0
        for it in range(prm.iterations):
            hinges = it % prm.hinge_every == 0 or it == prm.iterations - 1
            for g in prange(2):
                _sweep_segment(x, cl, pts, st, g, it, prm.iterations, 1.0 / (dt * dt), hinges, prm.hinge_every)
            _sweep_segment(x, cl, pts, st, 2, it, prm.iterations, 1.0 / (dt * dt), hinges, prm.hinge_every)
        contact_velocity(x, xp, w, st.push, prm.friction, 1.0 - prm.c_contact, st.hot, st.push_u, st.push_w, dt, prm.stick)
    return queries


@njit
def _sweep_segment(x, cl, pts, st, g, it, iterations, at_scale, hinges, hinge_every):
    """Sweep ``it`` of segment ``g``: its hinge constraints (if ``hinges``: a pass of every ``hinge_every``), its
    constraints, then its contacts (step 4). The first and last sweeps visit all constraints and contacts (the
    first lists the active constraints and live contacts), the others those listed; the first and last hinge
    passes visit every hinge constraint, the second lists those still moving, the others visit those."""
    full = it == 0 or it == iterations - 1
    c0, p0 = cl.c_seg[g], pts.p_seg[g]
    counts = st.counts
    if hinges:
        # the first pass answers the substep's own motion (every hinge moves); the second tells which still do
        mode = PASS_ALL if it < hinge_every or it == iterations - 1 else PASS_LIST if it < 2 * hinge_every else \
            PASS_LISTED
        n = project_hinge_range(x, cl.inv_mass, cl.hc_i, cl.hc_alpha, cl.hc_rest, st.h_lam, at_scale, cl.hc_seg[g],
                                cl.hc_seg[g + 1], st.h_active, counts[g, 4], mode)
        if mode == PASS_LIST:
            counts[g, 4] = n
    n = _solve_distances(x, cl.inv_mass, cl.c_i, cl.c_j, cl.c_lo, cl.c_hi, cl.c_alpha, cl.c_relax, cl.c_corner,
                         cl.c_cos_lo, cl.c_cos_hi, cl.c_once, st.lam, at_scale, st.active, st.hot, c0, cl.c_seg[g + 1],
                         counts[g, 2], full, SYMMETRIC and it % 2 == 1)
    if it == 0:
        counts[g, 2] = n
    if full:
        n = solve_contacts(x, cl.inv_mass, pts.pt_v, pts.pt_b, st.c_n, st.c_h, st.c_list, p0, counts[g, 0],
                            st.push, st.c_n2, st.c_nq2, st.c_h2, st.c_live, it == 0, st.c_u, st.push_u, st.push_w)
        if it == 0:
            counts[g, 1] = n
    else:
        solve_contacts(x, cl.inv_mass, pts.pt_v, pts.pt_b, st.c_n, st.c_h, st.c_live, p0, counts[g, 1], st.push,
                        st.c_n2, st.c_nq2, st.c_h2, st.c_live, False, st.c_u, st.push_u, st.push_w)


@njit
def _contacts_of_segment(x, w, pts, grid, prm, st, g):
    """Contact generation (step 3) of segment ``g``'s points; its counts in ``st.counts[g]``."""
    st.counts[g, 0], st.counts[g, 3] = make_contacts(
        x, w, pts.pt_v, pts.pt_b, pts.pt_skin, pts.spheres, grid, prm.use_grid, prm.reach, prm.max_push, prm.reuse,
        st.p_last, st.d_last, st.c_n, st.c_nq, st.c_h, st.c_list, st.c_n2, st.c_nq2, st.c_h2, pts.p_seg[g],
        pts.p_seg[g + 1], pts.body_vel, pts.sphere_vel, st.c_u, pts.body_sag, pts.sag_max, pts.ground)
