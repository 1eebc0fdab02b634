"""vfit's body as pattern placement reads it: its surface, its six parts, its landmark heights and girths, and
the signed distance that keeps placed panels off it.

Landmarks: floor, crotch and armpit from the body's horizontal sections
(:func:`vfit_engine.body.levels.body_levels`), the waist in the middle of the torso's narrowest stretch
(:meth:`BodyParts.narrowest`), the shoulder line at the base of the neck (the head of the rig's
``neck01`` bone: 84.6 % of the default female body's height, where GarmentCode's ``height - head_l`` puts it on
its mean body, 84.7 %), the top of the head. Parts: :func:`vfit_engine.body.segment.six_part_split`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, cKDTree

from vfit_engine.body.levels import body_levels
from vfit_engine.body.model import N_BODY
from vfit_engine.body.segment import SIX_PARTS, bone_positions, six_part_split
from vfit_engine.errors import InputError
from vfit_engine.geometry import closest_point_barycentric, vertex_normals


@dataclass
class BodyParts:
    """vfit's body as placement reads it: its surface, its six parts and its landmark heights.

    Attributes
    ----------
    surface : (13380, 3) float64, m
    tris : (T, 3) int64
    labels : (13380,) int64
        Index into :data:`vfit_engine.body.segment.SIX_PARTS` of every vertex.
    levels : dict
        ``floor``, ``crotch``, ``waist``, ``armpit``, ``shoulder`` (the shoulder line: base of the neck),
        ``top`` (m, heights) and ``center_x`` (m).
    """

    surface: np.ndarray
    tris: np.ndarray
    labels: np.ndarray
    levels: dict
    normals: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        self.normals = vertex_normals(self.surface, self.tris, outward=True)
        self._tree = cKDTree(self.surface)
        self._torso_tris = self.tris[(self.labels[self.tris] == SIX_PARTS.index("torso")).all(1)]
        # triangles round each vertex (CSR), for the closest point among those of the nearest vertices
        order = np.argsort(self.tris.ravel(), kind="stable")
        self._vert_tris = order // 3
        self._vert_start = np.searchsorted(self.tris.ravel()[order], np.arange(len(self.surface) + 1))

    @classmethod
    def from_model(cls, model, verts):
        """The body of ``verts`` ((19158, 3) or (13380, 3) m, hm08, A-pose) with ``model``'s topology and rig."""
        verts = np.asarray(verts, dtype=np.float64)
        surface = np.ascontiguousarray(verts[:N_BODY])
        tris = model.body_tris
        lv = body_levels(surface, tris)
        if not all(np.isfinite(lv[k]) for k in ("armpit_y", "waist_y", "crotch_y")):
            raise InputError("cannot find the body's armpit, waist and crotch levels (is the body in A-pose?)")
        neck_base = bone_positions(model, verts)["neck01"][0]
        levels = dict(floor=lv["y_min"], crotch=lv["crotch_y"], waist=lv["waist_y"], armpit=lv["armpit_y"],
                      shoulder=float(neck_base[1]), top=lv["y_max"], center_x=lv["center_x"])
        body = cls(surface, tris, six_part_split(model, verts), levels)
        band = [float(surface[model.rulers[k]["vertex_indices"], 1].mean()) for k in ("hips-circ", "underbust-circ")]
        body.levels["waist"] = body.narrowest(*band)
        return body

    def narrowest(self, y0, y1, step=0.005, tol=0.005):
        """The waist (m): middle of the torso's narrowest stretch between heights ``y0`` and ``y1``.

        The heights (every ``step``) whose tape girth is within ``tol`` (m) of the smallest, their median: a
        body whose torso is a tube from waist to underbust has no one narrowest height, and the narrowest
        x-width (:func:`body_levels`' waist) sat 6 cm above the girth's middle on a body morphed to
        GarmentCode's mean body; vfit's ISO waist is searched in the same band (hips to underbust rulers).
        """
        ys = np.arange(min(y0, y1), max(y0, y1) + 0.5 * step, step)
        g = np.array([self.girth(y)[0] for y in ys])
        return float(np.median(ys[g <= g.min() + tol]))

    def part_verts(self, *parts):
        """Vertices (k, 3) m of the named :data:`SIX_PARTS`."""
        keep = np.isin(self.labels, [SIX_PARTS.index(p) for p in parts])
        return self.surface[keep]

    def torso_section(self, y):
        """Points (k, 2) (x, z) m where the torso's edges cross the plane at height ``y``.

        The torso's triangles (all three corners on the torso) and its vertices within 1 cm when the plane
        misses them (above the shoulders, below the crotch).
        """
        tri = self._torso_tris
        pts = []
        for i, j in ((0, 1), (1, 2), (2, 0)):
            a, b = self.surface[tri[:, i]], self.surface[tri[:, j]]
            cross = (a[:, 1] - y) * (b[:, 1] - y) < 0
            a, b = a[cross], b[cross]
            t = (y - a[:, 1]) / (b[:, 1] - a[:, 1])
            pts.append((a + t[:, None] * (b - a))[:, [0, 2]])
        on = np.unique(tri)
        on = on[np.abs(self.surface[on, 1] - y) <= 1e-12]  # corners in the plane: no edge crosses there
        pts = np.concatenate(pts + [self.surface[on][:, [0, 2]]])
        if len(pts) < 8:
            near = self.part_verts("torso")
            pts = near[np.argsort(np.abs(near[:, 1] - y))[:16]][:, [0, 2]]
        return pts

    def girth(self, y):
        """Tape girth (m) of the torso at height ``y``: perimeter of the convex hull of its section (a tape
        bridges hollows), and the hull's centre (x, z) m."""
        xz = self.torso_section(y)
        hull = xz[ConvexHull(xz).vertices]
        return float(np.linalg.norm(np.diff(np.vstack([hull, hull[:1]]), axis=0), axis=1).sum()), hull.mean(0)

    def signed_distance(self, points, k=8):
        """Signed distance (p,) m of ``points`` (p, 3) to the body surface (negative inside) and the outward
        normal (p, 3) at the closest point.

        The closest point is searched on the triangles round the ``k`` nearest vertices (exact for points
        within a few centimetres, where it matters); the sign is that of the offset along the normal
        interpolated at the closest point.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        _, near = self._tree.query(p, k=k)
        counts = self._vert_start[near + 1] - self._vert_start[near]
        owner = np.repeat(np.arange(len(p)), counts.sum(1))
        starts = np.repeat(self._vert_start[near].ravel(), counts.ravel())
        offs = np.arange(counts.sum()) - np.repeat(np.cumsum(counts.ravel()) - counts.ravel(), counts.ravel())
        tri = self.tris[self._vert_tris[starts + offs]]
        v = self.surface
        w = closest_point_barycentric(p[owner], v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]])
        q = np.einsum("ij,ijk->ik", w, v[tri])
        d = np.linalg.norm(p[owner] - q, axis=1)
        best = np.full(len(p), np.inf)
        np.minimum.at(best, owner, d)
        pick = np.flatnonzero(d == best[owner])
        first = np.unique(owner[pick], return_index=True)[1]
        pick = pick[first]
        n = np.einsum("ij,ijk->ik", w[pick], self.normals[tri[pick]])
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-12)[:, None]
        sign = np.where(np.einsum("ij,ij->i", p - q[pick], n) < 0, -1.0, 1.0)
        return sign * best, n

    def push_out(self, points, clearance, rounds=4):
        """``points`` (p, 3) with those closer than ``clearance`` (or inside) moved out along the normal to
        ``clearance``; and how many moved.

        A point pushed out of one limb can land in another (between the thighs, in the armpit): it is pushed
        again from where it landed, up to ``rounds`` times.
        """
        p = np.array(points, dtype=np.float64).reshape(-1, 3)
        moved = np.zeros(len(p), dtype=bool)
        todo = np.arange(len(p))
        for _ in range(rounds):
            if not len(todo):
                break
            d, n = self.signed_distance(p[todo])
            close = d < clearance * (1.0 - 1e-6)
            todo, d, n = todo[close], d[close], n[close]
            p[todo] += (clearance - d)[:, None] * n
            moved[todo] = True
        return p, int(moved.sum())
