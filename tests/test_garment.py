"""Garment loading, .mhclo parsing/evaluation, automatic pins and body attachment."""
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.body.levels import body_levels
from vfit_engine.errors import InputError
from vfit_engine.garment.garment import choose_units, load_garment, piece_labels
from vfit_engine.garment.mhclo import evaluate_mhclo, gender_from_tags, parse_mhclo, scale_matrix
from vfit_engine.garment.pins import attach_to_body, attached_positions, auto_pins
from vfit_engine.geometry import boundary_loops, closest_point_barycentric, winding_number
from vfit_engine.io import mesh_from_faces, write_mesh

GARMENTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments"
NAMES = ["female_casualsuit01", "female_sportsuit01", "male_casualsuit02", "male_casualsuit06"]
needs_shared = pytest.mark.skipif(not GARMENTS.is_dir(), reason="../shared not present")


def _body_model():
    from vfit_engine.body.model import BodyModel

    return BodyModel.load()  # a broken loader fails the test, not a skip


def _tube(r, y0, y1, n_around=24, n_up=6, cx=0.0, cz=0.0):
    """Open cylinder (quads) around the vertical axis through (cx, cz)."""
    a = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    ys = np.linspace(y0, y1, n_up)
    verts = np.array([[cx + r * np.cos(t), y, cz + r * np.sin(t)] for y in ys for t in a])
    faces = []
    for j in range(n_up - 1):
        for i in range(n_around):
            k, k1 = j * n_around + i, j * n_around + (i + 1) % n_around
            faces.append([k, k1, k1 + n_around, k + n_around])
    return verts, np.array(faces)


def _write(tmp_path, name, verts, faces):
    p = tmp_path / name
    write_mesh(p, mesh_from_faces(verts, faces))
    return p


# ---------------------------------------------------------------- units and loading

@pytest.mark.parametrize(
    "height, body, unit",
    [(13.0, None, "dm"), (130.0, None, "cm"), (1300.0, None, "mm"), (1.3, None, "m"),
     (0.6, None, "m"), (60.0, None, "cm"), (600.0, 1.8, "mm"), (14.0, 1.5, "dm")],
)
def test_choose_units_table(height, body, unit):
    got, plausible = choose_units(height, body)
    assert got == unit and plausible


def test_choose_units_implausible():
    unit, plausible = choose_units(1e6)
    assert unit == "mm" and not plausible


@needs_shared
@pytest.mark.parametrize("name", NAMES)
def test_load_shared_garments(name):
    obj = GARMENTS / name / f"{name}.obj"
    nv = sum(ln.startswith("v ") for ln in obj.read_text().splitlines())
    g = load_garment(obj)
    assert g.units == "dm"
    assert g.mesh.n_verts == nv and g.pieces.shape == (nv,)
    assert g.n_pieces == 2  # top and trousers
    assert g.warnings == []
    assert g.mhclo_path is not None and g.mhclo_path.name == f"{name}.mhclo"
    height = np.ptp(g.mesh.verts[:, 1])
    assert 1.0 < height < 1.6  # metres
    g_cm = load_garment(obj, units="cm")
    np.testing.assert_allclose(g_cm.mesh.verts * 10, g.mesh.verts)


def test_units_auto_uses_body_height(tmp_path):
    v, f = _tube(0.15, 0.0, 0.6)
    p = _write(tmp_path, "skirt_m.obj", v, f)
    assert load_garment(p).units == "m"
    p_cm = _write(tmp_path, "skirt_cm.obj", v * 100, f)
    g = load_garment(p_cm, body_height_m=1.6)
    assert g.units == "cm"
    np.testing.assert_allclose(g.mesh.verts, v, atol=1e-9)
    with pytest.raises(InputError, match="unknown garment unit"):
        load_garment(p, units="inch")


