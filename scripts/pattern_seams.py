"""The shared sewing patterns draped, per seam and per panel (issue 35 section 3; docs/patterns.md).

Drapes each of ``../shared/assets/patterns/`` through ``vfit drape PATTERN`` (the path users take) on the default
female body, one at a time, then prints from its report.json: frames and whether it settled, the seams pulled
open (gap over 2 mm) of how many, the largest gap between sewn points and its seam, the most stretched seam line,
and every panel's yarn strain p50 / p99 / max and share of its area on the body. Exit 1 when a seam is pulled
open, 2 when ../shared is absent. Each drape takes 30-80 s on 2 loaded cores.

    python scripts/pattern_seams.py [--frames 800] [--out DIR] [NAME ...]
"""
import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PATTERNS = ROOT.parent / "shared" / "assets" / "patterns"
NAMES = ("garmentcode_shirt_mean", "garmentcode_dress_pencil", "gpg_tee", "gpg_skirt_4_panels")


def summary(name, report):
    """The lines of one pattern's report (units in each)."""
    block, frames = report["pattern"], report["frames"]
    seams = block["seams"]
    gap = max(seams, key=lambda s: s["gap_max_mm"])
    line = max(seams, key=lambda s: s["stretch_max_pct"])
    out = [f"{name}: {frames} frames, {'settled' if report['converged'] else 'NOT settled'}; "
           f"{block['seams_pulled_open']} of {len(seams)} seams pulled open (over {block['seam_open_bar_mm']:g} mm); "
           f"largest gap {gap['gap_max_mm']:.2f} mm ({gap['seam']}); most stretched seam line "
           f"{line['seam']}: p99 {line['stretch_p99_pct']:.1f} %, max {line['stretch_max_pct']:.1f} %"]
    out += [f"  {p['panel']}: strain p50 {p['strain_p50_pct']:.1f} %, p99 {p['strain_p99_pct']:.1f} %, max "
            f"{p['strain_max_pct']:.1f} %; on the body {p['contact_pct']:.0f} % of {p['area_m2']:.3f} m^2"
            for p in block["panels"]]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", default=NAMES)
    ap.add_argument("--frames", type=int, default=800)
    ap.add_argument("--out", default=None, help="Folder for the drapes (default: a temporary one).")
    args = ap.parse_args()
    if not PATTERNS.is_dir():
        print(f"{PATTERNS} is absent: put the project's shared/ folder beside the repository", file=sys.stderr)
        return 2
    out = Path(args.out or tempfile.mkdtemp(prefix="vfit-seams-"))
    vfit = Path(sys.executable).parent / "vfit"
    opened = 0
    for name in args.names:
        outdir = out / name
        subprocess.run([str(vfit), "drape", str(PATTERNS / f"{name}.json"), "-o", str(outdir), "-q", "--every", "0",
                        "--frames", str(args.frames)], check=False)
        report = json.loads((outdir / "report.json").read_text())
        opened += report["pattern"]["seams_pulled_open"]
        print("\n".join(summary(name, report)), flush=True)
    return 1 if opened else 0


if __name__ == "__main__":
    sys.exit(main())
