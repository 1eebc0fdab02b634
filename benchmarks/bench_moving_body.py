"""Benchmark of the moving body's exact collider (vfit_engine.collide.moving_body.MovingBodyCollider) on the walk.

The default man walking (the built-in stride at 1.3 m/s, 30 frames per second), the body parts within 5 cm
of a garment on him (as an animation takes them) (``--garment``, a shared MakeHuman outfit; or the whole body with ``--all``):

* ``advance``: one frame's grid (binning along the triangles' paths, lists, sides, bounds), median over the
  stride; beside it ``MeshCollider.refit`` of the whole body to the same frames (the still body's grid
  rebuilt), measured in the same run;
* ``at``: the surface put at one substep's time (records, pseudo-normals, motion field);
* queries at mid-frame: 25,000 points within +-1.5 cm of the surface with the contact generation's band
  (12 mm out, any depth in), and 100,000 with ``max_out = 0`` (the inside test of the figures), after
  ``settle_bounds``; beside them a still ``MeshCollider`` built at the same pose.

Usage: ``python benchmarks/bench_moving_body.py [--garment male_casualsuit02] [--cell F] [--margin F] [--json]``
(``--cell``/``--margin``: the grid's cell in mean triangle edges and the exact band in cells).
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SHARED = Path(__file__).resolve().parents[2] / "shared" / "assets" / "garments"


def _near(body, tris, garment_name, near):
    """The triangles the garment placed on ``body`` (its file's own place) collides with, as an animation
    takes them (:func:`vfit_engine.animate.colliders.near_triangles`): cheap, no drape needed for which are near."""
    from vfit_engine.animate.colliders import near_triangles
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.segment import skin_parts
    from vfit_engine.garment.garment import load_garment

    g = load_garment(SHARED / garment_name / f"{garment_name}.obj")
    return near_triangles(body, tris, g.verts, near, skin_parts(BodyModel.load()))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", default="male_casualsuit02")
    ap.add_argument("--all", action="store_true", help="the whole body, no garment")
    ap.add_argument("--cell", type=float, default=None, help="cell edge in mean edges of the active triangles")
    ap.add_argument("--margin", type=float, default=None, help="exact band in cells")
    ap.add_argument("--frames", type=int, default=16)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    from vfit_engine.animate.motion import Poser, load_clip
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import default_body
    from vfit_engine.collide.body_mesh import MeshCollider
    from vfit_engine.collide.moving_body import MovingBodyCollider

    model = BodyModel.load()
    body = default_body(model, "male")
    tris = model.body_tris
    clip = load_clip(model, "walk")
    poser = Poser(model, body.verts)
    poses = np.stack([poser.pose(*clip.sample(k / 30.0))[0] for k in range(args.frames + 1)])
    active = None if args.all else _near(poses[0], tris, args.garment, 0.05)
    lo, hi = poses.reshape(-1, 3).min(axis=0), poses.reshape(-1, 3).max(axis=0)
    sel = np.ones(len(tris), bool) if active is None else active
    a, b, c = (poses[0][tris[sel][:, k]] for k in range(3))
    mean_edge = float(np.mean([np.linalg.norm(u - w, axis=1).mean() for u, w in ((b, a), (c, b), (a, c))]))
    kw = {}
    if args.cell is not None:
        kw["cell"] = args.cell * mean_edge
    if args.margin is not None:
        kw["margin"] = args.margin * kw.get("cell", mean_edge)
    t = time.perf_counter()
    col = MovingBodyCollider(poses[0], tris, box=(lo, hi), active=active, **kw)
    out = dict(active_triangles=int(sel.sum()), cell_mm=1000 * col.cell, margin_mm=1000 * col.margin,
               grid_cells=int(col.ncells), first_s=time.perf_counter() - t)
    adv, ats, pairs = [], [], []
    for k in range(1, args.frames + 1):
        t = time.perf_counter()
        col.advance(poses[k])
        adv.append(time.perf_counter() - t)
        pairs.append(col.grid.cell_tris.size)
        t = time.perf_counter()
        for s in range(1, 17):
            col.at(s / 16)
        ats.append((time.perf_counter() - t) / 16)
    out.update(advance_ms=1000 * float(np.median(adv)), advance_max_ms=1000 * max(adv), at_ms=1000 * float(np.median(ats)),
               pairs=int(np.median(pairs)), seconds={k: round(v / args.frames * 1000, 2) for k, v in col.timings.items()})
    still = MeshCollider(poses[0], tris[sel])
    refits = []
    for k in range(1, min(args.frames, 6) + 1):
        t = time.perf_counter()
        still.refit(poses[k])
        refits.append(time.perf_counter() - t)
    out["refit_ms"] = 1000 * float(np.median(refits))
    # queries at mid-frame of the last interval
    col.at(0.5)
    rng = np.random.default_rng(0)
    pick = np.flatnonzero(sel)[rng.integers(0, sel.sum(), 125000)]
    bary = rng.dirichlet([1.0, 1.0, 1.0], 125000)
    pts = np.einsum("ij,ijk->ik", bary, col.verts[tris[pick]]) + rng.normal(0.0, 0.015, (125000, 3))
    contact, samples = np.ascontiguousarray(pts[:25000]), np.ascontiguousarray(pts[25000:])
    ref = MeshCollider(col.verts, tris[sel])
    for name, p, mo, mi in (("contact", contact, 0.012, np.inf), ("inside", samples, 0.0, np.inf)):
        for who, q in (("moving", col), ("still", ref)):
            if who == "moving" and name == "inside":
                col.settle_bounds()
            q.query(p[:100], mo, mi)
            times = []
            for _ in range(3):
                t = time.perf_counter()
                q.query(p, mo, mi)
                times.append(time.perf_counter() - t)
            out[f"{name}_{who}_ms"] = 1000 * min(times)
    if args.json:
        print(json.dumps(out))
        return
    print(f"walk of the default man, {args.frames} frames; {out['active_triangles']} triangles "
          f"({'whole body' if active is None else args.garment + ' within 5 cm'}); cell {out['cell_mm']:.1f} mm, "
          f"margin {out['margin_mm']:.1f} mm, {out['grid_cells']} cells")
    print(f"advance: {out['advance_ms']:.1f} ms median (max {out['advance_max_ms']:.1f}), {out['pairs']} pairs; "
          f"{out['seconds']} ms per frame by part")
    print(f"at (one substep): {out['at_ms']:.2f} ms;  MeshCollider.refit of the same triangles: {out['refit_ms']:.0f} ms")
    print(f"25k contact queries: moving {out['contact_moving_ms']:.1f} ms, still {out['contact_still_ms']:.1f} ms;  "
          f"100k inside tests: moving {out['inside_moving_ms']:.1f} ms, still {out['inside_still_ms']:.1f} ms")


if __name__ == "__main__":
    main()
