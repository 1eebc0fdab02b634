"""The body an animation's cloth meets (:class:`MovingBody`): which of its triangles collide
(:func:`reach_triangles`), the exact surface moving with the pose, and sphere colliders that follow the bones
(:class:`BoneSpheres`); and the body's velocity through each frame (the cloth's contacts act relative to it)."""
from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from vfit_engine.body.segment import PARTS, bone_positions, seed_bones
from vfit_engine.collide.auto_spheres import fit_spheres
from vfit_engine.collide.body_mesh import MeshCollider
from vfit_engine.collide.bone_spheres import MIN_BONE_LENGTH, fit_bone_spheres
from vfit_engine.collide.moving_body import MovingBodyCollider
from vfit_engine.errors import InputError

#: Body parts (:data:`vfit_engine.body.segment.PARTS`) of many small triangles: only their triangles near the
#: garment collide; of the other parts, any the garment comes near collides whole.
DETAIL_PARTS = ("head", "hand.L", "hand.R", "foot.L", "foot.R")


def near_triangles(body_verts, tris, cloth, near, parts=None):
    """(t,) bool: the triangles the garment at ``cloth`` collides with: those with a corner within ``near`` (m)
    of a cloth vertex and, given the body ``parts`` ((v,) int, :func:`vfit_engine.body.segment.skin_parts`),
    every triangle of a part (not one of :data:`DETAIL_PARTS`) that has such a triangle.

    A part is taken whole because a moving part comes to the cloth where it was far at rest (a thigh rising
    under a skirt as its wearer sits down); where a surface is cut open its inside and outside are not told
    apart, and cloth there would be pushed the wrong way. The detail parts (head, hands, feet: 70 % of the
    triangles) keep only their near triangles, cut where they are ``near`` from the cloth."""
    d, _ = cKDTree(cloth).query(body_verts, distance_upper_bound=near)
    return _whole_parts(np.isfinite(d)[tris].any(axis=1), tris, parts)


def _whole_parts(close, tris, parts):
    """``close`` triangles ((t,) bool) and every triangle of a part not in :data:`DETAIL_PARTS` that has one."""
    if parts is None:
        return close

    part = np.asarray(parts)[tris[:, 0]]
    whole = np.setdiff1d(np.unique(part[close]), [PARTS.index(p) for p in DETAIL_PARTS])
    return close | np.isin(part, whole)


def reach_triangles(bodies, tris, rest_cloth, near, parts=None):
    """(t,) bool: the triangles the garment may meet anywhere in the motion.

    The cloth moves with the skin it covers, so the body parts it can meet are those that come within
    ``near`` (m) of that skin in some frame: the skin within ``near`` of the draped garment at rest (``bodies[0]``
    and ``rest_cloth``), followed through every frame of ``bodies`` ((f + 1, v, 3), m). A shin that rises under
    a skirt's hem as its wearer sits down, or a hand laid on the lap, is far from the garment at rest. Parts
    are then taken as :func:`near_triangles` takes them (whole, except the detail parts).
    """
    d, _ = cKDTree(rest_cloth).query(bodies[0], distance_upper_bound=near)
    covered = np.flatnonzero(np.isfinite(d))
    close = np.zeros(bodies.shape[1], bool)
    for frame in bodies:
        if covered.size:
            d, _ = cKDTree(frame[covered]).query(frame, distance_upper_bound=near)
            close |= np.isfinite(d)
    return _whole_parts(close[tris].any(axis=1), tris, parts)


class MovingBody:
    """The moving body as the animation loop needs it: the exact collider the cloth meets (the triangles of
    :func:`reach_triangles`, moved every substep; or, with sphere colliders, only what judges the frames),
    the sphere colliders along the bones, and the whole body at each frame's end that judges it."""

    def __init__(self, setup, model, bodies, mats, rest_pos, st, dst):
        self.bodies, self.st = bodies, st
        self.tris = model.body_tris
        self.time = 0.0
        self.last_pos = None
        self.settle_step = dst.settle_step
        lo, hi = bodies.reshape(-1, 3).min(axis=0), bodies.reshape(-1, 3).max(axis=0)
        active = reach_triangles(bodies, self.tris, rest_pos, st.near, setup.body_parts)
        self.collider = MovingBodyCollider(bodies[0], self.tris, box=(lo, hi), active=active)
        # a frame is judged against the whole body, as an independent check sees it, not only the triangles
        # the cloth was expected to meet: cloth through a part left out of the collision must show
        self.whole = self.collider if active.all() else MovingBodyCollider(bodies[0], self.tris, box=(lo, hi))
        self.judged = 0
        self._vel, self._vel_frame = np.zeros_like(bodies[0]), -1
        self.spheres = None if st.collider == "mesh" else BoneSpheres.fitted(setup.body, model, mats, dst,
                                                                                st.collider)

    def advance(self, k):
        self.collider.advance(self.bodies[k])

    def judge(self, k):
        """The whole body's collider at the end of frame ``k`` (what :func:`frame_figures` measures against)."""
        if self.whole is not self.collider or self.spheres is not None:  # else the cloth's collider is there
            if self.judged != k:
                self.whole.advance(self.bodies[k])
                self.judged = k
            self.whole.at(1.0)
        return self.whole

    def at(self, k, s):
        """Put the body at time ``s`` of frame ``k``: (how far it moved at most (m), sphere colliders or None, the
        body mesh's vertices' velocity (v, 3) m/s or None, the spheres' (S, 3) m/s or None). The body goes from
        frame to frame on straight lines: its velocity is constant through a frame."""
        self.time = (k - 1 + s) / self.st.fps
        if self.spheres is not None:
            return 0.0, self.spheres.at(k, s), None, self.spheres.velocity(k, self.st.fps)
        self.collider.at(s)
        if self._vel_frame != k:
            np.subtract(self.bodies[k], self.bodies[k - 1], out=self._vel)
            self._vel *= self.st.fps
            self._vel_frame = k
        return self.collider.motion_bound, None, self._vel, None

    def describe(self):
        c = self.collider
        out = dict(kind=self.st.collider, near_m=self.st.near, active_triangles=int(c.active.sum()),
                   triangles=int(len(c.active)), cell_m=c.cell, margin_m=c.margin, piece_m=c.piece,
                   grid_cells=int(c.ncells), pairs_last_frame=int(c.grid.cell_tris.size),
                   side_queries=int(c.queried_sides), seconds={k: round(v, 4) for k, v in c.timings.items()})
        if self.spheres is not None:
            out["spheres"] = int(len(self.spheres.radii))
        return out


