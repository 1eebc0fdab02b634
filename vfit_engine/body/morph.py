"""Solve target weights so a body meets every requested measurement at once.

The seed system scanned one blend-shape weight at a time until
``|L - L_target| <= sigma``. Here all requested measurements are met jointly by
bounded nonlinear least squares:

* **plan** - what is not given follows the population (``population.py``,
  ANSUR II): the survey's regression on what is given estimates every girth and
  the mass not given (a height not given stays the average body's). Given
  values no adult body has (beyond ``population.REFUSE_Z``) are refused at once;
  values outside the 1st-99th percentile build with a warning.
* **semantic stage** - MakeHuman's macro sliders give a plausible body for the
  gender: ``height`` (0..1) meets the stature and the *build* path ``b``
  (``B_MIN``..``B_MAX``) the mass, given or estimated (enclosed volume x
  density). ``b > 0`` moves towards MakeHuman's heavy corner (weight 0.5 -> 1
  while muscle 0.5 -> 0), ``b < 0`` towards its light one (weight 0.5 -> 0, and
  on to -0.25); MakeHuman's weight slider alone spans only about +-7 kg.
* **measurement stage** - one *primary* channel per girth (``measure-*-incr``
  for weights > 0, ``-decr`` for < 0, range -1..1), *secondary* channels
  (torso and hip scale targets) that take over where a primary one saturates,
  and the height slider and the build. Residuals: every requested measurement
  and the mass if given (weight 1); every estimate (weight ``SOFT_WEIGHT``: it
  gives way to any target); a tiny pull of every channel towards zero (primary
  ``REG_PRIMARY`` < secondary ``REG_SECONDARY``) that picks one body among the
  many meeting the targets.
* **check** - a target missed by more than ``TOLERANCE_M`` raises InputError
  with the range reachable *given the other targets* (:meth:`Morpher.reachable`).

Tape girths are maxima/minima over a band of planes. By the envelope theorem
their derivative is the derivative at the extremal plane, so the inner solve
keeps each girth's planes fixed (as fractions of its band, so they move with
the band; every near-extremal plane seen so far, so the solve cannot cycle
between valleys) and the outer loop re-searches the bands until the full
measurement meets every target (a solve ending a few millimetres short goes
again with a residual per watched plane: ``morph_planes.py``). The bust is
taken at the bust points' plane (a man's chest a whole number of millimetres
above it, just under his armpits), which moves with them. The inner solve is a
trust-region Gauss-Newton (``gauss_newton.py``) with an exact Jacobian for the
channels: the body is linear in its channel weights, so ``dg/dx_j = grad_v g .
D_j`` with the gradients of ``gradients.py``; the two macro sliders by forward
differences.
"""
from __future__ import annotations

import copy
import time

import numpy as np

from ..errors import InputError
from ..kernels.blend import blend, project
from .channels import CHANNELS, GIRTHS, HEAVY, SECONDARY, ChannelSet  # noqa: F401  (re-exported)
from .gauss_newton import gauss_newton as _gauss_newton
from .measure import NAMES, Measurement, Measurer, stature
from .model import N_BODY, BodyModel, Macro, gender_value
from .morph_planes import SLACK_UNIT, GirthRows, Problem, add_planes, outer_loop
from .morph_reach import OutOfTime, ReachSearch  # noqa: F401  (OutOfTime: re-exported)
from .morph_result import MorphResult, Plan
from .morph_settings import (  # noqa: F401  (tests and scripts read them from morph)
    MASS_UNIT, MM, B_MAX, B_MIN, EACH_PLANE_MISS, EARLY_EXIT, POINT_MARGIN, RANGE_SEARCH_UNTIL, REACH_PULL,
    REACH_SOFT, REACH_WEIGHT, REG_PRIMARY, REG_SECONDARY, SEEN_PLANES, SOFT_TOL, SOFT_WEIGHT, TOLERANCE_M,
    TOLERANCE_MASS, UNDERBUST_SD,
)
from .population import VARIABLES, PopulationModel


def build_sliders(b: float) -> tuple[float, float]:
    """(muscle, weight) MakeHuman sliders of build ``b`` in ``B_MIN..B_MAX`` (0 = average).

    Within -1..1 the sliders stay in MakeHuman's 0..1; below, the weight slider goes on linearly
    to -0.25 at ``b = -1.5`` (see ``B_MIN``).
    """
    b = float(np.clip(b, B_MIN, B_MAX))
    if b >= 0:
        return max(0.0, 0.5 - 0.5 * b), 0.5 + 0.5 * b
    return 0.5, 0.5 + 0.5 * b


