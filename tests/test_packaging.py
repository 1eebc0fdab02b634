"""A plain (non-editable) wheel carries the body data and the CLI as vfit_cli."""
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_contents(tmp_path):
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                        "-w", str(tmp_path), str(ROOT)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    # no packaging warnings (a deprecated licence table; a data folder setuptools "would ignore")
    assert "deprecated" not in r.stderr.lower() and "would be ignored" not in r.stderr.lower(), r.stderr[-2000:]
    wheel = next(tmp_path.glob("vfit-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    for required in ("vfit_engine/data/hm08.npz", "vfit_engine/data/rulers.json", "vfit_engine/data/LICENSE-CC0.txt",
                     "vfit_engine/data/rig_default.json", "vfit_engine/data/garments/skirt.obj", "vfit_cli/main.py",
                     "vfit_engine/kernels/girth.py", "vfit_engine/drape/loop.py", "vfit_engine/sim/partition.py"):
        assert required in names, required
    assert not any(n.startswith("cli/") for n in names), "a top-level 'cli' package must not be installed"
    entry = next(n for n in names if n.endswith("entry_points.txt"))
    assert "vfit = vfit_cli.main:run" in zipfile.ZipFile(wheel).read(entry).decode()  # cli, then a quick end
