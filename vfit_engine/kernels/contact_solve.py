"""Numba kernel helpers: contact half-spaces solved (step 4 of :mod:`vfit_engine.kernels.cloth`) and the contact
velocity after them (step 5), shared by the cloth solvers.

A contact point p = sum_k b_k x_k with gap g > 0 below its half-space moves its vertices by
``dx_k = w_k b_k g n / sum_j w_j b_j^2`` (the point-triangle constraint of PBD): a triangle that
spans a body bump between its vertices is pushed out as a whole. The arrays are those of
:data:`vfit_engine.kernels.cloth.ContactPoints` and ``ContactState``.
"""
import math

from vfit_engine._jit import njit
from vfit_engine.kernels.contact_make import contact_point

#: A contact point more than this (m) clear of its half-space(s) after a substep's first sweep is
#: left to the last one (surface points between resting vertices mostly are).
ACTIVE_GAP = 0.0005
#: A vertex the contacts pushed out by more than this (m) in a substep is pressed into the body by its own
#: cloth's tension (resting cloth is pushed ~g dt^2 = 0.04 mm): its constraints stay in the next substep's
#: middle sweeps. There the contacts move the cloth millimetres per sweep and constraints well inside their
#: bands at the first sweep leave them in the middle ones; listed or not by a hair from one substep to the
#: next, they kept a period-6-substep cycle of the cloth round them that never settled (a top stretched
#: 24-37 % over the bust of a body 8 cm wider than it was made for).
PUSH_HOT = 0.0002


@njit
def solve_contacts(x, inv_mass, v, b, c_n, c_h, c_list, start, n_c, push, c_n2, c_nq2, c_h2, c_live, first, c_u,
                   push_u, push_w):
    """Project the contact points ``c_list[start:start + n_c]`` onto their half-space(s), spreading each
    move over its vertices. The ``first`` sweep lists in ``c_live`` (from ``start``) the points that were
    below or within ``ACTIVE_GAP`` of a half-space and returns their count (else returns ``n_c``). With
    ``c_u`` (not empty) each move also adds |move| times the body's velocity at the point to ``push_u`` and
    |move| to ``push_w``."""
    n_live = 0
    for m in range(start, start + n_c):
        p = c_list[m]
        gap = push_point(x, inv_mass, v, b, p, c_n[p, 0], c_n[p, 1], c_n[p, 2], c_h[p], push, c_u, push_u, push_w)
        if c_nq2[p] == c_nq2[p]:
            gap = max(gap, push_point(x, inv_mass, v, b, p, c_n2[p, 0], c_n2[p, 1], c_n2[p, 2], c_h2[p], push, c_u,
                                      push_u, push_w))
        if first and gap > -ACTIVE_GAP:
            c_live[start + n_live] = p
            n_live += 1
    return n_live if first else n_c


@njit(inline="always")
def push_point(x, inv_mass, v, b, p, nx, ny, nz, h, push, c_u, push_u, push_w):
    """Move point ``p`` onto the half-space n . p >= h (if outside it), spread over its vertices;
    returns the gap h - n . p it had (m; > 0: it was pushed). Weighs the body's velocity ``c_u[p]`` into
    ``push_u`` / ``push_w`` when ``c_u`` is not empty (:func:`solve_contacts`)."""
    px, py, pz = contact_point(x, v, b, p)
    gap = h - (nx * px + ny * py + nz * pz)
    if gap <= 0.0:
        return gap
    den = 0.0
    for k in range(3):
        den += inv_mass[v[p, k]] * b[p, k] * b[p, k]
    if den <= 0.0:
        return gap
    s = gap / den
    for k in range(3):
        ik = v[p, k]
        dk = inv_mass[ik] * b[p, k] * s
        if dk == 0.0:
            continue
        x[ik, 0] += dk * nx
        x[ik, 1] += dk * ny
        x[ik, 2] += dk * nz
        push[ik, 0] += dk * nx
        push[ik, 1] += dk * ny
        push[ik, 2] += dk * nz
        if c_u.shape[0] > 0:
            push_u[ik, 0] += dk * c_u[p, 0]
            push_u[ik, 1] += dk * c_u[p, 1]
            push_u[ik, 2] += dk * c_u[p, 2]
            push_w[ik] += dk
    return gap


@njit
def contact_velocity(x, xp, inv_mass, push, friction, keep_t, hot, push_u, push_w, dt, stick):
    """Contact velocity (step 5) of every pushed vertex; ``push`` (n, 3) is its summed push, m. Marks
    in ``hot`` the vertices pushed more than ``PUSH_HOT``.

    Velocities are displacements over the step ``dt`` relative to the body's: ``push_u / push_w`` (m/s,
    :func:`solve_contacts`) where ``push_w`` is not empty, else 0 (a still body). With ``stick`` the
    tangential slip is taken back as far as friction stops it (module docstring, step 5)."""
    moving = push_w.shape[0] > 0
    for i in range(x.shape[0]):
        p0, p1, p2 = push[i, 0], push[i, 1], push[i, 2]
        amount = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        hot[i] = amount > PUSH_HOT
        if amount <= 0.0 or inv_mass[i] <= 0.0:
            continue
        ux = uy = uz = 0.0
        if moving and push_w[i] > 0.0:
            s = dt / push_w[i]
            ux, uy, uz = push_u[i, 0] * s, push_u[i, 1] * s, push_u[i, 2] * s
        nx, ny, nz = p0 / amount, p1 / amount, p2 / amount
        vx, vy, vz = x[i, 0] - xp[i, 0] - ux, x[i, 1] - xp[i, 1] - uy, x[i, 2] - xp[i, 2] - uz
        vn = vx * nx + vy * ny + vz * nz
        tx, ty, tz = vx - vn * nx, vy - vn * ny, vz - vn * nz
        vn_in = vn - amount  # the normal velocity before the push
        vn_new = max(vn_in, 0.0)
        vt = math.sqrt(tx * tx + ty * ty + tz * tz)
        scale = 0.0
        if vt > 0.0:
            slide = max(0.0, vt - friction * (vn_new - vn_in))
            scale = keep_t * slide / vt
            if stick:
                back = 1.0 - slide / vt
                x[i, 0] -= back * tx
                x[i, 1] -= back * ty
                x[i, 2] -= back * tz
        xp[i, 0] = x[i, 0] - (ux + vn_new * nx + scale * tx)
        xp[i, 1] = x[i, 1] - (uy + vn_new * ny + scale * ty)
        xp[i, 2] = x[i, 2] - (uz + vn_new * nz + scale * tz)
