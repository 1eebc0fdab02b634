"""Numba kernels: the pattern analysis of the supernodal LDL^T (:mod:`vfit_engine.kernels.supernodal_ldl`).

Done once per sparsity pattern by :class:`vfit_engine.sim.linear.SPDFactor`, from the upper triangle of the
permuted matrix ``C = P A P^T`` and its elimination tree and column counts
(:func:`~vfit_engine.kernels.sparse_ldl.ldl_symbolic`): a postorder of the tree (:func:`etree_postorder`, the same
fill, each supernode's last child just before it), the supernodes (:func:`supernode_partition`), their row lists
(:func:`supernode_rows`) and the place of each of ``C``'s values in the blocks (:func:`value_map`). The layout
is described in :mod:`vfit_engine.kernels.supernodal_ldl`.
"""
from vfit_engine._jit import njit

#: Widest supernode: its ``w x w`` transposed factor (18 kB) stays in a core's L1 cache while the rows below are
#: solved, and the scratch stays small. 32, 48 and 64 measured alike (12.5 ms at 10 k vertices).
MAX_WIDTH = 48

#: Relaxed supernodes (CHOLMOD's defaults, Ashcraft & Grimes 1989): a supernode takes in its last child when the
#: merged one is at most ``RELAX_WIDTH[i]`` columns wide and at most ``RELAX_ZEROS[i]`` of its entries are zeros
#: it stores for nothing. On the 100 x 100 grid: 726 supernodes instead of 4,244, 802 k stored values instead of
#: 661 k, a refactor 1.3-1.4 times faster; fewer zeros (0.5 or 0.3 at 16 columns) measured alike.
RELAX_WIDTH = (4, 16, 48)
RELAX_ZEROS = (1.0, 0.8, 0.1)


@njit
def etree_postorder(parent, post_out, head, nxt, stack):
    """A postorder of the elimination tree (children before their parent, each subtree contiguous).

    Parameters
    ----------
    parent : (n,) int64
        Elimination tree, ``-1`` at the roots.
    post_out : (n,) int64
        Overwritten: ``post_out[k]`` is the column placed at ``k``; the order keeps ``L``'s fill and makes each
        supernode's last child the column just before it.
    head, nxt, stack : (n,) int64
        Scratch.
    """
    n = parent.shape[0]
    for j in range(n):
        head[j] = -1
    for j in range(n - 1, -1, -1):  # children lists, ascending
        p = parent[j]
        if p >= 0:
            nxt[j] = head[p]
            head[p] = j
    k = 0
    for root in range(n):
        if parent[root] != -1:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            v = stack[top]
            c = head[v]
            if c == -1:
                post_out[k] = v
                k += 1
                top -= 1
            else:
                head[v] = nxt[c]
                top += 1
                stack[top] = c


@njit
def supernode_partition(parent, count, sf_out, m_out, nz):
    """Relaxed supernodes of a postordered factor: fundamental runs (each column's parent the next, patterns
    nested) cut at :data:`MAX_WIDTH`, then merged with their last child by :data:`RELAX_WIDTH` and
    :data:`RELAX_ZEROS`.

    Parameters
    ----------
    parent, count : (n,) int64
        Elimination tree and column counts below the diagonal (:func:`~.sparse_ldl.ldl_symbolic`), postordered.
    sf_out : (n + 1,) int64
        Overwritten: the first column of each supernode, then ``n``.
    m_out : (n,) int64
        Overwritten: each supernode's row count (its columns and the rows below).
    nz : (n,) int64
        Scratch.

    Returns
    -------
    int
        The number of supernodes ``ns`` (``sf_out[:ns + 1]``, ``m_out[:ns]``).
    """
    n = parent.shape[0]
    ns = 0
    for j in range(n):
        if j > 0 and parent[j - 1] == j and count[j - 1] == count[j] + 1 and j - sf_out[ns - 1] < MAX_WIDTH:
            continue
        sf_out[ns] = j
        m_out[ns] = count[j] + 1
        ns += 1
    sf_out[ns] = n
    # merge on a stack of finished supernodes (written over the arrays' front: it is never ahead of the reading)
    top = 0
    for s in range(ns):
        f = sf_out[s]
        w = sf_out[s + 1] - f
        m = m_out[s]
        true_nz = w * m - w * (w - 1) // 2
        while top > 0:  # the stacked supernode t ends at column f - 1 (every one before s is stacked)
            t = top - 1
            if parent[f - 1] < f or parent[f - 1] >= f + w:
                break  # t is not a child of s
            nw = f - sf_out[t] + w
            nm = f - sf_out[t] + m
            size = nw * nm - nw * (nw - 1) // 2
            zeros = (size - nz[t] - true_nz) / size
            if nw > MAX_WIDTH or not ((nw <= RELAX_WIDTH[0] and zeros <= RELAX_ZEROS[0])
                                      or (nw <= RELAX_WIDTH[1] and zeros <= RELAX_ZEROS[1])
                                      or (nw <= RELAX_WIDTH[2] and zeros <= RELAX_ZEROS[2])):
                break
            f = sf_out[t]
            w = nw
            m = nm
            true_nz += nz[t]
            top -= 1
        sf_out[top] = f
        m_out[top] = m
        nz[top] = true_nz
        top += 1
    sf_out[top] = n
    return top


