"""Shape factors: exact recovery on synthetic linear bodies, accuracy on hm08 examples, bad input."""
import numpy as np
import pytest

from vfit_engine.errors import InputError
from vfit_engine.body.shape_factors import ShapeFactors

NAMES = ("bust", "waist", "hips")


def _linear_bodies(rng, m, n=50, k=3):
    """Bodies exactly ``v0 + sum_k g_k r_k`` for random features ``g`` (m, k)."""
    v0 = rng.normal(size=(n, 3))
    r = rng.normal(size=(k, n, 3))
    g = rng.uniform(0.6, 1.2, size=(m, k))
    return v0 + np.einsum("mk,knc->mnc", g, r), g, v0, r


# ------------------------------------------------------------------ synthetic, exact
def test_exact_on_linear_bodies():
    rng = np.random.default_rng(0)
    verts, g, v0, r = _linear_bodies(rng, 16)
    sf = ShapeFactors.fit(verts[:12], g[:12], NAMES)
    assert sf.features == NAMES and sf.r.shape == (3, 50, 3) and sf.residual_rms.shape == (50,)
    np.testing.assert_allclose(sf.r, r, rtol=0, atol=1e-10)
    assert sf.residual_rms.max() < 1e-12
    np.testing.assert_allclose(sf.g_ref, g[:12].mean(axis=0), rtol=0, atol=1e-15)
    for v, gj in zip(verts[12:], g[12:]):  # held-out bodies, by array and by dict in another order
        np.testing.assert_allclose(sf.shape(gj), v, rtol=0, atol=1e-10)
        np.testing.assert_allclose(sf.shape(dict(reversed(list(zip(NAMES, gj))))), v, rtol=0, atol=1e-10)


def test_one_feature_slope_is_covariance_over_variance():
    rng = np.random.default_rng(1)
    verts = rng.normal(size=(9, 20, 3))
    g = rng.uniform(0.5, 1.0, size=(9, 1))
    sf = ShapeFactors.fit(verts, g, ("waist",))
    gc = g[:, 0] - g[:, 0].mean()
    slope = np.einsum("m,mnc->nc", gc, verts - verts.mean(axis=0)) / (gc @ gc)
    np.testing.assert_allclose(sf.r[0], slope, rtol=0, atol=1e-12)
    fit = verts.mean(axis=0) + gc[:, None, None] * slope
    rms = np.sqrt(((verts - fit) ** 2).sum(axis=2).mean(axis=0))
    np.testing.assert_allclose(sf.residual_rms, rms, rtol=1e-12, atol=0)
    assert rms.min() > 0.1  # random bodies are far from linear: the residual must show it


def test_reference_body_is_reproduced_and_moved_by_the_factors():
    rng = np.random.default_rng(2)
    verts, g, _, r = _linear_bodies(rng, 8)
    v_ref = rng.normal(size=(50, 3))
    g_ref = {"bust": 0.9, "waist": 0.7, "hips": 1.0}
    sf = ShapeFactors.fit(verts, g, NAMES, reference=(v_ref, g_ref))
    np.testing.assert_array_equal(sf.shape(g_ref), v_ref)
    moved = sf.shape({"bust": 0.95, "waist": 0.7, "hips": 1.0})
    np.testing.assert_allclose(moved - v_ref, 0.05 * r[0], rtol=0, atol=1e-10)


# ------------------------------------------------------------------ bad input
def test_bad_input_raises_input_error():
    rng = np.random.default_rng(3)
    verts, g, _, _ = _linear_bodies(rng, 6)
    with pytest.raises(InputError, match="more examples than features"):
        ShapeFactors.fit(verts[:3], g[:3], NAMES)
    bad = verts.copy()
    bad[2, 7, 1] = np.nan
    with pytest.raises(InputError, match="NaN"):
        ShapeFactors.fit(bad, g, NAMES)
    bad = g.copy()
    bad[0, 0] = np.inf
    with pytest.raises(InputError, match="NaN"):
        ShapeFactors.fit(verts, bad, NAMES)
    with pytest.raises(InputError, match="shape"):
        ShapeFactors.fit(verts[:, :, :2], g, NAMES)
    with pytest.raises(InputError, match="features must have shape"):
        ShapeFactors.fit(verts, g[:5], NAMES)
    with pytest.raises(InputError, match="names"):
        ShapeFactors.fit(verts, g, ("bust", "waist"))
    collinear = g.copy()
    collinear[:, 2] = 2.0 * collinear[:, 0]
    with pytest.raises(InputError, match="collinear"):
        ShapeFactors.fit(verts, collinear, NAMES)
    sf = ShapeFactors.fit(verts, g, NAMES)
    with pytest.raises(InputError, match="missing"):
        sf.shape({"bust": 0.9, "waist": 0.7})
    with pytest.raises(InputError, match="3 values"):
        sf.shape([0.9, 0.7])
    with pytest.raises(InputError, match="NaN"):
        sf.shape([0.9, np.nan, 1.0])