def test_explicit_units_that_make_a_garment_absurd_warn(tmp_path):
    """--units m on a decimetre garment (a 6 m suit) or cm (6 mm): drawn as asked, with a warning naming the
    unit its height says; a plausible explicit unit warns nothing."""
    v, f = _tube(1.5, 0.0, 6.0)  # 6 units tall: dm
    p = _write(tmp_path, "dm.obj", v, f)
    for unit in ("m", "mm"):
        g = load_garment(p, units=unit)
        assert g.units == unit and any("implausible" in w and "says dm" in w for w in g.warnings), g.warnings
    assert not [w for w in load_garment(p, units="dm").warnings if "implausible" in w]


def test_triangle_soup_warns(tmp_path):
    """A tube exported as unconnected triangles (no shared vertices): loaded, with a warning that says what it
    is; the same tube welded warns nothing."""
    v, f = _tube(0.15, 0.0, 0.6)
    tris = np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])
    soup = _write(tmp_path, "soup.obj", v[tris].reshape(-1, 3), np.arange(tris.size).reshape(-1, 3))
    g = load_garment(soup, units="m")
    assert int(g.pieces.max()) + 1 == len(tris) and any("triangle soup" in w for w in g.warnings), g.warnings
    assert not [w for w in load_garment(_write(tmp_path, "tube.obj", v, f), units="m").warnings if "soup" in w]


