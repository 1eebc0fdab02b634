"""Hostile input (issue 31, section 6): a run never deletes or overwrites a file the user gave it, non-ASCII file
names everywhere, one holder of an OUTDIR lock, Ctrl-C at every phase says what is there, and what can fail late
(an output path, a directory where a file goes, a non-manifold garment) fails first: exit 2, one line naming the
file and the fix, nothing written."""
import hashlib
import multiprocessing
import os
import subprocess
import sys
import time
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner

from test_drape import DEMO_SKIRT
from vfit_cli.main import cli

CHEAP = ("--frames", "1", "--every", "0", "-q")  # a drape that stops after one frame (exit 3: not settled)


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def one_error(r, code=2):
    """The run's one ``Error:`` line (no traceback), after checking its exit code."""
    assert r.exit_code == code, r.output
    lines = [ln for ln in r.output.splitlines() if ln.startswith("Error")]
    assert len(lines) == 1 and "Traceback" not in r.output, r.output
    return lines[0]


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def listing(folder):
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else None


# -- 1. a run never deletes or overwrites its own input -------------------------------------------------------

@pytest.mark.parametrize("extra", [(), ("--material", "nosuch")], ids=["good", "failing"])
def test_redraping_the_final_garment_into_its_own_outdir_keeps_it(tmp_path, extra):
    """``vfit drape out/final.obj -o out`` used to remove final.obj with the earlier run's outputs after reading
    it: a failing run left the garment gone, a good one replaced it."""
    out = tmp_path / "out"
    out.mkdir()
    garment = out / "final.obj"
    garment.write_bytes(DEMO_SKIRT.read_bytes())
    (out / "report.json").write_text("{}")
    before = digest(garment)
    err = one_error(invoke("drape", garment, "-o", out, *extra, *CHEAP))
    assert str(garment) in err and "one of this run's outputs" in err and "choose another -o" in err
    assert digest(garment) == before and listing(out) == ["final.obj", "report.json"]


@pytest.mark.parametrize("option, name", [("--body", "body.obj"), ("--pin", "frame_0010.obj"),
                                          ("--material", "report.json")])
def test_any_input_among_the_outputs_is_refused(tmp_path, option, name):
    out = tmp_path / "out"
    out.mkdir()
    f = out / name
    f.write_text("whatever the user keeps there\n")
    err = one_error(invoke("drape", DEMO_SKIRT, "-o", out, option, f, *CHEAP))
    assert option in err and str(f) in err
    assert f.read_text() == "whatever the user keeps there\n" and listing(out) == [name]


def test_an_input_reached_through_a_link_or_named_as_json_is_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "final.obj").write_bytes(DEMO_SKIRT.read_bytes())
    link = tmp_path / "mine.obj"
    link.symlink_to(out / "final.obj")
    assert "one of this run's outputs" in one_error(invoke("drape", link, "-o", out, *CHEAP))
    material = tmp_path / "silk.json"
    material.write_text("{}")
    err = one_error(invoke("drape", DEMO_SKIRT, "-o", tmp_path / "o2", "--material", material, "--json", material,
                           *CHEAP))
    assert "--material" in err and material.read_text() == "{}" and not (tmp_path / "o2").exists()
    # the commands with a single output file: transfer, segment
    copy = tmp_path / "skirt.obj"
    copy.write_bytes(DEMO_SKIRT.read_bytes())
    err = one_error(invoke("transfer", copy, "--waist", "80", "-o", copy))
    assert "garment" in err and copy.read_bytes() == DEMO_SKIRT.read_bytes()
    body = tmp_path / "body.ply"
    body.write_bytes(b"not read")
    assert "BODY" in one_error(invoke("segment", body, "-o", body)) and body.read_bytes() == b"not read"


def test_an_input_beside_the_outputs_drapes_and_stays(tmp_path):
    """A garment in OUTDIR under a name that is not an output drapes and is left alone; --json into an OUTDIR
    that does not exist yet is accepted (it is created)."""
    out = tmp_path / "out"
    out.mkdir()
    garment = out / "jupe_été.obj"  # also a non-ASCII name through the whole run (item 2)
    garment.write_bytes(DEMO_SKIRT.read_bytes())
    before = digest(garment)
    new = out / "new"
    r = invoke("drape", garment, "-o", new, "--json", new / "r.json", "--format", "ply", "--frames", "1",
               "--every", "1", "-q")
    assert "did not settle" in one_error(r, 3)
    assert digest(garment) == before
    assert {"final.ply", "body.ply", "fit.ply", "frame_0000.ply", "frame_0001.ply", "report.json",
            "r.json"} <= set(listing(new))
    from vfit_engine.io.ply import read_ply

    head = (new / "final.ply").read_bytes()[:200]
    assert "jupe_été.obj".encode() in head  # the name as it is, in UTF-8
    assert read_ply(new / "final.ply").n_verts == read_ply(new / "frame_0000.ply").n_verts


