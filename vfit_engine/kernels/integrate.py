"""Numba kernels: position Verlet with air damping, and pins moving to their targets.

Position Verlet (Verlet 1967) with a velocity-proportional air damping ``c``::

    x+ = (2 - c) x - (1 - c) x- + a dt^2,    a = w f + g   (w = 1/m; pinned: w = 0, x+ = x)

i.e. ``x+ = x + (1 - c)(x - x-) + a dt^2``. Starting from ``x- = x0 - v0 dt + a0 dt^2 / 2``
makes undamped free fall exact at every step: ``x_n = x0 + v0 t + g t^2 / 2``,
because the second difference of a quadratic is exactly ``g dt^2``.
"""
import numpy as np

from vfit_engine._jit import njit


@njit
def advance_in_place(x, xp, inv_mass, f, gravity, keep, dt2):
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
def move_pins(x, pin_idx, pin_from, pin_to, alpha):
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