class BoneSpheres:
    """Sphere colliders fitted to the body at rest that follow its bones: each centre moves rigidly with its
    bone's skinning matrix, and between two frames along the straight line.

    ``kind`` ``"bone-spheres"``: spheres along the bones (:func:`vfit_engine.collide.bone_spheres.
    fit_bone_spheres`), each on its bone; ``"spheres"``: the greedy medial cover
    (:func:`vfit_engine.collide.auto_spheres.fit_spheres`), each following the bone that carries most of the
    skin nearest its centre.

    Parameters
    ----------
    centres : (s, 3) float64, m;  radii : (s,) float64, m
        The spheres at rest (radii with their skin).
    bone : (s,) int64
        The bone each follows (``model.bone_names`` order).
    mats : (f + 1, b, 3, 4) float64
        The bones' skinning matrices of every frame (:func:`pose_frames`).
    """

    def __init__(self, centres, radii, bone, mats):
        self.radii = np.asarray(radii, dtype=np.float64)
        m = mats[:, np.asarray(bone, dtype=np.int64)]  # (f + 1, s, 3, 4)
        self.centres = np.einsum("fsij,sj->fsi", m[:, :, :, :3], centres) + m[:, :, :, 3]
        self._out = np.empty((len(self.radii), 4))
        self._out[:, 3] = self.radii

    @classmethod
    def fitted(cls, body, model, mats, dst, kind="bone-spheres"):
        """The spheres ``kind`` (class docstring) fitted to ``body`` (at rest, with its helper vertices) with the
        drape's ``spheres_per_bone`` and ``sphere_skin`` (``dst``)."""
        if kind == "spheres":
            centres, radii, bone = cls._medial(body, model)
        else:
            centres, radii, bone = cls._along_bones(body, model, dst)
        return cls(centres, np.asarray(radii) * (1.0 + dst.sphere_skin), bone, mats)

    @staticmethod
    def _along_bones(body, model, dst):
        if not body.has_helpers:
            raise InputError("the bone-spheres collider needs the body's helper vertices (its skeleton): build the "
                             "body from measurements instead of reading it from a file")
        pos = bone_positions(model, body.verts)
        names = [b for _part, bones in seed_bones(model).items() for b in bones
                 if np.linalg.norm(np.subtract(pos[b][1], pos[b][0])) >= MIN_BONE_LENGTH]
        centres, radii, bone_of = fit_bone_spheres(body.surface, model.body_tris, [pos[n] for n in names],
                                                   per_bone=dst.spheres_per_bone)
        index = {n: i for i, n in enumerate(model.bone_names)}
        return centres, radii, np.array([index[names[i]] for i in bone_of], dtype=np.int64)

    @staticmethod
    def _medial(body, model):
        surface = body.surface
        centres, radii = fit_spheres(surface, model.body_tris, MeshCollider(surface, model.body_tris))
        bone, vertex, weight = model.skin
        keep = vertex < len(surface)
        w = sparse.csr_matrix((weight[keep], (vertex[keep], bone[keep])), shape=(len(surface), len(model.bone_names)))
        _, near = cKDTree(surface).query(centres, k=8)  # the skin round the sphere
        carry = np.asarray(sum(w[near[:, j]] for j in range(near.shape[1])).todense())
        return centres, radii, np.argmax(carry, axis=1)

    def at(self, k, s):
        """(s, 4) the spheres (centre, radius; m) at time ``s`` of frame ``k``."""
        c0 = self.centres[max(k - 1, 0)]
        self._out[:, :3] = c0 + s * (self.centres[k] - c0)
        return self._out.copy()

    def velocity(self, k, fps):
        """(s, 3) m/s: the centres' velocity through frame ``k`` (``fps`` frames per second)."""
        return (self.centres[k] - self.centres[max(k - 1, 0)]) * fps
