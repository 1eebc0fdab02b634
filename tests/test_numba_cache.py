"""Numba's on-disk cache of vfit's kernels never goes stale, and a first run's compile is shown where it happens.

Numba stamps a cached function with its own file only; a kernel that inlines a helper from a sibling module would
run the old helper after an edit there. :mod:`vfit_engine._jit` stamps every kernel with the modules of its folder
it imports too. The tests compile a tiny package in ``tmp_path`` (a kernel inlining a helper from a sibling module,
imported in parentheses over several lines) through the real :func:`vfit_engine._jit.njit`, in fresh processes, and
show its compile with the CLI's real :class:`vfit_cli._progress.Progress`; the commands' wiring is
checked with a fresh kernel compiled where the engine would compile its own.
"""
import ast
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

HELPER = '''from vfit_engine._jit import njit

SCALE = {scale}


@njit
def _scale(x):
    return x * SCALE
'''

KERNEL = '''from vfit_engine._jit import njit
from pkg.helper import (
    _scale,
)


@njit
def run(x):
    return _scale(x) + 1.0
'''

# run the kernel once under the CLI's compile notice (stderr not a terminal); print its value, cache hits, misses
# and whether it was cached before
SCRIPT = '''import sys
sys.path.insert(0, sys.argv[1])
from vfit_cli._progress import Progress
from pkg.kern import run
from vfit_engine.kernel_compiles import is_cached
cached = is_cached(run)
with Progress(True, command="vfit test").compiling():
    value = run(1.0)
assert is_cached(run)
print(value, sum(run.stats.cache_hits.values()), sum(run.stats.cache_misses.values()), cached)
'''


@pytest.fixture
def package(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "helper.py").write_text(HELPER.format(scale=2.0))
    (pkg / "kern.py").write_text(KERNEL)
    (pkg / "other.py").write_text("ANSWER = 42\n")  # a module of the folder that the kernel does not import
    return tmp_path


def run_kernel(root, **env):
    """(value, cache hits, cache misses, stderr) of the kernel in a fresh process; checks that
    :func:`vfit_engine.kernel_compiles.is_cached` knew beforehand whether it would compile."""
    environ = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    environ.update(env, NUMBA_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(root)], capture_output=True, text=True, env=environ,
                       cwd=root, timeout=120)
    assert r.returncode == 0, r.stderr
    value, hits, misses, cached = r.stdout.split()
    assert cached == str(hits == "1")
    return float(value), int(hits), int(misses), r.stderr


def test_an_edited_inlined_helper_recompiles_the_cached_kernel(package):
    """Compile and cache; edit the helper's constant: the next process compiles afresh and sees it, no cache
    deleted, and says so; after an edit to a module the kernel does not import, the next loads it from the cache
    and says nothing."""
    cache = package / "pkg" / "__pycache__"
    assert run_kernel(package)[:3] == (3.0, 0, 1)  # 1 * 2 + 1, compiled
    index = sorted(p.name for p in cache.glob("kern.run-*.nbi"))
    assert len(index) == 1
    (package / "pkg" / "helper.py").write_text(HELPER.format(scale=5.0))
    value, hits, misses, err = run_kernel(package)
    assert (value, hits, misses) == (6.0, 0, 1), "the cached kernel ran the old helper"
    assert "vfit test: compiling the kernels, once: later runs load them from the cache" in err, err
    assert "vfit test: compiled the kernels in " in err, err
    assert sorted(p.name for p in cache.glob("kern.run-*.nbi")) == index  # the same index, rewritten in place
    (package / "pkg" / "other.py").write_text("ANSWER = 43\n")
    assert run_kernel(package) == (6.0, 1, 0, "")  # warm: loaded, nothing said


def test_a_cache_dir_given_by_the_user_stays_fresh_too(package, tmp_path):
    """With ``NUMBA_CACHE_DIR`` set (Numba's user-provided locator) the kernel caches there, stamped the same."""
    cache = tmp_path / "numba-cache"
    assert run_kernel(package, NUMBA_CACHE_DIR=str(cache))[:3] == (3.0, 0, 1)
    assert list(cache.rglob("kern.run-*.nbi")) and not list(package.rglob("__pycache__/kern.run-*.nbi"))
    (package / "pkg" / "helper.py").write_text(HELPER.format(scale=7.0))
    assert run_kernel(package, NUMBA_CACHE_DIR=str(cache))[:3] == (8.0, 0, 1)


def test_only_kernels_of_njit_are_stamped():
    """A function compiled with numba's own ``njit`` (the user's) keeps Numba's locators and stamp."""
    import numba

    from vfit_engine import _jit

    def mine(x):
        return x + 1

    numba.njit(cache=True)(mine)
    assert _jit.StampedLocator.from_function(mine, __file__) is None
    assert _jit.LOCATORS[0] is _jit.StampedLocator


