"""The Cusick drape test (BS 5058 / ISO 9073-9: a 30 cm specimen on an 18 cm support) on the cloth solver.

    python benchmarks/bench_cusick.py --material silk [--edge 10] [--png top.png] [--json]
    python benchmarks/bench_cusick.py --material my_fabric.json --edge 5 --json
    python benchmarks/bench_cusick.py --material cotton --step 2.0833
    python benchmarks/bench_cusick.py --material silk --solver pd

``--step MS`` runs the solver at that step instead of the largest at which every hinge is explicit (2.0833 ms is
a drape's: 1/60 s in 8 substeps; hinges too stiff for it are then constraints, as in a drape).

Prints the drape coefficient and the folds; with ``--json`` the last line is one JSON object:
``drape_coefficient`` (fraction: shadow minus support over specimen minus support), ``nodes`` (folds),
``bending_length_m`` (Peirce's c of the material), ``edge_m``, ``vertices``, ``sim_time_s``, ``settled``, ``time_s``.
``--png`` draws the draped specimen seen from above (needs matplotlib). The method is
:mod:`vfit_engine.textile.cusick`'s.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))  # _fabric_args, also when loaded by path (tests)


def draw(path, r, title):
    """The specimen seen from above, coloured by height, with the support and the flat specimen's rims."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vfit_engine.textile.cusick import RADIUS, SUPPORT

    pos, tris = r["pos"], r["tris"]
    fig, ax = plt.subplots(figsize=(3.2, 3.4))
    ax.tripcolor(100 * pos[:, 0], 100 * pos[:, 2], tris, 100 * pos[:, 1], shading="gouraud", cmap="viridis")
    for radius, style in ((SUPPORT, "r-"), (RADIUS, "k--")):
        ax.add_patch(plt.Circle((0, 0), 100 * radius, fill=False, color=style[0], ls=style[1:], lw=0.8))
    ax.set_xlim(-16, 16)
    ax.set_ylim(-16, 16)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=8)
    ax.tick_params(labelsize=6)
    ax.set_xlabel("cm", fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    from _fabric_args import parse_fabric_args

    from vfit_engine.textile.cusick import drape_test

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0, help="the specimen mesh's jitter (default 0)")
    ap.add_argument("--png", help="draw the drape seen from above into this file")
    ap.add_argument("--solver", choices=("verlet", "pd"), default="verlet",
                    help="the Gauss-Seidel solver (default) or the projective one (its step 1/960 s unless --step)")
    ap.add_argument("--step", type=float, default=None, metavar="MS",
                    help="solver step, ms (default: the largest at which every hinge is explicit)")
    parsed = parse_fabric_args(ap, argv, 10.0, (2.0, 30.0), "the specimen is 300 mm across")
    if parsed is None:
        return 2
    args, material = parsed
    if args.step is not None and not 0.001 <= args.step <= 20.0:
        print(f"error: --step {args.step:g} ms: use 0.001-20 ms", file=sys.stderr)
        return 2
    r = drape_test(material, args.edge / 1000.0, seed=args.seed, dt=None if args.step is None else args.step / 1000.0,
                   solver=args.solver)
    title = (f"{material.name}: DC {100 * r['drape_coefficient']:.0f} %, {r['nodes']} nodes "
             f"(c {100 * material.bending_length:.2f} cm, {args.edge:g} mm)")
    print(f"{title}; {r['vertices']} vertices, {r['sim_time_s']:.2f} s simulated "
          f"({'settled' if r['settled'] else 'NOT settled'}), step {1e3 * r['dt_s']:.3f} ms, {r['time_s']:.1f} s")
    if args.png:
        draw(args.png, r, title)
        print(f"wrote {args.png}")
    if args.json:
        out = {k: v for k, v in r.items() if k not in ("pos", "tris")}
        out.update(material=material.name, bending_length_m=material.bending_length,
                   drape_coefficient=float(out["drape_coefficient"]), specimen_m2=float(out["specimen_m2"]))
        print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
