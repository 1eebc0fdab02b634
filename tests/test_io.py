"""Mesh I/O: OBJ and PLY round trips, tolerant reading, garbled input, atomic writes."""
import os
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.errors import InputError
from vfit_engine.io import MeshData, atomic_write, mesh_from_faces, read_mesh, write_mesh
from vfit_engine.io.obj import read_obj, write_obj
from vfit_engine.io.ply import read_ply, write_ply

GARMENTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "assets" / "garments"


def _mixed_mesh(seed=0):
    """Tri, quad, pentagon and a face without UVs; one unused vertex; groups and objects."""
    rng = np.random.default_rng(seed)
    verts = np.round(rng.normal(size=(9, 3)), 6)
    uvs = np.round(rng.random((8, 2)), 6)
    faces = [[0, 1, 2], [1, 3, 4, 2], [4, 5, 6, 7, 3], [0, 2, 7]]
    face_uvs = [[0, 1, 2], [1, 3, 4, 2], [4, 5, 6, 7, 3], [-1, -1, -1]]
    m = mesh_from_faces(verts, faces, uvs=uvs, face_uvs=face_uvs)
    m.groups = [("front", 0), ("back", 2)]
    m.objects = [("shirt", 0)]
    m.materials = [("cloth", 1)]
    m.mtllib = "shirt.mtl"
    return m


def _same_topology(a, b):
    assert np.array_equal(a.face_offsets, b.face_offsets)
    assert np.array_equal(a.face_verts, b.face_verts)


def test_obj_round_trip_keeps_everything(tmp_path):
    m = _mixed_mesh()
    p = tmp_path / "m.obj"
    write_obj(p, m, header=["vfit test", "two lines"])
    r = read_obj(p)
    assert r.n_verts == 9  # vertex 8 is used by no face and is kept
    np.testing.assert_array_equal(r.verts, m.verts)  # 6 decimals print exactly with %.9g
    _same_topology(r, m)
    np.testing.assert_array_equal(r.uvs, m.uvs)
    np.testing.assert_array_equal(r.face_uvs, m.face_uvs)
    assert r.groups == m.groups and r.objects == m.objects and r.materials == m.materials
    assert r.mtllib == "shirt.mtl"
    assert p.read_text().startswith("# vfit test\n# two lines\n")
    # writing what was read gives the same bytes (stable formatting)
    p2 = tmp_path / "m2.obj"
    write_obj(p2, r, header=["vfit test", "two lines"])
    assert p.read_bytes() == p2.read_bytes()


def test_obj_carries_vertex_normals_and_the_input_names(tmp_path):
    """Written OBJs have a unit ``vn`` per vertex (area-weighted, following the faces' winding) that every
    face corner references, beside the input's o/g names."""
    from vfit_engine.geometry import vertex_normals

    m = _mixed_mesh()
    p = tmp_path / "n.obj"
    write_obj(p, m)
    lines = p.read_text().splitlines()
    vn = np.array([[float(t) for t in ln.split()[1:]] for ln in lines if ln.startswith("vn ")])
    assert vn.shape == (m.n_verts, 3)
    np.testing.assert_allclose(vn, vertex_normals(m.verts, m.face_verts, m.face_offsets), atol=1e-8)
    used = np.unique(m.face_verts)
    np.testing.assert_allclose(np.linalg.norm(vn[used], axis=1), 1.0, atol=1e-8)
    for ln in (ln for ln in lines if ln.startswith("f ")):
        for corner in ln.split()[1:]:
            v, _, n = corner.split("/")
            assert v == n
    assert any(ln.startswith("g ") for ln in lines) and any(ln.startswith("o ") for ln in lines)
    write_obj(tmp_path / "plain.obj", m, normals=False)
    assert "vn" not in (tmp_path / "plain.obj").read_text()


def test_obj_round_trip_random_floats_within_print_precision(tmp_path):
    rng = np.random.default_rng(1)
    verts = rng.normal(scale=0.5, size=(50, 3))
    faces = rng.integers(0, 50, size=(30, 3))
    m = mesh_from_faces(verts, faces)
    write_mesh(tmp_path / "r.obj", m)
    r = read_mesh(tmp_path / "r.obj")
    np.testing.assert_allclose(r.verts, verts, rtol=1e-8, atol=1e-12)
    assert r.face_uvs is None and r.uvs is None
    _same_topology(r, m)


