"""Sparse LDL^T: the kernels against the slow references of naive_ldl.py (and the supernodal factor against the
simplicial one and a dense LDL^T), SPDFactor against scipy's spsolve.

Matrices are what the projective-dynamics global step solves: seeded random graph Laplacians (random springs with
random weights) plus a positive diagonal (the masses over h^2), and a real cloth grid's springs.
"""
import numba
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

import naive_ldl
import vfit_engine.sim.linear as linear
from vfit_engine.kernels import supernodal_analysis
from vfit_engine.kernels.sparse_ldl import ldl_numeric, ldl_solve3, ldl_symbolic
from vfit_engine.kernels.supernodal_analysis import etree_postorder
from vfit_engine.kernels.supernodal_ldl import sn_solve3
from vfit_engine.sim.linear import SPDFactor, spring_laplacian
from vfit_engine.sim.springs import BEND, build_springs, grid_polygons, vertex_masses

TOL = 1e-10


def random_spd(n, seed, springs_per_vertex=3.0, components=1):
    """Random springs (weights 0.1 .. 10) inside ``components`` disjoint vertex groups, plus a diagonal 0.01 .. 1.

    Returns
    -------
    (n, n) scipy.sparse.csc_matrix
    """
    rng = np.random.default_rng(seed)
    group = rng.integers(0, components, n)
    pairs = rng.integers(0, n, size=(int(springs_per_vertex * n) + 1, 2))
    pairs = pairs[(pairs[:, 0] != pairs[:, 1]) & (group[pairs[:, 0]] == group[pairs[:, 1]])]
    return spring_laplacian(pairs, rng.uniform(0.1, 10.0, len(pairs)), n, diagonal=rng.uniform(0.01, 1.0, n))


def cloth_matrix(nx, h=1.0 / 60, seed=None):
    """A = M / h^2 + sum_s k_s (e_i - e_j)(e_i - e_j)^T of an nx x nx grid's structural, shear and bend springs
    (cotton-like 0.12 kg/m^2, k 5000 N/m, bend 500 N/m: issue 32's measuring matrices); with a seed, each
    spring's k is scaled by a random 0.5 .. 2 (new values, the same pattern)."""
    pos, fv, fo = grid_polygons(nx, nx)
    springs = build_springs(fv, fo, pos)
    mass = vertex_masses(fv, fo, pos, 0.12)
    k = np.where(springs.type == BEND, 500.0, 5000.0)
    if seed is not None:
        k *= np.random.default_rng(seed).uniform(0.5, 2.0, k.shape[0])
    return spring_laplacian(springs.indices, k, nx * nx, diagonal=mass / h ** 2)


def rel_err(x, ref):
    return np.linalg.norm(x - ref) / np.linalg.norm(ref)


def upper_of_permuted(a, perm):
    """(cp, ci, cx, dense C) of C = P A P^T's upper triangle, by scipy."""
    c = a[perm][:, perm].toarray()
    up = sp.csc_matrix(np.triu(c))
    up.sort_indices()
    return up.indptr.astype(np.int64), up.indices.astype(np.int64), up.data.copy(), c


# -- the kernels against the references ----------------------------------------------------------

@pytest.mark.parametrize("n, seed", [(1, 0), (12, 1), (60, 2), (150, 3)])
def test_symbolic_kernel_matches_structural_elimination(n, seed):
    a = random_spd(n, seed)
    perm = np.random.default_rng(seed).permutation(n)
    cp, ci, _, c = upper_of_permuted(a, perm)
    parent, count = np.empty(n, np.int64), np.empty(n, np.int64)
    ldl_symbolic(cp, ci, parent, count, np.empty(n, np.int64))
    ref_parent, ref_count = naive_ldl.structural_factor(c != 0)
    np.testing.assert_array_equal(parent, ref_parent)
    np.testing.assert_array_equal(count, ref_count)
    assert n < 60 or count.sum() > (np.count_nonzero(c) - n) // 2  # a random order fills in: the test sees fill


