"""GLB scene and animation writers: read back independently (struct + json) and through trimesh."""
from pathlib import Path

import numpy as np
import pytest

import glb_reader
from vfit_engine.errors import InputError
from vfit_engine.io import gltf_quantize
from vfit_engine.io.gltf import ScenePart, write_animation_glb, write_scene_glb
from vfit_engine.io.mesh import read_mesh
from vfit_engine.io.meshdata import mesh_from_faces

SKIRT = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"


def _to_srgb(lin):
    lin = np.asarray(lin, dtype=np.float64)
    return np.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055)


def _seam_mesh():
    """Two quads sharing the edge 1-4 with different UVs on each side, plus a triangle whose
    middle corner has no UV and a vertex (7) no face uses."""
    verts = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0), (2, 1, 0), (3, 0.5, 0), (9, 9, 9)]
    uvs = [(0, 0), (0.5, 0), (0.5, 1), (0, 1), (0.6, 0), (1, 0), (1, 1), (0.6, 1)]
    faces = [[0, 1, 4, 3], [1, 2, 5, 4], [2, 6, 5]]
    face_uvs = [[0, 1, 2, 3], [4, 5, 6, 7], [5, -1, 6]]
    return mesh_from_faces(verts, faces, uvs=uvs, face_uvs=face_uvs)


def _body_like():
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.15)
    return mesh_from_faces(sphere.vertices, sphere.faces)


def test_seam_mesh_independent_parse(tmp_path):
    mesh = _seam_mesh()
    colors = np.linspace(0, 1, 24).reshape(8, 3)
    path = write_scene_glb(tmp_path / "s.glb", [ScenePart("garment", mesh, colors=colors)])
    doc, blob = glb_reader.parse_glb(path)
    assert [n["name"] for n in doc["nodes"]] == ["garment"]
    p = glb_reader.primitive(doc, blob, "garment")
    tri = mesh.triangles()
    assert p["indices"].shape == tri.shape == (5, 3)
    # every corner: source position, source UV (V flipped to glTF's top-left origin), source colour
    np.testing.assert_allclose(p["POSITION"][p["indices"]], mesh.verts[tri], atol=1e-6)
    src_uv = np.where((mesh.triangle_uvs() >= 0)[..., None], mesh.uvs[mesh.triangle_uvs()], 0.0)
    uv = p["TEXCOORD_0"][p["indices"]]
    np.testing.assert_allclose(np.stack([uv[..., 0], 1 - uv[..., 1]], -1), src_uv, atol=1e-6)
    np.testing.assert_allclose(_to_srgb(p["COLOR_0"][p["indices"]]), colors[tri], atol=1e-5)
    # split only at the seam: vertices 1 and 4 twice, vertex 6 (no UV) and unused 7 once: 10
    assert p["POSITION"].shape == (10, 3)
    np.testing.assert_allclose(np.linalg.norm(p["NORMAL"], axis=1), 1, atol=1e-6)
    np.testing.assert_allclose(p["NORMAL"][p["indices"]][..., 2], 1, atol=1e-6)  # flat, CCW: +Z
    mat = doc["materials"][doc["meshes"][0]["primitives"][0]["material"]]
    assert mat["doubleSided"] and mat["pbrMetallicRoughness"]["baseColorFactor"] == [1, 1, 1, 1]


