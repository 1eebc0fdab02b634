"""Projective-dynamics cloth solver: a few global iterations a step, each of which couples the whole garment.

``SolverPD(model, settings, contact=..., body=..., points=...)`` advances a :class:`~vfit_engine.sim.state.State`
as :class:`~vfit_engine.sim.solver_verlet.SolverVerlet` does, with the same constraints
(:mod:`vfit_engine.sim.constraints`: banded stretch, bend limits, corner angle limits, shear springs), hinges,
contacts, pins and friction, but solved by projective dynamics (:mod:`vfit_engine.kernels.pd`): every step
predicts the inertial motion, makes the contacts once, then ``iterations`` times updates the contact forces
(Uzawa), projects every element onto its allowed set (the local step) and solves one sparse SPD system for all
vertices at once (the global step, :mod:`vfit_engine.sim.linear`: factored once a drape, its bands' weights
refactored as the set of bands that act changes, ``PDSettings.band_weight``); the contact velocity is then taken
as the Verlet solver takes it (:func:`vfit_engine.kernels.contact_solve.contact_velocity`). A correction no longer
travels one edge a sweep: one solve carries it over the garment. Not yet the product's solver: where it stands,
what was tried and what is next are in ``docs/solver.md``.

A moving body (:meth:`body_moved`, the Verlet solver's interface: :class:`~vfit_engine.sim.body_motion.BodyMotion`):
the contacts of each step are made against the body where it is then, and the skin's velocity under each vertex
its contact points touch (:func:`vfit_engine.kernels.pd.contact_body_velocity`) enters the friction of the
iterations and the contact velocity, so skin that moves carries the cloth on it; the matrix does not depend on the
body and is not refactored for it.

What lies where: the stretch bands, shear diagonals, bend limits and bend springs and the corner angles (on the
polygons' own edges) are in the matrix; the hinges (four vertices: they would fill the factor) act as forces
evaluated at the iterate, with a diagonal that bounds their stiffness (:mod:`vfit_engine.kernels.pd`). The pair
elements' stiffness-proportional damping (``PDSettings.stiffness_damping``; a drape's 1 ms) is implicit: its
weight is in the matrix and its pull towards the step's start in the prediction
(:func:`vfit_engine.kernels.pd_matrix.add_damping_target`).

Quasi-Newton iterations (``PDSettings.history``; :meth:`_iterate_qn`, :mod:`vfit_engine.kernels.lbfgs`): the plain
iterations converge in the cloth's turning modes at ~1e-4 an iteration (the matrix's pair elements have no
direction), and a step that stops after a few ends where they have just undone its ``g h^2``: a still state that is
not the equilibrium (a hinge's wing at 61.9 deg where it rests at 1.07). L-BFGS on the same matrix learns those
modes from the iterates; the iterations start from the prediction without ``g h^2``, so that a still state is one
the iterations keep -- the equilibrium. ``PDSettings.edge_compression`` moves the bend springs' compression share
onto the edges, where it does not resist bending (docs/solver.md).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import sparse

from vfit_engine.collide.body_mesh import empty_grid
from vfit_engine.kernels.bending import hinge_scratch
from vfit_engine.kernels.contact_make import make_contacts
from vfit_engine.kernels.contact_solve import contact_velocity, solve_contacts
from vfit_engine.kernels.integrate import advance_in_place, move_pins
from vfit_engine.kernels.lbfgs import (dot3, first_loop, gradient, max_move, pair_energy, push_pair, second_loop,
                                      uzawa_energy)
from vfit_engine.kernels.pd import (chebyshev, contact_body_velocity, contact_forces, contact_friction, pd_rhs,
                                   soft_push)
from vfit_engine.kernels.pd_matrix import acting_bands, add_damping_target, band_matrix
from vfit_engine.kernels.supernodal_ldl import sn_solve3
from vfit_engine.sim.bending import hinge_gradient_norms
from vfit_engine.sim.body_motion import BodyMotion
from vfit_engine.sim.constraints import KIND_ANGLE, KIND_BEND, build_constraints, stretch_rigidity
from vfit_engine.sim.contact_points import body_sag, contact_points
from vfit_engine.sim.linear import SPDFactor
from vfit_engine.sim.materials import COMPRESSION_SHARE
from vfit_engine.sim.solver_settings import ContactSettings, PDSettings
from vfit_engine.sim.springs import BEND, STRUCTURAL
from vfit_engine.sim.state import State


class SolverPD(BodyMotion):
    """Cloth solver (module docstring); the parameters are :class:`SolverVerlet`'s, ``settings`` a
    :class:`~vfit_engine.sim.solver_settings.PDSettings`."""

    def __init__(self, model, settings=None, contact=None, body=None, spheres=None, points=None, colliders=(),
                 ground=None):
        self.model = model
        self.settings = settings or PDSettings()
        self.contact = contact or ContactSettings()
        self.colliders = list(colliders)
        if ground is not None and not math.isfinite(ground):
            raise ValueError(f"ground must be a finite height or None, got {ground!r}")
        self._ground = -math.inf if ground is None else float(ground)
        self.max_push = math.inf
        self.contact_queries = 0
        # what the Verlet solver reports of its explicit step (nothing is softened here)
        self.softened_fraction = self.stiff_hinges = self.implicit_hinges = self.softened_hinges = 0.0
        self.bending_kept = 1.0
        n = model.particle_count
        self._inv_mass = np.ascontiguousarray(model.inv_mass, dtype=np.float64).copy()
        self._gravity = np.ascontiguousarray(self.settings.gravity, dtype=np.float64)
        self._con = build_constraints(model, self.settings)
        self.points = points if points is not None else contact_points(np.zeros(0, np.int64), np.zeros(1, np.int64),
                                                                       model.rest_pos, surface=False)
        self._set_contacts(body, spheres)
        self._pins = np.ascontiguousarray(model.pin_indices, dtype=np.int64)
        self._pin_from = np.zeros((model.pin_count, 3))
        self._no_pins, self._no_pin_pos = np.zeros(0, np.int64), np.zeros((0, 3))
        self._y, self._xh, self._xprev, self._b = (np.zeros((n, 3)) for _ in range(4))
        self._g, self._g0, self._g0_old = (np.zeros((n, 3)) for _ in range(3))
        #: how often the quasi-Newton iterations dropped their history (PDSettings.history; _iterate_qn)
        self.qn_restarts = 0
        self._gap, self._push, self._zero_f = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
        self._count = np.zeros(n)
        self._f_lag = np.zeros((n, 3))
        self._work = np.zeros((n, 3))
        self._hinge_work = hinge_scratch()
        self._lam, self._nrm, self._plane = np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3))
        self._acc_g, self._acc_n, self._acc_w = np.zeros(n), np.zeros((n, 3)), np.zeros(n)
        self.refactors = 0
        self._hot = np.zeros(n, dtype=np.bool_)
        self._dt = None
        self._factor = None
        self._seams = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), 0.0)

    # -- set-up -------------------------------------------------------------------------
    def _set_contacts(self, body, spheres):
        p = self.points.count
        self.body = body
        if body is None:
            self._grid = empty_grid()
        elif hasattr(body, "grid"):
            self._grid = body.grid
        else:
            raise TypeError("body must be a MeshCollider (it has the grid the kernel queries)")
        self._spheres = np.zeros((0, 4)) if spheres is None else np.ascontiguousarray(spheres, dtype=np.float64)
        if self._spheres.ndim != 2 or self._spheres.shape[1] != 4:
            raise ValueError("spheres must have shape (S, 4): centre and radius")
        skin = np.full(p, self.contact.surface_skin)
        skin[:self.points.vertex_count] = self.contact.skin
        self._pt_v = np.ascontiguousarray(self.points.verts, dtype=np.int64)
        self._pt_b = np.ascontiguousarray(self.points.bary, dtype=np.float64)
        self._pt_skin = skin
        self._p_last, self._d_last = np.zeros((p, 3)), np.full(p, -np.inf)
        self._c_n, self._c_nq, self._c_h = np.zeros((p, 3)), np.zeros(p), np.zeros(p)
        self._c_list = np.zeros(p, dtype=np.int64)
        self._c_n2, self._c_nq2, self._c_h2 = np.zeros((p, 3)), np.full(p, np.nan), np.zeros(p)
        self._c_live = np.zeros(p, dtype=np.int64)
        self._c_u, self._push_u, self._push_w = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
        self._body_vel, self._sphere_vel = np.zeros((0, 3)), np.zeros((0, 3))
        self._body_sag = body_sag(body, self.points, self.contact)
        self._sag_max = float(self._body_sag.max(initial=0.0))

    def sweep_from(self, vertices):
        """Nothing to do: the global step couples every vertex at once, in no order (kept for the Verlet
        solver's callers)."""

    def allow_stretch(self, vertices, strain):
        """Let the cloth among ``vertices`` stretch freely up to ``strain`` (as :meth:`SolverVerlet.allow_stretch`)."""
        inside = np.zeros(self.model.particle_count, dtype=bool)
        inside[np.asarray(vertices, dtype=np.int64)] = True
        self._con.open_bands(inside, strain)
        self._dt = None

    def sew(self, pairs, length=0.0, weight=1.0):
        """Pull the vertex pairs ``pairs`` (s, 2) of seams together: each pair an element of the matrix free
        between lengths 0 and ``length`` (m; scalar or (s,)) and beyond with ``weight`` times the typical yarn's
        stiffness. Called again, it replaces the seams (a sewing shortens ``length`` to 0 as it closes them);
        the matrix is refactored at the next step."""
        p = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        hi = np.broadcast_to(np.asarray(length, dtype=np.float64), (p.shape[0],)).copy()
        if p.size and (p.min() < 0 or p.max() >= self.model.particle_count or np.any(p[:, 0] == p[:, 1])):
            raise ValueError("a seam pair refers to a vertex that does not exist, or joins a vertex to itself")
        if np.any(hi < 0) or not (weight > 0):
            raise ValueError("seam lengths must be >= 0 and the weight > 0")
        self._seams = (p[:, 0].copy(), p[:, 1].copy(), hi, float(weight))
        self._dt = None

    def close_seams(self, length):
        """Let the seams be at most ``length`` (m; scalar or (s,)) long from the next step on, without a refactor:
        the band re-weighing (``PDSettings.band_weight``) follows which seams are at their length."""
        hi = self._seams[2]
        hi[:] = np.broadcast_to(np.asarray(length, dtype=np.float64), hi.shape)
        if self._dt is not None and hi.size:
            at = self._seam_at
            self._arrays[6][at:at + hi.size] = hi
            self._pairs["hi"][at:at + hi.size] = hi

    def weigh(self, gravity=1.0):
        """Scale gravity by ``gravity`` from the next step on (0 while a sewing closes the seams)."""
        self._gravity = np.ascontiguousarray(np.asarray(self.settings.gravity, dtype=np.float64) * float(gravity))
        if self._dt is not None:
            self._gravity_step()

    def admit(self, pos, vertices):
        """Widen the bands among ``vertices`` to admit their lengths at ``pos`` (as :meth:`SolverVerlet.admit`)."""
        inside = np.zeros(self.model.particle_count, dtype=bool)
        inside[np.asarray(vertices, dtype=np.int64)] = True
        self._con.admit(pos, inside)
        self._dt = None

    # -- the elements and the matrix --------------------------------------------------------------
    def _elements(self, dt):
        """The local step's element arrays (:func:`vfit_engine.kernels.pd.pd_rhs`, after ``x0, y``) and the
        matrix they make at step ``dt``."""
        m, con, st = self.model, self._con, self.settings
        n = m.particle_count
        free = self._inv_mass > 0
        mass = np.where(free, np.asarray(m.mass, dtype=np.float64), 0.0)
        mh2 = self._mh2 = mass / (dt * dt)
        k_typ = stretch_rigidity(m) / float(np.median(m.spring_rest[m.spring_type == STRUCTURAL])) \
            if np.any(m.spring_type == STRUCTURAL) else 1.0
        dist = con.corner < 0
        # the bend limits and bend springs join second neighbours: in A they double its factor's fill, outside it
        # their diagonal slows every smooth mode (bend_in_matrix)
        soft = dist & (con.kind == KIND_BEND) & (not st.bend_in_matrix)
        in_a = dist & ~soft & (con.alpha > 0)
        (e_i, e_j, e_lo, e_hi, e_w), bend_sp = self._distance_elements(in_a)
        seam_i, seam_j, seam_hi, seam_w = self._seams
        self._seam_at = e_i.size
        if seam_i.size:  # the seams join the pair elements (sew)
            e_i, e_j = np.concatenate([e_i, seam_i]), np.concatenate([e_j, seam_j])
            e_lo, e_hi = np.concatenate([e_lo, np.zeros(seam_i.size)]), np.concatenate([e_hi, seam_hi])
            e_w = np.concatenate([e_w, np.full(seam_i.size, seam_w * k_typ)])
        ang = np.flatnonzero(con.kind == KIND_ANGLE)
        a_w = np.full(ang.size, st.angle_weight * k_typ)
        s_i = np.concatenate([con.i[soft], m.spring_indices[bend_sp, 0]]).astype(np.int64)
        s_j = np.concatenate([con.j[soft], m.spring_indices[bend_sp, 1]]).astype(np.int64)
        s_lo = np.concatenate([con.lo[soft], m.spring_rest[bend_sp]])
        s_hi = np.concatenate([con.hi[soft], m.spring_rest[bend_sp]])
        s_w = np.concatenate([1.0 / con.alpha[soft], m.spring_k[bend_sp]])
        d_off = np.bincount(s_i, 2.0 * s_w, n).astype(np.float64) + np.bincount(s_j, 2.0 * s_w, n)
        h = m.hinges
        if h is not None and h.count:
            h_i, h_k, h_rest = h.indices, np.asarray(h.k, dtype=np.float64), h.rest_angle
            g = hinge_gradient_norms(h_i, m.rest_pos)
            d_off += np.bincount(h_i.ravel(), (h_k[:, None] * g * g.sum(axis=1, keepdims=True)).ravel(), n)
        else:
            h_i, h_k, h_rest = np.zeros((0, 4), np.int64), np.zeros(0), np.zeros(0)
        self._w_lo = st.contact_weight * k_typ
        # the matrix: mass, diagonal of the forces outside it, contact weight, and the pair elements
        pi = np.concatenate([e_i, con.corner[ang], con.corner[ang]])
        pj = np.concatenate([e_j, con.i[ang], con.j[ang]])
        pw = np.concatenate([e_w, a_w, a_w])
        # stiffness-proportional damping on the cloth's own pair elements (not the seams: a sewing closes them)
        dw = pw * (float(st.stiffness_damping) / dt)
        dw[self._seam_at:e_i.size] = 0.0
        pm = pw + dw
        diag = np.where(free, mh2 + d_off + np.bincount(pi, pm, n) + np.bincount(pj, pm, n), 1.0)
        diag[free] += self._w_lo
        both = free[pi] & free[pj]
        rows = np.concatenate([pi[both], pj[both], np.arange(n)])
        cols = np.concatenate([pj[both], pi[both], np.arange(n)])
        vals = np.concatenate([-pm[both], -pm[both], diag])
        a = sparse.csc_matrix((vals, (rows, cols)), shape=(n, n))
        # a free vertex's coupling to a pinned one moves to the right-hand side (kernels.pd docstring)
        fi = np.concatenate([pi[free[pi] & ~free[pj]], pj[free[pj] & ~free[pi]]])
        fp = np.concatenate([pj[free[pi] & ~free[pj]], pi[free[pj] & ~free[pi]]])
        fw = np.concatenate([pm[free[pi] & ~free[pj]], pm[free[pj] & ~free[pi]]])
        order = np.argsort(fi, kind="stable")
        pin_ptr = np.concatenate([[0], np.cumsum(np.bincount(fi, minlength=n))]).astype(np.int64)
        # which pair each pin coupling came from (PDSettings.band_weight re-weighs both)
        pair_of = np.concatenate([np.flatnonzero(free[pi] & ~free[pj]), np.flatnonzero(free[pj] & ~free[pi])])[order]

        def c(x, dtype=np.float64):
            return np.ascontiguousarray(x, dtype=dtype)

        i64 = np.int64
        arrays = (c(mh2), self._inv_mass, c(np.where(free, d_off, 0.0)), c(e_i, i64), c(e_j, i64),
                  c(e_lo), c(e_hi), c(e_w), c(con.i[ang], i64), c(con.j[ang], i64),
                  c(con.corner[ang], i64), c(np.cos(con.t_lo[ang])), c(np.cos(con.t_hi[ang])), c(a_w),
                  c(s_i, i64), c(s_j, i64),
                  c(s_lo), c(s_hi), c(s_w), c(h_i, i64), c(h_k), c(h_rest), self._pins, pin_ptr,
                  c(fp[order], i64), c(fw[order]))
        band = np.zeros(pw.size, dtype=bool)
        band[:e_i.size] = e_lo < e_hi
        self._pairs = dict(i=pi, j=pj, w=pw, band=band, lo=np.concatenate([e_lo, np.zeros(2 * ang.size)]),
                           hi=np.concatenate([e_hi, np.zeros(2 * ang.size)]), both=both, base=np.where(
                               free, mh2 + d_off, 1.0), free=free, pair_of=pair_of,
                           active=np.ones(pw.size, dtype=np.bool_), at=None, dw=dw,
                           damped=bool(np.any(dw > 0)))
        return arrays, a

    def _distance_elements(self, in_a):
        """The distance elements of the matrix as ``(i, j, lo, hi, w)``: the constraints ``in_a`` and the cloth's
        compression springs -- on the edges (``PDSettings.edge_compression``) or the bend springs
        (``bend_in_matrix``) -- and the bend springs left as forces outside it."""
        m, con, st = self.model, self._con, self.settings
        parts = [(con.i[in_a], con.j[in_a], con.lo[in_a], con.hi[in_a], 1.0 / con.alpha[in_a])]
        bend = np.flatnonzero((m.spring_type == BEND) & (m.spring_k > 0))
        if st.edge_compression:  # free when longer than at rest
            e = np.flatnonzero((m.spring_type == STRUCTURAL) & (m.spring_k > 0))
            parts.append((m.spring_indices[e, 0], m.spring_indices[e, 1], m.spring_rest[e], np.full(e.size, np.inf),
                          COMPRESSION_SHARE * m.spring_k[e]))
            bend = bend[:0]
        elif st.bend_in_matrix:
            parts.append((m.spring_indices[bend, 0], m.spring_indices[bend, 1], m.spring_rest[bend],
                          m.spring_rest[bend], m.spring_k[bend]))
            bend = bend[:0]
        return [np.concatenate(c) for c in zip(*parts)], bend

    def _reweight(self, x):
        """With ``PDSettings.band_weight < 1``: the bands in the matrix weighed by whether they act at ``x`` (a yarn
        inside its free band has no stiffness; its full weight in the matrix holds the cloth where it is at each
        iteration); the matrix refactored when that changes (:mod:`vfit_engine.kernels.pd_matrix`). The step's
        element weights and the pins' couplings follow."""
        pr = self._pairs
        if float(self.settings.band_weight) >= 1.0 or not pr["band"].any():
            return
        first = pr["at"] is None
        if first:  # where each element's entries lie in the factor's values (a fixed pattern)
            i, j, both, n = pr["i"], pr["j"], pr["both"], self.model.particle_count
            at_ij, at_ji = np.full(i.size, -1, np.int64), np.full(i.size, -1, np.int64)
            at_ij[both] = self._factor.positions(i[both], j[both])
            at_ji[both] = self._factor.positions(j[both], i[both])
            pr["at"] = (at_ij, at_ji, self._factor.positions(np.arange(n), np.arange(n)))
            pr["data"] = np.zeros(self._factor.nnz)
        # every step the set changes a little (bands at their ends): refactoring only past a 2 % change let the
        # suit settle in 191 frames against 105, slower in all
        if not acting_bands(x, pr["i"], pr["j"], pr["lo"], pr["hi"], pr["band"], pr["active"]) and not first:
            return
        band_matrix(pr["i"], pr["j"], pr["w"], pr["active"], float(self.settings.band_weight), pr["free"],
                    pr["base"], self._w_c, *pr["at"], pr["data"], self._arrays[7], self._arrays[-1], pr["pair_of"],
                    pr["dw"])
        self._factor.refactor_values(pr["data"])
        self.refactors += 1

    def matrix(self):
        """The global step's matrix as built for the last step size prepared (scipy CSC, N/m): every band at its
        full weight (``PDSettings.band_weight`` re-weighs the factor as the drape goes) plus its stiffness damping,
        the contact weight on every free vertex, pinned rows the identity."""
        return self._matrix.copy()

    def _prepare(self, dt):
        if self._dt == dt:
            return
        self._arrays, a = self._elements(dt)
        self._matrix = a
        self._factor = SPDFactor(a)
        self._w_c = np.where(self._inv_mass > 0, self._w_lo, 0.0)
        self._rho = self.settings.contact_rho * (self._mh2 + self._w_c)
        self._dt = dt
        n, m = self.model.particle_count, int(self.settings.history)
        self._qn_s, self._qn_t = np.zeros((m, n, 3)), np.zeros((m, n, 3))
        self._qn_rho, self._qn_alpha = np.zeros(m), np.zeros(m)
        self._qn_at = [m - 1, 0]  # the newest slot, the pairs held (a new step size starts afresh)
        self._gravity_step()

    def _gravity_step(self):
        """``g h^2`` on the free vertices (n, 3) m, at the step ``self._dt`` and gravity as weighed: what the
        quasi-Newton iterations take off the prediction to start from."""
        self._g_h2 = np.where((self._inv_mass > 0)[:, None], self._gravity * (self._dt * self._dt), 0.0)

    @property
    def constraint_count(self):
        """Number of constraints (stretch, bend and shear limits, shear springs)."""
        return self._con.count

    @property
    def ground(self):
        """Height (m, y) of the ground plane the cloth rests on, None when there is none."""
        return None if self._ground == -math.inf else self._ground

    # -- state and stepping --------------------------------------------------------------------------
    def init_state(self, dt, pos=None, vel=None):
        """A state at ``pos`` (default rest) moving at ``vel`` (default 0), m and m/s; ``pos_prev = pos - vel dt +
        g dt^2 / 2`` so that free fall is exact (each step's prediction adds ``g dt^2`` to the last step's move)."""
        dt = float(dt)
        self._prepare(dt)
        m = self.model
        x = np.array(m.rest_pos if pos is None else pos, dtype=np.float64, order="C")
        if x.shape != (m.particle_count, 3):
            raise ValueError(f"pos must have shape ({m.particle_count}, 3)")
        v = np.zeros_like(x) if vel is None else np.broadcast_to(np.asarray(vel, dtype=np.float64), x.shape)
        free = (self._inv_mass > 0)[:, None]
        v = np.where(free, v, 0.0)
        self._d_last[:] = -np.inf
        self._c_nq2[:] = np.nan
        self._lam[:] = 0.0
        return State(x, x - v * dt + np.where(free, 0.5 * self._gravity * dt * dt, 0.0), dt)

    def set_iterations(self, iterations):
        """Iterate ``iterations`` times per step from the next step on."""
        self.settings = dataclasses.replace(self.settings, iterations=int(iterations))

    def step(self, state, dt):
        """Advance ``state`` in place by one step of ``dt`` (s); returns it."""
        return self._advance(state, float(dt), 1)

    def step_frame(self, state, frame_dt, substeps=None):
        """Advance ``state`` in place by ``frame_dt`` (s) in equal steps; returns it."""
        n_sub = int(substeps or self.settings.substeps)
        return self._advance(state, float(frame_dt) / n_sub, n_sub)

    def _advance(self, state, dt, n_sub):
        if not dt > 0:
            raise ValueError("dt must be > 0")
        m = self.model
        if state.pos.shape != (m.particle_count, 3):
            raise ValueError("state does not belong to this model")
        self._prepare(dt)
        state.change_step(dt)
        pinned = state.pin_target is not None and m.pin_count
        if pinned:
            if state.pin_target.shape != (m.pin_count, 3):
                raise ValueError(f"pin_target must have shape ({m.pin_count}, 3)")
            np.take(state.pos, m.pin_indices, axis=0, out=self._pin_from)
            target = np.ascontiguousarray(state.pin_target, dtype=np.float64)
        for s in range(n_sub):
            if pinned:
                self._step(state.pos, state.pos_prev, dt, self._pins, self._pin_from, target, (s + 1.0) / n_sub)
            else:
                self._step(state.pos, state.pos_prev, dt, self._no_pins, self._no_pin_pos, self._no_pin_pos, 1.0)
        state.time += dt * n_sub
        state.step_count += n_sub
        return state

    def _step(self, x, xp, dt, pin_idx, pin_from, pin_to, alpha):
        """One step of ``dt`` (module docstring), ``x`` and ``xp`` in place."""
        st, c = self.settings, self.contact
        keep = math.exp(-st.air_damping * dt)
        advance_in_place(x, xp, self._inv_mass, self._zero_f, self._gravity, keep, dt * dt)
        move_pins(x, pin_idx, pin_from, pin_to, alpha)
        np.copyto(self._y, x)
        n_c, queries = make_contacts(
            x, self._inv_mass, self._pt_v, self._pt_b, self._pt_skin, self._spheres, self._grid, self.body is not None,
            float(c.reach), float(self.max_push), float(c.reuse), self._p_last, self._d_last, self._c_n, self._c_nq,
            self._c_h, self._c_list, self._c_n2, self._c_nq2, self._c_h2, 0, self.points.count, self._body_vel,
            self._sphere_vel, self._c_u, self._body_sag, self._sag_max, self._ground)
        self.contact_queries += queries
        moving = self._push_w.shape[0] > 0
        if moving:  # a moving body (body_moved): the skin's velocity under each touching vertex
            contact_body_velocity(self._inv_mass, self._pt_v, self._pt_b, self._c_list, n_c, self._c_u, self._push_u,
                                  self._push_w)
        self._reweight(x)
        pr = self._pairs
        if pr["damped"]:
            add_damping_target(self._y, xp, pr["i"], pr["j"], pr["dw"], self._mh2)
        if int(st.history) > 0:  # the iterations start without the step's g h^2 (PDSettings.history)
            np.subtract(x, self._g_h2, out=x)
        factor = self._factor.arrays
        if int(st.history) > 0:
            self._iterate_qn(x, xp, dt, n_c, moving, factor)
        else:
            self._iterate(x, xp, dt, n_c, moving, factor)
        soft_push(self._gap, self._inv_mass, self._w_c, dt * dt, self._push, self._lam, self._nrm)
        for _ in range(int(st.contact_sweeps)):
            solve_contacts(x, self._inv_mass, self._pt_v, self._pt_b, self._c_n, self._c_h, self._c_list, 0, n_c,
                           self._push, self._c_n2, self._c_nq2, self._c_h2, self._c_live, False, self._c_u,
                           self._push_u, self._push_w)
        for col in self.colliders:
            col.project(x, xp, self._inv_mass)
        contact_velocity(x, xp, self._inv_mass, self._push, float(c.friction),
                         math.exp(-float(c.damping) * dt), self._hot, self._push_u, self._push_w, dt, bool(c.stick))

    def _local_step(self, x, xp, dt, n_c, moving, lag):
        """One iteration's right-hand side ``self._b`` at ``x``: Uzawa's contact forces updated, the local step
        (the forces outside the matrix kept from an earlier iterate with ``lag``) and the friction; returns the
        step's energy at ``x`` less the contact forces' (NaN with ``lag``; :func:`~vfit_engine.kernels.pd.pd_rhs`)."""
        st, c = self.settings, self.contact
        if st.contact_rho > 0:
            contact_forces(x, self._inv_mass, self._pt_v, self._pt_b, self._c_n, self._c_h, self._c_n2, self._c_nq2,
                           self._c_h2, self._c_list, n_c, self._rho, self._lam, self._nrm, self._plane, self._acc_g,
                           self._acc_n, self._acc_w, moving)
        e = pd_rhs(x, self._y, *self._arrays, self._pt_v, self._pt_b, self._c_n, self._c_h, self._c_n2, self._c_nq2,
                   self._c_h2, self._c_list, n_c, self._w_c, self._b, self._gap, self._count, self._f_lag, lag,
                   self._lam, self._nrm, self._hinge_work)
        return e + contact_friction(x, xp, self._inv_mass, self._w_c, self._gap, self._lam, self._nrm,
                                    float(st.friction_in_solve) * float(c.friction), self._push_u, self._push_w, dt,
                                    self._b)

    def _iterate(self, x, xp, dt, n_c, moving, factor):
        """The plain iterations of a step: Uzawa's contact forces, the local step, the global solve
        (Chebyshev-accelerated with ``PDSettings.chebyshev_rho``)."""
        st = self.settings
        np.copyto(self._xprev, x)
        omega = 1.0
        for k in range(int(st.iterations)):
            self._local_step(x, xp, dt, n_c, moving, k % int(st.hinge_every) != 0)
            np.copyto(self._xh, self._b)
            sn_solve3(*factor, self._xh, self._work)
            omega = chebyshev(x, self._xh, self._xprev, k, int(st.chebyshev_delay), float(st.chebyshev_rho), omega)

    def _iterate_qn(self, x, xp, dt, n_c, moving, factor):
        """The quasi-Newton iterations of a step (``PDSettings.history``, :mod:`vfit_engine.kernels.lbfgs`): each
        takes the gradient ``A x - b`` at the iterate (the forces outside the matrix evaluated there too) and moves
        by the L-BFGS step on ``A^-1``; the last takes the plain step (it descends, and no later iteration would
        check it). A quasi-Newton move is checked by the next iteration's local step, which gives the energy at
        its end for nothing (Armijo's test, the contact forces held): one that did not lower it is undone and the
        history dropped (its pairs no longer fit the cloth), as is a direction that does not descend or, under a
        moving body, one that moves a vertex more than ``PDSettings.qn_move_limit``; the plain step follows."""
        st, pr = self.settings, self._pairs
        s_, t_, rho, alpha, at = self._qn_s, self._qn_t, self._qn_rho, self._qn_alpha, self._qn_at
        indptr, indices, data = self._factor.matrix_arrays
        g, g0, g0_old, r, x_old = self._g, self._g0, self._g0_old, self._xh, self._xprev
        last = int(st.iterations) - 1
        limit = float(st.qn_move_limit) if moving else math.inf
        gr = e_ref = 0.0  # the last move's g . r (0: a plain one, not checked) and the energy it started from
        for k in range(last + 1):
            held = uzawa_energy(self._lam, self._nrm, x)
            e = self._local_step(x, xp, dt, n_c, moving, False)
            if pr["damped"]:
                e += pair_energy(x, pr["i"], pr["j"], pr["dw"])
            # (rounding allowed for: near the rest the energy's change is at its last digits)
            if gr > 0.0 and not e + held <= e_ref - 1e-4 * gr + 1e-12 * abs(e_ref):
                self.qn_restarts += 1  # undone, and the plain step from where it started
                at[1] = 0
                gr = 0.0
                np.copyto(x, x_old)
                continue
            e_ref = e + uzawa_energy(self._lam, self._nrm, x)
            gradient(indptr, indices, data, x, self._b, self._lam, self._nrm, g, g0)
            if k > 0:
                at[0], at[1] = push_pair(x, x_old, g0, g0_old, s_, t_, rho, at[0], at[1])
            np.copyto(r, g)
            quasi = at[1] > 0 and k < last
            if quasi:
                first_loop(r, s_, t_, rho, alpha, at[0], at[1])
            sn_solve3(*factor, r, self._work)
            gr = 0.0
            if quasi:
                second_loop(r, s_, t_, rho, alpha, at[0], at[1])
                gr = dot3(g, r)
                # no descent direction, or under a moving body a move beyond what the step's contacts see: plain
                if not gr > 0.0 or max_move(r) > limit:
                    self.qn_restarts += 1
                    at[1] = 0
                    gr = 0.0
                    np.copyto(r, g)
                    sn_solve3(*factor, r, self._work)
            np.copyto(x_old, x)
            np.copyto(g0_old, g0)
            np.subtract(x, r, out=x)

    # -- diagnostics ----------------------------------------------------------------------------
    def max_stretch(self, state, spring_type=0):
        """Largest ``l / l0 - 1`` among springs of ``spring_type`` (default structural)."""
        return self.model.max_stretch(state.pos, spring_type)

    def max_speed(self, state):
        """Largest particle speed, m/s."""
        return float(np.sqrt(np.max(np.sum(state.velocity() ** 2, axis=1)))) if state.particle_count else 0.0
