"""`vfit pattern show` and `vfit pattern export` through click's CliRunner: good runs, a DXF round trip through the
CLI, and every class of bad input (one line, exit 2, nothing written)."""
import json
import os
from pathlib import Path

import numpy as np
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


# -- vfit drape PATTERN ----------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def skirt_drape(tmp_path_factory):
    """The shared four-panel skirt sewn and draped through `vfit drape` (45 frames: sewn by frame 30, not settled:
    exit 3)."""
    out = tmp_path_factory.mktemp("skirt")
    r = CliRunner().invoke(cli, ["drape", str(SKIRT), "-o", str(out), "--frames", "45", "--every", "100"])
    return out, r


@needs_shared
def test_drape_sews_a_pattern_and_writes_it_with_its_panels(skirt_drape):
    from vfit_engine.pattern.load import load
    from vfit_engine.pattern.mesh import mesh_pattern

    from vfit_engine.io.mesh import read_mesh

    out, r = skirt_drape
    assert r.exit_code == 3, r.output  # 45 frames: sewn, still settling
    assert "against the flat pattern" in r.output and "slid" not in r.output
    final = read_mesh(out / "final.obj")
    v, vt, groups = final.verts, final.uvs, [name for name, _ in final.groups]
    assert groups == ["front", "right", "back", "left"]
    # UVs: the panels' own coordinates, metres of the pattern (the skirt's panels are 0.3-0.6 m tall)
    assert len(vt) == len(v) and 0.3 < np.ptp(np.array(vt)[:, 1]) < 0.8
    cloth = mesh_pattern(load(SKIRT)[0])
    pairs = cloth.seam_pairs
    gap = np.linalg.norm(v[pairs[:, 0]] - v[pairs[:, 1]], axis=1)
    assert gap.max() < 0.002  # sewn: every seam within 2 mm
    report = json.loads((out / "report.json").read_text())
    assert report["pattern"]["seam_pairs"] == len(pairs) and report["pattern"]["panel_count"] == 4
    assert report["surface_inside_percent"] <= 0.5 and report["surface_deeper_than_2mm"] == 0  # the surface bars
    assert report["strain_reference"].startswith("the flat pattern")
    # the fit table's openings are the sewn skirt's (its waist), not its four panels' outlines
    regions = [r["region"] for r in report["fit"]]
    assert regions.count("waistband") == 1 and len(regions) == len(set(regions)), regions
    # no pins: the seams and the body hold it up; it hangs from the hips, no higher than it started
    start = read_mesh(out / "frame_0000.obj").verts
    assert v[:, 1].max() <= start[:, 1].max() + 0.01


@needs_shared
@pytest.mark.parametrize("args,names", [
    (("--pin", "none"), "--pin"), (("--rest", "graded"), "--rest"), (("--refine", "1"), "--refine")])
def test_drape_refuses_mesh_options_on_a_pattern(tmp_path, args, names):
    r = CliRunner().invoke(cli, ["drape", str(SKIRT), "-o", str(tmp_path / "o"), *args])
    assert r.exit_code == 2 and names in r.output and len(lines(r.output)) == 1
    assert not (tmp_path / "o").exists()


def test_drape_refuses_pattern_options_on_a_mesh(tmp_path):
    skirt = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"
    r = CliRunner().invoke(cli, ["drape", str(skirt), "-o", str(tmp_path / "o"), "--spacing", "15"])
    assert r.exit_code == 2 and "--spacing" in r.output and len(lines(r.output)) == 1


@needs_shared
def test_drape_reports_every_seam_and_panel_and_prints_the_worst(skirt_drape):
    """report.json's pattern block: a row per stitch (closed: within the 2 mm bar) and per panel, the fit table's
    regions naming their panels; the printed lines: the 5 worst seams and every panel, each with its unit."""
    from vfit_engine.pattern.load import load

    out, r = skirt_drape
    pattern = load(SKIRT)[0]
    block = json.loads((out / "report.json").read_text())["pattern"]
    fit = json.loads((out / "report.json").read_text())["fit"]
    assert len(block["seams"]) == len(pattern.stitches) == 8 and block["seams_pulled_open"] == 0
    assert all(s["gap_max_mm"] < block["seam_open_bar_mm"] == 2.0 for s in block["seams"])
    assert all(0 <= s["gap_mean_mm"] <= s["gap_max_mm"] and s["stretch_p99_pct"] <= s["stretch_max_pct"] + 1e-9
               for s in block["seams"])
    assert [p["panel"] for p in block["panels"]] == list(pattern.panels)
    for p in block["panels"]:
        assert p["strain_p50_pct"] <= p["strain_p99_pct"] <= p["strain_max_pct"] + 1e-9
        assert 0.0 <= p["contact_pct"] <= 100.0 and p["area_m2"] > 0.05
    hips = next(row for row in fit if row["region"] == "hips")
    assert {p["panel"] for p in hips["panels"]} == set(pattern.panels)  # a skirt's four panels go round the hips
    assert sum(p["loop_share_pct"] for p in hips["panels"]) == pytest.approx(100.0, abs=0.05)
    # the panels' ease at the hips adds up to the region's
    ease = [x["ease_cm"] for p in block["panels"] for x in p["regions"] if x["region"] == "hips"]
    assert sum(ease) == pytest.approx(hips["ease_cm"], abs=0.03)
    text = r.output
    assert "seams (0 of 8 pulled open, gap over 2 mm), the 5 worst:" in text
    seam_lines = [ln for ln in text.splitlines() if "<->" in ln]
    assert len(seam_lines) == 5 and all("mm" in ln and "%" in ln for ln in seam_lines)
    assert seam_lines[0].strip().startswith(block["seams"][0]["seam"])
    for name in pattern.panels:
        assert any(ln.strip().startswith(f"{name}: strain p50") and ln.endswith("%") for ln in text.splitlines())
    assert any(ln.strip().startswith("hips: ") and " cm (" in ln for ln in text.splitlines())
