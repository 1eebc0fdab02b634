"""Run a drape: the cloth built on the garment's rest shape, untangled from the body, simulated until it settles.

:func:`run_drape` takes a :class:`~vfit_engine.drape.setup.DrapeSetup`:

1. the cloth (:class:`vfit_engine.sim.model.Model`) on the rest shape, with its contact points
   (:mod:`vfit_engine.sim.contact_points`) and the solver (:class:`vfit_engine.sim.solver_verlet.SolverVerlet`),
   whose constraints sweep outward from the pins and open round the openings the body forces wider;
2. the garment untangled from the body (:mod:`vfit_engine.sim.untangle`; exact mesh only): garments start
   partly inside the body (MakeHuman's by up to ~15 mm on its own average body), and the inside
   vertices are moved out along the sheet's own normal as a patch, with the pins put on their targets;
3. frames of ``solver.substeps`` substeps: the push out of the body per substep ramps from
   ``push_start`` to ``push_end`` and the pins move to their targets over ``ramp_frames``;
4. after each frame: divergence (non-finite positions, or a vertex faster than ``diverge_speed``)
   raises :class:`DrapeDiverged` at once, keeping the last good positions; the settle test
   (:meth:`~vfit_engine.drape.settings.DrapeSettings.settle_test`) ends the drape.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from vfit_engine.drape.metrics import drape_metrics
from vfit_engine.drape.refine import refine_setup
from vfit_engine.drape.settings import DrapeSettings
from vfit_engine.errors import VfitError
from vfit_engine.sim.contact_points import contact_points
from vfit_engine.sim.model import Model
from vfit_engine.sim.solver_pd import SolverPD
from vfit_engine.sim.solver_settings import PDSettings
from vfit_engine.sim.solver_verlet import SolverVerlet
from vfit_engine.sim.springs import STRUCTURAL
from vfit_engine.sim.untangle import untangle


class DrapeDiverged(VfitError):
    """The simulation blew up (NaN or runaway speed). Exit 4.

    Attributes
    ----------
    frame : int
    last_good : (n, 3) float64, m
        Positions after the last finite frame (the start if it was the first).
    last_good_frame : int
    """

    exit_code = 4

    def __init__(self, message, frame=0, last_good=None, last_good_frame=0):
        super().__init__(message)
        self.frame = frame
        self.last_good = last_good
        self.last_good_frame = last_good_frame


@dataclass
class DrapeResult:
    """What a drape produced.

    Attributes
    ----------
    pos : (n, 3) float64, m
        Final positions, the garment's vertex order.
    converged : bool
        The settle test passed.
    frames, steps : int
    sim_time, wall_time, setup_time : float, s
        Simulated time; the frame loop; building the cloth, solver and untangling.
    settle : dict
        The last frame's figures of the settle test: ``share_moving`` (fraction of vertices that moved
        more than ``settle_step`` in it), ``max_step_mm``, ``window_max_mm`` (largest move over the
        settled window, None before one), ``test`` (the test in words).
    metrics : dict
        :func:`vfit_engine.drape.metrics.drape_metrics`.
    info : dict
        Solver figures: ``untangle``, ``contact_points``, ``contact_queries``, ``softened_fraction``,
        ``refine`` (levels) and ``simulated_vertices``,
        ``implicit_hinges`` (the share of hinges too stiff for the explicit step, solved as constraints),
        ``softened_hinges`` (the share softened to the step's stability bound: round openings the body forces
        wider) and ``bending_kept`` (the share of the material's bending stiffness the drape carries: below 1
        the cloth bends more easily than the fabric there).
    fine : MeshData or None
        With ``DrapeSettings.refine``: the simulated (subdivided) cloth as it settled.
    """

    pos: np.ndarray
    converged: bool
    frames: int
    steps: int
    sim_time: float
    wall_time: float
    setup_time: float
    settle: dict
    metrics: dict
    info: dict = field(default_factory=dict)
    fine: object = None


def build_solver(setup, settings, garment=None):
    """The cloth model and solver of a drape (step 1). ``garment``: the setup of the garment as given when
    ``setup`` is its subdivided cloth (:mod:`vfit_engine.drape.refine`): the garment's own polygons, flat
    between its vertices, are held out of the body too (the drape is read back on them)."""
    fv, fo = setup.garment.mesh.face_verts, setup.garment.mesh.face_offsets
    model = Model.from_polygons(fv, fo, setup.rest, setup.material, pin_indices=setup.pins.indices)
    surface = settings.surface_spacing > 0
    points = contact_points(fv, fo, setup.rest, spacing=settings.surface_spacing, surface=surface)
    if garment is not None and surface:
        g = garment.garment.mesh
        points = points.joined(contact_points(g.face_verts, g.face_offsets, garment.rest,
                                              spacing=settings.surface_spacing))
    exact = setup.collider_kind == "mesh"
    kind = SolverPD if isinstance(settings.solver, PDSettings) else SolverVerlet
    solver = kind(model, settings.solver, settings.contact, body=setup.collider if exact else None,
                  spheres=setup.spheres, points=points, colliders=() if setup.project is None else [setup.project],
                  ground=setup.ground)
    solver.sweep_from(setup.pins.indices)
    if setup.seams.size:
        if not isinstance(solver, SolverPD):
            raise ValueError("sewing a pattern needs the projective solver (vfit_engine.drape.settings.projective)")
        solver.sew(setup.seams)
    for zone, strain in setup.zones:
        # the cloth round an opening the body forces wider may stretch that far, and it starts there
        solver.allow_stretch(zone, strain)
        solver.admit(setup.start, zone)
    if settings.admit_gap > 0 and not setup.info["transfer"]["identity"] and setup.info["rest"] == "garment":
        d, _, _, _ = setup.collider.query(setup.start, max_out=settings.admit_gap, max_in=np.inf)
        solver.admit(setup.start, np.flatnonzero(d < settings.admit_gap))
    return model, solver


def _untangled_start(setup, settings, model):
    """The start moved out of the body (step 2), pins on their targets; (positions, info)."""
    start = setup.start.copy()
    start[setup.pins.indices] = setup.pins.targets
    if not (settings.untangle and setup.collider_kind == "mesh"):
        return start, None
    sel = model.spring_type == STRUCTURAL
    return untangle(start, setup.garment.mesh.face_verts, setup.garment.mesh.face_offsets, setup.collider,
                    model.spring_indices[sel], model.spring_rest[sel] * (1.0 + settings.untangle_strain),
                    settings.contact.skin, pinned=setup.pins.indices, max_iterations=int(settings.untangle_iterations))


class _Sewing:
    """A pattern's sewing over the first frames (``DrapeSettings.sew_frames``): gravity off, each seam no longer
    than its gap at the start shrunk to 0 by ``sew_close`` of them; nothing when there are no seams."""

    def __init__(self, solver, seams, start, st):
        self.solver, self.st = solver, st
        self.frames = int(st.sew_frames) if seams.size else 0
        if self.frames:
            solver.weigh(0.0)
            self.gap = np.linalg.norm(start[seams[:, 0]] - start[seams[:, 1]], axis=1)

    def frame(self, frame):
        """Set the seams' lengths (and gravity) for ``frame`` (from 1)."""
        if frame <= self.frames:
            self.solver.close_seams(self.gap * max(1.0 - frame / (self.st.sew_close * self.frames), 0.0))
        elif frame == self.frames + 1 and self.frames:
            self.solver.weigh(1.0)


