"""Garment transfer benchmark: each shared garment moved from its gender's default body to bodies with
bust, waist or hips changed by +-15 cm, by mhclo, mhclo-delta, lbs and dqs (and none, the baseline).

    python benchmarks/bench_transfer.py [--repeat 5] [--json]

Per garment and method (over the six target bodies): time, vertices inside the target body and the
deepest one (mm), edge-length distortion |l/l0 - 1| (mean, max) and the change of garment area (%).
``l0`` and the reference area are the garment before the move: the authored OBJ, except for mhclo,
which re-fits the binding and so is compared with the binding's fit on the source body. Then a K
sweep for dqs and the timing of the pieces on the body and on a 10,000-vertex point set. No Numba:
everything is NumPy/SciPy, so there is no JIT compile time to separate.
"""
import argparse
import json
import time
from pathlib import Path

import numpy as np
from _timing import median_ms

GARMENTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments"
CHANGES_CM = [("bust", -15), ("bust", 15), ("waist", -15), ("waist", 15), ("hips", -15), ("hips", 15)]
METHODS = ("none", "mhclo", "mhclo-delta", "lbs", "dqs")
K_SWEEP = (1, 3, 6, 10, 20)




def _targets(morpher, measurer, gender, notes):
    """(label, verts) of the six target bodies; unreachable targets replaced by the nearest reachable one."""
    from vfit_engine.errors import InputError

    default = morpher.model.default_verts(gender)
    start = measurer.measure(default, "iso", mass=False).values
    out = []
    for name, dcm in CHANGES_CM:
        want = start[name] + dcm / 100.0
        try:
            res = morpher.solve({name: want}, gender=gender)
            label = f"{name}{dcm:+d}"
        except InputError:
            lo, hi = morpher.reachable(name, {name: want}, gender)
            near = float(np.clip(want, lo + 0.002, hi - 0.002))
            res = morpher.solve({name: near}, gender=gender)
            label = f"{name}{(near - start[name]) * 100:+.1f}*"
            notes.append(f"{gender} {name} {dcm:+d} cm unreachable (range {lo * 100:.1f}-{hi * 100:.1f} cm): "
                         f"used {near * 100:.1f} cm ({label})")
        out.append((label, res.verts))
    return out


