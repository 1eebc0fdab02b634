"""Sparse symmetric positive definite systems of the projective-dynamics cloth solver (issue 32).

The global step solves ``A X = B`` several times per time step with one constant matrix::

    A = M / h^2 + sum_s w_s (e_i - e_j)(e_i - e_j)^T        (Liu 2013, Bouaziz 2014)

(n, n), n the vertex count, ``X`` and ``B`` (n, 3). :class:`SPDFactor` factors it as ``P A P^T = L D L^T`` with
the supernodal kernels of :mod:`vfit_engine.kernels.supernodal_ldl` and hands the factor's arrays to a jitted
frame loop (:attr:`SPDFactor.arrays`, in the order :func:`~vfit_engine.kernels.supernodal_ldl.sn_solve3` takes
them). The solver refactors new values of the same pattern almost every step (:meth:`SPDFactor.refactor_values`):
all the pattern work (order, elimination tree, supernodes, where each value goes) is done once per pattern.

The fill-reducing order is SuperLU's multiple minimum degree on ``A + A^T`` (``splu(...).perm_c`` with
``permc_spec="MMD_AT_PLUS_A"``, symmetric mode, no pivoting), used symmetrically, then postordered along its
elimination tree (the same fill; each supernode's last child just before it, so small supernodes merge). On
garment matrices it gave the least fill of natural, reverse Cuthill-McKee, minimum degree and a geometric nested
dissection (issue 32's measurements); METIS's nested dissection (``pymetis``) was measured too and gave more (the
100 x 100 sphere-drape grid: 622 k entries of ``L`` against 601 k; the shared suit 87 k against 85 k), so it does
not earn a dependency. SuperLU computes the order only as part of a full LU, which costs most of the first
factor's time but happens once per sparsity pattern; should it fail, reverse Cuthill-McKee takes over.
"""
from collections import namedtuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee
from scipy.sparse.linalg import splu

from vfit_engine.kernels.sparse_ldl import ldl_symbolic
from vfit_engine.kernels.supernodal_analysis import etree_postorder, supernode_partition, supernode_rows, value_map
from vfit_engine.kernels.supernodal_ldl import sn_numeric, sn_solve3

#: The fill-reducing orders :class:`SPDFactor` knows, the default first.
ORDERINGS = ("mmd", "rcm", "natural")

#: Relative asymmetry ``|A_ij - A_ji| / max |A|`` still taken as symmetric: assembly sums the same terms in
#: different orders on either side of the diagonal, which leaves differences of a few ulps.
SYMMETRY_RTOL = 1e-10

#: The factor as :func:`~vfit_engine.kernels.supernodal_ldl.sn_solve3` takes it, before ``x`` and ``work``: the
#: supernodes' first columns ``sf`` (ns + 1,) int64, row-list pointers ``rp`` (ns + 1,) int64, row lists ``ri``
#: int32, value pointers ``xp`` (ns + 1,) int64, block values ``lx`` float64 (module docstring of the kernels),
#: ``d`` (n,) float64, ``perm`` (n,) int64.
LDLArrays = namedtuple("LDLArrays", "sf rp ri xp lx d perm")


def spring_laplacian(spring_indices, weights, n, diagonal=0.0):
    """The weighted graph Laplacian of springs plus a diagonal: ``diag(diagonal) + sum_s w_s (e_i - e_j)(e_i -
    e_j)^T``, the projective-dynamics global matrix with ``diagonal = mass / h^2``.

    Parameters
    ----------
    spring_indices : (s, 2) int
        Vertex pairs ``(i, j)``, ``i != j``; a repeated pair adds its weights.
    weights : (s,) float
        Weight of each spring (N/m for a projective-dynamics spring).
    n : int
        Vertex count.
    diagonal : float or (n,) float
        Added to the diagonal (kg/s^2 for ``mass / h^2``).

    Returns
    -------
    scipy.sparse.csc_matrix
        (n, n) float64, symmetric, with every diagonal entry and every spring's pair stored even when its value
        is zero: a weight set to zero keeps the sparsity pattern, so :meth:`SPDFactor.refactor` keeps its
        analysis. (Adding two scipy matrices drops zeros: pass the diagonal here rather than adding it.)
    """
    ij = np.asarray(spring_indices, dtype=np.int64).reshape(-1, 2)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape[0] != ij.shape[0]:
        raise ValueError(f"{ij.shape[0]} springs but {w.shape[0]} weights")
    i, j = ij[:, 0], ij[:, 1]
    diag = np.arange(n)
    rows = np.concatenate([i, j, i, j, diag])
    cols = np.concatenate([i, j, j, i, diag])
    vals = np.concatenate([w, w, -w, -w, np.broadcast_to(np.asarray(diagonal, dtype=np.float64), (n,))])
    return sp.csc_matrix((vals, (rows, cols)), shape=(n, n))