@njit
def supernode_rows(cp, ci, parent, sn_of, sf, rp, ri_out, flag, sflag, fill):
    """Row lists of the supernodes: their own columns, then the rows below, ascending.

    Parameters
    ----------
    cp : (n + 1,) int64
    ci : (nnz,) int64
        Upper triangle of ``C`` in CSC (rows > column are ignored).
    parent : (n,) int64
        Elimination tree (:func:`~vfit_engine.kernels.sparse_ldl.ldl_symbolic`).
    sn_of : (n,) int64
        Supernode of each column.
    sf : (ns + 1,) int64
        First column of each supernode, ``sf[ns] = n``.
    rp : (ns + 1,) int64
        Row-list pointers (:func:`supernode_partition`'s row counts).
    ri_out : (rp[ns],) int32
        Overwritten.
    flag : (n,) int64
    sflag, fill : (ns,) int64
        Scratch.

    Returns
    -------
    int
        ``-1``, or the first supernode whose rows differ in number from ``rp`` (a partition that is not of this
        pattern: nothing past its list was written).
    """
    ns = sf.shape[0] - 1
    n = cp.shape[0] - 1
    for s in range(ns):
        for c in range(sf[s + 1] - sf[s]):
            ri_out[rp[s] + c] = sf[s] + c
        fill[s] = sf[s + 1] - sf[s]
        sflag[s] = -1
    for k in range(n):
        # row k of L is nonzero in the columns that the tree paths from each C[i, k] up towards k pass
        # (Davis 2005); k is a row below supernode s when it passes one of s's columns
        flag[k] = k
        for p in range(cp[k], cp[k + 1]):
            i = ci[p]
            while i < k and flag[i] != k:
                flag[i] = k
                s = sn_of[i]
                if k >= sf[s + 1] and sflag[s] != k:
                    sflag[s] = k
                    if rp[s] + fill[s] < rp[s + 1]:
                        ri_out[rp[s] + fill[s]] = k
                    fill[s] += 1
                i = parent[i]
    for s in range(ns):
        if fill[s] != rp[s + 1] - rp[s]:
            return s
    return -1


@njit
def value_map(cp, ci, sn_of, sf, rp, ri, xp, dst_out):
    """Where each entry of ``C``'s upper triangle lies in the supernodal values ``lx``.

    Parameters
    ----------
    cp, ci : (n + 1,), (nnz,) int64
        Upper triangle of ``C`` in CSC, rows <= column only.
    sn_of, sf, rp, ri, xp : supernodal structure (module docstring)
    dst_out : (nnz,) int64
        Overwritten: ``C[i, k]`` (i <= k) is ``L``'s entry at row ``k``, column ``i``: its place in ``lx``.
    """
    n = cp.shape[0] - 1
    for k in range(n):
        for p in range(cp[k], cp[k + 1]):
            i = ci[p]
            s = sn_of[i]
            lo = rp[s]
            hi = rp[s + 1]
            while lo < hi:  # k in the supernode's ascending row list
                mid = (lo + hi) // 2
                if ri[mid] < k:
                    lo = mid + 1
                else:
                    hi = mid
            w = sf[s + 1] - sf[s]
            dst_out[p] = xp[s] + (lo - rp[s]) * w + (i - sf[s])
