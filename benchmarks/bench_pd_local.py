"""Benchmark of the projective-dynamics local step (issue 32): ``pd_rhs`` and ``contact_forces`` of
:mod:`vfit_engine.kernels.pd`, this checkout's against another commit's, on the arguments a drape gives them.

Cases: the sphere drape (``bench_sphere_drape.make_drape(100, solver="pd", substeps=1)``: 10,000 vertices, ~58 k
hinges) and ``female_casualsuit01`` on the default body (``drape.settings.projective()``: 2,197 vertices, ~12.5 k
hinges, thousands of surface contact points), each run for ``--frames`` frames while the solver's calls of the two
kernels are recorded (:mod:`vfit_engine.sim.solver_pd`'s names wrapped); the last call's arguments are kept. Each
kernel is then called ``--repeat`` times on copies of them, old and new in turn, and the median wall and CPU
(process) time of a call is printed, ms. ``pd_rhs`` is timed fresh (its hinges and springs evaluated: every
``hinge_every``-th iteration) and lagged (them kept); ``iteration`` is what one iteration of the local step costs
with ``hinge_every`` 2: ``contact_forces + (fresh + lagged) / 2``. ``same`` says whether old and new wrote the
same bits, ``diff`` the largest difference relative to the largest entry of ``b`` (``lam`` for the forces).

The old kernels are ``git show REV:vfit_engine/kernels/pd.py`` (default ``--old b29ff13``, the commit before the
local step was made faster), loaded from a temporary folder (compiled there at each run: a few seconds). On a
shared machine the times rise and fall with its load: run it with ``NUMBA_NUM_THREADS=1`` and compare old and new
of the same run. The calls take turns (old fresh, lagged, forces, then new), so each finds the caches as the
others left them, as in the solver, where the global solve runs between two local steps: the sphere's lagged
``pd_rhs`` takes about 1 ms less called over and over alone.

Usage: NUMBA_NUM_THREADS=1 python benchmarks/bench_pd_local.py [--old b29ff13] [--frames 40] [--repeat 15]
       [--case sphere --case suit] [--json]
"""
import argparse
import importlib.util
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
GARMENTS = ROOT / ".." / "shared" / "assets" / "garments"
SUIT = "female_casualsuit01"
#: The commit before the local step was made faster (issue 32)
OLD = "b29ff13"
#: pd_rhs's arguments: the iterate, the outputs (b, gap, count, f_lag) and the lag flag; contact_forces' outputs
#: (lam, nrm, plane and scratch)
X, B, LAG = 0, 38, 42
RHS_OUT = (38, 39, 40, 41)
#: Where b29ff13's pd_rhs took the corners' band in radians (a_lo, a_hi; now only their cosines, at 13 and 14)
OLD_ANGLES = 15
FORCES_OUT = (12, 13, 14, 15, 16, 17)
LAM = 12


def fail(message):
    """A one-line error and exit 2."""
    print(f"bench_pd_local: {message}", file=sys.stderr)
    sys.exit(2)


def old_kernels(rev, folder):
    """The module ``vfit_engine/kernels/pd.py`` of commit ``rev``, loaded from ``folder``."""
    try:
        text = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:vfit_engine/kernels/pd.py"], check=True,
                              capture_output=True, text=True).stdout
    except (OSError, subprocess.CalledProcessError) as exc:
        fail(f"--old {rev}: cannot read vfit_engine/kernels/pd.py at that commit ({type(exc).__name__}); give a "
             "commit of this repository")
    path = Path(folder) / "pd_old.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("pd_old", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def recorded_calls(run):
    """The last arguments the solver gave ``pd_rhs`` and ``contact_forces`` during ``run()`` (references: the
    arrays as they are after it)."""
    import vfit_engine.sim.solver_pd as solver_pd

    last = {}
    saved = {name: getattr(solver_pd, name) for name in ("pd_rhs", "contact_forces")}

    def wrap(name, kernel):
        def call(*args):
            last[name] = args
            return kernel(*args)
        return call

    try:
        for name, kernel in saved.items():
            setattr(solver_pd, name, wrap(name, kernel))
        run()
    finally:
        for name, kernel in saved.items():
            setattr(solver_pd, name, kernel)
    if set(last) != set(saved):
        fail("the drape did not call pd_rhs and contact_forces (does SolverPD still call them by these names?)")
    return last


def sphere_case(frames):
    from bench_sphere_drape import make_drape

    solver, state, _ = make_drape(100, solver="pd", substeps=1)
    return recorded_calls(lambda: [solver.step_frame(state, 1.0 / 60) for _ in range(frames)])


def suit_case(frames):
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import default_body
    from vfit_engine.drape import DrapeSettings, prepare_drape, run_drape
    from vfit_engine.drape.settings import projective
    from vfit_engine.drape.setup import garment_gender
    from vfit_engine.garment.garment import load_garment

    path = GARMENTS / SUIT / f"{SUIT}.obj"
    if not path.is_file():
        fail(f"{path} not found: the suit case needs the shared assets (../shared); or give --case sphere")
    model = BodyModel.load()
    garment = load_garment(path)
    body = default_body(model, garment_gender(garment) or "female")
    settings = projective(DrapeSettings(max_frames=frames))
    setup = prepare_drape(garment, body, model, settings=settings)
    return recorded_calls(lambda: run_drape(setup, settings))


