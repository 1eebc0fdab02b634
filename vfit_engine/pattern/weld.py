"""Sewing a meshed pattern: seam pairs welded into one vertex, the sewn mesh oriented one way, its openings.

:func:`vfit_engine.pattern.mesh.mesh_pattern` meshes the panels and pairs the stitched edges' vertices;
:meth:`~vfit_engine.pattern.mesh.PatternMesh.welded` builds a :class:`WeldedMesh` with the functions here.
Pure NumPy and scipy.sparse.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


@dataclass(frozen=True, eq=False)
class WeldedMesh:
    """The sewn garment as one triangle mesh; its faces are the pattern's faces, one for one, in their order
    (the corners of a ``flipped`` panel's faces in reverse order).

    Attributes
    ----------
    vertex_count : int
    faces : (m, 3) int64
        Triangles on the welded vertices (``PatternMesh.faces`` through ``welded_index``), oriented one way.
    corner_uv : (m, 3, 2) float64, m
        Each face corner's place in its panel's frame (the flat pattern: a seam vertex has one per panel).
    corner_yarn_uv : (m, 3, 2) float64, m
        The same turned so that the warp runs along +V (:meth:`PatternMesh.yarn_uv`).
    welded_index : (n,) int64
        The welded vertex of every pattern vertex.
    on_seam : (w,) bool
        Welded vertices on a seam.
    face_panel : (m,) int64
        The panel of each face (index into ``PatternMesh.panel_names``).
    flipped : (p,) bool
        Panels whose faces are reversed from ``PatternMesh.faces`` (clockwise in their frame) so that the sewn
        surface is oriented one way (:meth:`PatternMesh.welded`).
    consistent : bool
        Whether one orientation fits every seam (False for a surface with a twist, a seam sewn right side to
        wrong side round a loop).
    """

    vertex_count: int
    faces: np.ndarray
    corner_uv: np.ndarray
    corner_yarn_uv: np.ndarray
    welded_index: np.ndarray
    on_seam: np.ndarray
    face_panel: np.ndarray
    flipped: np.ndarray
    consistent: bool = True

    def average(self, values):
        """(w, ...) float64: per welded vertex, the mean of ``values`` (n, ...) over the pattern vertices welded
        into it (the placed panels' 3D positions give the sewn garment's start this way)."""
        values = np.asarray(values, dtype=np.float64)
        total = np.zeros((self.vertex_count,) + values.shape[1:])
        np.add.at(total, self.welded_index, values)
        count = np.bincount(self.welded_index, minlength=self.vertex_count)
        return total / count.reshape((-1,) + (1,) * (values.ndim - 1))

    def edge_use(self):
        """(unique edges (e, 2) int64 with the smaller index first, the number of faces using each (e,))."""
        e = np.sort(np.concatenate([self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]]), axis=1)
        return np.unique(e, axis=0, return_counts=True)

    def flat_edge_lengths(self):
        """(unique edges (e, 2) int64, their rest lengths (e,) float64, m): each edge's length in the flat
        pattern, the mean over the faces using it (a seam's two sides differ by the ease sewn into it). The sewn
        garment's rest shape is the flat pattern, which no single 3D shape holds; these are its edges' share."""
        f = self.faces
        a = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
        b = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
        d = np.concatenate([np.linalg.norm(self.corner_uv[:, (k + 1) % 3] - self.corner_uv[:, k], axis=1)
                            for k in range(3)])
        edges, inverse = np.unique(np.sort(np.stack([a, b], axis=1), axis=1), axis=0, return_inverse=True)
        inverse = inverse.ravel()
        total = np.bincount(inverse, weights=d, minlength=len(edges))
        return edges, total / np.bincount(inverse, minlength=len(edges))

    def flat_length(self, loop):
        """Length, m, of a closed boundary loop (from :meth:`boundary_loops`) measured on the flat pattern: each of
        its edges in the panel of the one face using it."""
        loop = np.asarray(loop, dtype=np.int64)
        f = self.faces
        length = {}
        for k in range(3):
            d = np.linalg.norm(self.corner_uv[:, (k + 1) % 3] - self.corner_uv[:, k], axis=1)
            length.update(zip(zip(f[:, k].tolist(), f[:, (k + 1) % 3].tolist()), d.tolist()))
        return float(sum(length[(a, b)] for a, b in zip(loop.tolist(), np.roll(loop, -1).tolist())))

    def boundary_loops(self):
        """The openings: closed loops of boundary edges (used by one face), each (L,) int64 in walking order
        following the faces' orientation. Open chains (a non-manifold border) are returned as they end."""
        f = self.faces
        directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        edges, counts = self.edge_use()
        once = {tuple(e) for e in edges[counts == 1].tolist()}
        nxt = {}
        for a, b in directed.tolist():
            if (min(a, b), max(a, b)) in once:
                nxt.setdefault(a, []).append(b)
        loops, used = [], set()
        for start in sorted(nxt):
            for b in nxt[start]:
                if (start, b) in used:
                    continue
                loop, a = [start], start
                while (a, b) not in used:
                    used.add((a, b))
                    if b == start:
                        break
                    loop.append(b)
                    a, b = b, next((c for c in nxt.get(b, ()) if (b, c) not in used), None)
                    if b is None:
                        break
                loops.append(np.array(loop, dtype=np.int64))
        return loops


def weld_index(count, pairs):
    """(count,) int64: the welded vertex of each of ``count`` vertices sewn by ``pairs``, numbered in the order of
    their first vertex (stable, and the identity when nothing is sewn)."""
    labels = components(count, pairs)
    first = np.full(labels.max() + 1 if count else 0, count, dtype=np.int64)
    np.minimum.at(first, labels, np.arange(count))
    rank = np.empty_like(first)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[labels]


def sewing_faults(faces):
    """(collapsed (m,) bool, doubled (m,) bool) of triangles on welded vertices: two corners on one vertex, or
    the same three vertices as an earlier triangle."""
    flat = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    _, first, counts = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
    doubled = np.ones(len(faces), dtype=bool)
    doubled[first] = False
    return flat, doubled


def panel_flips(faces, face_panel, panel_count):
    """Which panels to reverse so that every edge two faces share runs opposite ways in them.

    Returns (flip (p,) bool, consistent bool); a breadth-first walk over the panels joined by shared edges,
    each panel's faces being consistent already (all counter-clockwise in its frame).
    """
    a = np.concatenate([faces[:, 0], faces[:, 1], faces[:, 2]])
    b = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0]])
    panel = np.tile(face_panel, 3)
    n = int(faces.max()) + 1 if faces.size else 0
    key = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    key, forward, panel = key[order], (a < b)[order], panel[order]
    two = np.flatnonzero((key[1:] == key[:-1]) & np.r_[True, key[1:-1] != key[:-2]] & np.r_[key[2:] != key[1:-1], True])
    links = {}
    for i in two.tolist():
        p, q, same = int(panel[i]), int(panel[i + 1]), bool(forward[i] == forward[i + 1])
        links.setdefault(p, []).append((q, same))
        links.setdefault(q, []).append((p, same))
    flip, seen, consistent = np.zeros(panel_count, dtype=bool), np.zeros(panel_count, dtype=bool), True
    for root in range(panel_count):
        if seen[root]:
            continue
        seen[root], stack = True, [root]
        while stack:
            p = stack.pop()
            for q, same in links.get(p, ()):
                want = flip[p] ^ same
                if not seen[q]:
                    seen[q], flip[q] = True, want
                    stack.append(q)
                elif flip[q] != want:
                    consistent = False
    return flip, consistent


