"""Settings of a drape: the frame loop, the settle test, the start, and the solver's and contacts' settings."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from vfit_engine.errors import InputError
from vfit_engine.sim.solver_settings import ContactSettings, PDSettings, VerletSettings

#: Most subdivision levels of ``DrapeSettings.refine`` (:mod:`vfit_engine.drape.refine`; each multiplies the
#: polygons by ~4 and the time by ~3-5: 2.3-3.7 per frame, and more frames to settle).
MAX_LEVELS = 2


def _solver():
    # a drape damps the air more than the solver's default (a garment settles instead of swinging): 8/s is a
    # falling sheet's terminal speed g / 8 = 1.2 m/s, about a light fabric's in air; the settled shape is the
    # same as at 5/s (strain and shear within 0.05 points on the shared garments) in 10-30 % fewer frames
    return VerletSettings(substeps=8, air_damping=8.0)


def _contact():
    return ContactSettings(skin=0.002, surface_skin=0.001, reach=0.002, friction=0.8, damping=60.0, reuse=0.0001)


@dataclass(frozen=True)
class DrapeSettings:
    """Settings of a drape (:func:`vfit_engine.drape.run_drape`); the defaults are the product's.

    Attributes
    ----------
    fps : float, 1/s
        Frames per simulated second (a frame is the unit of output and of the settle test).
    max_frames : int
        Frames simulated at most (20 s; not settled by then means not converged, exit 3). Most drapes settle
        in 1-2 s, but some come to rest only slowly: cloth the body stretches far beyond what the fabric
        gives (4-5 s), and free cloth that hangs still for a while and then slides slowly into other folds
        (the demo skirt in jersey on a 160 cm / 75 kg woman: its hem still at frame 200 moves off and
        settles at frame 802). That slide is slow because the air damping that stops a falling garment
        quickly also slows it (at 5/s it settles at frame 584, at 3/s at 276).
    solver : VerletSettings
        Substeps, iterations, damping and the cloth's constraint bands
        (:class:`vfit_engine.sim.solver_verlet.VerletSettings`).
    contact : ContactSettings
        Clearances, friction and contact damping (:class:`vfit_engine.sim.solver_verlet.ContactSettings`).
    surface_spacing : float, m
        Spacing of the contact points over the cloth's triangles (:mod:`vfit_engine.sim.contact_points`);
        0 holds out the vertices only.
    push_start, push_end : float, m
        Longest push out of the body per substep at the first frame and after ``ramp_frames``: a
        garment that starts inside the body comes out gradually (a sudden push of centimetres would
        stretch the cloth around it and launch it).
    ramp_frames : int
        Frames over which the push limit ramps and the pins move to their targets.
    sew_frames : int
        A pattern's sewing (:mod:`vfit_engine.drape.sew`): for this many frames gravity is off and each seam may be
        no longer than its gap at the start shrunk linearly to 0 by three quarters of them; the settle test
        starts after them. 40 frames close a seam 45 cm apart (the GarmentCode shirt's sides) at 1.5 cm a frame,
        which the body's contacts hold.
    settle_frames, settle_step, settle_share, settle_max_step :
        The settle test: the cloth has settled when, for ``settle_frames`` consecutive frames after
        the ramp, at most ``settle_share`` of its vertices moved more than ``settle_step`` (m) in a
        frame and none more than ``settle_max_step`` (m), and no vertex moved more than
        ``settle_max_step`` over those frames together (so a slow creep does not count as settled).
    diverge_speed : float, m/s
        A vertex faster than this means the simulation has diverged (exit 4).
    untangle : bool
        Move the garment out of the body before the dynamics (:mod:`vfit_engine.sim.untangle`), its
        edges stretching by at most ``untangle_strain``, in at most ``untangle_iterations`` steps.
    untangle_strain : float;  untangle_iterations : int
    stretch_zone : float, m
        Width of the cloth round an opening smaller than the body part it goes round that may stretch
        as far as the opening must (:meth:`vfit_engine.sim.solver_verlet.SolverVerlet.allow_stretch`).
    pin_strain, pin_fit_strain : float
        Pin fitting on another body (:func:`vfit_engine.garment.pin_fit.fit_pins`).
    sphere_skin : float
        Relative margin of the sphere colliders (``spheres``, ``bone-spheres``).
    spheres_per_bone : int
        Spheres along each bone of the ``bone-spheres`` collider.
    slow_frames, slow_iterations : int
        A drape still moving after ``slow_frames`` frames sweeps its constraints ``slow_iterations`` times a substep
        from then on (``solver.iterations`` before). Where the sweeps leave the cloth a little unconverged it can
        cycle without end instead of settling: a long sleeve buckled in the crook of a bent elbow (a suit on a
        running pose) repeated the same 60-frame cycle of up to 0.9 mm a frame on 1 % of its vertices from frame
        300 to 1200 at 14 sweeps; it settled at frame 171 sweeping 20 times from the start, and at frame 344
        sweeping 20 times from frame 301. Sweeping 20 times from the start would sweep every drape 20 / 14 as
        often; the drapes that settle within ``slow_frames`` (the shared garments in 51-70) are unchanged.
    ground : bool
        A still ground plane under the body's lowest point (its soles, standing) that the cloth rests on
        (:func:`vfit_engine.drape.setup.ground_height`): trousers or a dress longer than the legs pool on it
        instead of hanging through where the floor would be.
    refine : int
        Simulate the cloth subdivided this many times (each polygon into quads round its centroid) and read the
        garment's own vertices back from it (:mod:`vfit_engine.drape.refine`): folds narrower than the
        garment's polygons (silk on a coarse skirt), at ~3-5 times the time per level; 0: the garment's mesh.
    """

    fps: float = 60.0
    max_frames: int = 1200
    solver: VerletSettings = field(default_factory=_solver)
    contact: ContactSettings = field(default_factory=_contact)
    surface_spacing: float = 0.015
    push_start: float = 0.0002
    push_end: float = 0.005
    ramp_frames: int = 40
    sew_frames: int = 40
    #: by this share of ``sew_frames`` every seam is closed (the rest let the sewn garment come to rest unweighed)
    sew_close: float = 0.75
    settle_frames: int = 10
    settle_step: float = 0.0001
    settle_share: float = 0.005
    settle_max_step: float = 0.001
    diverge_speed: float = 20.0
    untangle: bool = True
    untangle_strain: float = 0.08
    untangle_iterations: int = 60
    stretch_zone: float = 0.03
    admit_gap: float = 0.01
    pin_strain: float = 0.03
    pin_fit_strain: float = 0.015
    sphere_skin: float = 0.02
    spheres_per_bone: int = 4
    slow_frames: int = 300
    slow_iterations: int = 20
    ground: bool = True
    refine: int = 0

    def __post_init__(self):
        for name in ("fps", "push_start", "push_end", "settle_step", "settle_max_step", "diverge_speed"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"drape setting {name} must be a positive number, got {value!r}")
        for name in ("max_frames", "settle_frames", "slow_frames", "slow_iterations"):
            if int(getattr(self, name)) < 1:
                raise InputError(f"drape setting {name} must be >= 1")
        if int(self.ramp_frames) < 0:
            raise InputError("drape setting ramp_frames must be >= 0")
        if not 0.0 <= self.settle_share < 1.0:
            raise InputError(f"drape setting settle_share must be in [0, 1), got {self.settle_share!r}")
        if not (math.isfinite(self.surface_spacing) and self.surface_spacing >= 0):
            raise InputError("drape setting surface_spacing must be >= 0")
        if not 0 <= int(self.refine) <= MAX_LEVELS:
            raise InputError(f"drape setting refine must be 0 to {MAX_LEVELS}, got {self.refine!r}")

    def settle_test(self):
        """The settle test in words, with its numbers (for reports)."""
        return (f"for {self.settle_frames} consecutive frames ({self.settle_frames / self.fps:.3f} s) at most "
                f"{100 * self.settle_share:g} % of the vertices move more than {1000 * self.settle_step:g} mm per "
                f"frame, none more than {1000 * self.settle_max_step:g} mm per frame nor over the "
                f"{self.settle_frames} frames together")


#: A drape's stiffness-proportional damping on the projective solver (``PDSettings.stiffness_damping``, s). Without
#: it whether a drape settled hung on rounding: from three starts 1e-9 m apart a case settled at frame 309, at 215
#: or not in 400, and 12 of the battery's 36 such drapes did not settle; with it all 36 did, each case within 12
#: frames of itself (docs/solver.md). 0.5 ms settles the battery sooner but a sewn skirt only at frame 862; 2 ms
#: settles the drape issue's tight case but not the sewn shirt and dress (both in an experiment that damped the
#: seams too); more holds a garment that slides or swings where it is (the damping has no direction: it resists a
#: rotation as much as a stretch).
DRAPE_STIFFNESS_DAMPING = 0.001


def projective(settings=None, **solver):
    """``settings`` (default the product's) with the projective-dynamics solver
    (:class:`vfit_engine.sim.solver_pd.SolverPD`) and ``solver`` fields of its :class:`PDSettings`: the same
    air damping and constraint bands, the drape's stiffness damping (:data:`DRAPE_STIFFNESS_DAMPING`); the push
    limits, given per Verlet substep, scaled to its longer steps."""
    settings = settings or DrapeSettings()
    solver.setdefault("stiffness_damping", DRAPE_STIFFNESS_DAMPING)
    old = settings.solver
    pd = PDSettings(**{f: getattr(old, f) for f in ("gravity", "air_damping", "slack", "compression", "bend_limit",
                                                     "shear_limit_deg", "shear_restore")}, **solver)
    scale = old.substeps / pd.substeps
    # no switch to more iterations for a slow drape (``slow_iterations``): the Gauss-Seidel sweeps' cure; here more
    # iterations a step swung the contact forces further (a stretched suit moved 3.5 mm a frame at 30, 0.7 at 10)
    return replace(settings, solver=pd, push_start=settings.push_start * scale, push_end=settings.push_end * scale,
                   slow_iterations=pd.iterations)
