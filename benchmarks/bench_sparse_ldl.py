"""Benchmark of the sparse LDL^T of the projective-dynamics global step: the supernodal factor against the
simplicial one it replaced (old path and new in the same run) and scipy's SuperLU.

The matrices are the ones the solver factors (``SolverPD.matrix()``, cotton, h = 1/60 s, a sphere collider):
the shared ``female_casualsuit01`` (2,197 vertices; a 47 x 47 grid when ../shared is absent) and the 100 x 100
sphere-drape grid (10,000 vertices). Each refactor gets new values in the same pattern, alternating between the
matrix and one with its couplings weakened (:func:`new_values`, as the solver's band weights do). Times are medians
of CPU time (``time.process_time``: the machine is shared; old and new called in turn), in ms:

  * old: the simplicial up-looking LDL^T (``kernels/sparse_ldl.py``) on SuperLU's MMD order, as SPDFactor did
    before issue 32's supernodes: refactor = gathering C's values and ``ldl_numeric``; solve = ``ldl_solve3``;
  * new: ``SPDFactor.refactor_values`` (the solver's path: scatter and supernodal factor) and ``sn_solve3`` on
    the factor's arrays (what the jitted frame loop calls), three right-hand sides;
  * analyse: ``SPDFactor(A)``, the first factor of a pattern (checks, MMD order from a SuperLU LU, postorder,
    supernodes, numeric factor);
  * scipy: ``splu`` with the same MMD order (symmetric mode, no pivoting): factor and ``lu.solve`` of (n, 3).

Usage: NUMBA_NUM_THREADS=1 python benchmarks/bench_sparse_ldl.py [--repeat 15] [--solve-repeat 41] [--json]
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

GARMENT = (Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments" / "female_casualsuit01"
           / "female_casualsuit01.obj")


def cpu_ms(fn, repeat):
    """Median CPU time of ``repeat`` calls of ``fn()``, in milliseconds."""
    return paired_cpu_ms([fn], repeat)[0]


def paired_cpu_ms(fns, repeat):
    """Median CPU times (ms) of ``repeat`` calls of each of ``fns``, called in turn (old, new, old, ...): on a
    shared machine both see the same load."""
    times = [[] for _ in fns]
    for _ in range(repeat):
        for fn, out in zip(fns, times):
            t = time.process_time()
            fn()
            out.append(time.process_time() - t)
    return [1000 * float(np.median(t)) for t in times]


def solver_matrix(polygons):
    """SolverPD's global matrix of a cloth ``(face_verts, face_offsets, rest_pos)``, cotton, a sphere collider."""
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_pd import SolverPD
    from vfit_engine.sim.solver_settings import PDSettings

    fv, fo, pos = polygons
    model = Model.from_polygons(fv, fo, pos, "cotton")
    solver = SolverPD(model, PDSettings(), spheres=np.array([[0.0, 0.0, 0.0, 0.25]]))
    solver.init_state(1.0 / 60)
    return solver.matrix().tocsc()


def grid(nx):
    from vfit_engine.sim.springs import grid_polygons

    pos, fv, fo = grid_polygons(nx, nx, 1.0, 1.0)
    return f"grid {nx} x {nx}", (fv, fo, pos)


def suit():
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.units import LENGTH_UNITS

    g = load_garment(str(GARMENT))
    mesh = g.mesh
    pos = np.asarray(mesh.verts, dtype=np.float64) * LENGTH_UNITS[g.units]
    return GARMENT.stem, (np.asarray(mesh.face_verts, np.int64), np.asarray(mesh.face_offsets, np.int64), pos)


def new_values(a, seed):
    """``a`` with each symmetric pair off the diagonal scaled by a random 0.3 .. 1 (a band's weight going down
    to ``PDSettings.band_weight``; the diagonal kept, so it stays diagonally dominant, SPD): the same pattern."""
    u = np.random.default_rng(seed).uniform(0.0, 1.0, a.shape[0])
    rows, cols = a.indices, np.repeat(np.arange(a.shape[0]), np.diff(a.indptr))
    out = a.copy()
    out.data = np.where(rows == cols, a.data, a.data * (0.3 + 0.7 * np.modf(u[rows] + u[cols])[0]))
    return out


