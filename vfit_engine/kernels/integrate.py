"""Numba kernels: position Verlet with air damping, and the fused cloth substep.

Position Verlet (Verlet 1967) with a velocity-proportional air damping ``c``::

    x+ = (2 - c) x - (1 - c) x- + a dt^2,    a = w f + g   (w = 1/m; pinned: w = 0, x+ = x)

i.e. ``x+ = x + (1 - c)(x - x-) + a dt^2``. Starting from ``x- = x0 - v0 dt + a0 dt^2 / 2``
makes undamped free fall exact at every step: ``x_n = x0 + v0 t + g t^2 / 2``,
because the second difference of a quadratic is exactly ``g dt^2``.

The fused kernel (:data:`substeps_serial` / :data:`substeps_parallel`) runs
whole substeps without leaving compiled code or allocating::

    1. spring forces (scattered per spring, or gathered per vertex from a CSR
       adjacency, race-free, in the parallel kernel) + Verlet  -> x_new
    2. x_prev <- x, x <- x_new;  pinned particles follow their targets
    3. Provot strain limiting, Gauss-Seidel in the given order, a "colour" (a
       group of springs sharing no vertex) at a time; each colour's springs run
       in prange (race-free). One colour holding every spring = plain serial GS.
    4. sphere colliders (projection, friction, restitution)

The two dispatchers compile the same Python function, one with
``parallel=True``; given the same arguments (``gather=True``) they return the
same bytes.

Numba's cache watches only this file: after editing the helpers it inlines
(:mod:`.springs`, :mod:`.strain_limit`, :mod:`.collide_sphere`), delete
``vfit_engine/kernels/__pycache__`` (or touch this file).
"""
import types

import numpy as np

from vfit_engine._jit import njit, prange
from vfit_engine.kernels.collide_sphere import _project_particle_spheres
from vfit_engine.kernels.springs import _spring_forces, _vertex_spring_force
from vfit_engine.kernels.strain_limit import _limit_spring


@njit
def _advance_in_place(x, xp, inv_mass, f, gravity, keep, dt2):
    """One position-Verlet step with air damping, in place (the caller computed the forces ``f``):
    x+ = x + keep (x - x-) + (w f + g) dt^2, x- = x; pinned particles (w = 0) keep their position."""
    for i in range(x.shape[0]):
        w = inv_mass[i]
        for c in range(3):
            xi = x[i, c]
            if w != 0.0:
                x[i, c] = xi + keep * (xi - xp[i, c]) + (w * f[i, c] + gravity[c]) * dt2
            xp[i, c] = xi


@njit
def _move_pins(x, pin_idx, pin_from, pin_to, alpha):
    """Pinned particles at ``alpha`` of the way from ``pin_from`` to ``pin_to`` (linear over a frame)."""
    for p in range(pin_idx.shape[0]):
        i = pin_idx[p]
        for c in range(3):
            x[i, c] = pin_from[p, c] + alpha * (pin_to[p, c] - pin_from[p, c])


@njit
def _integrate_verlet(x, xp, inv_mass, f, gravity, dt, c_air, x_out):
    """One Verlet update into ``x_out`` (n, 3), m; pinned particles keep ``x``."""
    dt2 = dt * dt
    keep = 1.0 - c_air
    for i in range(x.shape[0]):
        w = inv_mass[i]
        if w == 0.0:
            for k in range(3):
                x_out[i, k] = x[i, k]
            continue
        for k in range(3):
            x_out[i, k] = x[i, k] + keep * (x[i, k] - xp[i, k]) + (w * f[i, k] + gravity[k]) * dt2


def integrate_verlet(pos, pos_prev, inv_mass, force, gravity, dt, air_damping=0.0):
    """One damped position-Verlet step (module docstring).

    Parameters
    ----------
    pos, pos_prev : (n, 3) float64, m
    inv_mass : (n,) float64, 1/kg
    force : (n, 3) float64, N
    gravity : (3,) float64, m/s^2
    dt : float, s
    air_damping : float
        ``c`` per step, in [0, 1).

    Returns
    -------
    (n, 3) float64, m
        The new positions (inputs untouched).
    """
    x = np.ascontiguousarray(pos, dtype=np.float64)
    out = np.empty_like(x)
    _integrate_verlet(x, np.ascontiguousarray(pos_prev, dtype=np.float64),
                      np.ascontiguousarray(inv_mass, dtype=np.float64),
                      np.ascontiguousarray(force, dtype=np.float64),
                      np.ascontiguousarray(gravity, dtype=np.float64).ravel(), float(dt), float(air_damping), out)
    return out


