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
