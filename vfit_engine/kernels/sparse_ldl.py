"""Numba kernels: sparse LDL^T factorisation and solve of a symmetric positive definite matrix.

The matrix is given permuted, ``C = P A P^T`` (``C[k, l] = A[perm[k], perm[l]]``, the fill-reducing order is
chosen by the caller, :mod:`vfit_engine.sim.linear`), as its upper triangle in CSC (column ``k`` holds the rows
``i <= k``: ``cp`` (n + 1,), ``ci`` (nnz,), ``cx`` (nnz,)). Then::

    C = L D L^T,   L unit lower triangular (strictly lower part stored by columns: lp, li, lx),
    D diagonal (d) > 0,
    A x = b   <=>   L D L^T (P x) = P b

The method is the simplicial up-looking LDL^T of T. A. Davis, "Algorithm 849: A concise sparse Cholesky
factorization package", ACM TOMS 31(4), 2005: row ``k`` of ``L`` is a sparse triangular solve with the rows
already computed, its pattern is found by walking the elimination tree from each nonzero of ``C[:k, k]``
(:func:`ldl_symbolic` gives the tree and the column counts once; :func:`ldl_numeric` fills preallocated arrays,
so a refactor with new values allocates nothing). Float64 throughout: float32 storage of ``L`` was measured
barely faster (issue 32).

:func:`ldl_solve3` takes plain arrays and a scratch array only, so a jitted loop can call it several times per step.

The cloth solver factors with the supernodal kernels of :mod:`vfit_engine.kernels.supernodal_ldl` (4.5-5 times
less CPU per refactor at 10 k vertices), which take their elimination tree and column counts from
:func:`ldl_symbolic`; :func:`ldl_numeric` and :func:`ldl_solve3` stay as the plain reference the supernodal factor
is tested against and the old path ``benchmarks/bench_sparse_ldl.py`` measures it against.
"""
from vfit_engine._jit import njit


@njit
def ldl_symbolic(cp, ci, parent_out, count_out, flag):
    """Elimination tree and column counts of ``L`` for ``C`` = P A P^T.

    Parameters
    ----------
    cp : (n + 1,) int64
    ci : (nnz,) int64
        Upper triangle of ``C`` in CSC (rows > column are ignored).
    parent_out : (n,) int64
        Elimination-tree parent of each column (``-1`` for a root), overwritten.
    count_out : (n,) int64
        Number of entries of each column of ``L`` below the diagonal, overwritten; ``lp`` is their running sum.
    flag : (n,) int64
        Scratch.
    """
    n = cp.shape[0] - 1
    for k in range(n):
        parent_out[k] = -1
        count_out[k] = 0
        flag[k] = k
        for p in range(cp[k], cp[k + 1]):
            i = ci[p]
            # row k of L is nonzero where the tree path from i up towards k passes (Davis 2005, section 2)
            while i < k and flag[i] != k:
                if parent_out[i] == -1:
                    parent_out[i] = k
                count_out[i] += 1
                flag[i] = k
                i = parent_out[i]


@njit
def ldl_numeric(cp, ci, cx, lp, parent, li_out, lx_out, d_out, y, flag, stack, fill):
    """Numeric LDL^T of ``C`` into preallocated arrays (the pattern of :func:`ldl_symbolic`).

    Parameters
    ----------
    cp, ci : (n + 1,), (nnz,) int64
        Upper triangle of ``C`` in CSC (rows > column are ignored).
    cx : (nnz,) float64
        Its values.
    lp : (n + 1,) int64
        Column pointers of ``L`` (running sum of the column counts).
    parent : (n,) int64
        Elimination tree.
    li_out : (nnz_l,) int64
        Row indices of ``L``, overwritten (ascending within each column).
    lx_out : (nnz_l,) float64
        Values of ``L`` below its unit diagonal, overwritten.
    d_out : (n,) float64
        Pivots ``D``, overwritten.
    y : (n,) float64
    flag, stack, fill : (n,) int64
        Scratch.

    Returns
    -------
    int
        ``-1`` when every pivot is positive, else the first column ``k`` with ``D[k] <= 0`` (or NaN): ``C`` is
        not positive definite and the factor is unusable.
    """
    n = cp.shape[0] - 1
    for k in range(n):
        # scatter column k of C into y and find the pattern of row k of L in topological order
        y[k] = 0.0
        top = n
        flag[k] = k
        fill[k] = 0
        for p in range(cp[k], cp[k + 1]):
            i = ci[p]
            if i > k:
                continue
            y[i] += cx[p]
            depth = 0
            while flag[i] != k:
                stack[depth] = i
                depth += 1
                flag[i] = k
                i = parent[i]
            while depth > 0:
                top -= 1
                depth -= 1
                stack[top] = stack[depth]
        # sparse triangular solve L[:k, :k] D z = C[:k, k]; row k of L is z / D, the pivot C[k, k] - z . l
        dk = y[k]
        y[k] = 0.0
        while top < n:
            i = stack[top]
            top += 1
            yi = y[i]
            y[i] = 0.0
            end = lp[i] + fill[i]
            for p in range(lp[i], end):
                y[li_out[p]] -= lx_out[p] * yi
            lki = yi / d_out[i]
            dk -= lki * yi
            li_out[end] = k
            lx_out[end] = lki
            fill[i] += 1
        d_out[k] = dk
        if not dk > 0.0:
            return k
    return -1


@njit
def ldl_solve3(lp, li, lx, d, perm, x, work):
    """Solve ``A X = B`` for three right-hand sides in place with the factor of :func:`ldl_numeric`.

    The three columns are written out rather than looped over: a loop over a run-time column count measured
    twice as slow (0.9 against 0.4 ms at 2.5k vertices), and positions are what the solver solves for.

    Parameters
    ----------
    lp, li, lx, d : arrays of :func:`ldl_numeric`
    perm : (n,) int64
        ``perm[k]`` is the row of ``A`` that is row ``k`` of ``C`` = P A P^T.
    x : (n, 3) float64
        ``B`` on entry, ``X`` on return.
    work : (n, 3) float64
        Scratch.
    """
    n = d.shape[0]
    for k in range(n):
        pk = perm[k]
        work[k, 0] = x[pk, 0]
        work[k, 1] = x[pk, 1]
        work[k, 2] = x[pk, 2]
    for j in range(n):  # L z = P b, by columns of L: a scatter
        z0 = work[j, 0]
        z1 = work[j, 1]
        z2 = work[j, 2]
        for p in range(lp[j], lp[j + 1]):
            r = li[p]
            v = lx[p]
            work[r, 0] -= v * z0
            work[r, 1] -= v * z1
            work[r, 2] -= v * z2
    for j in range(n - 1, -1, -1):  # D^-1 then L^T, by columns of L (rows of L^T): a gather
        inv = 1.0 / d[j]
        s0 = work[j, 0] * inv
        s1 = work[j, 1] * inv
        s2 = work[j, 2] * inv
        for p in range(lp[j], lp[j + 1]):
            r = li[p]
            v = lx[p]
            s0 -= v * work[r, 0]
            s1 -= v * work[r, 1]
            s2 -= v * work[r, 2]
        work[j, 0] = s0
        work[j, 1] = s1
        work[j, 2] = s2
    for k in range(n):
        pk = perm[k]
        x[pk, 0] = work[k, 0]
        x[pk, 1] = work[k, 1]
        x[pk, 2] = work[k, 2]