class SPDFactor:
    """``P A P^T = L D L^T`` of a sparse symmetric positive definite matrix, for repeated solves.

    Parameters
    ----------
    A : (n, n) scipy sparse matrix or array (or dense array)
        Symmetric positive definite; duplicate entries are summed. Explicit zeros are kept (a weight that is zero
        now keeps its place in the pattern) unless the pattern is unsymmetric with them.
    ordering : {"mmd", "rcm", "natural"}
        Fill-reducing order (module docstring), postordered along its elimination tree (the same fill);
        "natural" is for comparisons.

    Raises
    ------
    ValueError
        ``A`` is not square, is empty, has a NaN or infinite entry, is not symmetric, or is not positive definite
        (a pivot ``D[k] <= 0``), each named in the message.

    Notes
    -----
    :meth:`refactor` with the same pattern overwrites the arrays of :attr:`arrays` in place, so a jitted caller
    holding them sees the new factor; a new pattern replaces them (:meth:`refactor` says so).
    """

    def __init__(self, A, ordering="mmd"):
        if ordering not in ORDERINGS:
            raise ValueError(f"unknown ordering {ordering!r}: one of {', '.join(ORDERINGS)}")
        self._asked = ordering
        self._pattern = None
        self.refactor(A)

    def refactor(self, A):
        """Factor new values; the symbolic analysis is redone only when the sparsity pattern changed.

        Parameters
        ----------
        A : (n, n) sparse matrix
            As for the constructor (any size when the pattern changes).

        Returns
        -------
        bool
            True when the pattern changed: :attr:`arrays` are new arrays (re-read them), and the order too.

        Raises
        ------
        ValueError
            As the constructor. After a failed refactor the factor is unusable (:meth:`solve` raises
            RuntimeError) until a refactor succeeds.
        """
        self._valid = False  # until this factor succeeds: a failure part-way leaves no stale factor in use
        a = _canonical_csc(A)
        changed = not self._has_pattern(a)
        if changed and _transpose_index(a) is None:
            a.eliminate_zeros()  # an explicit zero without its mirror entry is no entry
            changed = not self._has_pattern(a)
        if changed:
            self._analyse(a)
        _check_symmetric(a, self._mirror)
        self._data = a.data
        self._factor(a.data)
        return changed

    def positions(self, rows, cols):
        """(k,) int64: where the entries (``rows``, ``cols``) lie in the matrix's stored values (for
        :meth:`refactor_values`); ValueError for an entry outside its pattern."""
        indptr, indices = self._pattern
        n = self.n
        keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr)) * n + indices
        want = np.asarray(cols, dtype=np.int64) * n + np.asarray(rows, dtype=np.int64)
        at = np.searchsorted(keys, want)
        if np.any(at >= keys.size) or np.any(keys[np.minimum(at, keys.size - 1)] != want):
            raise ValueError("an entry outside the matrix's pattern")
        return at

    def refactor_values(self, data):
        """Factor new values ``data`` (the stored values, in the order :meth:`positions` indexes) of the same
        pattern, with no checks of symmetry: for a solver that builds them from its own symmetric elements."""
        data = np.ascontiguousarray(data, dtype=np.float64)
        if data.shape != self._data.shape or not np.all(np.isfinite(data)):
            raise ValueError(f"the values must be {self._data.size} finite numbers")
        self._valid = False
        self._data = data
        self._factor(data)

    def solve(self, B):
        """``X = A^-1 B``.

        Parameters
        ----------
        B : (n,) or (n, m) float
            Right-hand sides (``m = 3`` is the kernel's native width; other widths go three columns at a time).

        Returns
        -------
        (n,) or (n, m) float64
            New array, the shape of ``B``.
        """
        if not self._valid:
            raise RuntimeError("the factor is unusable: its last refactor failed")
        b = np.asarray(B, dtype=np.float64)
        n = self.n
        if b.ndim not in (1, 2) or b.shape[0] != n:
            raise ValueError(f"B must have shape ({n},) or ({n}, m), got {b.shape}")
        cols = b.reshape(n, -1)
        out = np.empty(cols.shape)
        x = np.zeros((n, 3))
        work = np.empty((n, 3))  # per call, not shared: two threads may solve at once (the kernel is nogil)
        for c0 in range(0, cols.shape[1], 3):
            c1 = min(c0 + 3, cols.shape[1])
            x[:, : c1 - c0] = cols[:, c0:c1]
            x[:, c1 - c0:] = 0.0
            sn_solve3(*self.arrays, x, work)
            out[:, c0:c1] = x[:, : c1 - c0]
        return out.reshape(b.shape)

    @property
    def matrix_arrays(self):
        """``(indptr, indices, data)``: the matrix factored last, canonical CSC with both triangles (for products
        with it, e.g. :func:`vfit_engine.kernels.lbfgs.gradient`); arrays of the factor's own, not to be written."""
        return self._pattern[0], self._pattern[1], self._data

    @property
    def n(self):
        """Order of the matrix."""
        return int(self._d.shape[0])

    @property
    def nnz(self):
        """Stored values of the matrix (its pattern's entries)."""
        return int(self._data.size)

    @property
    def nnz_l(self):
        """Entries of ``L`` below its unit diagonal (the fill measure; the supernodes store more, :attr:`stored`)."""
        return self._nnz_l

    @property
    def supernodes(self):
        """Number of supernodes."""
        return int(self._sf.shape[0] - 1)

    @property
    def stored(self):
        """Values the supernodes' blocks hold: ``L``, ``D``, the blocks' unused upper parts and the zeros of
        merged supernodes."""
        return int(self._lx.shape[0])

    @property
    def ordering(self):
        """The order in use: the one asked for, or "rcm" when SuperLU failed to give "mmd"."""
        return self._ordering

    @property
    def arrays(self):
        """:data:`LDLArrays` ``(sf, rp, ri, xp, lx, d, perm)``: with ``x`` (n, 3) float64 (``B`` in, ``X`` out)
        and a scratch ``work`` (n, 3) float64, ``sn_solve3(*arrays, x, work)`` solves, also from jitted code."""
        return LDLArrays(self._sf, self._rp, self._ri, self._xp, self._lx, self._d, self._perm)

    def _has_pattern(self, a):
        return (self._pattern is not None and a.shape[0] == self.n
                and np.array_equal(a.indptr, self._pattern[0]) and np.array_equal(a.indices, self._pattern[1]))

    def _analyse(self, a):
        """Order (postordered), the upper triangle of P A P^T, its supernodes and where each value goes;
        allocate the numeric arrays."""
        mirror = _transpose_index(a)
        if mirror is None:
            raise ValueError(f"A is not symmetric: {_unmatched_entry(a)}")
        n = a.shape[0]
        perm, self._ordering = _order(a, self._asked)
        parent, _ = _etree(*_upper_triangle(a, perm)[1:])
        post = np.empty(n, dtype=np.int64)
        etree_postorder(parent, post, *(np.empty(n, dtype=np.int64) for _ in range(3)))
        perm = perm[post]
        c_index, cp, ci = _upper_triangle(a, perm)
        parent, count = _etree(cp, ci)
        sf, m = np.empty(n + 1, dtype=np.int64), np.empty(n, dtype=np.int64)
        ns = supernode_partition(parent, count, sf, m, np.empty(n, dtype=np.int64))
        sf, m = sf[:ns + 1].copy(), m[:ns].copy()
        w = np.diff(sf)
        sn_of = np.repeat(np.arange(ns, dtype=np.int64), w)
        rp = np.concatenate([[0], np.cumsum(m)]).astype(np.int64)
        xp = np.concatenate([[0], np.cumsum(m * w)]).astype(np.int64)
        ri = np.empty(rp[-1], dtype=np.int32)
        bad = supernode_rows(cp, ci, parent, sn_of, sf, rp, ri, np.empty(n, dtype=np.int64),
                             np.empty(ns, dtype=np.int64), np.empty(ns, dtype=np.int64))
        if bad >= 0:
            raise RuntimeError(f"supernode {bad}'s rows do not match its partition (a bug of the analysis)")
        dst = np.empty(ci.shape[0], dtype=np.int64)
        value_map(cp, ci, sn_of, sf, rp, ri, xp, dst)
        self._sf, self._rp, self._ri, self._xp, self._sn_of = sf, rp, ri, xp, sn_of
        self._src, self._dst = c_index, dst
        self._perm = np.ascontiguousarray(perm, dtype=np.int64)
        self._nnz_l = int(count.sum())
        self._lx = np.empty(xp[-1])
        self._d = np.empty(n)
        rows, width = int(m.max()), int(w.max())
        # scratch of sn_numeric: a row map, the descendants' lists, a transposed block, a row, a product
        self._relmap, self._head, self._link, self._ptr = (np.empty(k, dtype=np.int64) for k in (n, ns, ns, ns))
        self._tbuf, self._wrow = np.empty(int((m * w).max())), np.empty(rows)
        self._relb, self._wbuf = np.empty(rows, dtype=np.int64), np.empty(rows * width)
        self._mirror = mirror
        self._pattern = (a.indptr.copy(), a.indices.copy())

    def _factor(self, data):
        k = sn_numeric(self._sf, self._rp, self._ri, self._xp, self._lx, self._d, data, self._src, self._dst,
                       self._sn_of, self._relmap, self._head, self._link, self._ptr, self._tbuf, self._wrow,
                       self._relb, self._wbuf)
        self._valid = k < 0
        if k >= 0:
            raise ValueError(f"A is not positive definite: pivot {k} of its LDL^T (row {self._perm[k]} of A, "
                             f"order {self._ordering}) is {self._d[k]:.6g}")