@pytest.mark.parametrize("n, seed", [(1, 0), (9, 1), (40, 2), (90, 3)])
def test_numeric_kernel_matches_dense_ldl(n, seed):
    a = random_spd(n, seed)
    perm = np.random.default_rng(seed + 10).permutation(n)
    cp, ci, cx, c = upper_of_permuted(a, perm)
    parent, count = np.empty(n, np.int64), np.empty(n, np.int64)
    ldl_symbolic(cp, ci, parent, count, np.empty(n, np.int64))
    lp = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    li, lx, d = np.empty(lp[-1], np.int64), np.empty(lp[-1]), np.empty(n)
    scratch = [np.zeros(n)] + [np.empty(n, np.int64) for _ in range(3)]
    assert ldl_numeric(cp, ci, cx, lp, parent, li, lx, d, *scratch) == -1
    L = np.eye(n)
    for j in range(n):
        assert np.all(np.diff(li[lp[j]:lp[j + 1]]) > 0)  # rows ascending, no duplicates
        L[li[lp[j]:lp[j + 1]], j] = lx[lp[j]:lp[j + 1]]
    ref_L, ref_d = naive_ldl.dense_ldl(c)
    np.testing.assert_allclose(d, ref_d, rtol=1e-12)
    np.testing.assert_allclose(L, ref_L, rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("c, k", [([[-1.0, 0.0], [0.0, 2.0]], 0),
                                  ([[1.0, 2.0], [2.0, 1.0]], 1),  # positive diagonal, indefinite
                                  ([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 1.0]], 2)])  # singular
def test_numeric_kernel_returns_the_first_nonpositive_pivot(c, k):
    cp, ci, cx, _ = upper_of_permuted(sp.csc_matrix(np.array(c)), np.arange(len(c)))
    n = len(c)
    parent, count = np.empty(n, np.int64), np.empty(n, np.int64)
    ldl_symbolic(cp, ci, parent, count, np.empty(n, np.int64))
    lp = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    scratch = [np.zeros(n)] + [np.empty(n, np.int64) for _ in range(3)]
    assert ldl_numeric(cp, ci, cx, lp, parent, np.empty(lp[-1], np.int64), np.empty(lp[-1]), np.empty(n),
                       *scratch) == k


# -- the supernodal factor ------------------------------------------------------------------------

def dense_factor(f):
    """(L, d, C) of an SPDFactor: its supernodal blocks unpacked into a dense unit lower L of C = P A P^T (the
    blocks' unused upper parts left out), and C rebuilt from the factor's own order."""
    sf, rp, ri, xp, lx, d, perm = f.arrays
    n = f.n
    L = np.eye(n)
    for s in range(sf.size - 1):
        w, rows = sf[s + 1] - sf[s], ri[rp[s]:rp[s + 1]]
        block = lx[xp[s]:xp[s + 1]].reshape(rows.size, w)
        for c in range(w):
            L[rows[c + 1:], sf[s] + c] = block[c + 1:, c]
    return L, d.copy()


def dense_spd(n, seed):
    """A dense SPD matrix (every supernode as wide and long as the cut allows: the BLAS paths and their chunks)."""
    g = np.random.default_rng(seed).normal(size=(n, n))
    return sp.csc_matrix(g @ g.T / n + np.eye(n))


def test_postorder_puts_children_first_and_subtrees_together():
    rng = np.random.default_rng(30)
    n = 200
    parent = np.array([rng.integers(j + 1, n) if j < n - 1 and rng.random() < 0.9 else -1 for j in range(n)])
    post = np.empty(n, np.int64)
    etree_postorder(parent, post, *(np.empty(n, np.int64) for _ in range(3)))
    assert sorted(post.tolist()) == list(range(n))
    place = np.empty(n, np.int64)
    place[post] = np.arange(n)
    size = np.ones(n, np.int64)
    for j in range(n):  # subtree sizes (a parent is numbered after its children)
        if parent[j] >= 0:
            size[parent[j]] += size[j]
    for j in range(n):
        assert parent[j] < 0 or place[j] < place[parent[j]]
        # the subtree of j is the block of size[j] places ending at j's place
        block = set(post[place[j] - size[j] + 1:place[j] + 1].tolist())
        v = set()
        for i in range(n):
            k = i
            while k >= 0 and k != j:
                k = parent[k]
            if k == j:
                v.add(i)
        assert block == v


