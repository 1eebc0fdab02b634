"""A plain (non-editable) wheel carries every module, the body data and the CLI as vfit_cli.

The wheel is built from a clean copy of the source tree (the files git tracks: no ``build/`` left over from an
earlier build can add a module the tree lacks), and its modules are imported from it alone: a subpackage left
out of the wheel (``vfit_engine.textile`` was) fails here, not on a user's machine after ``pip install``.
"""
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: import name -> its folder in the source tree (pyproject.toml's package-dir: cli/ and data/ install renamed)
PACKAGE_DIRS = {"vfit_engine": "vfit_engine", "vfit_cli": "cli", "vfit_engine.data": "data"}


def source_modules():
    """Every module of the source tree by its import name (the three folders of :data:`PACKAGE_DIRS`)."""
    names = set()
    for package, folder in PACKAGE_DIRS.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            names.add(".".join((package, *parts)))
    return sorted(names)


def clean_copy(dst):
    """The source tree as a fresh clone has it: the files git tracks (as they are now), else the tree without
    what builds and installs leave behind."""
    r = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True) if shutil.which("git") else None
    if r is not None and r.returncode == 0 and r.stdout:
        for name in r.stdout.decode().split("\0"):
            if name and (ROOT / name).is_file():  # (a file deleted but not yet committed is not copied)
                (dst / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(ROOT / name, dst / name)
    else:
        shutil.copytree(ROOT, dst, dirs_exist_ok=True, ignore=shutil.ignore_patterns(
            ".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache", "out"))
    return dst


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    """(path of the wheel built from a clean copy of the source tree, pip's stderr)."""
    src = clean_copy(tmp_path_factory.mktemp("src"))
    out = tmp_path_factory.mktemp("wheel")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                        "-w", str(out), str(src)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    return next(out.glob("vfit-*.whl")), r.stderr


@pytest.mark.slow
def test_wheel_contents(wheel):
    wheel, stderr = wheel
    # no packaging warnings (a deprecated licence table; a data folder setuptools "would ignore")
    assert "deprecated" not in stderr.lower() and "would be ignored" not in stderr.lower(), stderr[-2000:]
    names = zipfile.ZipFile(wheel).namelist()
    for required in ("vfit_engine/data/hm08.npz", "vfit_engine/data/rulers.json", "vfit_engine/data/LICENSE-CC0.txt",
                     "vfit_engine/data/rig_default.json", "vfit_engine/data/garments/skirt.obj", "vfit_cli/main.py",
                     "vfit_engine/kernels/girth.py", "vfit_engine/drape/loop.py", "vfit_engine/sim/partition.py",
                     "vfit_engine/textile/cusick.py"):
        assert required in names, required
    assert not any(n.startswith("cli/") for n in names), "a top-level 'cli' package must not be installed"
    entry = next(n for n in names if n.endswith("entry_points.txt"))
    assert "vfit = vfit_cli.main:run" in zipfile.ZipFile(wheel).read(entry).decode()  # cli, then a quick end


#: run in a Python that sees the unpacked wheel and the dependencies only: every module imports from the wheel,
#: the body data loads from it and ``vfit --help`` answers
IMPORT_ALL = """
import importlib, json, os, sys
wheel_dir, names = sys.argv[1], json.loads(sys.argv[2])
failed = {}
for name in names:
    try:
        module = importlib.import_module(name)
    except Exception as exc:
        failed[name] = f"{type(exc).__name__}: {exc}"
    else:
        if not os.path.realpath(module.__file__).startswith(os.path.realpath(wheel_dir) + os.sep):
            failed[name] = f"imported from {module.__file__}, not the wheel"
from vfit_engine.body.model import BodyModel
model = BodyModel.load()  # hm08.npz; the rig and rulers (JSON) with it
print(json.dumps(dict(failed=failed, verts=len(model.default_verts("female")), bones=len(model.rig),
                      rulers=len(model.rulers))))
"""


@pytest.mark.slow
def test_wheel_alone_imports_every_module(wheel, tmp_path):
    """The wheel unpacked as pip installs it, on a path with the dependencies (this environment's site-packages)
    and nothing else: not the source tree, not the editable install's finder (``-S``: no .pth file runs)."""
    wheel, _ = wheel
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    paths = list(dict.fromkeys([str(site), sysconfig.get_path("purelib"), sysconfig.get_path("platlib")]))
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    code = f"import sys; sys.path[:0] = {paths!r}\n" + IMPORT_ALL
    names = source_modules()
    assert "vfit_engine.textile.cusick" in names and "vfit_cli.animate" in names
    r = subprocess.run([sys.executable, "-I", "-S", "-c", code, str(site), json.dumps(names)],
                       capture_output=True, text=True, cwd=tmp_path, env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads(r.stdout.splitlines()[-1])
    assert got["failed"] == {}, ("modules of the source tree the wheel does not import (is each file in git, its "
                                 "folder a package with an __init__.py?):\n"
                                 + "\n".join(f"{k}: {v}" for k, v in got["failed"].items()))
    assert got["verts"] > 0 and got["bones"] > 0 and got["rulers"] > 0, got