def _metrics(pos, ref, edges, tris, collider):
    l0 = np.linalg.norm(ref[edges[:, 1]] - ref[edges[:, 0]], axis=1)
    l1 = np.linalg.norm(pos[edges[:, 1]] - pos[edges[:, 0]], axis=1)
    ok = l0 > 0
    dist = np.abs(l1[ok] / l0[ok] - 1.0)

    def area(x):
        a, b, c = x[tris[:, 0]], x[tris[:, 1]], x[tris[:, 2]]
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()

    pen = collider.penetration(pos)
    return dict(inside=pen["inside_count"], depth_mm=1000 * pen["max_depth_m"], dist_mean=float(dist.mean()),
                dist_p99=float(np.percentile(dist, 99)), dist_max=float(dist.max()),
                area_pct=100 * (area(pos) / area(ref) - 1.0))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    say = (lambda *a: None) if args.json else print

    from vfit_engine.body.measure import Measurer
    from vfit_engine.body.model import N_BODY, BodyModel
    from vfit_engine.body.morph import Morpher
    from vfit_engine.collide.body_mesh import MeshCollider
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.garment.mhclo import evaluate_mhclo, parse_mhclo
    from vfit_engine.garment.transfer import BodyFrames, transfer

    model = BodyModel.load()
    measurer = Measurer(model)
    morpher = Morpher(model, measurer)
    tris = model.body_tris
    report = {"garments": {}, "timing": {}, "notes": [], "k_sweep": {}}

    # -- timing of the pieces on the body and on 10k points
    src = model.default_verts("female")
    tgt = morpher.solve({"waist": measurer.measure(src, "iso", mass=False).values["waist"] + 0.1}).verts
    rng = np.random.default_rng(0)
    pts = src[rng.integers(0, N_BODY, 10000)] + rng.normal(0.0, 0.01, (10000, 3))
    frames = BodyFrames(src, tris)
    rot = frames.rotations(tgt)
    timing = report["timing"]
    timing["frames_prepare_ms"] = median_ms(lambda: BodyFrames(src, tris), args.repeat)
    timing["arap_rotations_ms"] = median_ms(lambda: frames.rotations(tgt), args.repeat)
    for k in (6, 20):
        timing[f"bind_10k_k{k}_ms"] = median_ms(lambda: frames.bind(pts, k), args.repeat)
    bind = frames.bind(pts, 6)
    for m in ("lbs", "dqs"):
        timing[f"blend_10k_{m}_ms"] = median_ms(
            lambda: frames.transfer(pts, tgt, m, rotations=rot, binding=bind), args.repeat)
        timing[f"transfer_call_10k_{m}_ms"] = median_ms(
            lambda: transfer(pts, src, tgt, method=m, model=model), args.repeat)
    say("timing (median of %d, ms): " % args.repeat + ", ".join(f"{k[:-3]} {v:.1f}" for k, v in timing.items()))

    if not GARMENTS.is_dir():
        say("../shared not present: garment tables skipped")
        if args.json:
            print(json.dumps(report))
        return

    bodies, frames_of, colliders = {}, {}, {}
    sweep = {k: [] for k in K_SWEEP}
    rows, time_rows = [], []
    for obj in sorted(GARMENTS.glob("*/*.obj")):
        g = load_garment(obj)
        b = parse_mhclo(g.mhclo_path)
        gender = b.gender or "female"
        if gender not in bodies:
            bodies[gender] = _targets(morpher, measurer, gender, report["notes"])
            source = model.default_verts(gender)
            frames_of[gender] = (source, BodyFrames(source, tris))
            colliders[gender] = [MeshCollider(v[:N_BODY], tris) for _, v in bodies[gender]]
            colliders[gender + "-source"] = MeshCollider(source[:N_BODY], tris)
        source, fr = frames_of[gender]
        edges = g.mesh.edges()
        gtris = g.mesh.triangles()
        fit_src = evaluate_mhclo(b, source)
        own = colliders[gender + "-source"].penetration(g.verts)
        entry = {"vertices": g.mesh.n_verts, "gender": gender, "inside_own_body": own["inside_count"],
                 "depth_own_body_mm": 1000 * own["max_depth_m"],
                 "mhclo_fit_inside_own_body": colliders[gender + "-source"].penetration(fit_src)["inside_count"],
                 "targets": {}}
        times = {m: [] for m in METHODS}
        for (label, target), coll in zip(bodies[gender], colliders[gender]):
            rot = fr.rotations(target)
            per = {}
            for m in METHODS:
                if m in ("lbs", "dqs"):
                    def run(m=m):
                        return fr.transfer(g.verts, target, m, rotations=rot, binding=fr.bind(g.verts, 6))
                else:
                    def run(m=m):
                        return transfer(g.verts, source, target, method=m, mhclo=b, model=model)
                times[m].append(median_ms(run, args.repeat))
                pos = run()
                per[m] = _metrics(pos, fit_src if m == "mhclo" else g.verts, edges, gtris, coll)
            for k in K_SWEEP:
                t = median_ms(lambda: fr.transfer(g.verts, target, "dqs", k=k, rotations=rot), args.repeat)
                pos = fr.transfer(g.verts, target, "dqs", k=k, rotations=rot)
                sweep[k].append(dict(_metrics(pos, g.verts, edges, gtris, coll), ms=t))
            entry["targets"][label] = per
        entry["ms"] = {m: float(np.median(v)) for m, v in times.items()}
        report["garments"][obj.stem] = entry
        for m in METHODS:
            ts = [entry["targets"][lab][m] for lab in entry["targets"]]
            rows.append([obj.stem, m, f"{entry['ms'][m]:.2f}", f"{np.mean([t['inside'] for t in ts]):.0f}",
                         f"{max(t['depth_mm'] for t in ts):.1f}", f"{100 * np.mean([t['dist_mean'] for t in ts]):.2f}",
                         f"{100 * max(t['dist_p99'] for t in ts):.1f}",
                         f"{100 * max(t['dist_max'] for t in ts):.1f}",
                         f"{min(t['area_pct'] for t in ts):+.1f}..{max(t['area_pct'] for t in ts):+.1f}"])
        time_rows.append([obj.stem, str(g.mesh.n_verts), str(entry["inside_own_body"]),
                          str(entry["mhclo_fit_inside_own_body"])] + [f"{entry['ms'][m]:.2f}" for m in METHODS[1:]])

    for k in K_SWEEP:
        s = sweep[k]
        report["k_sweep"][k] = {"inside_mean": float(np.mean([x["inside"] for x in s])),
                                "depth_max_mm": float(max(x["depth_mm"] for x in s)),
                                "dist_mean_pct": 100 * float(np.mean([x["dist_mean"] for x in s])),
                                "dist_p99_pct": 100 * float(max(x["dist_p99"] for x in s)),
                                "dist_max_pct": 100 * float(max(x["dist_max"] for x in s)),
                                "area_pct_mean_abs": float(np.mean([abs(x["area_pct"]) for x in s])),
                                "ms_median": float(np.median([x["ms"] for x in s]))}
    if args.json:
        print(json.dumps(report))
        return

    from vfit_cli._common import fmt_table

    for n in report["notes"]:
        print("note:", n)
    print(f"\ntargets per gender: {', '.join(lab for lab, _ in next(iter(bodies.values())))} "
          "(* = nearest reachable)")
    print("\nper garment and method, over the 6 target bodies (inside: mean count; depth, distortion p99/max: "
          "worst; compare inside with 'inside own' below: the garments already cross their own body)")
    print(fmt_table(rows, ["garment", "method", "ms", "inside", "depth mm", "dist mean %", "dist p99 %", "dist max %",
                                 "area %"]))
    print("\ntime vs vertex count (ms, median over targets; lbs/dqs = bind + blend, ARAP frames apart)")
    print(fmt_table(time_rows, ["garment", "verts", "inside own", "mhclo fit inside own"] + list(METHODS[1:])))
    print("\nK sweep, dqs, all garments x targets")
    print(fmt_table([[str(k), f"{v['inside_mean']:.0f}", f"{v['depth_max_mm']:.1f}", f"{v['dist_mean_pct']:.2f}",
                      f"{v['dist_p99_pct']:.1f}", f"{v['dist_max_pct']:.1f}", f"{v['area_pct_mean_abs']:.2f}",
                      f"{v['ms_median']:.2f}"]
                     for k, v in report["k_sweep"].items()],
                    ["K", "inside", "depth mm", "dist mean %", "dist p99 %", "dist max %", "|area| %", "ms"]))


if __name__ == "__main__":
    main()
