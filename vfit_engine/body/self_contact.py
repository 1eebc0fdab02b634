"""Hands and forearms laid on the body stay on its skin instead of sinking into it.

Skinning has no self-contact: a hand resting on the lap (MakeHuman's ``sit01``) sinks up to ~1 cm into the thigh,
and cloth between the two cannot then be outside both. Flesh does not pass through flesh; the hand rests on the
thigh. :class:`ArmContact` moves each hand, with its forearm fading out towards the elbow, out along the skin
it sank into until it is ``clearance`` above it -- the thickness of what lies between (a skirt's cloth and its
contact clearance). Only the arms are moved: they are what a pose lays on the body; legs folded against each
other (a knee at the chest) are left as skinned.

The height of an arm vertex over the rest of the body is its distance to the closest point on the triangles round
the nearest other vertex, signed by the skin's normal there (interpolated from its corners): a vertex's own
tangent plane alone overstates a hand's depth in a thigh by half (14 against 9.4 mm in ``sit01``).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from vfit_engine.body.model import N_BODY
from vfit_engine.body.segment import PARTS, skin_parts
from vfit_engine.geometry import closest_point_barycentric, vertex_normals

#: Forearm vertices farther than this (m, at rest) from the hand do not move with it; the move fades linearly.
FOREARM = 0.22
#: Vertices nearer than this (m) to the rest of the body are tested; a deeper sinking is not a pose's.
REACH = 0.03
#: Only vertices that move with at least this share of the hand's move decide it: the hand and the wrist (a
#: forearm's middle lying on the thigh would lift the hand by twice its own depth).
LIFTS = 0.7
#: Passes of push-and-measure (a push can bring other vertices of the hand near the skin).
PASSES = 3


class ArmContact:
    """Pushes each arm's hand and forearm out of the rest of the body (module docstring).

    Parameters
    ----------
    rest : (13380, 3) float64, m
        The body at rest (the A pose), where no arm touches the body.
    tris : (t, 3) int64
        Body triangles.
    parts : (13380,) int
        Body part of each vertex (:func:`vfit_engine.body.segment.skin_parts`).
    clearance : float, m
        Height above the skin the arm is left at where it touched or sank.
    """

    def __init__(self, rest, tris, parts, clearance=0.004):
        self.tris = np.asarray(tris, dtype=np.int64)
        self.clearance = float(clearance)
        parts = np.asarray(parts)
        self.sides = []
        for side in ("L", "R"):
            hand = np.flatnonzero(parts == PARTS.index(f"hand.{side}"))
            fore = np.flatnonzero(parts == PARTS.index(f"lowerarm.{side}"))
            d, _ = cKDTree(rest[hand]).query(rest[fore])
            weight = np.concatenate([np.ones(len(hand)), np.clip(1.0 - d / FOREARM, 0.0, 1.0)])
            moved = np.concatenate([hand, fore])
            arm = np.isin(parts, [PARTS.index(f"{p}.{side}") for p in ("upperarm", "lowerarm", "hand")])
            self.sides.append((moved[weight > 0], weight[weight > 0], np.flatnonzero(~arm), _rings(self.tris, ~arm)))

    def apply(self, verts):
        """(v, 3) m: ``verts`` (a posed body) with each hand and forearm out of the rest of the body; the
        same array when no arm comes within ``clearance`` of it."""
        out = verts
        normals = None
        for moved, weight, other, ring in self.sides:
            tree = cKDTree(out[other])  # the rest of the body does not move while this arm does
            for _ in range(PASSES):
                p = out[moved]
                d, j = tree.query(p, distance_upper_bound=REACH)
                near = np.isfinite(d) & (weight >= LIFTS)
                if not near.any():
                    break
                if normals is None:
                    normals = vertex_normals(verts, self.tris, outward=True)
                v = other[j[near]]
                height, up = _heights(p[near], out, normals, self.tris[ring[v]])
                need = (self.clearance - height) / weight[near]  # the hand's move that lifts this vertex enough
                if need.max() <= 0.0:
                    break
                low = need > 0.0
                direction = (up[low] * need[low, None]).sum(axis=0)
                length = np.linalg.norm(direction)
                if length < 1e-12:  # pressed from opposite sides at once (a hand between the thighs): left as is
                    break
                direction /= length
                if out is verts:
                    out = verts.copy()
                out[moved] += np.minimum(need.max(), REACH) * weight[:, None] * direction
        return out


def lift_hands(model, rest):
    """A function of ``posed`` (a body of ``model``'s topology posed from ``rest``, with or without helper
    vertices) that returns it with its hands resting on the skin (:class:`ArmContact`, set up once for all
    the poses of ``rest``); the helper vertices are left as skinned."""
    arms = ArmContact(np.asarray(rest, dtype=np.float64)[:N_BODY], model.body_tris, skin_parts(model))

    def lift(posed):
        body = arms.apply(np.ascontiguousarray(posed[:N_BODY], dtype=np.float64))
        return np.concatenate([body, posed[N_BODY:]]) if len(posed) > N_BODY else body

    return lift


def _rings(tris, keep):
    """(v, r) int64: the triangles round each vertex whose corners are all ``keep`` ((v,) bool), padded by
    repeating the first (a vertex on none of them gets triangle 0; it is never a nearest ``keep`` vertex)."""
    inside = np.flatnonzero(keep[tris].all(axis=1))
    corner = tris[inside].ravel()
    tri = np.repeat(inside, 3)
    order = np.argsort(corner, kind="stable")
    corner, tri = corner[order], tri[order]
    count = np.bincount(corner, minlength=len(keep))
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    width = max(int(count.max()), 1)
    k = np.minimum(np.arange(width)[None, :], np.maximum(count[:, None] - 1, 0))
    ring = tri[np.minimum(start[:, None] + k, max(len(tri) - 1, 0))]
    ring[count == 0] = 0
    return ring


def _heights(points, verts, normals, rings):
    """Signed height (k,) m of each point over the triangles ``rings`` (k, r, 3) round its nearest vertex, and
    the skin's unit normal (k, 3) at the closest point (module docstring)."""
    k, r = rings.shape[:2]
    p = np.repeat(points, r, axis=0)
    t = rings.reshape(-1, 3)
    w = closest_point_barycentric(p, verts[t[:, 0]], verts[t[:, 1]], verts[t[:, 2]])
    q = np.einsum("ij,ijk->ik", w, verts[t])
    dist = np.linalg.norm(p - q, axis=1).reshape(k, r)
    best = np.argmin(dist, axis=1)
    pick = np.arange(k) * r + best
    n = np.einsum("ij,ijk->ik", w[pick], normals[t[pick]])
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-12)[:, None]
    side = np.sign(np.einsum("ij,ij->i", points - q[pick], n))
    return side * dist[np.arange(k), best], n