# -- 2. non-ASCII file names -----------------------------------------------------------------------------------

def test_ply_comments_take_any_name_and_read_back(tmp_path):
    from vfit_engine.io import mesh_from_faces
    from vfit_engine.io.ply import read_ply, write_ply

    m = mesh_from_faces(np.eye(3), [[0, 1, 2]])
    for binary in (True, False):
        p = tmp_path / f"körper_{binary}.ply"
        # a name in UTF-8, and one that is not (os gives its bytes as surrogates): neither raises
        write_ply(p, m, header=["vfit segment: körper.obj", "jupe_\udce9t\udce9.obj"], binary=binary,
                  properties={"strain": np.zeros(3)})
        assert np.array_equal(read_ply(p).verts, m.verts)
        assert "körper.obj".encode() in p.read_bytes()


def test_fit_ply_of_a_non_ascii_garment_as_batch_keep_meshes_writes_it(tmp_path):
    """``vfit batch --keep-meshes`` writes each task's fit.ply with the garment's name in its header (a task
    failed as ``UnicodeEncodeError:``)."""
    from vfit_engine.fit.outputs import write_fit_ply
    from vfit_engine.io import mesh_from_faces
    from vfit_engine.io.ply import read_ply

    mesh = mesh_from_faces(np.eye(3), [[0, 1, 2]])
    setup = SimpleNamespace(garment=SimpleNamespace(source=tmp_path / "jupe_été.obj", mesh=mesh),
                            body=SimpleNamespace(description={"source": "größe 42"}))
    write_fit_ply(tmp_path / "fit.ply", setup, mesh.verts, {"strain": np.zeros(3)})
    assert read_ply(tmp_path / "fit.ply").n_verts == 3


def test_segment_a_body_with_a_non_ascii_name(tmp_path, body_model):
    from vfit_engine.body.bodyio import write_body
    from vfit_engine.io.ply import read_ply

    body = tmp_path / "körper.obj"
    write_body(body, body_model, body_model.default_verts("female"))
    r = invoke("segment", body, "-o", tmp_path / "teile_ü.ply", "-q")
    assert r.exit_code == 0, r.output
    assert read_ply(tmp_path / "teile_ü.ply").colors is not None


# -- 3. the OUTDIR lock ----------------------------------------------------------------------------------------

def _contender(outdir_of, barrier, results, trials):
    """Each trial: meet at the barrier, try to take the lock on trial's OUTDIR, say whether it did, wait until
    both have tried, let go."""
    from vfit_cli._outdir import OutdirLock
    from vfit_engine.errors import InputError

    for k in range(trials):
        barrier.wait()
        lock = OutdirLock(outdir_of(k))
        try:
            lock.__enter__()
            took = True
        except InputError:
            took = False
        results.put((k, took))
        barrier.wait()
        if took:
            lock.__exit__(None, None, None)
        barrier.wait()


class _Dirs:
    def __init__(self, root):
        self.root = root

    def __call__(self, k):
        return os.path.join(self.root, f"t{k:03d}")


def test_two_runs_never_both_take_a_dead_lock(tmp_path):
    """Two processes meet at a barrier and both find a dead run's lock file: exactly one holds OUTDIR, 200 times
    (taking it over by reading the pid and replacing the file, both did in 81 of 200)."""
    trials = 200
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    dirs = _Dirs(str(tmp_path))
    for k in range(trials):
        os.mkdir(dirs(k))
        with open(os.path.join(dirs(k), ".vfit.lock"), "w") as f:
            f.write(f"{gone.pid}\n")  # a run that was killed
    ctx = multiprocessing.get_context("fork")
    barrier, results = ctx.Barrier(2), ctx.Queue()
    procs = [ctx.Process(target=_contender, args=(dirs, barrier, results, trials)) for _ in range(2)]
    t0 = time.monotonic()
    for p in procs:
        p.start()
    took = np.zeros(trials, dtype=int)
    for _ in range(2 * trials):
        k, ok = results.get(timeout=60)
        took[k] += ok
    for p in procs:
        p.join(timeout=60)
    assert all(p.exitcode == 0 for p in procs)
    assert np.all(took == 1), np.flatnonzero(took != 1)
    assert time.monotonic() - t0 < 10.0
    assert not any(os.listdir(dirs(k)) for k in range(trials))  # every lock released