@pytest.mark.parametrize("case", ["random 1", "random 90", "random 400", "cloth 24", "dense 300", "components"])
def test_supernodal_factor_matches_a_dense_ldl_and_holds_the_pattern(case):
    kind, size = case.split()[0], (case.split() + ["0"])[1]
    a = {"random": lambda: random_spd(int(size), 31), "cloth": lambda: cloth_matrix(int(size)),
         "dense": lambda: dense_spd(int(size), 32), "components": lambda: random_spd(300, 33, components=7)}[kind]()
    f = SPDFactor(a)
    perm = f.arrays.perm
    c = a[perm][:, perm].toarray()
    L, d = dense_factor(f)
    chol = np.linalg.cholesky(c)  # C = (chol / diag) diag^2 (chol / diag)^T
    np.testing.assert_allclose(d, np.diag(chol) ** 2, rtol=1e-10)
    np.testing.assert_allclose(L, chol / np.diag(chol), rtol=1e-9, atol=1e-11)
    structure = naive_ldl.structural_factor(c != 0)[1]
    assert f.nnz_l == structure.sum()
    widths = np.diff(f.arrays.sf)
    assert widths.max() <= supernodal_analysis.MAX_WIDTH and f.stored >= f.nnz_l + f.n
    if kind == "dense":  # one run of 300 columns, cut into the widest supernodes from the first column on
        w = supernodal_analysis.MAX_WIDTH
        assert widths.tolist() == [w] * (300 // w) + [300 % w]


@pytest.mark.parametrize("case", ["cloth", "random"])
def test_supernodes_are_subtrees_within_the_relaxation_bounds(case):
    a = cloth_matrix(24) if case == "cloth" else random_spd(400, 39)
    f = SPDFactor(a)
    sf, rp = f.arrays.sf, f.arrays.rp
    cp, ci, _, _ = upper_of_permuted(a, f.arrays.perm)
    n = f.n
    parent, count = np.empty(n, np.int64), np.empty(n, np.int64)
    ldl_symbolic(cp, ci, parent, count, np.empty(n, np.int64))
    fundamental = 1 + np.count_nonzero((parent[:-1] != np.arange(1, n)) | (count[:-1] != count[1:] + 1))
    assert sf.size - 1 < fundamental  # the relaxation merged some
    for s in range(sf.size - 1):
        cols = np.arange(sf[s], sf[s + 1])
        w, m = cols.size, rp[s + 1] - rp[s]
        assert w <= supernodal_analysis.MAX_WIDTH
        assert np.all((parent[cols[:-1]] > cols[:-1]) & (parent[cols[:-1]] <= cols[-1]))  # a subtree's columns
        size = w * m - w * (w - 1) // 2
        zeros = (size - (count[cols] + 1).sum()) / size
        bounds = zip(supernodal_analysis.RELAX_WIDTH, supernodal_analysis.RELAX_ZEROS)
        allowed = max([z for wmax, z in bounds if w <= wmax], default=0.0)
        assert zeros == 0 or zeros <= allowed + 1e-12, (s, w, zeros)


def test_supernodal_and_simplicial_factors_agree_on_the_same_order():
    """The simplicial kernels (the reference, and the benchmark's old path) on the supernodal factor's order."""
    a = cloth_matrix(20, seed=34)
    f = SPDFactor(a)
    n = f.n
    cp, ci, cx, _ = upper_of_permuted(a, f.arrays.perm)
    parent, count = np.empty(n, np.int64), np.empty(n, np.int64)
    ldl_symbolic(cp, ci, parent, count, np.empty(n, np.int64))
    lp = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    li, lx, d = np.empty(lp[-1], np.int64), np.empty(lp[-1]), np.empty(n)
    assert ldl_numeric(cp, ci, cx, lp, parent, li, lx, d, np.zeros(n), *(np.empty(n, np.int64) for _ in range(3))) < 0
    np.testing.assert_allclose(f.arrays.d, d, rtol=1e-12)
    L, _ = dense_factor(f)
    simplicial = np.eye(n)
    for j in range(n):
        simplicial[li[lp[j]:lp[j + 1]], j] = lx[lp[j]:lp[j + 1]]
    np.testing.assert_allclose(L, simplicial, rtol=1e-10, atol=1e-13)
    b = np.random.default_rng(35).normal(size=(n, 3))
    x_sn, x_simp = b.copy(), b.copy()
    sn_solve3(*f.arrays, x_sn, np.empty_like(b))
    ldl_solve3(lp, li, lx, d, f.arrays.perm, x_simp, np.empty_like(b))
    assert rel_err(x_sn, x_simp) < 1e-12 and rel_err(x_sn, spsolve(a, b)) < TOL


def test_a_value_refactor_of_wide_supernodes_is_a_fresh_factor():
    """refactor_values on a dense matrix (every update and block solve by BLAS, in chunks) equals a fresh
    factor of the new values, and solves them."""
    a = dense_spd(300, 36)
    f = SPDFactor(a)
    a2 = dense_spd(300, 37)
    f.refactor_values(a2.data)  # same (full) pattern, so the same value order
    fresh = SPDFactor(a2)
    for got, want in zip(f.arrays, fresh.arrays):
        np.testing.assert_array_equal(got, want)
    b = np.random.default_rng(38).normal(size=(300, 3))
    assert rel_err(f.solve(b), np.linalg.solve(a2.toarray(), b)) < TOL


# -- SPDFactor against spsolve ---------------------------------------------------------------------

@pytest.mark.parametrize("n", [1, 2, 5, 30, 120, 500])
@pytest.mark.parametrize("seed", [0, 1])
def test_solve_matches_spsolve(n, seed):
    a = random_spd(n, seed)
    f = SPDFactor(a)
    assert f.ordering == "mmd" and f.n == n
    rng = np.random.default_rng(seed + 100)
    b3, b1 = rng.normal(size=(n, 3)), rng.normal(size=n)
    x3, x1 = f.solve(b3), f.solve(b1)
    assert x3.shape == (n, 3) and x1.shape == (n,)
    assert rel_err(x3, spsolve(a, b3).reshape(n, 3)) < TOL
    assert rel_err(x1, spsolve(a, b1)) < TOL
    assert rel_err(a @ x3, b3) < TOL  # a residual too: spsolve is a reference, not the truth


@pytest.mark.parametrize("case", ["disconnected", "diagonal", "wide rhs"])
def test_solve_special_matrices_and_widths(case):
    n = 200
    if case == "disconnected":
        a = random_spd(n, 7, components=5)
        assert sp.csgraph.connected_components(a)[0] >= 5
    elif case == "diagonal":
        a = sp.diags(np.random.default_rng(8).uniform(0.5, 2.0, n)).tocsc()
    else:
        a = random_spd(n, 9)
    f = SPDFactor(a)
    if case == "diagonal":
        assert f.nnz_l == 0
    width = 5 if case == "wide rhs" else 3  # 5 = one full pass of three columns and a padded one
    b = np.random.default_rng(10).normal(size=(n, width))
    assert rel_err(f.solve(b), spsolve(a, b)) < TOL
    assert rel_err(f.solve(b[:, :1]), spsolve(a, b[:, :1]).reshape(n, 1)) < TOL


def test_cloth_grid_solves_and_minimum_degree_fills_less():
    a = cloth_matrix(30)
    b = np.random.default_rng(11).normal(size=(900, 3))
    ref = spsolve(a, b)
    fills = {}
    for ordering in ("mmd", "rcm", "natural"):
        f = SPDFactor(a, ordering=ordering)
        assert f.ordering == ordering
        assert rel_err(f.solve(b), ref) < TOL
        fills[ordering] = f.nnz_l
    # measured 28,477 / 36,755 / 51,386: the order is worth having, and a wrongly inverted perm_c would lose it
    assert fills["mmd"] < 0.7 * fills["natural"] and fills["mmd"] < fills["rcm"], fills


def test_the_input_matrix_is_left_as_given():
    a = random_spd(50, 12).tocoo()
    a = sp.coo_matrix((np.r_[a.data, 1.0], (np.r_[a.row, 3], np.r_[a.col, 3])), shape=a.shape)  # a duplicate
    before = (a.data.copy(), a.row.copy(), a.col.copy())
    f = SPDFactor(a)
    for got, want in zip((a.data, a.row, a.col), before):
        np.testing.assert_array_equal(got, want)
    b = np.ones((50, 3))
    assert rel_err(f.solve(b), spsolve(a.tocsc(), b)) < TOL


# -- refactor ------------------------------------------------------------------------------------------

def test_refactor_with_new_values_equals_a_fresh_factor_in_the_same_arrays():
    a = cloth_matrix(12)
    f = SPDFactor(a)
    held = f.arrays
    a2 = cloth_matrix(12, h=1.0 / 90, seed=13)
    assert not np.array_equal(a2.data, a.data)
    assert f.refactor(a2) is False
    fresh = SPDFactor(a2)
    for name, got, want in zip(held._fields, f.arrays, fresh.arrays):
        assert got is getattr(held, name)  # overwritten in place: a jitted caller holding them sees the factor
        np.testing.assert_array_equal(got, want)
    b = np.random.default_rng(14).normal(size=(a.shape[0], 3))
    np.testing.assert_array_equal(f.solve(b), fresh.solve(b))
    assert rel_err(f.solve(b), spsolve(a2, b)) < TOL


def test_refactor_with_a_new_pattern_redoes_the_analysis():
    a = random_spd(80, 15)
    f = SPDFactor(a)
    a2 = random_spd(80, 16)
    assert f.refactor(a2) is True
    b = np.random.default_rng(17).normal(size=(80, 3))
    assert rel_err(f.solve(b), spsolve(a2, b)) < TOL
    assert f.refactor(random_spd(30, 18)) is True and f.n == 30  # a new size is a new pattern


def test_explicit_zeros_keep_their_place_in_the_pattern():
    n = 40
    rng = np.random.default_rng(19)
    pairs = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    w = rng.uniform(1.0, 2.0, n - 1)
    diag = rng.uniform(0.5, 1.0, n)
    f = SPDFactor(spring_laplacian(pairs, w, n, diagonal=diag))
    w[5] = 0.0  # a spring switched off: its explicit zeros stay, the pattern too
    a2 = spring_laplacian(pairs, w, n, diagonal=diag)
    assert np.count_nonzero(a2.data == 0.0) == 2
    assert f.refactor(a2) is False
    assert rel_err(f.solve(np.ones(n)), spsolve(a2, np.ones(n))) < TOL
    one_sided = sp.csc_matrix((np.r_[a2.tocoo().data, 0.0], (np.r_[a2.tocoo().row, 0], np.r_[a2.tocoo().col, 9])))
    assert rel_err(SPDFactor(one_sided).solve(np.ones(n)), spsolve(a2, np.ones(n))) < TOL  # a zero, no mirror


# -- from jitted code ------------------------------------------------------------------------------

@numba.njit
def _iterate(sf, rp, ri, xp, lx, d, perm, b, x, work, iterations):
    """A projective-dynamics-like loop: each right-hand side depends on the previous solution."""
    x[:] = 0.0
    for _ in range(iterations):
        for i in range(x.shape[0]):
            for c in range(3):
                x[i, c] = b[i, c] + 0.5 * x[i, c]
        sn_solve3(sf, rp, ri, xp, lx, d, perm, x, work)


@numba.njit
def _solve_packed(factor, x, work):
    """The factor passed whole, as the named tuple of SPDFactor.arrays."""
    sn_solve3(factor.sf, factor.rp, factor.ri, factor.xp, factor.lx, factor.d, factor.perm, x, work)


def test_the_kernel_solve_called_from_jitted_code_matches_the_class():
    a = cloth_matrix(15)
    f = SPDFactor(a)
    b = np.random.default_rng(20).normal(size=(a.shape[0], 3))
    x, work = np.empty_like(b), np.empty_like(b)
    _iterate(*f.arrays, b, x, work, 4)
    ref = np.zeros_like(b)
    for _ in range(4):
        ref = f.solve(b + 0.5 * ref)
    np.testing.assert_array_equal(x, ref)
    _iterate(*f.arrays, b, x, work, 1)
    assert rel_err(x, spsolve(a, b)) < TOL
    packed = b.copy()
    _solve_packed(f.arrays, packed, work)
    np.testing.assert_array_equal(packed, x)


# -- bad input -------------------------------------------------------------------------------------

def test_a_matrix_that_is_not_positive_definite_raises_and_a_good_refactor_recovers():
    a = random_spd(30, 21).tolil()
    a[7, 7] = -1.0
    with pytest.raises(ValueError, match=r"not positive definite: pivot \d+ .*row 7 of A"):
        SPDFactor(a.tocsc())
    good = random_spd(30, 21)
    f = SPDFactor(good)
    indefinite = good.copy()
    indefinite.data = -indefinite.data
    with pytest.raises(ValueError, match="not positive definite"):
        f.refactor(indefinite)
    with pytest.raises(RuntimeError, match="unusable"):
        f.solve(np.ones(30))
    f.refactor(good)
    assert rel_err(f.solve(np.ones(30)), spsolve(good, np.ones(30))) < TOL
    unsymmetric = random_spd(30, 22).tolil()
    unsymmetric[3, 4] += 1.0
    with pytest.raises(ValueError, match="not symmetric"):
        f.refactor(unsymmetric)  # any failed refactor: the old factor is not used for the new matrix
    with pytest.raises(RuntimeError, match="unusable"):
        f.solve(np.ones(30))


@pytest.mark.parametrize("a, message", [
    (sp.csc_matrix(np.ones((3, 4))), "must be square"),
    (sp.csc_matrix((0, 0)), "empty"),
    (sp.csc_matrix(np.array([[2.0, 1.0], [1.5, 2.0]])), r"not symmetric: A\[\d, \d\] = 1\.5"),
    (sp.csc_matrix(np.array([[2.0, 1.0], [0.0, 2.0]])), r"not symmetric: entry \(0, 1\) is stored"),
    (sp.csc_matrix(np.array([[2.0, np.nan], [np.nan, 2.0]])), "NaN"),
    (sp.csc_matrix(np.array([[2.0, 1j], [-1j, 2.0]])), "real"),
])
def test_bad_matrices_raise_naming_the_problem(a, message):
    with pytest.raises(ValueError, match=message):
        SPDFactor(a)


def test_bad_arguments_raise():
    f = SPDFactor(random_spd(10, 22))
    with pytest.raises(ValueError, match=r"shape \(10,\) or \(10, m\)"):
        f.solve(np.ones((9, 3)))
    with pytest.raises(ValueError, match="unknown ordering"):
        SPDFactor(random_spd(10, 22), ordering="amd")


def test_minimum_degree_falls_back_to_reverse_cuthill_mckee_when_superlu_fails(monkeypatch):
    def failing_splu(*args, **kwargs):
        raise RuntimeError("Factor is exactly singular")

    monkeypatch.setattr(linear, "splu", failing_splu)
    a = cloth_matrix(10)
    f = SPDFactor(a)
    assert f.ordering == "rcm"
    b = np.ones((100, 3))
    assert rel_err(f.solve(b), spsolve(a, b)) < TOL


def test_spring_laplacian_matches_the_dense_sum():
    rng = np.random.default_rng(23)
    pairs = rng.integers(0, 12, size=(30, 2))
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]  # repeated pairs kept: their weights add
    w = rng.uniform(0.0, 3.0, len(pairs))
    lap = spring_laplacian(pairs, w, 15)
    np.testing.assert_allclose(lap.toarray(), naive_ldl.laplacian(15, pairs, w), rtol=1e-14, atol=1e-14)
    diag = rng.uniform(1.0, 2.0, 15)
    np.testing.assert_allclose(spring_laplacian(pairs, w, 15, diagonal=diag).toarray(),
                               naive_ldl.laplacian(15, pairs, w) + np.diag(diag), rtol=1e-14, atol=1e-14)
    assert np.all(lap.diagonal() >= 0) and (lap.tocsc()[14, 14] == 0)  # vertex 14 is in no spring
    assert lap.tocsc().indices[lap.indptr[14]:lap.indptr[15]].tolist() == [14]  # but its diagonal is stored


