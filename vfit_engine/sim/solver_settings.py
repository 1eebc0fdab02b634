"""Settings of the cloth solver (:class:`vfit_engine.sim.solver_verlet.SolverVerlet`): its substeps, sweeps and
constraint bands (:class:`VerletSettings`), and how the cloth meets the body (:class:`ContactSettings`)."""
from __future__ import annotations

import math
from dataclasses import dataclass


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
    iterations : int
        Gauss-Seidel sweeps over the constraints and contacts per substep.
    slack, compression : float
        The band (fractions of the rest length) in which a stretch constraint holds no force: woven
        yarns straighten their crimp at almost no load before the fabric resists (``slack``), and
        buckle at once under compression (``compression``: a little keeps the cloth from rippling
        at the scale of its mesh). Beyond the band the material's stretch stiffness acts.
    bend_limit : float or None
        Limit on the bend pairs (second neighbours): they may shorten freely (the cloth folds) but not
        lengthen by more than this without resistance, so folds modelled into the garment -- a turned
        hem, a collar, a lapel -- do not open out; beyond it they resist compliantly
        (:data:`vfit_engine.sim.constraints.BEND_LIMIT_SOFTNESS`). None: bend springs only.
    shear_limit_deg : float or None
        Polygon corner angles change by at most this (Provot's shear limit, as angle constraints on
        ``Model.corners``). None: no shear limit, and the shear springs act as explicit springs.
    shear_restore : float
        Weight (Gauss-Seidel relaxation) of the compliant shear springs that pull the corners back to
        their modelled angles within the limit; 0 leaves the corners free within it.
    relax_by_stiffness : bool
        Weigh the stretch constraints' corrections by their stiffness (``relax``,
        :mod:`vfit_engine.kernels.cloth`): where the body forces a stretch, the stretch is shared as an
        elastic sheet shares it instead of short stiff edges taking it all.
    stability_safety : float
        Fraction of the explicit stability bound the explicit springs are softened to; 0 disables
        softening.
    implicit_hinges : bool
        Solve the bending hinges too stiff for the explicit step as compliant angle constraints, with the
        fabric's whole stiffness (else they are softened to the bound as the springs are: the drape then
        bends more easily than the fabric where its mesh is fine or the fabric stiff).
    hinge_every : int
        The hinge constraints are solved in every ``hinge_every``-th sweep and the last.
    """

    substeps: int = 8
    gravity: tuple = (0.0, -9.81, 0.0)
    air_damping: float = 0.5
    iterations: int = 14
    slack: float = 0.015
    compression: float = 0.3
    bend_limit: float | None = 0.015
    shear_limit_deg: float | None = 10.0
    shear_restore: float = 0.02
    relax_by_stiffness: bool = True
    stability_safety: float = 0.2
    implicit_hinges: bool = True
    hinge_every: int = 2

    def __post_init__(self):
        if int(self.substeps) < 1 or int(self.iterations) < 0 or int(self.hinge_every) < 1:
            raise ValueError("substeps and hinge_every must be >= 1 and iterations >= 0")
        if len(self.gravity) != 3 or not all(math.isfinite(g) for g in self.gravity):
            raise ValueError("gravity must be three finite numbers")
        if not (self.air_damping >= 0 and self.stability_safety >= 0):
            raise ValueError("air_damping and stability_safety must be >= 0")
        for name in ("slack", "bend_limit"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0")
        if not 0.0 <= self.compression < 1.0:
            raise ValueError("compression must be in [0, 1)")
        if self.shear_limit_deg is not None and not 0.0 < self.shear_limit_deg < 90.0:
            raise ValueError("shear_limit_deg must be in (0, 90)")


@dataclass(frozen=True)
class PDSettings(VerletSettings):
    """Settings of the projective-dynamics solver (:class:`vfit_engine.sim.solver_pd.SolverPD`): the constraint
    bands of :class:`VerletSettings` (``substeps`` are its steps a frame, ``iterations`` its global iterations a
    step; the Verlet solver's explicit-step settings do not apply), and:

    Attributes
    ----------
    contact_weight : float
        The contacts' constant weight in the matrix on every free vertex, as a share of the fabric's typical
        stretch stiffness of an edge: a pull towards where the vertex is, moved by the push its contact points ask
        for. Weak: a strong one locks the cloth (0.3 held a sphere's drape at 28 % stretch at 5 iterations; 1.0 on
        the vertices touching the body alone, 15 %); the contact forces (``contact_rho``) hold the cloth out.
    contact_rho : float
        The contact forces' growth per unit depth at each iteration (Uzawa's step), as a share of the vertex's
        diagonal in the matrix; 0: no contact forces (the weights alone).
    angle_weight : float
        The corner angle limits' weight, as a share of the same stiffness.
    chebyshev_rho : float
        The spectral radius estimate of Chebyshev's acceleration (0: none). Off: the iteration's true radius is
        near 1 in cloth whose yarns lie inside their free band (the matrix holds their full stiffness there), and
        with an estimate below it the frames reach a still state that is not the equilibrium -- a hanging strip
        stopped at 0.50 % stretch with 0.8, not the 1.53 % its weight gives, for ever (``tests/test_pd.py``).
    chebyshev_delay : int
        Plain iterations before the acceleration starts.
    contact_sweeps : int
        Exact projections of the contact points onto their half-spaces after the iterations.
    hinge_every : int
        The hinges' forces (and the other forces outside the matrix) are evaluated at every ``hinge_every``-th
        iteration, the iterations between keep them.
    band_weight : float
        The weight in the matrix of a band (a yarn edge, a bend limit) inside its free band at the step's start,
        as a share of its stiffness (1: a constant matrix; below it the matrix is refactored when the set of acting
        bands changes).
    bend_in_matrix : bool
        The bend limits and bend springs (second neighbours) as elements of the matrix (else as forces with a
        diagonal, :mod:`vfit_engine.kernels.pd`).
    friction_in_solve : float
        Share of the contacts' Coulomb coefficient that acts inside the iterations, holding each pushed vertex
        where it lay along the body (:func:`vfit_engine.kernels.pd.contact_friction`); 0: friction on the
        velocity after the step only.
    stiffness_damping : float, s
        Rayleigh damping proportional to the matrix's elements: each pair element of the cloth (not a seam) pulls
        its two ends' relative motion over a step back with ``stiffness_damping / h`` times its weight, implicitly
        (:func:`vfit_engine.kernels.pd_matrix.add_damping_target`). A motion that moves no element relative to
        its ends -- a translation -- is not damped; a rotation is (the pair elements have no direction), so too
        much holds a sliding or swinging garment where it is (docs/solver.md). 0: none.
    history : int
        Quasi-Newton (L-BFGS) iterations on the matrix, keeping this many pairs of moves and gradient changes
        (:mod:`vfit_engine.kernels.lbfgs`), kept from step to step; 0: the plain iterations. With it the
        iterations start from the step's prediction without gravity's ``g h^2`` (a still state is then one the
        iterations keep, the equilibrium), and the forces outside the matrix are evaluated at every iteration.
    qn_move_limit : float, m
        Under a moving body (:meth:`SolverPD.body_moved`), a quasi-Newton move that would carry a vertex farther
        than this is not taken; the plain step is, and the history is dropped. The contacts are made once a step
        for the points near the body; the quasi-Newton moves, extrapolated from pairs learnt as the body moved,
        carried a walking suit through the skin where no contact had been made (22 of 30 frames over the walk's
        bars at no limit, 4 at 2 mm, none at 0.5 mm).
    edge_compression : bool
        The bend springs' share of the stretch stiffness (:data:`vfit_engine.sim.materials.COMPRESSION_SHARE`, the
        cloth's resistance to in-plane compression) on the polygon edges shorter than their rest length, in
        place of the bend springs: a bend spring joins second neighbours, which come closer as the cloth folds,
        so it resists bending too, by an amount that grows with the mesh's spacing (the cantilever's bending
        length +8.5 % (denim) to +41 % (silk) at 10 mm with them, within 2.2 % on the edges; docs/solver.md); the
        bending is then the hinges' alone.
    """

    substeps: int = 2
    iterations: int = 5
    contact_weight: float = 0.01
    contact_rho: float = 1.0
    angle_weight: float = 0.05
    chebyshev_rho: float = 0.0
    chebyshev_delay: int = 2
    contact_sweeps: int = 0
    bend_in_matrix: bool = True
    band_weight: float = 0.3
    friction_in_solve: float = 1.0
    stiffness_damping: float = 0.0
    history: int = 0
    qn_move_limit: float = 0.0005
    edge_compression: bool = False

    def __post_init__(self):
        super().__post_init__()
        if int(self.history) < 0:
            raise ValueError("history must be >= 0 (0: plain iterations)")
        if not self.qn_move_limit > 0:
            raise ValueError("qn_move_limit must be > 0 (m)")
        if not (math.isfinite(self.stiffness_damping) and self.stiffness_damping >= 0):
            raise ValueError("stiffness_damping must be finite and >= 0 (s)")


@dataclass(frozen=True)
class ContactSettings:
    """How the cloth meets the body.

    Attributes
    ----------
    skin : float, m
        Clearance the cloth's vertices keep from the body.
    surface_skin : float, m
        Clearance of the contact points inside the cloth's triangles (they lie between vertices,
        where a smaller clearance already keeps the surface out).
    reach : float, m
        Contacts are made for points within ``skin + reach`` of the body.
    friction : float
        Coulomb coefficient.
    damping : float, 1/s
        Decay rate of the tangential velocity of pushed cloth (cloth resting on skin comes to rest).
    reuse : float, m
        A point in contact that moved less than this since its last exact query keeps that query's
        tangent plane; 0 queries every substep.
    stick : bool
        Friction acts on the cloth's slip within a substep too, not only on its velocity
        (:mod:`vfit_engine.kernels.cloth`, step 5): cloth inside the friction cone stays where it lies on
        the skin. Without it cloth held by friction alone (a skirt's front on sloping thighs) creeps
        downhill by its tangential gravity, g sin(theta) dt^2, every substep (0.7 mm sin(theta) per 1/30 s at
        1/480 s substeps). Off by default: the still drape's cloth settles hanging from its pins, held by
        tension, not friction; and in an animation it also holds cloth that a moving body stretched as
        stretched as it is (:class:`vfit_engine.animate.loop.AnimateSettings`).
    sag : bool
        The body counts as thicker at its small bumps (nipples, knuckles, fingertips: convex in every
        direction) by as much as they rise between the contact points (:mod:`vfit_engine.collide.sag`), so a
        taut cloth resting on points round a bump does not cut into its tip. Needs the surface contact points
        (their spacing).
    """

    skin: float = 0.002
    surface_skin: float = 0.001
    reach: float = 0.002
    friction: float = 0.8
    damping: float = 0.0
    reuse: float = 0.0005
    stick: bool = False
    sag: bool = True