def test_write_mesh_with_replacement_verts(tmp_path):
    m = _mixed_mesh()
    moved = m.verts + 1.0
    write_mesh(tmp_path / "moved.obj", m, verts=moved)
    r = read_mesh(tmp_path / "moved.obj")
    np.testing.assert_allclose(r.verts, moved, atol=1e-8)
    _same_topology(r, m)
    with pytest.raises(InputError):
        write_mesh(tmp_path / "bad.obj", m, verts=moved[:3])


OBJ_VARIANTS = """\
# exported by something
mtllib missing_file.mtl
o thing
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0 1.0
v 0.5 0.5 1 0.2 0.3 0.4
vt 0 0
vt 1 0
vt 1 1 0
vt 0 1
vn 0 0 1
usemtl missing_material
g part_a
s 1
f 1/1/1 2/2/1 3/3/1
f 1//1 3//1 4//1
  f\t1/1 4/4 5/1
g part_b
f 2 3 5
f -4/-3 -3/-2 -1/-1
l 1 2
"""


def test_obj_reads_all_corner_forms_and_ignores_materials(tmp_path):
    p = tmp_path / "variants.obj"
    p.write_text(OBJ_VARIANTS)
    m = read_obj(p)
    assert m.n_verts == 5 and m.n_faces == 5
    np.testing.assert_array_equal(m.verts[3], [0, 1, 0])  # w ignored
    np.testing.assert_array_equal(m.verts[4], [0.5, 0.5, 1])  # colour columns ignored
    assert [list(f) for f in m.faces_list()] == [[0, 1, 2], [0, 2, 3], [0, 3, 4], [1, 2, 4], [1, 2, 4]]
    assert list(m.face_uvs) == [0, 1, 2, -1, -1, -1, 0, 3, 0, -1, -1, -1, 1, 2, 3]
    assert m.uvs.shape == (4, 2)
    assert m.groups == [("part_a", 0), ("part_b", 3)]
    assert m.objects == [("thing", 0)] and m.materials == [("missing_material", 0)]
    assert m.mtllib == "missing_file.mtl"


def test_obj_crlf_and_line_continuation(tmp_path):
    p = tmp_path / "crlf.obj"
    p.write_bytes(b"v 0 0 0\r\nv 1 0 0\r\nv 0 1 \\\r\n 0\r\nf 1 2 \\\n3\r\n")
    m = read_obj(p)
    np.testing.assert_array_equal(m.verts, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert [list(f) for f in m.faces_list()] == [[0, 1, 2]]


def test_byte_order_mark_is_not_part_of_the_first_line(tmp_path):
    """A UTF-8 byte-order mark right before the first ``v`` (Windows editors write one): read as text it
    glued itself to that line, the vertex was dropped and every face index shifted by one."""
    p = tmp_path / "bom.obj"
    p.write_bytes(b"\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n")
    m = read_obj(p)
    assert m.n_verts == 4 and [list(f) for f in m.faces_list()] == [[0, 1, 3, 2]]
    np.testing.assert_array_equal(m.verts[0], [0, 0, 0])
    plain = tmp_path / "plain.ply"
    write_ply(plain, m)
    bom = tmp_path / "bom.ply"
    bom.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    r = read_ply(bom)
    np.testing.assert_array_equal(r.verts, m.verts)
    assert [list(f) for f in r.faces_list()] == [[0, 1, 3, 2]]


def test_obj_negative_indices_are_relative_to_vertices_so_far(tmp_path):
    p = tmp_path / "neg.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf -3 -2 -1\nf 1 -1 3\n")
    m = read_obj(p)
    assert [list(f) for f in m.faces_list()] == [[0, 1, 2], [1, 2, 3], [0, 3, 2]]


