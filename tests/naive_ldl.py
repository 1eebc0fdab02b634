"""Slow, obvious NumPy versions of the sparse LDL^T kernels (:mod:`vfit_engine.kernels.sparse_ldl`), for tests.

Dense matrices, one entry at a time: the structural elimination gives the elimination tree and the column counts
of ``L`` (no numerical cancellation can hide an entry), the textbook column-by-column LDL^T gives ``L`` and ``D``.
"""
import numpy as np


def structural_factor(pattern):
    """Elimination tree and column counts of the Cholesky factor of a symmetric pattern.

    Parameters
    ----------
    pattern : (n, n) bool
        Symmetric nonzero pattern of ``C``.

    Returns
    -------
    parent : (n,) int64
        ``min{i > j : L[i, j] != 0}``, ``-1`` when column ``j`` of ``L`` has nothing below the diagonal.
    count : (n,) int64
        Entries of each column of ``L`` below the diagonal.
    """
    s = np.array(pattern, dtype=bool)
    n = s.shape[0]
    parent = np.full(n, -1, dtype=np.int64)
    count = np.zeros(n, dtype=np.int64)
    for j in range(n):
        below = [i for i in range(j + 1, n) if s[i, j]]
        count[j] = len(below)
        if below:
            parent[j] = below[0]
        for a in below:  # eliminating j joins all its later neighbours (fill)
            for b in below:
                s[a, b] = True
    return parent, count


def dense_ldl(c):
    """``C = L D L^T`` by columns (Golub & Van Loan, algorithm 4.1.2).

    Parameters
    ----------
    c : (n, n) float
        Symmetric positive definite.

    Returns
    -------
    L : (n, n) float64
        Unit lower triangular.
    d : (n,) float64
    """
    c = np.array(c, dtype=np.float64)
    n = c.shape[0]
    L = np.eye(n)
    d = np.zeros(n)
    for j in range(n):
        d[j] = c[j, j] - sum(L[j, k] ** 2 * d[k] for k in range(j))
        for i in range(j + 1, n):
            L[i, j] = (c[i, j] - sum(L[i, k] * L[j, k] * d[k] for k in range(j))) / d[j]
    return L, d


def laplacian(n, pairs, weights):
    """``sum_s w_s (e_i - e_j)(e_i - e_j)^T`` as a dense (n, n) array, spring by spring."""
    out = np.zeros((n, n))
    for (i, j), w in zip(pairs, weights):
        out[i, i] += w
        out[j, j] += w
        out[i, j] -= w
        out[j, i] -= w
    return out
