"""Numba kernel: cloth substeps with body-mesh contacts solved jointly with strain limiting.

Per substep (Jakobsen 2001; Mueller et al. 2007, "Position based dynamics", contacts as
inequality constraints solved in the same Gauss-Seidel loop as the stretch constraints)::

    1. damped Hooke springs + gravity, position Verlet with air damping
    2. pinned particles follow their targets
    3. contact generation: every free particle that may be within ``skin + reach`` of the
       body gets its closest point q and outward normal n from the exact mesh query
       (:func:`vfit_engine.kernels.collide_mesh._query_point`) and the half-space constraint
           n . (x - q) >= min(skin, d + max_push)       (d the signed distance now)
       -- a particle inside comes out by at most ``max_push`` per substep;
    4. ``iterations`` x { one Provot sweep over the limited springs (Provot 1995);
                          project every contact particle onto its half-space }
    5. contact velocity: the push adds no velocity; the approaching normal velocity is
       removed (inelastic) and the tangential velocity shrinks by ``friction`` times that
       normal change (Coulomb), never reversing.

Solving both constraint sets in one loop is what lets cloth in a concave crease (the
armpit) settle: when the limiter and the collider run one after the other each undoes
the other and the cloth jitters.

Contact generation is skipped for particles proven clear: the signed distance is
1-Lipschitz, so a particle whose last query found ``d_last`` (from ``x_last``) is still
at least ``d_last - |x - x_last|`` from the body. A particle in contact that has moved less
than ``reuse`` since its last query keeps that query's tangent plane (n, n . q) and its
distance is taken from the plane: cloth resting on the skin barely moves, and on a surface
whose triangles are ~1 cm the plane's error over ``reuse`` = 0.5 mm is below a micrometre,
while the exact query is most of a settled substep's cost.

Numba's cache watches only this file: after editing the helpers it inlines
(:mod:`.springs`, :mod:`.strain_limit`, :mod:`.collide_mesh`), delete
``vfit_engine/kernels/__pycache__`` (or touch this file).
"""
import math

from vfit_engine._jit import njit
from vfit_engine.kernels.collide_mesh import _query_point
from vfit_engine.kernels.integrate import _advance_in_place, _move_pins
from vfit_engine.kernels.springs import _spring_forces
from vfit_engine.kernels.strain_limit import _limit_spring


