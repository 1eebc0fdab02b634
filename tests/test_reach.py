"""Issue 11: every customer's body. The reach list built and measured independently, the extremes
still human, bust above underbust, estimates within the survey's standard error, plausibility
warnings and refusals, and error ranges whose ends are reachable.

Solves share the session's Morpher and each body is solved once (``_solved``); no mesh is written.
"""
import re

import numpy as np
import pytest
import trimesh

from body_checks import inverted_faces, section_overlap
from tape import breast_vertices, tape_measure
from vfit_engine.errors import InputError

MM = 1e-3
DENSITY = 985.0  # kg/m^3, as the issue states it
# (id, gender, targets in cm, weight kg): issue 11 section 1
REACH = [
    ("women-34", "female", dict(height=168, bust=80, waist=64, hips=90), None),
    ("women-38", "female", dict(height=168, bust=88, waist=72, hips=97), None),
    ("women-42", "female", dict(height=168, bust=96, waist=80, hips=103), None),
    ("women-46", "female", dict(height=168, bust=106, waist=90, hips=112), None),
    ("women-50", "female", dict(height=168, bust=118, waist=102, hips=124), None),
    ("women-54", "female", dict(height=168, bust=130, waist=114, hips=136), None),
    ("men-46", "male", dict(height=180, bust=92, waist=80, hips=96), None),
    ("men-50", "male", dict(height=180, bust=100, waist=88, hips=102), None),
    ("men-54", "male", dict(height=180, bust=108, waist=98, hips=108), None),
    ("men-58", "male", dict(height=180, bust=116, waist=108, hips=114), None),
    ("men-62", "male", dict(height=180, bust=124, waist=117, hips=121), None),
    ("women-150-45", "female", dict(height=150), 45.0),
    ("women-165-90", "female", dict(height=165), 90.0),
    ("women-160-110", "female", dict(height=160), 110.0),
    ("men-175-130", "male", dict(height=175), 130.0),
    ("men-195-75", "male", dict(height=195), 75.0),
    ("women-w110-h130", "female", dict(waist=110, hips=130), None),
]
CASES = {c[0]: c for c in REACH}
#: the extremes whose torso girths the independent tape re-measures and whose shape is checked
EXTREMES = ("women-34", "women-54", "men-62", "women-160-110", "men-175-130", "men-195-75", "women-w110-h130")
TAPED = ("women-54", "men-62")  # the two sizes the issue found out of reach: re-measured by the independent tape
_solved = {}


def _solve(morpher, case_id):
    if case_id not in _solved:
        _, gender, cm, kg = CASES[case_id]
        _solved[case_id] = morpher.solve({k: v / 100 for k, v in cm.items()}, gender=gender, weight_kg=kg)
    return _solved[case_id]


@pytest.fixture(scope="module")
def breasts():
    return breast_vertices()


@pytest.mark.parametrize("case_id", [c[0] for c in REACH])
def test_reach_list(morpher, body_model, breasts, case_id):
    """Girths and height to 1 mm, mass to 0.5 kg as trimesh's volume x 985 kg/m^3; the torso girths
    of the largest sizes by the independent tape (trimesh sections + scipy hulls; ~1.5 s a body, so
    only there: ``scripts/reach_check.py`` tapes every body of the list through the CLI)."""
    _, gender, cm, kg = CASES[case_id]
    res = _solve(morpher, case_id)
    verts = res.verts[:13380]
    mesh = trimesh.Trimesh(verts, body_model.body_tris, process=False)
    assert mesh.volume > 0
    if kg is not None:
        assert abs(mesh.volume * DENSITY - kg) <= 0.5
    if "height" in cm:
        assert abs(verts[:, 1].max() - verts[:, 1].min() - cm["height"] / 100) <= MM
    for k, v in cm.items():
        assert abs(res.measurement.values[k] - v / 100) <= MM, (k, res.measurement.values[k])
    if case_id in TAPED:
        tape = tape_measure(res.verts, body_model.body_quads, breasts, chest=gender == "male")
        for k, v in cm.items():
            assert abs(tape[k] - v / 100) <= MM, (k, tape[k])
    # the bust plane is above the underbust plane on every body (the low-bust case of the issue)
    assert res.measurement.planes["bust"] > res.measurement.planes["underbust"] + 0.009


