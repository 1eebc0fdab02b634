"""The population model (log-normal, fitted to NHANES 2017-2018, bdims and ANSUR II): conditional means against the bivariate formula,
anchoring, percentiles, warnings and refusals. No body model: milliseconds."""
import numpy as np
import pytest

from vfit_engine.body.population import _R, REFUSE_Z, VARIABLES, WARN_Z, PopulationModel, percentile


def test_conditional_mean_is_the_bivariate_regression():
    """Given stature alone, the mass median follows exp(mu_M + r s_M / s_H (log H - mu_H)), with
    standard error s_M sqrt(1 - r^2)."""
    pop = PopulationModel(1.0)
    h = 1.90
    med, sd = pop.predict({"height": h}, tape=False)  # the Gaussian's own regression (no waist <= hips)
    i, j = VARIABLES.index("height"), VARIABLES.index("mass")
    r = pop.cov[i, j] / (pop.sd[i] * pop.sd[j])
    assert r == pytest.approx(_R["male"][0, 1]) and 0.4 < r < 0.55  # NHANES men: 0.47
    want = np.exp(pop.mu[j] + r * pop.sd[j] / pop.sd[i] * (np.log(h) - pop.mu[i]))
    assert med["mass"] == pytest.approx(want, rel=1e-12)
    assert sd["mass"] == pytest.approx(pop.sd[j] * np.sqrt(1 - r ** 2), rel=1e-12)
    assert set(med) == set(VARIABLES) - {"height"}
    assert pop.predict({k: 1.0 for k in VARIABLES}) == ({}, {})


def test_medians_and_girths_grow_with_mass():
    pop = PopulationModel(0.0)
    med, _ = pop.predict({}, tape=False)  # NHANES's own medians
    assert med["height"] == pytest.approx(1.595) and med["mass"] == pytest.approx(74.4)  # NHANES women 20+
    light, _ = pop.predict({"height": 1.65, "mass": 55.0})
    heavy, _ = pop.predict({"height": 1.65, "mass": 95.0})
    for k in ("bust", "waist", "hips", "neck", "upper-arm", "thigh", "calf"):
        assert heavy[k] > light[k] * 1.05, k


def test_anchored_model_makes_the_anchor_body_typical():
    """After anchoring, the anchor body's girths are the conditional medians given its height and mass."""
    body = {"height": 1.59, "mass": 47.2, "bust": 0.841, "waist": 0.652, "hips": 0.947, "neck": 0.286,
            "upper-arm": 0.229, "thigh": 0.509, "calf": 0.353}
    pop = PopulationModel(0.0).anchored(body)
    med, _ = pop.predict({"height": body["height"], "mass": body["mass"]})
    for k in VARIABLES[2:]:
        assert med[k] == pytest.approx(body[k], rel=1e-12), k


def test_percentiles_warnings_and_refusals():
    pop = PopulationModel(0.0)
    assert percentile(0.0) == pytest.approx(50.0) and percentile(WARN_Z) == pytest.approx(99.0, abs=0.01)
    typical = pop.assess({"height": 1.63, "mass": 68.0})
    assert typical.warnings() == [] and typical.refusals() == []
    # NHANES women: 110 kg at 1.60 m is at percentile 93 (no warning); 150 kg is beyond the 99th
    assert pop.assess({"height": 1.60, "mass": 110.0}).warnings() == []
    heavy = pop.assess({"height": 1.60, "mass": 150.0})
    assert heavy.refusals() == [] and "mass is at percentile 99.60 of adult women" in heavy.warnings()[0]
    waist = pop.quantile("waist", -REFUSE_Z - 0.1)
    refused = pop.assess({"waist": waist}).refusals()
    assert len(refused) == 1 and "5.1 standard deviations below the mean of adult women" in refused[0]
    # a common waist with hips far too large for it: warned given the others, not refused
    # (+2.5 SD: waist and hips correlate 0.93 in the fitted model, so +3 SD with a median waist is refused)
    odd = pop.assess({"waist": pop.quantile("waist", 0.0), "hips": pop.quantile("hips", 2.5)})
    assert odd.refusals() == [] and "with the other measurements given" in " ".join(odd.warnings())


