"""Classic sphere drape: a 1 m x 1 m cloth of N x N particles falls onto a sphere.

The cloth starts horizontal with its centre 0.5 m above the centre of a fixed
sphere of radius 0.3 m and falls for 2 s (120 frames at 60 fps). The solver is the
drape's (:class:`vfit_engine.sim.solver_verlet.SolverVerlet`): the sphere runs inside
its substep kernel (``spheres``) and holds out the cloth's vertices and contact points
spread over its triangles (:func:`vfit_engine.sim.contact_points.contact_points`).
Reports wall time of the warm 2 s drape (JIT compile measured apart, on a tiny cloth),
ms per frame, particle-substeps per second, the largest structural stretch, and the
largest penetration into the true sphere (mm, 0 when nothing is inside) of the vertices
(``max_pen_mm``) and of the cloth surface (``max_pen_surface_mm``: a barycentric lattice
on every triangle, :func:`vfit_engine.drape.metrics.surface_samples`).
``--baseline`` also runs the plain Numba mass-spring of baseline_sphere_drape.py
(40 substeps, 5 Provot sweeps, 2 threads) in the same process after vfit's runs, and
measures its vertices and surface the same way.

``--threads 1,2`` times the drape on one thread and on two (the kernel runs the cloth's halves on two
threads) in the same run.

    python benchmarks/bench_sphere_drape.py --n 100 [--threads 1,2] [--baseline] [--json]
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
CENTRE = np.zeros(3)


def make_drape(n, material="cotton", substeps=8, iterations=None, friction=0.5, air_damping=0.5, spacing=0.015,
               bend_limit=True, solver="verlet"):
    """Solver and state of the drape scene for an n x n cloth.

    Parameters
    ----------
    n : int
        Particles per side.
    iterations : int or None
        Constraint sweeps per substep (None: the solver's default).
    spacing : float, m
        Spacing of the contact points over the cloth's triangles; 0: the vertices only.
    bend_limit : bool
        Keep the solver's bend limit (False: bend springs only).
    solver : {"verlet", "pd"}
        The Gauss-Seidel solver, or projective dynamics (:class:`vfit_engine.sim.solver_pd.SolverPD`; then
        ``substeps`` and ``iterations`` are its steps a frame and iterations a step).

    Returns
    -------
    solver : SolverVerlet;  state : State;  tris : (T, 3) int64
        The cloth's fan triangles (for the surface penetration).
    """
    from vfit_engine.sim.springs import grid_polygons
    from vfit_engine.io.meshdata import MeshData
    from vfit_engine.sim.contact_points import contact_points
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_pd import SolverPD
    from vfit_engine.sim.solver_settings import PDSettings
    from vfit_engine.sim.solver_verlet import ContactSettings, SolverVerlet, VerletSettings

    pos, fv, fo = grid_polygons(n, n, 1.0, 1.0)
    pos[:, 1] = HEIGHT
    model = Model.from_polygons(fv, fo, pos, material)
    kw = dict(substeps=substeps, air_damping=air_damping)
    if iterations is not None:
        kw["iterations"] = iterations
    if not bend_limit:
        kw["bend_limit"] = None
    settings = PDSettings(**kw) if solver == "pd" else VerletSettings(**kw)
    points = contact_points(fv, fo, pos, spacing=spacing if spacing > 0 else 0.015, surface=spacing > 0)
    kind = SolverPD if solver == "pd" else SolverVerlet
    solver = kind(model, settings, ContactSettings(friction=friction),
                  spheres=np.array([[CENTRE[0], CENTRE[1], CENTRE[2], RADIUS]]), points=points)
    state = solver.init_state(1.0 / FPS / substeps)
    return solver, state, MeshData(pos, fo, fv).triangles()


def run(n, frames=FRAMES, **kw):
    """Drape for ``frames`` frames; returns (wall s, cpu s, solver, state, tris)."""
    solver, state, tris = make_drape(n, **kw)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(frames):
        solver.step_frame(state, 1.0 / FPS)
    return time.perf_counter() - t0, time.process_time() - c0, solver, state, tris


def penetration_mm(pos, tris):
    """Deepest vertex and deepest surface sample inside the true sphere, mm (0 when none is inside).

    The surface is sampled like the drape metrics (:mod:`vfit_engine.drape.metrics`): a barycentric
    lattice of order ``ceil(longest edge / SURFACE_SPACING)`` (at least SURFACE_ORDER) on every triangle.

    Returns
    -------
    vertex_mm, surface_mm : float
    surface_inside_percent : float
    """
    from vfit_engine.drape.metrics import SURFACE_MAX_ORDER, SURFACE_ORDER, SURFACE_SPACING, surface_samples

    pos = np.asarray(pos, dtype=np.float64)
    vertex = RADIUS - np.linalg.norm(pos - CENTRE, axis=1).min()
    corners = pos[tris]
    longest = float(np.max(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)))
    order = int(np.clip(np.ceil(longest / SURFACE_SPACING), SURFACE_ORDER, SURFACE_MAX_ORDER))
    depth = RADIUS - np.linalg.norm(surface_samples(pos, tris, order) - CENTRE, axis=1)
    return (1000.0 * max(float(vertex), 0.0), 1000.0 * max(float(depth.max()), 0.0),
            100.0 * float(np.count_nonzero(depth > 0)) / depth.size)


def main(argv=None):
    from vfit_engine.sim.solver_settings import PDSettings
    from vfit_engine.sim.solver_verlet import VerletSettings

    defaults, pd = VerletSettings(), PDSettings()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="particles per side")
    ap.add_argument("--solver", choices=("verlet", "pd"), default="verlet",
                    help="the Gauss-Seidel solver or projective dynamics (default %(default)s)")
    ap.add_argument("--substeps", type=int, default=None, help=f"substeps (pd: steps) a frame (default {defaults.substeps}; pd {pd.substeps})")
    ap.add_argument("--iterations", type=int, default=None,
                    help="constraint and contact sweeps per substep, or pd iterations a step (default: the "
                         f"solver's, {defaults.iterations}; pd {pd.iterations})")
    ap.add_argument("--material", default="cotton")
    ap.add_argument("--spacing", type=float, default=0.015,
                    help="spacing of the contact points over the cloth's triangles, m (0: vertices only; "
                         "default %(default)s, the drape's)")
    ap.add_argument("--friction", type=float, default=0.5)
    ap.add_argument("--no-bend-limit", action="store_true", help="no bend limit (bend springs only)")
    ap.add_argument("--repeat", type=int, default=1, help="runs; the fastest is reported")
    ap.add_argument("--threads", default=None,
                    help="thread counts to time side by side, e.g. 1,2 (the kernel runs the cloth's halves on two "
                         "threads; results are the same for any count); the last is reported in full "
                         "(default: all cores)")
    ap.add_argument("--baseline", action="store_true",
                    help="also run the plain Numba baseline (baseline_sphere_drape.py) in this run")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if args.substeps is None:
        args.substeps = (pd if args.solver == "pd" else defaults).substeps

    t0 = time.perf_counter()
    import numba  # (import time is not compile time)
    t_import = time.perf_counter() - t0
    kw = dict(material=args.material, substeps=args.substeps, iterations=args.iterations, friction=args.friction,
              spacing=args.spacing, bend_limit=not args.no_bend_limit, solver=args.solver)
    t0 = time.perf_counter()
    run(4, frames=1, **kw)  # compiles (or loads from cache) every kernel used
    compile_s = time.perf_counter() - t0
    if args.baseline:
        t0 = time.perf_counter()
        import baseline_sphere_drape as baseline

        baseline.run(4, frames=1)
        baseline_compile_s = time.perf_counter() - t0

    counts = [int(t) for t in args.threads.split(",")] if args.threads else [numba.get_num_threads()]
    by_threads = {}
    for count in counts:
        numba.set_num_threads(count)
        runs = [run(args.n, **kw) for _ in range(max(1, args.repeat))]
        wall, cpu, solver, state, tris = min(runs, key=lambda r: r[0])
        by_threads[count] = round(wall, 4)
    st = solver.settings
    finite = bool(np.all(np.isfinite(state.pos)))
    pen_v, pen_s, inside = penetration_mm(state.pos, tris) if finite else (float("nan"),) * 3
    result = dict(
        n=args.n, solver=args.solver, substeps=args.substeps, iterations=st.iterations,
        # no Provot strain limit (stretch is compliant beyond a slack band); the kernel runs the cloth's
        # halves on up to two threads
        parallel=True, strain_limit=None, relaxation=None, bend_limited=st.bend_limit is not None,
        threads=counts[-1], wall_s_by_threads=by_threads, wall_s=round(wall, 4), cpu_s=round(cpu, 4),
        ms_per_frame=round(1000 * wall / FRAMES, 3),
        particle_substeps_per_s=float(f"{args.n * args.n * args.substeps * FRAMES / wall:.4g}"),
        compile_s=round(compile_s, 3), import_numba_s=round(t_import, 3),
        max_pen_mm=round(pen_v, 4), max_pen_surface_mm=round(pen_s, 4), surface_inside_percent=round(inside, 4),
        max_stretch=round(solver.max_stretch(state), 5),
        max_speed=round(solver.max_speed(state), 4), softened_fraction=round(solver.softened_fraction, 3),
        finite=finite, min_y=round(float(state.pos[:, 1].min()), 4),
        contact_points=solver.points.count, surface_spacing=args.spacing, friction=args.friction,
        slack=st.slack, compression=st.compression, bend_limit=st.bend_limit, shear_limit_deg=st.shear_limit_deg,
        skin_mm=1000 * solver.contact.skin, surface_skin_mm=1000 * solver.contact.surface_skin,
    )
    if args.baseline:
        b_runs = [baseline.run(args.n, threads=2) for _ in range(max(1, args.repeat))]
        b_wall, b_cpu, b_drape = min(b_runs, key=lambda r: r[0])
        b_finite = bool(np.all(np.isfinite(b_drape.pos)))
        # the baseline's particle (i, j) is vertex j n + i of the same grid: the same triangles
        b_pen_v, b_pen_s, b_inside = penetration_mm(b_drape.pos, tris) if b_finite else (float("nan"),) * 3
        result.update(
            baseline_wall_s=round(b_wall, 4), baseline_cpu_s=round(b_cpu, 4),
            baseline_ms_per_frame=round(1000 * b_wall / FRAMES, 3), speedup_vs_baseline=round(b_wall / wall, 3),
            baseline_max_stretch=round(b_drape.max_stretch(), 5), baseline_max_pen_mm=round(b_pen_v, 4),
            baseline_max_pen_surface_mm=round(b_pen_s, 4), baseline_surface_inside_percent=round(b_inside, 4),
            baseline_finite=b_finite, baseline_threads=2,
            baseline_compile_s=round(baseline_compile_s, 3),
        )
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:>{max(map(len, result))}}: {v}")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    raise SystemExit(main())