def outward(xyz, faces, reverse):
    """Sum over the faces, reversed where ``reverse``, of their area normals dotted with their centroid's offset
    from the garment's middle: positive when they face outwards on the whole."""
    f = np.where(reverse[:, None], faces[:, [0, 2, 1]], faces)
    p = xyz[f]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return float(np.sum(normal * (p.mean(axis=1) - xyz.mean(axis=0))))


def components(count, pairs):
    """(count,) int64: the connected component of each of ``count`` items joined by ``pairs`` (k, 2)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(count, count))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def sewn_to(count, pairs):
    """(count,) int64: the vertex each of ``count`` vertices is sewn to through the seam ``pairs`` (k, 2) -- the
    smallest of its seam's vertices; itself where it is on no seam."""
    comp = components(count, pairs)
    first = np.empty(int(comp.max()) + 1 if count else 0, dtype=np.int64)
    first[comp[::-1]] = np.arange(count, dtype=np.int64)[::-1]
    return first[comp]


def split_for_sewing(uv, vertex_panel, faces, seam_pairs, rounds=4):
    """Split the interior edges of the triangles that sewing would collapse or double, at their midpoints.

    A triangle on three consecutive vertices of a seam (an ear at a corner of the outline, common where an edge
    a few millimetres long meets the next) lands on the same three welded vertices as the ear across the seam;
    a triangle joining two vertices sewn to each other collapses. Splitting the triangle's interior edge puts
    an unsewn vertex into it. Returns (uv, vertex_panel, faces) with the new vertices appended.
    """
    uv, vp, faces = uv.copy(), vertex_panel.copy(), faces.copy()
    for _ in range(rounds):
        index = weld_index(len(uv), seam_pairs)
        welded = index[faces]
        flat, doubled = sewing_faults(welded)
        bad = np.flatnonzero(flat | doubled)
        if not bad.size:
            break
        e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        keys, uses = np.unique(e, axis=0, return_counts=True)
        interior = {tuple(k) for k in keys[uses == 2].tolist()}
        split = set()
        for f in bad.tolist():
            sides = [tuple(sorted((faces[f, k], faces[f, (k + 1) % 3]))) for k in range(3)]
            sides = [sd for sd in sides if sd in interior]
            if flat[f]:   # only the side whose ends weld together: splitting another leaves them in one face
                sides = [sd for sd in sides if index[sd[0]] == index[sd[1]]]
            if sides:
                split.add(max(sides, key=lambda sd: np.linalg.norm(uv[sd[0]] - uv[sd[1]])))
        if not split:
            break
        for a, b in sorted(split):
            m = len(uv)
            uv = np.vstack([uv, 0.5 * (uv[a] + uv[b])])
            vp = np.append(vp, vp[a])
            on = np.flatnonzero(np.any(faces == a, axis=1) & np.any(faces == b, axis=1))
            new = []
            for tri in faces[on].tolist():   # the two faces of the edge, each halved keeping its orientation
                k = next(k for k in range(3) if {tri[k], tri[(k + 1) % 3]} == {a, b})
                p, q, r = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
                new += [[p, m, r], [m, q, r]]
            faces = np.concatenate([np.delete(faces, on, axis=0), np.array(new, dtype=np.int64)])
    return uv, vp, faces
