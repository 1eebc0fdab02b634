"""`vfit batch` without a cluster: job files, customers CSV, task ids, the results store, one task in-process."""
import json
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli
from vfit_engine.batch.job import GIRTHS, load_job, read_customers
from vfit_engine.batch.results import SCHEMA, ResultStore, flat_row
from vfit_engine.batch.task import run_task
from vfit_engine.errors import InputError



def write_job(folder, text, name="job.yaml"):
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text)
    return path


@pytest.fixture
def job_dir(skirt_dir):
    d = skirt_dir
    (d / "customers.csv").write_text("Name,Gender,Height,Waist,Hips,Weight\nanna,female,168,72,98,\n"
                                     "bert,m,180,,,80\n")
    return d


def test_girth_names_match_vfit_morph():
    from vfit_cli.morph import GIRTH_OPTIONS

    assert GIRTHS == GIRTH_OPTIONS


def test_tasks_are_the_product_and_json_equals_yaml(job_dir):
    yaml_job = write_job(job_dir, "garments:\n  - skirt.obj\n  - {path: skirt.obj, material: jersey, sizes: [m, S]}\n"
                                  "bodies:\n  - {gender: female, waist: 70}\n  - customers.csv\n")
    json_job = write_job(job_dir, json.dumps(dict(
        garments=["skirt.obj", dict(path="skirt.obj", material="jersey", sizes=["m", "S"])],
        bodies=[dict(gender="female", waist=70), "customers.csv"])), "job.json")
    a, b = load_job(yaml_job), load_job(json_job)
    assert len(a.tasks) == (1 + 2) * 3 and (a.garments, a.bodies) == (2, 3)
    assert [t.id for t in a.tasks] == [t.id for t in b.tasks]
    assert len({t.id for t in a.tasks}) == 9
    assert {t.size for t in a.tasks} == {None, "S", "M"}  # sizes read in any case, smallest first
    labels = {t.body_label for t in a.tasks}
    assert {"anna", "bert", "female, waist 70"} == labels
    bert = next(t for t in a.tasks if t.body_label == "bert")
    assert bert.body == dict(name="bert", gender="male", height=180.0, weight=80.0)
    p = bert.payload()
    assert p["body"]["targets"] == {"height": 1.8} and p["body"]["weight_kg"] == 80.0


def test_task_ids_follow_content_not_place(job_dir, tmp_path):
    job = write_job(job_dir, "garments: [skirt.obj]\nbodies: [{gender: female}, {height: 170}]\n")
    ids = [t.id for t in load_job(job).tasks]
    moved = tmp_path / "elsewhere"
    shutil.copytree(job_dir, moved)
    assert [t.id for t in load_job(moved / "job.yaml").tasks] == ids  # moving the folder changes nothing
    with open(moved / "skirt.obj", "a") as f:
        f.write("# edited\n")
    assert not set(t.id for t in load_job(moved / "job.yaml").tasks) & set(ids)  # an edited garment runs again
    dup = write_job(job_dir, "garments: [skirt.obj, skirt.obj]\nbodies: [{gender: female}]\n")
    j = load_job(dup)
    assert len(j.tasks) == 1 and "listed twice" in j.warnings[0]


@pytest.mark.parametrize("text, needle", [
    ("garments: [skirt.obj]\n", "'bodies' must be a non-empty list"),
    ("garments: []\nbodies: [{}]\n", "'garments' must be a non-empty list"),
    ("garments: [nope.obj]\nbodies: [{}]\n", "garments[0]: garment file not found"),
    ("garments: [skirt.obj]\nbodies: [{waist: -3}]\n", "bodies[0]: waist -3 cm is absurd"),
    ("garments: [skirt.obj]\nbodies: [{waist: abc}]\n", "bodies[0]: waist 'abc' is not a number"),
    ("garments: [skirt.obj]\nbodies: [{wasit: 70}]\n", "bodies[0]: unknown key 'wasit'"),
    ("garments: [skirt.obj]\nbodies: [{gender: robot}]\n", "bodies[0]: gender 'robot'"),
    ("garments: [skirt.obj]\nbodies: [{body: none.obj}]\n", "bodies[0]: body file not found"),
    ("garments: [{path: skirt.obj, sizes: [XXL]}]\nbodies: [{}]\n", "garments[0]: unknown size 'XXL'"),
    ("garments: [{path: skirt.obj, material: tinfoil}]\nbodies: [{}]\n", "garments[0]:"),
    ("garments: [skirt.obj]\nbodies: [{}]\ndrape: {collider: bubble}\n", "drape: collider 'bubble'"),
    ("garments: [skirt.obj]\nbodies: [{}]\ndrape: {frames: 0}\n", "drape: frames 0"),
    ("garments: [skirt.obj]\nbodies: [missing.csv]\n", "customers file not found"),
    ("garments: [skirt.obj]\nbodies: [{}]\ncolour: red\n", "unknown key 'colour'"),
    ("garments: [skirt.obj\n", "not valid YAML at line"),
    ("- just a list\n", "a job is a mapping"),
])
def test_bad_jobs_name_the_file_and_element(job_dir, text, needle):
    path = write_job(job_dir, text)
    with pytest.raises(InputError, match=None) as err:
        load_job(path)
    assert needle in str(err.value) and str(path) in str(err.value), str(err.value)


@pytest.mark.parametrize("csv_text, needle", [
    ("name,waist\nanna,seventy\n", "line 2: waist 'seventy' is not a number"),
    ("name,shoe_size\nanna,38\n", "line 2: unknown key 'shoe_size'"),
    ("name,waist\nanna,70,1\n", "line 2 has 3 cells"),
    ("name,waist\n", "no customers"),
])
def test_bad_customers_csv(tmp_path, csv_text, needle):
    path = tmp_path / "c.csv"
    path.write_text(csv_text)
    with pytest.raises(InputError) as err:
        read_customers(path)
    assert needle in str(err.value) and "c.csv" in str(err.value)