def test_size_46_man_measures_92_under_his_armpits(morpher, body_model, breasts):
    """Issue 31: the EN 13402 size-46 man (180 cm, chest 92, waist 80, hips 96) measured 94.5 cm with a tape
    under his armpits when his chest was taken at most 3 cm above his nipples. Now the independent tape reads
    92 cm there (within 1 mm), in the last 1 mm plane with his arms apart; the old band reads 2 cm less."""
    from tape import _apart, bust_band

    res = _solve(morpher, "men-46")
    verts = res.verts[:13380]
    mesh = trimesh.Trimesh(verts, body_model.body_tris, process=False)
    tape = tape_measure(verts, body_model.body_quads, breasts, chest=True)
    assert abs(tape["bust"] - 0.92) <= MM, tape["bust"]
    lo, hi = bust_band(mesh, verts, breasts, chest=True)
    assert _apart(mesh, hi) and not _apart(mesh, hi + 0.001) and hi - lo > 0.03
    assert abs(res.measurement.planes["bust"] - hi) < 1e-6
    assert tape_measure(verts, body_model.body_quads, breasts)["bust"] < 0.92 - 0.01


@pytest.mark.parametrize("case_id", EXTREMES)
def test_extremes_stay_human(morpher, body_model, case_id):
    """No part into another beyond flesh contact (section loops of arms, torso and thighs overlap by
    < 10 mm, 1.5 cm apart from knee to shoulder); faces turned over: at most 12 of the 26,756 beyond
    those MakeHuman's own heaviest body of the gender turns (4 on the male head). Measured: 0-2 on
    every extreme but the 175 cm / 130 kg man: 8 (his estimated 140 cm chest pulled the bust channel to 1,
    which turned 24 under the pectorals, at the armpits and throat; channels.INCR_MAX now holds it at 0.8);
    extrapolating the weight slider to 1.2 instead turns 78."""
    _, gender, _, _ = CASES[case_id]
    res = _solve(morpher, case_id)
    verts = res.verts[:13380]
    tris = body_model.body_tris
    y0, y1 = verts[:, 1].min(), verts[:, 1].max()
    depth, _ = section_overlap(verts, tris, np.arange(y0 + 0.3 * (y1 - y0), y0 + 0.8 * (y1 - y0), 0.015))
    assert depth < 0.010, depth
    ref = body_model.default_verts(gender)[:13380]
    corner = morpher._body(morpher.macro(morpher.macro(0.0 if gender == "female" else 1.0, 0.5, 1.0).gender,
                                         0.5, 1.0), np.zeros(len(morpher._channel_names)))
    assert inverted_faces(verts, ref, tris) <= inverted_faces(corner, ref, tris) + 12


def test_low_bust_stays_above_underbust(measurer, body_model):
    """Breasts lowered 9 cm along their bones' skin weights: the bust points fall below the top of the
    underbust ruler's +-2 cm band; the bust band starts at the bust points and the underbust band is
    cut 1 cm below them, so the two never swap."""
    bone, vert, w = body_model.skin
    on = np.isin(bone, [body_model.bone_names.index(b) for b in ("breast.L", "breast.R")]) & (vert < 13380)
    weight = np.zeros(13380)
    np.add.at(weight, vert[on], w[on])
    verts = body_model.default_verts("female")[:13380].copy()
    verts[:, 1] -= 0.09 * weight
    got = measurer.measure(verts, names=("bust", "underbust"), mass=False)
    bust_points = measurer.bust_band(verts)[0]
    ruler_top = verts[body_model.rulers["underbust-circ"]["vertex_indices"], 1].mean() + 0.02
    assert bust_points < ruler_top - 0.005  # the case a fixed band would get wrong
    assert got.planes["underbust"] <= bust_points - 0.01 + 1e-9 and got.planes["bust"] >= bust_points
    assert got.values["bust"] > got.values["underbust"] + 0.05


