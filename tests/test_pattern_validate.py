"""Pattern validation: every error on a minimal hand-written pattern, the warnings, and the four shared patterns."""

import json
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.errors import InputError
from vfit_engine.pattern import garmentcode, model, validate

PATTERNS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "patterns"
needs_shared = pytest.mark.skipif(not PATTERNS.is_dir(), reason="../shared/assets/patterns absent")

RECT = [[0, 0], [40, 0], [40, 30], [0, 30]]  # cm


def panel_spec(vertices, loop=None, curvature=None):
    """A panel over ``vertices`` (cm) whose edges run round them in order (or along ``loop``'s index pairs)."""
    n = len(vertices)
    loop = loop or [[i, (i + 1) % n] for i in range(n)]
    edges = [{"endpoints": list(e)} for e in loop]
    for i, curv in (curvature or {}).items():
        edges[i]["curvature"] = curv
    return {"vertices": vertices, "edges": edges, "translation": [0, 0, 0], "rotation": [0, 0, 0]}


def read(tmp_path, panels, stitches=(), units=100):
    spec = {"pattern": {"panels": panels, "stitches": list(stitches)},
            "properties": {"units_in_meter": units, "normalized_edge_loops": True}}
    path = tmp_path / "pattern.json"
    path.write_text(json.dumps(spec))
    return garmentcode.read(path)


def refused(pattern, panel, edge, *words):
    with pytest.raises(InputError) as info:
        validate.validate(pattern)
    msg = str(info.value)
    assert "\n" not in msg and pattern.source in msg and "fix:" in msg, msg
    assert f"panel '{panel}'" in msg, msg
    if edge is not None:
        assert f"edge {edge}" in msg, msg
    for w in words:
        assert w in msg, msg
    return msg


def sides(*pairs):
    return [{"panel": p, "edge": e} for p, e in pairs]


# ---------------------------------------------------------------------- one panel
def test_a_rectangle_passes(tmp_path):
    assert validate.validate(read(tmp_path, {"r": panel_spec(RECT)})) == []


def test_open_loop(tmp_path):
    shape = RECT + [[0, 20]]  # edge 2 ends at vertex 3, edge 3 starts at vertex 4, 10 cm away
    pattern = read(tmp_path, {"r": panel_spec(shape, loop=[[0, 1], [1, 2], [2, 3], [4, 0]])})
    refused(pattern, "r", 2, "open loop", "10.00 cm")


def test_a_loop_closed_by_a_duplicated_vertex_passes(tmp_path):
    shape = RECT + [[0, 30]]  # vertex 4 repeats vertex 3: the loop is closed in space
    pattern = read(tmp_path, {"r": panel_spec(shape, loop=[[0, 1], [1, 2], [2, 3], [4, 0]])})
    assert validate.validate(pattern) == []


def test_zero_length_edge(tmp_path):
    shape = [[0, 0], [40, 0], [40, 0], [40, 30], [0, 30]]
    refused(read(tmp_path, {"r": panel_spec(shape)}), "r", 1, "zero-length")


def test_self_crossing_bowtie(tmp_path):
    pattern = read(tmp_path, {"bow": panel_spec([[0, 0], [40, 0], [0, 30], [40, 30]])})
    msg = refused(pattern, "bow", 1, "self-crossing")
    assert "edge 3" in msg


def test_touching_itself_at_a_point(tmp_path):
    # vertex 3 lies on edge 0: the outline touches itself there without crossing
    shape = [[0, 0], [40, 0], [40, 30], [20, 0], [0, 30]]
    msg = refused(read(tmp_path, {"t": panel_spec(shape)}), "t", 0, "self-crossing")
    assert "edge 2" in msg or "edge 3" in msg


def test_folding_back(tmp_path):
    shape = [[0, 0], [40, 0], [20, 0], [20, 30]]  # edge 1 runs back along edge 0
    msg = refused(read(tmp_path, {"f": panel_spec(shape)}), "f", 0, "self-crossing")
    assert "edge 1" in msg


def test_curved_edge_crossing_the_opposite_edge(tmp_path):
    # the top edge (2, from (40, 30) to (0, 30)) with its control point at (20, -50): its deepest point is at
    # (a + 2c + b) / 4 = (20, -10), below edge 0, which it crosses
    pattern = read(tmp_path, {"c": panel_spec(RECT, curvature={2: {"type": "quadratic", "params": [[0.5, 2.0]]}})})
    refused(pattern, "c", 0, "self-crossing", "edge 2")
    # control point at (20, 10): the deepest point at y = 20, inside the rectangle
    pattern = read(tmp_path, {"c": panel_spec(RECT, curvature={2: {"type": "quadratic", "params": [[0.5, 0.5]]}})})
    assert validate.validate(pattern) == []


def test_a_cubic_looping_over_itself(tmp_path):
    # edge 0 from (0, 0) to (40, 0) with its controls crossed over, below the rectangle: the curve makes a loop
    loop = {"type": "cubic", "params": [[1.5, -0.75], [-0.5, -0.75]]}  # relative: (60, -30) and (-20, -30)
    refused(read(tmp_path, {"l": panel_spec(RECT, curvature={0: loop})}), "l", 0, "crosses or touches itself")


