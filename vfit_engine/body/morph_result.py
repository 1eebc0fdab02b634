"""What a morph solve aims at (:class:`Plan`) and what it returns (:class:`MorphResult`)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .measure import Measurement
from .model import Macro
from .morph_settings import TOLERANCE_M, TOLERANCE_MASS


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
    #: name -> (survey estimate, relative standard error) of every girth (m) and the mass (kg) not given
    estimated: dict = field(default_factory=dict)
    #: lines saying which given values are outside the 1st-99th percentile of the population
    warnings: list = field(default_factory=list)


@dataclass
class Plan:
    """What a solve aims at. goals : name -> m (every girth and height); mass : kg; hard : the names
    given (``mass`` if the weight was); estimated, warnings : as in MorphResult; start : the average body."""

    goals: dict
    mass: float
    hard: set
    estimated: dict
    warnings: list
    start: Measurement

    def missed(self, meas: Measurement) -> bool:
        """Does ``meas`` miss a given value (girth or height, or the mass)?"""
        if "mass" in self.hard and abs(meas.mass_kg / self.mass - 1.0) > TOLERANCE_MASS:
            return True
        return any(abs(meas.values[k] - self.goals[k]) > TOLERANCE_M for k in self.hard if k != "mass")

    def worst(self, meas: Measurement) -> float:
        """The largest miss (m) of a given girth or height, the mass's counted as TOLERANCE_M per
        TOLERANCE_MASS."""
        mass = abs(meas.mass_kg / self.mass - 1.0) / TOLERANCE_MASS * TOLERANCE_M if "mass" in self.hard else 0.0
        return max([mass] + [abs(meas.values[k] - self.goals[k]) for k in self.hard if k != "mass"])
