"""Bounded-variable least squares with a warm start, for the morph's Gauss-Newton steps.

``min |A x - b|`` over ``lb <= x <= ub`` by Stark & Parker's active-set algorithm (1995), the
one ``scipy.optimize.lsq_linear(method='bvls')`` runs. SciPy starts every problem from the
unbounded solution clipped to the box and then frees the bound variables one at a time: on the
morph's problems (~26 variables, half of them channels held at zero) that is ~30 dense solves
a step, ~100 ms of a 6-target solve. Consecutive Gauss-Newton steps bind nearly the same
variables, so starting from the last step's active set ends in one to three solves.

The problems the morph passes have full column rank (every channel carries a regularisation
row), so the minimiser is unique and any exact active-set path reaches it: results equal
SciPy's to round-off (``tests/test_gauss_newton.py`` holds the two against each other).
"""
from __future__ import annotations

import numpy as np


def _solve(A, b):
    return np.linalg.lstsq(A, b, rcond=None)[0]


def bvls(A, b, lb, ub, on_bound=None, tol=1e-12, max_iter=None):
    """Solve ``min |A x - b|`` over ``lb <= x <= ub``.

    Parameters
    ----------
    A : (m, n) float64; b : (m,) float64; lb, ub : (n,) float64, ``lb <= ub``
    on_bound : (n,) int, optional
        A warm start: -1 / +1 for variables guessed at their lower / upper bound, 0 free (a previous
        call's second return value). Without it, the unbounded solution clipped to the box, as SciPy.
    tol : float
        Stop when no bound variable's gradient points inward by more than this (KKT), or when a
        pass lowers the cost by less than this fraction.

    Returns
    -------
    x : (n,) float64; on_bound : (n,) int64 - the active set at ``x``
    """
    n = A.shape[1]
    if on_bound is None:
        x = _solve(A, b)
        on_bound = np.where(x <= lb, -1, np.where(x >= ub, 1, 0)).astype(np.int64)
    else:
        on_bound = np.asarray(on_bound, dtype=np.int64).copy()
        x = np.zeros(n)
    x = np.where(on_bound < 0, lb, np.where(on_bound > 0, ub, np.clip(x, lb, ub)))
    # initialisation: the least-squares solution on the free variables must be feasible before the
    # main loop; fix each variable that leaves the box at the bound it crossed and solve again
    free = np.flatnonzero(on_bound == 0)
    while free.size:
        z = _solve(A[:, free], b - A @ np.where(on_bound != 0, x, 0.0))
        low, high = z < lb[free], z > ub[free]
        x[free[low]], on_bound[free[low]] = lb[free[low]], -1
        x[free[high]], on_bound[free[high]] = ub[free[high]], 1
        ok = ~(low | high)
        x[free[ok]] = z[ok]
        if ok.all():
            break
        free = free[ok]
    r = A @ x - b
    cost = float(r @ r)
    g = A.T @ r
    for _ in range(3 * n if max_iter is None else max_iter):  # a poor warm start may need more than n
        # a bound variable whose gradient points into the box can lower the cost: free the steepest
        push = g * on_bound
        j = int(np.argmax(push))
        if push[j] < tol and np.all(np.abs(g[on_bound == 0]) < tol):
            break
        if push[j] <= 0.0:
            break
        on_bound[j] = 0
        while True:  # solve on the free set; step back to the first bound crossed, fix it, repeat
            free = np.flatnonzero(on_bound == 0)
            xf = x[free]
            z = _solve(A[:, free], b - A @ np.where(on_bound != 0, x, 0.0))
            lo_f, hi_f = lb[free], ub[free]
            low, high = np.flatnonzero(z < lo_f), np.flatnonzero(z > hi_f)
            if low.size + high.size == 0:
                x[free] = z
                break
            v = np.concatenate([low, high])
            alphas = np.concatenate([lo_f[low] - xf[low], hi_f[high] - xf[high]]) / (z[v] - xf[v])
            i = int(np.argmin(alphas))
            x[free] = xf + alphas[i] * (z - xf)
            j = free[v[i]]
            on_bound[j] = -1 if i < low.size else 1
            x[j] = lb[j] if i < low.size else ub[j]  # exactly: the step's round-off may cross it
        r = A @ x - b
        new = float(r @ r)
        g = A.T @ r
        if cost - new < tol * cost:
            break
        cost = new
    return np.clip(x, lb, ub), on_bound