def test_cli_bad_job_is_one_line_exit_2_and_leaves_nothing(job_dir, tmp_path):
    path = write_job(job_dir, "garments: [skirt.obj]\nbodies: [{hips: 9000}]\n")
    out = tmp_path / "out"
    r = CliRunner().invoke(cli, ["batch", str(path), "-o", str(out)])
    assert r.exit_code == 2 and "Traceback" not in r.output, r.output
    assert r.output.startswith("Error: ") and r.output.count("\n") == 1 and "hips 9000" in r.output
    assert not out.exists()
    r = CliRunner().invoke(cli, ["batch", str(tmp_path / "none.yaml"), "-o", str(out)])
    assert r.exit_code == 2 and "job file not found" in r.output
    r = CliRunner().invoke(cli, ["batch", str(path), "--workers", "2", "--scheduler", "tcp://x:1"])
    assert r.exit_code == 2 and "not both" in r.output


def test_cli_unreachable_scheduler(job_dir, tmp_path, monkeypatch):
    from vfit_engine.batch import runner

    monkeypatch.setattr(runner, "CONNECT_TIMEOUT_S", 2)  # (20 s by default: a scheduler may be starting)
    path = write_job(job_dir, "garments: [skirt.obj]\nbodies: [{}]\n")
    r = CliRunner().invoke(cli, ["batch", str(path), "-o", str(tmp_path / "o"), "--scheduler", "tcp://127.0.0.1:9"])
    assert r.exit_code == 2 and "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in r.output, r.output


def _row(task_id, status, finished):
    import datetime

    return {"task_id": task_id, "status": status, "finished_at": datetime.datetime.fromtimestamp(
        finished, datetime.timezone.utc), "fit": []}


def test_result_store_keeps_the_newest_row_and_merges_parts(tmp_path, monkeypatch):
    from vfit_engine.batch import results

    store = ResultStore(tmp_path)
    assert store.read().num_rows == 0 and store.statuses() == {}
    store.add([_row("a", "failed", 100), _row("b", "ok", 100)])
    store.add([_row("a", "ok", 200)])  # a re-run of a failed task supersedes its row
    assert store.statuses() == {"a": "ok", "b": "ok"} and len(store.parts()) == 2
    store.flush()
    assert len(store.parts()) == 1 and store.statuses() == {"a": "ok", "b": "ok"}
    monkeypatch.setattr(results, "MERGE_EVERY", 3)
    for k in range(7):  # merged every 3 rows, never rewriting the earlier file
        store.add([_row(f"r{k}", "ok", 300 + k)])
    assert len(store.parts()) == 1 + 2 + 1 and len(store.statuses()) == 9
    store.flush()
    assert len(store.parts()) == 4 and store.read(["status"]).column_names == ["status"]
    table = pq.read_table(tmp_path / "results.parquet")  # readable as one dataset by pyarrow itself
    assert table.num_rows == 10 and table.schema.equals(SCHEMA)  # (with the superseded row of "a")
    assert not list((tmp_path / "results.parquet").glob(".*"))  # no temporary files left
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "results.parquet").write_text("not a folder")
    with pytest.raises(InputError, match="is a file"):
        ResultStore(tmp_path / "x")


def test_a_broken_garment_fails_its_task_with_the_message(job_dir, tmp_path):
    (job_dir / "broken.obj").write_text("v 0 0 0\nv nan 1 0\nf 1 2 3\n")
    job = load_job(write_job(job_dir, "garments: [broken.obj]\nbodies: [{gender: female}]\n"))
    row = run_task(job.tasks[0].payload())
    assert row["status"] == "failed" and "broken.obj" in row["error"], row["error"]
    flat = flat_row(row, job.tasks[0])
    assert set(flat) == set(SCHEMA.names) and flat["garment_name"] == "broken" and flat["task_s"] >= 0


def test_a_body_that_cannot_be_built_fails_its_tasks_with_the_message(job_dir):
    from vfit_engine.batch.task import build_body

    job = load_job(write_job(job_dir, "garments: [skirt.obj]\nbodies: [{gender: female, waist: 20}]\n"))
    payload = job.tasks[0].payload()
    built = build_body(payload["body"])
    assert built[0] is None and "refused: waist" in built[1] and built[2] > 0
    row = run_task(payload, built)
    assert row["status"] == "failed" and "waist" in row["error"] and row["times_s"]["body"] > 0


@pytest.mark.skipif(not (Path(__file__).resolve().parents[2] / "shared" / "assets" / "garments").is_dir(),
                    reason="../shared/assets/garments (MakeHuman clothes) absent")
def test_a_body_without_gender_takes_the_garments():
    shared = Path(__file__).resolve().parents[2] / "shared" / "assets" / "garments"
    from vfit_engine.batch.job import make_job

    garments = [dict(path=str(shared / n / f"{n}.obj"), units="auto", sizes=None, material="cotton",
                     material_key="cotton", gender=gender)
                for n, gender in (("male_casualsuit02", "male"), ("female_casualsuit01", "female"))]
    from vfit_engine.batch.job import _tag_gender

    assert [_tag_gender(Path(g["path"])) for g in garments] == ["male", "female"]
    job = make_job("j", garments, [{"height": 175.0}, {"gender": "female"}], {})
    assert [t.gender for t in job.tasks] == ["male", "female", "female", "female"]
    keys = [t.body_key() for t in job.tasks]  # 175 cm in each garment's gender; the female body, shared
    assert len(set(keys)) == 3 and keys[1] == keys[3] and keys[0] != keys[2]
