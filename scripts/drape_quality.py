"""Drape quality acceptance: every shared garment on three bodies of its gender.

Bodies: MakeHuman's young-adult average body of the garment's gender (from its .mhclo tags) and
that body morphed to -5 cm and +5 cm waist AND hips (iso tape girths). Acceptance per case:
converged, all finite, no garment vertex deeper than 2 mm inside the body, at most 0.5 % of them
inside at all, p99 structural strain <= 5 % and max <= 10 %.

    python scripts/drape_quality.py [--garment NAME ...] [--material cotton] [--transfer none] [--json]

``--transfer`` moves the garment from the default body to each case body before the drape
(``vfit_engine.garment.transfer.transfer_garment``; ``auto`` = mhclo-delta with the garment's .mhclo).
"""
import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

GARMENTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments"
DELTAS_CM = (0.0, -5.0, 5.0)


def case_bodies(morpher, gender):
    """[(label, verts (19158, 3) m)] for the default body and the +-5 cm waist and hips bodies."""
    default = morpher.model.default_verts(gender)
    start = morpher.measurer.measure(default, "iso").cm()
    out = []
    for d in DELTAS_CM:
        if d == 0:
            out.append(("default", default))
            continue
        targets = {"waist": (start["waist"] + d) / 100.0, "hips": (start["hips"] + d) / 100.0}
        out.append((f"{d:+g} cm w+h", morpher.solve(targets, gender=gender).verts))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", action="append", help="garment name(s) (default: all)")
    ap.add_argument("--material", default="cotton")
    ap.add_argument("--transfer", default="auto",
                    choices=("auto", "mhclo", "mhclo-delta", "dqs", "lbs", "none"),
                    help="garment transfer to the case body before the drape (default: auto, as vfit drape)")
    ap.add_argument("--rest", default="transferred", choices=("garment", "transferred"),
                    help="rest lengths of the cloth after a transfer (default: transferred, as vfit drape)")
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
    from vfit_engine.sim.drape import DrapeSettings, drape_garment

    morpher = Morpher()
    tris = morpher.model.body_tris
    names = args.garment or sorted(p.name for p in GARMENTS.iterdir() if p.is_dir())
    settings = DrapeSettings()
    rows, cases, bodies = [], [], {}
    for name in names:
        g = load_garment(GARMENTS / name / f"{name}.obj")
        binding = parse_mhclo(g.mhclo_path) if g.mhclo_path else None
        gender = (binding.gender if binding else None) or "female"
        if gender not in bodies:
            bodies[gender] = case_bodies(morpher, gender)
        ref = bodies[gender][0][1]
        for label, verts in bodies[gender]:
            t0 = time.perf_counter()
            # full 19,158-vertex bodies: the mhclo transfers read helper vertices (the drape uses the skin)
            r = drape_garment(g.mesh, g.pieces, verts, ref, tris, material=args.material, settings=settings,
                              transfer=args.transfer, mhclo=binding, rest=args.rest)
            total = time.perf_counter() - t0
            m = r.metrics
            ok = passes(r)
            rows.append([name, f"{gender} {label}", r.steps, "yes" if r.converged else "NO", f"{r.wall_time:.2f}",
                         f"{m['max_depth_mm']:.2f}", f"{100 * m['inside_fraction']:.2f}",
                         f"{100 * m['p99_strain']:.2f}", f"{100 * m['max_strain']:.2f}",
                         f"{100 * m['garment_strain']['p99']:.2f}", "pass" if ok else "FAIL"])
            cases.append(dict(garment=name, gender=gender, body=label, steps=r.steps, frames=r.frames,
                              converged=r.converged, wall_s=round(r.wall_time, 3), total_s=round(total, 3),
                              collide_s=round(r.collide_time, 3), pins=r.settings["pins"]["count"],
                              transfer=r.settings["transfer"],
                              metrics={k: (round(v, 6) if isinstance(v, float) else v) for k, v in m.items()},
                              passed=ok))
            if not args.json:
                print(fmt_table(rows[-1:], ["garment", "body", "steps", "converged", "wall s", "max depth mm",
                                            "% inside", "p99 strain %", "max strain %", "p99 vs garment %", "result"]).splitlines()[-1],
                      flush=True)
    if args.json:
        print(json.dumps(dict(material=args.material, transfer=args.transfer, settings=settings.__dict__, cases=cases,
                              passed=sum(c["passed"] for c in cases), total=len(cases))))
    else:
        print()
        print(fmt_table(rows, ["garment", "body", "steps", "converged", "wall s", "max depth mm", "% inside",
                               "p99 strain %", "max strain %", "p99 vs garment %", "result"]))
        print(f"\n{sum(c['passed'] for c in cases)}/{len(cases)} cases pass; material {args.material}; "
              f"transfer {args.transfer}; rest {args.rest}; "
              f"settings {settings}")
    return 0 if all(c["passed"] for c in cases) else 1


if __name__ == "__main__":
    sys.exit(main())
