"""Solve target weights so a body meets every requested measurement at once.

The seed system scanned one blend-shape weight at a time until
``|L - L_target| <= sigma``. Here all requested measurements are met jointly by
bounded nonlinear least squares:

* **semantic stage** - MakeHuman's macro sliders give a plausible body for the
  gender: ``height`` (0..1) meets ``--height`` (stature) and the *build* path
  ``b`` (-1..1) meets ``--weight`` (enclosed volume x density). ``b > 0`` moves
  towards MakeHuman's heavy corner (weight 0.5 -> 1 while muscle 0.5 -> 0),
  ``b < 0`` towards its light one (weight 0.5 -> 0); MakeHuman's weight slider
  alone spans only about +-7 kg, its muscle x weight grid about 30-82 kg.
* **measurement stage** - one *primary* channel per girth (``measure-*-incr``
  for weights > 0, ``-decr`` for < 0, range -1..1), *secondary* channels
  (torso and hip scale targets, and the build path when no weight is given)
  that take over where a primary one saturates, and the height (and build)
  sliders. Residuals, in order of priority: every requested measurement
  (weight 1), every girth and the height *not* requested held at its
  semantic-stage value (weight ``HOLD_WEIGHT``, so the waist alone moves bust
  and hips by well under a millimetre when the body allows it), and a tiny pull
  of every channel towards zero (primary ``REG_PRIMARY`` < secondary
  ``REG_SECONDARY``) that picks one body among the many meeting the targets.

Tape girths are maxima/minima over a band of planes. By the envelope theorem
their derivative is the derivative at the extremal plane, so the inner solve
keeps each girth's planes fixed (as fractions of its band, so they move with
the band; every near-extremal plane seen so far, so the solve cannot cycle
between two valleys) and the outer loop re-searches the bands until the full
measurement meets every target. The inner solve is a trust-region
Gauss-Newton with bounded linear steps (``scipy.optimize.lsq_linear``) and an
exact Jacobian: the body is linear in its channel weights, so
``dg/dx_j = grad_v g . D_j`` with the gradients of ``gradients.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .measure import _PLANE_GIRTHS, NAMES, Measurement, Measurer
from .model import N_BODY, BodyModel, Macro, gender_value

#: girth -> its primary target (``-incr``/``-decr`` appended)
CHANNELS = {
    "bust": "torso/measure-bust-circ",
    "underbust": "torso/measure-underbust-circ",
    "waist": "torso/measure-waist-circ",
    "hips": "torso/measure-hips-circ",
    "neck": "neck/measure-neck-circ",
    "upper-arm": "arms/measure-upperarm-circ",
    "thigh": "legs/measure-thigh-circ",
    "calf": "legs/measure-calf-circ",
}
GIRTHS = tuple(CHANNELS)
#: secondary channels: used when the primary ones saturate
SECONDARY = ("torso/torso-scale-horiz", "torso/torso-scale-depth", "hip/hip-scale-horiz", "hip/hip-scale-depth")
#: a girth or height within this of its target counts as met (m); the promise is 1 mm.
TOLERANCE_M = 0.0002
#: mass within this fraction of its target counts as met (the promise is 1 %).
TOLERANCE_MASS = 0.002
_MM = 1e-3
_MASS_UNIT = 1e-3  # mass residual unit: 0.1 % counts like 1 mm
# A strict hierarchy by weight (residuals in mm): a 1 mm target miss costs 1, a 1 mm
# hold miss 1e-4, a whole unit of a primary channel 1e-10 and of a secondary one 1e-8,
# so a target gives way to holds by only ~HOLD_WEIGHT**2 of their residual.
HOLD_WEIGHT = 0.01
REG_PRIMARY = 1e-5  # mm-equivalent per unit of channel weight
REG_SECONDARY = 1e-4


def build_sliders(b: float) -> tuple[float, float]:
    """(muscle, weight) MakeHuman sliders of build ``b`` in -1..1 (0 = average)."""
    b = float(np.clip(b, -1.0, 1.0))
    if b >= 0:
        return 0.5 - 0.5 * b, 0.5 + 0.5 * b
    return 0.5, 0.5 + 0.5 * b


@dataclass
class MorphResult:
    """A solved body.

    verts : (19158, 3) float64, m - all vertices (body first, then helpers)
    macro : the macro settings; channels : target base name -> signed weight
    measurement : full measurement of the result; targets : what was asked (m)
    start : measurement of the average body the solve started from
    """

    verts: np.ndarray
    macro: Macro
    build: float
    channels: dict
    measurement: Measurement
    targets: dict
    weight_kg: float | None
    start: Measurement
    iterations: int
    target_weights: dict


class Morpher:
    """Builds bodies to measurements. Create once: it loads the model and caches dense targets."""

    def __init__(self, model: BodyModel | None = None, measurer: Measurer | None = None):
        self.model = model or BodyModel.load()
        self.measurer = measurer or Measurer(self.model)
        self._channel_names = [CHANNELS[g] for g in GIRTHS] + list(SECONDARY)
        dense = lambda n: self.model.dense_target(n, N_BODY).ravel()
        self._incr = np.stack([dense(c + "-incr") for c in self._channel_names])
        self._decr = np.stack([dense(c + "-decr") for c in self._channel_names])
        self._incr3 = self._incr.reshape(len(self._channel_names), N_BODY, 3)
        self._decr3 = self._decr.reshape(len(self._channel_names), N_BODY, 3)
        self._macro_cache = {}
        self._last_macro = (None, None)

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
        return self.model.base_verts[:N_BODY].ravel() + stack.T.dot(w)

    def _body(self, macro: Macro, s: np.ndarray) -> np.ndarray:
        """Body of signed channel weights ``s`` (> 0 picks -incr, < 0 picks -decr)."""
        return self._body_split(macro, np.maximum(s, 0), np.maximum(-s, 0))

    def _body_split(self, macro: Macro, incr: np.ndarray, decr: np.ndarray) -> np.ndarray:
        """Body of separate, non-negative -incr and -decr weights: linear and smooth in both."""
        if self._last_macro[0] != macro:  # the solver varies channels far more often than sliders
            self._last_macro = (macro, self._macro_body(macro))
        # A.T.dot(x) rather than x @ A: the latter goes through a multithreaded BLAS path
        # that costs 50x more on a busy machine (3.4 ms against 0.04 ms measured)
        return (self._last_macro[1] + self._incr.T.dot(incr) + self._decr.T.dot(decr)).reshape(N_BODY, 3)

    # ----------------------------------------------------------------- solving
    def solve(self, targets: dict, gender="female", definition="iso", weight_kg=None) -> MorphResult:
        """Build a body meeting ``targets``.

        Parameters
        ----------
        targets : dict
            Measurement name (one of ``NAMES``) -> value in metres.
        gender : 'female', 'male' or 0..1
        definition : 'iso' | 'makehuman' | 'spline'
        weight_kg : float, optional
            Body mass to meet through volume x density.

        Raises
        ------
        InputError
            A target the model cannot reach (the message gives the reachable
            range) or targets that cannot be met together.
        """
        unknown = set(targets) - set(NAMES)
        if unknown:
            raise InputError(f"unknown measurement(s): {', '.join(sorted(unknown))}")
        g = gender_value(gender)
        m = self.measurer
        n_ch = len(self._channel_names)
        zero = np.zeros(n_ch)
        start = m.measure(self._body(self.macro(g, 0.5, 0.0), zero), definition)
        iterations = 0

        # -- semantic stage
        h, b = 0.5, 0.0
        free = [k for k in ("height", "weight") if (k == "height" and "height" in targets) or
                (k == "weight" and weight_kg is not None)]
        if free:
            def semantic(p, planes=None):
                hh = p[free.index("height")] if "height" in free else 0.5
                bb = p[free.index("weight")] if "weight" in free else 0.0
                v = self._body(self.macro(g, hh, bb), zero)
                r = []
                if "height" in free:
                    r.append((m.measure(v, definition, names=("height",), mass=False).values["height"]
                              - targets["height"]) / _MM)
                if "weight" in free:
                    r.append((m.mass(v) / weight_kg - 1.0) / _MASS_UNIT)
                return np.array(r), None

            lo = np.array([0.0 if k == "height" else -1.0 for k in free])
            p, _ = _gauss_newton(semantic, np.array([0.5 if k == "height" else 0.0 for k in free]), lo,
                                 np.ones(len(free)), np.zeros(len(free)), None)
            h = p[free.index("height")] if "height" in free else 0.5
            b = p[free.index("weight")] if "weight" in free else 0.0
            # only the girths to hold need their bands searched on the semantic body; targeted
            # girths just need starting planes, and the start body's (band fractions) serve
            hold = [k for k in NAMES if k not in targets or k not in _PLANE_GIRTHS]
            base = m.measure(self._body(self.macro(g, h, b), zero), definition, names=hold, mass=False)
            base.candidates = {**start.candidates, **base.candidates}
        else:
            base = start
        s = zero
        split = (zero, zero)

        # -- measurement stage. Each channel is two non-negative parameters (its
        # -incr and -decr weights): the body is then linear and smooth in them,
        # where one signed weight would put a kink exactly at the starting point.
        if any(k in GIRTHS for k in targets):
            keys = GIRTHS + ("height",)
            goal = np.array([targets[k] if k in targets else base.values[k] for k in keys])
            wres = np.array([1.0 if k in targets else HOLD_WEIGHT for k in keys])
            with_mass = weight_kg is not None
            x = np.zeros(2 * n_ch + int(with_mass))
            lo = np.zeros_like(x)
            hi = np.ones_like(x)
            if with_mass:
                x[-1], lo[-1] = b, -1.0
            reg_ch = np.concatenate([np.full(len(GIRTHS), REG_PRIMARY), np.full(len(SECONDARY), REG_SECONDARY)])
            reg = np.concatenate([reg_ch, reg_ch, [0.0] * int(with_mass)])

            def residual(p, planes, jac=False):
                bb = p[-1] if with_mass else b
                v = self._body_split(self.macro(g, h, bb), p[:n_ch], p[n_ch:2 * n_ch])
                meas = m.measure(v, definition, planes=planes, names=keys, mass=with_mass)
                r = (np.array([meas.values[k] for k in keys]) - goal) / _MM * wres
                if with_mass:
                    r = np.append(r, (meas.mass_kg / weight_kg - 1.0) / _MASS_UNIT)
                if not jac:
                    return r, meas
                return r, self._jacobian(v, p, keys, meas, definition, wres, weight_kg, residual, r, planes)

            def jacobian(p, planes):
                r, J = residual(p, planes, jac=True)
                return J

            hard = np.concatenate([wres == 1.0, np.ones(int(with_mass), dtype=bool)])
            meas = base
            # planes seen so far per girth: when the extremum jumps between two valleys
            # the inner solve must watch both, or the outer loop would cycle between them
            seen = {k: np.asarray(v, dtype=np.float64) for k, v in base.candidates.items()}
            for iterations in range(1, 8):
                x, _ = _gauss_newton(residual, x, lo, hi, reg, seen, hard=hard,
                                     jac=None if definition == "spline" else jacobian)
                r, meas = residual(x, None)  # full band search at the new shape
                for k, ys in meas.candidates.items():
                    new = [t for t in ys if np.min(np.abs(seen[k] - t)) > 5e-3]
                    seen[k] = np.concatenate([seen[k], new])[-4:]
                if np.all(np.abs(r[hard]) * _MM < TOLERANCE_M * 0.5):
                    break
            split = (x[:n_ch], x[n_ch:2 * n_ch])
            s = split[0] - split[1]
            if with_mass:
                b = x[-1]

        macro = self.macro(g, h, b)
        channels = {n: float(v) for n, v in zip(self._channel_names, s)}
        weights = dict(macro.target_weights())
        for name, up, down in zip(self._channel_names, *split):
            if up > 0:
                weights[name + "-incr"] = float(up)
            if down > 0:
                weights[name + "-decr"] = float(down)
        # the body vertices are exactly the array the last full measurement was taken on
        # (the sparse sum gives the helpers; it differs from the dense one by round-off)
        if any(k in GIRTHS for k in targets):
            body, result = self._body_split(macro, *split), meas
        else:
            body, result = self._body(macro, zero), base
        verts = self.model.shape(weights)
        verts[:N_BODY] = body
        result.values = {**{k: result.values[k] for k in NAMES}, **result.values}
        if not np.isfinite(result.mass_kg):
            result.mass_kg = m.mass(body)
        out = MorphResult(verts, macro, float(b), channels, result, dict(targets), weight_kg, start, iterations,
                          weights)
        self._check(out, definition)
        return out

    def _jacobian(self, v, p, keys, meas, definition, wres, weight_kg, residual, r, planes):
        """Exact Jacobian of the measurement-stage residuals: ``grad g . D`` per channel
        (the body is linear in them); the build column by a forward difference."""
        n_ch = len(self._channel_names)
        J = np.zeros((r.size, p.size))
        for row, k in enumerate(keys):
            idx, grad = self.measurer.gradient(v, k, definition, meas.fractions.get(k))
            scale = wres[row] / _MM
            J[row, :n_ch] = np.einsum("jkc,kc->j", self._incr3[:, idx], grad) * scale
            J[row, n_ch:2 * n_ch] = np.einsum("jkc,kc->j", self._decr3[:, idx], grad) * scale
        if weight_kg is not None:  # the mass row, and the build column (a macro slider, nonlinear)
            from .gradients import volume_gradient
            from .measure import DENSITY

            idx, grad = volume_gradient(v, self.measurer.tris)
            scale = DENSITY / weight_kg / _MASS_UNIT
            J[-1, :n_ch] = np.einsum("jkc,kc->j", self._incr3[:, idx], grad) * scale
            J[-1, n_ch:2 * n_ch] = np.einsum("jkc,kc->j", self._decr3[:, idx], grad) * scale
            step = -1e-5 if p[-1] + 1e-5 > 1.0 else 1e-5
            q = p.copy()
            q[-1] += step
            J[:, -1] = (residual(q, planes)[0] - r) / step
        return J

    # ----------------------------------------------------------------- checks
    def _check(self, res: MorphResult, definition: str) -> None:
        """Raise InputError naming each target that was missed, with its reachable range."""
        parts = []
        for k, want in res.targets.items():
            got = res.measurement.values[k]
            if abs(got - want) > TOLERANCE_M:
                lo, hi = self.reachable(k, res, definition)
                parts.append(f"{k} {want * 100:.1f} cm (reachable {lo * 100:.1f}-{hi * 100:.1f} cm, "
                             f"got {got * 100:.1f})")
        if res.weight_kg is not None and abs(res.measurement.mass_kg / res.weight_kg - 1) > TOLERANCE_MASS:
            lo, hi = self.reachable("weight", res, definition)
            parts.append(f"weight {res.weight_kg:.1f} kg (reachable {lo:.1f}-{hi:.1f} kg, "
                         f"got {res.measurement.mass_kg:.1f})")
        if parts:
            what = "cannot be reached" if len(parts) == 1 else "cannot be met together"
            raise InputError(f"target {what}: " + "; ".join(parts) + " with the other targets as given")

    def reachable(self, name: str, res: MorphResult, definition: str = "iso") -> tuple[float, float]:
        """Range of ``name`` when its own channels go to their bounds, the rest as in ``res``.

        For a girth its primary and secondary channels move together; for height
        the height slider; for weight the build path.
        """
        n_ch = len(self._channel_names)
        s0 = np.array([res.channels[n] for n in self._channel_names])
        vals = []
        for end in (-1.0, 1.0):
            s, mac = s0.copy(), res.macro
            if name == "height":
                mac = self.macro(mac.gender, (end + 1) / 2, res.build)
            elif name == "weight":
                mac = self.macro(mac.gender, mac.height, end)
            else:
                s[GIRTHS.index(name)] = end
                if name in ("bust", "underbust", "waist"):
                    s[len(GIRTHS):len(GIRTHS) + 2] = end
                if name in ("hips", "waist", "thigh"):
                    s[len(GIRTHS) + 2:n_ch] = end
            v = self._body(mac, s)
            vals.append(self.measurer.mass(v) if name == "weight" else
                        self.measurer.measure(v, definition, names=(name,)).values[name])
        return min(vals), max(vals)


def _gender_of(name: str) -> str:
    return "male" if "-male-" in name or name.split("/")[-1].startswith("male-") else "female"


def _genders(g: float) -> tuple:
    return tuple(x for x, w in (("female", 1.0 - g), ("male", g)) if w > 0)


def _gauss_newton(fun, x, lo, hi, reg, planes, hard=None, jac=None, max_iter=40, fd_step=1e-5):
    """Minimise ``|r(x)|^2 + |reg * x|^2`` over ``lo <= x <= hi``.

    ``fun(x, planes) -> (r, info)``. A trust-region Gauss-Newton: a
    forward-difference Jacobian with Broyden rank-one updates between refreshes,
    and each step the bounded linear least-squares problem (``lsq_linear``)
    within a box of half-width ``delta`` that grows after good steps and shrinks
    after bad ones (a bad step first refreshes a stale Jacobian). Stops when the
    objective stalls (relative decrease < 1e-2) or is tiny, with the ``hard``
    residuals (all by default) under 0.03 (in their units, here 0.03 mm; the
    caller verifies its own tolerance afterwards). With ``jac(x,
    planes) -> J`` the exact Jacobian is used at every iterate instead.
    """
    from scipy.optimize import lsq_linear

    def objective(r, x):
        d = reg * x
        return float(r @ r + d @ d)

    def jacobian(x, r):
        if jac is not None:
            return jac(x, planes)
        J = np.empty((r.size, x.size))
        for j in range(x.size):
            step = fd_step if x[j] + fd_step <= hi[j] else -fd_step
            xp = x.copy()
            xp[j] += step
            J[:, j] = (fun(xp, planes)[0] - r) / step
        return J

    x = np.clip(np.asarray(x, dtype=np.float64), lo, hi)
    r, _ = fun(x, planes)
    hard = np.ones(r.size, dtype=bool) if hard is None else hard
    J, fresh = jacobian(x, r), True
    f = objective(r, x)
    A_reg = np.diag(reg)
    delta = 1.0
    for _ in range(max_iter):
        A = np.vstack([J, A_reg])
        rhs = -np.concatenate([r, reg * x])
        box = (np.maximum(lo - x, -delta) - 1e-15, np.minimum(hi - x, delta) + 1e-15)
        dx = lsq_linear(A, rhs, bounds=box, method="bvls", tol=1e-12).x
        if np.max(np.abs(dx)) < 1e-10:
            break
        model = A @ dx - rhs
        predicted = f - float(model @ model)
        x_new = np.clip(x + dx, lo, hi)
        r_new, _ = fun(x_new, planes)
        f_new = objective(r_new, x_new)
        rho = (f - f_new) / predicted if predicted > 0 else -1.0
        if rho < 0.1:
            if not fresh:  # the Broyden model went stale: refresh it and retry from x
                J, fresh = jacobian(x, r), True
                continue
            delta *= 0.25
            if delta < 1e-7:
                break
            if f_new >= f:
                continue
        step = x_new - x
        if jac is not None:
            J, fresh = jacobian(x_new, r_new), True
        else:
            J = J + np.outer(r_new - r - J @ step, step) / (step @ step)
            fresh = False
        if rho > 0.75 and np.max(np.abs(dx)) > 0.5 * delta:
            delta = min(2.0 * delta, 1.0)
        stalled = f - f_new < 1e-2 * f
        x, r, f = x_new, r_new, f_new
        if np.all(np.abs(r[hard]) < 0.03) and (stalled or f < 1e-6):
            break
    return x, r
