"""A hand laid on the body rests on its skin (vfit_engine.body.self_contact)."""
from pathlib import Path

import numpy as np
import pytest

from vfit_engine.body.model import N_BODY
from vfit_engine.body.segment import PARTS, skin_parts
from vfit_engine.body.self_contact import ArmContact
from vfit_engine.collide.body_mesh import MeshCollider


@pytest.fixture(scope="module")
def rest(body_model):
    verts = np.ascontiguousarray(body_model.default_verts("female")[:N_BODY])
    return verts, body_model.body_tris, skin_parts(body_model)


def _gap(verts, tris, parts, side="L", part="hand"):
    """Signed distance (m) of the arm ``part``'s vertices within 3 cm of the body without that arm (negative: sunk
    in). That body is open at the shoulder, so only near points are measured: their sign is the closest skin's."""
    arm = [PARTS.index(f"{p}.{side}") for p in ("upperarm", "lowerarm", "hand")]
    collider = MeshCollider(verts, tris[~np.isin(parts[tris[:, 0]], arm)])
    d, *_ = collider.query(verts[parts == PARTS.index(f"{part}.{side}")], max_out=0.03, max_in=0.03)
    d = d[np.isfinite(d)]
    return d if d.size else np.array([np.inf])


def test_the_rest_body_is_left_as_it_is(rest):
    verts, tris, parts = rest
    assert ArmContact(verts, tris, parts).apply(verts) is verts


def test_a_hand_sunk_into_the_thigh_is_lifted_onto_its_skin(rest):
    """The left hand moved 8 mm into the thigh beside it (as skinning leaves it in MakeHuman's sit01) comes out
    to the clearance above the skin (4 mm; a few mm more where the skin curves under it), not centimetres off;
    the right arm and the rest of the body do not move."""
    verts, tris, parts = rest
    hand = parts == PARTS.index("hand.L")
    gap = _gap(verts, tris, parts)
    assert gap.min() > 0.005  # at rest the hand hangs clear of the thigh
    thigh = verts[parts == PARTS.index("thigh.L")]
    centre = verts[hand].mean(axis=0)
    to = thigh[np.argmin(np.linalg.norm(thigh - centre, axis=1))] - centre  # the hand hangs ~34 cm out
    to /= np.linalg.norm(to)
    sunk = verts.copy()
    step = 0.02
    for _ in range(200):  # the hand towards the thigh until its deepest vertex is 8 mm in (finer when near)
        g = _gap(sunk, tris, parts).min()
        if g < -0.008:
            break
        step = 0.02 if g == np.inf else 0.001
        sunk[hand] += step * to
    depth = -_gap(sunk, tris, parts).min()
    assert 0.008 <= depth < 0.011
    out = ArmContact(verts, tris, parts).apply(sunk)
    lifted = _gap(out, tris, parts)
    assert 0.003 <= lifted.min() <= 0.010
    arm = np.isin(parts, [PARTS.index(p) for p in ("hand.L", "lowerarm.L")])
    assert np.array_equal(out[~arm], sunk[~arm])


POSES = Path(__file__).resolve().parents[2] / "shared" / "assets" / "poses"


@pytest.mark.skipif(not POSES.is_dir(), reason="../shared/assets/poses (MakeHuman poses) absent")
def test_sit01_s_hand_rests_on_the_knee(body_model, rest):
    """MakeHuman's sit01 lays the left hand on the raised knee: skinned, it sinks into the thigh; lifted
    (``vfit pose``, ``vfit animate``), it rests above the skin and the right hand, on the floor, is not moved."""
    from vfit_engine.body.pose import pose_body
    from vfit_engine.body.self_contact import lift_hands
    from vfit_engine.io.bvh import read_bvh

    verts, tris, parts = rest
    posed = pose_body(body_model, verts, read_bvh(POSES / "sit01.bvh")).verts
    assert _gap(posed, tris, parts).min() < -0.005
    lifted = lift_hands(body_model, verts)(posed)
    assert 0.002 <= _gap(lifted, tris, parts).min() <= 0.010
    right = np.isin(parts, [PARTS.index("hand.R"), PARTS.index("lowerarm.R")])
    assert np.array_equal(lifted[right], posed[right])