class Morpher(ReachSearch):
    """Builds bodies to measurements. Create once: it loads the model and caches dense targets."""

    def __init__(self, model: BodyModel | None = None, measurer: Measurer | None = None):
        self.model = model or BodyModel.load()
        self.measurer = measurer or Measurer(self.model)
        base = [CHANNELS[g] for g in GIRTHS] + list(SECONDARY)
        self._sets = (ChannelSet(self.model, base), ChannelSet(self.model, base + list(HEAVY)))
        self._channel_names = self._sets[0].names
        self._base_flat = np.ascontiguousarray(self.model.base_verts[:N_BODY].ravel())
        self._macro_cache = {}
        self._last_macro = (None, None)
        self._start_cache = {}

    # ----------------------------------------------------------------- shaping
    def macro(self, gender: float, height: float, build: float) -> Macro:
        muscle, weight = build_sliders(build)
        return Macro(gender=gender, muscle=muscle, weight=weight, height=float(height))

    def _macro_body(self, macro: Macro) -> np.ndarray:
        """Flattened body vertices of a macro setting, from a per-gender dense target stack."""
        tw = macro.target_weights()
        key = macro.gender
        if key not in self._macro_cache:
            names = [n for n in self.model.target_names if n.startswith("macrodetails/")
                     and "proportions" not in n and _gender_of(n) in _genders(key)]
            stack = np.stack([self.model.dense_target(n, N_BODY).ravel() for n in names])
            self._macro_cache[key] = ({n: i for i, n in enumerate(names)}, stack)
        index, stack = self._macro_cache[key]
        w = np.zeros(len(index))
        for n, x in tw.items():
            w[index[n]] = x
        out = np.empty(3 * N_BODY)
        blend(self._base_flat, stack, w, out)
        return out

    def _body(self, macro: Macro, s: np.ndarray) -> np.ndarray:
        """Body of signed channel weights ``s`` (> 0 picks -incr, < 0 picks -decr)."""
        return self._body_split(macro, np.maximum(s, 0), np.maximum(-s, 0))

    def _body_split(self, macro: Macro, incr: np.ndarray, decr: np.ndarray) -> np.ndarray:
        """Body of separate, non-negative -incr and -decr weights: linear and smooth in both."""
        if self._last_macro[0] != macro:  # the solver varies channels far more often than sliders
            self._last_macro = (macro, self._macro_body(macro))
        # a serial kernel, not NumPy's dot: the BLAS path costs 0.1-6 ms a call on a busy machine
        out = np.empty(3 * N_BODY)
        blend(self._last_macro[1], self._set(incr.size).updown, np.concatenate([incr, decr]), out)
        return out.reshape(N_BODY, 3)

    def _set(self, n_channels: int) -> ChannelSet:
        """The channel set with ``n_channels`` channels (the base one, or with the HEAVY channels)."""
        return self._sets[0] if n_channels == self._sets[0].n else self._sets[1]

    # ----------------------------------------------------------------- solving
    def start(self, gender: float, definition: str = "iso") -> Measurement:
        """Measurement of the average body of ``gender`` (0..1), cached per definition (a fresh copy)."""
        key = (float(gender), definition)
        if key not in self._start_cache:
            zero = np.zeros(len(self._channel_names))
            self._start_cache[key] = self.measurer.measure(self._body(self.macro(gender, 0.5, 0.0), zero), definition,
                                                           gender=gender)
        return copy.deepcopy(self._start_cache[key])

    def population(self, gender: float, definition: str = "iso") -> PopulationModel:
        """The survey's model for a gender, its girth levels anchored at the average body measured with
        ``definition`` (see :meth:`population.PopulationModel.anchored`)."""
        start = self.start(gender, definition)
        return PopulationModel(gender).anchored({**start.values, "mass": start.mass_kg})

    def plan(self, targets: dict, gender: float, definition: str = "iso", weight_kg=None) -> Plan:
        """What the solve aims at: the targets, and the survey's estimate of everything not given.

        Raises InputError (at once, before any solve) where a given value is so far outside the
        population that no adult body has it (:data:`population.REFUSE_Z`).
        """
        start = self.start(gender, definition)
        pop = self.population(gender, definition)
        given = {k: v for k, v in targets.items() if k in VARIABLES}
        if weight_kg is not None:
            given["mass"] = float(weight_kg)
        assessment = pop.assess(given)
        refused = assessment.refusals()
        if definition != "makehuman" and targets.get("waist", 0.0) > targets.get("hips", np.inf) + 2 * TOLERANCE_M:
            # the waist band (hips line to underbust line) and the hips band (hips line +-4 cm) share the
            # hips line's plane, so the smallest girth of one is at most the largest of the other on every
            # body. Surveys tape a man's waist at the iliac crest (NHANES), over the belly: there it can be
            # the larger. (The estimates keep waist <= hips: PopulationModel.predict.)
            refused.append(f"waist {targets['waist'] * 100:.1f} cm is more than hips {targets['hips'] * 100:.1f} "
                           "cm: the waist is the narrowest girth from the hips line up, the hips the largest "
                           "within 4 cm of it, so no body's waist exceeds its hips")
        if refused:
            raise InputError("refused: " + "; ".join(refused))
        # a height not given stays the average body's: the survey's estimates then follow that height
        known = {"height": start.values["height"], **given}
        est, sd = pop.predict(known)
        if "underbust" not in targets:
            # not in the survey: it follows the bust at the average body's ratio, and not below the
            # waist (their bands overlap: on a body without a waist both are the same girth)
            bust = targets.get("bust", est.get("bust"))
            waist = targets.get("waist", est.get("waist"))
            est["underbust"] = max(bust * start.values["underbust"] / start.values["bust"], waist)
            sd["underbust"] = max(sd.get("bust", 0.0), UNDERBUST_SD)
        estimated = {k: (est[k], sd[k]) for k in GIRTHS + ("mass",) if k not in given and k in est}
        goals = {k: targets[k] if k in targets else est[k] for k in GIRTHS}
        goals["height"] = known["height"]
        mass = float(weight_kg) if weight_kg is not None else est["mass"]
        hard = set(targets) | ({"mass"} if weight_kg is not None else set())
        return Plan(goals, mass, hard, estimated, assessment.warnings(), start)

    def solve(self, targets: dict, gender="female", definition="iso", weight_kg=None,
              search_seconds=None) -> MorphResult:
        """Build a body meeting ``targets``; what is not given follows the population (``population.py``).

        Parameters
        ----------
        targets : dict
            Measurement name (one of ``NAMES``) -> value in metres.
        gender : 'female', 'male' or 0..1
        definition : 'iso' | 'makehuman' | 'spline'
        weight_kg : float, optional
            Body mass to meet through volume x density.
        search_seconds : float, optional
            A failure's search for the ranges reachable ends this long after the solve starts (default
            :data:`RANGE_SEARCH_UNTIL`: a failure answers within ~3 s); a range cut short says so.

        Raises
        ------
        InputError
            A target the model cannot reach (the message gives the range reachable with the other
            targets as given), targets that cannot be met together, or values no adult body has.
        """
        unknown = set(targets) - set(NAMES)
        if unknown:
            raise InputError(f"unknown measurement(s): {', '.join(sorted(unknown))}")
        g = gender_value(gender)
        if not targets and weight_kg is None:  # nothing asked: MakeHuman's average body
            start = self.start(g, definition)
            zero = np.zeros(len(self._channel_names))
            macro = self.macro(g, 0.5, 0.0)
            verts = self.model.shape(macro.target_weights(), first=N_BODY)
            verts[:N_BODY] = self._body(macro, zero)
            return MorphResult(verts, macro, 0.0, {n: 0.0 for n in self._channel_names}, start, {}, None,
                               self.start(g, definition), 0, dict(macro.target_weights()))
        t0 = time.perf_counter()
        plan = self.plan(targets, g, definition, weight_kg)
        h, b = self._semantic(g, plan.goals["height"], plan.mass, definition)
        x, meas, iterations = self._fit_all(g, h, b, plan, definition)
        out = self._result(g, x, meas, plan, targets, weight_kg, iterations)
        limit = RANGE_SEARCH_UNTIL if search_seconds is None else float(search_seconds)
        self._check(out, definition, g, deadline=t0 + limit, x=x)
        return out

    def _semantic(self, g, height, mass, definition):
        """Height slider and build meeting a stature (m) and a mass (kg) on the average body's shape."""
        m = self.measurer
        zero = np.zeros(len(self._channel_names))

        def semantic(p, planes=None):
            v = self._body(self.macro(g, p[0], p[1]), zero)
            return np.array([(stature(v) - height) / MM, (m.mass(v) / mass - 1.0) / MASS_UNIT]), None

        p, _ = _gauss_newton(semantic, np.array([0.5, 0.0]), np.array([0.0, B_MIN]), np.array([1.0, B_MAX]),
                             np.zeros(2), None)
        return float(p[0]), float(p[1])

    def _fit_all(self, g, h, b, plan, definition, deadline=None, x0=None):
        """:meth:`_fit`, then, if it ended at the heavy corner short of a target, again from there with the
        HEAVY channels open; if it ends a few millimetres short, once more with a residual per watched
        plane. Returns as :meth:`_fit` (``deadline``, ``x0``: as there)."""
        x, meas, iterations = self._fit(g, h, b, plan, definition, x0=x0, deadline=deadline)
        if x[-1] >= B_MAX - 1e-9 and plan.missed(meas) and x.size == 2 * self._sets[0].n + 2:
            x0 = self._sets[0].widen(x, self._sets[1])
            x, meas, more = self._fit(g, h, b, plan, definition, x0=x0, heavy=True, deadline=deadline)
            iterations += more
        if plan.missed(meas) and plan.worst(meas) < EACH_PLANE_MISS:
            # a close miss: the extremum may have jumped between planes. Solve again from the start with a
            # residual per watched plane (morph_planes.py) and keep the nearer body. Not in every solve:
            # it costs a gradient per watched plane and takes other paths, on which bodies that build
            # without it can miss (168 cm, bust 90, waist 72, hips 98 ended 0.2 mm off her waist); from
            # the missed body instead, a 158.5 cm / 104 kg man stalled at his chest band's jumps
            x2, meas2, more = self._fit(g, h, b, plan, definition, each_plane=True, deadline=deadline)
            iterations += more
            if plan.worst(meas2) < plan.worst(meas):
                x, meas = x2, meas2
        return x, meas, iterations

    def _fit(self, g, h, b, plan, definition, push=None, max_outer=7, max_inner=40, x0=None, soft=SOFT_WEIGHT,
             heavy=False, each_plane=False, deadline=None):
        """The measurement stage: channel weights, height slider and build meeting ``plan``.

        ``push`` = (name, goal, weight) replaces one goal (the reach search). Returns (x, measurement,
        outer iterations); ``x`` = [-incr weights, -decr weights, height slider, build] of the base channels,
        or with ``heavy`` (or an ``x0`` of that size) of the base and HEAVY ones. ``each_plane``: a residual
        per watched plane. The outer loop: ``morph_planes.outer_loop``. Past ``deadline`` (time.perf_counter())
        it raises :class:`OutOfTime` (a reach search's time limit)."""
        m = self.measurer
        n_ch = self._sets[1 if heavy else 0].n if x0 is None else (len(x0) - 2) // 2
        rows, mass, w_mass = self._goals(plan, push, soft, each_plane and definition != "makehuman")
        keys, nx = rows.keys, 2 * n_ch + 2
        x, lo, hi, reg = self._start_x(n_ch, h, b, x0)
        # the bust points of the last full measurement (at first the start body's), held while the planes are
        held = [m.bust_points(self._body_split(self.macro(g, x[-2], x[-1]), x[:n_ch], x[n_ch:2 * n_ch]))]

        def residual(q, planes, jac=False):
            # q = [x, slacks of the watched planes (morph_planes.py), during an inner solve]
            if deadline is not None and time.perf_counter() > deadline:
                raise OutOfTime
            p, slack = q[:nx], (q[nx:] if q.size > nx else None)
            v = self._body_split(self.macro(g, p[-2], p[-1]), p[:n_ch], p[n_ch:2 * n_ch])
            m.held_points = None if planes is None else held[0]
            meas = m.measure(v, definition, planes=planes, names=keys, mass=True, gender=g)
            if planes is None:
                held[0] = m.bust_points(v)
            r, plane_rows, grads, signs = rows.rows(meas, planes, slack)
            r = np.concatenate([r, [(meas.mass_kg / mass - 1.0) / MASS_UNIT * w_mass],
                                self._point_gap(v, held[0])[0], plane_rows])
            if not jac:
                return r, meas
            J = self._jacobian(v, p, keys, meas, definition, rows.wres, mass, w_mass, r, grads)
            if slack is not None:
                J = np.hstack([J, np.zeros((r.size, slack.size))])
                J[r.size - slack.size + np.arange(slack.size), nx + np.arange(slack.size)] = signs * SLACK_UNIT
            return r, J

        base_hard = np.concatenate([rows.wres == 1.0, [w_mass == 1.0], [True, True]])

        def slack0(p, planes):  # the slacks start where the planes are (none without rows per plane)
            return rows.slack0(residual(p, planes)[1], planes) if rows.each_plane else np.zeros(0)

        problem = Problem(residual, lambda q, planes: residual(q, planes, True)[1],
                          lambda planes: np.concatenate([base_hard, rows.hard(planes)]), slack0)
        # planes seen so far per girth (fractions of its band): when the extremum jumps between two
        # valleys the inner solve must watch both, or the outer loop would cycle between them. The
        # average body's serve to start: bands move with the body, so fractions stay near
        seen = {k: np.asarray(v, dtype=np.float64) for k, v in plan.start.candidates.items()}
        if x0 is not None:
            # a warm start watches its own body's planes too: on the average body's alone, the first inner
            # solve fits planes far from this body's extrema and walks far off the start (the heavy
            # re-fit of a 174 cm / 146 kg woman put a 160 cm belly into her hips band)
            add_planes(seen, residual(x, None)[1].candidates)
        try:
            return outer_loop(problem, x, (lo, hi), reg, seen, max_outer, max_inner)
        finally:
            m.held_points = None

    @staticmethod
    def _goals(plan, push, soft, each_plane):
        """(GirthRows, mass goal kg, mass weight) of ``plan`` with ``push`` (:meth:`_fit`)."""
        keys = GIRTHS + ("height",)
        goal = np.array([plan.goals[k] for k in keys])
        wres = np.array([1.0 if k in plan.hard else soft for k in keys])
        mass, w_mass = plan.mass, (1.0 if "mass" in plan.hard else soft)
        if push is not None:
            name, value, weight = push
            if name == "weight":
                mass, w_mass = value, weight
            else:
                goal[keys.index(name)], wres[keys.index(name)] = value, weight
        return GirthRows(keys, goal, wres, each_plane), mass, w_mass

    def _start_x(self, n_ch, h, b, x0):
        """(x, lo, hi, reg) of :meth:`_fit`: the start (``x0`` or zero channels at sliders ``h``, ``b``),
        the bounds and the channels' pull towards zero."""
        x = np.zeros(2 * n_ch + 2)
        x[-2:] = h, b
        if x0 is not None:  # a warm start (the reach search starts from a body meeting the other targets)
            x = np.array(x0, dtype=np.float64)
        lo, hi = np.zeros_like(x), np.ones_like(x)
        lo[-1], hi[-1] = B_MIN, B_MAX
        hi[:n_ch] = self._set(n_ch).incr_max
        x[:n_ch] = np.minimum(x[:n_ch], hi[:n_ch])
        reg_ch = np.concatenate([np.full(len(GIRTHS), REG_PRIMARY), np.full(n_ch - len(GIRTHS), REG_SECONDARY)])
        return x, lo, hi, np.concatenate([reg_ch, reg_ch, [0.0, 0.0]])

    def _point_gap(self, v, points):
        """Per side: (hinge residual, held bust point, its nearest rival), the residual in mm
        ``max(0, z_rival - z_held + POINT_MARGIN)``: it keeps the held points the most anterior (a flat
        chest's rows tie, and the chest band jumps with them: :attr:`Measurer.held_points`)."""
        if points is None:
            return np.zeros(2), np.zeros(2, dtype=np.int64), np.zeros(2, dtype=np.int64)
        gaps, rivals = np.zeros(2), np.zeros(2, dtype=np.int64)
        for side, (idx, a) in enumerate(zip(self.measurer.breasts, points)):
            z = np.where(idx == a, -np.inf, v[idx, 2])
            rivals[side] = idx[np.argmax(z)]
            gaps[side] = max(0.0, (z.max() - v[a, 2] + POINT_MARGIN) / MM)
        return gaps, np.asarray(points), rivals

    def _result(self, g, x, meas, plan, targets, weight_kg, iterations) -> MorphResult:
        ch = self._set((x.size - 2) // 2)
        up, down = x[:ch.n], x[ch.n:2 * ch.n]
        macro = self.macro(g, x[-2], x[-1])
        weights = {**macro.target_weights(), **ch.weights(up, down)}
        # the body vertices are exactly the array the last full measurement was taken on
        # (the sparse sum gives the helpers; it differs from the dense one by round-off)
        verts = self.model.shape(weights, first=N_BODY)
        verts[:N_BODY] = self._body_split(macro, up, down)
        meas.values = {k: meas.values[k] for k in NAMES}
        channels = {n: float(v) for n, v in zip(ch.names, up - down)}
        return MorphResult(verts, macro, float(x[-1]), channels, meas, dict(targets), weight_kg, plan.start,
                           iterations, weights, plan.estimated, plan.warnings)

    def _jacobian(self, v, p, keys, meas, definition, wres, mass, w_mass, r, grads):
        """Jacobian of the measurement-stage residuals: ``grad g . D`` per channel (the body is
        linear in them), and ``grad g . dv`` for the height slider and the build, with ``dv`` the
        body's forward difference (the macro sliders are nonlinear, but the body is linear in the
        macro targets' weights: one macro blend per slider instead of a whole measurement)."""
        ch = self._set((p.size - 2) // 2)
        n_ch = ch.n
        J = np.zeros((r.size, p.size))
        # v was just built by _body_split at p's sliders: its macro body is the one cached
        macro, base = self._last_macro
        assert macro == self.macro(macro.gender, p[-2], p[-1])
        moves = np.empty((2, 3 * N_BODY))  # d body / d (height slider, build), flattened
        for row, (col, top) in enumerate(((-2, 1.0), (-1, B_MAX))):
            step = -1e-5 if p[col] + 1e-5 > top else 1e-5
            q = p.copy()
            q[col] += step
            moves[row] = (self._macro_body(self.macro(macro.gender, q[-2], q[-1])) - base) / step
        moves3 = moves.reshape(2, N_BODY, 3)
        base = len(keys) + 3  # the hinge rows follow the keys', the mass's and the two point gaps'
        # the profile spline's girth has no gradient of its own here: the tape's at the same plane stands in (the
        # spline follows the hull but for hollows the tape bridges). The steps are then Gauss-Newton's with an
        # approximate Jacobian and the spline girths decide when the targets are met: 24 random feasible target
        # sets all met (worst 0.077 mm) in half the time of finite differences (0.144 mm), and a missed target
        # found in 0.4-0.5 s instead of 1.1-2.2 s (a failure of `vfit morph --definition spline` took 2.7-3.5 s)
        jdef = "iso" if definition == "spline" else definition
        for row, k, fraction in grads:
            idx, grad = self.measurer.gradient(v, k, jdef, fraction, gender=macro.gender)
            scale = wres[keys.index(k)] / MM
            row = row if row < len(keys) else row - len(keys) + base
            J[row, :n_ch] = np.einsum("jkc,kc->j", ch.incr3[:, idx], grad) * scale
            J[row, n_ch:2 * n_ch] = np.einsum("jkc,kc->j", ch.decr3[:, idx], grad) * scale
            J[row, -2:] = np.einsum("jkc,kc->j", moves3[:, idx], grad) * scale
        grad = self.measurer.mass_gradient(v).ravel()
        scale = 1.0 / mass / MASS_UNIT * w_mass
        col = np.empty(2 * n_ch)
        project(ch.updown, grad, col)
        J[len(keys), :2 * n_ch] = col * scale
        # the serial kernel, not NumPy's dot (see kernels/blend.py: BLAS threads on a busy machine)
        slider = np.empty(2)
        project(moves, grad, slider)
        J[len(keys), -2:] = slider * scale
        for side, (gap, a, o) in enumerate(zip(*self._point_gap(v, self.measurer.held_points))):
            if gap > 0:  # an active hinge: d(z_o - z_a)
                row = len(keys) + 1 + side
                J[row, :n_ch] = (ch.incr3[:, o, 2] - ch.incr3[:, a, 2]) / MM
                J[row, n_ch:2 * n_ch] = (ch.decr3[:, o, 2] - ch.decr3[:, a, 2]) / MM
                J[row, -2:] = (moves3[:, o, 2] - moves3[:, a, 2]) / MM
        return J


def _gender_of(name: str) -> str:
    return "male" if "-male-" in name or name.split("/")[-1].startswith("male-") else "female"


def _genders(g: float) -> tuple:
    return tuple(x for x, w in (("female", 1.0 - g), ("male", g)) if w > 0)
