"""Analytic measurement gradients (used for the morph solver's exact Jacobian) against central
finite differences along seeded random directions."""
import numpy as np
import pytest

from vfit_engine.body.gradients import ruler_gradient, volume_gradient
from vfit_engine.body.measure import enclosed_volume, ruler_length


@pytest.fixture(scope="module")
def body(body_model):
    return body_model.default_verts("female")[:13380].copy()


def _directional(idx, grad, d):
    return float((grad * d[idx]).sum())


@pytest.mark.parametrize("name", ["bust", "underbust", "waist", "hips"])
def test_tape_girth_gradient_moves_with_its_band(measurer, body, name):
    """d girth along a direction, the plane held at its fraction of the (moving) band."""
    rng = np.random.default_rng(7)
    base = measurer.measure(body, "iso")
    frac = {name: base.fractions[name]}
    d = rng.normal(size=body.shape) * 1e-3
    idx, grad = measurer.gradient(body, name, "iso", frac[name])
    eps = 1e-3
    plus = measurer.measure(body + eps * d, "iso", planes=frac, names=(name,)).values[name]
    minus = measurer.measure(body - eps * d, "iso", planes=frac, names=(name,)).values[name]
    fd = (plus - minus) / (2 * eps)
    assert _directional(idx, grad, d) == pytest.approx(fd, rel=1e-4, abs=1e-9)


def test_ruler_and_volume_gradients(body_model, body):
    rng = np.random.default_rng(8)
    d = rng.normal(size=body.shape) * 1e-3
    eps = 1e-3
    r = body_model.rulers["waist-circ"]["vertex_indices"]
    idx, grad = ruler_gradient(body, r)
    fd = (ruler_length(body + eps * d, r) - ruler_length(body - eps * d, r)) / (2 * eps)
    assert _directional(idx, grad, d) == pytest.approx(fd, rel=1e-6)
    tris = body_model.body_tris
    idx, grad = volume_gradient(body, tris)
    fd = (enclosed_volume(body + eps * d, tris) - enclosed_volume(body - eps * d, tris)) / (2 * eps)
    assert _directional(idx, grad, d) == pytest.approx(fd, rel=1e-6)


def test_hull_gradient_of_a_circle(measurer):
    """Analytic case: scaling every vertex of a body about the plane's centre line by (1 + s)
    scales a horizontal girth by (1 + s), so the directional derivative equals the girth."""
    from vfit_engine.body.gradients import girth_gradient

    verts = measurer.model.default_verts("female")[:13380].copy()
    y = 0.21
    g0 = measurer.torso_girth(verts, y)
    d = np.zeros_like(verts)
    d[:, [0, 2]] = verts[:, [0, 2]]  # radial in x, z about the y axis (x = z = 0)
    idx, grad = girth_gradient(measurer.sections, verts, y)
    assert _directional(idx, grad, d) == pytest.approx(g0, rel=1e-9)
