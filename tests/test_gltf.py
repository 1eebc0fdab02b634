"""GLB scene writer: read back independently (struct + json) and through trimesh."""
import json
import struct
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.errors import InputError
from vfit_engine.io.gltf import ScenePart, write_scene_glb
from vfit_engine.io.mesh import mesh_from_faces, read_mesh

SKIRT = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"
_DTYPES = {5126: np.float32, 5125: np.uint32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _parse_glb(path):
    """(json document, BIN chunk bytes) of a GLB file, by hand."""
    data = Path(path).read_bytes()
    magic, version, total = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, total) == (b"glTF", 2, len(data))
    js_len, js_type = struct.unpack_from("<I4s", data, 12)
    assert js_type == b"JSON" and js_len % 4 == 0
    doc = json.loads(data[20:20 + js_len])
    bin_len, bin_type = struct.unpack_from("<I4s", data, 20 + js_len)
    assert bin_type == b"BIN\0" and bin_len % 4 == 0
    assert 28 + js_len + bin_len == len(data)
    return doc, data[28 + js_len:28 + js_len + bin_len]


def _accessor(doc, blob, index):
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    start = view["byteOffset"] + acc.get("byteOffset", 0)
    a = np.frombuffer(blob, _DTYPES[acc["componentType"]], acc["count"] * _WIDTH[acc["type"]], start)
    return a.reshape(acc["count"], -1) if acc["type"] != "SCALAR" else a


def _primitive(doc, blob, name):
    """{attribute: array, "indices": (T, 3)} of the mesh called ``name``."""
    mesh = next(m for m in doc["meshes"] if m["name"] == name)
    prim = mesh["primitives"][0]
    out = {k: _accessor(doc, blob, i) for k, i in prim["attributes"].items()}
    out["indices"] = _accessor(doc, blob, prim["indices"]).reshape(-1, 3)
    return out


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
    doc, blob = _parse_glb(path)
    assert [n["name"] for n in doc["nodes"]] == ["garment"]
    p = _primitive(doc, blob, "garment")
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
    doc, blob = _parse_glb(path)
    p = _primitive(doc, blob, "body")
    assert "TEXCOORD_0" not in p and "COLOR_0" not in p
    np.testing.assert_array_equal(p["POSITION"], body.verts.astype(np.float32))
    np.testing.assert_array_equal(p["indices"], body.triangles())
    # icosphere winding is outward: normals point away from the centre
    assert np.all(np.sum(p["NORMAL"] * p["POSITION"], axis=1) > 0)
    assert not doc["materials"][0]["doubleSided"]
    g = trimesh.load(path, force="scene", process=False).geometry["body"]
    np.testing.assert_allclose(g.vertices, body.verts, atol=1e-6)


def test_container_is_valid(tmp_path):
    path = write_scene_glb(tmp_path / "v.glb", [("body", _body_like()), ("garment", _seam_mesh())])
    doc, blob = _parse_glb(path)  # header magic, version, lengths, chunk types and padding
    assert doc["asset"]["version"] == "2.0"
    assert doc["buffers"] == [{"byteLength": len(blob)}]
    for acc in doc["accessors"]:
        view = doc["bufferViews"][acc["bufferView"]]
        size = np.dtype(_DTYPES[acc["componentType"]]).itemsize
        assert (view["byteOffset"] + acc["byteOffset"]) % size == 0 and view["byteOffset"] % 4 == 0
        assert acc["byteOffset"] + acc["count"] * size * _WIDTH[acc["type"]] <= view["byteLength"]
        assert view["byteOffset"] + view["byteLength"] <= len(blob)
    for m in doc["meshes"]:
        pos = m["primitives"][0]["attributes"]["POSITION"]
        arr = _accessor(doc, blob, pos)
        assert doc["accessors"][pos]["min"] == arr.min(0).tolist()
        assert doc["accessors"][pos]["max"] == arr.max(0).tolist()
        idx = _accessor(doc, blob, m["primitives"][0]["indices"])
        assert idx.max() < len(arr)
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
    doc, blob = _parse_glb(path)
    assert [n["name"] for n in doc["nodes"]] == ["body", "garment"]
    p = _primitive(doc, blob, "garment")
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
