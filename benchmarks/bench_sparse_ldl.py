"""Benchmark of the sparse LDL^T of the projective-dynamics global step against scipy's SuperLU.

The matrix is issue 32's: an nx x nx cloth grid (1 m square, 0.12 kg/m^2), A = M / h^2 + sum_s k_s (e_i - e_j)
(e_i - e_j)^T over its structural, shear and bend springs (5000 / 5000 / 500 N/m), h = 1/60 s; 2,500 and 10,000
vertices. Times are medians, in ms:

  * factor: ``SPDFactor(A)`` (checks, the MMD order from a SuperLU LU, symbolic and numeric factor);
  * refactor: ``SPDFactor.refactor`` with new values in the same pattern (checks and numeric factor);
  * solve: three right-hand sides, by the kernel ``ldl_solve3`` on the factor's arrays (what a jitted frame loop
    calls) and by ``SPDFactor.solve`` (Python: copies and a fresh scratch);
  * scipy: ``splu`` with the same MMD order (symmetric mode, no pivoting) and with its default COLAMD, factor
    and ``lu.solve`` of the (n, 3) block;
  * the first factor in the process apart (the kernels loaded from Numba's cache, or compiled).

Usage: NUMBA_NUM_THREADS=1 python benchmarks/bench_sparse_ldl.py [--repeat 7] [--solve-repeat 41] [--json]
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import median_ms  # noqa: E402

SIZES = (50, 100)


def cloth_matrix(nx, seed=None):
    """The grid's global matrix; with a seed, spring weights scaled by a random 0.5 .. 2 (same pattern)."""
    from vfit_engine.sim.linear import spring_laplacian
    from vfit_engine.sim.springs import BEND, build_springs, grid_polygons, vertex_masses

    pos, fv, fo = grid_polygons(nx, nx)
    springs = build_springs(fv, fo, pos)
    k = np.where(springs.type == BEND, 500.0, 5000.0)
    if seed is not None:
        k *= np.random.default_rng(seed).uniform(0.5, 2.0, k.shape[0])
    return spring_laplacian(springs.indices, k, nx * nx, diagonal=vertex_masses(fv, fo, pos, 0.12) * 60.0 ** 2)


def measure(nx, repeat, solve_repeat):
    from scipy.sparse.linalg import splu

    from vfit_engine.kernels.sparse_ldl import ldl_solve3
    from vfit_engine.sim.linear import SPDFactor

    a, a2 = cloth_matrix(nx), cloth_matrix(nx, seed=1)
    n = a.shape[0]
    b = np.random.default_rng(0).normal(size=(n, 3))
    f = SPDFactor(a)
    row = dict(n=n, nnz_a=int(a.nnz), nnz_l=f.nnz_l, ordering=f.ordering)
    row["factor_ms"] = median_ms(lambda: SPDFactor(a), repeat)
    row["refactor_ms"] = median_ms(lambda: f.refactor(a2), repeat)
    x, work = np.empty_like(b), np.empty_like(b)

    def kernel_solve():
        x[:] = b
        ldl_solve3(*f.arrays, x, work)

    row["solve3_kernel_ms"] = median_ms(kernel_solve, solve_repeat)
    row["solve3_python_ms"] = median_ms(lambda: f.solve(b), solve_repeat)
    row["rel_residual"] = float(np.linalg.norm(a2 @ f.solve(b) - b) / np.linalg.norm(b))
    for name, kwargs in (("splu_mmd", dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                           options=dict(SymmetricMode=True))),
                         ("splu_colamd", dict())):
        row[f"{name}_factor_ms"] = median_ms(lambda: splu(a, **kwargs), repeat)
        lu = splu(a, **kwargs)
        row[f"{name}_solve3_ms"] = median_ms(lambda: lu.solve(b), solve_repeat)
        row[f"{name}_nnz_l"] = int(lu.L.nnz - n)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=7, help="runs of each factor timing")
    ap.add_argument("--solve-repeat", type=int, default=41, help="runs of each solve timing")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()

    t = time.perf_counter()
    from vfit_engine.sim.linear import SPDFactor  # imports numba and the kernels' module

    import_s = time.perf_counter() - t
    t = time.perf_counter()
    SPDFactor(cloth_matrix(4))
    first = dict(import_s=import_s, first_factor_s=time.perf_counter() - t)
    rows = [measure(nx, args.repeat, args.solve_repeat) for nx in SIZES]
    if args.json:
        print(json.dumps(dict(first, sizes=rows), indent=1))
        return
    print(f"import {first['import_s']:.2f} s; first factor (kernels loaded or compiled) "
          f"{first['first_factor_s']:.2f} s")
    print(f"{'n':>6} {'nnz L':>8} {'factor':>7} {'refact':>7} {'solve3':>7} {'py':>6} | "
          f"{'splu mmd f/s':>14} {'nnz L':>8} | {'splu colamd f/s':>15}   (ms)")
    for r in rows:
        print(f"{r['n']:>6} {r['nnz_l']:>8} {r['factor_ms']:7.1f} {r['refactor_ms']:7.1f} "
              f"{r['solve3_kernel_ms']:7.2f} {r['solve3_python_ms']:6.2f} | "
              f"{r['splu_mmd_factor_ms']:6.1f} / {r['splu_mmd_solve3_ms']:5.2f} {r['splu_mmd_nnz_l']:>8} | "
              f"{r['splu_colamd_factor_ms']:6.1f} / {r['splu_colamd_solve3_ms']:5.2f}   "
              f"(residual {r['rel_residual']:.1e})")


if __name__ == "__main__":
    main()
