"""Numba kernel for a linear blend of dense blend-shape targets: ``out = base + w @ targets``.

NumPy's ``dot`` runs this product through a multithreaded BLAS whose cost on a busy 2-core machine
swings from 0.1 ms to 6 ms a call (measured; which call form is slow changes with the load), and the
morph solver makes hundreds of them; a plain serial loop costs ~0.3 ms always.

Importing this module imports numba; only body-shaping code imports it.
"""
from vfit_engine._jit import njit


@njit
def blend(base, targets, weights, out):
    """``out[i] = base[i] + sum_j weights[j] * targets[j, i]``.

    base : (n,) float64; targets : (k, n) float64 C-contiguous; weights : (k,) float64;
    out : (n,) float64, overwritten (may not alias ``targets``).
    """
    out[:] = base
    for j in range(targets.shape[0]):
        w = weights[j]
        if w == 0.0:
            continue
        row = targets[j]
        for i in range(out.shape[0]):
            out[i] += w * row[i]


@njit
def project(targets, vec, out):
    """``out[j] = sum_i targets[j, i] * vec[i]``: how far each target moves along ``vec``.

    targets : (k, n) float64 C-contiguous; vec : (n,) float64; out : (k,) float64, overwritten.
    """
    for j in range(targets.shape[0]):
        row = targets[j]
        acc = 0.0
        for i in range(vec.shape[0]):
            acc += row[i] * vec[i]
        out[j] = acc
