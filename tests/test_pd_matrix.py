"""The projective-dynamics matrix re-weighed by acting bands (:mod:`vfit_engine.kernels.pd_matrix`) against a
NumPy assembly of the same matrix, on seeded data."""
import numpy as np
import pytest
from scipy import sparse

from vfit_engine.kernels.pd_matrix import acting_bands, add_damping_target, band_matrix


def _case(seed, n=40, pairs=120):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3)) * 0.05
    pi = rng.integers(0, n, pairs)
    pj = (pi + 1 + rng.integers(0, n - 1, pairs)) % n  # never i == j
    length = np.linalg.norm(x[pj] - x[pi], axis=1)
    # a third of the bands around their pair's length (free), a third stretched past their end, a third squeezed
    scale = rng.choice([1.0, 0.8, 1.3], pairs)
    lo, hi = 0.9 * length * scale, 1.1 * length * scale
    band = rng.random(pairs) < 0.8
    w = rng.uniform(1.0, 50.0, pairs)
    free = rng.random(n) < 0.85
    base = rng.uniform(0.1, 2.0, n)
    w_c = np.where(free, 0.3, 0.0)
    return x, pi, pj, lo, hi, band, w, free, base, w_c


def _reference(x, pi, pj, lo, hi, band, w, share, free, base, w_c, dw):
    length = np.linalg.norm(x[pj] - x[pi], axis=1)
    active = ~band | (length <= lo * 1.002) | (length >= hi * 0.998)
    we = np.where(active, w, share * w)
    wm = we + dw
    n = x.shape[0]
    diag = np.where(free, base + np.bincount(pi, wm, n) + np.bincount(pj, wm, n) + w_c, 1.0)
    both = free[pi] & free[pj]
    a = sparse.coo_matrix((np.concatenate([-wm[both], -wm[both], diag]),
                           (np.concatenate([pi[both], pj[both], np.arange(n)]),
                            np.concatenate([pj[both], pi[both], np.arange(n)]))), shape=(n, n)).toarray()
    return active, we, a


@pytest.mark.parametrize("seed, damping", [(0, 0.0), (1, 0.0), (2, 0.0), (3, 0.4), (4, 1.2)])
def test_reweighed_matrix_matches_the_numpy_assembly(seed, damping):
    x, pi, pj, lo, hi, band, w, free, base, w_c = _case(seed)
    n, share = x.shape[0], 0.3
    dw = damping * w * (np.random.default_rng(seed).random(pi.size) < 0.9)  # some pairs undamped (seams)
    want_active, want_w, want_a = _reference(x, pi, pj, lo, hi, band, w, share, free, base, w_c, dw)
    # the factor's value array: here the dense matrix's entries in row-major order
    at_ij = np.where(free[pi] & free[pj], pi * n + pj, -1)
    at_ji = np.where(free[pi] & free[pj], pj * n + pi, -1)
    at_d = np.arange(n) * (n + 1)
    data = np.full(n * n, np.nan)
    active = np.ones(pi.size, dtype=np.bool_)
    pair_of = np.array([3, 7, 11], dtype=np.int64)
    e_w, pin_w = np.zeros(50), np.zeros(3)
    changed = acting_bands(x, pi, pj, lo, hi, band, active)
    assert changed == (not want_active.all())
    np.testing.assert_array_equal(active, want_active)
    assert 0 < np.count_nonzero(band & ~active) < np.count_nonzero(band)  # both kinds are in the case
    band_matrix(pi, pj, w, active, share, free, base, w_c, at_ij, at_ji, at_d, data, e_w, pin_w, pair_of, dw)
    np.testing.assert_allclose(data.reshape(n, n), want_a, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(e_w, want_w[:50], rtol=1e-15)  # the local step's weights carry no damping
    np.testing.assert_allclose(pin_w, want_w[pair_of] + dw[pair_of], rtol=1e-15)
    assert not acting_bands(x, pi, pj, lo, hi, band, active)  # the same iterate: no change, nothing to refactor


@pytest.mark.parametrize("seed", [0, 1])
def test_damping_target_matches_numpy(seed):
    """``y + M^-1 h^2 K_d x_n``: with ``dw`` on the matrix, the solve's damping force is ``-K_d (x - x_n)``."""
    x, pi, pj, _, _, _, w, free, _, _ = _case(seed)
    rng = np.random.default_rng(seed)
    n = x.shape[0]
    xp = x + rng.normal(size=x.shape) * 0.01
    dw = 0.5 * w * (rng.random(pi.size) < 0.9)
    mh2 = np.where(free, rng.uniform(1.0, 5.0, n), 0.0)
    y = rng.normal(size=x.shape)
    want = y.copy()
    for c in range(3):
        f = dw * (xp[pi, c] - xp[pj, c])
        r = np.bincount(pi, f, n) - np.bincount(pj, f, n)
        want[free, c] += r[free] / mh2[free]
    add_damping_target(y, xp, pi, pj, dw, mh2)
    np.testing.assert_allclose(y, want, rtol=1e-12, atol=1e-14)
