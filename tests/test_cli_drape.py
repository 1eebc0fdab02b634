"""``vfit drape`` through click's CliRunner: help, a small real run, exit codes 2/3/4, outputs."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def skirt_file(tmp_path_factory, body_model):
    """A small skirt around the default female body's hips, as an OBJ in metres with UVs."""
    from test_drape import skirt_mesh

    from vfit_engine.body.model import N_BODY
    from vfit_engine.io.mesh import write_mesh

    body = body_model.default_verts("female")[:N_BODY]
    path = tmp_path_factory.mktemp("garment") / "skirt.obj"
    write_mesh(path, skirt_mesh(body, body_model.body_tris, around=32, rows=6))
    return path


def run(*args):
    return CliRunner().invoke(cli, ["drape", *map(str, args)])


def one_line_error(result, code):
    assert result.exit_code == code, result.output
    lines = [ln for ln in result.output.splitlines() if ln.startswith("Error")]
    assert len(lines) == 1 and "Traceback" not in result.output
    return lines[0]


def test_help():
    r = run("--help")
    assert r.exit_code == 0
    for opt in ("--body", "--waist", "--hips", "--material", "--collider", "--pin", "--frames", "--every", "--format",
                "--json", "--quiet", "--transfer", "--rest"):
        assert opt in r.output


def test_vfit_help_does_not_import_numba():
    code = "import sys; from vfit_cli.main import cli; cli(['drape', '--help'], standalone_mode=False); " \
           "print('numba' in sys.modules, 'numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "False False"


def test_small_real_run(tmp_path, skirt_file):
    from vfit_engine.io.mesh import read_mesh

    out = tmp_path / "out"
    r = run(skirt_file, "--units", "m", "-o", out, "--every", 20, "--quiet", "--json", tmp_path / "r.json")
    assert r.exit_code == 0, r.output
    report = json.loads((out / "report.json").read_text())
    assert report == json.loads((tmp_path / "r.json").read_text())
    assert report["converged"] is True and report["diverged"] is False
    assert report["steps"] == report["frames"] * report["settings"]["substeps"]
    assert report["max_penetration_mm"] <= 2.0 and report["max_strain"] <= 0.10
    assert report["units"]["mesh"] == "m" and report["settings"]["pins"]["count"] == 32
    frames = sorted(p.name for p in out.glob("frame_*.obj"))
    assert frames[0] == "frame_0000.obj" and frames[1] == "frame_0020.obj"
    src, fin = read_mesh(skirt_file), read_mesh(out / "final.obj")
    assert fin.n_verts == src.n_verts and np.array_equal(fin.face_verts, src.face_verts)
    assert np.array_equal(fin.face_uvs, src.face_uvs) and np.allclose(fin.uvs, src.uvs)
    assert np.all(np.isfinite(fin.verts)) and not np.allclose(fin.verts, src.verts)
    assert read_mesh(out / "body.obj").n_verts == 13380
    # determinism: the same run gives the same bytes
    r2 = run(skirt_file, "--units", "m", "-o", tmp_path / "again", "--every", 0, "--quiet")
    assert r2.exit_code == 0
    assert (tmp_path / "again" / "final.obj").read_bytes() == (out / "final.obj").read_bytes()
    assert not list((tmp_path / "again").glob("frame_*"))


def test_ply_output_and_pin_file(tmp_path, skirt_file):
    pins = tmp_path / "pins.txt"
    pins.write_text("\n".join(str(i) for i in range(32)) + "\n")
    r = run(skirt_file, "--units", "m", "-o", tmp_path / "o", "--format", "ply", "--pin", pins, "--every", 0, "-q",
            "--collider", "spheres")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "o" / "final.ply").is_file() and (tmp_path / "o" / "body.ply").is_file()
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["settings"]["pins"]["mode"] == "file" and report["collider"] == "spheres"
    assert report["max_penetration_mm"] <= 2.0


def test_not_converged_exits_3(tmp_path, skirt_file):
    r = run(skirt_file, "--units", "m", "-o", tmp_path / "o", "--frames", 2, "-q")
    assert "did not settle" in one_line_error(r, 3)
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["converged"] is False and report["frames"] == 2
    assert (tmp_path / "o" / "final.obj").is_file()


def test_divergence_exits_4_without_nan_files(tmp_path, skirt_file, monkeypatch):
    from vfit_engine.sim.solver_verlet import SolverVerlet

    original = SolverVerlet.step_frame
    calls = {"n": 0}

    def poisoned(self, state, frame_dt, substeps=None):
        calls["n"] += 1
        original(self, state, frame_dt, substeps)
        if calls["n"] == 5:
            state.pos[3] = np.nan
        return state

    monkeypatch.setattr(SolverVerlet, "step_frame", poisoned)
    out = tmp_path / "o"
    r = run(skirt_file, "--units", "m", "-o", out, "--every", 2, "-q")
    assert "diverged at frame 5" in one_line_error(r, 4)
    assert not (out / "final.obj").exists()
    assert (out / "frame_0004.obj").is_file()
    for f in out.glob("*.obj"):
        assert "nan" not in f.read_text().lower()
    report = json.loads((out / "report.json").read_text())
    assert report["diverged"] is True and report["last_good_frame"] == 4