class _SettleTest:
    """The settle test of :class:`~vfit_engine.drape.settings.DrapeSettings`, with scratch arrays."""

    def __init__(self, st, n, start):
        self.st, self.n = st, n
        self.prev, self.anchor = start.copy(), start.copy()
        self.step = np.zeros(n)
        self.d = np.zeros((n, 3))
        self.run = 0
        self.share = self.max_step = 0.0
        self.window = None

    def _dist(self, a, b, out):
        np.subtract(a, b, out=self.d)
        np.multiply(self.d, self.d, out=self.d)
        np.sum(self.d, axis=1, out=out)
        np.sqrt(out, out=out)
        return out

    def frame(self, pos, after_ramp):
        """Judge the frame that ended at ``pos``; True when the cloth has settled."""
        st = self.st
        step = self._dist(pos, self.prev, self.step)
        self.max_step = float(step.max()) if self.n else 0.0
        self.share = float(np.count_nonzero(step > st.settle_step)) / max(self.n, 1)
        still = after_ramp and self.share <= st.settle_share and self.max_step <= st.settle_max_step
        if still and self.run == 0:
            np.copyto(self.anchor, self.prev)  # the window starts where the first still frame started
        np.copyto(self.prev, pos)
        self.run = self.run + 1 if still else 0
        if self.run < st.settle_frames:
            return False
        self.window = float(self._dist(pos, self.anchor, self.step).max()) if self.n else 0.0
        if self.window <= st.settle_max_step:
            return True
        self.run = 0  # a slow creep: start a new window
        return False

    def speed(self, state):
        """Fastest vertex over the last substep, m/s (inf when a position is not finite)."""
        step = self._dist(state.pos, state.pos_prev, self.step)
        top = float(step.max()) if self.n else 0.0
        return top / state.dt if math.isfinite(top) else math.inf

    def figures(self):
        return dict(share_moving=self.share, max_step_mm=1000.0 * self.max_step,
                    window_max_mm=None if self.window is None else 1000.0 * self.window, test=self.st.settle_test())


