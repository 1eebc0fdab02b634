"""`vfit batch` on a real Dask cluster: tasks become rows, a bad garment fails alone, a re-run skips what is done,
a customers CSV, a scheduler given by address, and a worker killed mid-task (SIGKILL) costing a retry, not a row."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli
from vfit_engine.batch.job import load_job
from vfit_engine.batch.runner import local_cluster, run_batch
from vfit_engine.fit.verdict import VERDICTS

DEMO_SKIRT = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def cluster():
    """Two worker processes, started once for the module (the scheduler-address test reaches it by address)."""
    with local_cluster(2) as c:
        yield c


@pytest.fixture(scope="module")
def client(cluster):
    from distributed import Client

    with Client(cluster, set_as_default=False) as c:
        yield c


@pytest.fixture
def job_dir(skirt_dir):
    return skirt_dir


def rows_of(outdir):
    return pq.read_table(Path(outdir) / "results.parquet").to_pylist()


def test_four_tasks_give_four_rows_and_a_rerun_runs_nothing(client, job_dir, tmp_path):
    (job_dir / "job.yaml").write_text("garments:\n  - skirt.obj\n  - {path: skirt.obj, sizes: [M]}\n"
                                      "bodies:\n  - {name: anna, gender: female, height: 168, waist: 72, hips: 98}\n"
                                      "  - {gender: female}\n")
    job = load_job(job_dir / "job.yaml")
    seen = []
    s = run_batch(job, tmp_path / "out", client=client, keep_meshes=True,
                  on_task=lambda done, todo, row: seen.append((done, todo)))
    rows = rows_of(tmp_path / "out")
    assert len(rows) == 4 and {r["task_id"] for r in rows} == {t.id for t in job.tasks}
    assert [r["status"] for r in rows] == ["ok"] * 4, [r["error"] for r in rows]
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)] and s.counts == {"ok": 4, "not_converged": 0, "failed": 0}
    for r in rows:
        assert r["surface_inside_percent"] <= 0.5 and r["surface_max_depth_mm"] <= 2.0
        assert 0 < r["p99_strain"] < 0.05 and r["hips_verdict"] in VERDICTS and r["fit"]
        assert r["worker"].startswith("tcp://") and r["task_s"] >= r["drape_s"] > 0
    assert {r["size"] for r in rows} == {None, "M"} and all(r["grade_s"] > 0 for r in rows if r["size"])
    from vfit_engine.io.mesh import read_mesh

    n_verts = read_mesh(str(DEMO_SKIRT)).n_verts
    for r in rows:  # --keep-meshes: the drape in metres with the garment's vertices, the body once per body
        final = read_mesh(str(tmp_path / "out" / r["final_mesh"]))
        assert final.n_verts == n_verts and 0.3 < np.ptp(final.verts[:, 1]) < 1.0
        assert (tmp_path / "out" / r["body_mesh"]).is_file() and (tmp_path / "out" / r["final_mesh"]).with_name(
            "fit.ply").is_file()
    assert len(list((tmp_path / "out" / "bodies").glob("*.obj"))) == 2
    # each body was built once for its two drapes (the same build time in both rows)
    by = {}
    for r in rows:
        by.setdefault(r["body_key"], set()).add(r["body_s"])
    assert len(by) == 2 and all(len(v) == 1 and min(v) > 0 for v in by.values()), by
    # a re-run: nothing to do, so no cluster is even reached (this address has none)
    again = run_batch(job, tmp_path / "out", scheduler="tcp://127.0.0.1:9")
    assert again.ran == 0 and again.skipped == 4 and len(rows_of(tmp_path / "out")) == 4


def test_a_bad_garment_fails_alone(client, job_dir, tmp_path):
    (job_dir / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    (job_dir / "job.yaml").write_text("garments: [bad.obj, skirt.obj]\nbodies: [{gender: female}]\n")
    s = run_batch(load_job(job_dir / "job.yaml"), tmp_path / "out", client=client)
    rows = {r["garment_name"]: r for r in rows_of(tmp_path / "out")}
    assert rows["bad"]["status"] == "failed" and "bad.obj" in rows["bad"]["error"], rows["bad"]["error"]
    assert rows["skirt"]["status"] == "ok" and s.counts["failed"] == 1
    assert s.failures[0][0].startswith("bad on ")
    # --retry-failed runs the failed task again (and only it); its new row replaces the old one
    again = run_batch(load_job(job_dir / "job.yaml"), tmp_path / "out", client=client, retry_failed=True)
    from vfit_engine.batch.results import ResultStore

    table = ResultStore(tmp_path / "out").read().to_pylist()  # one row per task: the newest
    rows2 = {r["garment_name"]: r for r in table}
    assert again.ran == 1 and len(table) == 2 and rows2["bad"]["finished_at"] > rows["bad"]["finished_at"]
    assert rows2["skirt"]["finished_at"] == rows["skirt"]["finished_at"]


def test_customers_csv_through_the_cli_on_a_scheduler_by_address(cluster, job_dir, tmp_path):
    (job_dir / "customers.csv").write_text("customer,gender,height,waist,hips\nc1,female,165,70,96\n"
                                           "c2,female,172,,100\n")
    (job_dir / "job.yaml").write_text("garments: [skirt.obj]\nbodies: customers.csv\n")
    out = tmp_path / "out"
    r = CliRunner().invoke(cli, ["batch", str(job_dir / "job.yaml"), "-o", str(out), "--scheduler",
                                 cluster.scheduler_address])
    assert r.exit_code == 0, r.output
    assert "2 tasks: 2 ok, 0 not converged, 0 failed; ran 2" in r.output
    rows = rows_of(out)
    assert sorted(r["body"] for r in rows) == ["c1", "c2"] and all(r["status"] == "ok" for r in rows)
    hips = {r["body"]: next(f for f in r["fit"] if f["region"] == "hips")["body_girth_cm"] for r in rows}
    assert abs(hips["c1"] - 96.0) < 0.15 and abs(hips["c2"] - 100.0) < 0.15  # the bodies asked for
    assert (out / "summary.json").is_file()


def test_a_local_cluster_needs_no_port_8787():
    """The scheduler of a local cluster serves its HTTP routes on a free port: with 8787 taken (another
    cluster, a notebook) it neither warns nor needs it."""
    import socket
    import warnings

    held = socket.socket()
    try:
        held.bind(("127.0.0.1", 8787))  # a cluster already running here holds it
        held.listen(1)
    except OSError:
        pass  # something on this machine holds it already: the same case
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with local_cluster(0) as c:
                port = c.scheduler.http_server.port
    finally:
        held.close()
    assert not [w for w in caught if "already in use" in str(w.message)], [str(w.message) for w in caught]
    assert port not in (0, 8787)


def _worker_pids(parent):
    import psutil

    return [p.pid for p in psutil.Process(parent).children()
            if "spawn_main" in " ".join(p.cmdline()) and "resource_tracker" not in " ".join(p.cmdline())]


def test_a_worker_killed_mid_task_costs_a_retry_not_a_row(job_dir, tmp_path):
    """The acceptance run on 2 workers, one worker SIGKILLed mid-task.

    The two workers start a task each at once; when the first row is written, the worker that did not write
    it is still on its task, and that one is killed (its task must come back as a row from another worker),
    while the first takes the third task. Three tasks suffice: the demo skirt on the default body, which
    needs no solve, in fabrics that settle in 110-120 frames there (the acceptance run's 2 garments x 3
    bodies, two of them built to measurements, half of them in jersey, which took 228-321 frames, cost 129 s
    of a loaded `make test`: a test about workers, not drapes)."""
    (job_dir / "job.yaml").write_text(
        "garments: [skirt.obj, {path: skirt.obj, material: silk}, {path: skirt.obj, material: denim}]\n"
        "bodies: [{gender: female}]\n")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "vfit_cli.main", "batch", str(job_dir / "job.yaml"), "-o", str(out),
           "--workers", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 240
        while not list((out / "results.parquet").glob("part-*")) and time.monotonic() < deadline:
            time.sleep(0.2)
        pids = _worker_pids(proc.pid)
        assert len(pids) == 2 and proc.poll() is None, (pids, proc.poll())
        first = pq.read_table(next((out / "results.parquet").glob("part-*"))).to_pylist()
        victim = next(p for p in pids if p not in {r["pid"] for r in first})  # still on its first task
        os.kill(victim, signal.SIGKILL)
        killed = time.time()
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr
    rows = rows_of(out)
    assert len(rows) == 3 and len({r["task_id"] for r in rows}) == 3 and {r["status"] for r in rows} == {"ok"}
    assert not any(r["pid"] == victim and r["finished_at"].timestamp() > killed for r in rows)
    t = time.perf_counter()
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert again.returncode == 0 and "nothing to run" in again.stderr and time.perf_counter() - t < 15
    assert len(rows_of(out)) == 3
