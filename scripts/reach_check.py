"""Check the morph's reach (issue 11) with a tape independent of the code under test.

    python scripts/reach_check.py             # the issue's list of bodies, each built by `vfit morph`
    python scripts/reach_check.py --population [--no-tape]
                                               # the 1st/99th percentile bodies of the survey, likewise

Every body is re-measured by tests/tape.py (trimesh sections + scipy hulls, its own bust points), its
stature from the vertices and its mass as trimesh's enclosed volume x 985 kg/m^3. Prints one row per
body: the largest girth/height error (mm), the mass error (kg), the time, and the warnings.

Population bodies: for each gender and each of height, mass, bust, waist, hips, the value at the 1st
and at the 99th percentile with the other four at the survey's regression on it (how they occur
together), plus the four diagonal corners of the 98 % height-mass ellipse with the girths regressed on
them; all five are then given as targets.
"""
import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from tape import breast_vertices, tape_measure  # noqa: E402
from test_reach import REACH  # noqa: E402  (issue 11's list: one copy, the tests')

DENSITY = 985.0
Z99 = 2.3263
def independent(verts, quads, targets_cm, weight_kg, breasts, tape=True, chest=False):
    """(largest |error| mm over the targets, mass error kg or None) measured without vfit's code; ``chest``: a
    man's body, whose bust is his chest girth under the armpits (tests/tape.py)."""
    import trimesh

    v = np.asarray(verts)[:13380]
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    got = {"height": float(v[:, 1].max() - v[:, 1].min())}
    if tape and set(targets_cm) & {"bust", "underbust", "waist", "hips"}:
        got.update(tape_measure(v, quads, breasts, chest))
    err = max((abs(got[k] * 100 - c) * 10 for k, c in targets_cm.items() if k in got), default=0.0)
    mass = trimesh.Trimesh(v, tris, process=False).volume * DENSITY
    return err, (mass - weight_kg if weight_kg is not None else None), mass


def _obj_vertices(path):
    """The ``v`` lines of an OBJ in file order (no loader that would split vertices at UV seams)."""
    with open(path) as fh:
        return np.array([[float(t) for t in ln.split()[1:4]] for ln in fh if ln.startswith("v ")])


def build(tmp, gender, cm, kg):
    """Build a body by `vfit morph` (a process, as a user runs it): (vertices or None, seconds, warnings or the
    error)."""
    exe = Path(sys.executable).parent / "vfit"
    out, rep = Path(tmp) / "b.obj", Path(tmp) / "b.json"
    args = [str(exe), "morph", "--gender", gender, "-o", str(out), "--json", str(rep), "--quiet"]
    for k, v in cm.items():
        args += [f"--{k}", repr(float(v))]
    if kg is not None:
        args += ["--weight", repr(float(kg))]
    t = time.perf_counter()
    p = subprocess.run(args, capture_output=True, text=True)
    dt = time.perf_counter() - t
    if p.returncode:
        return None, dt, p.stderr.strip()
    return _obj_vertices(out), dt, "; ".join(json.loads(rep.read_text())["warnings"])


def run_list(quads, breasts):
    print(f"{'body':18s} {'max err mm':>10s} {'mass err kg':>11s} {'mass kg':>8s} {'CLI s':>6s}  warnings")
    with tempfile.TemporaryDirectory() as tmp:
        for name, gender, cm, kg in REACH:
            verts, dt, text = build(tmp, gender, cm, kg)
            if verts is None:
                print(f"{name:18s} FAILED ({dt:.2f} s): {text}")
                continue
            err, dm, mass = independent(verts, quads, cm, kg, breasts, chest=gender == "male")
            dm_text = f"{dm:+.3f}" if dm is not None else "-"
            print(f"{name:18s} {err:10.3f} {dm_text:>11s} {mass:8.1f} {dt:6.2f}  {text}", flush=True)


def population_bodies(pop):
    """(label, targets m, mass kg) of the 1st/99th percentile bodies (see the module docstring)."""
    names = ("height", "mass", "bust", "waist", "hips")
    out = []
    for k in names:
        for z in (-Z99, Z99):
            given = {k: pop.quantile(k, z)}
            med, _ = pop.predict(given)
            body = {**{n: med[n] for n in names if n != k}, **given}
            out.append((f"{k} {'1st' if z < 0 else '99th'}", body))
    hm = [0, 1]
    c = np.linalg.cholesky(pop.cov[np.ix_(hm, hm)])
    radius = np.sqrt(-2 * np.log(0.02))  # the 98 % ellipse of a bivariate normal
    for a in (45, 135, 225, 315):
        y = pop.mu[hm] + c @ (radius * np.array([np.cos(np.radians(a)), np.sin(np.radians(a))]))
        given = {"height": float(np.exp(y[0])), "mass": float(np.exp(y[1]))}
        med, _ = pop.predict(given)
        out.append((f"H-M ellipse {a} deg", {**given, **{n: med[n] for n in names[2:]}}))
    return out


def run_population(model, quads, breasts, tape):
    from vfit_engine.body.morph import Morpher

    morpher = Morpher(model)
    print(f"{'gender':7s} {'body':18s} {'height':>6s} {'mass':>6s} {'bust':>6s} {'waist':>6s} {'hips':>6s} "
          f"{'max err mm':>10s} {'mass err kg':>11s} {'CLI s':>6s}")
    with tempfile.TemporaryDirectory() as tmp:
        for gender in ("female", "male"):
            g = 0.0 if gender == "female" else 1.0
            for label, body in population_bodies(morpher.population(g)):
                cm = {k: v * 100 for k, v in body.items() if k != "mass"}
                row = f"{gender:7s} {label:18s} " + " ".join(f"{body[k] * (1 if k == 'mass' else 100):6.1f}"
                                                          for k in ("height", "mass", "bust", "waist", "hips"))
                verts, dt, text = build(tmp, gender, cm, body["mass"])
                if verts is None:
                    print(f"{row} FAILED ({dt:.2f} s): {text}")
                    continue
                err, dm, _ = independent(verts, quads, cm, body["mass"], breasts, tape, gender == "male")
                print(f"{row} {err:10.3f} {dm:+11.3f} {dt:6.2f}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--population", action="store_true", help="the survey's 1st/99th percentile bodies")
    ap.add_argument("--no-tape", action="store_true", help="population: height and mass only (fast)")
    args = ap.parse_args()
    from vfit_engine.body.model import BodyModel

    model = BodyModel.load()
    breasts = breast_vertices()
    if args.population:
        run_population(model, model.body_quads, breasts, not args.no_tape)
    else:
        run_list(model.body_quads, breasts)


if __name__ == "__main__":
    main()
