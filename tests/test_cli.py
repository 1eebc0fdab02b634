"""`vfit`, `vfit morph` and `vfit measure` through click's CliRunner: good runs and every class of bad input."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_cli.main import cli

DEMO_SKIRT = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def command_paths(group=cli, path=()):
    """Every command of the ``vfit`` group by its path, subcommands of a group included, as the group lists
    them (not a list kept by hand)."""
    import click

    ctx = click.Context(group)
    out = []
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        out.append((*path, name))
        if isinstance(command, click.Group):
            out += command_paths(command, (*path, name))
    return out


COMMAND_PATHS = command_paths()


def test_every_command_is_found():
    from vfit_cli.main import COMMANDS

    assert {p[0] for p in COMMAND_PATHS} == set(COMMANDS) and ("animate",) in COMMAND_PATHS


@pytest.mark.parametrize("path", [(), *COMMAND_PATHS], ids=lambda p: " ".join(p) or "vfit")
def test_help(path):
    r = run(*path, "--help")
    assert r.exit_code == 0 and "Usage" in r.output


def test_help_does_not_import_numba():
    """No help loads Numba, SciPy or the batch's libraries; ``vfit --help`` (the commands' modules loaded, their
    option types built) loads no NumPy either: the engine constants behind the choices are read when a help
    lists them."""
    code = ("import sys\nfrom click.testing import CliRunner\nfrom vfit_cli.main import cli\n"
            "assert CliRunner().invoke(cli, ['--help']).exit_code == 0\n"
            "print('numpy' in sys.modules)\n"
            f"for path in {COMMAND_PATHS!r}:\n"
            "    assert CliRunner().invoke(cli, [*path, '--help']).exit_code == 0\n"
            "print(*(m in sys.modules for m in ('numba', 'scipy', 'distributed', 'pyarrow')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False"] * 5


def cli_params():
    """(command path, parameter) of every parameter of every command."""
    import click

    out = []
    for path in COMMAND_PATHS:
        ctx = click.Context(cli)
        command = cli
        for name in path:
            command = command.get_command(ctx, name)
        out += [(path, p) for p in command.params]
    return out


def test_every_choice_list_is_the_engines():
    """No command keeps a list of choices by hand: each is an engine constant (``EngineChoice``)."""
    import click

    from vfit_cli._common import EngineChoice

    choices = [(path, p.name, p.type) for path, p in cli_params() if isinstance(p.type, click.Choice)]
    assert len(choices) >= 15
    for path, name, ptype in choices:
        assert isinstance(ptype, EngineChoice), f"vfit {' '.join(path)} --{name}: a list by hand"


def choice_of(command, option):
    return next(p.type.choices for path, p in cli_params() if path == (command,) and p.name == option)


def test_choices_tie_to_the_engine():
    """Each command's choices are the engine's lists (the transfer methods of vfit drape and vfit transfer,
    the units of every command that reads a mesh, ...)."""
    from vfit_engine.animate.loop import COLLIDERS as ANIMATE_COLLIDERS
    from vfit_engine.body.measure import DEFINITIONS
    from vfit_engine.body.skinning import METHODS as SKINNING
    from vfit_engine.drape.colliders import COLLIDERS
    from vfit_engine.drape.setup import REST_MODES
    from vfit_engine.fit.outputs import PICTURE_MAPS
    from vfit_engine.garment.transfer import METHODS
    from vfit_engine.io.mesh import FORMATS
    from vfit_engine.units import LENGTH_UNITS

    assert choice_of("drape", "transfer") == METHODS
    assert choice_of("transfer", "method") == tuple(m for m in METHODS if m != "none")
    assert choice_of("drape", "collider") == COLLIDERS and choice_of("animate", "collider") == ANIMATE_COLLIDERS
    assert choice_of("drape", "rest") == REST_MODES and choice_of("drape", "fmt") == FORMATS
    assert choice_of("drape", "map_name") == tuple(PICTURE_MAPS)
    assert choice_of("pose", "skinning") == choice_of("animate", "skinning") == SKINNING
    with_units = [path[0] for path, p in cli_params() if p.name == "units"]
    assert set(with_units) == {"animate", "drape", "measure", "segment", "size", "transfer"}
    for command in with_units:
        assert choice_of(command, "units") == ("auto", *LENGTH_UNITS), command
    with_definition = [path[0] for path, p in cli_params() if p.name == "definition"]
    assert len(with_definition) >= 7
    for command in with_definition:
        assert choice_of(command, "definition") == DEFINITIONS, command


def test_body_options_tie_to_the_engine():
    """vfit morph's girth options are the engine's girths, and its ranges those a batch job checks."""
    from vfit_cli._common import Quantity
    from vfit_cli.morph import GIRTH_OPTIONS
    from vfit_engine.batch.job import RANGES
    from vfit_engine.body.measure import NAMES

    assert GIRTH_OPTIONS == tuple(n.replace("-", "_") for n in NAMES if n != "height")
    ranges = {p.name: (p.type.lo, p.type.hi) for path, p in cli_params()
              if path == ("morph",) and isinstance(p.type, Quantity)}
    assert ranges == RANGES


def test_help_texts_tie_to_the_engine():
    """Figures and names written into help texts (click cannot build them when asked) are the engine's."""
    from vfit_engine.body.measure import DENSITY
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.segment import PARTS
    from vfit_engine.drape.settings import DrapeSettings
    from vfit_engine.garment.transfer import DEFAULT_K, MAX_K
    from vfit_engine.sim.materials import PRESETS

    params = {(path[0], p.name): p for path, p in cli_params()}
    for command in ("animate", "drape", "size"):
        assert params[command, "material"].help.startswith(", ".join(PRESETS) + ", or a material"), command
    k = params["transfer", "k"]
    assert (k.type.min, k.type.max, k.default) == (1, MAX_K, DEFAULT_K)
    fps, frames = (DrapeSettings.__dataclass_fields__[k].default for k in ("fps", "max_frames"))
    assert f"({fps:g} per simulated second; {frames / fps:g} s) [default: {frames}]" in params["drape", "frames"].help
    assert f"into {len(PARTS)} parts" in run("segment", "--help").output
    assert f"MakeHuman's {len(BodyModel.load().rulers)} rulers" in params["measure", "definition"].help
    assert f"body volume x {DENSITY:g} kg/m^3" in params["morph", "weight"].help