def _upper_triangle(a, perm):
    """(c_index, cp, ci): the entries of canonical CSC ``a`` that make up C = P A P^T's upper triangle, in C's CSC
    order (column, then row), and that triangle's pattern (int64)."""
    n = a.shape[0]
    pinv = np.empty(n, dtype=np.int64)
    pinv[perm] = np.arange(n)
    row = pinv[a.indices]
    col = pinv[np.repeat(np.arange(n), np.diff(a.indptr))]
    keep = np.flatnonzero(row <= col)
    c_index = keep[np.lexsort((row[keep], col[keep]))]
    cp = np.concatenate([[0], np.cumsum(np.bincount(col[c_index], minlength=n))]).astype(np.int64)
    return c_index.astype(np.int64), cp, np.ascontiguousarray(row[c_index])


def _etree(cp, ci):
    """(parent, count): the elimination tree of C and its columns' counts below the diagonal."""
    n = cp.shape[0] - 1
    parent, count = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    ldl_symbolic(cp, ci, parent, count, np.empty(n, dtype=np.int64))
    return parent, count


def _canonical_csc(A):
    """A float64 CSC copy of ``A`` with summed duplicates and sorted indices; checks shape and finiteness."""
    if np.iscomplexobj(A.data if sp.issparse(A) else A):
        raise ValueError("A must be real")
    a = sp.csc_matrix(A, dtype=np.float64, copy=True)
    if a.shape[0] != a.shape[1]:
        raise ValueError(f"A must be square, got shape {a.shape}")
    if a.shape[0] == 0:
        raise ValueError("A is empty (0 x 0)")
    a.sum_duplicates()
    if not np.isfinite(a.data).all():
        raise ValueError("A has NaN or infinite entries")
    return a


