"""A drape simulated on the garment subdivided (vfit_engine.drape.refine) and read back on its own vertices."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from vfit_engine.drape.refine import refine_setup, subdivide
from vfit_engine.io.meshdata import MeshData

DEMO_SKIRT = Path(__file__).resolve().parents[1] / "data" / "garments" / "skirt.obj"


def _strip():
    """Two unit quads side by side and a triangle on the second's far edge, in the plane y = 0."""
    verts = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 0, 1], [1, 0, 1], [2, 0, 1], [3, 0, 0.5]], float)
    faces = [[0, 3, 4, 1], [1, 4, 5, 2], [2, 5, 6]]
    offsets = np.concatenate([[0], np.cumsum([len(f) for f in faces])])
    return MeshData(verts, offsets.astype(np.int64), np.concatenate(faces).astype(np.int64))


def test_subdivision_keeps_the_vertices_and_shares_the_midpoints():
    mesh = _strip()
    fine, w = subdivide(mesh)
    edges = len(mesh.edges())
    assert edges == 9 and fine.n_verts == 7 + edges + 3 and fine.n_faces == 4 + 4 + 3
    np.testing.assert_array_equal(fine.verts[:7], mesh.verts)  # the garment's own vertices, in order
    np.testing.assert_allclose(np.asarray(w.sum(axis=1)).ravel(), 1.0)
    np.testing.assert_allclose(fine.verts, w @ mesh.verts)
    # every edge midpoint lies on its edge's middle: the shared edge 1-4 once
    mids = fine.verts[7:7 + edges]
    assert sum(np.allclose(m, [1.0, 0.0, 0.5]) for m in mids) == 1
    # the quads keep the polygons' winding: all normals along the parents' (+y here)
    def normals(m):
        t = m.triangles()
        return np.cross(m.verts[t[:, 1]] - m.verts[t[:, 0]], m.verts[t[:, 2]] - m.verts[t[:, 0]])

    assert np.all(normals(mesh)[:, 1] > 0)
    n = normals(fine)
    assert np.all(n[:, 1] > 0) and np.allclose(n[:, [0, 2]], 0.0)
    # the same surface: the areas add up
    area = 0.5 * np.linalg.norm(n, axis=1).sum()
    assert area == pytest.approx(2.0 + 0.5)


@pytest.fixture(scope="module")
def skirt_setup(body_model):
    from vfit_engine.body.resolve import default_body
    from vfit_engine.drape import prepare_drape
    from vfit_engine.garment.garment import load_garment

    return prepare_drape(load_garment(DEMO_SKIRT), default_body(body_model, "female"), body_model)


def test_refined_setup_pins_its_waistband_and_keeps_the_garment(skirt_setup):
    setup = skirt_setup
    n = setup.garment.mesh.n_verts
    fine, w = refine_setup(setup, 1)
    assert fine.garment.mesh.n_verts == w.shape[0] > 3 * n and w.shape[1] == n
    np.testing.assert_array_equal(fine.rest[:n], setup.rest)
    np.testing.assert_array_equal(fine.start[:n], setup.start)
    np.testing.assert_allclose(fine.rest, w @ setup.rest)
    # the garment's pins stay, with their targets; a midpoint of two pins is pinned between their targets
    assert set(setup.pins.indices) <= set(fine.pins.indices) and len(fine.pins.indices) > len(setup.pins.indices)
    targets = dict(zip(fine.pins.indices.tolist(), fine.pins.targets))
    for i, t in zip(setup.pins.indices, setup.pins.targets):
        np.testing.assert_array_equal(targets[i], t)
    new = [i for i in fine.pins.indices if i >= n]
    parents = w[new].tocoo()
    assert set(setup.pins.indices) >= set(parents.col.tolist())
    np.testing.assert_allclose([targets[i] for i in new], (w @ _full_targets(setup, n))[new])
    assert fine.garment.pieces.shape == (fine.garment.mesh.n_verts,)
    assert setup.garment.mesh.n_verts == n  # the garment as given is untouched


def _full_targets(setup, n):
    """(n, 3): the pins' targets, zero at the other vertices."""
    out = np.zeros((n, 3))
    out[setup.pins.indices] = setup.pins.targets
    return out


def test_a_refined_drape_is_read_back_on_the_garment(skirt_setup):
    from vfit_engine.drape import DrapeSettings, run_drape

    frames = []
    result = run_drape(skirt_setup, DrapeSettings(refine=1, max_frames=12),
                       on_frame=lambda k, pos, moving: frames.append(pos.shape))
    n = skirt_setup.garment.mesh.n_verts
    assert result.pos.shape == (n, 3) and set(frames) == {(n, 3)} and len(frames) == 12
    assert result.fine.n_verts == result.info["simulated_vertices"] > 3 * n and result.info["refine"] == 1
    np.testing.assert_array_equal(result.fine.verts[:n], result.pos)
    assert np.all(np.isfinite(result.pos)) and result.metrics["surface_samples"] > 0


def test_refine_out_of_range_is_refused():
    from vfit_cli.main import cli
    from vfit_engine.drape import DrapeSettings
    from vfit_engine.errors import InputError

    with pytest.raises(InputError, match="refine must be 0 to 2"):
        DrapeSettings(refine=3)
    out = CliRunner().invoke(cli, ["drape", str(DEMO_SKIRT), "--refine", "3"])
    assert out.exit_code == 2 and "--refine" in out.output and "Traceback" not in out.output


def test_the_garments_own_surface_points_join_the_fine_cloths():
    """A refined drape also holds out the garment's own polygons (flat between its vertices, what is written):
    their points index the garment's vertices, which are the fine cloth's first ones."""
    from vfit_engine.sim.contact_points import contact_points

    mesh = _strip()
    fine, _ = subdivide(mesh)
    own = contact_points(fine.face_verts, fine.face_offsets, fine.verts, spacing=0.3)
    coarse = contact_points(mesh.face_verts, mesh.face_offsets, mesh.verts, spacing=0.3)
    both = own.joined(coarse)
    assert both.vertex_count == fine.n_verts and both.count == own.count + coarse.count - mesh.n_verts
    np.testing.assert_allclose(both.positions(fine.verts)[own.count:], coarse.positions(mesh.verts)[mesh.n_verts:])