# ------------------------------------------------------------------ hm08 examples vs the morph solver
@pytest.fixture(scope="module")
def hm08():
    from vfit_engine.body.measure import Measurer
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.morph import Morpher

    model = BodyModel.load()  # a broken loader fails here, not as a skip
    measurer = Measurer(model)
    return model, measurer, Morpher(model, measurer)


def _rms_mm(a, b):
    return float(np.sqrt(((a - b) ** 2).sum(axis=1).mean()) * 1e3)


def test_model_examples_against_the_solver(hm08):
    from vfit_engine.body.model import N_BODY
    from vfit_engine.body.shape_factors import examples_from_model

    model, measurer, morpher = hm08
    verts, g = examples_from_model(model, measurer, 32, np.random.default_rng(1), NAMES)
    assert verts.shape == (32, N_BODY, 3) and g.shape == (32, 3)
    # held-out bodies inside the examples' range: their girths are the targets, their verts the truth
    held_v, held_g = examples_from_model(model, measurer, 6, np.random.default_rng(2), NAMES, amplitude=0.8)
    sf = ShapeFactors.fit(verts, g, NAMES)
    res_mm = sf.residual_rms * 1e3
    print(f"\nfit residual RMS per vertex: mean {res_mm.mean():.2f} mm, max {res_mm.max():.2f} mm")
    assert 0.5 < res_mm.max() < 6.0 and res_mm.mean() < 0.5  # channel kinks at 0: not exactly linear

    sf_err, sol_err, ref_err, rows = [], [], [], []
    for truth, gj in zip(held_v, held_g):
        targets = dict(zip(NAMES, gj))
        body = sf.shape(targets)
        got = measurer.measure(body, names=NAMES, mass=False).values
        sf_err.append([(got[x] - targets[x]) * 1e3 for x in NAMES])
        solved = morpher.solve(targets)
        sol_err.append([(solved.measurement.values[x] - targets[x]) * 1e3 for x in NAMES])
        refined, meas = sf.shape_measured(targets, measurer)
        ref_err.append([(meas[x] - targets[x]) * 1e3 for x in NAMES])
        v_sol = solved.verts[:N_BODY]
        rows.append((_rms_mm(body, v_sol), _rms_mm(body, truth), _rms_mm(v_sol, truth), _rms_mm(refined, truth)))
    sf_err, sol_err, ref_err, rows = map(np.abs, map(np.array, (sf_err, sol_err, ref_err, rows)))
    print("girth |error| mm (bust, waist, hips), max over 6 held-out bodies:")
    print(f"  shape factors {np.round(sf_err.max(axis=0), 2)}, refined {np.round(ref_err.max(axis=0), 3)}, "
          f"solver {np.round(sol_err.max(axis=0), 3)}")
    print("vertex RMS mm, max: sf-solver {:.2f}, sf-truth {:.2f}, solver-truth {:.2f}, refined-truth {:.2f}"
          .format(*rows.max(axis=0)))
    assert sol_err.max() < 0.2
    # bust and hips are nearly linear in the vertices; the waist is a minimum over planes whose
    # plane jumps between two hollows (~0.20 m and ~0.275 m), so it is off by up to ~12 mm here
    assert sf_err[:, [0, 2]].max() < 2.0
    assert sf_err[:, 1].max() < 15.0
    assert ref_err.max() < 0.2
    # the shape-factor body is nearer the true example than the solver's body is
    assert rows[:, 1].max() < 1.5 and rows[:, 3].max() < 1.5
    assert rows[:, 0].max() < 10.0
    # on average: the solver's body has its other girths and mass from the survey (issue 11) where the
    # examples keep them at the average body's, so on one of the six it now comes a little nearer
    assert rows[:, 1].mean() < 0.5 * rows[:, 2].mean()
