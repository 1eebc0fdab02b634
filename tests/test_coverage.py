"""Coverage of a body by a fitted collider: analytic cases on a sphere 'body'."""
import numpy as np
import pytest
import trimesh

from vfit_engine.collide.body_mesh import MeshCollider
from vfit_engine.collide.coverage import coverage
from vfit_engine.collide.spheres import SphereCollider


@pytest.fixture(scope="module")
def ball():
    m = trimesh.creation.icosphere(subdivisions=4, radius=0.1)
    return np.asarray(m.vertices), MeshCollider(m.vertices, m.faces)


@pytest.mark.parametrize("radius, outside, gap_mm, overshoot_mm", [
    (0.09, 1.0, 10.0, 0.0),    # inscribed and too small: every vertex 1 cm outside, nothing floats
    (0.11, 0.0, 0.0, 10.0),    # too big: nothing outside, the surface floats 1 cm off
])
def test_sphere_collider_on_a_ball(ball, radius, outside, gap_mm, overshoot_mm):
    verts, body = ball
    labels = (verts[:, 0] > 0).astype(np.int64)  # two 'parts'
    cov = coverage(SphereCollider([[0.0, 0.0, 0.0]], [radius]), verts, labels, ["left", "right"], body)
    t = cov["total"]
    assert t["vertices"] == len(verts) and set(cov["parts"]) == {"left", "right"}
    assert t["outside_fraction"] == pytest.approx(outside)
    # the icosphere's faces lie up to ~0.1 mm inside its circumscribed radius
    assert t["max_gap_mm"] == pytest.approx(gap_mm, abs=0.01)
    assert t["overshoot_max_mm"] == pytest.approx(overshoot_mm, abs=0.15)
    assert sum(p["samples"] for p in cov["parts"].values()) == t["samples"] > 0
