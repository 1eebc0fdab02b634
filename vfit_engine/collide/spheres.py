"""Solid spheres as cloth colliders.

The collider interface shared with the body-mesh collider: an object with
``project(x, x_prev, inv_mass)`` that moves particles out of the solid in place
(``x``, ``x_prev`` C-contiguous float64 (n, 3), m; ``inv_mass`` (n,) 1/kg, pinned
particles have 0 and are left alone). :class:`SphereCollider` also offers
:meth:`~SphereCollider.sphere_arrays`, which lets
:class:`vfit_engine.sim.solver_verlet.SolverVerlet` run it inside its fused
substep kernel instead of calling back into Python every substep.
"""
from __future__ import annotations

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.kernels.collide_sphere import collide_spheres


class SphereCollider:
    """A set of spheres with a skin, friction and restitution.

    Parameters
    ----------
    centres : (s, 3) float, m
    radii : (s,) float, m
    skin : float
        Relative margin: particles closer than ``radius * (1 + skin)`` to a
        centre are pushed out to that distance. This is the seed's radius
        "adjustment factor" ``1 + skin`` (default 1.01): it keeps the straight
        cloth edges between surface particles (chords) out of the true sphere
        and leaves room for the cloth's thickness.
    friction : float
        Cf in [0, 1]: fraction of the tangential displacement removed per
        contact substep (0 slides freely, 1 sticks).
    restitution : float
        Cr in [0, 1]: fraction of the inward normal displacement reflected.

    Attributes
    ----------
    centres : (s, 3) float64, m
        May be reassigned between frames to move the spheres.
    radii : (s,) float64, m
    """

    def __init__(self, centres, radii, skin=0.01, friction=0.5, restitution=0.0):
        centres = np.array(centres, dtype=np.float64, order="C").reshape(-1, 3)
        radii = np.array(radii, dtype=np.float64).ravel()
        if radii.shape[0] != centres.shape[0]:
            raise InputError(f"{centres.shape[0]} sphere centres but {radii.shape[0]} radii")
        if not (np.all(np.isfinite(centres)) and np.all(np.isfinite(radii))) or np.any(radii <= 0):
            raise InputError("sphere centres must be finite and radii finite and > 0")
        for name, value in (("skin", skin), ("friction", friction), ("restitution", restitution)):
            if not (np.isfinite(value) and 0.0 <= value <= (1.0 if name != "skin" else 10.0)):
                raise InputError(f"sphere {name} out of range: {value}")
        self.centres = centres
        self.radii = radii
        self.skin = float(skin)
        self.friction = float(friction)
        self.restitution = float(restitution)

    @property
    def count(self):
        return int(self.radii.shape[0])

    def sphere_arrays(self):
        """Arrays for the fused solver kernel.

        Returns
        -------
        centres : (s, 3) float64, m
        radii : (s,) float64, m
            Effective radii ``radius * (1 + skin)``.
        friction, restitution : (s,) float64
        """
        s = self.count
        return (np.ascontiguousarray(self.centres, dtype=np.float64), self.radii * (1.0 + self.skin),
                np.full(s, self.friction), np.full(s, self.restitution))

    def project(self, x, x_prev, inv_mass):
        """Push particles out of the spheres in place (see
        :mod:`vfit_engine.kernels.collide_sphere` for the formula)."""
        collide_spheres(x, x_prev, inv_mass, *self.sphere_arrays())

    def signed_distance(self, x):
        """Distance of each point to the nearest true sphere surface (no skin), m;
        negative inside. ``x`` (n, 3) -> (n,)."""
        x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
        d = np.linalg.norm(x[:, None, :] - self.centres[None, :, :], axis=2) - self.radii[None, :]
        return d.min(axis=1)
