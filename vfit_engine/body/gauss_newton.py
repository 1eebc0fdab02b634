"""A bounded trust-region Gauss-Newton for the morph solver's small least-squares problems.

Its own module because two stages of the solver (semantic sliders, measurement channels) and the
reach search all call it; it knows nothing of bodies.
"""
import numpy as np

from .bvls import bvls


def gauss_newton(fun, x, lo, hi, reg, planes, hard=None, jac=None, max_iter=40, fd_step=1e-5, soft_tol=0.0):
    """Minimise ``|r(x)|^2 + |reg * x|^2`` over ``lo <= x <= hi``.

    ``fun(x, planes) -> (r, info)``. A trust-region Gauss-Newton: a
    forward-difference Jacobian with Broyden rank-one updates between refreshes,
    and each step the bounded linear least-squares problem (``bvls.py``, warm-started)
    within a box of half-width ``delta`` that grows after good steps and shrinks
    after bad ones (a bad step first refreshes a stale Jacobian). Stops when the
    objective stalls (relative decrease < 1e-2) or is tiny, with the ``hard``
    residuals (all by default) under 0.03 (in their units, here 0.03 mm; the
    caller verifies its own tolerance afterwards) and the other residuals under
    ``soft_tol``, or, while a hard residual is missed, after three unclipped
    steps that each gain less than 0.1 % or six steps that gain less than 1 %
    together (a target out of reach). With ``jac(x,
    planes) -> J`` the exact Jacobian is used at every iterate instead.
    """
    def objective(r, x):
        d = reg * x
        return float(r @ r + d @ d)

    def jacobian(x, r):
        if jac is not None:
            return jac(x, planes)
        J = np.empty((r.size, x.size))
        for j in range(x.size):
            step = fd_step if x[j] + fd_step <= hi[j] else -fd_step
            xp = x.copy()
            xp[j] += step
            J[:, j] = (fun(xp, planes)[0] - r) / step
        return J

    x = np.clip(np.asarray(x, dtype=np.float64), lo, hi)
    r, _ = fun(x, planes)
    hard = np.ones(r.size, dtype=bool) if hard is None else hard
    J, fresh = jacobian(x, r), True
    f = objective(r, x)
    A_reg = np.diag(reg)
    delta = 1.0
    active = None
    crawling = 0
    history = []
    for _ in range(max_iter):
        A = np.vstack([J, A_reg])
        rhs = -np.concatenate([r, reg * x])
        box = (np.maximum(lo - x, -delta) - 1e-15, np.minimum(hi - x, delta) + 1e-15)
        # each step binds nearly the variables the last one bound: start the active set there
        dx, active = bvls(A, rhs, box[0], box[1], on_bound=active, tol=1e-12)
        if np.max(np.abs(dx)) < 1e-10:
            break
        model = A @ dx - rhs
        predicted = f - float(model @ model)
        x_new = np.clip(x + dx, lo, hi)
        r_new, _ = fun(x_new, planes)
        f_new = objective(r_new, x_new)
        rho = (f - f_new) / predicted if predicted > 0 else -1.0
        if rho < 0.1:
            if not fresh:  # the Broyden model went stale: refresh it and retry from x
                J, fresh = jacobian(x, r), True
                continue
            delta *= 0.25
            if delta < 1e-7:
                break
            if f_new >= f:
                continue
        step = x_new - x
        if jac is not None:
            J, fresh = jacobian(x_new, r_new), True
        else:
            J = J + np.outer(r_new - r - J @ step, step) / (step @ step)
            fresh = False
        limited = np.max(np.abs(dx)) > 0.5 * delta  # the trust region, not the model, ended the step
        if rho > 0.75 and limited:
            delta = min(2.0 * delta, 1.0)
        # slow progress means "done" only when the step was the model's own, not a clipped one
        stalled = f - f_new < 1e-2 * f and not limited
        crawling = crawling + 1 if (f - f_new < 1e-3 * f and not limited) else 0
        x, r, f = x_new, r_new, f_new
        if np.all(np.abs(r[hard]) < 0.03) and (stalled or f < 1e-6 or np.all(np.abs(r[~hard]) < soft_tol)):
            break
        if crawling >= 3:  # three steps that each gain < 0.1 %: a target out of reach holds it there
            break
        history.append(f)
        met = np.all(np.abs(r[hard]) < 0.03)
        if not met and len(history) > 6 and history[-7] - f < 0.01 * history[-7]:
            break  # six steps, clipped or not, gained < 1 % together while a target is missed: out of reach
    return x, r
