"""The band planes the morph solver watches: its outer loop, and the girth residuals of its inner solves.

A tape girth is the extremum over its band: the waist the smallest girth, the hips the largest. The outer
loop (:func:`outer_loop`) alternates an inner solve over the band planes seen so far with a full search of
every band at the new body, adding the planes it finds.

By default the inner solve has one residual per girth, at its extremal watched plane. A step that meets
the target there can take another watched plane past it; the extremum jumps, and the solve can zigzag
between the two and stall millimetres short (NHANES's 135-degree corner of the men's height-mass ellipse,
158.5 cm / 104.1 kg, waist 122.7 and hips 123.8 cm, stopped 3.7 mm off its waist). With ``each_plane``
(:class:`GirthRows`) a girth of mode ``min`` and target ``T`` is asked, at its watched planes ``g_i``, for

* ``g_i >= T`` at every plane: a row ``e_i - s_i`` per plane, ``e_i = g_i - T``, with a slack variable
  ``s_i >= 0`` (so that minimising over ``s_i`` leaves the hinge ``min(0, e_i)``: smooth in the body and
  the slack together, so that the Gauss-Newton model sees every plane, not only those already past), and
* ``min_i g_i <= T``: one row ``max(0, min_i g_i - T)`` in the girth's own place,

(``max`` mirrored), which together hold exactly where ``min_i g_i = T``. The bust keeps its one row: the
top of its band is the last whole millimetre with the arms apart, so its planes jump with it, and a row
per plane made the solve stall at those jumps.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .gauss_newton import gauss_newton
from .morph_settings import MM, EARLY_EXIT, SEEN_PLANES, SOFT_TOL, TOLERANCE_M

#: +1 where the girth is the smallest over its band, -1 where the largest (``measure.py``'s definitions)
SIGN = {"underbust": 1.0, "waist": 1.0, "hips": -1.0}
#: a slack variable's unit (in the rows' weighted mm): the inner solve's trust region bounds every
#: variable's step by about 1, and a plane can lie centimetres clear of its target
SLACK_UNIT = 100.0


@dataclass
class GirthRows:
    """The measurement rows of one solve: ``(value - goal) / mm * weight`` per key, and with ``each_plane``
    one more per watched plane of each girth in :data:`SIGN` (the module docstring).

    keys : tuple of str; goal : (len(keys),) float, m; wres : (len(keys),) float - residual weights
    each_plane : bool
    """

    keys: tuple
    goal: np.ndarray
    wres: np.ndarray
    each_plane: bool

    def _watched(self, planes):
        return planes if self.each_plane else None

    def rows(self, meas, planes, slack=None):
        """(r (len(keys),), plane rows (n,), grads, signs) of ``meas`` taken at ``planes`` (None: a full
        search); ``slack`` (n,) in units of :data:`SLACK_UNIT`. ``grads``: (row, key, band fraction) of every
        row with a nonzero derivative, plane rows counted from ``len(keys)``; ``signs``: d row / d slack /
        SLACK_UNIT per plane row."""
        planes = self._watched(planes)
        r = (np.array([meas.values[k] for k in self.keys]) - self.goal) / MM * self.wres
        grads, rows, signs = [], [], []
        for i, k in enumerate(self.keys):
            if planes is None or k not in SIGN or k not in meas.at_planes:
                grads.append((i, k, meas.fractions.get(k)))
                continue
            s = SIGN[k]
            e = self._excess(meas, i, k)
            r[i] = s * max(0.0, float(np.nanmin(e)))
            if r[i] != 0.0:
                grads.append((i, k, meas.fractions[k]))
            for t, ej in zip(np.atleast_1d(planes[k]), e):
                row = len(self.keys) + len(rows)
                if not np.isfinite(ej):  # no torso loop at this plane: nothing to hold
                    rows.append(0.0)
                elif slack is not None:
                    rows.append(s * (ej - SLACK_UNIT * slack[len(signs)]))
                    grads.append((row, k, float(t)))
                else:
                    rows.append(s * min(0.0, float(ej)))
                    if ej < 0.0:
                        grads.append((row, k, float(t)))
                signs.append(-s)
        return r, np.asarray(rows, dtype=np.float64), grads, np.asarray(signs)

    def _excess(self, meas, i, k):
        """Per watched plane of girth ``k``: how far (weighted mm) it lies on the allowed side of its goal."""
        return SIGN[k] * (np.asarray(meas.at_planes[k]) - self.goal[i]) / MM * self.wres[i]

    def slack0(self, meas, planes):
        """(n,) the slacks that start an inner solve at ``meas`` (taken at ``planes``): each plane's excess,
        0 where past its goal or without a torso loop."""
        planes = self._watched(planes)
        out = [self._excess(meas, i, k) for i, k in enumerate(self.keys)
               if planes is not None and k in SIGN and k in meas.at_planes]
        if not out:
            return np.zeros(0)
        e = np.concatenate(out)
        return np.where(np.isfinite(e), np.maximum(e, 0.0), 0.0) / SLACK_UNIT

    def hard(self, planes):
        """(n,) bool: which plane rows belong to a target (a girth of weight 1)."""
        planes = self._watched(planes)
        if planes is None:
            return np.zeros(0, dtype=bool)
        out = [np.full(np.atleast_1d(planes[k]).size, w == 1.0) for k, w in zip(self.keys, self.wres)
               if k in SIGN and k in planes]
        return np.concatenate(out) if out else np.zeros(0, dtype=bool)


class Problem(NamedTuple):
    """What :func:`outer_loop` solves. ``residual(q, planes)`` -> (r, Measurement), ``q`` = [x, one slack per
    plane row], ``planes`` None for a full band search; ``jacobian(q, planes)`` -> J, or None (forward
    differences); ``hard(planes)`` -> (r.size,) bool, the target rows; ``slack0(x, planes)`` -> the slacks
    that start an inner solve at ``x``."""

    residual: Callable
    jacobian: Callable | None
    hard: Callable
    slack0: Callable


def add_planes(seen, candidates, keep=None):
    """``seen`` (name -> band fractions) with the ``candidates`` more than 1e-4 from any, the latest
    ``keep`` of each."""
    for k, ys in candidates.items():
        new = [t for t in ys if np.min(np.abs(seen[k] - t)) > 1e-4]
        seen[k] = np.concatenate([seen[k], new])[-keep if keep else None:]
    return seen


def outer_loop(problem, x, bounds, reg, seen, max_outer, max_inner):
    """The measurement stage's outer loop: inner solves of ``problem`` at the planes ``seen`` (name -> band
    fractions; updated), each followed by a full band search that adds the planes it finds.

    ``bounds`` = (lo, hi) and ``reg`` of ``x`` (:func:`gauss_newton.gauss_newton`). Returns (x,
    measurement, iterations). Stops once every target is met within half the tolerance, or where a target
    stays more than 1 mm away without closing in.
    """
    iterations, worst, prev_inner = 0, np.inf, np.inf
    (lo, hi), hard = bounds, problem.hard
    for iterations in range(1, max_outer + 1):
        hard_in = hard(seen)
        s0 = problem.slack0(x, seen)
        n = s0.size
        q, r_inner = gauss_newton(problem.residual, np.concatenate([x, s0]), np.concatenate([lo, np.zeros(n)]),
                                  np.concatenate([hi, np.full(n, np.inf)]), np.concatenate([reg, np.zeros(n)]),
                                  seen, hard=hard_in, max_iter=max_inner, soft_tol=SOFT_TOL, jac=problem.jacobian)
        x = q[:x.size]
        r, meas = problem.residual(x, None)  # full band search at the new shape
        add_planes(seen, meas.candidates, SEEN_PLANES)
        miss = float(np.max(np.abs(r[hard(None)]), initial=0.0)) * MM
        if miss < TOLERANCE_M * 0.5:
            break
        # a target out of reach: the inner solve missed it by over 1 mm even at its own planes, twice
        # running without halving the miss (on every body of the reach list it ends within 0.03 mm;
        # after one such pass new planes can still open the way), or passes stop closing in
        inner = float(np.max(np.abs(r_inner[hard_in]), initial=0.0)) * MM
        if inner > EARLY_EXIT and inner > 0.5 * prev_inner or (miss > 1e-3 and miss > 0.8 * worst):
            break
        prev_inner = inner
        worst = min(worst, miss)
    return x, meas, iterations
