"""`vfit pattern show` and `vfit pattern export` through click's CliRunner: good runs, a DXF round trip through the
CLI, and every class of bad input (one line, exit 2, nothing written)."""
import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner
from PIL import Image

from vfit_cli.main import cli

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")
SHIRT = PATTERNS / "garmentcode_shirt_mean.json"
SKIRT = PATTERNS / "gpg_skirt_4_panels.json"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def lines(text):
    return [ln for ln in text.splitlines() if ln.strip()]


@needs_shared
def test_show_draws_the_panels_and_prints_them_in_cm(tmp_path):
    png = tmp_path / "shirt.png"
    r = run("pattern", "show", SHIRT, "-o", png)
    assert r.exit_code == 0, r.output
    assert "8 panels, 18 seams" in r.output and "(cm)" in r.output
    assert sum(ln.split()[0].endswith("torso") for ln in lines(r.output)) == 4
    with Image.open(png) as im:
        assert im.size[0] == 1600 and im.size[1] > 400


@needs_shared
def test_export_then_show_reads_the_same_seams_back(tmp_path):
    dxf = tmp_path / "skirt.dxf"
    r = run("pattern", "export", SKIRT, "-o", dxf)
    assert r.exit_code == 0, r.output
    sidecar = tmp_path / "skirt.seams.json"
    assert dxf.is_file() and sidecar.is_file() and len(json.loads(sidecar.read_text())["seams"]) == 8
    before = run("pattern", "show", SKIRT, "-o", tmp_path / "a.png").output
    after = run("pattern", "show", dxf, "--seams", sidecar, "-o", tmp_path / "b.png").output
    # the same panels, edges and seams with the same lengths, to the 0.1 cm printed (the first line names the
    # file, the last the PNG)
    assert len(lines(before)) == 1 + (2 + 4) + (2 + 8) + 1  # headed tables of 4 panels and 8 seams
    assert lines(before)[1:-1] == lines(after)[1:-1]


def test_a_dxf_without_its_seams_is_shown_and_says_so(tmp_path):
    pytest.importorskip("ezdxf")
    from vfit_engine.pattern import dxf_aama, model
    import numpy as np

    panel = model.Panel("square", np.array([[0, 0], [0.3, 0], [0.3, 0.3], [0, 0.3]], float),
                        [model.Edge(i, (i + 1) % 4) for i in range(4)])
    dxf = tmp_path / "square.dxf"
    dxf_aama.write(model.Pattern({"square": panel}, []), dxf)
    r = run("pattern", "show", dxf, "-o", tmp_path / "s.png")
    assert r.exit_code == 0 and "0 seams" in r.output and "--seams" in r.output


@needs_shared
@pytest.mark.parametrize("case", ["missing", "garbled", "suffix", "seams_on_json", "png_suffix", "onto_input",
                                  "missing_seams"])
def test_bad_input_is_one_line_exit_2_and_nothing_written(tmp_path, case):
    garbled = tmp_path / "garbled.json"
    garbled.write_text('{"pattern": {"panels": {"p": {"vertices": [[0, 0]], "edges": [{"endpoints": [0, 7]}]}}}}')
    obj = tmp_path / "shirt.obj"
    obj.write_text("v 0 0 0\n")
    copy = tmp_path / "copy.json"
    copy.write_text(SHIRT.read_text())
    args = {
        "missing": ("show", tmp_path / "nothere.json", "-o", tmp_path / "x.png"),
        "garbled": ("show", garbled, "-o", tmp_path / "x.png"),
        "suffix": ("show", obj, "-o", tmp_path / "x.png"),
        "seams_on_json": ("show", SHIRT, "--seams", garbled, "-o", tmp_path / "x.png"),
        "png_suffix": ("show", SHIRT, "-o", tmp_path / "x.jpg"),
        "onto_input": ("export", copy, "-o", tmp_path / "copy.dxf", "--seams-out", copy),
        "missing_seams": ("show", tmp_path / "x.dxf", "--seams", tmp_path / "none.json", "-o", tmp_path / "x.png"),
    }[case]
    if case == "missing_seams":
        (tmp_path / "x.dxf").write_text("0\nEOF\n")
    before = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()}
    r = CliRunner().invoke(cli, ["pattern", *map(str, args)])
    assert r.exit_code == 2, r.output
    assert r.exception is None or isinstance(r.exception, SystemExit)
    err = lines(r.output)
    assert len(err) == 1 and err[0].startswith("Error:"), r.output
    after = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()}
    assert after == before  # nothing written, nothing removed, the input untouched
    assert "Traceback" not in r.output and os.path.getsize(copy) > 0
