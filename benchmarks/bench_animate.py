"""Benchmark of animated fitting (vfit_engine.animate): a garment walking, the time per frame split into posing,
collision and cloth, with the exact moving body and with spheres along the bones, side by side.

One rest drape (the drape path), then ``--frames`` frames of the built-in walk at 30 frames per second for each
collider, in the same process; the figures of every frame are measured (and timed apart). Prints, per
collider, ms per frame (posing, collision, cloth, their sum: the simulation; figures apart), the animation
frames per second of wall time, the worst frame's figures and the frames that miss the quality bars.

Usage: ``python benchmarks/bench_animate.py [--garment male_casualsuit02] [--frames 30] [--json]``
(``NUMBA_NUM_THREADS=1`` to run the cloth on one thread).
"""
import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SHARED = Path(__file__).resolve().parents[2] / "shared" / "assets" / "garments"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", default="male_casualsuit02", help="a shared MakeHuman outfit, or 'skirt' (the demo)")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--colliders", default="mesh,bone-spheres")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    from vfit_engine.animate.loop import AnimateSettings, run_animation
    from vfit_engine.animate.motion import load_clip
    from vfit_engine.animate.outputs import quality
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import default_body
    from vfit_engine.drape import DrapeSettings, prepare_drape, run_drape
    from vfit_engine.drape.setup import garment_gender
    from vfit_engine.garment.garment import load_garment

    path = (Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj" if args.garment == "skirt"
            else SHARED / args.garment / f"{args.garment}.obj")
    model = BodyModel.load()
    g = load_garment(path)
    body = default_body(model, garment_gender(g) or "female")
    dst = DrapeSettings(ground=False)  # as vfit animate drapes at rest (animate_garment: no ground in an animation)
    setup = prepare_drape(g, body, model, settings=dst)
    t = time.perf_counter()
    drape = run_drape(setup, dst)
    out = dict(garment=args.garment, vertices=int(g.mesh.n_verts), frames=args.frames,
               rest_drape_s=round(time.perf_counter() - t, 2), rest_settled=drape.converged, colliders={})
    clip = load_clip(model, "walk")
    for kind in args.colliders.split(","):
        res = run_animation(setup, drape.pos, clip, model, AnimateSettings(frames=args.frames, collider=kind), dst)
        ms = {k: round(1000 * v / args.frames, 1) for k, v in res.timings.items()}
        worst = {k: round(max(f[k] for f in res.figures[1:]), 3) for k in
                 ("surface_max_depth_mm", "surface_inside_percent", "p99_strain", "max_strain")}
        q = quality(res.figures)
        out["colliders"][kind] = dict(ms_per_frame=ms, fps_wall=round(args.frames / res.timings["simulation"], 2),
                                      collision_share=round(res.timings["collision"] / res.timings["simulation"], 3),
                                      worst=worst, failed_frames=len(q["failed_frames"]),
                                      contact_queries_per_frame=int(res.info["contact_queries"] / args.frames),
                                      collider=res.info["collider"])
    if args.json:
        print(json.dumps(out))
        return
    print(f"{args.garment} ({out['vertices']} vertices) walking, {args.frames} frames at 30/s; rest drape "
          f"{out['rest_drape_s']} s ({'settled' if drape.converged else 'not settled'})")
    print(f"{'collider':<14}{'posing':>8}{'collision':>11}{'cloth':>8}{'sim':>8}{'fps':>7}{'figures':>9}"
          f"{'depth mm':>10}{'inside %':>10}{'p99 %':>7}{'failed':>8}")
    for kind, r in out["colliders"].items():
        ms, w = r["ms_per_frame"], r["worst"]
        print(f"{kind:<14}{ms['posing']:>8.1f}{ms['collision']:>11.1f}{ms['cloth']:>8.1f}{ms['simulation']:>8.1f}"
              f"{r['fps_wall']:>7.2f}{ms['figures']:>9.1f}{w['surface_max_depth_mm']:>10.2f}"
              f"{w['surface_inside_percent']:>10.3f}{100 * w['p99_strain']:>7.1f}{r['failed_frames']:>8}")


if __name__ == "__main__":
    main()
