"""Classic sphere drape: a 1 m x 1 m cloth of N x N particles falls onto a sphere.

The cloth starts horizontal with its centre 0.5 m above the centre of a fixed
sphere of radius 0.3 m and falls for 2 s (120 frames at 60 fps). Reports wall
time of the warm 2 s drape (JIT compile measured apart, on a tiny cloth),
ms per frame, particle-substeps per second, the largest penetration into the
true sphere (mm, 0 when nothing is inside) and the largest structural stretch.
``--baseline`` also runs the plain Numba mass-spring of baseline_sphere_drape.py
(40 substeps, 5 Provot sweeps, 2 threads) in the same process after vfit's runs.

    python benchmarks/bench_sphere_drape.py --n 100 [--parallel] [--baseline] [--json]
"""
import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

RADIUS = 0.3
HEIGHT = 0.5
FPS = 60
FRAMES = 120


def make_drape(n, material="cotton", substeps=8, iterations=3, parallel=False, strain_limit=0.09,
               relaxation=1.5, limit_bend=True, friction=0.5, air_damping=0.5):
    """Solver, state, collider and frame step of the drape scene for an n x n cloth."""
    from vfit_engine.collide.spheres import SphereCollider
    from vfit_engine.garment.springs import grid_polygons
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_verlet import SolverVerlet, VerletSettings

    pos, fv, fo = grid_polygons(n, n, 1.0, 1.0)
    pos[:, 1] = HEIGHT
    model = Model.from_polygons(fv, fo, pos, material)
    sphere = SphereCollider([[0.0, 0.0, 0.0]], [RADIUS], skin=0.01, friction=friction, restitution=0.0)
    settings = VerletSettings(substeps=substeps, strain_limit_iterations=iterations, parallel=parallel,
                              strain_limit=strain_limit, air_damping=air_damping,
                              bend_strain_limit=strain_limit if limit_bend else None,
                              strain_limit_relaxation=relaxation)
    solver = SolverVerlet(model, settings, [sphere])
    state = solver.init_state(1.0 / FPS / substeps)
    return solver, state, sphere


def run(n, frames=FRAMES, **kw):
    """Drape for ``frames`` frames; returns (wall s, cpu s, solver, state, sphere)."""
    solver, state, sphere = make_drape(n, **kw)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(frames):
        solver.step_frame(state, 1.0 / FPS)
    return time.perf_counter() - t0, time.process_time() - c0, solver, state, sphere


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="particles per side")
    ap.add_argument("--substeps", type=int, default=8)
    ap.add_argument("--iterations", type=int, default=3, help="Provot sweeps per substep")
    ap.add_argument("--relaxation", type=float, default=1.5, help="over-relaxation of Provot corrections")
    ap.add_argument("--material", default="cotton")
    ap.add_argument("--strain-limit", type=float, default=0.09,
                    help="Provot limit (0.09 leaves a margin for the Gauss-Seidel residual under 10 %%)")
    ap.add_argument("--no-bend-limit", action="store_true", help="do not strain-limit bend springs")
    ap.add_argument("--repeat", type=int, default=1, help="runs; the fastest is reported")
    ap.add_argument("--parallel", action="store_true", help="use the parallel=True kernel")
    ap.add_argument("--threads", type=int, default=None, help="numba threads (with --parallel)")
    ap.add_argument("--baseline", action="store_true",
                    help="also run the plain Numba baseline (baseline_sphere_drape.py) in this run")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    import numba  # noqa: F401  (import time is not compile time)
    t_import = time.perf_counter() - t0
    if args.threads:
        numba.set_num_threads(args.threads)
    kw = dict(material=args.material, substeps=args.substeps, iterations=args.iterations,
              parallel=args.parallel, strain_limit=args.strain_limit, relaxation=args.relaxation,
              limit_bend=not args.no_bend_limit)
    t0 = time.perf_counter()
    run(4, frames=1, **kw)  # compiles (or loads from cache) every kernel used
    compile_s = time.perf_counter() - t0
    if args.baseline:
        t0 = time.perf_counter()
        import baseline_sphere_drape as baseline

        baseline.run(4, frames=1)
        baseline_compile_s = time.perf_counter() - t0

    runs = [run(args.n, **kw) for _ in range(max(1, args.repeat))]
    wall, cpu, solver, state, sphere = min(runs, key=lambda r: r[0])
    pen = -sphere.signed_distance(state.pos).min()
    result = dict(
        n=args.n, substeps=args.substeps, iterations=args.iterations, parallel=args.parallel,
        strain_limit=args.strain_limit, relaxation=args.relaxation, bend_limited=not args.no_bend_limit,
        threads=numba.get_num_threads() if args.parallel else 1, wall_s=round(wall, 4), cpu_s=round(cpu, 4), ms_per_frame=round(1000 * wall / FRAMES, 3),
        particle_substeps_per_s=float(f"{args.n * args.n * args.substeps * FRAMES / wall:.4g}"),
        compile_s=round(compile_s, 3), import_numba_s=round(t_import, 3),
        max_pen_mm=round(max(pen, 0.0) * 1000, 4), max_stretch=round(solver.max_stretch(state), 5),
        max_speed=round(solver.max_speed(state), 4), softened_fraction=round(solver.softened_fraction, 3),
        finite=bool(np.all(np.isfinite(state.pos))), min_y=round(float(state.pos[:, 1].min()), 4),
    )
    if args.baseline:
        b_runs = [baseline.run(args.n, threads=2) for _ in range(max(1, args.repeat))]
        b_wall, b_cpu, b_drape = min(b_runs, key=lambda r: r[0])
        result.update(
            baseline_wall_s=round(b_wall, 4), baseline_cpu_s=round(b_cpu, 4),
            baseline_ms_per_frame=round(1000 * b_wall / FRAMES, 3), speedup_vs_baseline=round(b_wall / wall, 3),
            baseline_max_stretch=round(b_drape.max_stretch(), 5), baseline_max_pen_mm=round(b_drape.max_pen_mm(), 4),
            baseline_finite=bool(np.all(np.isfinite(b_drape.pos))), baseline_threads=2,
            baseline_compile_s=round(baseline_compile_s, 3),
        )
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:>24}: {v}")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    raise SystemExit(main())