def test_obj_topology_ignores_uv_seams(tmp_path):
    # two quads sharing the edge 2-3 in v but with different vt there (a UV seam)
    p = tmp_path / "seam.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
                 "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0 0\nvt 0 1\nvt 1 0\nvt 1 1\n"
                 "f 1/1 2/2 3/3 4/4\nf 2/5 5/7 6/8 3/6\n")
    m = read_obj(p)
    assert m.n_verts == 6
    assert len(m.edges()) == 7  # the seam edge 1-2 is shared, not duplicated
    assert len(m.boundary_edges()) == 6


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("v 0 0 0\nv 1 0 zero\nv 0 1 0\nf 1 2 3\n", ":2:"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", ":4: vertex index 4 out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", ":4:"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", ":4:"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n# c\nf 1 2 3.5\n", ":5:"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", ":4: face with fewer than 3"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n", ":5: texture index 2"),
        ("v 0 0\n", ":1:"),
        ("", "no vertices"),
        ("# only a comment\nvt 0 0\n", "no vertices"),
    ],
)
def test_garbled_obj_raises_input_error_naming_file_and_line(tmp_path, text, fragment):
    p = tmp_path / "bad.obj"
    p.write_text(text)
    with pytest.raises(InputError) as err:
        read_obj(p)
    msg = str(err.value)
    assert "bad.obj" in msg and fragment in msg and "\n" not in msg


def test_obj_too_many_vertices(tmp_path):
    p = tmp_path / "big.obj"
    p.write_text("v 0 0 0\n" * 300_001)
    with pytest.raises(InputError, match="300001 vertices"):
        read_mesh(p)
    assert read_mesh(p, max_verts=300_001).n_verts == 300_001


def test_missing_file_and_unknown_extension(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_mesh(tmp_path / "nope.obj")
    (tmp_path / "m.stl").write_text("solid")
    with pytest.raises(InputError, match="unknown mesh format"):
        read_mesh(tmp_path / "m.stl")
    with pytest.raises(InputError, match="unknown mesh format"):
        write_mesh(tmp_path / "m.fbx", _mixed_mesh())


def test_triangles_quads_edges():
    m = mesh_from_faces(np.zeros((6, 3)), [[0, 1, 2, 3], [1, 4, 5, 2, 3]])
    np.testing.assert_array_equal(m.triangles(), [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2], [1, 2, 3]])
    np.testing.assert_array_equal(m.triangle_face(), [0, 0, 1, 1, 1])
    assert m.quads_or_none() is None
    expected = {(0, 1), (1, 2), (2, 3), (0, 3), (1, 4), (4, 5), (2, 5), (1, 3)}
    assert {tuple(e) for e in m.edges().tolist()} == expected
    q = mesh_from_faces(np.zeros((6, 3)), np.array([[0, 1, 2, 3], [1, 4, 5, 2]]))
    np.testing.assert_array_equal(q.quads_or_none(), [[0, 1, 2, 3], [1, 4, 5, 2]])


def test_select_faces_remaps_groups():
    m = _mixed_mesh()
    s = m.select_faces(np.array([True, False, True, True]))
    assert s.n_faces == 3 and s.n_verts == m.n_verts
    assert s.groups == [("front", 0), ("back", 1)]
    assert [list(f) for f in s.faces_list()] == [[0, 1, 2], [4, 5, 6, 7, 3], [0, 2, 7]]
    assert list(s.face_uvs[-3:]) == [-1, -1, -1]


@pytest.mark.parametrize("binary", [True, False])
def test_ply_round_trip_with_colours(tmp_path, binary):
    m = _mixed_mesh()
    rng = np.random.default_rng(2)
    colors = rng.integers(0, 256, size=(m.n_verts, 3)).astype(np.uint8)
    p = tmp_path / "m.ply"
    write_ply(p, m, colors=colors, binary=binary, header="segment map")
    r = read_ply(p)
    np.testing.assert_array_equal(r.verts, m.verts)  # doubles, exact in both encodings
    _same_topology(r, m)
    np.testing.assert_array_equal(r.colors, colors)
    assert p.read_bytes().startswith(b"ply\nformat " + (b"binary_little_endian" if binary else b"ascii"))


def test_ply_is_readable_by_meshio(tmp_path):
    meshio = pytest.importorskip("meshio")
    m = mesh_from_faces(np.eye(4, 3), np.array([[0, 1, 2], [0, 2, 3]]),
                        colors=np.full((4, 3), 7, np.uint8))
    write_mesh(tmp_path / "t.ply", m)
    r = meshio.read(tmp_path / "t.ply")
    np.testing.assert_array_equal(r.points, m.verts)
    np.testing.assert_array_equal(r.cells_dict["triangle"], [[0, 1, 2], [0, 2, 3]])


