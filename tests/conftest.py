"""Session-wide fixtures: the body model and the measurement/morph machinery are built once; on a fresh clone
Numba's cache is filled before the test processes start (:func:`pytest_configure`)."""
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"


def pytest_configure(config):
    """On a fresh clone run with two or more test processes (``make test``), fill Numba's cache first, in two
    processes with disjoint work (``_warm_kernels.py`` says why), so no kernel compiles twice at once."""
    workers = getattr(config.option, "numprocesses", None)
    if hasattr(config, "workerinput") or not isinstance(workers, int) or workers < 2:
        return
    from vfit_engine.kernel_compiles import is_cached
    from vfit_engine.kernels.cloth import cloth_substeps

    if is_cached(cloth_substeps):
        return
    t0 = time.perf_counter()
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    warm = Path(__file__).with_name("_warm_kernels.py")
    parts = ("gs", "rest")
    with tempfile.TemporaryDirectory() as tmp:
        logs = [open(Path(tmp) / f"{part}.err", "w+") for part in parts]
        runs = [subprocess.Popen([sys.executable, str(warm), part], env=env, stdout=subprocess.DEVNULL, stderr=log)
                for part, log in zip(parts, logs)]
        failed = []
        for part, run, log in zip(parts, runs, logs):
            if run.wait():
                log.seek(0)
                failed.append(f"{part}: " + (log.read().strip().splitlines() or ["no message"])[-1])
            log.close()
    print(f"\nNumba's cache filled before the tests in {time.perf_counter() - t0:.0f} s (two processes)"
          + (f"; not all of it ({'; '.join(failed)}): those kernels compile in the tests" if failed else ""),
          file=sys.stderr)


@pytest.fixture(scope="session")
def body_model():
    from vfit_engine.body.model import BodyModel

    return BodyModel.load()


@pytest.fixture(scope="session")
def measurer(body_model):
    from vfit_engine.body.measure import Measurer

    return Measurer(body_model)


@pytest.fixture(scope="session")
def morpher(body_model, measurer):
    from vfit_engine.body.morph import Morpher

    return Morpher(body_model, measurer)


@pytest.fixture
def skirt_dir(tmp_path):
    """A folder with a copy of vfit's demo skirt (``skirt.obj``), for job files that name it."""
    import shutil

    d = tmp_path / "job"
    d.mkdir()
    shutil.copy(Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj", d / "skirt.obj")
    return d