def test_a_dead_lock_naming_a_live_process_is_taken_over(tmp_path):
    """A killed run's lock whose pid now belongs to another process (pid 1) does not block: only a lock held
    by a live run does, and the message names its pid."""
    from vfit_cli._outdir import OutdirLock
    from vfit_engine.errors import InputError

    out = tmp_path / "o"
    out.mkdir()
    (out / ".vfit.lock").write_text("1\n")
    with OutdirLock(str(out)):
        assert (out / ".vfit.lock").read_text().split()[0] == str(os.getpid())
        code = ("import sys; from vfit_cli._outdir import OutdirLock\n"
                "try:\n    OutdirLock(sys.argv[1]).__enter__()\nexcept Exception as e:\n    print(e)")
        other = subprocess.run([sys.executable, "-c", code, str(out)],
                               capture_output=True, text=True, timeout=60)
        assert f"in use by another vfit run (pid {os.getpid()})" in other.stdout, other
    assert listing(out) == []
    with OutdirLock(str(out)):  # released: taken again at once
        with pytest.raises(InputError, match="in use by another vfit run"):
            OutdirLock(str(out)).__enter__()  # another holder, even in this process


# -- 4. Ctrl-C at every phase says what is true ------------------------------------------------------------------

def _interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def _interrupt_second_frame(original):
    def run(setup, settings=None, on_frame=None):
        def frame(k, pos, moving):
            on_frame(k, pos, moving)
            raise KeyboardInterrupt

        return original(setup, settings, on_frame=frame)

    return run


PHASES = {  # where Ctrl-C lands -> (module, attribute, replacement maker)
    "reading": ("vfit_engine.garment.garment", "load_garment", lambda f: _interrupt),
    "set-up": ("vfit_engine.drape", "prepare_drape", lambda f: _interrupt),
    "settling": ("vfit_engine.drape", "run_drape", _interrupt_second_frame),
    "writing final": ("vfit_engine.body.bodyio", "write_body", lambda f: _interrupt),
    "measuring the fit": ("vfit_engine.fit.maps", "fit_maps", lambda f: _interrupt),
    "writing the scene": ("vfit_engine.fit.outputs", "write_scene", lambda f: _interrupt),
}


@pytest.mark.parametrize("phase", PHASES)
def test_ctrl_c_at_every_phase_says_which_files_are_there(tmp_path, monkeypatch, phase):
    """The message names the outputs present (it said "before the drape started; nothing written" with 16 files
    there), and a report written is marked interrupted and lists only files that exist."""
    import importlib
    import json

    module, name, make = PHASES[phase]
    mod = importlib.import_module(module)
    monkeypatch.setattr(mod, name, make(getattr(mod, name)))
    out = tmp_path / "o"
    out.mkdir()
    (out / "final.obj").write_text("# an earlier run's\n")
    err = one_error(invoke("drape", DEMO_SKIRT, "-o", out, "--frames", "3", "--every", "1", "-q"), 130)
    assert "interrupted by SIGINT" in err
    present = listing(out)
    assert ".vfit.lock" not in present and not [n for n in present if n.endswith(".tmp")]
    if phase in ("reading", "set-up"):
        assert "nothing written" in err and present == ["final.obj"]  # not yet cleared: the earlier run's
        return
    frames = [n for n in present if n.startswith("frame_")]
    assert frames and f"{len(frames)} frame file" in err
    for n in set(present) - set(frames):
        assert n in err
    for n in ("final.obj", "body.obj", "fit.ply", "scene.glb"):
        assert (n in err) == (n in present)
    report = json.loads((out / "report.json").read_text())
    assert report["interrupted"] is True and report["signal"] == "SIGINT"
    assert all(os.path.exists(p) for p in report["outputs"])
    assert {os.path.basename(p) for p in report["outputs"]} == set(present) - {"report.json"}


# -- 5 and 7. what fails late fails first ------------------------------------------------------------------------

LONG = "x" * 300