def test_ply_big_endian_and_extra_properties(tmp_path):
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=">f4")
    head = ("ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nproperty float nx\nelement face 2\nproperty list uchar uint vertex_index\n"
            "end_header\n").encode()
    vrec = np.zeros(4, dtype=[("x", ">f4"), ("y", ">f4"), ("z", ">f4"), ("nx", ">f4")])
    vrec["x"], vrec["y"], vrec["z"] = verts.T
    faces = b"".join(bytes([3]) + np.array(f, ">u4").tobytes() for f in ([0, 1, 2], [1, 3, 2]))
    (tmp_path / "be.ply").write_bytes(head + vrec.tobytes() + faces)
    r = read_mesh(tmp_path / "be.ply")
    np.testing.assert_array_equal(r.verts, verts.astype(np.float64))
    assert [list(f) for f in r.faces_list()] == [[0, 1, 2], [1, 3, 2]]
    assert r.colors is None


def test_ply_garbled(tmp_path):
    p = tmp_path / "bad.ply"
    p.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                  b"0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n")
    with pytest.raises(InputError, match="out of range"):
        read_ply(p)
    p.write_bytes(b"not a ply")
    with pytest.raises(InputError, match="not a PLY"):
        read_ply(p)


def _leftovers(directory):
    return sorted(f for f in os.listdir(directory) if f.endswith(".tmp"))


def test_atomic_write_success_and_exception(tmp_path):
    target = tmp_path / "out.txt"
    with atomic_write(target) as f:
        f.write("hello\n")
    assert target.read_text() == "hello\n"
    with pytest.raises(RuntimeError):
        with atomic_write(target) as f:
            f.write("half")
            raise RuntimeError("boom")
    assert target.read_text() == "hello\n"  # previous version intact
    fresh = tmp_path / "fresh.bin"
    with pytest.raises(ValueError):
        with atomic_write(fresh, "wb") as f:
            f.write(b"x")
            raise ValueError
    assert not fresh.exists()
    assert _leftovers(tmp_path) == []


def test_atomic_write_unwritable_path(tmp_path):
    missing = tmp_path / "no_such_dir" / "out.obj"
    with pytest.raises(InputError, match="cannot write .*out.obj"):
        with atomic_write(missing) as f:
            f.write("x")
    with pytest.raises(InputError, match="cannot write"):
        write_mesh(missing, _mixed_mesh())
    assert not missing.parent.exists()


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root ignores permissions")
def test_atomic_write_read_only_directory(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(InputError, match="cannot write"):
            write_mesh(ro / "x.ply", _mixed_mesh())
        assert os.listdir(ro) == []
    finally:
        ro.chmod(0o700)


def test_writer_refuses_nan(tmp_path):
    m = _mixed_mesh()
    m.verts[0, 0] = np.nan
    for name in ("n.obj", "n.ply"):
        with pytest.raises(InputError):
            write_mesh(tmp_path / name, m)
        assert not (tmp_path / name).exists()


@pytest.mark.skipif(not GARMENTS.is_dir(), reason="../shared not present")
def test_shared_garment_obj_keeps_counts(tmp_path):
    for obj in sorted(GARMENTS.glob("*/*.obj")):
        lines = obj.read_text().splitlines()
        nv = sum(ln.startswith("v ") for ln in lines)
        nf = sum(ln.startswith("f ") for ln in lines)
        m = read_mesh(obj)
        assert (m.n_verts, m.n_faces) == (nv, nf)
        assert m.quads_or_none() is not None and m.face_uvs.min() >= 0
        write_mesh(tmp_path / obj.name, m)
        r = read_mesh(tmp_path / obj.name)
        np.testing.assert_array_equal(r.verts, m.verts)
        np.testing.assert_array_equal(r.face_uvs, m.face_uvs)
        _same_topology(r, m)


def test_meshdata_is_exported():
    assert MeshData.__module__ == "vfit_engine.io.meshdata"
