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
    """d girth along a direction, the plane held at its fraction of the (moving) band; the bust's
    plane follows the bust points (no band)."""
    rng = np.random.default_rng(7)
    base = measurer.measure(body, "iso")
    frac = {name: base.fractions[name]} if name in base.fractions else None
    d = rng.normal(size=body.shape) * 1e-3
    idx, grad = measurer.gradient(body, name, "iso", frac and frac[name])
    eps = 1e-3
    plus = measurer.measure(body + eps * d, "iso", planes=frac, names=(name,)).values[name]
    minus = measurer.measure(body - eps * d, "iso", planes=frac, names=(name,)).values[name]
    fd = (plus - minus) / (2 * eps)
    assert _directional(idx, grad, d) == pytest.approx(fd, rel=1e-4, abs=1e-9)


def test_mans_chest_gradient_follows_the_bust_points(measurer, body_model):
    """A man's chest (under the armpits: a whole number of millimetres above his bust points): d girth along
    seeded random directions, the plane following the bust points, against central differences."""
    male = body_model.default_verts("male")[:13380].copy()
    base = measurer.measure(male, "iso", gender="male")
    frac = {"bust": base.fractions["bust"]}
    idx, grad = measurer.gradient(male, "bust", "iso", frac["bust"], gender="male")
    rng = np.random.default_rng(12)
    for _ in range(2):
        d = rng.normal(size=male.shape) * 1e-3
        eps = 1e-3
        plus, minus = (measurer.measure(male + s * eps * d, "iso", planes=frac, names=("bust",), gender="male")
                       for s in (1, -1))
        assert plus.planes["bust"] != minus.planes["bust"]  # the plane moved with the body
        fd = (plus.values["bust"] - minus.values["bust"]) / (2 * eps)
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


def test_volume_and_blend_kernels_against_numpy(body_model, body):
    """The Numba kernels the morph solver runs against their NumPy references on seeded random data."""
    from vfit_engine.kernels.blend import blend, project
    from vfit_engine.kernels.volume import enclosed_volume as volume_kernel
    from vfit_engine.kernels.volume import volume_gradient as volume_gradient_kernel

    rng = np.random.default_rng(9)
    tris = body_model.body_tris
    v = np.ascontiguousarray(body + rng.normal(size=body.shape) * 1e-3)
    assert volume_kernel(v, tris) == pytest.approx(enclosed_volume(v, tris), rel=1e-12)
    g = np.empty_like(v)
    volume_gradient_kernel(v, tris, g)
    idx, ref = volume_gradient(v, tris)
    assert np.allclose(g[idx], ref, rtol=0, atol=1e-15) and not np.delete(g, idx, axis=0).any()
    targets = rng.normal(size=(5, 300))
    w = rng.normal(size=5)
    w[2] = 0.0
    base = rng.normal(size=300)
    out = np.empty(300)
    blend(base, targets, w, out)
    assert np.allclose(out, base + w @ targets, rtol=0, atol=1e-13)
    col = np.empty(5)
    project(targets, base, col)
    assert np.allclose(col, targets @ base, rtol=0, atol=1e-12)


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


def _rows(idx, grad):
    return sorted(zip(idx.tolist(), map(tuple, grad.tolist())))


@pytest.mark.parametrize("gender", ["female", "male"])
def test_girth_gradient_kernel_matches_reference(measurer, gender):
    """The Numba kernel against the NumPy/SciPy reference, on seeded jittered bodies and planes over the
    torso (bust points to hips): the same rows, bit for bit (the order is a rotation: the hulls start at
    different points). Planes through the legs (no loop across x = 0) take the reference itself."""
    from vfit_engine.body.gradients import girth_gradient, girth_gradient_dy, girth_gradient_reference

    rng = np.random.default_rng(11)
    base = measurer.model.default_verts(gender)[:13380]
    for trial in range(3):
        verts = base + rng.normal(0.0, 2e-4, base.shape) * (trial > 0)
        bands = measurer.measure(verts, names=("bust", "hips"), mass=False).planes
        for y in np.concatenate([rng.uniform(bands["hips"] - 0.05, bands["bust"] + 0.05, 6),
                                 [bands["hips"], bands["bust"]]]):
            i1, g1 = girth_gradient_reference(measurer.sections, verts, y)
            i2, g2 = girth_gradient(measurer.sections, verts, y)
            assert len(i2) > 0 and _rows(i1, g1) == _rows(i2, g2)
            # the girths beside the plane from the same call: bit for bit those of the scan kernel
            _, _, g = girth_gradient_dy(measurer.sections, verts, y, 1e-6)
            assert list(g) == list(measurer.sections.girths(verts, np.array([y - 1e-6, y + 1e-6])))
    # a plane through a vertex row (several cut edges give the same point) and one missing the body
    v = base[int(np.argmin(np.abs(base[:, 1] - bands["hips"]))), 1]
    for y in (v, 5.0):
        assert _rows(*girth_gradient_reference(measurer.sections, base, y)) == \
            _rows(*girth_gradient(measurer.sections, base, y))
