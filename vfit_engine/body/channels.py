"""The blend-shape channels the morph solver moves: which hm08 targets, and their dense stacks.

A channel is one signed weight: > 0 applies its ``-incr`` target(s), < 0 its ``-decr`` ones. A name with
``{}`` moves the left and the right target together (``arms/{}-upperarm-fat``: l and r).
"""
from __future__ import annotations

import numpy as np

from .model import N_BODY

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
#: channels that add volume where MakeHuman's heavy corner ends, used only when a solve ends there (build at
#: its maximum) with a target missed (``Morpher._fit_all``). Without them a 160 cm woman stops at ~143 kg
#: with every other channel at its end; NHANES 2017-2018 puts 1 % of US women over 146 kg. In every solve,
#: they made a 165 cm / 90 kg solve 3x slower and let one of fifty random feasible target sets stall 0.7 mm
#: short of its waist; present but held at zero, they changed the bounded least-squares steps enough to
#: fail EN 13402 size 54
HEAVY = ("stomach/stomach-pregnant", "arms/{}-upperarm-fat", "arms/{}-lowerarm-fat", "legs/{}-upperleg-fat",
         "legs/{}-lowerleg-fat")

#: upper bounds below 1 of some channels' ``-incr`` weight. measure-bust-circ-incr folds the skin under the
#: pectorals and at the armpits on MakeHuman's heavy corner: faces turned over on the heavy male (build 1)
#: at bust weight 0.5, 0.7, 0.8, 0.9, 1.0: 8, 8, 14, 20, 28 (the corner alone 4; on the heavy female 2, 2,
#: 4, 6, 10). A 175 cm / 130 kg man, whose estimated chest (140 cm) pulled it to 1, turned 24.
#: measure-underbust-circ-incr does the same at the armpits: the survey's 99th-percentile-waist man (181.7 cm,
#: 156.4 kg, waist 143.8, hips 146.8) turned 20 with it at 1, 10 at 0.8 (and still builds)
INCR_MAX = {"torso/measure-bust-circ": 0.8, "torso/measure-underbust-circ": 0.8}


def channel_targets(channel: str) -> tuple:
    """The hm08 targets (base names) a channel moves together."""
    return (channel.format("l"), channel.format("r")) if "{}" in channel else (channel,)


class ChannelSet:
    """Dense stacks of a list of channels on the body's vertices.

    names : list of str; n : channel count
    updown : (2n, 3 * 13380) float64 C-contiguous - the ``-incr`` rows, then the ``-decr`` rows (m)
    incr3, decr3 : (n, 13380, 3) views of the two halves
    incr_max : (n,) upper bound of each ``-incr`` weight (:data:`INCR_MAX`)
    """

    def __init__(self, model, names):
        self.names = list(names)
        self.n = len(self.names)
        self.incr_max = np.array([INCR_MAX.get(c, 1.0) for c in self.names])

        def dense(channel, end):
            return sum(model.dense_target(t + end, N_BODY).ravel() for t in channel_targets(channel))

        self.updown = np.empty((2 * self.n, 3 * N_BODY))
        for i, c in enumerate(self.names):
            self.updown[i], self.updown[self.n + i] = dense(c, "-incr"), dense(c, "-decr")
        self.incr3 = self.updown[:self.n].reshape(self.n, N_BODY, 3)
        self.decr3 = self.updown[self.n:].reshape(self.n, N_BODY, 3)

    def weights(self, up, down) -> dict:
        """hm08 target name -> weight of channel weights ``up`` (-incr) and ``down`` (-decr), both >= 0."""
        out = {}
        for name, u, d in zip(self.names, up, down):
            for target in channel_targets(name):
                if u > 0:
                    out[target + "-incr"] = float(u)
                if d > 0:
                    out[target + "-decr"] = float(d)
        return out

    def widen(self, x, other: "ChannelSet") -> np.ndarray:
        """A solver vector ``x`` of this set ([up, down, height slider, build]) as one of ``other``, a
        superset: the channels this set lacks at zero."""
        out = np.zeros(2 * other.n + 2)
        at = [other.names.index(c) for c in self.names]
        out[at], out[[other.n + i for i in at]], out[-2:] = x[:self.n], x[self.n:2 * self.n], x[-2:]
        return out