def test_bad_garments_raise(tmp_path):
    v, f = _tube(0.15, 0.0, 0.6)
    v_nan = v.copy()
    v_nan[5, 1] = np.nan
    p = tmp_path / "nan.obj"
    p.write_text("".join(f"v {a} {b} {c}\n" for a, b, c in v_nan) + "f 1 2 3\n")
    with pytest.raises(InputError, match="vertex 6 has a NaN"):
        load_garment(p)
    p = tmp_path / "inf.obj"
    p.write_text("v 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError, match="NaN or infinite"):
        load_garment(p)
    p = tmp_path / "empty.obj"
    p.write_text("")
    with pytest.raises(InputError, match="no vertices"):
        load_garment(p)
    p = tmp_path / "nofaces.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(InputError, match="no faces"):
        load_garment(p)
    with pytest.raises(InputError, match="not found"):
        load_garment(tmp_path / "missing.obj")
    p = _write(tmp_path, "tube.obj", v, f)
    with pytest.raises(InputError, match="more than the limit"):
        load_garment(p, max_verts=10)


def test_degenerate_faces_dropped_with_warning(tmp_path):
    v, f = _tube(0.15, 0.0, 0.6)
    v = np.vstack([v, [[0.0, 0.3, 0.0], [0.01, 0.3, 0.0], [0.02, 0.3, 0.0]]])  # collinear
    n = len(v)
    faces = [list(x) for x in f] + [[0, 1, 1, 25], [n - 3, n - 2, n - 1]]
    p = tmp_path / "degen.obj"
    write_mesh(p, mesh_from_faces(v, faces))
    g = load_garment(p, units="m")
    assert g.mesh.n_faces == len(f) and g.mesh.n_verts == n
    assert any("dropped 2 degenerate faces" in w for w in g.warnings)
    assert any("3 vertices are not used" in w for w in g.warnings)


def test_piece_labels_two_squares():
    edges = np.array([[0, 1], [1, 2], [2, 0], [3, 4], [4, 5]])
    np.testing.assert_array_equal(piece_labels(7, edges), [0, 0, 0, 1, 1, 1, 2])
    edges = np.array([[5, 6], [0, 1]])
    np.testing.assert_array_equal(piece_labels(7, edges), [0, 0, 1, 2, 3, 4, 4])


# ---------------------------------------------------------------- mhclo

@needs_shared
@pytest.mark.parametrize("name", NAMES)
def test_parse_shared_mhclo(name):
    b = parse_mhclo(GARMENTS / name / f"{name}.mhclo")
    obj = GARMENTS / name / f"{name}.obj"
    nv = sum(ln.startswith("v ") for ln in obj.read_text().splitlines())
    assert b.n_verts == nv
    assert b.ref_verts.shape == (nv, 3) and b.weights.shape == (nv, 3) and b.offsets.shape == (nv, 3)
    assert b.ref_verts.min() >= 0 and b.ref_verts.max() < 19158
    np.testing.assert_allclose(b.weights.sum(axis=1), 1.0, atol=1e-4)
    assert set(b.scales) == {"x", "y", "z"} and b.scales["x"][:2] == (5399, 11998)
    assert b.name == name and b.obj_path == obj
    assert b.gender == name.split("_")[0]
    assert b.z_depth == 50 and len(b.delete_verts) > 1000


def test_mhclo_synthetic_parse_and_evaluate(tmp_path):
    p = tmp_path / "t.mhclo"
    p.write_text(
        "# comment\nname test\ntag Female\ntag Casual\nobj_file t.obj\n"
        "x_scale 0 1 2.0\nz_scale 0 2 4.0\ny_scale 0 3 1.0\n"
        "verts 0\n3\n0 1 2 0.5 0.25 0.25 1.0 2.0 -3.0\n1 2 3 0.2 0.3 0.5\n"
        "delete_verts\n1 4 - 7 10\n"
    )
    b = parse_mhclo(p)
    np.testing.assert_array_equal(b.ref_verts, [[3, 3, 3], [0, 1, 2], [1, 2, 3]])
    np.testing.assert_array_equal(b.delete_verts, [1, 4, 5, 6, 7, 10])
    assert b.gender == "female"
    # a body whose reference distances equal the file's (in dm -> m): unit scale
    body = np.array([[0, 0, 0], [0.2, 0, 0], [0, 0, 0.4], [0, 0.1, 0]], dtype=np.float64)
    np.testing.assert_allclose(scale_matrix(b, body), [1, 1, 1])
    x = evaluate_mhclo(b, body)
    np.testing.assert_allclose(x[0], body[3])
    np.testing.assert_allclose(x[1], 0.5 * body[0] + 0.25 * body[1] + 0.25 * body[2] + [0.1, 0.2, -0.3])
    np.testing.assert_allclose(x[2], 0.2 * body[1] + 0.3 * body[2] + 0.5 * body[3])
    # doubling the body doubles positions and offsets alike (scale 2 on every axis)
    np.testing.assert_allclose(scale_matrix(b, 2 * body), [2, 2, 2])
    np.testing.assert_allclose(evaluate_mhclo(b, 2 * body), 2 * x)
    # stretching only X scales only the X offsets
    stretched = body * [3, 1, 1]
    expected = 0.5 * stretched[0] + 0.25 * stretched[1] + 0.25 * stretched[2] + [0.3, 0.2, -0.3]
    np.testing.assert_allclose(evaluate_mhclo(b, stretched)[1], expected)
    with pytest.raises(InputError, match="up to index 3"):
        evaluate_mhclo(b, body[:3])


def test_mhclo_with_a_byte_order_mark(tmp_path):
    """A byte-order mark before the first line is not part of its key (the binding would be lost)."""
    p = tmp_path / "bom.mhclo"
    p.write_bytes(b"\xef\xbb\xbfverts 0\n1 2 3 0.5 0.25 0.25\n")
    np.testing.assert_array_equal(parse_mhclo(p).ref_verts, [[1, 2, 3]])


def test_mhclo_garbled(tmp_path):
    p = tmp_path / "bad.mhclo"
    p.write_text("name x\nverts 0\n1 2 3 0.5 zero 0.5\n")
    with pytest.raises(InputError, match="bad.mhclo:3"):
        parse_mhclo(p)
    p.write_text("name x\n")
    with pytest.raises(InputError, match="no vertex binding"):
        parse_mhclo(p)


@pytest.mark.parametrize(
    "tags, gender",
    [(["MakeHuman™", "Female", "Casual"], "female"), (["male"], "male"),
     (["Female", "Male"], None), ([], None)],
)
def test_gender_from_tags(tags, gender):
    assert gender_from_tags(tags) == gender


@needs_shared
def test_mhclo_on_default_body_reproduces_obj():
    bm = _body_model()
    for name in ("female_casualsuit01", "male_casualsuit02"):
        b = parse_mhclo(GARMENTS / name / f"{name}.mhclo")
        g = load_garment(GARMENTS / name / f"{name}.obj")
        right = np.linalg.norm(evaluate_mhclo(b, bm.default_verts(b.gender)) - g.mesh.verts, axis=1)
        other = "male" if b.gender == "female" else "female"
        wrong = np.linalg.norm(evaluate_mhclo(b, bm.default_verts(other)) - g.mesh.verts, axis=1)
        # the assets were fitted to MakeHuman's default body; ours differs by ~1 % in size
        assert right.mean() < 0.02 and right.max() < 0.04
        assert wrong.mean() > 3 * right.mean()


# ---------------------------------------------------------------- pins

def test_winding_number():
    a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], 1)
    assert winding_number(ring, [0, 0]) == pytest.approx(1.0)
    assert winding_number(ring[::-1], [0.5, 0.1]) == pytest.approx(-1.0)
    assert winding_number(ring, [3, 0]) == pytest.approx(0.0)