def _transpose_index(a):
    """For each stored entry (i, j) of a canonical CSC ``a``, the position of its entry (j, i); None when one
    is missing (an unsymmetric pattern)."""
    n = a.shape[0]
    col = np.repeat(np.arange(n, dtype=np.int64), np.diff(a.indptr))
    row = a.indices.astype(np.int64)
    key = col * n + row  # ascending: canonical CSC is column-major with sorted rows
    mirror_key = row * n + col
    pos = np.minimum(np.searchsorted(key, mirror_key), key.shape[0] - 1)
    return pos if np.array_equal(key[pos], mirror_key) else None


def _unmatched_entry(a):
    """Text naming one stored entry (i, j) of ``a`` without an entry (j, i)."""
    coo = a.tocoo()
    mirrored = set(zip(coo.col.tolist(), coo.row.tolist()))
    i, j = next((i, j) for i, j in zip(coo.row.tolist(), coo.col.tolist()) if (i, j) not in mirrored)
    return f"entry ({i}, {j}) is stored, ({j}, {i}) is not"


def _check_symmetric(a, mirror):
    diff = np.abs(a.data - a.data[mirror])
    worst = int(np.argmax(diff)) if diff.size else 0
    if diff.size and diff[worst] > SYMMETRY_RTOL * np.abs(a.data).max():
        i = int(a.indices[worst])
        j = int(np.searchsorted(a.indptr, worst, side="right") - 1)
        raise ValueError(f"A is not symmetric: A[{i}, {j}] = {a.data[worst]:.17g} but "
                         f"A[{j}, {i}] = {a.data[mirror[worst]]:.17g}")


def _order(a, asked):
    """(perm, name): ``perm[k]`` is the row of ``A`` placed at row ``k``."""
    n = a.shape[0]
    if asked == "mmd":
        try:
            lu = splu(a, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
            # perm_c maps an old column to its new place; inverted, it lists the old index of each new one
            return np.argsort(lu.perm_c).astype(np.int64), "mmd"
        except RuntimeError:  # SuperLU's "factor is exactly singular" and kin: a non-SPD A fails later, named
            asked = "rcm"
    if asked == "rcm":
        return np.asarray(reverse_cuthill_mckee(a.tocsr(), symmetric_mode=True), dtype=np.int64), "rcm"
    return np.arange(n, dtype=np.int64), "natural"