def _substeps_impl(x, xp, inv_mass, gravity, gather, si, sj, rest, k, kd,
                   adj_off, adj_j, adj_rest, adj_k, adj_kd,
                   lim_i, lim_j, lim_len, colour_off, iterations, omega,
                   sph_c, sph_r, sph_fric, sph_rest,
                   pin_idx, pin_from, pin_to, dt, c_air, sub_begin, sub_end, sub_total, x_new, f):
    """Substeps ``sub_begin .. sub_end - 1`` of ``sub_total`` (module docstring).

    x, xp : (n, 3) positions now / one step ago, m (in place)
    inv_mass : (n,) 1/kg;  gravity : (3,) m/s^2
    gather : bool -- True: forces gathered per vertex from the CSR arrays (race-free,
        prange-able, each spring evaluated twice); False: scattered once per spring
        (serial, half the work). The two differ only by float summation order.
    si, sj (s,), rest (s,) m, k (s,) N/m, kd (s,) N s/m : springs (scatter form)
    adj_off (n+1,), adj_j (2s,), adj_rest (2s,) m, adj_k (2s,) N/m, adj_kd (2s,) N s/m : CSR form
    lim_i, lim_j (L,), lim_len (L,) m : limited springs in colour order, max lengths
    colour_off (C+1,), iterations, omega : Provot colours, sweeps and over-relaxation
    sph_c (S,3) m, sph_r (S,) m, sph_fric (S,), sph_rest (S,) : sphere colliders
    pin_idx (P,), pin_from, pin_to (P,3) m : pinned particles moved linearly from
        ``pin_from`` (start of substep 0) to ``pin_to`` (end of substep ``sub_total - 1``);
        P = 0 leaves pinned particles where they are
    dt s, c_air per step;  x_new, f (n,3) scratch
    """
    n = x.shape[0]
    inv_dt = 1.0 / dt
    dt2 = dt * dt
    keep = 1.0 - c_air
    g0 = gravity[0]
    g1 = gravity[1]
    g2 = gravity[2]
    n_colours = colour_off.shape[0] - 1
    n_spheres = sph_r.shape[0]
    for s in range(sub_begin, sub_end):
        if gather:
            for i in prange(n):
                w = inv_mass[i]
                if w == 0.0:
                    x_new[i, 0] = x[i, 0]
                    x_new[i, 1] = x[i, 1]
                    x_new[i, 2] = x[i, 2]
                else:
                    f0, f1, f2 = _vertex_spring_force(x, xp, inv_dt, i, adj_off, adj_j, adj_rest, adj_k, adj_kd)
                    x_new[i, 0] = x[i, 0] + keep * (x[i, 0] - xp[i, 0]) + (w * f0 + g0) * dt2
                    x_new[i, 1] = x[i, 1] + keep * (x[i, 1] - xp[i, 1]) + (w * f1 + g1) * dt2
                    x_new[i, 2] = x[i, 2] + keep * (x[i, 2] - xp[i, 2]) + (w * f2 + g2) * dt2
            for i in prange(n):
                xp[i, 0] = x[i, 0]
                xp[i, 1] = x[i, 1]
                xp[i, 2] = x[i, 2]
                x[i, 0] = x_new[i, 0]
                x[i, 1] = x_new[i, 1]
                x[i, 2] = x_new[i, 2]
        else:
            _spring_forces(x, xp, inv_dt, si, sj, rest, k, kd, f)
            # forces are known, so each particle can be advanced in place
            _advance_in_place(x, xp, inv_mass, f, gravity, keep, dt2)
        _move_pins(x, pin_idx, pin_from, pin_to, (s + 1.0) / sub_total)
        for _ in range(iterations):
            for c in range(n_colours):
                start = colour_off[c]
                for q in prange(colour_off[c + 1] - start):
                    e = start + q
                    _limit_spring(x, inv_mass, lim_i[e], lim_j[e], lim_len[e], omega)
        if n_spheres > 0:
            for i in prange(n):
                if inv_mass[i] > 0.0:
                    _project_particle_spheres(x, xp, i, sph_c, sph_r, sph_fric, sph_rest)


def _clone(func, name):
    """A copy of ``func`` under another name, so each dispatcher gets its own cache file."""
    clone = types.FunctionType(func.__code__, func.__globals__, name, func.__defaults__, func.__closure__)
    clone.__qualname__ = name
    clone.__doc__ = func.__doc__
    return clone


#: Fused substeps, serial (prange runs as range).
substeps_serial = njit(_clone(_substeps_impl, "substeps_serial"))
#: Fused substeps with ``parallel=True`` (vertex loops and each colour's springs in prange).
substeps_parallel = njit(parallel=True)(_clone(_substeps_impl, "substeps_parallel"))
