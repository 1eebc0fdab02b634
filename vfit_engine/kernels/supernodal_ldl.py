"""Numba kernels: supernodal LDL^T factorisation and solve of a symmetric positive definite matrix.

The same factor as :mod:`vfit_engine.kernels.sparse_ldl` (``C = P A P^T = L D L^T``, the order chosen by
:mod:`vfit_engine.sim.linear`), stored by **supernodes**: runs of consecutive columns ``f .. f + w - 1`` of ``L``
in which each column's elimination-tree parent is the next one and the pattern below the run is the same. A
supernode's columns share one list of rows (``ri[rp[s]:rp[s + 1]]``: its own ``w`` columns, then the rows below,
ascending) and one dense block of ``m x w`` values, row-major: ``lx[xp[s] + r * w + c]`` is ``L`` at the ``r``-th
row of the list and column ``f + c``. The block's strictly upper part is unused and its diagonal holds ``C``'s
until the block is factored; ``D`` is in ``d``.

The numeric factor is left-looking by supernodes (Ng & Peyton 1993; CHOLMOD's supernodal method, Chen, Davis,
Hager & Rajamanickam 2008): a supernode gathers the updates of the supernodes below it that reach its columns
(each of them kept in a linked list under the next supernode it updates), then factors its own block. The
pattern work is done once per pattern (:mod:`vfit_engine.kernels.supernodal_analysis`), so a refactor with new
values is a scatter of ``A``'s values and dense arithmetic along contiguous rows, which LLVM vectorises (no
fastmath needed: the inner loops are ``y += s * x``, not sums). The solve reads each row of a block once with
one index per row, not one per entry.

The simplicial kernels of :mod:`vfit_engine.kernels.sparse_ldl` stay as the plain reference this factor is
tested and measured against (``benchmarks/bench_sparse_ldl.py``).
"""
import numpy as np

from vfit_engine._jit import njit

#: Multiply-adds from which a product (a supernode's update of another, or the solve of a block's rows below its
#: diagonal) is done by BLAS (numpy's ``dot``), then scattered; smaller ones by loops. At 10 k vertices a refactor
#: took 13.0 ms of CPU against 20.3 ms with loops only; thresholds from 128 to 8,192 measured alike.
BLAS_MIN = 2048

#: Multiply-adds up to which OpenBLAS (numpy's and scipy's) multiplies in the calling thread
#: (``65536 * GEMM_MULTITHREAD_THRESHOLD``, its default 4): larger products are cut into row chunks of this size.
#: OpenBLAS's own threads, on a machine whose cores are busy, made a refactor 2.5 times slower (32 against 12.6 ms
#: of CPU at 10 k vertices); one thread is the cloth solver's rule (it runs beside other work).
BLAS_SERIAL = 262144


@njit
def sn_numeric(sf, rp, ri, xp, lx, d, data, src, dst, sn_of, relmap, head, link, ptr, tbuf, wrow, relb, wbuf):
    """Numeric supernodal LDL^T of ``C`` into ``lx`` and ``d`` (their pattern fixed by the structure arrays).

    Parameters
    ----------
    sf, rp, ri, xp : supernodal structure (module docstring)
    lx : (xp[ns],) float64
        Block values, overwritten.
    d : (n,) float64
        Pivots ``D``, overwritten.
    data : (nnz_a,) float64
        Stored values of ``A``.
    src, dst : (nnz_c,) int64
        ``lx[dst[p]] = data[src[p]]`` puts ``C``'s upper triangle in the blocks
        (:func:`~.supernodal_analysis.value_map`).
    sn_of : (n,) int64
        Supernode of each column.
    relmap : (n,) int64
    head, link, ptr : (ns,) int64
    tbuf : (max block size,) float64
    wrow, relb : (max rows,) float64, int64
        Scratch.

    Returns
    -------
    int
        ``-1`` when every pivot is positive, else the first column ``k`` with ``D[k] <= 0`` (or NaN).
    """
    ns = sf.shape[0] - 1
    lx[:] = 0.0
    for p in range(src.shape[0]):
        lx[dst[p]] = data[src[p]]
    for s in range(ns):
        head[s] = -1
    for j in range(ns):
        f = sf[j]
        w = sf[j + 1] - f
        m = rp[j + 1] - rp[j]
        for r in range(m):
            relmap[ri[rp[j] + r]] = r
        k = head[j]
        while k != -1:
            nxt = link[k]
            _update(j, k, sf, rp, ri, xp, lx, d, relmap, ptr, tbuf, wrow, relb, wbuf)
            p2 = ptr[k]
            if p2 < rp[k + 1] - rp[k]:  # on to the next supernode this one updates
                t = sn_of[ri[rp[k] + p2]]
                link[k] = head[t]
                head[t] = k
            k = nxt
        bad = _factor_block(lx, xp[j], m, w, d, f, tbuf, wrow, wbuf)
        if bad >= 0:
            return bad
        if m > w:
            ptr[j] = w
            t = sn_of[ri[rp[j] + w]]
            link[j] = head[t]
            head[t] = j
    return -1