def _ansur_sample(sex):
    """The ANSUR II sample of ``sex`` as ``scripts/fit_population.py`` keeps it (the same row checks)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "scripts" / "fit_population.py"
    spec = importlib.util.spec_from_file_location("fit_population", path)
    fit = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fit)
    rows, _ = fit.load_ansur(fit.ANSUR[sex], sex)
    return rows


def test_womens_neck_is_the_womens_regression():
    """The women's neck follows ANSUR II women (it once borrowed the men's regression, which put a woman of
    the sample's mean stature and mass at a 37.3 cm neck against their 33.1): at the sample's (geometric) mean
    stature and mass the model gives the sample's mean neck within 1 cm, and a woman of 165 cm / 65 kg gets a
    neck within one SD of the sample's mean (ANSUR II women: mean 33 cm, SD about 2 cm), well below the men's
    model at the same stature and mass."""
    women = _ansur_sample("female")
    neck = women["neckcircumference"] / 1000.0  # mm -> m
    assert len(neck) == 115 and 0.325 < neck.mean() < 0.337 and 0.015 < neck.std(ddof=1) < 0.025
    height = float(np.exp(np.log(women["stature"] / 1000.0).mean()))
    mass = float(np.exp(np.log(women["weightkg"]).mean()))
    med, _ = PopulationModel(0.0).predict({"height": height, "mass": mass})
    assert abs(med["neck"] - neck.mean()) < 0.01
    med, sd = PopulationModel(0.0).predict({"height": 1.65, "mass": 65.0})
    assert abs(med["neck"] - neck.mean()) < neck.std(ddof=1)
    assert 0.03 < sd["neck"] < 0.045  # the women's residual SD (0.038) plus the waist's part
    men, _ = PopulationModel(1.0).predict({"height": 1.65, "mass": 65.0})
    assert men["neck"] - med["neck"] > 0.03


def test_estimates_keep_the_waist_below_the_hips():
    """The tape's waist is never above its hips, but the men's fitted log-normal predicts one past ~140 kg (waist
    140.4 against hips 132.4 cm at the mass's 99th percentile): with ``tape`` the unknowns are the Gaussian's
    truncated to log waist <= log hips. Their mean against 400,000 samples of the conditional Gaussian with the
    others dropped (within 3 standard errors of the sample mean); the waist below the hips from 40 to 180 kg and
    with either one given; a typical body's estimates barely moved (a woman's waist is far below her hips: under
    1e-8; a 60 kg man's hips are ~1.2 times his waist, the truncation's tail moves them by 0.04 %)."""
    pop = PopulationModel(1.0)
    given = {"height": 1.84, "mass": 148.0}
    plain, _ = pop.predict(given, tape=False)
    assert plain["waist"] > plain["hips"]  # the case: the survey's model alone measures no tape's body
    med, _ = pop.predict(given)
    names = [k for k in VARIABLES if k not in given]
    ig, io = [VARIABLES.index(k) for k in given], [VARIABLES.index(k) for k in names]
    b = np.linalg.solve(pop.cov[np.ix_(ig, ig)], pop.cov[np.ix_(ig, io)])
    mean = pop.mu[io] + (np.log(list(given.values())) - pop.mu[ig]) @ b
    cov = pop.cov[np.ix_(io, io)] - pop.cov[np.ix_(io, ig)] @ b
    y = np.random.default_rng(3).multivariate_normal(mean, cov, 400_000)
    kept = y[y[:, names.index("waist")] <= y[:, names.index("hips")]]
    for k in names:
        col = kept[:, names.index(k)]
        assert abs(np.log(med[k]) - col.mean()) < 3 * col.std() / np.sqrt(len(col)) + 1e-9, k
    for sex in (0.0, 1.0):
        pop = PopulationModel(sex)
        for mass in np.linspace(40.0, 180.0, 15):
            med, _ = pop.predict({"height": 1.75, "mass": mass})
            assert med["waist"] < med["hips"], (sex, mass)
        for name, other in (("waist", "hips"), ("hips", "waist")):
            value = pop.quantile(name, 2.33)
            med, _ = pop.predict({name: value})
            assert (value < med[other]) if name == "waist" else (med[other] < value), (sex, name)
    typical = {"height": 1.65, "mass": 60.0}
    for sex, within in ((0.0, 1e-8), (1.0, 5e-4)):
        a, _ = PopulationModel(sex).predict(typical)
        b, _ = PopulationModel(sex).predict(typical, tape=False)
        assert all(abs(a[k] / b[k] - 1) < within for k in a), sex
