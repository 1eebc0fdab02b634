"""Collider comparison: the exact body mesh against spheres, ellipsoids and convex hulls fitted to it.

For a shared garment on the default body of its gender, each collider type is fitted to the body
(:func:`vfit_engine.drape.colliders.fitted_collider`, nothing placed by hand), its coverage of the body
measured (gaps where cloth can sink in, overshoot where it floats: :mod:`vfit_engine.collide.coverage`;
spheres with the skin the solver holds out), and the garment draped with it the product's way
(``prepare_drape(..., collider=kind)`` then ``run_drape``, default settings). Reported per type: fit
time, coverage, penetration of the draped garment into the TRUE body (the exact mesh: the cloth surface
sampled over its triangles, and its vertices), yarn strain against the garment as given, collision time
per substep and the total drape time. The mesh and sphere contacts run inside the fused substep kernel:
the mesh's collision time is estimated as (exact queries made per substep) x (time per query, measured
on the draped garment); the spheres' is not separable (``-``); ellipsoids and hulls project the cloth
after every substep and are timed.

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


def _coverage_collider(kind, spheres, project):
    """What :func:`vfit_engine.collide.coverage.coverage` measures: the spheres as the solver holds them
    out (radius with its skin), or the fitted ellipsoids / hulls."""
    from vfit_engine.collide.spheres import SphereCollider

    if spheres is not None:
        return SphereCollider(spheres[:, :3], spheres[:, 3], skin=0.0)
    return project.inner


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", default="male_casualsuit02")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if not GARMENTS.is_dir():
        print("../shared not present", file=sys.stderr)
        return 1

    from vfit_cli._common import fmt_table
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import default_body
    from vfit_engine.body.segment import segment
    from vfit_engine.collide.coverage import coverage
    from vfit_engine.drape import DrapeDiverged, DrapeSettings, prepare_drape, run_drape
    from vfit_engine.drape.colliders import fitted_collider
    from vfit_engine.drape.setup import garment_gender
    from vfit_engine.garment.garment import load_garment

    model = BodyModel.load()
    g = load_garment(GARMENTS / args.garment / f"{args.garment}.obj")
    gender = garment_gender(g) or "female"
    body = default_body(model, gender)
    st = DrapeSettings()
    t0 = time.perf_counter()
    seg = segment(model, body.verts)
    t_seg = time.perf_counter() - t0
    # first call: JIT compile or cache load of every kernel used below, on 3 frames
    short = DrapeSettings(max_frames=3)
    for kind in KINDS:
        try:
            run_drape(prepare_drape(g, body, model, collider=kind, settings=short), short)
        except DrapeDiverged:
            pass

    per_part = {}
    rows, out = [], dict(garment=args.garment, gender=gender, vertices=g.mesh.n_verts, segmentation_s=round(t_seg, 3),
                         colliders={})
    for kind in KINDS:
        t0 = time.perf_counter()
        setup = prepare_drape(g, body, model, collider=kind, settings=st)
        t_prepare = time.perf_counter() - t0
        exact = setup.collider
        t_fit, cov = 0.0, None
        if kind != "mesh":
            # fitted again on its own to time it (prepare_drape fits it among the rest)
            t0 = time.perf_counter()
            spheres, project = fitted_collider(kind, model, body, exact, st)
            t_fit = time.perf_counter() - t0
            full_cov = coverage(_coverage_collider(kind, spheres, project), body.surface, seg.labels, seg.names, exact)
            cov = full_cov["total"]
            per_part[kind] = full_cov["parts"]
        t0 = time.perf_counter()
        try:
            res = run_drape(setup, st)
        except DrapeDiverged as exc:
            out["colliders"][kind] = dict(diverged=str(exc))
            rows.append([kind, f"{t_fit:.2f}", "-", "-", "-", "diverged", "-", "-", "-", "-", "-", "-"])
            continue
        total = time.perf_counter() - t0 + t_prepare
        m = res.metrics
        coll_ms = None
        if kind == "mesh":
            queries = res.info["contact_queries"] / max(res.steps, 1)
            t1 = time.perf_counter()
            for _ in range(5):
                exact.query(res.pos, max_out=0.006, max_in=np.inf)
            per_query = (time.perf_counter() - t1) / (5 * res.pos.shape[0])
            coll_ms = 1000.0 * queries * per_query
        elif setup.project is not None:
            coll_ms = 1000.0 * setup.project.seconds / max(res.steps, 1)
        rec = dict(fit_s=round(t_fit, 3), coverage=cov, coverage_parts=per_part.get(kind), converged=res.converged,
                   frames=res.frames, surface_max_depth_mm=round(m["surface_max_depth_mm"], 2),
                   surface_inside_percent=round(m["surface_inside_percent"], 2),
                   surface_deeper_than_2mm=m["surface_deeper_than_2mm"],
                   vertex_max_depth_mm=round(m["vertex_max_depth_mm"], 2),
                   vertex_inside_percent=round(m["vertex_inside_percent"], 2),
                   p99_strain=round(m["p99_strain"], 4), max_strain=round(m["max_strain"], 4),
                   shear_p99_deg=round(m["shear_p99_deg"], 2),
                   collision_ms_per_substep=None if coll_ms is None else round(coll_ms, 3),
                   drape_wall_s=round(res.wall_time, 3), drape_total_s=round(total, 3))
        out["colliders"][kind] = rec
        rows.append([kind, f"{t_fit:.2f}",
                     "0 (exact)" if cov is None else f"{100 * cov['outside_fraction']:.1f}",
                     "0" if cov is None else f"{cov['max_gap_mm']:.1f}",
                     "0" if cov is None else f"{cov['overshoot_p95_mm']:.1f} / {cov['overshoot_max_mm']:.1f}",
                     "yes" if res.converged else "NO",
                     f"{m['surface_max_depth_mm']:.1f} / {m['vertex_max_depth_mm']:.1f}",
                     f"{m['surface_inside_percent']:.1f} / {m['vertex_inside_percent']:.1f}",
                     f"{100 * m['p99_strain']:.1f} / {100 * m['max_strain']:.1f}", f"{m['shear_p99_deg']:.1f}",
                     "-" if coll_ms is None else f"{coll_ms:.3f}", f"{total:.2f}"])
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{args.garment} ({g.mesh.n_verts} vertices) on the default {gender} body; segmentation {t_seg:.2f} s")
        print(fmt_table(rows, ["collider", "fit s", "body outside %", "max gap mm", "overshoot p95/max mm",
                               "converged", "true body depth mm surf / vert",
                               "% in true body surf / vert", "yarn strain p99/max %", "shear p99 deg",
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