def test_bad_inputs_exit_2(tmp_path, skirt_file):
    out = tmp_path / "o"
    assert "not found" in one_line_error(run(tmp_path / "missing.obj", "-o", out), 2)
    garbled = tmp_path / "garbled.obj"
    garbled.write_text("v 1 2\nf 1 2 banana\n")
    one_line_error(run(garbled, "-o", out), 2)
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n")
    assert "NaN" in one_line_error(run(nan, "-o", out), 2)
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing\n")
    one_line_error(run(empty, "-o", out), 2)
    assert "unknown material" in one_line_error(run(skirt_file, "-o", out, "--material", "tweed"), 2)
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    one_line_error(run(skirt_file, "-o", blocker / "sub"), 2)
    one_line_error(run(skirt_file, "-o", blocker), 2)
    bad_pins = tmp_path / "pins.txt"
    bad_pins.write_text("0\n99999\n")
    assert "pin file" in one_line_error(run(skirt_file, "--units", "m", "-o", out, "--pin", bad_pins), 2)
    assert "not both" in one_line_error(run(skirt_file, "--body", skirt_file, "--waist", 70, "-o", out), 2)
    assert "--transfer" in one_line_error(run(skirt_file, "-o", out, "--transfer", "warp"), 2)
    assert "--rest" in one_line_error(run(skirt_file, "-o", out, "--rest", "pattern"), 2)
    # mhclo needs the garment's .mhclo, which the synthetic skirt has not
    assert "mhclo" in one_line_error(run(skirt_file, "--units", "m", "-o", out, "--transfer", "mhclo"), 2)
    # nothing half-written
    assert not list(out.glob("*.obj")) and not list(out.glob(".*tmp"))


def test_transfer_dqs_to_a_body_file(tmp_path, skirt_file, body_model):
    """dqs onto a translated body moves the start by the translation; order, faces and UVs are kept."""
    from vfit_engine.body.bodyio import write_body
    from vfit_engine.body.model import N_BODY
    from vfit_engine.io.mesh import read_mesh

    shift = np.array([0.02, 0.04, -0.01])
    body_file = tmp_path / "moved.obj"
    write_body(body_file, body_model, body_model.default_verts("female")[:N_BODY] + shift)
    out = tmp_path / "o"
    r = run(skirt_file, "--body", body_file, "--units", "m", "-o", out, "--transfer", "dqs", "--frames", 3,
            "--every", 50, "-q")
    assert r.exit_code == 3, r.output  # 3 frames: not settled, outputs written
    report = json.loads((out / "report.json").read_text())
    t = report["transfer"]
    assert t["requested"] == "dqs" and t["method"] == "dqs" and t["identity"] is False and t["time_s"] >= 0
    assert abs(t["max_move_mm"] - 1000 * np.linalg.norm(shift)) < 0.01 and t["pin_gap_mm"]["max"] < 0.01
    # graded by default; a translation changes no length, so both strains agree
    assert t["rest"] == "transferred"
    assert report["garment_max_strain"] == pytest.approx(report["max_strain"], abs=1e-6)
    # the skirt's waistband goes round the waist with room to spare
    assert len(report["openings"]) >= 1 and report["tight_openings"] == []
    assert all(o["body_tape_mm"] > 500 and o["required_strain"] < 0 for o in report["openings"])
    src, start, fin = (read_mesh(p) for p in (skirt_file, out / "frame_0000.obj", out / "final.obj"))
    assert np.allclose(start.verts, src.verts + shift, atol=1e-6)
    for m in (start, fin):
        assert m.n_verts == src.n_verts and np.array_equal(m.face_verts, src.face_verts)
        assert np.array_equal(m.face_uvs, src.face_uvs) and np.allclose(m.uvs, src.uvs)


def test_transfer_on_the_default_body_changes_nothing(tmp_path, skirt_file):
    """On the garment's own body every transfer but mhclo is the identity: the same bytes as none."""
    finals = []
    for method in ("none", "dqs"):
        r = run(skirt_file, "--units", "m", "-o", tmp_path / method, "--every", 0, "-q", "--transfer", method)
        assert r.exit_code == 0, r.output
        report = json.loads((tmp_path / method / "report.json").read_text())
        assert report["transfer"]["method"] == method and report["transfer"]["identity"] is True
        finals.append((tmp_path / method / "final.obj").read_bytes())
    assert finals[0] == finals[1]


@pytest.mark.parametrize("collider", ["bone-spheres", "ellipsoids", "hulls"])
def test_fitted_colliders(tmp_path, skirt_file, collider):
    """The shapes are fitted to the body's segmentation on the fly; their collision time is reported."""
    out = tmp_path / collider
    r = run(skirt_file, "--units", "m", "-o", out, "--collider", collider, "--frames", 3, "--every", 0, "-q")
    assert r.exit_code == 3, r.output  # 3 frames: not settled, outputs written
    report = json.loads((out / "report.json").read_text())
    assert report["collider"] == collider and report["settings"]["collider"] == collider
    assert report["collision_time_s"] > 0 and report["frames"] == 3
    assert (out / "final.obj").is_file()
