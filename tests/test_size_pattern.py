"""`vfit size PATTERN` through click's CliRunner: its help, every class of bad input (one line, exit 2, before any
drape), and the run's wiring (made for, the rule, each size graded and handed to the sewing) with the sewn drape
itself replaced, as it takes 10-60 s a size (scripts/pattern_sizes.py runs them)."""
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")
SHIRT = PATTERNS / "garmentcode_shirt_mean.json"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def one_line_error(r):
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    return r.exit_code == 2 and len(lines) == 1 and lines[0].startswith("Error")


def tube_file(tmp_path):
    """A GarmentCode specification with no placement and no body: a front and a back sewn into a skirt tube
    (110 cm round, 40 cm long; cm units)."""
    def rect():
        return {"vertices": [[0, 0], [55, 0], [55, 40], [0, 40]],
                "edges": [{"endpoints": [i, (i + 1) % 4]} for i in range(4)]}
    spec = {"pattern": {"panels": {"skirt_front": rect(), "skirt_back": rect()},
                        "stitches": [[{"panel": "skirt_front", "edge": 1}, {"panel": "skirt_back", "edge": 3}],
                                     [{"panel": "skirt_front", "edge": 3}, {"panel": "skirt_back", "edge": 1}]]},
            "properties": {"units_in_meter": 100}}
    path = tmp_path / "tube_skirt.json"
    path.write_text(json.dumps(spec))
    return path


def test_help_names_patterns_the_rule_and_the_pattern_options():
    r = run("size", "--help")
    assert r.exit_code == 0
    text = " ".join(r.output.split())
    for words in ("sewing pattern", "--seams", "--spacing", "--arrange", "in proportion to their width",
                  "caps kept to their armholes", "lengths as made", "vfit size shirt.json"):
        assert words in text, words


@pytest.mark.parametrize("args, words", [
    (["--units", "cm"], "--units is for a garment mesh"),
    (["--sizes", "XXL"], "unknown size 'XXL'"),
    (["--gender", "robot"], "gender"),
    (["--seams", "missing.json"], "seams"),
])
def test_bad_options_on_a_pattern_exit_2_in_one_line(tmp_path, args, words):
    r = run("size", tube_file(tmp_path), *args)
    assert one_line_error(r) and words in r.output, r.output


def test_pattern_options_on_a_mesh_and_bad_pattern_files_exit_2_in_one_line(tmp_path):
    skirt = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"
    r = run("size", skirt, "--spacing", 30)
    assert one_line_error(r) and "--spacing is for a sewing pattern" in r.output
    broken = tmp_path / "broken.json"
    broken.write_text('{"pattern": {"panels": {}}}')
    r = run("size", broken, "--workers", 1)
    assert one_line_error(r) and "broken.json" in r.output and "panels" in r.output
    r = run("size", tmp_path / "absent.json")
    assert one_line_error(r) and "absent.json" in r.output
    sidecar = tmp_path / "seams.json"
    sidecar.write_text('{"seams": []}')
    r = run("size", tube_file(tmp_path), "--seams", sidecar)
    assert one_line_error(r) and "carries its own stitches" in r.output


def test_a_pattern_graded_to_each_size_is_tried_and_said(tmp_path, monkeypatch):
    from vfit_engine import pattern_sizes
    from vfit_engine.errors import InputError

    tried = []

    def no_drape(pattern, body, model, **kw):  # the sewn drape is the size run's slow part: stop before it
        tried.append((pattern, kw))
        raise InputError("replaced in this test")

    monkeypatch.setattr(pattern_sizes, "prepare_pattern_drape", no_drape)
    out = tmp_path / "fit.json"
    r = run("size", tube_file(tmp_path), "--sizes", "L", "--workers", 1, "--spacing", 60, "--json", out)
    assert r.exit_code == 3, r.output  # no size judged: its drape "failed"
    text = " ".join(r.output.split())
    assert "made for: unknown (the pattern names no body), assumed the default female body" in text
    assert "the pattern as given is size S" in text and "graded by the rule: girth growth spread" in text
    assert "hips 110.0 cm x 1.1" in text and "replaced in this test" in text
    res = json.loads(out.read_text())
    assert [s["size"] for s in res["sizes"]] == ["L"] and res["made_for"].startswith("made for: unknown")
    # L is graded by the steps from the default body (S) to its centres at the hips and the waist (the tube,
    # a skirt here, hangs from the waist)
    levels = res["sizes"][0]["grading"]["levels"]
    assert levels["hips"]["garment_cm"] == pytest.approx(110.0, abs=0.1) and levels["hips"]["scale"] > 1.1
    # the graded pattern went to the sewing, with the options given: its top as wide as the widest scale says
    ((graded, kw),) = tried
    assert kw["spacing"] == pytest.approx(0.06) and kw["arrange"] == "auto"
    widest = max(r["scale"] for r in levels.values())
    assert float(np.ptp(graded.panels["skirt_front"].vertices[:, 0])) == pytest.approx(0.55 * widest, abs=1e-3)
