"""Body model benchmarks: data load, a full iso measurement set, morph solves, `vfit morph` end to end.

    python benchmarks/bench_morph.py [--repeat 5] [--json]

Warm figures (the JIT cache filled by a first run) are medians over ``--repeat`` runs.
"""
import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _timing import median_ms




def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()

    from vfit_engine.body.model import BodyModel

    t = time.perf_counter()
    model = BodyModel.load()
    load_ms = 1000 * (time.perf_counter() - t)
    from vfit_engine.body.measure import Measurer
    from vfit_engine.body.morph import Morpher
    from vfit_engine.errors import InputError

    t = time.perf_counter()
    measurer = Measurer(model)
    verts = model.default_verts("female")
    measurer.measure(verts)  # JIT compile or cache load
    first_measure_s = time.perf_counter() - t
    iso_ms = median_ms(lambda: measurer.measure(verts, "iso", mass=False), args.repeat * 4)
    mh_ms = median_ms(lambda: measurer.measure(verts, "makehuman", mass=False), args.repeat * 4)
    morpher = Morpher(model, measurer)
    six = {"waist": 0.70, "bust": 0.92, "hips": 1.00, "height": 1.70, "underbust": 0.76, "neck": 0.32}
    four = {"waist": 0.72, "bust": 0.90, "hips": 0.98, "height": 1.68}
    morpher.solve(six)
    solve6_ms = median_ms(lambda: morpher.solve(six), args.repeat)
    solve4_ms = median_ms(lambda: morpher.solve(four), args.repeat)
    weight_ms = median_ms(lambda: morpher.solve({"height": 1.75}, weight_kg=70.0), args.repeat)
    heavy_ms = median_ms(lambda: morpher.solve({"height": 1.60}, weight_kg=110.0), args.repeat)
    size54_ms = median_ms(lambda: morpher.solve({"height": 1.68, "bust": 1.30, "waist": 1.14, "hips": 1.36}),
                          args.repeat)

    def fails(targets):
        try:
            morpher.solve(targets)
        except InputError:
            return
        raise AssertionError(f"{targets} did not fail")

    refuse_ms = median_ms(lambda: fails({"waist": 0.33}), args.repeat)
    fail_runs = []
    for _ in range(max(3, args.repeat // 2)):  # the slowest failure path: a solve, then the range searches
        t = time.perf_counter()
        fails({"bust": 0.70, "underbust": 0.90})
        fail_runs.append(time.perf_counter() - t)

    cli_s = float("nan")
    exe = shutil.which("vfit", path=str(Path(sys.executable).parent)) or shutil.which("vfit")
    if exe:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [exe, "morph", "--waist", "72", "--bust", "90", "--hips", "98", "--height", "168",
                   "-o", str(Path(tmp) / "b.obj"), "--quiet"]
            subprocess.run(cmd, check=True, capture_output=True)  # warm the cache
            runs = []
            for _ in range(3):
                t = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True)
                runs.append(time.perf_counter() - t)
            cli_s = float(np.median(runs))
    out = {
        "load_ms": round(load_ms, 1),
        "first_measure_s": round(first_measure_s, 3),
        "iso_set_ms": round(iso_ms, 2),
        "makehuman_set_ms": round(mh_ms, 2),
        "solve_6_targets_ms": round(solve6_ms, 1),
        "solve_4_targets_ms": round(solve4_ms, 1),
        "solve_height_weight_ms": round(weight_ms, 1),
        "solve_160cm_110kg_ms": round(heavy_ms, 1),
        "solve_women_size_54_ms": round(size54_ms, 1),
        "refusal_ms": round(refuse_ms, 2),
        "failure_with_ranges_s": [round(min(fail_runs), 2), round(float(np.median(fail_runs)), 2),
                                  round(max(fail_runs), 2)],
        "cli_morph_end_to_end_s": round(cli_s, 3),
    }
    if args.json:
        print(json.dumps(out))
        return
    print(f"body model load                     {out['load_ms']:8.1f} ms")
    print(f"first measurement (JIT cache load)  {out['first_measure_s']:8.3f} s")
    print(f"iso measurement set (9 values)      {out['iso_set_ms']:8.2f} ms   (aim <= 30 ms)")
    print(f"makehuman set (29 values)           {out['makehuman_set_ms']:8.2f} ms")
    print(f"solve 6 targets (warm)              {out['solve_6_targets_ms']:8.1f} ms   (aim <= 150 ms)")
    print(f"solve 4 targets (warm)              {out['solve_4_targets_ms']:8.1f} ms")
    print(f"solve height + weight (warm)        {out['solve_height_weight_ms']:8.1f} ms")
    print(f"solve 160 cm + 110 kg (warm)        {out['solve_160cm_110kg_ms']:8.1f} ms")
    print(f"solve women's size 54 at 168 cm     {out['solve_women_size_54_ms']:8.1f} ms")
    print(f"refusal (waist 33 cm)               {out['refusal_ms']:8.2f} ms")
    lo, med, hi = out["failure_with_ranges_s"]
    print(f"failure with ranges (bust 70 + underbust 90)  {lo:.2f} / {med:.2f} / {hi:.2f} s min/median/max"
          f"   (aim <= 3 s)")
    print(f"vfit morph end to end (warm cache)  {out['cli_morph_end_to_end_s']:8.3f} s    (aim <= 2 s)")


if __name__ == "__main__":
    sys.exit(main())
