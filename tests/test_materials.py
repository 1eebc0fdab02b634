"""Materials: the JSON keys with their units, the ranges, the presets."""
import json

import pytest

from vfit_engine.errors import InputError
from vfit_engine.sim.materials import KEYS, PRESETS, load_material, material_from_dict, resolve_material


def _good():
    return {k: v for k, v in PRESETS["cotton"].to_dict().items() if k != "name"}


def test_presets_cover_the_fabrics_and_order_their_stiffness():
    assert {"silk", "cotton", "wool", "denim", "jersey"} <= set(PRESETS)
    b = {k: sum(m.bending_rigidity) / 2 for k, m in PRESETS.items()}
    assert b["silk"] < b["cotton"] < b["wool"] < b["denim"]
    assert PRESETS["jersey"].stretch_stiffness < PRESETS["cotton"].stretch_stiffness / 5  # a knit stretches
    for m in PRESETS.values():
        assert 0.01 < m.bending_length < 0.04  # fabrics' bending lengths are 1-3 cm (FABRICS.md)


def test_a_material_file_round_trips_in_its_units(tmp_path):
    path = tmp_path / "poplin.json"
    path.write_text(json.dumps({**_good(), "bending_rigidity_uN_m": [8, 6], "areal_density_g_m2": 110}))
    mat = load_material(path)
    assert mat.name == "poplin"
    assert mat.areal_density == pytest.approx(0.110) and mat.bending_rigidity == pytest.approx((8e-6, 6e-6))
    assert material_from_dict(mat.to_dict()) == mat
    assert resolve_material(str(path)) == mat
    single = material_from_dict({**_good(), "bending_rigidity_uN_m": 6.0})
    assert single.bending_rigidity == pytest.approx((6e-6, 6e-6))


@pytest.mark.parametrize("change, message", [
    ({"areal_density_g_m2": 0.12}, r"areal_density_g_m2 0.12 g/m\^2 is outside the physical range 10-1500"),
    ({"bending_rigidity_uN_m": 6e-6}, r"bending_rigidity_uN_m 6e-06 uN m is outside"),
    ({"bending_rigidity_uN_m": [6, 6, 6]}, r"bending_rigidity_uN_m takes one value or \[warp, weft\]"),
    ({"stretch_stiffness_N_m": -1}, r"stretch_stiffness_N_m -1 N/m is outside"),
    ({"shear_stiffness_N_m": float("nan")}, r"shear_stiffness_N_m must be a finite number"),
    ({"wearable_stretch": "5%"}, r"wearable_stretch must be a finite number"),
    ({"friction": 7}, r"friction 7 is outside the physical range 0-2"),
    ({"bend_stiffness": 20}, r"unknown key 'bend_stiffness' \(now bending_rigidity_uN_m"),
    ({"colour": "red"}, r"unknown key 'colour'; keys: areal_density_g_m2"),
])
def test_bad_values_are_refused_naming_the_key_and_its_range(tmp_path, change, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({**_good(), **change}))
    with pytest.raises(InputError, match=message) as err:
        load_material(path)
    assert str(path) in str(err.value)


def test_missing_keys_and_broken_files_are_refused(tmp_path):
    path = tmp_path / "m.json"
    for key in [k for k, spec in KEYS.items() if spec[5]]:
        path.write_text(json.dumps({k: v for k, v in _good().items() if k != key}))
        with pytest.raises(InputError, match=f"missing key.*{key}"):
            load_material(path)
    path.write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        load_material(path)
    with pytest.raises(InputError, match="unknown material 'tweed'"):
        resolve_material("tweed")
    with pytest.raises(InputError, match="cannot read"):
        load_material(tmp_path / "absent.json")