def test_estimates_within_the_regression_standard_error(morpher):
    """--height 165 --weight 90: the girths not given land within one standard error of the survey's
    estimate, and grow with mass against --weight 60."""
    res = morpher.solve({"height": 1.65}, weight_kg=90.0)
    light = morpher.solve({"height": 1.65}, weight_kg=60.0)
    assert set(res.estimated) == {"bust", "underbust", "waist", "hips", "neck", "upper-arm", "thigh", "calf"}
    for k, (value, sd) in res.estimated.items():
        assert abs(res.measurement.values[k] - value) <= value * sd, (k, res.measurement.values[k], value)
        assert res.measurement.values[k] > light.measurement.values[k] + 0.01, k


def test_plausibility_warning_and_refusal(morpher):
    """A 60 cm waist with 110 cm hips builds, warned with its percentile; a 33 cm waist, or a 55 cm
    waist with 130 cm hips (waist-to-hip 0.42), is refused with the reason."""
    res = morpher.solve({"height": 1.68, "waist": 0.60, "hips": 1.10})
    text = " ".join(res.warnings)
    assert "waist is at percentile" in text and "with the other measurements given (NHANES 2017-2018" in text
    with pytest.raises(InputError, match=r"refused: waist is 5\.\d standard deviations below the mean of adult women"):
        morpher.solve({"waist": 0.33})
    with pytest.raises(InputError, match=r"refused: waist is 9\.\d standard deviations below what adult women "
                                         r"with the other measurements given have"):
        morpher.solve({"height": 1.68, "waist": 0.55, "hips": 1.30})
    # a waist given above the hips (as NHANES tapes a man's, over the belly): no body's narrowest waist exceeds
    # its hips
    with pytest.raises(InputError, match=r"refused: waist 143\.8 cm is more than hips 138\.2 cm"):
        morpher.solve({"height": 1.772, "waist": 1.438, "hips": 1.382}, gender="male", weight_kg=141.9)


def test_flat_chest_builds(morpher, body_model, breasts):
    """The survey's 1st-percentile chest of men (168.2 cm, 52.1 kg, chest 87.1, waist 66.8, hips 88.0): two
    rows of his flat chest tie for the bust point, and the chest band jumped 13 mm between them under the
    solver's steps; it stopped 1.4 mm short of the waist. Re-measured by the independent tape."""
    cm = dict(height=168.153, bust=87.134, waist=66.814, hips=88.018)
    res = morpher.solve({k: v / 100 for k, v in cm.items()}, gender="male", weight_kg=52.095)
    tape = tape_measure(res.verts, body_model.body_quads, breasts, chest=True)
    for k, v in cm.items():
        assert abs(tape[k] - v / 100) <= MM, (k, tape[k])


def test_extremum_jumping_between_planes_builds(morpher, body_model, breasts):
    """The 135-degree corner of the men's 98 % height-mass ellipse (158.5 cm, 104.1 kg, chest 131.6, waist
    122.7, hips 123.8): his waist's smallest plane jumped between the hips line and 9 cm above it, and the
    solve stopped 3.7 mm short of the waist. A residual per watched plane (morph_planes.py) builds him;
    re-measured by the independent tape, and 0.5 kg by trimesh's volume."""
    cm = dict(height=158.5, bust=131.6, waist=122.7, hips=123.8)
    res = morpher.solve({k: v / 100 for k, v in cm.items()}, gender="male", weight_kg=104.1)
    tape = tape_measure(res.verts, body_model.body_quads, breasts, chest=True)
    verts = res.verts[:13380]
    assert abs(verts[:, 1].max() - verts[:, 1].min() - cm["height"] / 100) <= MM
    for k in ("bust", "waist", "hips"):
        assert abs(tape[k] - cm[k] / 100) <= MM, (k, tape[k])
    mesh = trimesh.Trimesh(verts, body_model.body_tris, process=False)
    assert abs(mesh.volume * DENSITY - 104.1) <= 0.5


