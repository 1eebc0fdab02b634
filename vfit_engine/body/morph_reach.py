"""The morph solver's answer to targets it cannot meet: each missed target with the range reachable given the others.

:class:`ReachSearch` is a part of :class:`vfit_engine.body.morph.Morpher` (its solves and plans): after a solve,
:meth:`ReachSearch._check` raises the failure, searching each missed target's range (:meth:`ReachSearch.reachable`)
worst miss first until a deadline. A search running at the deadline is cut (:class:`OutOfTime`, raised from the
solve's residual), so that a failure answers within its time.
"""
from __future__ import annotations

import time

import numpy as np

from ..errors import InputError
from .model import gender_value
from .morph_result import MorphResult
from .morph_settings import B_MAX, REACH_PULL, REACH_SOFT, REACH_WEIGHT, TOLERANCE_M, TOLERANCE_MASS


class OutOfTime(Exception):
    """A reach search ran past its deadline (``Morpher.reachable``): a failure answers within its time."""


class ReachSearch:
    """The failure and reach-search methods of :class:`~vfit_engine.body.morph.Morpher` (which supplies ``plan``,
    ``_semantic``, ``_fit_all``, ``_fit`` and ``_sets``)."""

    def _check(self, res: MorphResult, definition: str, g: float, deadline: float, x=None) -> None:
        """Raise InputError naming each target that was missed, with the range reachable given the others.

        Ranges are searched for the worst-missed targets first, each from the missed body ``x`` (the solve's
        channels and sliders), while ``deadline`` (time.perf_counter()) allows (:data:`RANGE_SEARCH_UNTIL`).
        """
        miss = {k: abs(res.measurement.values[k] / want - 1) for k, want in res.targets.items()
                if abs(res.measurement.values[k] - want) > TOLERANCE_M}
        if res.weight_kg is not None and abs(res.measurement.mass_kg / res.weight_kg - 1) > TOLERANCE_MASS:
            miss["weight"] = abs(res.measurement.mass_kg / res.weight_kg - 1)
        if not miss:
            return
        parts = {}
        for k in sorted(miss, key=miss.get, reverse=True):
            unit, scale = ("kg", 1.0) if k == "weight" else ("cm", 100.0)
            want = res.weight_kg if k == "weight" else res.targets[k] * 100
            got = res.measurement.mass_kg if k == "weight" else res.measurement.values[k] * 100
            reach = "range not searched in the time limit: --search-time to search longer"
            if time.perf_counter() < deadline:
                try:
                    lo, hi = self.reachable(k, res.targets, g, definition, res.weight_kg, deadline=deadline, x0=x)
                    reach = _range_text(lo * scale, hi * scale, 0.1, unit)
                except OutOfTime:  # the search is cut short: a failure answers within its time
                    pass
                except InputError:  # without it the others are refused: no body meets them, so no range
                    reach = "no range: without it the other targets are outside the population"
            parts[k] = f"{k} {want:.1f} {unit} ({reach}, got {got:.1f})"
        what = "cannot be reached" if len(parts) == 1 else "cannot be met together"
        order = [k for k in list(res.targets) + ["weight"] if k in parts]
        raise InputError(f"target {what}: " + "; ".join(parts[k] for k in order) + " with the other targets as given")

    def reachable(self, name: str, targets: dict, gender, definition: str = "iso", weight_kg=None, deadline=None,
                  x0=None):
        """(lo, hi) of ``name`` (m; kg for ``'weight'``) over bodies that meet the *other* targets.

        A solve without ``name`` finds a body meeting the others; from it, two short solves pull
        ``name`` towards half and twice its value (at a weight that gives way to every other
        target) and read where they stopped. Each end is the value of a body that meets the other
        targets, so the range is true, though a longer search may find it a little wider.
        ``(nan, nan)`` if the other targets cannot be met together either. Raises :class:`OutOfTime` past
        ``deadline`` (time.perf_counter(); None: no limit). ``x0``: where the solve without ``name`` starts (the
        body that missed: it is near the others' targets, and from there that solve took 0.5 s where it took 1.6 s
        from the average body (waist 90, hips 95, bust 130, underbust 70: the underbust's range)).
        """
        g = gender_value(gender)
        others = {k: v for k, v in targets.items() if k != name}
        w_others = None if name == "weight" else weight_kg

        def value(meas):
            return meas.mass_kg if name == "weight" else meas.values[name]

        def meets_others(meas):
            ok = all(abs(meas.values[k] - v) <= TOLERANCE_M for k, v in others.items())
            return ok and (w_others is None or abs(meas.mass_kg / w_others - 1) <= TOLERANCE_MASS)

        plan = self.plan(others, g, definition, w_others)
        h, b = self._semantic(g, plan.goals["height"], plan.mass, definition)
        if x0 is not None and (x0.size != 2 * self._sets[0].n + 2 or x0[-1] >= B_MAX - 1e-9):
            x0 = None  # missed at the heavy corner: from there the solve refits with the HEAVY channels, slower
        x, meas, _ = self._fit_all(g, h, b, plan, definition, deadline=deadline, x0=x0)
        if not meets_others(meas):
            return float("nan"), float("nan")
        ends = [value(meas)]
        for far in REACH_PULL:
            # the estimates barely pull here (REACH_SOFT): what limits the range is the other targets
            push = (name, value(meas) * far, REACH_WEIGHT)
            x2, meas2, _ = self._fit(g, h, b, plan, definition, push=push, max_outer=2, max_inner=12, x0=x,
                                     soft=REACH_SOFT, deadline=deadline)
            if meets_others(meas2):
                ends.append(value(meas2))
            if far > 1.0 and x2[-1] >= B_MAX - 1e-9 and x2.size == 2 * self._sets[0].n + 2:
                # stopped at the heavy corner: go on with the HEAVY channels, as a solve would
                x3, meas3, _ = self._fit(g, h, b, plan, definition, push=push, max_outer=2, max_inner=12,
                                         x0=self._sets[0].widen(x2, self._sets[1]), soft=REACH_SOFT, heavy=True,
                                         deadline=deadline)
                if meets_others(meas3):
                    ends.append(value(meas3))
        return min(ends), max(ends)


def _range_text(lo, hi, step, unit):
    """'reachable lo-hi unit', rounded inwards to ``step`` so that both printed ends are reachable."""
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "the other targets cannot be met together either"
    a, b = np.ceil(lo / step - 1e-9) * step, np.floor(hi / step + 1e-9) * step
    if a > b:
        return f"reachable only about {lo:.2f} {unit}"
    return f"reachable {a:.1f}-{b:.1f} {unit}"
