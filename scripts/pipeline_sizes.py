"""The full pipeline on every shared garment x five bodies spanning EN 13402 letter sizes XS-XL.

For each garment (its gender from the .mhclo tags) and each size: the body built to the size's bust
(men: chest), waist and hips (iso tape girths; ``vfit_engine.body.resolve.resolve_body``), the garment
set up on it and draped the product's way (``vfit_engine.drape``: ``prepare_drape`` -- placed on the
default body of its gender, moved to this one by ``--transfer``, rest shape ``--rest`` -- then
``run_drape`` with the exact body mesh), and checked against the drape issue's bars
(``vfit_engine.drape.meets_bars``: settled, finite, no cloth-surface sample deeper than 2 mm and
<= 0.5 % inside, yarn strain p99 <= 5 % and max <= 10 % -- or, where an opening is smaller than the body
under it, its required strain + 5 points --, shear p99 <= 15 deg; strain against the garment as given).
A garment made for size M is tight on XL and loose on XS: the failures there are the garment's size,
and the ``need %`` column says how far its tightest opening must stretch. With ``--compare`` each case is
draped once more with ``--transfer none`` (the garment starts where it was modelled) and the frames to
settle are compared.

    python scripts/pipeline_sizes.py [--garment NAME ...] [--size M ...] [--compare] [--json]

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

from vfit_engine.sizes import SIZES  # noqa: E402  (size, bust/chest, waist, hips) in cm, mid-interval


HEAD = ["garment", "size", "frames", "settled", "wall s", "surface in %", "deepest mm", "p99 strain %",
        "max strain %", "need %", "shear p99 deg", "result"]


def _row(name, label, r, setup, passed):
    """A table row of one drape (``r`` a DrapeResult or the DrapeDiverged it raised)."""
    from vfit_engine.drape import DrapeDiverged

    if isinstance(r, DrapeDiverged):
        return [name, label, r.frame, "DIVERGED"] + ["-"] * (len(HEAD) - 5) + ["FAIL"]
    m = r.metrics
    need = max([o["required_strain"] for o in setup.openings] + [0.0])
    return [name, label, r.frames, "yes" if r.converged else "NO", f"{r.wall_time:.2f}",
            f"{m['surface_inside_percent']:.2f}", f"{m['surface_max_depth_mm']:.2f}", f"{100 * m['p99_strain']:.2f}",
            f"{100 * m['max_strain']:.2f}", f"{100 * need:.1f}" if need > 0 else "-", f"{m['shear_p99_deg']:.1f}",
            "pass" if passed else "FAIL"]


def _case(r, setup, passed, total):
    from vfit_engine.drape import DrapeDiverged

    if isinstance(r, DrapeDiverged):
        return dict(diverged=str(r), passed=False)
    return dict(frames=r.frames, steps=r.steps, converged=r.converged, wall_s=round(r.wall_time, 3),
                total_s=round(total, 3), transfer=setup.info["transfer"], rest=setup.info["rest"],
                tight_openings=[{k: o[k] for k in ("vertices", "rest_length_mm", "body_tape_mm", "required_strain")}
                                for o in setup.openings if o["required_strain"] > 0],
                metrics={k: (round(v, 6) if isinstance(v, float) else v) for k, v in r.metrics.items()},
                passed=passed)


def _json_default(value):
    """numpy scalars and arrays for json.dumps."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


def main(argv=None):
    from vfit_engine.drape.setup import REST_MODES
    from vfit_engine.garment.transfer import METHODS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", action="append", help="garment name(s) (default: all)")
    ap.add_argument("--size", action="append", choices=[s[0] for s in SIZES["female"]],
                    help="size(s) (default: all)")
    ap.add_argument("--material", default="cotton")
    # every transfer method but none, which --compare drapes with
    ap.add_argument("--transfer", default="auto", choices=[m for m in METHODS if m != "none"])
    ap.add_argument("--rest", default="garment", choices=REST_MODES,
                    help="the cloth's rest shape (default: garment, as vfit drape)")
    ap.add_argument("--frames", type=int, default=None, help="most frames per drape (default: vfit drape's)")
    ap.add_argument("--compare", action="store_true", help="also drape with --transfer none and compare frames")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if not GARMENTS.is_dir():
        print("../shared not present", file=sys.stderr)
        return 1

    from dataclasses import asdict

    from vfit_cli._common import fmt_table
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import resolve_body
    from vfit_engine.drape import DrapeDiverged, DrapeSettings, meets_bars, prepare_drape, run_drape
    from vfit_engine.drape.setup import garment_gender
    from vfit_engine.garment.garment import load_garment

    model = BodyModel.load()
    settings = DrapeSettings() if args.frames is None else DrapeSettings(max_frames=args.frames)
    names = args.garment or sorted(p.name for p in GARMENTS.iterdir() if p.is_dir())
    bodies, rows, cases = {}, [], []
    head = HEAD + (["frames none", "none result"] if args.compare else [])
    for name in names:
        g = load_garment(GARMENTS / name / f"{name}.obj")
        gender = garment_gender(g) or "female"
        if gender not in bodies:
            bodies[gender] = [(size, resolve_body(model, targets={"bust": b / 100, "waist": w / 100, "hips": h / 100},
                                                  gender=gender, definition="iso"))
                              for size, b, w, h in SIZES[gender] if not args.size or size in args.size]
        for size, body in bodies[gender]:
            runs = {}
            for which in ("main", "none") if args.compare else ("main",):
                t0 = time.perf_counter()
                setup = prepare_drape(g, body, model, material=args.material, rest=args.rest, settings=settings,
                                      transfer=args.transfer if which == "main" else "none")
                try:
                    r = run_drape(setup, settings)
                    passed = meets_bars(r, setup.openings)
                except DrapeDiverged as exc:
                    r, passed = exc, False
                runs[which] = (r, setup, passed, time.perf_counter() - t0)
            r, setup, passed, total = runs["main"]
            row = _row(name, f"{gender} {size}", r, setup, passed)
            case = dict(garment=name, gender=gender, size=size, **_case(r, setup, passed, total))
            if args.compare:
                rn, setup_n, passed_n, total_n = runs["none"]
                if isinstance(rn, DrapeDiverged):
                    row += ["diverged", "FAIL"]
                else:
                    row += [f"{rn.frames}{'' if rn.converged else ' (not settled)'}", "pass" if passed_n else "FAIL"]
                case["none"] = _case(rn, setup_n, passed_n, total_n)
            rows.append(row)
            cases.append(case)
            if not args.json:
                print(fmt_table(rows[-1:], head).splitlines()[-1], flush=True)
    passed = sum(c["passed"] for c in cases)
    if args.json:
        print(json.dumps(dict(material=args.material, transfer=args.transfer, rest=args.rest,
                              settings=asdict(settings), cases=cases, passed=passed, total=len(cases)),
                         default=_json_default))
    else:
        print()
        print(fmt_table(rows, head))
        print(f"\n{passed}/{len(cases)} cases pass; material {args.material}; transfer {args.transfer}; "
              f"rest {args.rest}")
    return 0 if passed == len(cases) else 1


if __name__ == "__main__":
    sys.exit(main())