def test_seam_mesh_through_trimesh(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    mesh = _seam_mesh()
    colors = (np.arange(24).reshape(8, 3) * 10).astype(np.uint8)
    path = write_scene_glb(tmp_path / "s.glb", [("garment", mesh, mesh.verts + 0.25, colors)])
    scene = trimesh.load(path, force="scene", process=False)
    assert set(scene.graph.nodes_geometry) == {"garment"}
    g = scene.geometry["garment"]
    tri = mesh.triangles()
    assert len(g.faces) == len(tri)
    np.testing.assert_allclose(g.vertices[g.faces], mesh.verts[tri] + 0.25, atol=1e-6)
    tuv = mesh.triangle_uvs()
    seam = tuv >= 0  # trimesh flips V back to OBJ's convention
    np.testing.assert_allclose(g.visual.uv[g.faces][seam], mesh.uvs[tuv[seam]], atol=1e-6)
    got = _to_srgb(g.visual.vertex_attributes["color"])[g.faces] * 255
    assert np.abs(got - colors[tri]).max() <= 1.0
    np.testing.assert_allclose(np.linalg.norm(g.vertex_normals, axis=1), 1, atol=1e-6)


def test_without_uvs_keeps_vertex_order(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    body = _body_like()
    path = write_scene_glb(tmp_path / "b.glb", [ScenePart("body", body)])
    doc, blob = glb_reader.parse_glb(path)
    p = glb_reader.primitive(doc, blob, "body")
    assert "TEXCOORD_0" not in p and "COLOR_0" not in p
    np.testing.assert_array_equal(p["POSITION"], body.verts.astype(np.float32))
    np.testing.assert_array_equal(p["indices"], body.triangles())
    # icosphere winding is outward: normals point away from the centre
    assert np.all(np.sum(p["NORMAL"] * p["POSITION"], axis=1) > 0)
    assert not doc["materials"][0]["doubleSided"]
    g = trimesh.load(path, force="scene", process=False).geometry["body"]
    np.testing.assert_allclose(g.vertices, body.verts, atol=1e-6)


def _assert_valid_layout(doc, blob):
    """Every view 4-aligned and inside the buffer, every accessor inside its view, every vertex-attribute element
    on a 4-byte boundary (byteStride a multiple of 4), min/max equal to the stored component values."""
    assert doc["buffers"] == [{"byteLength": len(blob)}]
    attributes = set()
    for m in doc["meshes"]:
        for prim in m["primitives"]:
            attributes.update(prim["attributes"].values())
            for target in prim.get("targets", []):
                attributes.update(target.values())
    for i, acc in enumerate(doc["accessors"]):
        view = doc["bufferViews"][acc["bufferView"]]
        size = np.dtype(glb_reader.DTYPES[acc["componentType"]]).itemsize
        element = size * glb_reader.WIDTH[acc["type"]]
        stride = view.get("byteStride", element)
        assert view["byteOffset"] % 4 == 0 and (view["byteOffset"] + acc["byteOffset"]) % size == 0
        assert acc["byteOffset"] + stride * (acc["count"] - 1) + element <= view["byteLength"]
        assert view["byteOffset"] + view["byteLength"] <= len(blob)
        if i in attributes:
            assert stride % 4 == 0 and acc["byteOffset"] % 4 == 0 and stride >= element
        else:
            assert "byteStride" not in view
        if "min" in acc:  # the spec: the stored values, whatever `normalized` says (integers for integer data)
            raw = glb_reader.raw_accessor(doc, blob, i).reshape(acc["count"], -1)
            assert acc["min"] == raw.min(0).tolist() and acc["max"] == raw.max(0).tolist()
            assert all(type(x) is (float if acc["componentType"] == 5126 else int) for x in acc["min"] + acc["max"])


def test_container_is_valid(tmp_path):
    path = write_scene_glb(tmp_path / "v.glb", [("body", _body_like()), ("garment", _seam_mesh())])
    doc, blob = glb_reader.parse_glb(path)  # header magic, version, lengths, chunk types and padding
    assert doc["asset"]["version"] == "2.0"
    _assert_valid_layout(doc, blob)
    for m in doc["meshes"]:
        idx = glb_reader.raw_accessor(doc, blob, m["primitives"][0]["indices"])
        assert idx.max() < doc["accessors"][m["primitives"][0]["attributes"]["POSITION"]]["count"]
    # the same input gives the same bytes
    again = write_scene_glb(tmp_path / "w.glb", [("body", _body_like()), ("garment", _seam_mesh())])
    assert again.read_bytes() == path.read_bytes()


@pytest.mark.parametrize("case, message", [
    ("nan", "NaN"), ("colours", "colours have shape"), ("index", "out of range"), ("empty", "empty"),
])
def test_bad_input_raises_and_leaves_no_file(tmp_path, case, message):
    mesh = _seam_mesh()
    part = ScenePart("garment", mesh)
    if case == "nan":
        verts = mesh.verts.copy()
        verts[3, 1] = np.nan
        part = part._replace(verts=verts)
    elif case == "colours":
        part = part._replace(colors=np.zeros((7, 3)))
    elif case == "index":
        part = part._replace(mesh=mesh_from_faces(mesh.verts, [[0, 1, 8]]))
    else:
        part = part._replace(mesh=mesh_from_faces(mesh.verts, [[0, 1]]))
    target = tmp_path / "x.glb"
    with pytest.raises(InputError, match=message) as err:
        write_scene_glb(target, [("body", _body_like()), part])
    assert "'garment'" in str(err.value) and "\n" not in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_demo_skirt_with_body(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    skirt = read_mesh(SKIRT)
    assert skirt.uvs is not None and len(skirt.uvs) > skirt.n_verts  # it has a UV seam
    rng = np.random.default_rng(0)
    fit = rng.random((skirt.n_verts, 3))
    path = write_scene_glb(tmp_path / "scene.glb",
                           [("body", _body_like()), ScenePart("garment", skirt, colors=fit)])
    doc, blob = glb_reader.parse_glb(path)
    assert [n["name"] for n in doc["nodes"]] == ["body", "garment"]
    p = glb_reader.primitive(doc, blob, "garment")
    tri = skirt.triangles()
    assert len(p["indices"]) == len(tri) == 2 * skirt.n_faces
    pairs = np.unique(np.stack([tri.ravel(), skirt.triangle_uvs().ravel()], 1), axis=0)
    assert len(p["POSITION"]) == len(pairs)
    np.testing.assert_allclose(p["POSITION"][p["indices"]], skirt.verts[tri], atol=1e-6)
    uv = p["TEXCOORD_0"][p["indices"]]
    np.testing.assert_allclose(uv[..., 0], skirt.uvs[skirt.triangle_uvs()][..., 0], atol=1e-6)
    np.testing.assert_allclose(_to_srgb(p["COLOR_0"][p["indices"]]), fit[tri], atol=1e-5)
    scene = trimesh.load(path, force="scene", process=False)
    assert set(scene.geometry) == {"body", "garment"}
    assert len(scene.geometry["garment"].faces) == len(tri)


# -- the animated GLB: quantized morph targets ----------------------------------------------------------------

_POS_TOL = 0.05e-3  # m: the bar the animation must meet; the int16 rounding alone is 0.5/32767 m = 0.015 mm
_NORMAL_TOL_DEG = 0.45  # int8 normal deltas: 0.5/127 per component moves a unit normal by < 0.4 degrees


def _rot_y(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rigid_frames(mesh, moves):
    """(f, n, 3) positions, m: frame 0 as given, then each (y rotation in degrees about the centre, shift)."""
    centre = mesh.verts.mean(axis=0)
    out = [mesh.verts + 0.0]
    for deg, shift in moves:
        out.append((mesh.verts - centre) @ _rot_y(deg).T + centre + np.asarray(shift, float))
    return np.array(out)


def _write_walkers(path, moves):
    """An animated skirt (UV seams) and an icosphere, both turned and shifted by ``moves``; returns the frames."""
    skirt, ball = read_mesh(SKIRT), _body_like()
    frames = [_rigid_frames(skirt, moves), _rigid_frames(ball, moves)]
    write_animation_glb(path, [("garment", skirt), ("body", ball)], frames, fps=30)
    return {"garment": (skirt, frames[0]), "body": (ball, frames[1])}


def _target_types(doc, name, attribute):
    prim = next(m for m in doc["meshes"] if m["name"] == name)["primitives"][0]
    return [(doc["accessors"][t[attribute]]["componentType"], doc["accessors"][t[attribute]].get("normalized", False))
            for t in prim["targets"]]


def _assert_frames_match(doc, blob, given, moves):
    """Every frame's corners within _POS_TOL of the positions given; normals the base's turned by the frame's
    rotation (a rigid turn turns the normals exactly so) within _NORMAL_TOL_DEG."""
    errors = {}
    for name, (mesh, frames) in given.items():
        pos, nrm = glb_reader.morph_frames(doc, blob, name)
        tri = glb_reader.primitive(doc, blob, name)["indices"]
        assert pos.shape[0] == len(frames) == len(moves) + 1
        err = np.abs(pos[:, tri] - frames[:, mesh.triangles()]).max()
        assert err <= _POS_TOL, (name, err)
        errors[name] = err
        for k, (deg, _) in enumerate([(0.0, None)] + list(moves)):
            want = nrm[0] @ _rot_y(deg).T
            cos = np.clip(np.sum(nrm[k] * want, axis=1), -1.0, 1.0)
            assert np.degrees(np.arccos(cos)).max() <= _NORMAL_TOL_DEG, (name, k)
    return errors


def test_animation_targets_quantized_and_exact(tmp_path):
    moves = [(5, (0.01, 0.0, 0.0)), (20, (0.0, 0.02, 0.1)), (45, (-0.2, 0.0, 0.0)), (55, (0.3, 0.1, -0.3))]
    given = _write_walkers(tmp_path / "a.glb", moves)
    doc, blob = glb_reader.parse_glb(tmp_path / "a.glb")
    assert doc["extensionsUsed"] == doc["extensionsRequired"] == ["KHR_mesh_quantization"]
    for name in given:
        assert _target_types(doc, name, "POSITION") == [(5122, True)] * len(moves)  # SHORT normalized
        assert _target_types(doc, name, "NORMAL") == [(5120, True)] * len(moves)  # BYTE normalized
    _assert_valid_layout(doc, blob)
    errors = _assert_frames_match(doc, blob, given, moves)
    assert max(errors.values()) <= 0.5 / 32767 + 1e-6  # the rounding of int16, and float32 sums
    # the base mesh is float32 as in a still scene
    prim = doc["meshes"][0]["primitives"][0]
    assert {doc["accessors"][i]["componentType"] for i in prim["attributes"].values()} == {5126}


def test_far_travel_and_turned_normals_fall_back_to_float(tmp_path):
    """A target with a delta beyond 1 m keeps float32 positions; one whose normals turn by more than 60
    degrees (components change by more than 1) keeps float32 normals; the others stay quantized; all exact."""
    moves = [(10, (0.05, 0.0, 0.0)), (0, (1.5, 0.0, 0.0)), (150, (0.0, 0.0, 0.0)), (30, (-2.0, 0.0, 3.0))]
    given = _write_walkers(tmp_path / "t.glb", moves)
    doc, blob = glb_reader.parse_glb(tmp_path / "t.glb")
    for name in given:
        assert _target_types(doc, name, "POSITION") == [(5122, True), (5126, False), (5122, True), (5126, False)]
        assert _target_types(doc, name, "NORMAL") == [(5120, True), (5120, True), (5126, False), (5120, True)]
    _assert_valid_layout(doc, blob)
    errors = _assert_frames_match(doc, blob, given, moves)
    pos, _ = glb_reader.morph_frames(doc, blob, "body")
    frames = given["body"][1]
    np.testing.assert_allclose(pos[1], frames[1], atol=_POS_TOL)
    np.testing.assert_allclose(pos[[2, 4]], frames[[2, 4]], atol=1e-6)  # float32 travel targets: exact
    assert max(errors.values()) <= _POS_TOL


def test_all_float_animation_needs_no_extension(tmp_path):
    """Every target moved beyond 1 m and turned past 60 degrees: nothing quantized, so no extension is listed
    (a plain glTF 2.0 file)."""
    given = _write_walkers(tmp_path / "f.glb", [(150, (2.0, 0, 0)), (120, (0, 0, -1.5))])
    doc, blob = glb_reader.parse_glb(tmp_path / "f.glb")
    assert "extensionsUsed" not in doc and "extensionsRequired" not in doc
    assert "normalized" not in str(doc["accessors"])
    _assert_frames_match(doc, blob, given, [(150, None), (120, None)])


def test_repeated_frames_share_their_accessors(tmp_path):
    """A cycle played twice: the second lap's targets are the first lap's accessors, and the parts' weight
    tracks one accessor; the frames still read back."""
    lap = [(5, (0.01, 0, 0)), (15, (0.02, 0, 0)), (25, (0.0, 0.01, 0))]
    moves = lap + [(0, (0, 0, 0))] + lap
    given = _write_walkers(tmp_path / "r.glb", moves)
    doc, blob = glb_reader.parse_glb(tmp_path / "r.glb")
    prim = doc["meshes"][1]["primitives"][0]
    first, second = prim["targets"][:3], prim["targets"][4:]
    assert first == second
    assert len({s["output"] for s in doc["animations"][0]["samplers"]}) == 1
    _assert_valid_layout(doc, blob)
    _assert_frames_match(doc, blob, given, moves)


def _target_bytes(path):
    doc, _ = glb_reader.parse_glb(path)
    views = {doc["accessors"][i]["bufferView"] for m in doc["meshes"] for t in m["primitives"][0]["targets"]
             for i in t.values()}
    return sum(doc["bufferViews"][v]["byteLength"] for v in views)


def test_quantized_targets_are_half_the_float_ones(tmp_path, monkeypatch):
    """20 frames of the skirt and the ball: the targets take 12 bytes per vertex instead of 24 (POSITION int16
    padded to 8, NORMAL int8 padded to 4); with the float32 base mesh the file is 1.8 times smaller."""
    moves = [(2 * k, (0.01 * k, 0.0, 0.0)) for k in range(1, 20)]
    _write_walkers(tmp_path / "q.glb", moves)
    monkeypatch.setattr(gltf_quantize, "_RANGE", -1.0)  # every delta "exceeds": the all-float32 version
    _write_walkers(tmp_path / "f.glb", moves)
    assert _target_bytes(tmp_path / "f.glb") == 2 * _target_bytes(tmp_path / "q.glb")
    quantized, floats = (tmp_path / "q.glb").stat().st_size, (tmp_path / "f.glb").stat().st_size
    assert floats / quantized >= 1.75, (floats, quantized)
    doc, _ = glb_reader.parse_glb(tmp_path / "f.glb")
    assert "extensionsRequired" not in doc


def test_animation_is_deterministic(tmp_path):
    moves = [(10, (0.05, 0, 0)), (150, (1.5, 0, 0))]
    _write_walkers(tmp_path / "a.glb", moves)
    _write_walkers(tmp_path / "b.glb", moves)
    assert (tmp_path / "a.glb").read_bytes() == (tmp_path / "b.glb").read_bytes()


def test_animated_glb_through_trimesh(tmp_path):
    """trimesh reads the file (it ignores the morph targets): the base meshes as frame 0."""
    trimesh = pytest.importorskip("trimesh")
    given = _write_walkers(tmp_path / "a.glb", [(20, (0.1, 0, 0)), (40, (0.2, 0, 0))])
    scene = trimesh.load(tmp_path / "a.glb", force="scene", process=False)
    assert set(scene.geometry) == {"body", "garment"}
    frames = given["body"][1]
    np.testing.assert_allclose(scene.geometry["body"].vertices, frames[0], atol=1e-6)