@njit
def _update(j, k, sf, rp, ri, xp, lx, d, relmap, ptr, tbuf, wrow, relb, wbuf):
    """Subtract supernode ``k``'s contribution ``L_k[rows >= f_j] D_k L_k[rows in j]^T`` from block ``j``; move
    ``ptr[k]`` past the rows of ``j``'s columns."""
    fj = sf[j]
    lj = sf[j + 1]
    wj = lj - fj
    wk = sf[k + 1] - sf[k]
    mk = rp[k + 1] - rp[k]
    rk = rp[k]
    p1 = ptr[k]
    p2 = p1
    while p2 < mk and ri[rk + p2] < lj:
        p2 += 1
    ptr[k] = p2
    m1 = p2 - p1
    bk = xp[k]
    fk = sf[k]
    # tbuf[c * m1 + b] = d_c L_k[p1 + b, c]: the rows in j's columns, transposed and scaled, for axpys along b
    for b in range(m1):
        relb[b] = relmap[ri[rk + p1 + b]]
        _scaled_column(tbuf, b, m1, d, fk, lx, bk + (p1 + b) * wk, wk)
    bj = xp[j]
    m2 = mk - p1
    if m2 * m1 * wk >= BLAS_MIN:  # one product by BLAS, then scattered
        _gemm(lx, bk + p1 * wk, m2, wk, tbuf, 0, m1, wbuf, 0)
        flat = wbuf[:m2 * m1]
        for a in range(m2):
            _scatter_sub(lx, bj + relmap[ri[rk + p1 + a]] * wj, relb, flat[a * m1:], min(a + 1, m1))
        return
    for a in range(m2):
        row = bk + (p1 + a) * wk
        top = min(a + 1, m1)  # the lower triangle only where the rows are j's columns
        for b in range(top):
            wrow[b] = 0.0
        for c in range(wk):
            _axpy(wrow, 0, tbuf, c * m1, top, lx[row + c])
        _scatter_sub(lx, bj + relmap[ri[rk + p1 + a]] * wj, relb, wrow, top)


@njit
def _factor_block(lx, base, m, w, d, f, tbuf, dinv, wbuf):
    """Dense LDL^T of a supernode's diagonal block, then the solve of the rows below. Returns the first bad
    column of ``C`` or -1.

    The diagonal block goes row by row, each row a forward substitution by axpys along the transposed rows
    above it (``U = L^T`` kept in ``tbuf``, ``w x w``). The rows below solve ``L21 D L11^T = C21``: as one BLAS
    product ``C21 L11^-T`` when it is large enough, else row by row like the block's own rows."""
    for r in range(min(m, w)):
        row = base + r * w
        for k in range(r - 1):  # z = L[:r, :r]^-1 C[r, :r]: axpys along U's rows
            _axpy(lx, row + k + 1, tbuf, k * w + k + 1, r - k - 1, -lx[row + k])
        dr = lx[row + r]
        for k in range(r):  # L[r, k] = z_k / d_k, and the pivot C[r, r] - sum_k L[r, k] z_k
            z = lx[row + k]
            lrk = z * dinv[k]
            lx[row + k] = lrk
            dr -= lrk * z
            tbuf[k * w + r] = lrk
        d[f + r] = dr
        if not dr > 0.0:
            return f + r
        dinv[r] = 1.0 / dr
    below = m - w
    if below <= 0:
        return -1
    if below * w * w >= BLAS_MIN:
        # wbuf[:w*w] = L11^-T (row i of L11^-1 is e_i - sum_k L[i, k] (row k of L11^-1); then transposed)
        for i in range(w):
            for c in range(w):
                wbuf[i * w + c] = 0.0
            wbuf[i * w + i] = 1.0
            for k in range(i):
                _axpy(wbuf, i * w, wbuf, k * w, k + 1, -tbuf[k * w + i])
        for i in range(w):
            for c in range(i):
                wbuf[c * w + i], wbuf[i * w + c] = wbuf[i * w + c], wbuf[c * w + i]
        _gemm(lx, base + w * w, below, w, wbuf, 0, w, wbuf, w * w)
        for r in range(below):
            _scaled_row(lx, base + (w + r) * w, wbuf, w * w + r * w, dinv, w)
        return -1
    for r in range(w, m):
        row = base + r * w
        for k in range(w - 1):
            _axpy(lx, row + k + 1, tbuf, k * w + k + 1, w - k - 1, -lx[row + k])
        _scale(lx, row, dinv, w)
    return -1


