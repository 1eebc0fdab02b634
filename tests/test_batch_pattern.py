"""`vfit batch` with a sewing pattern: the job's pattern keys (seams, spacing) and what a pattern refuses, a
pattern task through the CLI on an in-process Dask cluster (its row's worst seam and panel), a broken pattern
failing its task alone."""
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli
from vfit_engine.batch.job import load_job
from vfit_engine.batch.task import run_task
from vfit_engine.errors import InputError

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")
SKIRT = PATTERNS / "gpg_skirt_4_panels.json"


def write_job(folder, text):
    path = folder / "job.yaml"
    path.write_text(text)
    return path


@pytest.fixture
def pieces(skirt_dir):
    """The job folder with a DXF and its seams sidecar (their bytes only matter to the task ids here)."""
    (skirt_dir / "pieces.dxf").write_text("0\nEOF\n")
    (skirt_dir / "pieces.seams.json").write_text('{"seams": []}')
    return skirt_dir


def test_a_pattern_entry_carries_its_seams_and_spacing_into_its_task(pieces):
    job = load_job(write_job(pieces, "garments:\n  - skirt.obj\n  - {path: pieces.dxf, seams: pieces.seams.json, "
                                     "spacing: 40}\nbodies: [{gender: female}]\n"
                                     "drape: {collider: mesh, pin: auto}\n"))  # mesh options at their defaults
    mesh, pattern = job.tasks
    assert (mesh.seams, mesh.spacing_mm) == (None, None) and mesh.payload()["spacing_m"] is None
    assert pattern.seams == str((pieces / "pieces.seams.json").resolve()) and pattern.spacing_mm == 40.0
    p = pattern.payload()
    assert p["seams"] == pattern.seams and p["spacing_m"] == pytest.approx(0.04)
    # the id follows the spacing and the sidecar's bytes; the mesh's does not change with them
    again = load_job(write_job(pieces, "garments:\n  - skirt.obj\n  - {path: pieces.dxf, seams: pieces.seams.json, "
                                       "spacing: 30}\nbodies: [{gender: female}]\n"
                                       "drape: {collider: mesh, pin: auto}\n"))
    assert again.tasks[0].id == mesh.id and again.tasks[1].id != pattern.id
    (pieces / "pieces.seams.json").write_text('{"seams": [], "note": 1}')
    edited = load_job(write_job(pieces, "garments:\n  - {path: pieces.dxf, seams: pieces.seams.json, spacing: 40}\n"
                                        "bodies: [{gender: female}]\n"))
    assert edited.tasks[0].id != pattern.id


@pytest.mark.parametrize("garment, extra, needle", [
    ("{path: skirt.obj, seams: pieces.seams.json}", "", "'seams' is for a sewing pattern"),
    ("{path: skirt.obj, spacing: 20}", "", "'spacing' is for a sewing pattern"),
    ("{path: pieces.dxf, sizes: [M]}", "", "'sizes' is for a garment mesh"),
    ("{path: pieces.dxf, units: cm}", "", "'units' is for a garment mesh"),
    ("{path: pieces.dxf, seams: none.json}", "", "garments[0]: seams file not found"),
    ("{path: pieces.dxf, spacing: 1}", "", "spacing 1; give the cloth's edge length in mm, 3-100"),
    ("{path: pieces.dxf, spacing: yes}", "", "spacing True"),
    ("pieces.dxf", "drape: {pin: none}\n", "drape: 'pin' is for a garment mesh, and garments[0] is a sewing pattern"),
])
def test_bad_pattern_entries_name_the_file_and_element(pieces, garment, extra, needle):
    path = write_job(pieces, f"garments: [{garment}]\nbodies: [{{gender: female}}]\n{extra}")
    with pytest.raises(InputError) as err:
        load_job(path)
    assert needle in str(err.value) and str(path) in str(err.value), str(err.value)


def test_a_broken_pattern_fails_its_task_with_the_message(pieces):
    (pieces / "broken.json").write_text('{"pattern": {"panels": {}}}')
    job = load_job(write_job(pieces, "garments: [broken.json]\nbodies: [{gender: female}]\n"))
    row = run_task(job.tasks[0].payload(), built=(object(), None, 0.0))
    assert row["status"] == "failed" and "broken.json" in row["error"], row["error"]


@needs_shared
def test_batch_drapes_a_pattern_and_its_row_names_the_worst_seam_and_panel(tmp_path):
    """The shared skirt at a 60 mm spacing, 8 frames (not settled: a row all the same), on a Dask cluster in this
    process (its worker shares the warm kernels), given to the CLI by its scheduler's address."""
    from distributed import LocalCluster

    from vfit_engine.pattern.load import load

    job = write_job(tmp_path, f"garments:\n  - {{path: {SKIRT}, spacing: 60}}\nbodies: [{{gender: female}}]\n"
                              "drape: {frames: 8}\n")
    out = tmp_path / "out"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        r = CliRunner().invoke(cli, ["batch", str(job), "-o", str(out), "--scheduler", cluster.scheduler_address])
    assert r.exit_code == 0, r.output
    row = pq.read_table(out / "results.parquet").to_pylist()[0]
    assert row["status"] == "not_converged" and row["frames"] == 8, row["error"]
    pattern = load(SKIRT)[0]
    seam = row["worst_seam"].split(" <-> ")
    assert len(seam) == 2 and all(s.split(":")[0] in pattern.panels for s in seam)
    assert row["worst_panel"] in pattern.panels
    assert row["worst_seam_gap_mm"] >= 0.0 and 0.0 <= row["worst_panel_p99_pct"] < 50.0
    assert row["fit"] and row["fit_summary"]