def test_boundary_loops_of_tube():
    v, f = _tube(0.1, 0.0, 1.0, n_around=12, n_up=4)
    m = mesh_from_faces(v, f)
    loops = boundary_loops(m)
    assert sorted(len(lp) for lp in loops) == [12, 12]
    assert sorted(float(m.verts[lp, 1].mean()) for lp in loops) == pytest.approx([0.0, 1.0])


def _synthetic_body():
    """A capsule-like 'torso' (closed tube) standing on y = 0..1.7, no arms."""
    import trimesh

    body = trimesh.creation.capsule(height=1.4, radius=0.15, count=[24, 24])
    body.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    body.apply_translation([0, 0.85, 0])
    return np.asarray(body.vertices), np.asarray(body.faces, dtype=np.int64)


def test_auto_pins_synthetic_trousers_pick_waist_loop():
    bv, bt = _synthetic_body()
    # 'trousers': waist tube around the torso plus two leg tubes off the axis (separate pieces)
    w, wf = _tube(0.2, 0.8, 1.0)
    l1, lf1 = _tube(0.05, 0.1, 0.8, cx=-0.08)
    l2, lf2 = _tube(0.05, 0.1, 0.8, cx=0.08)
    verts = np.vstack([w, l1, l2])
    faces = np.vstack([wf, lf1 + len(w), lf2 + len(w) + len(l1)])
    m = mesh_from_faces(verts, faces)
    pins, info = auto_pins(m, bv, bt, kind="bottom")
    by_piece = {p["piece"]: p for p in info["pieces"]}
    assert by_piece[0]["method"] == "waist_loop" and by_piece[0]["n_pins"] == 24
    assert by_piece[0]["mean_y"] == pytest.approx(1.0)
    # leg tubes do not encircle the body axis: they fall back to their top band, with a warning
    assert by_piece[1]["method"] == "top_band" and by_piece[2]["method"] == "top_band"
    assert len(info["warnings"]) == 2
    assert np.all(np.isin(np.flatnonzero(np.isclose(verts[:, 1], 1.0)), pins))


def _closest_ref(p, a, b, c):
    """Slow reference: the plane projection if inside, else the best point on the three edges."""
    n = np.cross(b - a, c - a)
    q = p - np.dot(p - a, n) / np.dot(n, n) * n
    area = np.dot(n, n)
    u = np.dot(np.cross(c - b, q - b), n) / area
    v = np.dot(np.cross(a - c, q - c), n) / area
    w = 1 - u - v
    if min(u, v, w) >= 0:
        return q
    best = None
    for s, e in ((a, b), (b, c), (c, a)):
        t = np.clip(np.dot(p - s, e - s) / np.dot(e - s, e - s), 0, 1)
        x = s + t * (e - s)
        if best is None or np.linalg.norm(p - x) < np.linalg.norm(p - best):
            best = x
    return best


