"""The polygon mesh every layer passes around: :class:`MeshData` and :func:`mesh_from_faces`.

Faces are stored flat (CSR): face ``i`` uses ``face_verts[face_offsets[i]:face_offsets[i + 1]]``.
This keeps triangles, quads and n-gons of a file in their original order, so a garment written back
after draping has the same vertex order, faces and UVs as the file it came from. The readers and
writers (:mod:`vfit_engine.io.obj`, :mod:`vfit_engine.io.ply`, :mod:`vfit_engine.io.mesh`) import it.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from vfit_engine.errors import InputError

#: Largest vertex count vfit accepts in an input mesh (a cap against absurd inputs).
MAX_VERTS = 300_000


@dataclass
class MeshData:
    """A polygon mesh as read from a file.

    Attributes
    ----------
    verts : (n, 3) float64
        Vertex positions in the file's units (``read_mesh`` never converts units).
    face_offsets : (m + 1,) int64
        CSR offsets into ``face_verts``; ``face_offsets[0] == 0``.
    face_verts : (k,) int64
        Vertex index of every face corner, faces one after another.
    uvs : (t, 2) float64 or None
        Texture coordinates (OBJ ``vt`` table).
    face_uvs : (k,) int64 or None
        ``uvs`` index of every face corner, aligned with ``face_verts``; -1 where a corner has none.
    groups, objects, materials : list of (str, int)
        ``g``, ``o`` and ``usemtl`` statements as (name, index of the first face after them).
    mtllib : str or None
        The ``mtllib`` argument, passed through to written OBJ files (never read).
    colors : (n, 3) uint8 or None
        Per-vertex colours (PLY ``red green blue``).
    """

    verts: np.ndarray
    face_offsets: np.ndarray
    face_verts: np.ndarray
    uvs: np.ndarray | None = None
    face_uvs: np.ndarray | None = None
    groups: list = field(default_factory=list)
    objects: list = field(default_factory=list)
    materials: list = field(default_factory=list)
    mtllib: str | None = None
    colors: np.ndarray | None = None

    @property
    def n_verts(self):
        """Number of vertices."""
        return int(self.verts.shape[0])

    @property
    def n_faces(self):
        """Number of polygons."""
        return int(self.face_offsets.shape[0] - 1)

    def face_sizes(self):
        """(m,) int64 corner count of every face."""
        return np.diff(self.face_offsets)

    def faces_list(self):
        """Faces as a list of int64 arrays (slow; for tests and small meshes)."""
        o = self.face_offsets
        return [self.face_verts[o[i]:o[i + 1]] for i in range(self.n_faces)]

    def _fan(self):
        """Fan triangulation: corner indices (into face_verts) (T, 3) and owning face (T,)."""
        sizes = self.face_sizes()
        ntri = np.maximum(sizes - 2, 0)
        face = np.repeat(np.arange(self.n_faces, dtype=np.int64), ntri)
        # j-th triangle of a face uses corners 0, j+1, j+2 of that face
        first = np.cumsum(ntri) - ntri
        j = np.arange(face.shape[0], dtype=np.int64) - np.repeat(first, ntri)
        base = self.face_offsets[:-1][face]
        corners = np.stack([base, base + j + 1, base + j + 2], axis=1)
        return corners, face

    def triangles(self):
        """(T, 3) int64 fan triangulation of every polygon, faces in order."""
        corners, _ = self._fan()
        return self.face_verts[corners]

    def triangle_face(self):
        """(T,) int64 index of the polygon each row of ``triangles()`` comes from."""
        return self._fan()[1]

    def triangle_uvs(self):
        """(T, 3) int64 ``uvs`` indices of ``triangles()`` corners, or None without UVs."""
        if self.face_uvs is None:
            return None
        corners, _ = self._fan()
        return self.face_uvs[corners]

    def quads_or_none(self):
        """(m, 4) int64 faces if every face is a quad, else None."""
        if self.n_faces and np.all(self.face_sizes() == 4):
            return self.face_verts.reshape(-1, 4)
        return None

    def edges(self):
        """(E, 2) int64 unique undirected polygon edges (not triangulation diagonals), i < j, sorted."""
        return self._unique_edges()[0]

    def _unique_edges(self):
        """Sorted unique undirected edges (E, 2) and how many face sides use each (E,)."""
        a, b = self._edge_pairs()
        lo, hi = np.minimum(a, b).astype(np.int64, copy=False), np.maximum(a, b).astype(np.int64, copy=False)
        keep = lo != hi
        # one int64 key per edge, ordered as the (lo, hi) rows are: np.unique of an int64 array is
        # ~20x faster than np.unique(axis=0), which sorts the rows as structured records
        n = int(hi.max()) + 1 if hi.size else 1
        key, count = np.unique(lo[keep] * n + hi[keep], return_counts=True)
        return np.stack([key // n, key % n], axis=1).astype(self.face_verts.dtype, copy=False), count

    def _edge_pairs(self):
        """Directed edges (a, b) of every face corner to the next corner of the same face."""
        nxt = np.arange(1, self.face_verts.shape[0] + 1, dtype=np.int64)
        # the last corner of each face wraps to the face's first corner
        if self.n_faces:
            nxt[self.face_offsets[1:] - 1] = self.face_offsets[:-1]
        return self.face_verts, self.face_verts[nxt] if self.face_verts.size else self.face_verts

    def boundary_edges(self):
        """(B, 2) int64 edges used by exactly one face (the open border of a cloth)."""
        u, count = self._unique_edges()
        return u[count == 1]

    def with_verts(self, verts):
        """A copy sharing the topology with new (n, 3) vertex positions."""
        verts = np.ascontiguousarray(verts, dtype=np.float64)
        if verts.shape != self.verts.shape:
            raise InputError(f"vertex array has shape {verts.shape}, mesh needs {self.verts.shape}")
        return replace(self, verts=verts)

    def select_faces(self, keep):
        """A copy keeping the faces where ``keep`` (m,) bool is true; vertices untouched.

        Group/object/material first-face indices are remapped to the kept faces.
        """
        keep = np.asarray(keep, dtype=bool)
        sizes = self.face_sizes()
        corner_keep = np.repeat(keep, sizes)
        offsets = np.concatenate([[0], np.cumsum(sizes[keep])]).astype(np.int64)
        new_index = np.concatenate([[0], np.cumsum(keep)]).astype(np.int64)

        def remap(entries):
            return [(name, int(new_index[first])) for name, first in entries]

        return replace(
            self,
            face_offsets=offsets,
            face_verts=self.face_verts[corner_keep],
            face_uvs=None if self.face_uvs is None else self.face_uvs[corner_keep],
            groups=remap(self.groups),
            objects=remap(self.objects),
            materials=remap(self.materials),
        )


def mesh_from_faces(verts, faces, uvs=None, face_uvs=None, colors=None):
    """Build a MeshData from (n, 3) verts and (m, s) faces or a list of polygons.

    Parameters
    ----------
    verts : (n, 3) array_like
    faces : (m, s) array_like int or list of sequences of int
    uvs : (t, 2) array_like or None
    face_uvs : same layout as ``faces`` or None
    colors : (n, 3) uint8 or None
    """
    verts = np.ascontiguousarray(verts, dtype=np.float64).reshape(-1, 3)

    def flat(f):
        if isinstance(f, np.ndarray) and f.ndim == 2:
            sizes = np.full(f.shape[0], f.shape[1], dtype=np.int64)
            return np.ascontiguousarray(f, dtype=np.int64).ravel(), sizes
        lst = [np.asarray(p, dtype=np.int64).ravel() for p in f]
        sizes = np.array([p.size for p in lst], dtype=np.int64)
        cat = np.concatenate(lst) if lst else np.zeros(0, np.int64)
        return cat, sizes

    fv, sizes = flat(faces)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    fu = None
    if face_uvs is not None:
        fu, _ = flat(face_uvs)
    return MeshData(
        verts=verts,
        face_offsets=offsets,
        face_verts=fv,
        uvs=None if uvs is None else np.ascontiguousarray(uvs, dtype=np.float64).reshape(-1, 2),
        face_uvs=fu,
        colors=None if colors is None else np.ascontiguousarray(colors, dtype=np.uint8),
    )
