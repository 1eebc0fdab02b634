"""The cantilever bending test (ASTM D1388) of a fabric on the cloth solver, against Peirce's bending length.

    python benchmarks/bench_cantilever.py --material cotton [--edge 5] [--json]
    python benchmarks/bench_cantilever.py --material my_fabric.json --edge 10 --json
    python benchmarks/bench_cantilever.py --material denim --step 2.0833 [--softened]
    python benchmarks/bench_cantilever.py --material silk --solver pd [--edge 10]

``--step MS`` runs the solver at that step instead of the largest explicit one (2.0833 ms is a drape's:
1/60 s in 8 substeps); hinges too stiff for it are constraints, or with ``--softened`` softened to its
bound as the solver did before. ``--solver pd`` runs the projective solver
(:data:`vfit_engine.textile.cantilever.PD_SETTINGS`, its step 1/480 s unless ``--step``).

Prints each try (overhang, tip angle) and the result; with ``--json`` the last line is one JSON object:
``bending_length_m`` (the overhang at 41.5 degrees / 2), ``peirce_m`` (c = (B / (w g))^(1/3) of the
material), ``relative_error``, ``overhang_m``, ``angle_deg``, ``edge_m``, ``time_s`` and the last try's figures.
The method is :mod:`vfit_engine.textile.cantilever`'s.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))  # _fabric_args, also when loaded by path (tests)


def main(argv=None):
    from _fabric_args import parse_fabric_args

    from vfit_engine.textile.cantilever import bending_length

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=float, default=None, metavar="MS",
                    help="solver step, ms (default: the largest at which every hinge is explicit)")
    ap.add_argument("--softened", action="store_true",
                    help="soften the hinges too stiff for --step instead of solving them as constraints")
    ap.add_argument("--solver", choices=("verlet", "pd"), default="verlet",
                    help="the Gauss-Seidel solver (default) or the projective one")
    parsed = parse_fabric_args(ap, argv, 5.0, (0.5, 25.0), "the strip is 25 mm wide")
    if parsed is None:
        return 2
    args, material = parsed
    if args.step is not None and not 0.001 <= args.step <= 20.0:
        print(f"error: --step {args.step:g} ms: use 0.001-20 ms", file=sys.stderr)
        return 2
    r = bending_length(material, args.edge / 1000.0, dt=None if args.step is None else args.step / 1000.0,
                       implicit_hinges=not args.softened, solver=args.solver)
    for t in r["tries"]:
        print(f"overhang {100 * t['overhang_m']:6.2f} cm -> tip {t['angle_deg']:5.2f} deg below the edge")
    print(f"{material.name}: bending length {100 * r['bending_length_m']:.2f} cm (Peirce {100 * r['peirce_m']:.2f} cm, "
          f"{100 * r['relative_error']:+.1f} %) at {args.edge:g} mm spacing; {r['vertices']} vertices, "
          f"step {1e3 * r['dt_s']:.3f} ms ({100 * r['implicit_hinges']:.0f} % of the hinges constraints, "
          f"{100 * r['softened_hinges']:.0f} % softened), {r['time_s']:.1f} s")
    if args.json:
        out = {k: v for k, v in r.items() if k != "tries"}
        out.update(material=material.name, tries=r["tries"])
        print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