def _for(label, args, module=None):
    """``pd_rhs``'s arguments in the layout of ``label``'s kernel (``module``'s): b29ff13's also took the corners'
    band in radians and no hinge scratch (the same arrays otherwise, so its outputs land where the new layout reads
    them); an old kernel of today's layout (``--old`` a later commit) takes them as they are."""
    if label != "old" or (module is not None and module.pd_rhs.py_func.__code__.co_argcount == len(args)):
        return args
    angles = [np.arccos(np.clip(args[k], -1.0, 1.0)) for k in (13, 14)]
    return args[:OLD_ANGLES] + angles + args[OLD_ANGLES:-1]


def _forces_for(module, args):
    """``contact_forces``' arguments as ``module``'s takes them: before session 40 it had no ``release`` (last)."""
    return args[:module.contact_forces.py_func.__code__.co_argcount]


def _copy(args, outputs):
    """``args`` with copies of the arrays the kernel writes (``outputs``); the inputs shared, as the solver's
    iterations share them (copies of every array for each variant would time their cache misses)."""
    return [a.copy() if k in outputs else a for k, a in enumerate(args)]


def timed(calls, repeat):
    """Median wall and CPU ms a call of each of ``calls`` (name -> function), called in turn ``repeat`` times."""
    wall, cpu = {k: [] for k in calls}, {k: [] for k in calls}
    for fn in calls.values():
        fn()  # compiled or loaded before timing
    for _ in range(repeat):
        for name, fn in calls.items():
            t, c = time.perf_counter(), time.process_time()
            fn()
            wall[name].append(time.perf_counter() - t)
            cpu[name].append(time.process_time() - c)
    return {k: (1000 * float(np.median(wall[k])), 1000 * float(np.median(cpu[k]))) for k in calls}


def measure(case, last, kernels, repeat):
    """Old and new per call on one case's recorded arguments, and whether their outputs agree."""
    rhs, forces = last["pd_rhs"], last["contact_forces"]
    calls, outputs = {}, {}
    for label, module in kernels.items():
        for lag in (False, True):
            args = _copy(rhs, RHS_OUT)
            args[LAG] = lag
            a = _for(label, args, module)
            calls[(label, "fresh" if not lag else "lagged")] = (lambda m=module, a=a: m.pd_rhs(*a))
        args = _forces_for(module, _copy(forces, FORCES_OUT))
        calls[(label, "forces")] = (lambda m=module, a=args: m.contact_forces(*a))
        # the outputs of one call each on fresh copies of the same arguments
        for lag in (False, True):
            args = _copy(rhs, RHS_OUT)
            args[LAG] = lag
            module.pd_rhs(*_for(label, args, module))
            outputs[(label, lag)] = args[B]
        args = _forces_for(module, _copy(forces, FORCES_OUT))
        module.contact_forces(*args)
        outputs[(label, "forces")] = args[LAM]
    times = timed(calls, repeat)
    n = rhs[X].shape[0]
    rows = []
    for part, key in (("pd_rhs fresh", False), ("pd_rhs lagged", True), ("contact_forces", "forces")):
        name = {False: "fresh", True: "lagged", "forces": "forces"}[key]
        old, new = outputs[("old", key)], outputs[("new", key)]
        scale = float(np.abs(old).max()) or 1.0
        rows.append(dict(case=case, n=n, part=part, old_ms=times[("old", name)], new_ms=times[("new", name)],
                         same=bool(np.array_equal(old, new)), diff=float(np.abs(old - new).max()) / scale))
    it = {label: [sum(times[(label, k)][c] * w for k, w in (("forces", 1.0), ("fresh", 0.5), ("lagged", 0.5)))
                  for c in (0, 1)] for label in kernels}
    rows.append(dict(case=case, n=n, part="iteration", old_ms=tuple(it["old"]), new_ms=tuple(it["new"]),
                     same=all(r["same"] for r in rows), diff=max(r["diff"] for r in rows)))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--old", default=OLD, help=f"the commit whose kernels/pd.py is 'old' (default {OLD})")
    ap.add_argument("--frames", type=int, default=40, help="frames of each drape before the arguments are kept")
    ap.add_argument("--repeat", type=int, default=15, help="timed calls of each kernel (median; >= 7)")
    ap.add_argument("--case", action="append", choices=("sphere", "suit"), help="the cases (default both)")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = ap.parse_args(argv)
    if args.frames < 1 or args.repeat < 1:
        ap.error("--frames and --repeat must be >= 1")
    from vfit_engine.kernels import pd

    rows = []
    with tempfile.TemporaryDirectory() as folder:
        kernels = dict(old=old_kernels(args.old, folder), new=pd)
        for case in args.case or ["sphere", "suit"]:
            last = (sphere_case if case == "sphere" else suit_case)(args.frames)
            rows += measure(case if case == "sphere" else SUIT, last, kernels, args.repeat)
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    print(f"old: {args.old}'s kernels/pd.py, new: this checkout's; median of {args.repeat} calls, ms "
          "(wall / cpu)")
    for r in rows:
        (ow, oc), (nw, nc) = r["old_ms"], r["new_ms"]
        print(f"{r['case']:>20} n={r['n']:<6} {r['part']:<15} old {ow:7.3f} / {oc:7.3f}   new {nw:7.3f} / {nc:7.3f}"
              f"   x{oc / nc:4.2f} cpu   same {'yes' if r['same'] else 'no '}  diff {r['diff']:.1e}")


if __name__ == "__main__":
    main()