class Simplicial:
    """The old path: the simplicial kernels on SuperLU's MMD order (not postordered), as SPDFactor was."""

    def __init__(self, a):
        from scipy.sparse.linalg import splu

        from vfit_engine.kernels.sparse_ldl import ldl_symbolic

        n = a.shape[0]
        lu = splu(a, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
        self.perm = np.argsort(lu.perm_c).astype(np.int64)
        pinv = np.empty(n, np.int64)
        pinv[self.perm] = np.arange(n)
        row, col = pinv[a.indices], pinv[np.repeat(np.arange(n), np.diff(a.indptr))]
        keep = np.flatnonzero(row <= col)
        self.c_index = keep[np.lexsort((row[keep], col[keep]))]
        self.cp = np.concatenate([[0], np.cumsum(np.bincount(col[self.c_index], minlength=n))]).astype(np.int64)
        self.ci = np.ascontiguousarray(row[self.c_index])
        self.cx = np.empty(self.ci.size)
        self.parent, count = np.empty(n, np.int64), np.empty(n, np.int64)
        self.scratch = [np.empty(n, np.int64) for _ in range(3)]
        ldl_symbolic(self.cp, self.ci, self.parent, count, self.scratch[0])
        self.lp = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
        self.li, self.lx, self.d = np.empty(self.lp[-1], np.int64), np.empty(self.lp[-1]), np.empty(n)
        self.y = np.zeros(n)

    def refactor(self, data):
        from vfit_engine.kernels.sparse_ldl import ldl_numeric

        np.take(data, self.c_index, out=self.cx)
        if ldl_numeric(self.cp, self.ci, self.cx, self.lp, self.parent, self.li, self.lx, self.d, self.y,
                       *self.scratch) >= 0:
            raise RuntimeError("the simplicial factor failed")

    def solve3(self, x, work):
        from vfit_engine.kernels.sparse_ldl import ldl_solve3

        ldl_solve3(self.lp, self.li, self.lx, self.d, self.perm, x, work)


def measure(name, a, repeat, solve_repeat):
    from scipy.sparse.linalg import splu

    from vfit_engine.kernels.supernodal_ldl import sn_solve3
    from vfit_engine.sim.linear import SPDFactor

    a2 = new_values(a, 1)
    n = a.shape[0]
    b = np.random.default_rng(0).normal(size=(n, 3))
    x, work = np.empty_like(b), np.empty_like(b)
    old, new = Simplicial(a), SPDFactor(a)
    row = dict(matrix=name, n=n, nnz_a=int(a.nnz), old_nnz_l=int(old.lp[-1]), new_nnz_l=new.nnz_l,
               new_stored=new.stored, supernodes=new.supernodes)
    row["analyse_ms"] = cpu_ms(lambda: SPDFactor(a), max(3, repeat // 3))
    datas = (a.data, a2.data)
    turns = [iter(range(10 ** 9)), iter(range(10 ** 9))]
    row["old_refactor_ms"], row["new_refactor_ms"] = paired_cpu_ms(
        [lambda: old.refactor(datas[next(turns[0]) % 2]), lambda: new.refactor_values(datas[next(turns[1]) % 2])],
        repeat)

    def solve(label):
        x[:] = b
        if label == "old":
            old.solve3(x, work)
        else:
            sn_solve3(*new.arrays, x, work)

    row["old_solve3_ms"], row["new_solve3_ms"] = paired_cpu_ms([lambda: solve("old"), lambda: solve("new")],
                                                               solve_repeat)
    for label, factor in (("old", old), ("new", new)):
        factor.refactor(a2.data) if label == "old" else factor.refactor_values(a2.data)
        solve(label)
        row[f"{label}_residual"] = float(np.linalg.norm(a2 @ x - b) / np.linalg.norm(b))
    kwargs = dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    row["splu_factor_ms"] = cpu_ms(lambda: splu(a, **kwargs), max(3, repeat // 3))
    lu = splu(a, **kwargs)
    row["splu_solve3_ms"] = cpu_ms(lambda: lu.solve(b), solve_repeat)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=15, help="runs of each factor timing")
    ap.add_argument("--solve-repeat", type=int, default=41, help="runs of each solve timing")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()

    t = time.perf_counter()
    from vfit_engine.sim.linear import SPDFactor, spring_laplacian  # imports numba and the kernels' modules

    import_s = time.perf_counter() - t
    t = time.perf_counter()
    SPDFactor(spring_laplacian([[0, 1], [1, 2]], [1.0, 1.0], 3, diagonal=1.0)).solve(np.ones(3))
    first = dict(import_s=import_s, first_factor_s=time.perf_counter() - t)
    cases = [suit() if GARMENT.exists() else grid(47), grid(100)]
    rows = [measure(name, solver_matrix(polygons), args.repeat, args.solve_repeat) for name, polygons in cases]
    if args.json:
        print(json.dumps(dict(first, sizes=rows), indent=1))
        return
    print(f"import {first['import_s']:.2f} s; first factor (kernels loaded or compiled) "
          f"{first['first_factor_s']:.2f} s; CPU ms, medians")
    print(f"{'matrix':>20} {'n':>6} | {'nnz L old/new':>15} {'stored':>8} {'sn':>5} | "
          f"{'refactor old/new':>17} {'solve3 old/new':>15} | {'analyse':>7} | {'splu f/s':>13}")
    for r in rows:
        print(f"{r['matrix']:>20} {r['n']:>6} | {r['old_nnz_l']:>7}/{r['new_nnz_l']:<7} {r['new_stored']:>8} "
              f"{r['supernodes']:>5} | {r['old_refactor_ms']:7.2f} /{r['new_refactor_ms']:7.2f} "
              f"{r['old_solve3_ms']:6.2f} /{r['new_solve3_ms']:6.2f} | {r['analyse_ms']:7.1f} | "
              f"{r['splu_factor_ms']:6.1f}/{r['splu_solve3_ms']:5.2f}   "
              f"(residuals {r['old_residual']:.0e} / {r['new_residual']:.0e})")


if __name__ == "__main__":
    main()
