"""Position-Verlet cloth solver: explicit bending, banded stretch, bend and shear constraints, surface contacts.

``SolverVerlet(model, settings, contact=..., body=..., points=...)`` advances a
:class:`~vfit_engine.sim.state.State` by substeps of :func:`vfit_engine.kernels.cloth.cloth_substeps`:

* **explicit forces** (position Verlet, Verlet 1967 / Jakobsen 2001): the bending hinges
  (:mod:`vfit_engine.sim.bending`), the bend springs (damped Hooke springs between second neighbours) and
  the damping of every spring family. When
  ``stability_safety > 0`` each spring's ``k`` and ``kd`` is scaled by ``min(1, s_i, s_j)`` with
  ``s_i = 4 safety / (2 w_i sum k dt^2 + 4 w_i sum kd dt)`` (Gershgorin's bound on the explicit step:
  stable when ``lambda dt^2 + 2 gamma dt < 4``): a spring stiffer than the step can carry becomes as
  stiff as it allows (:attr:`SolverVerlet.softened_fraction`). The margin is wide (0.2 of the bound)
  because the constraints below stiffen the system the explicit springs act in: at 0.5 they rang
  against them in cloth the body held stretched, and the drape never settled;
* **constraints** (built by :mod:`vfit_engine.sim.constraints`), solved ``iterations`` times per substep
  (Gauss-Seidel; XPBD, Macklin et al. 2016;
  the bands are Provot's strain limits, Provot 1995), each holding a length (or an angle) inside a
  band and acting only outside it:

  - *stretch*: every polygon edge, free from ``(1 - compression) l0`` to ``(1 + slack) l0`` (a woven's
    yarns straighten their crimp at almost no load, and cloth buckles rather than compresses), beyond
    that with the material's stretch stiffness (compliance ``1 / k``, not softened);
  - *bend limit*: every second-neighbour pair may shorten freely (the cloth folds) but not lengthen
    beyond ``(1 + bend_limit) l0``: folds modelled into a garment (a turned hem, a collar) keep their
    turn instead of opening out;
  - *shear limit*: every corner of every quad or n-gon keeps its angle within ``shear_limit_deg`` of
    the garment's (an angle constraint, so scaling a quad is not shear): cloth trellises easily up to
    a locking angle and then jams, and polygons do not collapse;
  - *shear springs*: each polygon diagonal, with the material's shear stiffness, pulls its quad back
    to its modelled angles; ``shear_restore`` weighs it lightly where it conflicts with the others;
  - *stiff hinges*: a hinge stiffer than the explicit step can carry (small polygons at seams and
    details, a stiff fabric) is an angle constraint of compliance ``1 / k`` (XPBD), stable at any step,
    instead of being softened: the drape bends with the fabric's whole rigidity. Softening it as the
    springs are (``implicit_hinges`` off) left denim 0.39-0.67 of its bending on the shared suits and
    draped silk and denim skirts 4 mm apart; as constraints they are 20 mm apart. Round an opening the
    body forces wider (:meth:`SolverVerlet.allow_stretch`) hinges stay explicit and softened: there the
    cloth is stretched open, and seams held at their modelled angle pulled the stretch onto their
    shortest edges (an armhole edge 0.2 points over its allowance);

* **contacts** with the body -- an exact triangle mesh (:class:`vfit_engine.collide.body_mesh.MeshCollider`)
  and/or spheres -- and with the ground under it (a still plane, ``ground``) of the cloth's vertices and of
  points spread over its triangles
  (:mod:`vfit_engine.sim.contact_points`), solved in the same loop as the constraints;
* any other collider with ``project(x, x_prev, inv_mass)`` (ellipsoids, hulls) after each substep.

The kernel runs on two threads (:mod:`vfit_engine.sim.partition`): the solver numbers the cloth's
vertices in two halves and orders its springs, constraints and contact points by segment; a
:class:`State` keeps the garment's vertex order (each step gathers it into the solver's numbering and
back), and the result is the same for any number of threads.

The solver owns every array the kernel reads or writes: callers set the sweep order, open the bands
round an opening the body forces wider or to admit a start shape, and ramp the push limit through
:meth:`SolverVerlet.sweep_from`, :meth:`SolverVerlet.allow_stretch`, :meth:`SolverVerlet.admit` and
:attr:`SolverVerlet.max_push`.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import dijkstra

from vfit_engine.collide.body_mesh import empty_grid
from vfit_engine.kernels.bending import eval_hinge_forces
from vfit_engine.kernels.cloth import ClothArrays, ContactPoints, ContactState, StepParams, cloth_substeps
from vfit_engine.kernels.springs import eval_spring_forces
from vfit_engine.sim.bending import hinge_gradient_norms
from vfit_engine.sim.body_motion import BodyMotion
from vfit_engine.sim.constraints import KIND_SHEAR, build_constraints
from vfit_engine.sim.contact_points import body_sag, contact_points
from vfit_engine.sim.partition import halves, segment_of, segments
from vfit_engine.sim.solver_settings import ContactSettings, VerletSettings  # noqa: F401  (the solver's API)
from vfit_engine.sim.springs import SHEAR, STRUCTURAL
from vfit_engine.sim.state import State


def _stable_scale(inv_mass, ksum, dsum, dt, safety):
    """(n,) float64: per vertex, the factor (<= 1) that brings its explicit stiffness ``ksum`` (N/m) and damping
    ``dsum`` (N s/m) within ``safety`` of Gershgorin's bound on the step (module docstring)."""
    demand = inv_mass * (2.0 * ksum * dt * dt + 4.0 * dsum * dt)
    scale = np.ones(inv_mass.shape[0])
    np.divide(4.0 * safety, demand, out=scale, where=demand > 4.0 * safety)
    return scale


