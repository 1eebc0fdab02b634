"""Position-Verlet mass-spring solver with Provot strain limiting and colliders.

``SolverVerlet(model, settings, colliders).step(state, dt)`` advances a
:class:`~vfit_engine.sim.state.State` by one substep; :meth:`SolverVerlet.step_frame`
runs ``settings.substeps`` of them in one compiled call. Per substep (see
:mod:`vfit_engine.kernels.integrate`): damped Hooke springs + gravity, position
Verlet with air damping, pins, Provot strain limiting (Provot 1995), spheres,
then any other collider's ``project(x, x_prev, inv_mass)`` (e.g. the body mesh).

Explicit stability. Position Verlet with spring damping on a particle of inverse
mass ``w`` is stable when ``lambda dt^2 + 2 gamma dt < 4`` for the largest
eigenvalue ``lambda`` of the stiffness and ``gamma`` of the damping; by
Gershgorin ``lambda <= 2 w sum(k)`` and ``gamma <= 2 w sum(kd)`` over the
particle's springs. When ``stability_safety > 0`` the solver scales each
spring's ``k`` and ``kd`` by ``min(1, s_i, s_j)`` with
``s_i = 4 safety / (2 w_i sum k dt^2 + 4 w_i sum kd dt)``, so fabrics stiffer than the
step can carry become as stiff as it allows and strain limiting provides the
inextensibility -- the reason Provot introduced it. The model is not changed;
:attr:`SolverVerlet.softened_fraction` reports how many springs were softened.

Strain-limiting order. Serially the limited springs are swept in index order
(structural springs sorted by vertex, then bend), which carries corrections
along mesh rows; the parallel kernel needs springs grouped in colours sharing
no vertex, an order that converges more slowly (benchmarks/bench_sphere_drape.py
shows ~16 % vs ~10.7 % peak stretch at N = 100), so ``parallel=True`` also
changes results, not only speed. Gauss-Seidel leaves a residual above the limit
that grows with cloth resolution and step size; over-relaxation and limiting
bend springs (redundant constraints on quad grids) shrink it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vfit_engine.sim.state import State


@dataclass(frozen=True)
class VerletSettings:
    """Solver settings.

    Attributes
    ----------
    substeps : int
        Substeps per :meth:`SolverVerlet.step_frame`.
    gravity : (3,) float, m/s^2
    air_damping : float, 1/s
        Velocity decay rate; per step ``c = 1 - exp(-air_damping dt)``.
    strain_limit : float or None
        Provot limit of structural springs (0.10 = 10 %); None: ``model.max_strain``.
    shear_strain_limit : float or None
        Limit of shear springs; None leaves them unlimited (free to shear, so
        the cloth can fold over doubly curved shapes).
    bend_strain_limit : float or None
        Limit of bend springs. On quad grids a row/column bend pair can only
        exceed the structural limit if a structural spring does, so limiting it
        too is a redundant constraint that carries corrections two vertices at a
        time and speeds convergence; on triangle meshes it also restrains shear.
    strain_limit_iterations : int
        Gauss-Seidel sweeps per substep (Provot used a few).
    strain_limit_relaxation : float
        Over-relaxation ``omega`` of each correction (1 = Provot; successive
        over-relaxation with 1 < omega < 2 converges faster).
    stability_safety : float
        Fraction of the explicit stability bound springs are softened to; 0
        disables softening (then too stiff a fabric explodes).
    parallel : bool
        Use the ``parallel=True`` kernel (forces gathered per vertex).
    gather : bool or None
        Gather spring forces per vertex (race-free; needed for parallel) instead of
        scattering them per spring (half the arithmetic). None: ``parallel``.
    """

    substeps: int = 10
    gravity: tuple = (0.0, -9.81, 0.0)
    air_damping: float = 0.5
    strain_limit: float | None = None
    shear_strain_limit: float | None = None
    bend_strain_limit: float | None = None
    strain_limit_iterations: int = 5
    strain_limit_relaxation: float = 1.0
    stability_safety: float = 0.5
    parallel: bool = False
    gather: bool | None = None

    def __post_init__(self):
        if int(self.substeps) < 1 or int(self.strain_limit_iterations) < 0:
            raise ValueError("substeps must be >= 1 and strain_limit_iterations >= 0")
        if len(self.gravity) != 3 or not all(math.isfinite(g) for g in self.gravity):
            raise ValueError("gravity must be three finite numbers")
        if not (self.air_damping >= 0 and self.stability_safety >= 0):
            raise ValueError("air_damping and stability_safety must be >= 0")
        if not 0.0 < self.strain_limit_relaxation < 2.0:
            raise ValueError("strain_limit_relaxation must be in (0, 2)")
        for lim in (self.strain_limit, self.shear_strain_limit, self.bend_strain_limit):
            if lim is not None and not (math.isfinite(lim) and lim >= 0):
                raise ValueError("strain limits must be finite and >= 0")


class SolverVerlet:
    """Mass-spring cloth solver (module docstring).

    Parameters
    ----------
    model : Model
    settings : VerletSettings, optional
    colliders : sequence
        Objects with ``project(x, x_prev, inv_mass)``; those that also have
        ``sphere_arrays()`` (:class:`vfit_engine.collide.spheres.SphereCollider`)
        run inside the fused kernel. ``colliders`` may be changed between frames.
    """

    def __init__(self, model, settings=None, colliders=()):
        from vfit_engine.garment.springs import BEND, SHEAR, STRUCTURAL, vertex_spring_adjacency
        from vfit_engine.kernels.strain_limit import colour_springs

        self.model = model
        self.settings = settings or VerletSettings()
        self.colliders = list(colliders)
        n = model.particle_count
        self._adj_off, self._adj_j, self._adj_spring = vertex_spring_adjacency(n, model.spring_indices)
        self._adj_rest = np.ascontiguousarray(model.spring_rest[self._adj_spring])
        self._si = np.ascontiguousarray(model.spring_indices[:, 0])
        self._sj = np.ascontiguousarray(model.spring_indices[:, 1])
        self._rest = np.ascontiguousarray(model.spring_rest)

        st = self.settings
        limit = model.max_strain if st.strain_limit is None else st.strain_limit
        lim_factor = np.full(model.spring_count, np.inf)
        lim_factor[model.spring_type == STRUCTURAL] = 1.0 + limit
        if st.shear_strain_limit is not None:
            lim_factor[model.spring_type == SHEAR] = 1.0 + st.shear_strain_limit
        if st.bend_strain_limit is not None:
            lim_factor[model.spring_type == BEND] = 1.0 + st.bend_strain_limit
        limited = np.nonzero(np.isfinite(lim_factor))[0]
        if st.parallel:
            order, self._colour_off = colour_springs(model.spring_indices[limited], n)
        else:
            # serial: classic Gauss-Seidel in spring order (sorted by vertex), which
            # carries corrections along rows and converges faster than colour order
            order, self._colour_off = np.arange(limited.size), np.array([0, limited.size], dtype=np.int64)
        sel = limited[order]
        self._lim_i = np.ascontiguousarray(model.spring_indices[sel, 0])
        self._lim_j = np.ascontiguousarray(model.spring_indices[sel, 1])
        self._lim_len = np.ascontiguousarray(model.spring_rest[sel] * lim_factor[sel])

        self._inv_mass = np.ascontiguousarray(model.inv_mass, dtype=np.float64).copy()
        self._gravity = np.ascontiguousarray(st.gravity, dtype=np.float64)
        self._x_new = np.zeros((n, 3))
        self._f = np.zeros((n, 3))
        self._gather = bool(self.settings.parallel if self.settings.gather is None else self.settings.gather)
        self._no_pins = np.zeros(0, np.int64)
        self._no_pin_pos = np.zeros((0, 3))
        self._pin_from = np.zeros((model.pin_count, 3))
        self._const_dt = None
        self.softened_fraction = 0.0

    # -- constants ---------------------------------------------------------
    def effective_constants(self, dt):
        """Spring constants after stability softening at step ``dt`` (s).

        Returns
        -------
        k : (s,) float64, N/m
        kd : (s,) float64, N s/m
        """
        m = self.model
        k = np.array(m.spring_k)
        kd = np.array(m.spring_kd)
        safety = self.settings.stability_safety
        if safety > 0 and m.spring_count:
            n = m.particle_count
            i, j = m.spring_indices[:, 0], m.spring_indices[:, 1]
            ksum = np.bincount(i, k, n) + np.bincount(j, k, n)
            dsum = np.bincount(i, kd, n) + np.bincount(j, kd, n)
            demand = m.inv_mass * (2.0 * ksum * dt * dt + 4.0 * dsum * dt)
            scale_v = np.ones(n)
            np.divide(4.0 * safety, demand, out=scale_v, where=demand > 4.0 * safety)
            scale = np.minimum(scale_v[i], scale_v[j])
            self.softened_fraction = float(np.mean(scale < 1.0))
            k *= scale
            kd *= scale
        return k, kd

    def _prepare(self, dt):
        if self._const_dt == dt:
            return
        k, kd = self.effective_constants(dt)
        self._k = np.ascontiguousarray(k)
        self._kd = np.ascontiguousarray(kd)
        self._adj_k = np.ascontiguousarray(k[self._adj_spring])
        self._adj_kd = np.ascontiguousarray(kd[self._adj_spring])
        self._c_air = 1.0 - math.exp(-self.settings.air_damping * dt)
        self._const_dt = dt

    # -- state ---------------------------------------------------------------
    def init_state(self, dt, pos=None, vel=None):
        """A state at ``pos`` (default rest) moving at ``vel`` (default 0), m and m/s.

        ``pos_prev = pos - vel dt + a0 dt^2 / 2`` with the initial acceleration
        ``a0`` (springs + gravity), so the first steps follow
        ``pos + vel t + a0 t^2 / 2`` (exactly, for free fall without air damping).
        """
        from vfit_engine.kernels.springs import eval_spring_forces_gather

        dt = float(dt)
        self._prepare(dt)
        m = self.model
        x = np.array(m.rest_pos if pos is None else pos, dtype=np.float64, order="C")
        if x.shape != (m.particle_count, 3):
            raise ValueError(f"pos must have shape ({m.particle_count}, 3)")
        v = np.zeros_like(x) if vel is None else np.broadcast_to(np.asarray(vel, dtype=np.float64), x.shape)
        f = eval_spring_forces_gather(x, x - v * dt, dt, self._adj_off, self._adj_j, self._adj_rest,
                                      self._adj_k, self._adj_kd)
        free = (self._inv_mass > 0)[:, None]
        a0 = np.where(free, self._inv_mass[:, None] * f + self._gravity, 0.0)
        v = np.where(free, v, 0.0)
        x_prev = x - v * dt + 0.5 * a0 * dt * dt
        return State(x, x_prev, dt)

    # -- stepping --------------------------------------------------------------
    def step(self, state, dt):
        """Advance ``state`` in place by one substep of ``dt`` (s); returns it."""
        return self._advance(state, float(dt), 1)

    def step_frame(self, state, frame_dt, substeps=None):
        """Advance ``state`` in place by ``frame_dt`` (s) in equal substeps; returns it."""
        n_sub = int(substeps or self.settings.substeps)
        return self._advance(state, float(frame_dt) / n_sub, n_sub)

    def _advance(self, state, dt, n_sub):
        from vfit_engine.kernels.integrate import substeps_parallel, substeps_serial

        if not dt > 0:
            raise ValueError("dt must be > 0")
        m = self.model
        if state.pos.shape != (m.particle_count, 3):
            raise ValueError("state does not belong to this model")
        self._prepare(dt)
        if dt != state.dt:
            # keep the velocity when the step changes: pos_prev is one *new* step back
            state.pos_prev[:] = state.pos - (state.pos - state.pos_prev) * (dt / state.dt)
            state.dt = dt

        fused, other = [], []
        for c in self.colliders:
            (fused if hasattr(c, "sphere_arrays") else other).append(c)
        if fused:
            parts = [c.sphere_arrays() for c in fused]
            sph = [np.ascontiguousarray(np.concatenate([p[q] for p in parts]), dtype=np.float64) for q in range(4)]
        else:
            sph = [np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0)]
        if state.pin_target is not None and m.pin_count:
            if state.pin_target.shape != (m.pin_count, 3):
                raise ValueError(f"pin_target must have shape ({m.pin_count}, 3)")
            pin_idx = m.pin_indices
            np.take(state.pos, pin_idx, axis=0, out=self._pin_from)
            pin_from, pin_to = self._pin_from, np.ascontiguousarray(state.pin_target, dtype=np.float64)
        else:
            pin_idx, pin_from, pin_to = self._no_pins, self._no_pin_pos, self._no_pin_pos

        st = self.settings
        mesh = [c for c in other if hasattr(c, "contact_args")]
        if mesh:
            if len(mesh) > 1 or fused:
                raise ValueError("a fused mesh-contact collider must be the only collider")
            self._advance_contacts(state, mesh[0], pin_idx, pin_from, pin_to, dt, n_sub)
            for c in other:
                if c is not mesh[0]:
                    c.project(state.pos, state.pos_prev, self._inv_mass)
            state.time += dt * n_sub
            state.step_count += n_sub
            return state
        kernel = substeps_parallel if self.settings.parallel else substeps_serial
        args_head = (state.pos, state.pos_prev, self._inv_mass, self._gravity, self._gather,
                     self._si, self._sj, self._rest, self._k, self._kd,
                     self._adj_off, self._adj_j, self._adj_rest, self._adj_k, self._adj_kd,
                     self._lim_i, self._lim_j, self._lim_len, self._colour_off,
                     int(st.strain_limit_iterations), float(st.strain_limit_relaxation),
                     sph[0], sph[1], sph[2], sph[3], pin_idx, pin_from, pin_to, dt, self._c_air)
        if not other:
            kernel(*args_head, 0, n_sub, n_sub, self._x_new, self._f)
        else:
            for s in range(n_sub):
                kernel(*args_head, s, s + 1, n_sub, self._x_new, self._f)
                for c in other:
                    c.project(state.pos, state.pos_prev, self._inv_mass)
        state.time += dt * n_sub
        state.step_count += n_sub
        return state

    def _advance_contacts(self, state, coll, pin_idx, pin_from, pin_to, dt, n_sub):
        """Substeps with the body contacts solved inside the strain-limit iterations
        (:mod:`vfit_engine.kernels.drape_step`); ``coll.contact_args()`` gives
        ``(mesh_args, skin, reach, friction, max_push, contact_damping)`` (contact damping a rate, 1/s)."""
        from vfit_engine.kernels.drape_step import drape_substeps

        n = self.model.particle_count
        if getattr(self, "_contact_owner", None) is not coll:
            self._contact_owner = coll
            self._x_last = np.zeros((n, 3))
            self._d_last = np.full(n, -np.inf)
            self._c_n = np.zeros((n, 3))
            self._c_nq = np.zeros(n)
            self._c_h = np.zeros(n)
            self._c_push = np.zeros(n)
            self._c_list = np.zeros(n, dtype=np.int64)
            self.contact_queries = 0
        mesh_args, skin, reach, friction, max_push, contact_damping = coll.contact_args()
        st = self.settings
        # the limited springs in serial order (colours only matter for the parallel kernel)
        self.contact_queries += drape_substeps(
            state.pos, state.pos_prev, self._inv_mass, self._gravity, self._si, self._sj, self._rest,
            self._k, self._kd, self._lim_i, self._lim_j, self._lim_len, int(st.strain_limit_iterations),
            float(st.strain_limit_relaxation), pin_idx, pin_from, pin_to, dt, self._c_air, 0, n_sub, n_sub,
            *mesh_args, float(skin), float(reach), float(friction), float(max_push),
            1.0 - math.exp(-float(contact_damping) * dt), float(getattr(coll, "reuse", 0.0)),
            self._x_last, self._d_last, self._c_n, self._c_nq, self._c_h, self._c_push, self._c_list, self._f)

    # -- diagnostics -------------------------------------------------------------
    def max_stretch(self, state, spring_type=0):
        """Largest ``l / l0 - 1`` among springs of ``spring_type`` (default structural)."""
        return self.model.max_stretch(state.pos, spring_type)

    def max_speed(self, state):
        """Largest particle speed, m/s."""
        return float(np.sqrt(np.max(np.sum(state.velocity() ** 2, axis=1)))) if state.particle_count else 0.0