@njit
def drape_substeps(x, xp, inv_mass, gravity, si, sj, rest, k, kd, lim_i, lim_j, lim_len, iterations, omega,
                   pin_idx, pin_from, pin_to, dt, c_air, sub_begin, sub_end, sub_total, grid,
                   skin, reach, friction, max_push, c_contact, reuse,
                   x_last, d_last, c_n, c_nq, c_h, c_push, c_list, f):
    """Substeps ``sub_begin .. sub_end - 1`` of ``sub_total`` (module docstring); returns mesh queries made.

    Parameters
    ----------
    x, xp : (n, 3) float64, m
        Positions now / one step ago (in place).
    inv_mass : (n,) float64, 1/kg;  gravity : (3,) float64, m/s^2
    si, sj : (s,) int64;  rest : (s,) m;  k : (s,) N/m;  kd : (s,) N s/m
        Springs.
    lim_i, lim_j : (L,) int64;  lim_len : (L,) float64, m
        Limited springs in sweep order and their longest allowed lengths.
    iterations : int;  omega : float
        Joint constraint iterations per substep and over-relaxation of the limiter.
    pin_idx : (P,) int64;  pin_from, pin_to : (P, 3) float64, m
        Pinned particles move linearly from ``pin_from`` (start of substep 0) to ``pin_to``
        (end of substep ``sub_total - 1``).
    dt : float, s;  c_air : float
        Substep and air damping per step.
    grid : BodyGrid
        The body (:data:`vfit_engine.kernels.collide_mesh.BodyGrid`).
    skin, reach : float, m
        Clearance kept from the body; contacts are made for particles within ``skin + reach``.
    friction : float;  max_push : float, m
        Coulomb coefficient; longest push out of the body per substep.
    c_contact : float
        Extra tangential velocity decay per substep of particles the body pushed (viscous
        contact damping, so cloth resting on skin comes to rest).
    reuse : float, m
        A particle in contact that moved less than this since its last query reuses that
        query's plane (0: query every substep).
    x_last : (n, 3) float64, m;  d_last : (n,) float64, m
        Position and signed distance (a lower bound) at each particle's last query
        (in/out; ``d_last = -inf`` forces a query).
    c_n : (n, 3);  c_nq : (n,) m
        Normal and ``n . q`` of each particle's last query (in/out: the reused planes).
    c_h : (n,) m;  c_push : (n,) m;  c_list : (n,) int64;  f : (n, 3)
        Scratch: plane offsets, accumulated pushes, contact list, forces.
    """
    n = x.shape[0]
    inv_dt = 1.0 / dt
    dt2 = dt * dt
    keep = 1.0 - c_air
    band = skin + reach
    query_out = band + 4.0 * reach  # a looser band makes the clear-distance cache last longer
    queries = 0
    for s in range(sub_begin, sub_end):
        _spring_forces(x, xp, inv_dt, si, sj, rest, k, kd, f)
        _advance_in_place(x, xp, inv_mass, f, gravity, keep, dt2)
        _move_pins(x, pin_idx, pin_from, pin_to, (s + 1.0) / sub_total)

        n_contacts = 0
        for i in range(n):
            if inv_mass[i] <= 0.0:
                continue
            mx = x[i, 0] - x_last[i, 0]
            my = x[i, 1] - x_last[i, 1]
            mz = x[i, 2] - x_last[i, 2]
            moved = math.sqrt(mx * mx + my * my + mz * mz)
            if d_last[i] - moved >= band:
                continue
            if moved < reuse and -math.inf < d_last[i] < band:
                # the last query's plane still holds (module docstring)
                d = c_n[i, 0] * x[i, 0] + c_n[i, 1] * x[i, 1] + c_n[i, 2] * x[i, 2] - c_nq[i]
                c_h[i] = c_nq[i] + min(skin, d + max_push)
                c_push[i] = 0.0
                c_list[n_contacts] = i
                n_contacts += 1
                continue
            d, qx, qy, qz, nx, ny, nz, t = _query_point(x[i, 0], x[i, 1], x[i, 2], grid, True, query_out, math.inf)
            queries += 1
            x_last[i, 0], x_last[i, 1], x_last[i, 2] = x[i, 0], x[i, 1], x[i, 2]
            if t < 0:
                d_last[i] = query_out
                continue
            d_last[i] = d
            if d >= band:
                continue
            c_n[i, 0], c_n[i, 1], c_n[i, 2] = nx, ny, nz
            c_nq[i] = nx * qx + ny * qy + nz * qz
            c_h[i] = c_nq[i] + min(skin, d + max_push)
            c_push[i] = 0.0
            c_list[n_contacts] = i
            n_contacts += 1

        n_lim = lim_i.shape[0]
        for _ in range(iterations):
            for e in range(n_lim):
                _limit_spring(x, inv_mass, lim_i[e], lim_j[e], lim_len[e], omega)
            for m in range(n_contacts):
                i = c_list[m]
                gap = c_h[i] - (c_n[i, 0] * x[i, 0] + c_n[i, 1] * x[i, 1] + c_n[i, 2] * x[i, 2])
                if gap > 0.0:
                    x[i, 0] += gap * c_n[i, 0]
                    x[i, 1] += gap * c_n[i, 1]
                    x[i, 2] += gap * c_n[i, 2]
                    c_push[i] += gap

        for m in range(n_contacts):
            i = c_list[m]
            push = c_push[i]
            if push <= 0.0:
                continue
            nx, ny, nz = c_n[i, 0], c_n[i, 1], c_n[i, 2]
            vx, vy, vz = x[i, 0] - xp[i, 0], x[i, 1] - xp[i, 1], x[i, 2] - xp[i, 2]
            vn = vx * nx + vy * ny + vz * nz
            tx, ty, tz = vx - vn * nx, vy - vn * ny, vz - vn * nz
            vn_in = vn - push
            vn_new = max(vn_in, 0.0)
            vt = math.sqrt(tx * tx + ty * ty + tz * tz)
            scale = 0.0
            if vt > 0.0:
                scale = (1.0 - c_contact) * max(0.0, vt - friction * (vn_new - vn_in)) / vt
            xp[i, 0] = x[i, 0] - (vn_new * nx + scale * tx)
            xp[i, 1] = x[i, 1] - (vn_new * ny + scale * ty)
            xp[i, 2] = x[i, 2] - (vn_new * nz + scale * tz)
    return queries