def test_closest_point_barycentric_against_reference():
    rng = np.random.default_rng(7)
    k = 400
    a, b, c = rng.normal(size=(3, k, 3))
    p = rng.normal(scale=2.0, size=(k, 3))
    bary = closest_point_barycentric(p, a, b, c)
    assert np.all(bary >= -1e-12) and np.allclose(bary.sum(1), 1)
    got = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
    ref = np.array([_closest_ref(p[i], a[i], b[i], c[i]) for i in range(k)])
    np.testing.assert_allclose(got, ref, atol=1e-9)


def test_attach_to_body_matches_brute_force_and_follows_the_body():
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=3, radius=0.2)
    bv, bt = np.asarray(s.vertices), np.asarray(s.faces, dtype=np.int64)
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(60, 3))
    pts *= (0.2 + rng.uniform(-0.05, 0.05, size=(60, 1))) / np.linalg.norm(pts, axis=1, keepdims=True)
    tri, bary = attach_to_body(pts, bv, bt)
    assert np.all(bary >= -1e-12) and np.allclose(bary.sum(1), 1)
    q = attached_positions(tri, bary, bv, bt)
    # brute force over every triangle
    for i in range(len(pts)):
        pp = np.repeat(pts[i:i + 1], len(bt), 0)
        bb = closest_point_barycentric(pp, bv[bt[:, 0]], bv[bt[:, 1]], bv[bt[:, 2]])
        d = np.linalg.norm(np.einsum("ij,ijk->ik", bb, bv[bt]) - pts[i], axis=1).min()
        assert np.linalg.norm(q[i] - pts[i]) == pytest.approx(d, abs=1e-12)
    moved = bv * 1.1 + [0.0, 0.5, 0.0]
    np.testing.assert_allclose(attached_positions(tri, bary, moved, bt), q * 1.1 + [0.0, 0.5, 0.0])


@needs_shared
def test_auto_pins_on_shared_garments_and_default_body():
    bm = _body_model()
    tris = bm.body_tris
    for name in NAMES:
        gender = name.split("_")[0]
        bv = bm.default_verts(gender)
        lv = body_levels(bv, tris)
        assert lv["crotch_y"] < lv["waist_y"] < lv["armpit_y"] < lv["neck_y"]
        g = load_garment(GARMENTS / name / f"{name}.obj")
        pins, info = auto_pins(g.mesh, bv, tris, pieces=g.pieces)
        kinds = {p["kind"]: p for p in info["pieces"]}
        assert set(kinds) == {"top", "bottom"}, name
        bottom, top = kinds["bottom"], kinds["top"]
        assert bottom["method"] == "waist_loop" and bottom["n_pins"] >= 16
        assert lv["crotch_y"] < bottom["mean_y"] < lv["waist_y"], name
        assert top["method"] == "shoulders" and top["n_pins"] >= 30
        assert lv["armpit_y"] <= top["min_y"] and top["max_y"] <= lv["neck_y"] + 0.03
        assert info["warnings"] == []
        # every pin is near the body it will be attached to
        tri, bary = attach_to_body(g.mesh.verts[pins], bv, tris)
        d = np.linalg.norm(attached_positions(tri, bary, bv, tris) - g.mesh.verts[pins], axis=1)
        assert d.max() < 0.06


def test_demo_skirt_is_reproducible():
    """data/garments/skirt.obj is what vfit_engine.garment.demo_skirt builds on the default body."""
    from vfit_engine.body.model import BodyModel, data_dir
    from vfit_engine.garment.demo_skirt import flared_skirt
    from vfit_engine.io.mesh import read_mesh

    model = BodyModel.load()
    built = flared_skirt(model.default_verts("female"), model.body_tris)
    shipped = read_mesh(data_dir() / "garments" / "skirt.obj")
    assert shipped.n_verts == built.n_verts and np.array_equal(shipped.face_verts, built.face_verts)
    assert np.abs(shipped.verts - built.verts).max() < 1e-8
    assert np.abs(shipped.uvs - built.uvs).max() < 1e-8 and np.array_equal(shipped.face_uvs, built.face_uvs)
