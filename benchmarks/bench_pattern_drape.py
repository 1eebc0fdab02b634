"""A sewing pattern from its file to a settled drape, against the same garment given as an OBJ on the body.

The issue's speed bar for patterns: the Garment-Pattern-Generator four-panel skirt (``../shared/assets/patterns``)
read, meshed, placed, sewn and draped to rest on the default female body (``vfit drape PATTERN``'s path:
:func:`vfit_engine.pattern.load.load`, :func:`vfit_engine.drape.sew.prepare_pattern_drape`, ``run_drape`` on the
projective solver) takes at most 3 times what the same skirt takes given as an OBJ already on the body (``vfit
drape GARMENT.obj``'s path: ``load_garment``, ``prepare_drape``, ``run_drape`` on the product's solver). The OBJ is
the pattern's own settled drape with its seams welded (one vertex per sewn point), written in metres: the skirt
as a 3D garment file of it would be, its rest shape the draped one.

Each path is timed from its file to the settled drape (wall time, warm: one untimed run of each first, so no
kernel compiles in the timed ones), ``--repeat`` times, median reported, with its frames and frame loop time.

    python benchmarks/bench_pattern_drape.py [--pattern PATH] [--repeat 3] [--json]
"""
import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

PATTERNS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "patterns"


def pattern_drape(path, body, model):
    """The pattern at ``path`` from its file to a settled drape: (DrapeSetup, DrapeResult, seconds)."""
    from vfit_engine.drape import DrapeSettings, run_drape
    from vfit_engine.drape.settings import projective
    from vfit_engine.drape.sew import prepare_pattern_drape
    from vfit_engine.pattern.load import load

    t0 = time.perf_counter()
    settings = projective(DrapeSettings())
    setup = prepare_pattern_drape(load(path)[0], body, model, settings=settings)
    result = run_drape(setup, settings)
    return setup, result, time.perf_counter() - t0


def welded_obj(setup, pos, path):
    """Write the sewn drape ``pos`` of ``setup`` as one garment mesh, its seams welded, to ``path`` (OBJ, m)."""
    from vfit_engine.io.mesh import write_mesh
    from vfit_engine.io.meshdata import MeshData
    from vfit_engine.pattern.weld import weld_index

    mesh = setup.garment.mesh
    index = weld_index(mesh.n_verts, setup.seams)
    verts = np.zeros((int(index.max()) + 1, 3))
    verts[index] = pos  # a sewn point's vertices lie within the seams' tolerance of each other: any of them will do
    faces = index[mesh.triangles()]
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    faces = faces[keep]
    write_mesh(path, MeshData(verts, np.arange(0, faces.size + 1, 3, dtype=np.int64), faces.ravel()))


def obj_drape(path, body, model):
    """The OBJ at ``path`` (metres, on the body) from its file to a settled drape: (DrapeResult, seconds)."""
    from vfit_engine.drape import DrapeSettings, prepare_drape, run_drape
    from vfit_engine.garment.garment import load_garment

    t0 = time.perf_counter()
    settings = DrapeSettings()
    setup = prepare_drape(load_garment(path, units="m"), body, model, settings=settings)
    result = run_drape(setup, settings)
    return result, time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pattern", default=str(PATTERNS / "gpg_skirt_4_panels.json"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if not Path(args.pattern).is_file():
        print(f"{args.pattern}: not found (the shared assets: ../shared)", file=sys.stderr)
        return 1
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import default_body

    model = BodyModel.load()
    body = default_body(model, "female")
    with tempfile.TemporaryDirectory() as tmp:
        obj = Path(tmp) / "skirt_sewn.obj"
        setup, first, _ = pattern_drape(args.pattern, body, model)  # warm (kernels), and the OBJ's shape
        welded_obj(setup, first.pos, obj)
        obj_drape(obj, body, model)  # warm
        runs = {"pattern": [], "obj": []}
        for _ in range(args.repeat):
            _, r, s = pattern_drape(args.pattern, body, model)
            runs["pattern"].append((s, r.frames, r.converged, r.wall_time))
            r, s = obj_drape(obj, body, model)
            runs["obj"].append((s, r.frames, r.converged, r.wall_time))
    out = {}
    for name, rows in runs.items():
        s, frames, converged, loop = (list(c) for c in zip(*rows))
        out[name] = dict(total_s=float(np.median(s)), frames=frames, settled=converged,
                         loop_s=float(np.median(loop)), runs_s=[round(v, 2) for v in s])
    out["ratio"] = out["pattern"]["total_s"] / out["obj"]["total_s"]
    out["vertices"] = dict(pattern=int(setup.garment.mesh.n_verts))
    if args.json:
        print(json.dumps(out))
    else:
        for name in ("pattern", "obj"):
            o = out[name]
            print(f"{name:8s} file -> settled {o['total_s']:.2f} s median (runs {o['runs_s']} s), frame loop "
                  f"{o['loop_s']:.2f} s, frames {o['frames']}, settled {o['settled']}")
        print(f"pattern / OBJ: {out['ratio']:.2f} x (the issue's bar: <= 3 x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