def test_help_lists_every_command():
    from vfit_cli.main import COMMANDS

    listed = [ln.split()[0] for ln in run("--help").output.split("Commands:")[1].splitlines() if ln.strip()]
    assert listed == sorted(COMMANDS)


def test_morph_imports_no_other_command(tmp_path):
    """A morph imports only its own command's module (click's lazy commands)."""
    code = ("import sys\nfrom vfit_cli.main import cli\n"
            f"cli(['morph', '--height', '170', '-q', '-o', {str(tmp_path / 'b.obj')!r}], standalone_mode=False)\n"
            "print(sorted(m for m in sys.modules if m.startswith('vfit_cli.') and m[9:] in "
            f"{tuple(p[0] for p in COMMAND_PATHS if p[0] != 'morph')!r}))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.splitlines()[-1] == "[]"


def test_morph_then_measure(tmp_path):
    body = tmp_path / "b.obj"
    report = tmp_path / "b.json"
    r = run("morph", "--waist", 72, "--bust", 90, "--hips", 98, "--height", 168, "-o", body, "--json", report)
    assert r.exit_code == 0, r.output
    assert f"wrote {body}" in r.output and "waist (cm)" in r.output
    rep = json.loads(report.read_text())
    assert rep["units"]["length"] == "cm" and rep["definition"] == "iso"
    assert all(abs(e) <= 1.0 for e in rep["error_mm"].values())
    lines = body.read_text().splitlines()
    assert sum(1 for ln in lines if ln.startswith("v ")) == 13380
    assert sum(1 for ln in lines if ln.startswith("vt ")) > 0
    assert sum(1 for ln in lines if ln.startswith("f ")) == 13378
    r = run("measure", body, "--json", tmp_path / "m.json")
    assert r.exit_code == 0, r.output
    got = json.loads((tmp_path / "m.json").read_text())["values"]
    for k, want in (("waist", 72), ("bust", 90), ("hips", 98), ("height", 168)):
        assert abs(got[k] - want) <= 0.1, k


def test_morph_estimates_and_warnings(tmp_path):
    """--height and --weight alone: the survey's typical girths, marked (estimated) with their standard
    error, in the table and the JSON; a value outside the 1st-99th percentile warns on stderr."""
    report = tmp_path / "b.json"
    r = CliRunner().invoke(cli, ["morph", "--height", 180, "--weight", 110, "-o", str(tmp_path / "b.obj"),
                                 "--json", str(report)])
    assert r.exit_code == 0, r.output
    rows = {ln.split(" (cm)")[0]: ln for ln in r.stdout.splitlines() if " (cm)" in ln}
    for k in ("bust", "underbust", "waist", "hips", "neck", "upper-arm", "thigh", "calf"):
        assert "(estimated)" in rows[k] and " ±" in rows[k], rows[k]
    assert "(estimated)" not in rows["height"]
    # NHANES 2017-2018 women: 110 kg is at percentile 94, 180 cm beyond the 99th
    assert "warning: height is at percentile 99.7" in r.stderr and "of adult women (NHANES 2017-2018)" in r.stderr
    rep = json.loads(report.read_text())
    assert rep["estimated"]["waist"]["unit"] == "cm" and rep["estimated"]["waist"]["standard_error"] > 0
    assert abs(rep["achieved"]["waist"] - rep["estimated"]["waist"]["value"]) <= rep["estimated"]["waist"][
        "standard_error"]
    assert "NHANES 2017-2018" in rep["population"] and len(rep["warnings"]) == 1


def test_morph_default_output_and_ply(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = run("morph", "--waist", 68)
    assert r.exit_code == 0 and (tmp_path / "body.obj").exists() and "wrote body.obj" in r.output
    r = run("morph", "--gender", "male", "-o", "m.ply", "--quiet")
    assert r.exit_code == 0 and (tmp_path / "m.ply").read_bytes().startswith(b"ply")


@pytest.mark.parametrize("args,needle", [
    (["--waist", "-5"], "must be positive"),
    (["--waist", "nan"], "not a finite number"),
    (["--waist", "abc"], "not a number"),
    (["--hips", "1e6"], "absurd"),
    (["--gender", "robot"], "not female, male"),
    (["--frobnicate", "3"], "No such option"),
    (["--definition", "tailor"], "Invalid value"),
    (["--search-time", "-1"], "Invalid value for '--search-time'"),
])
def test_morph_usage_errors(tmp_path, args, needle):
    out = tmp_path / "x.obj"
    r = CliRunner().invoke(cli, ["morph", *args, "-o", str(out)])
    assert r.exit_code == 2 and needle in r.output
    assert len(r.output.strip().splitlines()) == 1, r.output
    assert not out.exists()


@pytest.mark.parametrize("args,needle", [
    (["--waist", "20"], "refused: waist is 8.5 standard deviations below"),
    (["--bust", "70", "--underbust", "90"], "cannot be met together: bust 70.0 cm ("),
    (["--bust", "70", "--underbust", "90", "--search-time", "0"],
     "bust 70.0 cm (range not searched in the time limit: --search-time to search longer, got"),
    (["--weight", "400", "--height", "150"], "refused: mass is 6.4 standard deviations above"),
])
def test_morph_unreachable(tmp_path, args, needle):
    out = tmp_path / "x.obj"
    r = CliRunner().invoke(cli, ["morph", *args, "-o", str(out), "--json", str(tmp_path / "x.json")])
    assert r.exit_code == 2 and needle in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("path", ["missing/dir/b.obj", "b.stl", "."])
def test_morph_unwritable_output(tmp_path, monkeypatch, path):
    monkeypatch.chdir(tmp_path)
    r = CliRunner().invoke(cli, ["morph", "--waist", "70", "-o", path])
    assert r.exit_code == 2 and ("cannot write" in r.output or "is a directory" in r.output)
    assert list(tmp_path.iterdir()) == []


def test_measure_makehuman_units(tmp_path, body_model):
    """A MakeHuman-style export in decimetres is read as dm and measures like the metre original."""
    from vfit_engine.body.bodyio import write_body

    verts = body_model.default_verts("female")
    write_body(tmp_path / "m.obj", body_model, verts)
    write_body(tmp_path / "dm.obj", body_model, verts * 10.0)
    a = run("measure", tmp_path / "m.obj", "--definition", "makehuman", "--json", tmp_path / "a.json")
    b = run("measure", tmp_path / "dm.obj", "--definition", "makehuman", "--json", tmp_path / "b.json")
    assert a.exit_code == b.exit_code == 0 and "read as dm" in b.output
    va = json.loads((tmp_path / "a.json").read_text())["values"]
    vb = json.loads((tmp_path / "b.json").read_text())["values"]
    assert all(abs(va[k] - vb[k]) < 1e-3 for k in va)
    # an explicit unit that makes the body 16.6 m tall is refused, naming the unit its height says
    r = run("measure", tmp_path / "dm.obj", "--units", "m")
    assert r.exit_code == 2 and "not a human body" in r.output and "--units dm" in r.output, r.output
    assert run("measure", tmp_path / "m.obj", "--units", "cm").exit_code == 2  # 1.7 cm tall
    assert run("measure", tmp_path / "dm.obj", "--units", "dm").exit_code == 0
    with np.errstate(over="ignore"):  # (its vertex normals overflow on the way out)
        write_body(tmp_path / "huge.obj", body_model, verts * 1e100)  # no unit makes it a body
    r = run("measure", tmp_path / "huge.obj")
    assert r.exit_code == 2 and "not a human body in any unit" in r.output, r.output


def test_measure_takes_a_mans_chest_under_the_armpits(tmp_path, body_model):
    """--gender male: the default man's chest under his armpits (98.82 cm, ISO 8559-1); without a gender the bust
    band, at most 3 cm above his nipples (97.25)."""
    from vfit_engine.body.bodyio import write_body

    write_body(tmp_path / "m.obj", body_model, body_model.default_verts("male"))
    a = run("measure", tmp_path / "m.obj", "--gender", "male", "--json", tmp_path / "a.json")
    b = run("measure", tmp_path / "m.obj", "--json", tmp_path / "b.json")
    assert a.exit_code == b.exit_code == 0, a.output
    got = [json.loads((tmp_path / f"{k}.json").read_text()) for k in "ab"]
    assert abs(got[0]["values"]["bust"] - 98.82) < 0.01 and abs(got[1]["values"]["bust"] - 97.25) < 0.01
    assert got[0]["gender"] == "male" and got[1]["gender"] is None
    assert got[0]["values"]["waist"] == got[1]["values"]["waist"]


def test_measure_reads_a_body_with_a_byte_order_mark(tmp_path, body_model):
    """The same body written with a UTF-8 byte-order mark measures the same (no vertex lost)."""
    from vfit_engine.body.bodyio import write_body

    write_body(tmp_path / "b.obj", body_model, body_model.default_verts("female"))
    (tmp_path / "bom.obj").write_bytes(b"\xef\xbb\xbf" + (tmp_path / "b.obj").read_bytes())
    a = run("measure", tmp_path / "b.obj", "--json", tmp_path / "a.json")
    b = run("measure", tmp_path / "bom.obj", "--json", tmp_path / "b.json")
    assert a.exit_code == b.exit_code == 0, b.output
    values = [json.loads((tmp_path / f"{k}.json").read_text())["values"] for k in "ab"]
    assert values[0] == values[1]


def test_a_flat_body_is_named_as_such(tmp_path, body_model):
    """A body flattened to one height: 'not a body mesh' (it asked for --units, which vfit drape uses for the
    garment), from measure and from drape --body."""
    from vfit_engine.body.bodyio import write_body

    verts = body_model.default_verts("female").copy()
    verts[:, 1] = 0.0
    write_body(tmp_path / "flat.obj", body_model, verts)
    for args in (["measure", tmp_path / "flat.obj"],
                 ["drape", DEMO_SKIRT, "--body", tmp_path / "flat.obj", "-o", tmp_path / "o"]):
        r = CliRunner().invoke(cli, [str(a) for a in args])
        assert r.exit_code == 2 and "flat" in r.output and "--units" not in r.output, r.output


def test_measure_bad_inputs(tmp_path):
    import trimesh

    r = CliRunner().invoke(cli, ["measure", str(tmp_path / "none.obj")])
    assert r.exit_code == 2 and "no such file" in r.output
    garbled = tmp_path / "g.obj"
    garbled.write_text("v 1 2 x\nf 1 2 3\n")
    r = CliRunner().invoke(cli, ["measure", str(garbled)])
    assert r.exit_code == 2 and "Traceback" not in r.output
    cube = tmp_path / "cube.obj"
    trimesh.creation.box().export(cube)
    r = CliRunner().invoke(cli, ["measure", str(cube)])
    assert r.exit_code == 2 and "hm08" in r.output
    r = CliRunner().invoke(cli, ["measure", str(cube), "--units", "km"])
    assert r.exit_code == 2


def test_measure_rejects_nan_and_shuffled_topology(tmp_path, body_model):
    from vfit_engine.body.bodyio import write_body
    from vfit_engine.io.mesh import write_mesh
    from vfit_engine.io.meshdata import mesh_from_faces

    verts = body_model.default_verts("female")
    write_body(tmp_path / "ok.obj", body_model, verts)
    lines = (tmp_path / "ok.obj").read_text().splitlines()
    first_v = next(i for i, ln in enumerate(lines) if ln.startswith("v "))
    lines[first_v + 5] = "v 0.1 nan 0.2"
    (tmp_path / "nan.obj").write_text("\n".join(lines) + "\n")
    r = CliRunner().invoke(cli, ["measure", str(tmp_path / "nan.obj")])
    assert r.exit_code == 2 and "NaN" in r.output
    perm = np.random.default_rng(0).permutation(13380)
    write_mesh(tmp_path / "shuffled.obj", mesh_from_faces(verts[:13380], perm[body_model.body_quads]))
    r = CliRunner().invoke(cli, ["measure", str(tmp_path / "shuffled.obj")])
    assert r.exit_code == 2


def test_parallel_kernels_prefer_openmp_to_tbb():
    """vfit_engine._jit puts OpenMP before TBB (a process that ran a parallel kernel from a worker thread can hang
    at exit in TBB's finalize, numba/numba#10556) unless the user chose an order; the layer taken is not TBB where
    another is there (OpenMP ships with Numba's wheels; workqueue always)."""
    code = ("import os, threading\nos.environ.pop('NUMBA_THREADING_LAYER_PRIORITY', None)\n"
            "import vfit_engine._jit, numba, numpy as np\n"
            "f = numba.njit(parallel=True)(lambda a: np.sum(a * 2.0))\n"
            "t = threading.Thread(target=f, args=(np.ones(1000),)); t.start(); t.join()\n"
            "print(os.environ['NUMBA_THREADING_LAYER_PRIORITY'].split()[0], numba.threading_layer())")
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_THREADING_LAYER")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env,
                         timeout=120).stdout
    assert out.split() in (["omp", "omp"], ["omp", "workqueue"])


@pytest.mark.parametrize("code,thread,want_code,want_out", [
    (3, False, 3, "written"),  # ends at once: what was written is flushed first
    (None, False, 0, "written"),
    ("Error: bad", False, 1, "written"),  # a SystemExit message goes to stderr, exit 1
    (3, True, 3, "written, then the thread"),  # a thread that is not a daemon still runs: ends as usual
])
def test_program_end_flushes_and_waits_for_what_runs(code, thread, want_code, want_out):
    """The ``vfit`` program skips Python's teardown after a command (cli.main.end), unless something still
    runs that it waits for: written output is never lost and the exit code is the command's."""
    import subprocess
    import sys

    src = ("import sys, threading, time\n"
           "from vfit_cli.main import end\n"
           "sys.stdout.write('written')\n"
           + ("threading.Thread(target=lambda: (time.sleep(0.3), sys.stdout.write(', then the thread'))).start()\n"
              if thread else "")
           + f"end({code!r})\n")
    r = subprocess.run([sys.executable, "-c", src], capture_output=True, text=True, timeout=60)
    assert r.returncode == want_code and r.stdout == want_out, (r.returncode, r.stdout, r.stderr)
    assert r.stderr == ("Error: bad\n" if isinstance(code, str) else "")
