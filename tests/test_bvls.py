"""The morph's warm-started bounded least squares against SciPy's ``lsq_linear(method='bvls')`` on
seeded random problems shaped like the morph's (a Jacobian over a regularisation diagonal, a box)."""
import numpy as np
from scipy.optimize import lsq_linear

from vfit_engine.body.bvls import bvls


def _problem(rng, m=10, n=26):
    J = rng.normal(size=(m, n)) * rng.uniform(1.0, 500.0, size=(1, n))
    A = np.vstack([J, np.diag(np.full(n, 1e-3))])
    b = np.concatenate([rng.normal(scale=50.0, size=m), np.zeros(n)])
    x = rng.uniform(0.0, 1.0, n) * (rng.uniform(size=n) < 0.5)
    delta = rng.choice([0.01, 0.1, 1.0])
    return A, b, np.maximum(-x, -delta), np.minimum(1.0 - x, delta)


def test_bvls_matches_scipy_cold_and_warm():
    rng = np.random.default_rng(7)
    active = None
    bound = 0
    for k in range(60):
        # more rows than variables: a well-posed minimiser; fewer (as the morph's): only the
        # regularisation fixes it, in directions where the cost is flat to round-off
        m = 40 if k % 2 else 10
        A, b, lb, ub = _problem(rng, m=m)
        ref = lsq_linear(A, b, bounds=(lb, ub), method="bvls", tol=1e-12)
        for start in (None, active):
            x, on = bvls(A, b, lb, ub, on_bound=start, tol=1e-12)
            assert np.all(x >= lb) and np.all(x <= ub)
            cost, cost_ref = np.sum((A @ x - b) ** 2), np.sum((A @ ref.x - b) ** 2)
            assert cost <= cost_ref + 1e-12 * (b @ b)  # optimal to round-off
            np.testing.assert_allclose(A[:m] @ x, A[:m] @ ref.x, atol=1e-6 * np.abs(b).max())
            if m == 40:
                np.testing.assert_allclose(x, ref.x, atol=1e-9)
        active = on  # a warm start from another problem's active set still ends at the optimum
        bound += int(np.count_nonzero(on))
    assert bound > 0