def test_crossing_found_in_a_long_outline(tmp_path):
    # a 600-vertex circle whose last two vertices are swapped: the crossing is past the first block of rows
    t = np.linspace(0, 2 * np.pi, 600, endpoint=False)
    circle = np.column_stack([30 * np.cos(t), 30 * np.sin(t)])
    circle[[-3, -2]] = circle[[-2, -3]]
    refused(read(tmp_path, {"o": panel_spec(circle.tolist())}), "o", 596, "self-crossing")
    circle[[-3, -2]] = circle[[-2, -3]]
    assert validate.validate(read(tmp_path, {"o": panel_spec(circle.tolist())})) == []


@pytest.mark.parametrize("units, words", [
    (10000, ["4.00 mm across"]),            # a 40 cm panel read in 1/100 mm: the 4 mm shirt
    (1000, ["largest panel is 4.0 cm"]),    # read as mm: a 4 cm garment
    (1, ["40.0 m across"]),                 # read as metres
])
def test_implausible_units(tmp_path, units, words):
    refused(read(tmp_path, {"r": panel_spec(RECT)}, units=units), "r", None, "units", *words)


def test_no_panels():
    with pytest.raises(InputError, match="x.json: the pattern has no panels"):
        validate.validate(model.Pattern(panels={}, stitches=[], source="x.json"))


def test_small_panel_warned(tmp_path):
    small = [[0, 0], [1.5, 0], [1.5, 1], [0, 1]]  # a 1.5 cm tab beside a 40 cm panel
    warnings = validate.validate(read(tmp_path, {"r": panel_spec(RECT), "tab": panel_spec(small)}))
    assert len(warnings) == 1 and "'tab'" in warnings[0] and "1.5 cm" in warnings[0]


# ---------------------------------------------------------------------- stitches
def two_panels(tmp_path, width_b, stitches=None):
    """Rectangle a (40 cm bottom edge 0) and rectangle b (``width_b`` cm bottom edge 0), stitched edge 0 to 0."""
    b = [[0, 0], [width_b, 0], [width_b, 30], [0, 30]]
    stitches = stitches if stitches is not None else [sides(("a", 0), ("b", 0))]
    return read(tmp_path, {"a": panel_spec(RECT), "b": panel_spec(b)}, stitches)


def test_matching_seam_is_silent(tmp_path):
    assert validate.validate(two_panels(tmp_path, 39.5)) == []  # 5 mm: below notice


def test_eased_seam_warned(tmp_path):
    warnings = validate.validate(two_panels(tmp_path, 37))
    assert len(warnings) == 1 and "3.00 cm" in warnings[0] and "'a'" in warnings[0] and "edge 0" in warnings[0]


def test_seam_too_different_in_length(tmp_path):
    refused(two_panels(tmp_path, 30), "a", 0, "10.00 cm", "more than a seam can ease")


def test_gathers_let_through_as_warnings(tmp_path):
    warnings = validate.validate(two_panels(tmp_path, 30), gathers=True)
    assert len(warnings) == 1 and "10.00 cm" in warnings[0] and "gathered beyond easing" in warnings[0]


def test_seam_lengths_two_to_one(tmp_path):
    # 4 cm onto 1.5 cm: only 2.5 cm, but the edges are not the pair the pattern meant
    b = [[0, 0], [1.5, 0], [1.5, 30], [0, 30]]
    a = [[0, 0], [4, 0], [4, 30], [0, 30]]
    pattern = read(tmp_path, {"a": panel_spec(a), "b": panel_spec(b)}, [sides(("a", 0), ("b", 0))])
    refused(pattern, "a", 0, "2.50 cm")


def test_edge_stitched_twice(tmp_path):
    stitches = [sides(("a", 0), ("b", 0)), sides(("b", 2), ("a", 0))]
    refused(two_panels(tmp_path, 40, stitches), "a", 0, "stitched twice", "stitches 0 and 1")


def test_edge_stitched_to_itself(tmp_path):
    refused(two_panels(tmp_path, 40, [sides(("b", 1), ("b", 1))]), "b", 1, "to itself")


def test_stitch_naming_a_missing_edge(tmp_path):
    # readers of other formats may hand over a bad reference: validate names it too
    pattern = two_panels(tmp_path, 40)
    pattern.stitches.append(model.Stitch(model.EdgeRef("a", 9), model.EdgeRef("b", 1)))
    refused(pattern, "a", 9, "stitch 1", "does not have")


def test_a_dart_stitching_two_edges_of_one_panel_passes(tmp_path):
    dart = [[0, 0], [40, 0], [40, 30], [22, 30], [20, 20], [18, 30], [0, 30]]
    pattern = read(tmp_path, {"d": panel_spec(dart)}, [sides(("d", 3), ("d", 4))])
    assert validate.validate(pattern) == []


# ---------------------------------------------------------------------- the shared patterns
@needs_shared
@pytest.mark.parametrize("name, n_warnings", [
    ("garmentcode_shirt_mean.json", 0), ("garmentcode_dress_pencil.json", 10),
    ("gpg_tee.json", 0), ("gpg_skirt_4_panels.json", 0),
])
def test_shared_patterns_validate(name, n_warnings):
    pattern = garmentcode.read(PATTERNS / name)
    warnings = validate.validate(pattern)
    # the dress's bodice is gathered 23 % onto the skirt at every waist stitch, its skirt side seams eased 1.2 cm
    assert len(warnings) == n_warnings, warnings
    assert all("eased or gathered" in w for w in warnings)
