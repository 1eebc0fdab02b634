"""Issue 33's acceptance, at full length: every output of a drape gives each region one and the same verdict.

Drapes, each through ``vfit drape`` (the path users take, ``--preview`` included), then reads its report.json and
what it printed with :func:`vfit_engine.verdict_check.disagreements` (the one checker; ``tests/test_verdict.py``
runs it on shorter drapes):

* the issue's customers: its own (``male_casualsuit02 --gender male --waist 84 --hips 100``, the issue's first
  command: a garment too small at his chest), and the demo skirt (waist 74, hips 102 cm) on a woman it is too
  small for and one it is too big for (waist 90 / hips 114 and waist 62 / hips 90 cm);
* the four shared garments on the default body of their gender and on that body with waist and hips -6 and +8 cm
  (``scripts/drape_quality.py``'s bodies: :func:`drape_quality.case_targets`), the measurements given to the CLI.

One line per case (its regions and verdicts, then ``agree`` or the disagreements); exit 1 on any disagreement,
2 when ../shared is absent. The drapes take ~1 min each on 2 cores.

    python scripts/verdict_consistency.py [--garment NAME ...] [--deltas -6,0,8] [--frames N] [--out DIR]
"""
import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from drape_quality import GARMENTS, _attach_value, case_targets, parse_deltas  # noqa: E402

DEMO_SKIRT = ROOT / "data" / "garments" / "skirt.obj"
#: The issue's customers: (label, garment, CLI arguments).
ISSUE_CASES = [
    ("issue customer", GARMENTS / "male_casualsuit02" / "male_casualsuit02.obj",
     ["--gender", "male", "--waist", "84", "--hips", "100"]),
    ("skirt too small", DEMO_SKIRT, ["--gender", "female", "--waist", "90", "--hips", "114"]),
    ("skirt too big", DEMO_SKIRT, ["--gender", "female", "--waist", "62", "--hips", "90"]),
]


def shared_cases(names, deltas):
    """(label, garment, CLI arguments) of each shared garment on its gender's bodies of ``deltas``."""
    from vfit_engine.body.measure import Measurer
    from vfit_engine.body.model import BodyModel
    from vfit_engine.drape.setup import garment_gender
    from vfit_engine.garment.garment import load_garment

    model = BodyModel.load()
    measurer = Measurer(model)
    out, bodies = [], {}
    for name in names:
        path = GARMENTS / name / f"{name}.obj"
        gender = garment_gender(load_garment(path)) or "female"
        if gender not in bodies:
            bodies[gender] = case_targets(model, measurer, gender, deltas)
        for label, _, targets in bodies[gender]:
            args = ["--gender", gender]
            for key, value in (targets or {}).items():
                args += [f"--{key}", f"{100.0 * value:.3f}"]
            out.append((f"{name} {label}", path, args))
    return out


def run_case(garment, args, outdir, frames):
    """``vfit drape`` of one case: (exit code, report or None, printed text, wall s)."""
    cmd = [str(Path(sys.executable).with_name("vfit")), "drape", str(garment), *args, "--every", "0", "--preview",
           "-o", str(outdir)]
    if frames is not None:
        cmd += ["--frames", str(frames)]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    outdir.mkdir(parents=True, exist_ok=True)
    (outdir / "printed.txt").write_text(p.stdout + p.stderr)  # beside report.json, to read again
    report = outdir / "report.json"
    return (p.returncode, json.loads(report.read_text()) if report.exists() else None, p.stdout + p.stderr,
            time.perf_counter() - t0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--garment", action="append", help="a shared garment's name (default: all four)")
    ap.add_argument("--deltas", type=parse_deltas, default=(-6.0, 0.0, 8.0), help="waist and hips offsets, cm")
    ap.add_argument("--frames", type=int, help="vfit drape --frames (default: the CLI's)")
    ap.add_argument("--no-issue", action="store_true", help="only the shared garments")
    ap.add_argument("--out", type=Path, help="where the drapes go (default: a temporary folder)")
    args = ap.parse_args(_attach_value(sys.argv[1:] if argv is None else list(argv), "--deltas"))
    if not GARMENTS.is_dir():
        print("../shared not present", file=sys.stderr)
        return 2
    from vfit_engine.verdict_check import disagreements, verdict_line

    names = args.garment or sorted(p.name for p in GARMENTS.iterdir() if p.is_dir())
    cases = ([] if args.no_issue else ISSUE_CASES) + shared_cases(names, args.deltas)
    out = args.out or Path(tempfile.mkdtemp(prefix="verdict_consistency_"))
    print(f"{len(cases)} cases, drapes in {out}")
    bad = 0
    for k, (label, garment, cli_args) in enumerate(cases):
        code, report, printed, wall = run_case(garment, cli_args, out / f"case{k:02d}", args.frames)
        if report is None or code not in (0, 3):  # 3: not settled, judged on its last frame
            bad += 1
            print(f"{label}: vfit drape failed (exit {code}): {printed.strip().splitlines()[-1:]}")
            continue
        problems = disagreements(report, printed)
        bad += bool(problems)
        state = "settled" if code == 0 else "not settled"
        print(f"{label} ({state}, {wall:.0f} s): {verdict_line(report)} -> "
              + ("agree" if not problems else "DISAGREE: " + "; ".join(problems)), flush=True)
    print(f"{len(cases) - bad} of {len(cases)} cases agree")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