def test_refactor_values_at_positions_is_a_fresh_factor():
    """New values written through positions() and refactor_values() factor as a fresh SPDFactor of the matrix."""
    from scipy.sparse.linalg import spsolve
    from vfit_engine.sim.linear import SPDFactor

    rng = np.random.default_rng(7)
    n = 40
    i = rng.integers(0, n, 120)
    j = rng.integers(0, n, 120)
    keep = i != j
    i, j = i[keep], j[keep]

    def matrix(w):
        lap = sp.coo_matrix((np.concatenate([-w, -w]), (np.concatenate([i, j]), np.concatenate([j, i]))), (n, n))
        d = -np.asarray(lap.sum(axis=1)).ravel() + 1.0
        return (lap + sp.diags(d)).tocsc(), d

    a, _ = matrix(rng.uniform(1, 2, i.size))
    f = SPDFactor(a)
    w2 = rng.uniform(0.1, 5, i.size)
    a2, d2 = matrix(w2)
    data = np.zeros(f.nnz)
    np.add.at(data, f.positions(i, j), -w2)
    np.add.at(data, f.positions(j, i), -w2)
    data[f.positions(np.arange(n), np.arange(n))] += d2
    f.refactor_values(data)
    b = rng.normal(size=(n, 3))
    np.testing.assert_allclose(f.solve(b), spsolve(a2, b), rtol=1e-10, atol=1e-12)
    present = set(zip(i.tolist(), j.tolist())) | set(zip(j.tolist(), i.tolist()))
    absent = next((r, c) for r in range(n) for c in range(n) if r != c and (r, c) not in present)
    with pytest.raises(ValueError):
        f.positions([absent[0]], [absent[1]])