@njit
def _gemm(a, a0, rows, inner, b, b0, cols, out, out0):
    """``out[out0:] = A B`` (row-major, flat): ``A`` (rows x inner) at ``a[a0:]``, ``B`` (inner x cols) at
    ``b[b0:]``. By BLAS, in row chunks of at most :data:`BLAS_SERIAL` multiply-adds each."""
    step = max(1, BLAS_SERIAL // max(1, inner * cols))
    bm = b[b0:b0 + inner * cols].reshape((inner, cols))
    for r0 in range(0, rows, step):
        r1 = min(rows, r0 + step)
        np.dot(a[a0 + r0 * inner:a0 + r1 * inner].reshape((r1 - r0, inner)), bm,
               out[out0 + r0 * cols:out0 + r1 * cols].reshape((r1 - r0, cols)))


@njit(inline="always")
def _axpy(y, y0, x, x0, count, a):
    """``y[y0 + i] += a * x[x0 + i]`` for ``i < count``. Unsigned indices: with Numba's signed ones every access
    checks for a negative index to wrap, which keeps LLVM from vectorising (measured 5x slower)."""
    if count <= 0:
        return
    yo = np.uint64(y0)
    xo = np.uint64(x0)
    for i in range(np.uint64(count)):
        y[yo + i] += a * x[xo + i]


@njit(inline="always")
def _scaled_row(y, y0, x, x0, s, count):
    """``y[y0 + i] = x[x0 + i] * s[i]`` for ``i < count`` (unsigned indices, as :func:`_axpy`)."""
    yo = np.uint64(y0)
    xo = np.uint64(x0)
    for i in range(np.uint64(count)):
        y[yo + i] = x[xo + i] * s[i]


@njit(inline="always")
def _scaled_column(y, y0, stride, s, s0, x, x0, count):
    """``y[y0 + i * stride] = s[s0 + i] * x[x0 + i]`` for ``i < count`` (unsigned indices)."""
    yo = np.uint64(y0)
    st = np.uint64(stride)
    so = np.uint64(s0)
    xo = np.uint64(x0)
    for i in range(np.uint64(count)):
        y[yo + i * st] = s[so + i] * x[xo + i]


@njit(inline="always")
def _scale(y, y0, x, count):
    """``y[y0 + i] *= x[i]`` for ``i < count`` (unsigned indices, as :func:`_axpy`)."""
    yo = np.uint64(y0)
    for i in range(np.uint64(count)):
        y[yo + i] *= x[i]


@njit(inline="always")
def _scatter_sub(y, y0, at, x, count):
    """``y[y0 + at[i]] -= x[i]`` for ``i < count``."""
    yo = np.uint64(y0)
    for i in range(np.uint64(count)):
        y[yo + np.uint64(at[i])] -= x[i]


@njit
def sn_solve3(sf, rp, ri, xp, lx, d, perm, x, work):
    """Solve ``A X = B`` for three right-hand sides in place with the factor of :func:`sn_numeric`.

    Parameters
    ----------
    sf, rp, ri, xp, lx, d : arrays of :func:`sn_numeric`
    perm : (n,) int64
        ``perm[k]`` is the row of ``A`` that is row ``k`` of ``C`` = P A P^T.
    x : (n, 3) float64
        ``B`` on entry, ``X`` on return.
    work : (n, 3) float64
        Scratch.
    """
    n = d.shape[0]
    ns = sf.shape[0] - 1
    for k in range(n):
        pk = perm[k]
        work[k, 0] = x[pk, 0]
        work[k, 1] = x[pk, 1]
        work[k, 2] = x[pk, 2]
    z = work.reshape(3 * n)  # flat, with unsigned indices (no wrap checks: :func:`_axpy`)
    for s in range(ns):  # L y = P b: the block's own rows, then the rows below
        f3 = np.uint64(3 * sf[s])
        w = np.uint64(sf[s + 1] - sf[s])
        r0 = np.uint64(rp[s])
        row = np.uint64(xp[s])
        for r in range(np.uint64(rp[s + 1] - rp[s])):
            # two sums per column, even and odd terms: twice the independent chains of multiply-adds
            y0 = 0.0
            y1 = 0.0
            y2 = 0.0
            u0 = 0.0
            u1 = 0.0
            u2 = 0.0
            top = min(r, w)
            half = top // np.uint64(2)
            for h in range(half):
                c = np.uint64(2) * h
                v = lx[row + c]
                u = lx[row + c + np.uint64(1)]
                q = f3 + np.uint64(3) * c
                y0 += v * z[q]
                y1 += v * z[q + np.uint64(1)]
                y2 += v * z[q + np.uint64(2)]
                u0 += u * z[q + np.uint64(3)]
                u1 += u * z[q + np.uint64(4)]
                u2 += u * z[q + np.uint64(5)]
            if top > np.uint64(2) * half:
                c = top - np.uint64(1)
                v = lx[row + c]
                q = f3 + np.uint64(3) * c
                y0 += v * z[q]
                y1 += v * z[q + np.uint64(1)]
                y2 += v * z[q + np.uint64(2)]
            t = np.uint64(3 * ri[r0 + r])
            z[t] -= y0 + u0
            z[t + 1] -= y1 + u1
            z[t + 2] -= y2 + u2
            row += w
    for k in range(n):
        inv = 1.0 / d[k]
        work[k, 0] *= inv
        work[k, 1] *= inv
        work[k, 2] *= inv
    for s in range(ns - 1, -1, -1):  # L^T x = y: the rows below, then the block's own rows upwards
        f3 = np.uint64(3 * sf[s])
        w = np.uint64(sf[s + 1] - sf[s])
        r0 = np.uint64(rp[s])
        m = np.uint64(rp[s + 1] - rp[s])
        base = np.uint64(xp[s])
        r = w
        while r + np.uint64(1) < m:  # rows below the block two at a time: half the passes over the block's x
            t = np.uint64(3 * ri[r0 + r])
            u = np.uint64(3 * ri[r0 + r + np.uint64(1)])
            x0, x1, x2 = z[t], z[t + np.uint64(1)], z[t + np.uint64(2)]
            y0, y1, y2 = z[u], z[u + np.uint64(1)], z[u + np.uint64(2)]
            row = base + r * w
            for c in range(w):
                v = lx[row + c]
                e = lx[row + w + c]
                q = f3 + np.uint64(3) * c
                z[q] -= v * x0 + e * y0
                z[q + np.uint64(1)] -= v * x1 + e * y1
                z[q + np.uint64(2)] -= v * x2 + e * y2
            r += np.uint64(2)
        for q in range(m - min(r, m)):  # the last row below (if odd), then the block's own rows upwards
            _row_transposed(z, f3, lx, base, ri, r0, m - np.uint64(1) - q, w)
        for q in range(min(m, w)):
            _row_transposed(z, f3, lx, base, ri, r0, min(m, w) - np.uint64(1) - q, w)
    for k in range(n):
        pk = perm[k]
        x[pk, 0] = work[k, 0]
        x[pk, 1] = work[k, 1]
        x[pk, 2] = work[k, 2]


@njit(inline="always")
def _row_transposed(z, f3, lx, base, ri, r0, r, w):
    """``x[f + c] -= L[r, c] x[ri[r]]`` for the columns ``c < min(r, w)`` of a block (flat (n, 3) ``z``,
    unsigned indices)."""
    t = np.uint64(3 * ri[r0 + r])
    x0, x1, x2 = z[t], z[t + np.uint64(1)], z[t + np.uint64(2)]
    row = base + r * w
    for c in range(min(r, w)):
        v = lx[row + c]
        q = f3 + np.uint64(3) * c
        z[q] -= v * x0
        z[q + np.uint64(1)] -= v * x1
        z[q + np.uint64(2)] -= v * x2
