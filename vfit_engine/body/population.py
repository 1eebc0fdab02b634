"""How adult bodies vary together: a log-normal model of stature, mass and girths from a survey.

Source: ANSUR II, the 2012 Anthropometric Survey of U.S. Army Personnel (Gordon C. C. et al.,
"2012 Anthropometric Survey of U.S. Army Personnel: Methods and Summary Statistics", NATICK/TR-15/007,
U.S. Army Natick Soldier RD&E Center, 2014; public data 4,082 men and 1,986 women aged 17-58). It is the
public survey that measured stature, mass and all of chest (bust), waist, buttock (hips), neck, upper arm
(biceps), thigh and calf circumference on the same people, which a joint model needs (NHANES 2015-2018 has
no chest, neck, thigh or calf; SizeUSA and CAESAR are not public). Its people are soldiers: the heaviest
civilians (NHANES 2015-2018 mean mass 90.6 kg men / 77.5 kg women, above ANSUR II's 85.5 / 67.8 kg) lie
further out in this model than in their own population, so its percentiles are conservative at the heavy
end.

The figures below are the survey's summary statistics as the author of this module recalls them from the
report and the public data (means to about 0.5 cm / 1 kg; correlations rounded to 0.05). They were NOT
re-checked against the report while writing this module (no access to it then): re-fit ``_SURVEY`` from the
public data before relying on the third digit.

Model. ``y = log(x)`` for x = (stature, mass, chest, waist, hips, neck, upper arm, thigh, calf) is normal
with mean ``log(median)`` and covariance ``D R D`` (``D`` the standard deviations of the logs, about the
coefficients of variation; ``R`` the correlations). What a user does not give is its conditional mean given
what they give (the regression), with the conditional standard deviation as the regression's standard error;
a given value's percentile is taken marginally and given the other values (a waist of 60 cm is common, with
hips of 130 cm it is not).

Definitions differ: the survey's waist is at the navel (omphalion), vfit's is the narrowest; its arm girth
is the flexed biceps, vfit's the MakeHuman ruler. So the survey supplies how each girth changes (in log, i.e.
relative terms) with stature, mass and the other girths, and its spread; the level is set by
:meth:`PopulationModel.anchored`, which makes MakeHuman's average body of the gender (measured with the
definition in use) the typical body of its own stature and mass. Stature and mass are absolute.

The underbust is not in the survey: it follows the bust at the anchor body's ratio.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import erf, sqrt

import numpy as np

#: the model's variables: measurement names of ``measure.NAMES`` plus ``mass`` (kg); lengths in m
VARIABLES = ("height", "mass", "bust", "waist", "hips", "neck", "upper-arm", "thigh", "calf")
SOURCE = "ANSUR II 2012"
CITATION = ("ANSUR II: Gordon C. C. et al., 2012 Anthropometric Survey of U.S. Army Personnel: Methods and "
            "Summary Statistics, NATICK/TR-15/007, 2014")

# name: (median, sd of log) per sex; lengths in cm, mass in kg (converted below)
_SURVEY = {
    "male": {
        "height": (175.6, 0.039), "mass": (85.5, 0.165), "bust": (105.9, 0.073), "waist": (94.1, 0.115),
        "hips": (102.2, 0.073), "neck": (39.8, 0.062), "upper-arm": (35.8, 0.085), "thigh": (62.6, 0.085),
        "calf": (39.3, 0.068),
    },
    "female": {
        "height": (162.9, 0.039), "mass": (67.8, 0.160), "bust": (95.0, 0.083), "waist": (86.0, 0.110),
        "hips": (102.0, 0.075), "neck": (33.1, 0.055), "upper-arm": (30.0, 0.100), "thigh": (62.3, 0.088),
        "calf": (37.0, 0.072),
    },
}
# correlations of the logs, in VARIABLES order (the same structure for both sexes but stature-mass,
# which is 0.50 for men and 0.45 for women)
_R = np.array([
    [1.00, 0.50, 0.25, 0.25, 0.40, 0.35, 0.20, 0.25, 0.35],
    [0.50, 1.00, 0.88, 0.85, 0.90, 0.80, 0.83, 0.85, 0.78],
    [0.25, 0.88, 1.00, 0.83, 0.78, 0.78, 0.80, 0.72, 0.68],
    [0.25, 0.85, 0.83, 1.00, 0.82, 0.73, 0.70, 0.70, 0.63],
    [0.40, 0.90, 0.78, 0.82, 1.00, 0.70, 0.72, 0.85, 0.75],
    [0.35, 0.80, 0.78, 0.73, 0.70, 1.00, 0.70, 0.65, 0.63],
    [0.20, 0.83, 0.80, 0.70, 0.72, 0.70, 1.00, 0.73, 0.65],
    [0.25, 0.85, 0.72, 0.70, 0.85, 0.65, 0.73, 1.00, 0.75],
    [0.35, 0.78, 0.68, 0.63, 0.75, 0.63, 0.65, 0.75, 1.00],
])
#: |z| beyond which a value is refused: about 1 in 3.5 million adults lies further out
REFUSE_Z = 5.0
#: the same, for a value given the other given values (a 55 cm waist with 130 cm hips: -9.4). Wider than
#: REFUSE_Z because the conditional spread rests on rounded correlations and on the definitions' differing
#: landmarks: an apple-shaped woman's waist 90 cm with hips 95 cm scores 4.5 here though common
REFUSE_Z_GIVEN = 8.0
#: |z| beyond which a value builds with a warning: outside the 1st-99th percentile
WARN_Z = 2.326


def _unit(name):
    return 1.0 if name == "mass" else 0.01  # cm -> m


def percentile(z: float) -> float:
    """Percentile (0-100) of a standard normal score."""
    return 50.0 * (1.0 + erf(z / sqrt(2.0)))


@dataclass
class Assessment:
    """How usual the given values are: per value its z score marginally and given the others."""

    marginal_z: dict
    conditional_z: dict
    who: str = "adults"

    def warnings(self) -> list[str]:
        """One line per given value outside the 1st-99th percentile (marginal or given the others)."""
        out = []
        for k, z in self.marginal_z.items():
            zc = self.conditional_z.get(k, 0.0)
            if abs(z) > WARN_Z:
                out.append(f"{_label(k)} is at {_pct_text(z)} of {self.who} ({SOURCE})")
            elif abs(zc) > WARN_Z:
                out.append(f"{_label(k)} is at {_pct_text(zc)} of {self.who} with the other measurements "
                           f"given ({SOURCE})")
        return out

    def refusals(self) -> list[str]:
        """One line per given value no adult body has: beyond REFUSE_Z alone or REFUSE_Z_GIVEN given the
        other values."""
        out = []
        for k, z in self.marginal_z.items():
            zc = self.conditional_z.get(k, 0.0)
            if abs(z) > REFUSE_Z:
                out.append(f"{_label(k)} is {abs(z):.1f} standard deviations {'below' if z < 0 else 'above'} "
                           f"the mean of {self.who} ({SOURCE}; {_pct_text(z)}), where no adult body is")
            elif abs(zc) > REFUSE_Z_GIVEN:
                out.append(f"{_label(k)} is {abs(zc):.1f} standard deviations {'below' if zc < 0 else 'above'} "
                           f"what {self.who} with the other measurements given have ({SOURCE}), where no "
                           f"adult body is")
        return out


def _label(k):
    return "mass" if k == "mass" else k


def _pct_text(z):
    """'percentile 0.52' (two decimals outside 1-99, else whole numbers; '<0.01' / '>99.99' beyond)."""
    p = percentile(z)
    if p < 0.01:
        return "percentile <0.01"
    if p > 99.99:
        return "percentile >99.99"
    return f"percentile {p:.2f}" if (p < 1 or p > 99) else f"percentile {p:.0f}"


class PopulationModel:
    """The survey's joint distribution of ``VARIABLES`` for a gender (0 female ... 1 male, blends mixed).

    Values are in metres (lengths) and kg (mass).
    """

    def __init__(self, gender: float = 0.0):
        g = float(gender)
        mu, sd = np.zeros(len(VARIABLES)), np.zeros(len(VARIABLES))
        for i, k in enumerate(VARIABLES):
            (mf, sf), (mm, sm) = _SURVEY["female"][k], _SURVEY["male"][k]
            mu[i] = (1 - g) * np.log(mf * _unit(k)) + g * np.log(mm * _unit(k))
            sd[i] = (1 - g) * sf + g * sm
        r = _R.copy()
        r[0, 1] = r[1, 0] = (1 - g) * 0.45 + g * 0.50
        self.mu, self.sd = mu, sd
        self.cov = r * np.outer(sd, sd)
        self.who = "adult women" if g == 0.0 else "adult men" if g == 1.0 else "adults of this gender blend"

    def _index(self, names):
        return [VARIABLES.index(k) for k in names]

    def anchored(self, values: dict) -> "PopulationModel":
        """A copy whose girth levels make ``values`` (a body's height, mass and girths) the typical body of
        its own height and mass: each girth's mean is moved so that its conditional mean given that
        height and mass equals the body's value."""
        out = PopulationModel.__new__(PopulationModel)
        out.mu, out.sd, out.cov, out.who = self.mu.copy(), self.sd, self.cov, self.who
        hm = self._index(("height", "mass"))
        y_hm = np.log([values["height"], values["mass"]])
        for k in VARIABLES[2:]:
            i = VARIABLES.index(k)
            beta = np.linalg.solve(self.cov[np.ix_(hm, hm)], self.cov[hm, i])
            out.mu[i] = np.log(values[k]) - beta @ (y_hm - self.mu[hm])
        return out

    def predict(self, given: dict) -> tuple[dict, dict]:
        """Conditional median and log standard deviation of every variable not in ``given``.

        Returns (median dict name -> value, sd dict name -> standard deviation of the log, i.e. the
        regression's relative standard error).
        """
        g = [k for k in VARIABLES if k in given]
        o = [k for k in VARIABLES if k not in given]
        if not o:
            return {}, {}
        ig, io = self._index(g), self._index(o)
        if not g:
            return ({k: float(np.exp(self.mu[i])) for k, i in zip(o, io)},
                    {k: float(self.sd[i]) for k, i in zip(o, io)})
        y = np.log([given[k] for k in g])
        S_gg = self.cov[np.ix_(ig, ig)]
        B = np.linalg.solve(S_gg, self.cov[np.ix_(ig, io)])  # (g, o)
        mean = self.mu[io] + (y - self.mu[ig]) @ B
        var = np.diag(self.cov[np.ix_(io, io)] - self.cov[np.ix_(io, ig)] @ B)
        return ({k: float(np.exp(m)) for k, m in zip(o, mean)},
                {k: float(np.sqrt(max(v, 0.0))) for k, v in zip(o, var)})

    def assess(self, given: dict) -> Assessment:
        """z scores of the given values: marginal, and each given the other given values."""
        names = [k for k in VARIABLES if k in given]
        marg, cond = {}, {}
        for k in names:
            i = VARIABLES.index(k)
            marg[k] = float((np.log(given[k]) - self.mu[i]) / self.sd[i])
            others = {j: given[j] for j in names if j != k}
            if others:
                med, sd = self.predict(others)
                cond[k] = float(np.log(given[k] / med[k]) / sd[k])
        return Assessment(marg, cond, self.who)

    def quantile(self, name: str, z: float, given: dict | None = None) -> float:
        """The value of ``name`` at standard score ``z``, marginally or given ``given``."""
        if given:
            med, sd = self.predict(given)
            return med[name] * float(np.exp(z * sd[name]))
        i = VARIABLES.index(name)
        return float(np.exp(self.mu[i] + z * self.sd[i]))
