"""Collider comparison: the exact body mesh against spheres, ellipsoids and convex hulls fitted to it.

For a shared garment on the default body of its gender, each collider type is fitted to the body
(nothing placed by hand), its coverage of the body measured (gaps where cloth can sink in,
overshoot where it floats: :mod:`vfit_engine.collide.coverage`), and the garment draped with it
(transfer none, default settings). Reported per type: fit time, coverage, penetration of the
draped garment into the TRUE body (the exact mesh), strain, collision time per substep and the
total drape time. The mesh collider's contacts run inside the fused substep kernel, so its
collision time is estimated as (exact queries made per substep) x (time per query, measured on
the draped garment).

    python benchmarks/bench_colliders.py [--garment NAME] [--json]
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

GARMENTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments"
KINDS = ("mesh", "spheres", "bone-spheres", "ellipsoids", "hulls")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", default="male_casualsuit02")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if not GARMENTS.is_dir():
        print("../shared not present", file=sys.stderr)
        return 1

    from vfit_cli._common import fmt_table
    from vfit_engine.body.model import N_BODY, BodyModel
    from vfit_engine.body.segment import segment
    from vfit_engine.collide.bone_spheres import skeleton_bones
    from vfit_engine.collide.body_mesh import MeshCollider
    from vfit_engine.collide.coverage import coverage
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.garment.mhclo import parse_mhclo
    from vfit_engine.sim.colliders import fit_collider
    from vfit_engine.sim.drape import DrapeDiverged, DrapeSettings, drape_garment

    model = BodyModel.load()
    g = load_garment(GARMENTS / args.garment / f"{args.garment}.obj")
    gender = parse_mhclo(g.mhclo_path).gender or "female"
    full = model.default_verts(gender)
    body, tris = np.ascontiguousarray(full[:N_BODY]), model.body_tris
    st = DrapeSettings()
    exact = MeshCollider(body, tris, skin=st.skin, friction=st.friction)
    t0 = time.perf_counter()
    seg = segment(model, full)
    t_seg = time.perf_counter() - t0
    segments = (seg.labels, seg.names)
    bones = skeleton_bones(model, full)
    # first call: JIT compile or cache load of every kernel used below, on 3 frames
    for kind in KINDS:
        try:
            drape_garment(g.mesh, g.pieces, body, body, tris, settings=DrapeSettings(max_frames=3), collider=kind,
                          body_collider=exact, segments=segments, bones=bones)
        except DrapeDiverged:
            pass

    per_part = {}
    rows, out = [], dict(garment=args.garment, gender=gender, vertices=g.mesh.n_verts, segmentation_s=round(t_seg, 3),
                         colliders={})
    for kind in KINDS:
        t0 = time.perf_counter()
        coll = None if kind == "mesh" else fit_collider(kind, body, tris, exact, segments, st, bones)
        t_fit = time.perf_counter() - t0
        full_cov = None if coll is None else coverage(coll, body, seg.labels, seg.names, exact)
        cov = None if full_cov is None else full_cov["total"]
        if full_cov is not None:
            per_part[kind] = full_cov["parts"]
        t0 = time.perf_counter()
        try:
            res = drape_garment(g.mesh, g.pieces, body, body, tris, settings=st, collider=kind, body_collider=exact,
                                segments=segments, bones=bones)
        except DrapeDiverged as exc:
            out["colliders"][kind] = dict(diverged=str(exc))
            rows.append([kind, "-", "-", "-", "-", "diverged", "-", "-", "-", "-", "-"])
            continue
        total = time.perf_counter() - t0
        m = res.metrics
        if kind == "mesh":
            queries = res.settings["contact_queries"] / max(res.steps, 1)
            t1 = time.perf_counter()
            for _ in range(5):
                exact.query(res.pos, max_out=0.006, max_in=np.inf)
            per_query = (time.perf_counter() - t1) / (5 * res.pos.shape[0])
            coll_ms = 1000.0 * queries * per_query
        else:
            coll_ms = 1000.0 * res.collide_time / max(res.steps, 1)
        rec = dict(fit_s=round(t_fit, 3), coverage=cov, coverage_parts=per_part.get(kind), converged=res.converged, frames=res.frames,
                   max_depth_mm=round(m["max_depth_mm"], 2), inside_percent=round(100 * m["inside_fraction"], 2),
                   p99_strain=round(m["p99_strain"], 4), max_strain=round(m["max_strain"], 4),
                   collision_ms_per_substep=round(coll_ms, 3), drape_wall_s=round(res.wall_time, 3),
                   drape_total_s=round(total, 3))
        out["colliders"][kind] = rec
        rows.append([kind, f"{t_fit:.2f}",
                     "0 (exact)" if cov is None else f"{100 * cov['outside_fraction']:.1f}",
                     "0" if cov is None else f"{cov['max_gap_mm']:.1f}",
                     "0" if cov is None else f"{cov['overshoot_p95_mm']:.1f} / {cov['overshoot_max_mm']:.1f}",
                     "yes" if res.converged else "NO", f"{m['max_depth_mm']:.1f}", f"{100 * m['inside_fraction']:.1f}",
                     f"{100 * m['p99_strain']:.1f} / {100 * m['max_strain']:.1f}", f"{coll_ms:.3f}", f"{total:.2f}"])
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{args.garment} ({g.mesh.n_verts} vertices) on the default {gender} body; segmentation {t_seg:.2f} s")
        print(fmt_table(rows, ["collider", "fit s", "body outside %", "max gap mm", "overshoot p95/max mm",
                               "converged", "depth in true body mm", "% inside true body", "strain p99/max %",
                               "collide ms/substep", "drape s"]))
        print("\nper body part: % of its vertices outside the collider (max gap mm) | overshoot p95 / max mm")
        parts = list(next(iter(per_part.values()))) if per_part else []
        prow = [[p] + [f"{100 * c[p]['outside_fraction']:.0f} ({c[p]['max_gap_mm']:.0f}) | "
                       f"{c[p]['overshoot_p95_mm']:.0f} / {c[p]['overshoot_max_mm']:.0f}" if p in c else "-"
                       for c in per_part.values()] for p in parts]
        print(fmt_table(prow, ["part"] + list(per_part)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
