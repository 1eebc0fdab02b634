"""Animated fitting: the garment draped at rest, then simulated on the body moving through a clip.

:func:`run_animation` takes a drape's set-up and its settled result (:func:`vfit_engine.drape.prepare_drape`,
:func:`vfit_engine.drape.run_drape`: the drape path ``vfit drape`` runs) and a clip
(:mod:`vfit_engine.animate.motion`):

1. **poses**: the body and the garment's pins in every animation frame, the clip blended in from the A pose
   over ``blend_s`` (:class:`~vfit_engine.animate.motion.Poser`);
2. **collider**: the exact surface of the body parts the garment comes near in any frame
   (:mod:`vfit_engine.animate.colliders`), moving (:class:`vfit_engine.collide.moving_body.MovingBodyCollider`):
   one grid per frame, the surface where it is at every substep; or spheres fitted to the body that follow
   its bones (:class:`~vfit_engine.animate.colliders.BoneSpheres`);
3. **the cloth**: the drape's solver (:func:`vfit_engine.drape.loop.build_solver`: the same constraints,
   sweeps and openings; :class:`~vfit_engine.sim.solver_pd.SolverPD` when the drape's settings are projective,
   ``drape.settings.projective``, else :class:`~vfit_engine.sim.solver_verlet.SolverVerlet`, both taking the
   body's motion through ``body_moved``) from the settled drape; each frame is ``substeps`` substeps of the
   drape's step, the body moved between them (``body_every``) and the pins moved with it; the contacts
   (inelastic push, friction, contact damping) act on the cloth's velocity relative to the body's where it
   touches it: skin that moves carries the cloth on it (the seat of a skirt as its wearer sits down);
4. **figures** of every frame (:func:`frame_figures`): the cloth surface against the whole body (the drape's
   lattice of samples), yarn strain against the garment as given, contact pressure; and the time each part
   took.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from vfit_engine.animate.colliders import MovingBody
from vfit_engine.animate.motion import Poser
from vfit_engine.body.self_contact import ArmContact
from vfit_engine.drape.loop import DrapeDiverged, build_solver, run_drape
from vfit_engine.drape.metrics import surface_penetration, yarn_strain
from vfit_engine.drape.settings import DrapeSettings
from vfit_engine.errors import InputError
from vfit_engine.fit.maps import CONTACT_MM
from vfit_engine.fit.pressure import collider_pressure
from vfit_engine.sim.solver_settings import PDSettings

#: Colliders of an animation: the exact body near the garment, or spheres fitted to the body that follow its
#: bones (along the bones, or the medial cover).
COLLIDERS = ("mesh", "bone-spheres", "spheres")
#: The step (s) ``AnimateSettings.max_push`` is given per.
PUSH_DT = 1.0 / 480.0


@dataclass(frozen=True)
class AnimateSettings:
    """Settings of an animation (:func:`run_animation`).

    Attributes
    ----------
    fps : float, 1/s
        Animation frames per second (the frames written, the GLB's rate).
    frames : int
        Frames simulated after the rest drape.
    blend_s : float, s
        The clip is blended in from the A pose over this time (a smoothstep).
    body_every : int
        Substeps between two moves of the body (1: the body is where it is at every substep).
    max_push : float, m
        Longest push out of the body per 1/480 s (:data:`PUSH_DT`, the drape's Verlet substep): the body moves the
        cloth by pushing it, up to this much each such substep (a walking shin moves ~6 mm per substep of
        1/480 s); a solver with longer steps (the projective one's 1/120 s) pushes as much further each step.
    max_speed : float, m/s
        Cloth faster than this after a body move is slowed to it (its previous position moved up): cloth
        caught where the body closes on itself (the crease of a hip bent to sitting) is pushed from both
        sides and, unchecked, runs away (tens of m/s). A walking foot moves ~5 m/s; the report counts the
        vertices slowed in each frame.
    near : float, m
        The exact collider holds the body parts that come within this of the skin the draped garment covers
        in some frame (:func:`~vfit_engine.animate.colliders.reach_triangles`).
    surface_spacing : float or None, m
        Spacing of the contact points over the cloth's triangles while the body moves (None: the drape's,
        15 mm): a moving body pushes the cloth between them more than a still one rests on it (the suit's
        walk, 50 frames: 15 of 60 frames 2.0-2.9 mm deep at 15 mm, none over 1.43 mm at 10 mm), and a hand
        landing on a hem came between points 10 mm apart (the demo skirt in ``sit01.bvh``: frames 40-41 2.4 and
        2.7 mm deep at 10 mm; 0.04 mm at 7 mm, but 5.8 and 2.4 mm at 8 and 9 mm: where the points fall on the
        41 mm hem triangle decides whether the hand's edge catches it; a finer cloth would not depend on it).
    friction : float
        Coulomb coefficient of the cloth on the moving skin. The still drape's contacts hold 0.8, the grip of
        warm skin on resting cloth (static; it keeps trousers up); cloth that the body slides under moves at
        kinetic friction, lower (fabric on skin 0.25-0.9 by site and moisture: Temel, Johnson & Lloyd 2022, the
        figures of :mod:`vfit_engine.sim.materials`). At 0.8 the hand landing on the sitting skirt's lap held the
        hem while the knee rose and stretched it (strain p99 8.8-10.4 % in frames 40-56, 7 mm points); at 0.5 it
        stays within 7.4 % in all 360 frames, and the walking suit's trousers stay up (p99 5.5 %).
    skinning : {"dqs", "lbs"}
    collider : {"mesh", "bone-spheres", "spheres"}
    pd_iterations : int
        Global iterations a step of the projective solver (``drape.settings.projective``) while the body moves (the
        still drape's 5): the contact forces against a body part that moves centimetres a step must build up
        within the step. The walking suit (male_casualsuit02, 30 frames) meets the bars in every frame at 5 and
        at 10 (before a vertex that lost its contact points let go of its force, its trousers rode up the shins
        from frame 19-21 whatever the iterations); the sitting skirt does not yet (docs/patterns.md).
    stick : bool
        The contacts' friction holds the cloth's slip on the skin, not only its velocity
        (:class:`~vfit_engine.sim.solver_settings.ContactSettings`). Off: it holds stretched cloth stretched
        as well (the demo skirt in ``sit01.bvh``, 1.5 s blend: strain p99 18.4 % from frame 42 to the end of
        360 frames, against at most 6.4 % without it).
    """

    fps: float = 30.0
    frames: int = 60
    blend_s: float = 0.5
    body_every: int = 1
    max_push: float = 0.02
    max_speed: float = 8.0
    near: float = 0.05
    surface_spacing: float | None = 0.007
    friction: float = 0.5
    skinning: str = "dqs"
    collider: str = "mesh"
    pd_iterations: int = 10
    stick: bool = False

    def __post_init__(self):
        if not (math.isfinite(self.fps) and 1.0 <= self.fps <= 240.0):
            raise InputError(f"fps must be 1..240, got {self.fps!r}")
        if int(self.frames) < 1 or int(self.body_every) < 1 or int(self.pd_iterations) < 1:
            raise InputError("frames, body_every and pd_iterations must be >= 1")
        for name in ("blend_s", "max_push", "near", "friction"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise InputError(f"animate setting {name} must be >= 0")
        if self.collider not in COLLIDERS:
            raise InputError(f"unknown animation collider {self.collider!r}; use {' or '.join(COLLIDERS)}")


@dataclass
class AnimationResult:
    """What an animation produced.

    Attributes
    ----------
    pos : (n, 3) float64, m
        The cloth at the last frame.
    frames : int
    figures : list of dict
        :func:`frame_figures` of every frame (frame 0: the rest drape).
    timings : dict
        Seconds: ``posing`` (all frames' bodies and pins), ``collision`` (the collider's grids and surface per
        substep), ``cloth`` (the solver), ``figures``, and their sum ``simulation`` (posing + collision +
        cloth).
    info : dict
        ``substeps`` per frame, the collider's figures, the solver's ``contact_queries``.
    settled : bool or None
        For a clip that ends in a still pose: the cloth had come to rest by the last frame (the drape's
        settle test on the frames after the clip ended); None for a clip still moving.
    """

    pos: np.ndarray
    frames: int
    figures: list
    timings: dict
    info: dict = field(default_factory=dict)
    settled: bool | None = None


def smoothstep(x):
    """0 -> 1 with zero slope at both ends (the blend's weight)."""
    x = min(max(float(x), 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


def pose_frames(poser, clip, settings):
    """Bodies (f + 1, 13380, 3) m, pins (f + 1, p, 3) m, the bones' skinning matrices (f + 1, b, 3, 4) and the
    travel (f + 1, 3) m of frames 0..f: the clip at ``k / fps``, blended in.

    The root's vertical motion (a walk's bob) moves the body the cloth is simulated on; its horizontal path is
    the travel, added to what is written: the cloth is simulated in the frame that moves along it, which for a
    steady walk is the same physics (Galilean; the solver's air damping is numerical, not wind), and leaves out
    the path's accelerations (starting, stopping, turning)."""
    n = int(settings.frames) + 1
    bodies, pins, mats, travel = [], [], [], []
    for k in range(n):
        t = k / settings.fps
        w = smoothstep(t / settings.blend_s) if settings.blend_s > 0 else 1.0
        rot, root = clip.sample(t, blend=w)
        m = poser.matrices(rot, np.array([0.0, root[1], 0.0]))
        b, p = poser.skin_all(m)
        bodies.append(b)
        pins.append(p)
        mats.append(m)
        travel.append([root[0], 0.0, root[2]])
    return np.stack(bodies), np.stack(pins), np.stack(mats), np.array(travel)


def run_animation(setup, rest_pos, clip, model, settings=None, drape_settings=None, on_frame=None):
    """Simulate the garment of ``setup`` (settled at ``rest_pos``) on its body moving through ``clip``.

    Parameters
    ----------
    setup : DrapeSetup
        The drape's set-up (its body is the body animated; its pins follow the body).
    rest_pos : (n, 3) float64, m
        The settled drape.
    clip : Clip
    model : BodyModel
    settings : AnimateSettings or None
    drape_settings : DrapeSettings or None
        The drape's (solver, contacts, step).
    on_frame : callable or None
        ``on_frame(k, body, pos, figures, travel)`` for the rest drape (``k`` = 0) and after each frame
        (``body`` (13380, 3) and ``pos`` (n, 3) m are live arrays: copy them to keep them; ``travel`` (3,) m: the
        horizontal path to add to them, :func:`pose_frames`).

    Returns
    -------
    AnimationResult

    Raises
    ------
    DrapeDiverged
        The cloth blew up (NaN or runaway speed); the last good frame is kept in the exception.
    """
    st = settings or AnimateSettings()
    dst = drape_settings or DrapeSettings()
    timings = dict(setup=0.0, posing=0.0, collision=0.0, cloth=0.0, figures=0.0)
    t0 = time.perf_counter()
    rest_pos = np.ascontiguousarray(rest_pos, dtype=np.float64)
    pins = setup.pins.indices
    poser = Poser(model, setup.body.verts, pin_points=rest_pos[pins] if pins.size else None, method=st.skinning)
    t1 = time.perf_counter()
    bodies, pin_pos, mats, travel = pose_frames(poser, clip, st)
    if setup.body_parts is not None:  # hands laid on the body rest on its skin (skinning lets them sink in)

        arms = ArmContact(bodies[0], model.body_tris, setup.body_parts)
        for k in range(len(bodies)):
            bodies[k] = arms.apply(bodies[k])
    timings["posing"] = time.perf_counter() - t1
    body = MovingBody(setup, model, bodies, mats, rest_pos, st, dst)
    # no ground in motion (animate_garment says why)
    moving = dataclasses.replace(setup, collider=body.collider, ground=None) if st.collider == "mesh" else \
        dataclasses.replace(setup, collider_kind="spheres", spheres=body.spheres.at(0, 0.0), ground=None)
    if st.surface_spacing is not None:
        dst = dataclasses.replace(dst, surface_spacing=float(st.surface_spacing))
    dst = dataclasses.replace(dst, contact=dataclasses.replace(dst.contact, stick=bool(st.stick),
                                                               friction=float(st.friction)))
    if isinstance(dst.solver, PDSettings):  # the solver is the drape's: projective settings, SolverPD
        # without the still drape's stiffness damping: it resists a rotation as much as a stretch, and the cloth
        # lagged the swinging legs (the walk: 1 frame over the bars, 7.2 mm deep, against none and 0.5 mm)
        dst = dataclasses.replace(dst, solver=dataclasses.replace(dst.solver, iterations=int(st.pd_iterations),
                                                                  stiffness_damping=0.0))
    _, solver = build_solver(moving, dst)
    sub_dt = 1.0 / (dst.fps * dst.solver.substeps)
    substeps = max(int(round(1.0 / (st.fps * sub_dt))), 1)
    chunks = max(substeps // int(st.body_every), 1)
    per_chunk = substeps // chunks
    frame_dt = substeps * sub_dt
    state = solver.init_state(sub_dt, pos=rest_pos)
    solver.max_push = st.max_push * sub_dt / PUSH_DT
    timings["setup"] = time.perf_counter() - t0 - timings["posing"]
    figures = [frame_figures(setup, body, rest_pos, dst.solver.slack)]
    figures[0]["slowed_vertices"] = 0
    if on_frame is not None:
        on_frame(0, bodies[0], rest_pos, figures[0], travel[0])
    last_good = rest_pos.copy()
    step = np.zeros(len(rest_pos))
    for k in range(1, int(st.frames) + 1):
        slowed = _simulate_frame(k, body, solver, state, pin_pos if pins.size else None, chunks, per_chunk * sub_dt,
                                 per_chunk, st.max_speed, step, timings)
        speed = _fastest(state, step)
        if not (math.isfinite(speed) and speed <= dst.diverge_speed):
            what = "NaN/infinite positions" if not math.isfinite(speed) else f"a vertex at {speed:.3g} m/s"
            exc = DrapeDiverged(f"the animation diverged at frame {k} ({what}); last good frame {k - 1}",
                                frame=k, last_good=last_good.copy(), last_good_frame=k - 1)
            exc.figures, exc.body = figures, bodies[k - 1]  # what the frames so far measured
            raise exc
        np.copyto(last_good, state.pos)
        t0 = time.perf_counter()
        body.judge(k)  # the whole exact body at the frame's end, whatever the cloth met
        figures.append(frame_figures(setup, body, state.pos, dst.solver.slack))
        figures[-1]["slowed_vertices"] = slowed
        timings["figures"] += time.perf_counter() - t0
        if on_frame is not None:
            on_frame(k, bodies[k], state.pos, figures[-1], travel[k])
    timings["simulation"] = timings["posing"] + timings["collision"] + timings["cloth"]
    info = dict(solver=type(solver).__name__, substeps=substeps, substep_s=sub_dt, frame_s=frame_dt,
                body_moves_per_frame=chunks, contact_queries=int(solver.contact_queries),
                matrix_refactors=int(getattr(solver, "refactors", 0)), collider=body.describe(),
                clip=clip.description)
    return AnimationResult(state.pos.copy(), int(st.frames), figures, timings, info,
                           _settled(clip, figures, st, dst))


def _simulate_frame(k, body, solver, state, pin_pos, chunks, chunk_dt, per_chunk, max_speed, scratch, timings):
    """Frame ``k``: the body's grid for the frame, then ``chunks`` times the body moved on (and the pins with
    it) and ``per_chunk`` substeps of the cloth; returns the vertices slowed to ``max_speed``."""
    t0 = time.perf_counter()
    if body.spheres is None:
        body.advance(k)
    timings["collision"] += time.perf_counter() - t0
    slowed = 0
    for c in range(chunks):
        s = (c + 1) / chunks
        t0 = time.perf_counter()
        moved, spheres, velocity, sphere_velocity = body.at(k, s)
        solver.body_moved(moved, spheres, velocity, sphere_velocity)
        t1 = time.perf_counter()
        if pin_pos is not None:
            state.pin_target = pin_pos[k - 1] + s * (pin_pos[k] - pin_pos[k - 1])
        solver.step_frame(state, chunk_dt, substeps=per_chunk)
        slowed += _limit_speed(state, max_speed, scratch)
        timings["collision"] += t1 - t0
        timings["cloth"] += time.perf_counter() - t1
    return slowed


def _limit_speed(state, top, scratch):
    """Slow the vertices faster than ``top`` (m/s) over the last substep to it; returns how many."""
    d = state.pos - state.pos_prev
    np.sqrt(np.einsum("ij,ij->i", d, d), out=scratch)
    fast = scratch > top * state.dt
    if not fast.any():
        return 0
    state.pos_prev[fast] = state.pos[fast] - d[fast] * (top * state.dt / scratch[fast])[:, None]
    return int(np.count_nonzero(fast))


def _fastest(state, scratch):
    """Fastest vertex over the last substep, m/s (inf for non-finite positions)."""
    d = state.pos - state.pos_prev
    np.sqrt(np.einsum("ij,ij->i", d, d), out=scratch)
    top = float(scratch.max()) if scratch.size else 0.0
    return top / state.dt if math.isfinite(top) else math.inf


def _settled(clip, figures, st, dst):
    """For a clip that ends still: whether the cloth was at rest over the last frames (the drape's settle test:
    for ``settle_frames`` frames at most ``settle_share`` of the vertices moved more than ``settle_step`` per
    frame, none more than ``settle_max_step``); None when the clip still moves at the end."""
    end = clip.duration + st.blend_s
    if clip.looping or st.frames / st.fps < end:
        return None
    tail = [f for f in figures[1:] if f["time_s"] > end][-int(dst.settle_frames):]
    if len(tail) < int(dst.settle_frames):
        return False
    return all(f["share_moving"] <= dst.settle_share and f["max_step_mm"] <= 1000 * dst.settle_max_step for f in tail)


def frame_figures(setup, body, pos, slack):
    """The figures of one frame: the cloth surface against the body (``surface_inside_percent``,
    ``surface_max_depth_mm``, ``surface_deeper_than_2mm``: :func:`vfit_engine.drape.metrics.surface_penetration`),
    the yarn strain against the garment as given (``p99_strain``, ``max_strain``), the largest contact pressure
    (``pressure_max_kpa``, :func:`vfit_engine.fit.pressure.collider_pressure`) and how far the cloth moved since
    the last frame (``max_step_mm``, ``share_moving``). ``slack``: the strain the solver leaves free (the
    pressure's tension starts beyond it)."""
    mesh = setup.garment.mesh
    judge = body.whole
    judge.settle_bounds()  # exact centre distances now: points clear of the body are dismissed
    out = surface_penetration(judge, pos, mesh.triangles())
    strain = yarn_strain(mesh, pos)
    query = judge.query(pos, max_out=CONTACT_MM / 1000.0, max_in=np.inf)
    contact = (query[0] <= CONTACT_MM / 1000.0) & (query[3] >= 0)
    pressure = collider_pressure(mesh, pos, setup.material, judge, query, contact, slack)
    step = np.linalg.norm(pos - body.last_pos, axis=1) if body.last_pos is not None else np.zeros(len(pos))
    body.last_pos = pos.copy()
    out.update(p99_strain=strain["p99_strain"], max_strain=strain["max_strain"],
               pressure_max_kpa=float(pressure.max()) if pressure.size else 0.0, time_s=body.time,
               max_step_mm=1000.0 * float(step.max()) if step.size else 0.0,
               share_moving=float(np.mean(step > body.settle_step)) if step.size else 0.0)
    return out


def animate_garment(setup, clip, model, settings=None, drape_settings=None, on_drape_frame=None, on_frame=None):
    """The whole animated fitting: the garment draped at rest on the still body (:func:`vfit_engine.drape.
    run_drape`, the path ``vfit drape`` runs), then :func:`run_animation` from there.

    The rest drape has no ground under the body (the comment below says why).

    Returns
    -------
    (DrapeResult, AnimationResult)
    """
    # no ground, at rest or in motion: the motion is simulated in the body's own frame (pose_frames), where a
    # walk's stance foot slides back over the ground as on a treadmill. A still ground trapped a long hem under the
    # feet (a maxi skirt walking 30 frames: p99 strain 152 %), and so did the hem it had pooled on at rest without
    # it in motion (148 %); hanging through where the floor would be, the hem keeps 4.4 %.
    setup = dataclasses.replace(setup, ground=None)
    drape = run_drape(setup, drape_settings, on_frame=on_drape_frame)
    return drape, run_animation(setup, drape.pos, clip, model, settings, drape_settings, on_frame=on_frame)
