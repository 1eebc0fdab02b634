"""The full pipeline on every shared garment x five bodies spanning EN 13402 letter sizes XS-XL.

For each garment (its gender from the .mhclo tags) and each size: morph the body to the size's
bust (men: chest), waist and hips (iso tape girths), transfer the garment from the default body of
its gender (``--transfer``, default auto = mhclo-delta), drape it with the exact body mesh, and check
the cloth issue's bars (converged, finite, no vertex deeper than 2 mm, <= 0.5 % inside, p99 strain
<= 5 %, max <= 10 %; strain against the cloth's rest lengths, ``--rest``). With ``--compare`` each case
is draped once more with ``--transfer none`` (the garment starts where it was modelled, rest lengths
its own) and the simulated steps to convergence are compared.

    python scripts/pipeline_sizes.py [--garment NAME ...] [--compare] [--json]

Sizes are mid-interval girths (cm) of EN 13402-3 (../shared/reference/MEASUREMENTS.md: women's bust
XS 74-82 ... XL 107-119, men's chest XS 78-86 ... XL 110-118), with waist and hips stepped alongside.
"""
import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

GARMENTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments"

#: (size, bust/chest, waist, hips) in cm, mid-interval.
SIZES = {
    "female": [("XS", 78, 62, 86), ("S", 86, 70, 94), ("M", 94, 78, 102), ("L", 102, 86, 110), ("XL", 113, 95, 119)],
    "male": [("XS", 82, 70, 84), ("S", 90, 78, 91), ("M", 98, 86, 98), ("L", 106, 94, 105), ("XL", 114, 102, 112)],
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", action="append", help="garment name(s) (default: all)")
    ap.add_argument("--transfer", default="auto", choices=("auto", "mhclo", "mhclo-delta", "dqs", "lbs"))
    ap.add_argument("--rest", default="transferred", choices=("transferred", "garment"))
    ap.add_argument("--compare", action="store_true", help="also drape with --transfer none and compare steps")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if not GARMENTS.is_dir():
        print("../shared not present", file=sys.stderr)
        return 1

    from vfit_cli._common import fmt_table
    from vfit_engine.sim.report import meets_bars as passes
    from vfit_engine.body.morph import Morpher
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.garment.mhclo import parse_mhclo
    from vfit_engine.sim.drape import DrapeDiverged, DrapeSettings, drape_garment

    morpher = Morpher()
    tris = morpher.model.body_tris
    settings = DrapeSettings()
    names = args.garment or sorted(p.name for p in GARMENTS.iterdir() if p.is_dir())
    bodies, rows, cases = {}, [], []
    head = ["garment", "size", "steps", "converged", "wall s", "max depth mm", "% inside", "p99 strain %",
            "max strain %", "result"] + (["steps none", "none result"] if args.compare else [])
    for name in names:
        g = load_garment(GARMENTS / name / f"{name}.obj")
        binding = parse_mhclo(g.mhclo_path) if g.mhclo_path else None
        gender = (binding.gender if binding else None) or "female"
        ref = morpher.model.default_verts(gender)
        if gender not in bodies:
            bodies[gender] = [(size, morpher.solve({"bust": b / 100, "waist": w / 100, "hips": h / 100},
                                                   gender=gender).verts) for size, b, w, h in SIZES[gender]]
        for size, verts in bodies[gender]:
            runs = {}
            for transfer in ("main", "none") if args.compare else ("main",):
                t0 = time.perf_counter()
                try:
                    r = drape_garment(g.mesh, g.pieces, verts, ref, tris, settings=settings, mhclo=binding,
                                      transfer=args.transfer if transfer == "main" else "none", rest=args.rest)
                except DrapeDiverged as exc:
                    r = exc
                runs[transfer] = (r, time.perf_counter() - t0)
            r, total = runs["main"]
            if isinstance(r, DrapeDiverged):
                row = [name, f"{gender} {size}", "-", "DIVERGED", "-", "-", "-", "-", "-", "FAIL"]
                case = dict(garment=name, size=size, diverged=str(r), passed=False)
            else:
                m = r.metrics
                ok = passes(r)
                row = [name, f"{gender} {size}", r.steps, "yes" if r.converged else "NO", f"{r.wall_time:.2f}",
                       f"{m['max_depth_mm']:.2f}", f"{100 * m['inside_fraction']:.2f}", f"{100 * m['p99_strain']:.2f}",
                       f"{100 * m['max_strain']:.2f}", "pass" if ok else "FAIL"]
                case = dict(garment=name, gender=gender, size=size, steps=r.steps, converged=r.converged,
                            wall_s=round(r.wall_time, 3), total_s=round(total, 3), transfer=r.settings["transfer"],
                            metrics={k: (round(v, 6) if isinstance(v, float) else v) for k, v in m.items()},
                            passed=ok)
            if args.compare:
                rn = runs["none"][0]
                if isinstance(rn, DrapeDiverged):
                    row += ["diverged", "FAIL"]
                    case["none"] = dict(diverged=str(rn))
                else:
                    row += [f"{rn.steps}{'' if rn.converged else ' (not settled)'}", "pass" if passes(rn) else "FAIL"]
                    case["none"] = dict(steps=rn.steps, converged=rn.converged, passed=passes(rn),
                                        max_strain=rn.metrics.get("max_strain"),
                                        p99_strain=rn.metrics.get("p99_strain"))
            rows.append(row)
            cases.append(case)
            if not args.json:
                print(fmt_table(rows[-1:], head).splitlines()[-1], flush=True)
    if args.json:
        print(json.dumps(dict(transfer=args.transfer, rest=args.rest, settings=settings.__dict__, cases=cases,
                              passed=sum(c["passed"] for c in cases), total=len(cases))))
    else:
        print()
        print(fmt_table(rows, head))
        print(f"\n{sum(c['passed'] for c in cases)}/{len(cases)} cases pass; transfer {args.transfer}; rest {args.rest}")
    return 0 if all(c["passed"] for c in cases) else 1


if __name__ == "__main__":
    sys.exit(main())