def test_stamp_follows_imports_of_the_folder_only():
    """The cloth kernel's stamp covers the modules it inlines from, through each other; a stamp is a few ms."""
    import time

    from vfit_engine import _jit

    kernels = ROOT / "vfit_engine" / "kernels"
    _jit.source_stamp.cache_clear()
    _jit._module_source.cache_clear()
    t = time.perf_counter()
    _jit.source_stamp(str(kernels / "cloth.py"))
    assert time.perf_counter() - t < 0.1
    seen, todo = set(), [(kernels / "cloth.py").resolve()]
    while todo:
        path = todo.pop()
        if path not in seen:
            seen.add(path)
            todo += _jit._module_source(path)[1]
    assert {p.stem for p in seen} == {"cloth", "bending", "contact_make", "contact_solve", "collide_mesh", "integrate",
                                      "springs"}


def test_kernels_import_from_vfit_only_their_folder_and_the_preset():
    """What a kernel inlines or freezes (helpers, constants) comes from its own folder, which the stamp covers."""
    bad = []
    for path in sorted((ROOT / "vfit_engine" / "kernels").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                names = [("." * node.level) + (node.module or "")]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            for name in names:
                inside = name.startswith(("vfit_engine.kernels.", ".")) and not name.startswith("..")
                if (name.startswith("vfit_engine") or name.startswith("..")) and not inside \
                        and name != "vfit_engine._jit":
                    bad.append(f"{path.name}: {name}")
    assert not bad, bad


def test_the_notice_ticks_on_a_terminal_and_ends_its_line():
    """On a terminal the compile line is rewritten in place with the seconds, ended before the next stage line;
    a warm kernel (compiled already in this process) prints nothing."""
    import numba

    from vfit_cli._progress import Progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    stream = Tty()
    progress = Progress(False, stream=stream, command="vfit test")
    kernel = numba.njit(lambda x: x * 3)
    with progress.compiling():
        kernel(1)
        progress.stage("next")
    text = stream.getvalue()
    assert text.startswith("\rvfit test: compiling the kernels, once (later runs load them from the cache): ")
    assert "s\033[K\nvfit test: next" in text
    assert "\nvfit test: compiled the kernels in " in text
    stream = Tty()
    with Progress(False, stream=stream, command="vfit test").compiling():
        kernel(2)
    assert stream.getvalue() == ""


@pytest.mark.parametrize("command", ["morph", "drape"])
def test_a_command_shows_a_compile_where_it_happens_and_a_warm_run_does_not(monkeypatch, tmp_path, command):
    """The engine's call that compiles on a first run (Morpher, prepare_drape) stands in for one that compiles a
    kernel new to this process, then stops the command: the notice and its total are said, even under --quiet;
    run again (the kernel compiled), nothing is."""
    import numba
    from click.testing import CliRunner

    import vfit_engine.body.morph
    import vfit_engine.drape
    from vfit_cli.main import cli
    from vfit_engine.errors import InputError

    kernel = numba.njit(lambda x: x + 1.0)

    def compile_and_stop(*args, **kwargs):
        kernel(1.0)
        raise InputError("stopped by the test")

    if command == "morph":
        monkeypatch.setattr(vfit_engine.body.morph, "Morpher", compile_and_stop)
        args = ["morph", "--waist", "72", "-o", str(tmp_path / "body.obj"), "--quiet"]
    else:
        monkeypatch.setattr(vfit_engine.drape, "prepare_drape", compile_and_stop)
        args = ["drape", str(ROOT / "data" / "garments" / "skirt.obj"), "-o", str(tmp_path / "o"), "--quiet"]
    cold = CliRunner().invoke(cli, args)
    warm = CliRunner().invoke(cli, args)
    for r in (cold, warm):
        assert r.exit_code == 2 and "Error: stopped by the test" in r.output, r.output
    assert f"vfit {command}: compiling the kernels, once: later runs load them from the cache" in cold.output
    assert f"vfit {command}: compiled the kernels in " in cold.output, cold.output
    assert "compil" not in warm.output, warm.output


def test_a_compile_cut_short_is_not_called_done():
    """A compile that fails or is interrupted (Ctrl-C) leaves its kernel uncached: the last line says so."""
    import numba

    from vfit_cli._progress import Progress

    stream = io.StringIO()
    with Progress(True, stream=stream, command="vfit test").compiling():
        with pytest.raises(numba.core.errors.TypingError):
            numba.njit(lambda x: x + "a")(1)
    assert stream.getvalue().splitlines()[-1].startswith("vfit test: compiled kernels for ")
    assert stream.getvalue().endswith("the last one cut short: the next run compiles it again\n")
