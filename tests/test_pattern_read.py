"""The GarmentCode / GPG reader: each curve form against its closed form, the four shared patterns, every refusal."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.errors import InputError
from vfit_engine.pattern import curves, garmentcode

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")

# file: (panels, stitches, frame) as the files hold them (counted by hand in the JSON)
SHARED = {
    "garmentcode_shirt_mean.json": (8, 18, "garmentcode"),
    "garmentcode_dress_pencil.json": (6, 23, "garmentcode"),
    "gpg_tee.json": (6, 12, "gpg"),
    "gpg_skirt_4_panels.json": (4, 8, "gpg"),
}


def write(tmp_path, spec, name="p.json"):
    path = tmp_path / name
    path.write_text(json.dumps(spec))
    return path


def one_edge_spec(curvature, a=(0.0, 0.0), b=(40.0, 0.0), units=100, coords="relative"):
    """A triangle whose edge 0 (a to b) carries ``curvature``; lengths in cm (units 100)."""
    edge = {"endpoints": [0, 1]}
    if curvature is not None:
        edge["curvature"] = curvature
    panel = {"vertices": [list(a), list(b), [20.0, -30.0]], "translation": [0, 100, 10], "rotation": [0, 0, 0],
             "edges": [edge, {"endpoints": [1, 2]}, {"endpoints": [2, 0]}]}
    return {"pattern": {"panels": {"p": panel}, "stitches": []},
            "properties": {"units_in_meter": units, "curvature_coords": coords, "normalized_edge_loops": True}}


# ---------------------------------------------------------------------- curves against closed forms
@pytest.mark.parametrize("large", [0, 1])
@pytest.mark.parametrize("right", [0, 1])
def test_circle_arc_length_and_side(tmp_path, large, right):
    r, c = 25.0, 40.0  # cm: chord 40 between (0, 0) and (40, 0)
    pattern = garmentcode.read(write(tmp_path, one_edge_spec({"type": "circle", "params": [r, large, right]})))
    panel = pattern.panels["p"]
    half = math.asin(c / (2 * r))  # half the small arc's angle
    angle = 2 * math.pi - 2 * half if large else 2 * half
    assert panel.edge_length(0) == pytest.approx(r * angle / 100, rel=1e-9)
    mid = panel.edge_points(0, np.array([0.5]))[0]
    sagitta = (r + math.sqrt(r * r - c * c / 4)) if large else (r - math.sqrt(r * r - c * c / 4))
    # left of the edge (+y for an edge along +x) unless ``right``
    assert mid == pytest.approx([0.2, (-sagitta if right else sagitta) / 100], abs=1e-9)
    # every sampled point on the circle of radius r
    centre_y = (sagitta - r) if not right else (r - sagitta)
    pts = panel.edge_points(0, np.linspace(0, 1, 9)) * 100
    assert np.hypot(pts[:, 0] - 20, pts[:, 1] - centre_y) == pytest.approx(np.full(9, r), abs=1e-9)


def test_half_circle(tmp_path):
    pattern = garmentcode.read(write(tmp_path, one_edge_spec({"type": "circle", "params": [20.0, 0, 0]})))
    assert pattern.panels["p"].edge_length(0) == pytest.approx(math.pi * 0.2, rel=1e-9)


@pytest.mark.parametrize("form", ["legacy", "dict"])
def test_quadratic_midpoint_relative(tmp_path, form):
    x, y = 0.3, 0.25
    curv = [x, y] if form == "legacy" else {"type": "quadratic", "params": [[x, y]]}
    panel = garmentcode.read(write(tmp_path, one_edge_spec(curv, a=(10, 20), b=(50, 50)))).panels["p"]
    a, b = np.array([10.0, 20.0]), np.array([50.0, 50.0])
    d = b - a
    ctrl = a + x * d + y * np.array([-d[1], d[0]])
    assert np.array(panel.edges[0].controls[0]) * 100 == pytest.approx(ctrl)
    # B(1/2) = (a + 2 c + b) / 4
    mid = curves.curve_points("quadratic", panel.edge_ends(0), panel.edges[0].controls, [0.5])[0]
    assert mid * 100 == pytest.approx((a + 2 * ctrl + b) / 4)


def test_quadratic_absolute_coords(tmp_path):
    spec = one_edge_spec({"type": "quadratic", "params": [[20.0, 10.0]]}, coords="absolute")
    panel = garmentcode.read(write(tmp_path, spec)).panels["p"]
    assert panel.edges[0].controls[0] == pytest.approx((0.2, 0.1))
    # a parabola through its vertex: B(1/2) = (a + 2c + b) / 4 = (20, 5) cm
    assert panel.edge_points(0, np.array([0.5]))[0] == pytest.approx([0.2, 0.05], abs=1e-5)


def test_cubic_on_a_straight_control_polygon(tmp_path):
    # controls on the chord, at 1/3 and 2/3: the curve is the segment itself, 40 cm
    curv = {"type": "cubic", "params": [[1 / 3, 0.0], [2 / 3, 0.0]]}
    panel = garmentcode.read(write(tmp_path, one_edge_spec(curv))).panels["p"]
    assert panel.edge_length(0) == pytest.approx(0.4, rel=1e-6)
    # controls beyond the ends, still on the line: the curve stays on the segment and is no longer than it
    curv = {"type": "cubic", "params": [[-0.5, 0.0], [1.5, 0.0]]}
    panel = garmentcode.read(write(tmp_path, one_edge_spec(curv))).panels["p"]
    pts = panel.edge_points(0, np.linspace(0, 1, 50))
    assert np.abs(pts[:, 1]).max() < 1e-12
    assert panel.edge_length(0) >= 0.4 - 1e-6


def test_units_and_placement(tmp_path):
    spec = one_edge_spec(None, units=300)
    pattern = garmentcode.read(write(tmp_path, spec))
    panel = pattern.panels["p"]
    assert pattern.units_in_meter == 300
    assert panel.edge_length(0) == pytest.approx(40 / 300)
    assert panel.translation == pytest.approx([0, 100 / 300, 10 / 300])


def test_bare_pattern_defaults_to_cm_and_no_frame(tmp_path):
    spec = one_edge_spec(None)["pattern"]
    del spec["panels"]["p"]["translation"]
    pattern = garmentcode.read(write(tmp_path, spec))
    assert pattern.units_in_meter == 100
    assert pattern.frame is None
    assert pattern.panels["p"].edge_length(0) == pytest.approx(0.4)


def test_frame_rule(tmp_path):
    spec = one_edge_spec(None)
    assert garmentcode.read(write(tmp_path, spec)).frame == "garmentcode"
    del spec["properties"]["normalized_edge_loops"]
    assert garmentcode.read(write(tmp_path, spec)).frame == "gpg"
    spec["properties"]["normalized_edge_loops"] = True
    spec["parameters"] = {"len": {"influence": [], "type": "length", "value": 1}}
    assert garmentcode.read(write(tmp_path, spec)).frame == "gpg"


def test_panel_order_and_stitch_flags(tmp_path):
    spec = one_edge_spec(None)
    panels = spec["pattern"]["panels"]
    panels["q"] = json.loads(json.dumps(panels["p"]))
    panels["r"] = json.loads(json.dumps(panels["p"]))
    spec["pattern"]["panel_order"] = ["r", "p"]
    spec["pattern"]["stitches"] = [[{"panel": "p", "edge": 1}, {"panel": "q", "edge": 2}],
                                   [{"panel": "q", "edge": 1}, {"panel": "r", "edge": 2}, "right_wrong"]]
    pattern = garmentcode.read(write(tmp_path, spec))
    assert list(pattern.panels) == ["r", "p", "q"]
    s0, s1 = pattern.stitches
    assert (s0.a.panel, s0.a.edge, s0.b.panel, s0.b.edge) == ("p", 1, "q", 2)
    assert not s0.right_wrong and s1.right_wrong
    assert s0.opposed is None and s1.opposed is None


# ---------------------------------------------------------------------- the shared patterns
@needs_shared
@pytest.mark.parametrize("name", sorted(SHARED))
def test_shared_pattern_reads(name):
    panels, stitches, frame = SHARED[name]
    pattern = garmentcode.read(PATTERNS / name)
    assert (len(pattern.panels), len(pattern.stitches), pattern.frame) == (panels, stitches, frame)
    for panel in pattern.panels.values():
        for i, edge in enumerate(panel.edges):  # every loop closed: each edge ends where the next begins
            assert edge.end == panel.edges[(i + 1) % len(panel.edges)].start
        size = np.ptp(panel.outline(), axis=0)
        assert 0.05 < size.max() < 1.5, f"{panel.name}: {size} m"  # garment pieces, in metres
    for s in pattern.stitches:
        assert abs(pattern.edge_length(s.a) - pattern.edge_length(s.b)) < 0.08


@needs_shared
def test_shared_body_beside_garmentcode_files():
    body = garmentcode.read(PATTERNS / "garmentcode_shirt_mean.json").body
    assert body["height"] == pytest.approx(171.99) and body["bust"] == pytest.approx(99.8407)
    assert garmentcode.read(PATTERNS / "gpg_tee.json").body == {}


def _inside(poly, p):
    """Even-odd point-in-polygon test."""
    x, y = poly[:, 0], poly[:, 1]
    x2, y2 = np.roll(x, -1), np.roll(y, -1)
    cross = (y > p[1]) != (y2 > p[1])
    xs = x + (p[1] - y) * (x2 - x) / np.where(y2 == y, 1, y2 - y)
    return bool(np.sum(cross & (p[0] < xs)) % 2)


@needs_shared
def test_shared_necklines_and_armholes_curve_into_the_panel():
    """The control-point side convention: a scooped neckline or armhole bulges into its panel, not out of it
    (with the perpendicular turned the other way they would all bulge outwards)."""
    cases = [("garmentcode_shirt_mean.json", "left_ftorso", [2, 4]), ("garmentcode_shirt_mean.json", "right_btorso",
             None), ("gpg_tee.json", "front", [2, 6])]
    for name, panel_name, edges in cases:
        panel = garmentcode.read(PATTERNS / name).panels[panel_name]
        straight = panel.vertices[[e.start for e in panel.edges]]
        curved = [i for i, e in enumerate(panel.edges) if e.kind != "line"] if edges is None else edges
        assert curved
        for i in curved:
            mid = panel.edge_points(i, np.array([0.5]))[0]
            chord_mid = 0.5 * (panel.vertices[panel.edges[i].start] + panel.vertices[panel.edges[i].end])
            if np.linalg.norm(mid - chord_mid) > 0.005:  # visibly curved: it must lie inside the straight polygon
                assert _inside(straight, mid), f"{name} {panel_name} edge {i}"


# ---------------------------------------------------------------------- refusals
def _refused(tmp_path, spec, *words, raw=None):
    path = tmp_path / "bad.json"
    path.write_text(raw if raw is not None else json.dumps(spec))
    with pytest.raises(InputError) as info:
        garmentcode.read(path)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg and "fix:" in msg
    for w in words:
        assert w in msg, msg
    return msg


def test_refuses_unreadable_json(tmp_path):
    _refused(tmp_path, None, "JSON", raw="{\"pattern\": [")
    _refused(tmp_path, [1, 2], "top level")
    _refused(tmp_path, {"pattern": {"stitches": []}}, "panels")


def test_refuses_missing_vertices(tmp_path):
    spec = one_edge_spec(None)
    del spec["pattern"]["panels"]["p"]["vertices"]
    _refused(tmp_path, spec, "panel 'p'", "vertices")


def test_refuses_endpoint_out_of_range(tmp_path):
    spec = one_edge_spec(None)
    spec["pattern"]["panels"]["p"]["edges"][2]["endpoints"] = [2, 3]
    _refused(tmp_path, spec, "panel 'p'", "edge 2", "out of range")


@pytest.mark.parametrize("curv, words", [
    ({"type": "spline", "params": [[0.5, 0.1]]}, ["unknown curvature type"]),
    ({"type": "cubic", "params": [[0.5, 0.1]]}, ["1 control points, not 2"]),
    ({"type": "quadratic", "params": [[0.5, 0.1], [0.2, 0.2], [0.3, 0.3]]}, ["3 control points, not 1"]),
    ({"type": "circle", "params": [30.0, 0]}, ["circle params"]),
    ({"type": "circle", "params": [10.0, 0, 0]}, ["shorter than half the chord"]),
    ([0.5, float("nan")], ["not finite"]),
    ({"type": "quadratic", "params": [[0.5, "x"]]}, ["control point 0"]),
])
def test_refuses_bad_curvature(tmp_path, curv, words):
    _refused(tmp_path, one_edge_spec(curv), "panel 'p'", "edge 0", *words)


def test_refuses_non_finite_vertex_and_units(tmp_path):
    spec = one_edge_spec(None)
    spec["pattern"]["panels"]["p"]["vertices"][1] = [1e400, 0]  # json writes Infinity
    _refused(tmp_path, spec, "panel 'p'", "vertex 1", "not finite")
    spec = one_edge_spec(None, units=0)
    _refused(tmp_path, spec, "units_in_meter")
    spec = one_edge_spec(None)
    spec["pattern"]["panels"]["p"]["translation"] = [0, 1]
    _refused(tmp_path, spec, "panel 'p'", "translation")


@pytest.mark.parametrize("side, words", [
    ({"panel": "nope", "edge": 0}, ["panel 'nope'", "not in the pattern"]),
    ({"panel": "p", "edge": 7}, ["panel 'p'", "edge 7", "0 to 2"]),
])
def test_refuses_stitch_to_missing_panel_or_edge(tmp_path, side, words):
    spec = one_edge_spec(None)
    spec["pattern"]["stitches"] = [[{"panel": "p", "edge": 0}, side]]
    _refused(tmp_path, spec, "stitch 0", *words)


def test_refuses_one_sided_stitch(tmp_path):
    spec = one_edge_spec(None)
    spec["pattern"]["stitches"] = [[{"panel": "p", "edge": 0}]]
    _refused(tmp_path, spec, "stitch 0", "1 sides")


def test_refuses_panel_order_naming_a_missing_panel(tmp_path):
    spec = one_edge_spec(None)
    spec["pattern"]["panel_order"] = ["p", "ghost"]
    _refused(tmp_path, spec, "ghost", "panel_order")