@pytest.mark.parametrize("args", [
    ("drape", DEMO_SKIRT, "-o", "{tmp}/o", "--json", "/proc/r.json"),
    ("drape", DEMO_SKIRT, "-o", "{tmp}/o", "--json", "{tmp}/" + LONG + ".json"),
    ("drape", DEMO_SKIRT, "-o", "{tmp}/o/" + LONG),
    ("size", DEMO_SKIRT, "--json", "/proc/r.json"),
    ("size", DEMO_SKIRT, "--json", "{tmp}/" + LONG + ".json"),
    ("morph", "--waist", "70", "-o", "{tmp}/" + LONG + ".obj"),
    ("morph", "--waist", "70", "-o", "{tmp}/b.obj", "--json", "/proc/r.json"),
    ("segment", DEMO_SKIRT, "-o", "/proc/p.ply"),
    ("pose", "--pose", "walk", "-o", "{tmp}/p.obj", "--gif", "{tmp}/" + LONG + ".gif"),
    ("transfer", DEMO_SKIRT, "--waist", "80", "-o", "/proc/t.obj"),
    ("animate", DEMO_SKIRT, "-o", "{tmp}/o", "--json", "/proc/r.json"),
], ids=lambda a: " ".join(str(w)[:20] for w in a[:1] + a[-2:]))
def test_an_output_path_that_cannot_be_written_stops_the_run_before_its_work(tmp_path, args):
    args = [str(a).format(tmp=tmp_path) for a in args]
    t0 = time.monotonic()
    err = one_error(invoke(*args))
    assert time.monotonic() - t0 < 20.0  # refused before the drape or the solve (13.5 s for morph's)
    assert "cannot" in err and ("choose another" in err or "does not exist" in err), err
    assert listing(tmp_path) == []


def test_atomic_write_takes_a_name_as_long_as_the_file_system_does(tmp_path):
    """Its temporary file's name is not longer than the file's (a 250-character name failed)."""
    from vfit_engine.io.atomic import atomic_write, check_writable

    path = tmp_path / ("é" * 120 + ".json")  # 245 bytes
    check_writable(path)
    assert listing(tmp_path) == []
    with atomic_write(path) as f:
        f.write("{}")
    assert path.read_text() == "{}"


@pytest.mark.parametrize("command, name", [("drape", "report.json"), ("drape", "final.obj"),
                                           ("drape", "frame_0002.obj"), ("animate", "report.json")])
def test_a_directory_where_an_output_file_goes_is_refused_first(tmp_path, command, name):
    out = tmp_path / "o"
    (out / name).mkdir(parents=True)
    err = one_error(invoke(command, DEMO_SKIRT, "-o", out, "--frames", "1", "-q"))
    assert f"cannot write {out / name}: it is a directory" in err and "choose another -o" in err
    assert listing(out) == [name] and listing(out / name) == []


def test_a_directory_where_batch_writes_its_summary_is_refused_first(tmp_path, skirt_dir):
    job = skirt_dir / "job.yaml"
    job.write_text("garments: [skirt.obj]\nbodies: [{gender: female}]\n")
    (tmp_path / "o" / "summary.json").mkdir(parents=True)
    err = one_error(invoke("batch", job, "-o", tmp_path / "o", "-q"))
    assert "summary.json: it is a directory" in err


def test_a_non_manifold_garment_is_refused_before_the_drape(tmp_path):
    """A third face on an edge that two faces share: refused at once, naming the edge (1-based, as in the OBJ)
    and the fix; it failed after the whole drape with "1 edges are shared by more than two triangles"."""
    text = DEMO_SKIRT.read_text()
    faces = [[int(w.split("/")[0]) for w in ln.split()[1:]] for ln in text.splitlines() if ln.startswith("f ")]
    a, b = faces[0][1], faces[0][2]
    assert sum(1 for f in faces for k in range(len(f)) if {f[k], f[(k + 1) % len(f)]} == {a, b}) == 2
    n = sum(1 for ln in text.splitlines() if ln.startswith("v "))
    bad = tmp_path / "flag.obj"
    bad.write_text(text + f"v 0.3 1.0 0.3\nf {a} {b} {n + 1}\n")
    t0 = time.monotonic()
    err = one_error(invoke("drape", bad, "-o", tmp_path / "o", "-q"))
    assert time.monotonic() - t0 < 20.0
    lo, hi = sorted((a, b))
    assert str(bad) in err and f"between vertices {lo} and {hi}" in err and "non-manifold" in err
    assert "remove" in err and not (tmp_path / "o").exists()


def test_a_json_copy_failing_after_the_drape_does_not_hide_exit_3(tmp_path, monkeypatch):
    """--json checked writable before the drape but failing after it (a disk filled since): a warning, and the
    drape's own exit 3 (not settled), not exit 2."""
    import vfit_cli.drape as drape_cli
    from vfit_engine.errors import InputError

    write_json = drape_cli.write_json
    copy = tmp_path / "r.json"

    def full_disk(path, payload):
        if str(path) == str(copy):
            raise InputError(f"cannot write {path}: No space left on device")
        write_json(path, payload)

    monkeypatch.setattr(drape_cli, "write_json", full_disk)
    r = invoke("drape", DEMO_SKIRT, "-o", tmp_path / "o", "--json", copy, *CHEAP)
    assert "did not settle" in one_error(r, 3)
    assert "Warning: cannot write" in r.output and (tmp_path / "o" / "report.json").is_file()
