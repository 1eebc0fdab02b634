"""A cloth solver's contacts with a body that moves (:class:`BodyMotion`): both solvers take the body's motion the
same way, so an animation's loop (:mod:`vfit_engine.animate.loop`) does not ask which one it drives."""
from __future__ import annotations

import math

import numpy as np


class BodyMotion:
    """The moving body's side of a solver's contacts, shared by :class:`~vfit_engine.sim.solver_verlet.SolverVerlet`
    and :class:`~vfit_engine.sim.solver_pd.SolverPD` (a base class: each solver's ``_set_contacts`` makes the
    arrays it updates: ``_grid``, ``_spheres``, ``_p_last``, ``_d_last``, ``_pt_skin``, ``_body_vel``,
    ``_sphere_vel``, ``_c_u``, ``_push_u``, ``_push_w``)."""

    def body_moved(self, distance, spheres=None, velocity=None, sphere_velocity=None):
        """The body moved since the last step: take its grid again (``self.body.grid``; a moving body's collider
        makes one per frame) and, given ``spheres`` (S, 4) m, the sphere colliders' new centres and radii.

        ``distance`` (m) bounds how far the body moved: a number, or a function of points (k, 3) m giving the
        bound near each (the contact points are looked up where they were last queried). A point proven clear
        of the body is proven that much less clear, and one that was touching it queries it afresh where the
        body moved more than ``contact.reuse`` (the tangent plane it kept moved with the body).

        ``velocity`` (V, 3) m/s, the body mesh's vertices' velocity during the coming steps (the grid's vertex
        numbering), and ``sphere_velocity`` (S, 3) m/s, the spheres': the contacts' friction, damping and
        inelastic push then act on the cloth's velocity relative to the body's at the contact, so a moving limb
        carries the cloth it touches (:mod:`vfit_engine.kernels.cloth`, step 5; the projective solver's friction
        in its iterations too, :func:`vfit_engine.kernels.pd.contact_friction`). Once given, they stay until
        given again. Nothing here changes a solver's matrix: a moving body costs no refactor.
        """
        if self.body is not None:
            self._grid = self.body.grid
        if spheres is not None:
            spheres = np.array(spheres, dtype=np.float64, order="C")  # its own copy
            if spheres.shape != self._spheres.shape:
                raise ValueError(f"spheres must have shape {self._spheres.shape}, got {spheres.shape}")
            self._spheres = spheres
        if velocity is not None:
            velocity = np.ascontiguousarray(velocity, dtype=np.float64)
            if velocity.ndim != 2 or velocity.shape[1] != 3 or self.body is None:
                raise ValueError("velocity must have shape (V, 3), the body mesh's vertices'")
            self._body_vel = velocity
        if sphere_velocity is not None:
            sphere_velocity = np.array(sphere_velocity, dtype=np.float64, order="C")
            if sphere_velocity.shape != (self._spheres.shape[0], 3):
                raise ValueError(f"sphere_velocity must have shape ({self._spheres.shape[0]}, 3)")
            self._sphere_vel = sphere_velocity
        if (self._body_vel.shape[0] or self._sphere_vel.shape[0]) and not self._push_w.shape[0]:
            n, p = self.model.particle_count, self.points.count
            self._c_u, self._push_u, self._push_w = np.zeros((p, 3)), np.zeros((n, 3)), np.zeros(n)
        d = distance(self._p_last) if callable(distance) else float(distance)
        self._d_last -= d
        self._d_last[(self._d_last < self._pt_skin + self.contact.reach) & (d > self.contact.reuse)] = -math.inf
