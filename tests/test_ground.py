"""The ground under the body: a garment longer than the legs rests on it and settles.

The demo skirt (``data/garments/skirt.obj``, 55 cm) lengthened below its hips into a maxi skirt whose hem, as
made, lies 5 cm below the soles of the average female body it was made on: without the ground the hem hangs
below the feet, through where the floor would be; with it (the drape's default) it pools on the ground.
"""
import dataclasses
from pathlib import Path

import numpy as np
import pytest

SKIRT = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"


@pytest.fixture(scope="module")
def maxi_drape(body_model):
    from vfit_engine.body.resolve import default_body
    from vfit_engine.drape import prepare_drape, run_drape
    from vfit_engine.garment.garment import load_garment

    skirt = load_garment(SKIRT)
    body = default_body(body_model, "female")
    sole = float(body.surface[:, 1].min())
    v = skirt.verts.copy()
    below = v[:, 1] < -0.10  # from the hips down the panels are stretched lengthwise, the hem to 5 cm below the soles
    v[below, 1] = -0.10 + (v[below, 1] + 0.10) * (sole - 0.05 + 0.10) / (v[:, 1].min() + 0.10)
    maxi = dataclasses.replace(skirt, mesh=skirt.mesh.with_verts(v))
    setup = prepare_drape(maxi, body, body_model)
    return setup, run_drape(setup), sole


@pytest.mark.slow
def test_maxi_skirt_pools_on_the_ground_and_settles(maxi_drape):
    setup, res, sole = maxi_drape
    from vfit_engine.drape import DrapeSettings

    skin = DrapeSettings().contact.skin
    assert setup.ground == pytest.approx(sole - 2 * skin - 0.001) and setup.info["ground_y_m"] == setup.ground
    assert res.converged and res.metrics["finite"]
    y = res.pos[:, 1]
    assert y.min() >= setup.ground + skin - 1e-9  # nothing through the ground
    resting = np.abs(y - (setup.ground + skin)) < 1e-4
    assert resting.sum() >= 64  # at least a hem's worth (64 round) lies on it
    assert res.metrics["surface_deeper_than_2mm"] == 0 and res.metrics["surface_inside_percent"] <= 0.5
    assert res.metrics["p99_strain"] <= 0.05