def run_drape(setup, settings=None, on_frame=None):
    """Simulate the drape of a :class:`DrapeSetup` until it settles (module docstring).

    Parameters
    ----------
    setup : DrapeSetup
    settings : DrapeSettings or None
    on_frame : callable or None
        ``on_frame(frame, pos, moving)`` after each good frame (frame counts from 1; ``moving``: the share
        of the vertices that moved more than ``settle_step`` in it, the settle test's; ``pos`` is the live
        (n, 3) array: copy it to keep it).

    Returns
    -------
    DrapeResult

    Raises
    ------
    DrapeDiverged
    """
    st = settings or DrapeSettings()
    t0 = time.perf_counter()
    sim, n = setup, setup.garment.mesh.n_verts  # sim: the cloth simulated; its first n vertices are the garment's
    if st.refine:
        sim, _ = refine_setup(setup, st.refine)
    model, solver = build_solver(sim, st, garment=setup if st.refine else None)
    start, untangle_info = _untangled_start(sim, st, model)
    frame_dt = 1.0 / st.fps
    state = solver.init_state(frame_dt / st.solver.substeps, pos=start)
    pin_from, pin_to = start[sim.pins.indices].copy(), sim.pins.targets
    pin_now = pin_from.copy()
    settle = _SettleTest(st, model.particle_count, start)
    last_good = start.copy()
    setup_time = time.perf_counter() - t0
    t0 = time.perf_counter()
    ramp = max(int(st.ramp_frames), 1)
    converged, frame = False, 0
    sewing = _Sewing(solver, setup.seams, start, st)
    for frame in range(1, int(st.max_frames) + 1):
        sewing.frame(frame)
        if frame == st.slow_frames + 1 and st.slow_iterations > solver.settings.iterations:
            solver.set_iterations(st.slow_iterations)  # still moving: DrapeSettings.slow_frames says why
        alpha = min(frame / ramp, 1.0)
        push = st.push_start + alpha * (st.push_end - st.push_start)
        solver.max_push = push
        if setup.project is not None:
            setup.project.max_push = push
        if pin_to.size:
            np.subtract(pin_to, pin_from, out=pin_now)
            pin_now *= alpha
            pin_now += pin_from
            state.pin_target = pin_now
        solver.step_frame(state, frame_dt)
        speed = settle.speed(state)
        if not (math.isfinite(speed) and speed <= st.diverge_speed):
            what = "NaN/infinite positions" if not math.isfinite(speed) else f"a vertex at {speed:.3g} m/s"
            raise DrapeDiverged(f"simulation diverged at frame {frame} ({what}); last good frame {frame - 1}",
                                frame=frame, last_good=last_good[:n].copy(), last_good_frame=frame - 1)
        np.copyto(last_good, state.pos)
        settled = settle.frame(state.pos, frame >= max(ramp, sewing.frames + 1))
        if on_frame is not None:
            on_frame(frame, state.pos[:n], settle.share)
        if settled:
            converged = True
            break
    wall = time.perf_counter() - t0
    pos = state.pos[:n].copy()
    info = dict(refine=int(st.refine), simulated_vertices=int(model.particle_count),
                untangle=untangle_info, contact_points=solver.points.count, contact_queries=int(solver.contact_queries),
                softened_fraction=solver.softened_fraction, implicit_hinges=round(solver.implicit_hinges, 4),
                softened_hinges=round(solver.softened_hinges, 4),
                bending_kept=round(solver.bending_kept, 4), constraints=int(solver.constraint_count),
                iterations=int(solver.settings.iterations))
    return DrapeResult(pos, converged, frame, int(state.step_count), float(state.time), wall, setup_time,
                       settle.figures(), drape_metrics(setup, pos), info,
                       sim.garment.mesh.with_verts(state.pos) if st.refine else None)