class SolverVerlet(BodyMotion):
    """Cloth solver (module docstring).

    Parameters
    ----------
    model : Model
    settings : VerletSettings, optional
    contact : ContactSettings, optional
    body : MeshCollider or None
        The exact body surface to keep the cloth out of.
    spheres : (S, 4) float64 or None
        Sphere colliders: centre (m) and radius (m).
    points : ContactPointSet or None
        Contact points; None: the cloth's vertices only.
    colliders : sequence
        Other colliders, each with ``project(x, x_prev, inv_mass)``, applied after every substep.
    ground : float or None
        Height (m, y) of a still ground plane the cloth rests on (normal +y); None: no ground.
    """

    def __init__(self, model, settings=None, contact=None, body=None, spheres=None, points=None, colliders=(),
                 ground=None):
        self.model = model
        self.settings = settings or VerletSettings()
        self.contact = contact or ContactSettings()
        self.colliders = list(colliders)
        if ground is not None and not math.isfinite(ground):
            raise ValueError(f"ground must be a finite height or None, got {ground!r}")
        self._ground = -math.inf if ground is None else float(ground)  # the kernel's: -inf, none
        self.max_push = math.inf
        self.contact_queries = 0
        self.softened_fraction = 0.0
        #: shares of the hinges stiffer than the explicit step can carry (at the last step prepared), of those
        #: solved as constraints, and of those softened (:meth:`effective_constants`)
        self.stiff_hinges = self.implicit_hinges = self.softened_hinges = 0.0
        #: the share of the material's bending stiffness (summed over the hinges) the step carries unsoftened
        self.bending_kept = 1.0
        self._hinge_g = None
        n = model.particle_count
        self._inv_mass = np.ascontiguousarray(model.inv_mass, dtype=np.float64).copy()
        self._gravity = np.ascontiguousarray(self.settings.gravity, dtype=np.float64)
        # the kernel's numbering: the cloth in two halves (vfit_engine.sim.partition)
        self._order, self._rank, self._half = halves(model.rest_pos)
        self._k_inv_mass = np.ascontiguousarray(self._inv_mass[self._order])
        self._x, self._xp = np.zeros((n, 3)), np.zeros((n, 3))
        self._k_pins = np.ascontiguousarray(self._rank[model.pin_indices])
        self._counts = np.zeros((3, 5), dtype=np.int64)
        self._con = build_constraints(model, self.settings)
        self._lam = np.zeros(self._con.count)
        self._active = np.zeros(self._con.count, dtype=np.int64)
        self.points = points if points is not None else contact_points(np.zeros(0, np.int64), np.zeros(1, np.int64),
                                                                       model.rest_pos, surface=False)
        self._set_contacts(body, spheres)
        self._no_pins, self._no_pin_pos = np.zeros(0, np.int64), np.zeros((0, 3))
        self._pin_from = np.zeros((model.pin_count, 3))
        self._const_dt = None
        self._f = np.zeros((n, 3))
        # the hinge constraints' multipliers and active list (_prepare sizes them)
        self._h_lam, self._h_active = np.zeros(0), np.zeros(0, np.int64)
        self._h_explicit = np.zeros(0 if model.hinges is None else model.hinges.count, dtype=bool)

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
        v = self.points.verts
        order, self._p_seg = segments(segment_of(self._half, v[:, 0], v[:, 1], v[:, 2]))
        self._pt_v = np.ascontiguousarray(self._rank[v[order]])
        self._pt_b = np.ascontiguousarray(self.points.bary[order])
        self._pt_skin = np.ascontiguousarray(skin[order])
        self._p_last = np.zeros((p, 3))
        self._d_last = np.full(p, -np.inf)
        self._c_n, self._c_nq, self._c_h = np.zeros((p, 3)), np.zeros(p), np.zeros(p)
        self._c_list = np.zeros(p, dtype=np.int64)
        self._c_live = np.zeros(p, dtype=np.int64)
        self._c_n2, self._c_nq2, self._c_h2 = np.zeros((p, 3)), np.full(p, np.nan), np.zeros(p)
        self._push = np.zeros((self.model.particle_count, 3))
        self._hot = np.zeros(self.model.particle_count, dtype=np.bool_)
        # a still body: no velocities (body_moved gives them, and the scratch to carry the cloth with them)
        self._body_vel, self._sphere_vel = np.zeros((0, 3)), np.zeros((0, 3))
        self._c_u, self._push_u, self._push_w = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
        self._body_sag = body_sag(body, self.points, self.contact)
        self._sag_max = float(self._body_sag.max(initial=0.0))

    def sweep_from(self, vertices):
        """Sweep the constraints outward from ``vertices`` (by graph distance, nearest first).

        Pins move the cloth and hold it up: a sweep that starts at them passes their pull on down
        the cloth within one sweep, where the vertex order may meet the pulled constraint last.
        """
        vertices = np.asarray(vertices, dtype=np.int64)
        con = self._con
        if vertices.size == 0 or con.count == 0:
            return
        n = self.model.particle_count
        adj = sparse.coo_matrix((np.ones(con.count), (con.i, con.j)), shape=(n, n)).tocsr()
        depth = dijkstra(adj, directed=False, indices=vertices, unweighted=True, min_only=True)
        con.reorder(np.argsort(np.minimum(depth[con.i], depth[con.j]), kind="stable"))
        self._const_dt = None

    def allow_stretch(self, vertices, strain):
        """Let the cloth among ``vertices`` (k,) int64 stretch freely up to ``strain`` (fraction).

        For the cloth round an opening smaller than the body part it must go round: it has to
        stretch that much, and a free band lets it open to the body without the constraints nearest
        the body taking it all; its stretch and bend limits open by ``strain``, its corner angles by
        ``strain`` radians (a quad one side of which stretches by s more than the other turns so much), and
        its hinges stay explicit (module docstring, *stiff hinges*).
        """
        inside = np.zeros(self.model.particle_count, dtype=bool)
        inside[np.asarray(vertices, dtype=np.int64)] = True
        self._con.open_bands(inside, strain)
        if self.model.hinges is not None:
            self._h_explicit |= inside[self.model.hinges.indices].any(axis=1)
        self._const_dt = None

    def admit(self, pos, vertices):
        """Widen the bands of the constraints among ``vertices`` (k,) int64 to admit their lengths at
        ``pos`` (n, 3) m: a garment moved onto a bigger body is as stretched there as the body forces it,
        and the cloth the body holds out should not fight back towards a size it cannot have."""
        inside = np.zeros(self.model.particle_count, dtype=bool)
        inside[np.asarray(vertices, dtype=np.int64)] = True
        self._con.admit(pos, inside)
        self._const_dt = None

    # -- constants ------------------------------------------------------------------------
    def effective_constants(self, dt):
        """The explicit springs' and hinges' constants at step ``dt`` (s), and the hinges solved as constraints.

        A spring stiffer than the explicit step can carry is softened to its bound (module docstring). So
        is a hinge when ``settings.implicit_hinges`` is off, or when its cloth is in a zone the body forces
        wider (:meth:`allow_stretch`); otherwise it keeps the material's stiffness as a compliant angle
        constraint (``h_alpha = 1 / k``) and its explicit ``k`` is 0.

        Returns
        -------
        k : (s,) float64, N/m
            0 for springs that are constraints (their stiffness lives in the constraint).
        kd : (s,) float64, N s/m
        hk : (h,) float64, N m;  hkd : (h,) float64, N m s
            The bending hinges' explicit constants (empty without hinges).
        h_alpha : (h,) float64, 1 / (N m)
            The compliance of the hinges solved as constraints, 0 for the others.
        """
        m = self.model

        k = np.array(m.spring_k)
        # the stretch constraints hold the stretch stiffness; with a shear limit the quads trellis
        # freely within it (explicit shear springs stiffer than the step can carry only ring there)
        k[m.spring_type == STRUCTURAL] = 0.0
        if self.settings.shear_limit_deg is not None:
            k[m.spring_type == SHEAR] = 0.0
        kd = np.array(m.spring_kd)
        hinges = m.hinges
        hk = np.zeros(0) if hinges is None else np.array(hinges.k)
        hkd = np.zeros(0) if hinges is None else np.array(hinges.kd)
        h_alpha = np.zeros(hk.size)
        safety = self.settings.stability_safety
        if safety > 0 and (m.spring_count or hk.size):
            n = m.particle_count
            i, j = m.spring_indices[:, 0], m.spring_indices[:, 1]
            ksum = np.bincount(i, k, n) + np.bincount(j, k, n)
            dsum = np.bincount(i, kd, n) + np.bincount(j, kd, n)
            scale_v = _stable_scale(m.inv_mass, ksum, dsum, dt, safety)
            scale = np.minimum(scale_v[i], scale_v[j])
            self.softened_fraction = float(np.mean(scale < 1.0)) if scale.size else 0.0
            k *= scale
            kd *= scale
            if hk.size:
                h_scale = self._hinge_scale(hk, hkd, dt, safety)
                stiff = h_scale < 1.0
                implicit = stiff & ~self._h_explicit if self.settings.implicit_hinges else np.zeros_like(stiff)
                self.stiff_hinges = float(np.mean(stiff))
                self.implicit_hinges = float(np.mean(implicit))
                self.softened_hinges = float(np.mean(stiff & ~implicit))
                kept = np.where(implicit, 1.0, h_scale)
                self.bending_kept = float(np.sum(hk * kept) / max(np.sum(hk), 1e-300))
                h_alpha = np.where(implicit, 1.0 / np.maximum(hk, 1e-300), 0.0)
                hk = np.where(implicit, 0.0, hk * h_scale)
                hkd *= h_scale
        return k, kd, hk, hkd, h_alpha

    def _hinge_scale(self, hk, hkd, dt, safety):
        """(h,) float64: each hinge's factor (<= 1) to its own explicit bound at ``dt`` (a spring's damping,
        stiff on a light vertex, must not soften the bending that decides the drape's shape): a hinge's
        stiffness at vertex m is k |g_m| sum_l |g_l| (Gershgorin on k g g^T)."""
        m = self.model
        g = self._hinge_gradient_norms()
        row = g * g.sum(axis=1, keepdims=True)
        flat = m.hinges.indices.ravel()
        n = m.particle_count
        h_v = _stable_scale(m.inv_mass, np.bincount(flat, (hk[:, None] * row).ravel(), n),
                            np.bincount(flat, (hkd[:, None] * row).ravel(), n), dt, safety)
        return h_v[m.hinges.indices].min(axis=1)

    def _hinge_gradient_norms(self):
        """(h, 4) float64, 1/m: |d theta / d x| of every hinge's vertices at rest."""
        if self._hinge_g is None:
            h, pos = self.model.hinges, self.model.rest_pos
            self._hinge_g = hinge_gradient_norms(h.indices, pos)
        return self._hinge_g

    def max_stable_dt(self):
        """The largest step (s) at which every hinge is within ``stability_safety`` of its explicit bound: the
        bending is the material's explicit force everywhere, none of it a constraint (springs may still be
        softened: their damping only slows motion)."""
        lo, hi = 1e-7, 1.0
        for _ in range(60):
            mid = math.sqrt(lo * hi)
            self.effective_constants(mid)
            if self.stiff_hinges > 0:
                hi = mid
            else:
                lo = mid
        self._const_dt = None
        return lo

    def _prepare(self, dt):
        if self._const_dt == dt:
            return

        k, kd, hk, hkd, h_alpha = self.effective_constants(dt)
        keep = np.flatnonzero((k > 0) | (kd > 0))
        m = self.model
        # the explicit springs, given numbering (init_state), and both families in the kernel's
        self._explicit = (m.spring_indices[keep], m.spring_rest[keep], k[keep], kd[keep])
        rank, con = self._rank, self._con
        corner = con.corner
        s_order, sp_seg = segments(segment_of(self._half, *self._explicit[0].T))
        sp = keep[s_order]
        c_order, c_seg = segments(segment_of(self._half, con.i, con.j, corner))
        if m.hinges is not None:
            hi, rest = m.hinges.indices, m.hinges.rest_angle
        else:
            hi, rest = np.zeros((0, 4), np.int64), np.zeros(0)
        force = np.flatnonzero((hk > 0) | (hkd > 0))  # the hinges that act as forces, and the constraints
        held = np.flatnonzero(h_alpha > 0)
        self._explicit_hinges = (hi[force], hk[force], hkd[force], rest[force])
        h_order, h_seg = self._hinge_segments(hi, force)
        hc_order, hc_seg = self._hinge_segments(hi, held)
        if self._h_lam.size != held.size:
            self._h_lam, self._h_active = np.zeros(held.size), np.zeros(held.size, np.int64)

        def arr(a, order):
            return np.ascontiguousarray(a[order])

        self._cloth = ClothArrays(
            self._k_inv_mass, self._gravity, arr(rank[m.spring_indices[:, 0]], sp),
            arr(rank[m.spring_indices[:, 1]], sp), arr(m.spring_rest, sp), arr(k, sp), arr(kd, sp),
            arr(rank[con.i], c_order), arr(rank[con.j], c_order), arr(con.lo, c_order), arr(con.hi, c_order),
            arr(con.alpha, c_order),
            arr(con.relax, c_order), arr(np.where(corner >= 0, rank[np.maximum(corner, 0)], -1), c_order),
            arr(np.cos(con.t_lo), c_order), arr(np.cos(con.t_hi), c_order),
            arr(con.kind == KIND_SHEAR, c_order), sp_seg, c_seg, arr(rank[hi], h_order), arr(hk, h_order),
            arr(hkd, h_order), arr(rest, h_order), h_seg, arr(rank[hi], hc_order), arr(h_alpha, hc_order),
            arr(rest, hc_order), hc_seg)
        self._c_air = 1.0 - math.exp(-self.settings.air_damping * dt)
        self._const_dt = dt

    def _hinge_segments(self, hinge_indices, chosen):
        """The hinges ``chosen`` (k,) int64 in the kernel's segment order, and the segments' bounds (4,)."""
        if not chosen.size:
            return chosen, np.zeros(4, np.int64)
        order, seg = segments(segment_of(self._half, *hinge_indices[chosen].T))
        return chosen[order], seg

    # -- state ----------------------------------------------------------------------------
    def init_state(self, dt, pos=None, vel=None):
        """A state at ``pos`` (default rest) moving at ``vel`` (default 0), m and m/s.

        ``pos_prev = pos - vel dt + a0 dt^2 / 2`` with the initial acceleration ``a0`` (explicit
        springs + gravity), so the first steps follow ``pos + vel t + a0 t^2 / 2`` (exactly, for
        free fall without air damping).
        """
        dt = float(dt)
        self._prepare(dt)
        m = self.model
        x = np.array(m.rest_pos if pos is None else pos, dtype=np.float64, order="C")
        if x.shape != (m.particle_count, 3):
            raise ValueError(f"pos must have shape ({m.particle_count}, 3)")
        v = np.zeros_like(x) if vel is None else np.broadcast_to(np.asarray(vel, dtype=np.float64), x.shape)
        f = eval_spring_forces(x, np.ascontiguousarray(x - v * dt), dt, *self._explicit)
        f += eval_hinge_forces(x, np.ascontiguousarray(x - v * dt), dt, *self._explicit_hinges)
        free = (self._inv_mass > 0)[:, None]
        a0 = np.where(free, self._inv_mass[:, None] * f + self._gravity, 0.0)
        v = np.where(free, v, 0.0)
        self._d_last[:] = -np.inf
        self._c_nq2[:] = np.nan
        self._hot[:] = False
        self._lam[:] = 0.0
        return State(x, x - v * dt + 0.5 * a0 * dt * dt, dt)

    def set_iterations(self, iterations):
        """Sweep the constraints ``iterations`` times per substep from the next step on."""
        self.settings = dataclasses.replace(self.settings, iterations=int(iterations))

    # -- stepping ---------------------------------------------------------------------------
    def step(self, state, dt):
        """Advance ``state`` in place by one substep of ``dt`` (s); returns it."""
        return self._advance(state, float(dt), 1)

    def step_frame(self, state, frame_dt, substeps=None):
        """Advance ``state`` in place by ``frame_dt`` (s) in equal substeps; returns it."""
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
        if state.pin_target is not None and m.pin_count:
            if state.pin_target.shape != (m.pin_count, 3):
                raise ValueError(f"pin_target must have shape ({m.pin_count}, 3)")
            np.take(state.pos, m.pin_indices, axis=0, out=self._pin_from)
            pins = (self._k_pins, self._pin_from, np.ascontiguousarray(state.pin_target, dtype=np.float64))
        else:
            pins = (self._no_pins, self._no_pin_pos, self._no_pin_pos)
        c = self.contact
        prm = StepParams(dt, self._c_air, int(self.settings.iterations), float(c.reach), float(c.friction),
                         float(self.max_push), 1.0 - math.exp(-float(c.damping) * dt), float(c.reuse),
                         self.body is not None, int(self.settings.hinge_every), bool(c.stick))
        pts = ContactPoints(self._pt_v, self._pt_b, self._pt_skin, self._spheres, self._p_seg, self._body_vel,
                            self._sphere_vel, self._body_sag, self._sag_max, self._ground)
        cst = ContactState(self._p_last, self._d_last, self._c_n, self._c_nq, self._c_h, self._c_list, self._push,
                           self._f, self._lam, self._active, self._c_n2, self._c_nq2, self._c_h2, self._c_live,
                           self._counts, self._hot, self._h_lam, self._h_active, self._c_u, self._push_u,
                           self._push_w)
        x, xp = self._x, self._xp
        np.take(state.pos, self._order, axis=0, out=x)
        np.take(state.pos_prev, self._order, axis=0, out=xp)
        spans = [(0, n_sub)] if not self.colliders else [(s, s + 1) for s in range(n_sub)]
        for begin, end in spans:
            self.contact_queries += cloth_substeps(x, xp, self._cloth, *pins, pts, self._grid, prm, cst, begin, end,
                                                   n_sub)
            for col in self.colliders:
                col.project(x, xp, self._k_inv_mass)
        state.pos[self._order] = x
        state.pos_prev[self._order] = xp
        state.time += dt * n_sub
        state.step_count += n_sub
        return state

    @property
    def segment_sizes(self):
        """(3,) int64: constraints in the first half of the cloth, the second, and across
        (:mod:`vfit_engine.sim.partition`; the first two run on two threads)."""
        return np.diff(segments(segment_of(self._half, self._con.i, self._con.j, self._con.corner))[1])

    @property
    def ground(self):
        """Height (m, y) of the ground plane the cloth rests on, None when there is none."""
        return None if self._ground == -math.inf else self._ground

    @property
    def constraint_count(self):
        """Number of distance constraints (stretch, shear and bend limits)."""
        return self._con.count

    # -- diagnostics ----------------------------------------------------------------------------
    def max_stretch(self, state, spring_type=0):
        """Largest ``l / l0 - 1`` among springs of ``spring_type`` (default structural)."""
        return self.model.max_stretch(state.pos, spring_type)

    def max_speed(self, state):
        """Largest particle speed, m/s."""
        return float(np.sqrt(np.max(np.sum(state.velocity() ** 2, axis=1)))) if state.particle_count else 0.0