@pytest.mark.parametrize("name", ["mass", "bust", "waist"])
def test_heaviest_men_of_the_population_build(morpher, body_model, breasts, name):
    """The men at the 99th percentile of mass, chest and waist, the other four of stature, mass, chest, waist and
    hips the survey's estimates given that one (``scripts/reach_check.py --population``). The survey's log-normal
    once estimated them a waist at or above their hips (mass: 139.07 against 139.08 cm, which no solve met to
    0.2 mm; chest and waist: 137.7 > 136.7 and 143.8 > 138.2 cm, refused), which no tape measures; now built
    to 1 mm by the independent tape (hips, waist, chest) and 0.5 kg by trimesh's volume."""
    pop = morpher.population(1.0)
    given = {name: pop.quantile(name, 2.3263)}
    est, _ = pop.predict(given)
    body = {**est, **given}
    assert body["waist"] < body["hips"] - 0.01
    cm = {k: body[k] * 100 for k in ("height", "bust", "waist", "hips")}
    res = morpher.solve({k: v / 100 for k, v in cm.items()}, gender="male", weight_kg=body["mass"])
    verts = res.verts[:13380]
    assert abs(verts[:, 1].max() - verts[:, 1].min() - cm["height"] / 100) <= MM
    tape = tape_measure(res.verts, body_model.body_quads, breasts, chest=True)
    for k in ("bust", "waist", "hips"):
        assert abs(tape[k] - cm[k] / 100) <= MM, (k, tape[k])
    mesh = trimesh.Trimesh(verts, body_model.body_tris, process=False)
    assert abs(mesh.volume * DENSITY - body["mass"]) <= 0.5
    # still human (test_extremes_stay_human's bars): no part into another beyond flesh contact, few faces turned
    y0, y1 = verts[:, 1].min(), verts[:, 1].max()
    depth, _ = section_overlap(verts, body_model.body_tris, np.arange(y0 + 0.3 * (y1 - y0), y0 + 0.8 * (y1 - y0), 0.015))
    assert depth < 0.010, depth
    ref = body_model.default_verts("male")[:13380]
    corner = morpher._body(morpher.macro(morpher.macro(1.0, 0.5, 1.0).gender, 0.5, 1.0),
                           np.zeros(len(morpher._channel_names)))
    assert inverted_faces(verts, ref, body_model.body_tris) <= inverted_faces(corner, ref, body_model.body_tris) + 12


def test_error_range_ends_are_reachable(morpher):
    """bust 70 with underbust 90 cannot be met; the bust range given the underbust is printed, and
    both its ends are then built. (The range search's time limit is lifted: this machine's load must
    not decide whether the range is printed; bench_morph times the failure.)"""
    with pytest.raises(InputError, match="cannot be met together") as err:
        morpher.solve({"bust": 0.70, "underbust": 0.90}, search_seconds=60.0)
    lo, hi = map(float, re.search(r"bust 70\.0 cm \(reachable (\d+\.\d)-(\d+\.\d) cm", str(err.value)).groups())
    assert hi - lo > 5.0
    for end in (lo, hi):
        res = morpher.solve({"bust": end / 100, "underbust": 0.90})
        assert abs(res.measurement.values["bust"] - end / 100) <= MM


def test_range_search_keeps_its_time_limit(morpher):
    """A failure's range searches end by their deadline: none begins after it, and one running then is cut
    (``OutOfTime``) and named as not searched, with the option that searches longer. Without a target the
    others may be refused (no body has them): that target gets no range, and the error stays the failure's."""
    from vfit_engine.body.morph import OutOfTime

    with pytest.raises(InputError, match=r"bust 70\.0 cm \(range not searched in the time limit: --search-time"):
        morpher.solve({"bust": 0.70, "underbust": 0.90}, search_seconds=0.0)
    with pytest.raises(OutOfTime):
        morpher.reachable("bust", {"bust": 0.70, "underbust": 0.90}, 0.0, deadline=0.0)
    targets = {"waist": 0.90, "hips": 0.95, "bust": 1.30, "underbust": 0.70}
    with pytest.raises(InputError, match="cannot be met together") as err:
        morpher.solve(targets, search_seconds=60.0)
    text = str(err.value)
    assert "waist 90.0 cm (no range: without it the other targets are outside the population" in text
    assert re.search(r"underbust 70\.0 cm \(reachable 10\d\.\d-10\d\.\d cm", text), text
