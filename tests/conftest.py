"""Session-wide fixtures: the body model and the measurement/morph machinery are built once."""
from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"


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
