"""Drape a garment on a body: the frame loop, pins that follow the body, convergence and divergence.

One drape (:func:`drape`) is:

1. a cloth :class:`~vfit_engine.sim.model.Model` built on the garment as given (its rest lengths
   are the garment's own edge lengths: MakeHuman clothes are modelled on the default body of
   their gender, so they start unstretched there);
2. pins (:class:`~vfit_engine.sim.pin_fit.PinAttachment`): each pinned garment vertex is bound to the nearest point of the
   *reference* body (the body the garment was modelled on) as a triangle, barycentric
   coordinates and a normal offset; on the *current* body the same triangle gives its target,
   so pins follow a morphed body. Offsets are clamped to at least the collider skin so a pin
   never sits inside the body. On a morphed body a pinned waistband is spread evenly and a
   pinned patch (shoulders) moved rigidly where following the triangles would stretch the cloth
   (:mod:`vfit_engine.sim.pin_fit`). Pins move to their targets over the first ``ramp_frames`` (at
   once when the garment is untangled, step 3);
3. the garment is untangled (:mod:`vfit_engine.sim.untangle`, mesh collider): garments usually
   start partly inside the body (up to ~13 mm on the default body, more on a wider one), and
   inside vertices are moved out along the sheet's own normal as a patch, under a looser strain
   limit (``untangle_strain``), with no gravity; the pins are put on their targets first;
4. the strain limiter is swept outward from the pins (:func:`vfit_engine.sim.limiter.order_from_pins`),
   and the cloth round an opening too small for the body part it goes round may stretch as far
   as it must (``stretch_zones``, :func:`vfit_engine.sim.limiter.relax_zone`);
5. frames of ``substeps`` Verlet substeps (:class:`~vfit_engine.sim.solver_verlet.SolverVerlet`)
   whose body contacts are solved inside the strain-limit iterations
   (:mod:`vfit_engine.kernels.drape_step`): what the untangling left inside comes out by at
   most ``max_push`` per substep, and ``max_push`` ramps from ``push_start`` to ``push_end``
   over ``ramp_frames``: a sudden push of centimetres would stretch the springs around it
   and launch the cloth;
6. after each frame: divergence (non-finite positions, or a particle faster than
   ``diverge_speed``) raises :class:`DrapeDiverged` at once, keeping the last good positions;
   the cloth has settled when, for ``settle_frames`` consecutive frames after the ramp, the
   99th percentile of the particles' mean speeds over the frame stays below ``settle_speed``
   and, over those frames as a whole, the fastest particle's mean speed is below
   ``settle_max_speed`` (a few particles in contact may jitter in place by a fraction of a
   millimetre from frame to frame with no net motion; ``settings['frame_speed']`` reports the
   fastest particle and ``settings['frame_speed_quantile']`` the percentile at the last frame,
   ``settings['window_speed']`` the fastest over the last settled window).

Before all this :func:`drape_garment` can move the garment from the body it was modelled on to the
target body (:func:`vfit_engine.garment.transfer.transfer_garment`, ``transfer=``): the cloth then starts there, while its rest
lengths stay the garment's own and the pins are attached and fitted as above.

:func:`vfit_engine.sim.metrics.drape_metrics` measures the result against the exact body mesh (penetration depth and
count, structural strain); :mod:`vfit_engine.sim.report` turns a result into ``report.json``.
Everything is SI (m, s), Y up.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from vfit_engine.errors import InputError, VfitError
from vfit_engine.sim.colliders import COLLIDERS, LimitedPush, RampedMesh, fit_collider
from vfit_engine.sim.limiter import order_from_pins, relax_zone
from vfit_engine.sim.metrics import drape_metrics, edge_strain
from vfit_engine.sim.pin_fit import PinAttachment  # noqa: F401  (public here too)


#: hm08 vertex counts: the visible body, and with the helpers the mhclo bindings read.
_HM08_BODY, _HM08_ALL = 13380, 19158


class DrapeDiverged(VfitError):
    """The simulation blew up (NaN or runaway speed). Exit 4.

    Attributes
    ----------
    frame : int
        The frame at which divergence was detected.
    last_good : (n, 3) float64, m, or None
        Positions after the last finite frame (the initial ones if it was the first).
    last_good_frame : int
    transfer : dict or None
        The transfer info (:func:`drape_garment`), when raised from there.
    """

    exit_code = 4
    transfer = None

    def __init__(self, message, frame=0, last_good=None, last_good_frame=0):
        super().__init__(message)
        self.frame = frame
        self.last_good = last_good
        self.last_good_frame = last_good_frame


@dataclass(frozen=True)
class DrapeSettings:
    """Settings of a drape (module docstring); the defaults are the tuned drape settings.

    Attributes
    ----------
    fps : float, 1/s
        Frames per simulated second (a frame is the unit of output and of the convergence test).
    max_frames : int
        Frames simulated at most; not settled by then means not converged.
    substeps : int
        Verlet substeps per frame.
    strain_limit : float or None
        Provot limit of structural and bend springs; None: the material's ``max_strain``, capped at
        ``strain_cap``.
    strain_cap : float
        Largest strain limit used when ``strain_limit`` is None (keeps knits near their rest size).
    strain_iterations : int
        Gauss-Seidel sweeps of the strain limiter per substep.
    strain_relaxation : float
        Over-relaxation of the strain limiter.
    air_damping : float, 1/s
    skin : float, m
        Clearance the body collider keeps (also the smallest pin offset).
    friction : float
        Coulomb coefficient of cloth on body.
    push_start, push_end : float, m
        Longest collision correction per substep at the first frame and after the ramp.
    ramp_frames : int
        Frames over which ``max_push`` ramps and pins move to their targets on the body.
    settle_speed : float, m/s
        A frame counts as settled when the ``settle_quantile`` quantile of the particles' mean
        speeds over the frame (``|x(frame) - x(frame - 1)| / frame time``) is below this ...
    settle_quantile : float
        ... (0.99: the 99th percentile) ...
    settle_max_speed : float, m/s
        ... and the drape ends after ``settle_frames`` such frames in a row if the fastest
        particle's mean speed over those frames together is below this.
    settle_frames : int
        Consecutive settled frames that end the drape.
    diverge_speed : float, m/s
        A particle faster than this means the simulation has diverged.
    sphere_skin : float
        Relative skin of the sphere collider (``--collider spheres``).
    untangle : bool
        Move the garment out of the body before the dynamics (:mod:`vfit_engine.sim.untangle`;
        mesh collider only), with strain limit ``max(limit, untangle_strain)`` and at most
        ``untangle_iterations`` iterations.
    untangle_strain : float;  untangle_iterations : int
    contact_damping : float, 1/s
        Decay rate of the tangential velocity of cloth the body pushes (mesh collider).
    spheres_per_bone : int
        Spheres along each bone of the ``bone-spheres`` collider.
    stretch_zone : float, m
        Width of the cloth round a too-small opening whose strain limit is raised
        (``stretch_zones`` of :func:`drape`).
    contact_reuse : float, m
        A particle in contact that moved less than this since its last exact body query keeps
        that query's tangent plane (:mod:`vfit_engine.kernels.drape_step`); 0 queries every substep.
    pin_strain : float
        A pin whose garment edge to another pin would be stretched more than this on the
        target body is released (:func:`drape_garment`).
    pin_fit_strain : float
        A pinned loop (waistband) some spring of which following the body would stretch more than
        this is refitted evenly on the body (:mod:`vfit_engine.sim.pin_fit`).
    """

    fps: float = 60.0
    max_frames: int = 400
    substeps: int = 8
    strain_limit: float | None = None
    strain_cap: float = 0.015
    strain_iterations: int = 14
    strain_relaxation: float = 1.0
    air_damping: float = 5.0
    skin: float = 0.002
    friction: float = 0.8
    push_start: float = 0.0002
    push_end: float = 0.005
    ramp_frames: int = 40
    settle_speed: float = 0.005
    settle_frames: int = 8
    settle_quantile: float = 0.99
    pin_strain: float = 0.03
    pin_fit_strain: float = 0.015
    settle_max_speed: float = 0.03
    diverge_speed: float = 20.0
    sphere_skin: float = 0.02
    untangle: bool = True
    untangle_strain: float = 0.08
    untangle_iterations: int = 60
    contact_damping: float = 60.0
    contact_reuse: float = 0.0005
    stretch_zone: float = 0.03
    spheres_per_bone: int = 4

    def __post_init__(self):
        if not 0.0 < self.settle_quantile <= 1.0:
            raise InputError(f"drape setting settle_quantile must be in (0, 1], got {self.settle_quantile!r}")
        for name in ("fps", "skin", "push_start", "push_end", "settle_speed", "settle_max_speed", "diverge_speed"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"drape setting {name} must be a positive number, got {value!r}")
        for name in ("max_frames", "substeps", "settle_frames"):
            if int(getattr(self, name)) < 1:
                raise InputError(f"drape setting {name} must be >= 1")
        if int(self.ramp_frames) < 0:
            raise InputError("drape setting ramp_frames must be >= 0")

    def limit_for(self, material):
        """The strain limit used with ``material`` (a Material)."""
        if self.strain_limit is not None:
            return float(self.strain_limit)
        return float(min(material.max_strain, self.strain_cap))


@dataclass
class DrapeResult:
    """What a drape produced.

    Attributes
    ----------
    pos : (n, 3) float64, m
        Final garment positions, input vertex order.
    frames : int
    steps : int
        Substeps simulated.
    sim_time : float, s
    wall_time : float, s
        Frame loop only (setup excluded; see ``setup_time``).
    setup_time : float, s
        Cloth model, colliders and pins.
    collide_time : float, s
        Wall time inside a stand-alone collider projection (0 for the mesh collider, whose
        contacts run inside the fused substep kernel; ``settings['contact_queries']`` counts
        its mesh queries).
    converged : bool
    max_speed : float, m/s
        Fastest particle at the last frame.
    metrics : dict
        :func:`drape_metrics` of ``pos``.
    settings : dict
    softened_fraction : float
        Share of springs the solver softened for stability.
    pin_indices : (p,) int64 or None;  pin_targets : (p, 3) float64 m or None
        Pinned vertices and where they end (set by :func:`drape_garment`).
    openings : list of dict or None
        The garment's openings against the body parts they go round, with the strain each
        must take at least (:func:`vfit_engine.garment.openings.check_openings`; set by
        :func:`drape_garment`).
    """

    pos: np.ndarray
    frames: int
    steps: int
    sim_time: float
    wall_time: float
    setup_time: float
    collide_time: float
    converged: bool
    max_speed: float
    metrics: dict
    settings: dict = field(default_factory=dict)
    softened_fraction: float = 0.0
    pin_indices: np.ndarray | None = None
    pin_targets: np.ndarray | None = None
    openings: list | None = None


def drape(garment_pos, face_verts, face_offsets, body_verts, body_tris, material="cotton", pins=None,
          collider="mesh", settings=None, body_collider=None, on_frame=None, start_pos=None, segments=None,
          stretch_zones=None, bones=None):
    """Drape a garment on a body.

    Parameters
    ----------
    garment_pos : (n, 3) float64, m
        Garment as given: the cloth's rest shape (and its start unless ``start_pos`` is given).
    face_verts : (k,) int64;  face_offsets : (m + 1,) int64
        The garment's polygons (flat, as in MeshData).
    body_verts : (N, 3) float64, m
        The body to drape on (N >= max(body_tris) + 1).
    body_tris : (T, 3) int64
        Outward-wound body triangles.
    material : str, Path or Material
    pins : (PinAttachment, (p, 3) float64 m) or None
        Attachment and the pins' targets on this body (:meth:`PinAttachment.positions`).
    collider : {"mesh", "spheres", "bone-spheres", "ellipsoids", "hulls"}
        The exact body, or shapes fitted to it (:data:`COLLIDERS`): spheres covering the body
        (:mod:`vfit_engine.collide.auto_spheres`), ``spheres_per_bone`` spheres along each bone with
        radii from the body's sections (:mod:`vfit_engine.collide.bone_spheres`), an ellipsoid per
        body part, or convex hulls per part with spheres at the joints.
    settings : DrapeSettings or None
    body_collider : MeshCollider or None
        Reused if given (must be built on ``body_verts``; its skin/friction are overridden).
    on_frame : callable or None
        ``on_frame(frame, pos, state)`` after each good frame (frame counts from 1; pos is the
        live (n, 3) array: copy it to keep it).
    start_pos : (n, 3) float64, m, or None
        Where the cloth starts (e.g. the garment transferred to this body, :func:`vfit_engine.garment.transfer.transfer_garment`);
        None: ``garment_pos``. The rest lengths stay those of ``garment_pos``.
    segments : ((N,) int64, list of str) or None
        Body part label of every body vertex and the part names
        (:func:`vfit_engine.body.segment.segment`); needed by ``ellipsoids`` and ``hulls``.
    bones : list of ((3,), (3,)) float64 m or None
        Head and tail of the body's bones (:func:`vfit_engine.collide.bone_spheres.skeleton_bones`);
        needed by ``bone-spheres``.
    stretch_zones : list of ((L,) int64, float) or None
        Openings that must stretch by at least the given strain to go round the body
        (:func:`vfit_engine.garment.openings.check_openings`): the strain limit of the cloth within
        ``st.stretch_zone`` of each is raised to that strain, so the opening stretches evenly
        instead of the limiter tearing one edge open.

    Returns
    -------
    DrapeResult

    Raises
    ------
    DrapeDiverged
        NaN/inf positions or a particle faster than ``settings.diverge_speed``.
    """
    from vfit_engine.collide.body_mesh import MeshCollider
    from vfit_engine.sim.materials import resolve_material
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_verlet import SolverVerlet, VerletSettings

    st = settings or DrapeSettings()
    t_setup = time.perf_counter()
    mat = resolve_material(material)
    pos0 = np.ascontiguousarray(garment_pos, dtype=np.float64)
    body_verts = np.ascontiguousarray(body_verts, dtype=np.float64)
    body_tris = np.ascontiguousarray(body_tris, dtype=np.int64)
    pin_idx = pins[0].indices if pins is not None else np.zeros(0, np.int64)
    model = Model.from_polygons(face_verts, face_offsets, pos0, mat, pin_indices=pin_idx)
    limit = st.limit_for(mat)
    vs = VerletSettings(substeps=int(st.substeps), air_damping=st.air_damping, strain_limit=limit,
                        bend_strain_limit=limit, strain_limit_iterations=int(st.strain_iterations),
                        strain_limit_relaxation=st.strain_relaxation, parallel=False)
    if body_collider is None:
        body_collider = MeshCollider(body_verts, body_tris, skin=st.skin, friction=st.friction)
    else:
        body_collider.skin, body_collider.friction = float(st.skin), float(st.friction)
    ramped = RampedMesh(body_collider, st.push_start, damping=st.contact_damping, reuse=st.contact_reuse)
    timed = None
    if collider == "mesh":
        colliders = [ramped]
    elif collider in COLLIDERS:
        timed = LimitedPush(fit_collider(collider, body_verts, body_tris, body_collider, segments, st, bones))
        colliders = [timed]
    else:
        raise InputError(f"unknown collider {collider!r}; use one of {', '.join(COLLIDERS)}")
    solver = SolverVerlet(model, vs, colliders)
    if pin_idx.size:
        order_from_pins(solver, pin_idx, model.particle_count)
    for loop, strain in stretch_zones or ():
        relax_zone(solver, model, loop, strain, limit, st.stretch_zone)
    frame_dt = 1.0 / st.fps
    dt = frame_dt / int(st.substeps)
    pin_to = np.zeros((0, 3)) if pins is None else np.ascontiguousarray(pins[1], dtype=np.float64)
    given = pos0 if start_pos is None else np.ascontiguousarray(start_pos, dtype=np.float64)
    start = given
    if start.shape != pos0.shape:
        raise InputError(f"start positions {start.shape} do not match the garment {pos0.shape}")
    untangle_info = None
    if collider == "mesh" and st.untangle:
        from vfit_engine.sim.untangle import untangle

        start = start.copy()
        start[pin_idx] = pin_to
        start, untangle_info = untangle(start, face_verts, face_offsets, body_collider,
                                        np.stack([solver._lim_i, solver._lim_j], axis=1),
                                        solver._lim_len * ((1.0 + max(limit, st.untangle_strain)) / (1.0 + limit)),
                                        st.skin, pinned=pin_idx, max_iterations=int(st.untangle_iterations))
    state = solver.init_state(dt, pos=start)
    n = model.particle_count
    pin_from = start[pin_idx].copy()
    pin_now = pin_from.copy()
    # scratch for the per-frame checks (no allocation inside the frame loop)
    last_good = given.copy()
    anchor = given.copy()
    window_speed = math.inf
    disp = np.zeros((n, 3))
    speed2 = np.zeros(n)
    setup_time = time.perf_counter() - t_setup

    t0 = time.perf_counter()
    settled_run = 0
    converged = False
    max_speed = 0.0
    frame_speed = frame_speed_q = 0.0
    q_index = min(max(int(math.ceil(st.settle_quantile * n)) - 1, 0), max(n - 1, 0))
    frame = 0
    ramp = max(int(st.ramp_frames), 1)
    for frame in range(1, int(st.max_frames) + 1):
        alpha = min(frame / ramp, 1.0)
        ramped.max_push = st.push_start + alpha * (st.push_end - st.push_start)
        if timed is not None:
            timed.max_push = ramped.max_push
        if pin_idx.size:
            np.subtract(pin_to, pin_from, out=pin_now)
            pin_now *= alpha
            pin_now += pin_from
            state.pin_target = pin_now
        solver.step_frame(state, frame_dt)
        np.subtract(state.pos, state.pos_prev, out=disp)
        np.multiply(disp, disp, out=disp)
        np.sum(disp, axis=1, out=speed2)
        top = float(speed2.max()) if n else 0.0
        max_speed = math.sqrt(top) / state.dt if math.isfinite(top) else math.inf
        if not (math.isfinite(max_speed) and max_speed <= st.diverge_speed):
            what = "NaN/infinite positions" if not math.isfinite(max_speed) else f"a particle at {max_speed:.3g} m/s"
            raise DrapeDiverged(f"simulation diverged at frame {frame} ({what}); last good frame {frame - 1}",
                                frame=frame, last_good=last_good.copy(), last_good_frame=frame - 1)
        # settling is judged on each particle's mean velocity over the frame, so a substep-level
        # jitter of a few springs (zero net motion) does not hold the drape open
        np.subtract(state.pos, last_good, out=disp)
        np.multiply(disp, disp, out=disp)
        np.sum(disp, axis=1, out=speed2)
        frame_speed = math.sqrt(float(speed2.max())) / frame_dt if n else 0.0
        # the settle statistic: a quantile of the frame speeds (a handful of particles jittering in
        # place on the body by a fraction of a mm must not hold the drape open); the fastest
        # particle is bounded over the whole window below
        frame_speed_q = math.sqrt(float(np.partition(speed2, q_index)[q_index])) / frame_dt if n else 0.0
        quiet = frame >= ramp and frame_speed_q < st.settle_speed
        if quiet and settled_run == 0:
            np.copyto(anchor, last_good)  # the window of the run starts at the previous frame
        np.copyto(last_good, state.pos)
        if on_frame is not None:
            on_frame(frame, state.pos, state)
        if quiet:
            settled_run += 1
            if settled_run >= st.settle_frames:
                # the fastest particle's mean speed over the whole window: a particle in contact
                # jittering in place by a fraction of a millimetre has no net motion
                np.subtract(state.pos, anchor, out=disp)
                np.multiply(disp, disp, out=disp)
                np.sum(disp, axis=1, out=speed2)
                window_speed = math.sqrt(float(speed2.max())) / (settled_run * frame_dt) if n else 0.0
                if window_speed < st.settle_max_speed:
                    converged = True
                    break
                settled_run = 0
        else:
            settled_run = 0
    wall = time.perf_counter() - t0
    pos = state.pos.copy()
    settings_out = asdict(st)
    settings_out.update(strain_limit_used=limit, material=mat.to_dict(), collider=collider, untangle=untangle_info,
                        contact_queries=int(getattr(solver, "contact_queries", 0)),
                        frame_speed=frame_speed, frame_speed_quantile=frame_speed_q, window_speed=window_speed)
    return DrapeResult(
        pos=pos, frames=frame, steps=int(state.step_count), sim_time=float(state.time), wall_time=wall,
        setup_time=setup_time, collide_time=ramped.seconds if timed is None else timed.seconds, converged=converged, max_speed=max_speed,
        metrics=drape_metrics(model, pos, body_collider), settings=settings_out,
        softened_fraction=solver.softened_fraction,
    )


def read_pin_file(path, vertex_count):
    """Garment vertex indices (0-based, one per line; blank lines and ``#`` comments skipped).

    Raises
    ------
    InputError
        Unreadable file, a line that is not an integer, or an index outside ``0..vertex_count-1``.
    """
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read pin file {path}: {getattr(exc, 'strerror', None) or exc}") from None
    out = []
    for no, line in enumerate(lines, 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        try:
            value = int(text)
        except ValueError:
            raise InputError(f"pin file {path}, line {no}: {text!r} is not a vertex index") from None
        if not 0 <= value < vertex_count:
            raise InputError(f"pin file {path}, line {no}: vertex {value} does not exist "
                             f"(garment has {vertex_count})")
        out.append(value)
    return np.unique(np.array(out, dtype=np.int64))


def drape_garment(garment_mesh, pieces, body_verts, reference_verts, body_tris, material="cotton", pin="auto",
                  collider="mesh", settings=None, body_collider=None, on_frame=None, transfer="none", mhclo=None,
                  start_verts=None, rest="garment", segments=None, bones=None):
    """Pick and attach pins, then :func:`drape` a garment on a body.

    Parameters
    ----------
    garment_mesh : MeshData
        Garment in m, placed where it was modelled (on ``reference_verts``).
    pieces : (n,) int64 or None
        Piece label per garment vertex (``Garment.pieces``).
    body_verts : (N, 3) float64, m
        The body to drape on.
    reference_verts : (N, 3) float64, m
        The body the garment was modelled on (same topology): pins are bound to it and follow
        ``body_verts``. Pass ``body_verts`` when unknown.
    body_tris : (T, 3) int64
    material, collider, settings, body_collider, on_frame, segments, bones
        As in :func:`drape`.
    pin : "auto", "none" or (p,) int64
        ``auto``: :func:`vfit_engine.garment.pins.auto_pins` on ``body_verts``.
    transfer : str
        :func:`vfit_engine.garment.transfer.transfer_garment` method moving the garment from ``reference_verts`` to
        ``body_verts`` before the drape ("none": it starts where it is). The cloth's rest lengths
        stay the garment's own; pins are attached on ``reference_verts`` as without transfer.
    mhclo : MhcloBinding or None
        The garment's binding, for the mhclo methods.
    start_verts : (n, 3) float64 m or None
        An already transferred start (then ``transfer`` is not applied).
    rest : {"garment", "transferred"}
        Where the cloth's rest lengths come from when it starts transferred: the garment as given
        (a fixed-size garment put on a body of another size is stretched or loose), or the
        transferred garment (the garment graded to the body, as MakeHuman refits clothes to every
        body through their .mhclo; pins are then attached on ``body_verts`` itself). Either way
        ``metrics['garment_strain']`` gives the strain against the garment as given.

    Returns
    -------
    DrapeResult
        ``settings['pins']`` holds the pin count and the auto-pin summary; ``settings['transfer']``
        the :func:`vfit_engine.garment.transfer.transfer_garment` info and ``pin_gap_mm`` (max/mean distance of the started
        pinned vertices from their targets on the body).
    """
    from vfit_engine.garment.pins import auto_pins

    st = settings or DrapeSettings()
    if start_verts is not None:
        start, tinfo = np.ascontiguousarray(start_verts, dtype=np.float64), dict(requested="given", method="given")
    elif transfer != "none":
        from vfit_engine.garment.transfer import transfer_garment

        start, tinfo = transfer_garment(garment_mesh.verts, reference_verts, body_verts, body_tris, transfer, mhclo)
    else:
        start, tinfo = None, dict(requested="none", method="none", time_s=0.0)
    if rest not in ("garment", "transferred"):
        raise InputError(f"unknown rest shape {rest!r}; use garment or transferred")
    tinfo["rest"] = rest
    given_mesh = garment_mesh
    if rest == "transferred" and start is not None:
        # the transferred garment is the cloth's pattern on this body: it starts at rest there
        garment_mesh, reference_verts, start = garment_mesh.with_verts(start), body_verts, None
    if np.size(body_tris) and int(np.max(body_tris)) < _HM08_BODY:
        # hm08's helper vertices (19,158 in all) serve the transfer only; the drape sees the skin
        if np.shape(body_verts)[0] == _HM08_ALL:
            body_verts = body_verts[:_HM08_BODY]
        if np.shape(reference_verts)[0] == _HM08_ALL:
            reference_verts = reference_verts[:_HM08_BODY]
    info = None
    if isinstance(pin, str) and pin == "auto":
        idx, info = auto_pins(garment_mesh, body_verts, body_tris, pieces=pieces)
    elif isinstance(pin, str) and pin == "none":
        idx = np.zeros(0, np.int64)
    elif isinstance(pin, str):
        raise InputError(f"unknown pin mode {pin!r}; use auto, none or a file")
    else:
        idx = np.unique(np.asarray(pin, dtype=np.int64).ravel())
        if idx.size and (idx[0] < 0 or idx[-1] >= garment_mesh.n_verts):
            raise InputError(f"pin index out of range 0..{garment_mesh.n_verts - 1}")
    pins = None
    dropped = 0
    if idx.size:
        att = PinAttachment.attach(garment_mesh.verts, idx, reference_verts, body_tris)
        # a pin inside (or within the skin of) the reference body would have to be moved out while its
        # pinned neighbours stay put, stretching the springs between them; it stays free instead and
        # the collider brings it out with its neighbours
        keep = att.offset >= st.skin
        dropped = int(np.count_nonzero(~keep))
        idx = idx[keep]
        att = att.select(keep)
    fit = dict(released_stretched=0, refitted_groups=0)
    if idx.size:
        # on a morphed body pinned loops (waistbands) are spread evenly and pinned patches
        # (shoulders) moved rigidly; pins the cloth still cannot reach are released (pin_fit)
        from vfit_engine.sim.pin_fit import fit_pins

        # also after a transfer: pins merely following the transferred garment (no refit) did worse
        # on scripts/drape_quality.py (4/12 pass, 4 not settled, against 5/12)
        idx, att, target, fit = fit_pins(garment_mesh, idx, att, body_verts, body_tris, st.skin, st.pin_strain,
                                         st.pin_fit_strain)
    if idx.size:
        pins = (att, target)
    from_pos = garment_mesh.verts if start is None else start
    if pins is not None:
        gap = 1000.0 * np.linalg.norm(from_pos[idx] - target, axis=1)
        tinfo["pin_gap_mm"] = dict(max=float(gap.max()), mean=float(gap.mean()))
    from vfit_engine.garment.openings import check_openings

    # openings smaller than the body part they go round bound the strain from below (a garment
    # authored too tight there cannot be put on without stretching them): they stretch evenly
    openings = check_openings(garment_mesh, body_verts, body_tris, skin=st.skin, pos=from_pos)
    zones = [(o["indices"], o["required_strain"]) for o in openings if o["required_strain"] > 0]
    try:
        res = drape(garment_mesh.verts, garment_mesh.face_verts, garment_mesh.face_offsets, body_verts, body_tris,
                    material=material, pins=pins, collider=collider, settings=st, body_collider=body_collider,
                    segments=segments, stretch_zones=zones, bones=bones,
                    on_frame=on_frame, start_pos=start)
    except DrapeDiverged as exc:
        exc.transfer = tinfo
        raise
    res.settings["transfer"] = tinfo
    if res.metrics.get("finite"):
        res.metrics["garment_strain"] = edge_strain(given_mesh, res.pos)
    res.settings["pins"] = dict(
        mode=pin if isinstance(pin, str) else "file", count=int(idx.size), dropped_inside=dropped,
        **fit,
        pieces=None if info is None else [{k: p[k] for k in ("piece", "kind", "method", "n_pins")}
                                          for p in info["pieces"]])
    res.pin_indices = idx
    res.pin_targets = None if pins is None else pins[1]
    res.openings = openings
    return res
