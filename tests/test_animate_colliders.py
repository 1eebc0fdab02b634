"""Which body triangles an animation's cloth meets, and what judges its frames (vfit_engine.animate.colliders)."""
import numpy as np

from vfit_engine.animate.colliders import near_triangles, reach_triangles
from vfit_engine.body.segment import PARTS


def _square(x0, z):
    """Two triangles of a 4 cm square in the plane z = ``z``, its corner at x = ``x0`` (4 vertices)."""
    v = np.array([[x0, 0.0, z], [x0 + 0.04, 0.0, z], [x0 + 0.04, 0.04, z], [x0, 0.04, z]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _body(shin_x, hand_x):
    """A thigh square under the cloth, a shin square and a hand square (two triangles each, its own part)."""
    pieces = [_square(0.0, 0.0), _square(shin_x, 0.0), _square(hand_x, 0.0), _square(hand_x + 0.1, 0.0)]
    verts = np.concatenate([p[0] for p in pieces])
    tris = np.concatenate([p[1] + 4 * i for i, p in enumerate(pieces)])
    parts = np.repeat([PARTS.index("thigh.L"), PARTS.index("shin.L"), PARTS.index("hand.L"),
                       PARTS.index("hand.L")], 4)
    return verts, tris, parts


def test_a_part_that_comes_near_in_a_later_frame_collides_whole():
    """A shin far from the draped cloth at rest that rises next to the skin the cloth covers (a knee bent to
    sitting) collides; it is missed by the rest-pose test. A hand laid on that skin brings only its near
    triangles (a detail part), and a part that never comes near stays out."""
    cloth = np.array([[0.02, 0.02, 0.005]])  # over the thigh square
    rest = _body(shin_x=0.5, hand_x=0.9)
    sitting = _body(shin_x=0.06, hand_x=0.03)  # shin 2 cm from the thigh; hand's first square on it
    bodies = np.stack([rest[0], sitting[0]])
    tris, parts = rest[1], rest[2]
    at_rest = near_triangles(bodies[0], tris, cloth, 0.05, parts)
    moving = reach_triangles(bodies, tris, cloth, 0.05, parts)
    assert at_rest.tolist() == [True, True, False, False, False, False, False, False]
    # thigh, shin whole, the hand's near square only (its other square stays 9 cm from the thigh's skin)
    assert moving.tolist() == [True, True, True, True, True, True, False, False]
    # a motion that never brings them near leaves them out
    still = reach_triangles(np.stack([rest[0], rest[0]]), tris, cloth, 0.05, parts)
    assert still.tolist() == at_rest.tolist()
