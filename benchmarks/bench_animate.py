"""Benchmark of animated fitting (vfit_engine.animate): a garment in motion, the time per frame split into posing,
collision and cloth, with the exact moving body and with spheres along the bones, on the Gauss-Seidel and the
projective-dynamics solver, side by side.

Per solver, one rest drape (the drape path with that solver: ``DrapeSettings`` or ``drape.settings.projective``),
then ``--frames`` frames of the motion at 30 frames per second for each collider, in the same process; the
figures of every frame are measured (and timed apart). Prints, per solver and collider, ms per frame (posing,
collision, cloth, their sum: the simulation; figures apart), the animation frames per second of wall time, the
worst frame's figures, the frames that miss the quality bars and the projective solver's matrix refactors a frame.

Usage: ``python benchmarks/bench_animate.py [--garment male_casualsuit02] [--frames 30] [--solvers verlet,pd]
[--motion walk | --motion ../shared/assets/poses/sit01.bvh --blend 1.5] [--json]``
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
    ap.add_argument("--solvers", default="verlet", help="verlet, pd or both (verlet,pd)")
    ap.add_argument("--motion", default="walk", help="walk or a BVH file")
    ap.add_argument("--blend", type=float, default=0.5, help="seconds the motion is blended in over")
    ap.add_argument("--save", default=None, help="a folder: each run's frames --save-every apart as OBJ "
                                                 "(SOLVER_COLLIDER_frame_NNNN.obj, body_NNNN.obj), to render")
    ap.add_argument("--save-every", type=int, default=10)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    from vfit_engine.animate.loop import AnimateSettings, run_animation
    from vfit_engine.animate.motion import load_clip
    from vfit_engine.animate.outputs import quality
    from vfit_engine.body.bodyio import write_body
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import default_body
    from vfit_engine.drape import DrapeSettings, prepare_drape, run_drape
    from vfit_engine.drape.settings import projective
    from vfit_engine.drape.setup import garment_gender
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.io.mesh import write_mesh

    path = (Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj" if args.garment == "skirt"
            else SHARED / args.garment / f"{args.garment}.obj")
    model = BodyModel.load()
    g = load_garment(path)
    body = default_body(model, garment_gender(g) or "female")
    def saver(name):
        def save(k, body_verts, pos, figures, travel):
            if args.save and k % args.save_every == 0:
                write_mesh(str(Path(args.save) / f"{name}_frame_{k:04d}.obj"), g.mesh.with_verts(pos))
                write_body(str(Path(args.save) / f"body_{k:04d}.obj"), model, body_verts)
        return save

    if args.save:
        Path(args.save).mkdir(parents=True, exist_ok=True)
    out = dict(garment=args.garment, vertices=int(g.mesh.n_verts), frames=args.frames, motion=args.motion, runs={})
    clip = load_clip(model, args.motion, until=args.frames / 30.0)
    for solver in args.solvers.split(","):
        # as vfit animate drapes at rest (animate_garment: no ground in an animation)
        dst = DrapeSettings(ground=False) if solver == "verlet" else projective(DrapeSettings(ground=False))
        setup = prepare_drape(g, body, model, settings=dst)
        t = time.perf_counter()
        drape = run_drape(setup, dst)
        rest = dict(rest_drape_s=round(time.perf_counter() - t, 2), rest_settled=drape.converged,
                    rest_frames=drape.frames)
        for kind in args.colliders.split(","):
            st = AnimateSettings(frames=args.frames, collider=kind, blend_s=args.blend)
            res = run_animation(setup, drape.pos, clip, model, st, dst, on_frame=saver(f"{solver}_{kind}"))
            ms = {k: round(1000 * v / args.frames, 1) for k, v in res.timings.items()}
            worst = {k: round(max(f[k] for f in res.figures[1:]), 3) for k in
                     ("surface_max_depth_mm", "surface_inside_percent", "p99_strain", "max_strain")}
            q = quality(res.figures)
            out["runs"][f"{solver} {kind}"] = dict(
                **rest, ms_per_frame=ms, fps_wall=round(args.frames / res.timings["simulation"], 2),
                collision_share=round(res.timings["collision"] / res.timings["simulation"], 3), worst=worst,
                failed_frames=len(q["failed_frames"]), failed=[f["frame"] for f in q["failed_frames"]],
                refactors_per_frame=round(res.info["matrix_refactors"] / args.frames, 2),
                contact_queries_per_frame=int(res.info["contact_queries"] / args.frames),
                frames=[{k: round(f[k], 3) for k in ("surface_max_depth_mm", "surface_inside_percent", "p99_strain")}
                        for f in res.figures], collider=res.info["collider"])
    if args.json:
        print(json.dumps(out))
        return
    print(f"{args.garment} ({out['vertices']} vertices), {args.motion}, {args.frames} frames at 30/s")
    print(f"{'solver collider':<20}{'rest s':>7}{'posing':>8}{'collision':>11}{'cloth':>8}{'sim':>8}{'fps':>7}"
          f"{'figures':>9}{'depth mm':>10}{'inside %':>10}{'p99 %':>7}{'failed':>8}{'refac':>7}")
    for name, r in out["runs"].items():
        ms, w = r["ms_per_frame"], r["worst"]
        print(f"{name:<20}{r['rest_drape_s']:>7.1f}{ms['posing']:>8.1f}{ms['collision']:>11.1f}{ms['cloth']:>8.1f}"
              f"{ms['simulation']:>8.1f}{r['fps_wall']:>7.2f}{ms['figures']:>9.1f}{w['surface_max_depth_mm']:>10.2f}"
              f"{w['surface_inside_percent']:>10.3f}{100 * w['p99_strain']:>7.1f}{r['failed_frames']:>8}"
              f"{r['refactors_per_frame']:>7.2f}")


if __name__ == "__main__":
    main()
