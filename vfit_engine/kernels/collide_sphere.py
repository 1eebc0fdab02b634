"""Numba kernels: particles against solid spheres, by projection (Verlet form).

For each sphere (centre ``c``, effective radius ``R`` = radius x (1 + skin)) and a
free particle at ``x`` with ``x_prev``::

    d = x - c,  r = |d|;   if r < R:
        n = d / r                      (+Y when r == 0: any direction is as good)
        v = x - x_prev                 (this step's displacement, before projection)
        v_n = (v . n) n,   v_t = v - v_n
        v_n' = -Cr v_n  if v . n < 0 (moving inwards)  else  v_n
        x      = c + R n
        x_prev = x - ((1 - Cf) v_t + v_n')

i.e. the particle is put on the inflated surface and its implied velocity
(``x - x_prev``) keeps a fraction ``1 - Cf`` of its tangential part (friction)
and ``Cr`` of its inward normal part, reversed (restitution). Jakobsen (2001),
"Advanced character physics", for projection with Verlet; Bridson et al. (2002)
for the normal/tangential split. Cf applies per substep.
"""
import math

import numpy as np

from vfit_engine._jit import njit


@njit
def place_on_surface(x, xp, i, q0, q1, q2, n0, n1, n2, friction, restitution):
    """Move particle ``i`` to the surface point q with outward normal n; its Verlet velocity
    ``v = x - xp`` is split into normal and tangential parts: an inward normal part is reflected
    by ``restitution`` (0: inelastic), the tangential part keeps ``1 - friction`` of itself."""
    v0 = x[i, 0] - xp[i, 0]
    v1 = x[i, 1] - xp[i, 1]
    v2 = x[i, 2] - xp[i, 2]
    vn = v0 * n0 + v1 * n1 + v2 * n2
    t0 = v0 - vn * n0
    t1 = v1 - vn * n1
    t2 = v2 - vn * n2
    if vn < 0.0:
        vn = -restitution * vn
    keep = 1.0 - friction
    x[i, 0] = q0
    x[i, 1] = q1
    x[i, 2] = q2
    xp[i, 0] = q0 - (keep * t0 + vn * n0)
    xp[i, 1] = q1 - (keep * t1 + vn * n1)
    xp[i, 2] = q2 - (keep * t2 + vn * n2)


@njit
def radial_exit(x0, x1, x2, c0, c1, c2, radius):
    """The point of the sphere (centre c, ``radius``) straight out from its centre through x, and
    the outward normal there (+Y for a point at the centre)."""
    d0 = x0 - c0
    d1 = x1 - c1
    d2 = x2 - c2
    r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if r > 0.0:
        n0 = d0 / r
        n1 = d1 / r
        n2 = d2 / r
    else:
        n0 = 0.0
        n1 = 1.0
        n2 = 0.0
    return c0 + radius * n0, c1 + radius * n1, c2 + radius * n2, n0, n1, n2


@njit
def _project_particle_spheres(x, xp, i, centres, radii, friction, restitution):
    """Project particle ``i`` out of every sphere it is inside (in place)."""
    for s in range(radii.shape[0]):
        d0 = x[i, 0] - centres[s, 0]
        d1 = x[i, 1] - centres[s, 1]
        d2 = x[i, 2] - centres[s, 2]
        r2 = d0 * d0 + d1 * d1 + d2 * d2
        big_r = radii[s]
        if r2 >= big_r * big_r:
            continue
        q0, q1, q2, n0, n1, n2 = radial_exit(x[i, 0], x[i, 1], x[i, 2], centres[s, 0], centres[s, 1],
                                             centres[s, 2], big_r)
        place_on_surface(x, xp, i, q0, q1, q2, n0, n1, n2, friction[s], restitution[s])


@njit
def _collide_spheres(x, xp, inv_mass, centres, radii, friction, restitution):
    """Project every free particle (inv_mass > 0) out of every sphere, serially."""
    for i in range(x.shape[0]):
        if inv_mass[i] > 0.0:
            _project_particle_spheres(x, xp, i, centres, radii, friction, restitution)


def collide_spheres(pos, pos_prev, inv_mass, centres, radii, friction, restitution):
    """Project particles out of spheres in place (see module docstring).

    Parameters
    ----------
    pos, pos_prev : (n, 3) float64, m
        C-contiguous float64, modified in place.
    inv_mass : (n,) float64, 1/kg
        Pinned particles (0) are left alone.
    centres : (s, 3) float64, m
    radii : (s,) float64, m
        Effective radii (skin included).
    friction, restitution : (s,) float64
        Per-sphere Cf and Cr in [0, 1].
    """
    for a in (pos, pos_prev):
        if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and a.ndim == 2):
            raise TypeError("pos and pos_prev must be C-contiguous float64 (n, 3) arrays (modified in place)")
    _collide_spheres(pos, pos_prev, np.ascontiguousarray(inv_mass, dtype=np.float64),
                     np.ascontiguousarray(centres, dtype=np.float64).reshape(-1, 3),
                     np.ascontiguousarray(radii, dtype=np.float64).ravel(),
                     np.ascontiguousarray(friction, dtype=np.float64).ravel(),
                     np.ascontiguousarray(restitution, dtype=np.float64).ravel())
