"""Load a garment mesh: units to metres, validation, degenerate faces, pieces, the .mhclo beside it."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from vfit_engine.errors import InputError
from vfit_engine.garment.mhclo import parse_mhclo
from vfit_engine.io.mesh import read_mesh
from vfit_engine.io.meshdata import MAX_VERTS, MeshData
from vfit_engine.units import LENGTH_UNITS

#: A garment of more than this many pieces, with fewer than SOUP_FACES_PER_PIECE faces each on average, is
#: probably a triangle soup (an export that did not share vertices between faces): a warning says so.
SOUP_PIECES = 50
SOUP_FACES_PER_PIECE = 4
#: Largest coordinate a garment file may hold, in its own units (1 km in mm): beyond it a file is not a
#: garment (coordinates of 1e155 overflowed the k-d trees with a traceback).
MAX_COORDINATE = 1e6

#: Plausible garment height / body height (a bikini top ... a long coat or dress on a raised body).
HEIGHT_RATIO_RANGE = (0.05, 1.3)
#: Ratio a typical garment has; among plausible units the one closest to it (log scale) wins.
TYPICAL_HEIGHT_RATIO = 0.55
#: A garment whose every extent is under this share of the body's height (25 cm on 1.7 m: a cap, a sock) is
#: questioned when its units were given and its height reads as a garment in another unit.
SMALL_SIZE_RATIO = 0.15
#: Body height assumed when none is given, m.
DEFAULT_BODY_HEIGHT_M = 1.7


@dataclass
class Garment:
    """A garment mesh in metres and what was learned while loading it.

    Attributes
    ----------
    mesh : MeshData
        Vertices in m, file order; degenerate faces removed.
    units : str
        Unit of the file (``m``, ``dm``, ``cm`` or ``mm``).
    source : Path
    warnings : list of str
    pieces : (n,) int64
        Connected-component label of every vertex over the ``v``-index topology (0..n_pieces-1,
        numbered in order of the first vertex of each piece).
    mhclo_path : Path or None
        A MakeHuman ``.mhclo`` beside the file that binds this OBJ.
    """

    mesh: MeshData
    units: str
    source: Path
    warnings: list = field(default_factory=list)
    pieces: np.ndarray = None
    mhclo_path: Path | None = None

    @property
    def n_pieces(self):
        """Number of connected pieces (isolated vertices count as pieces)."""
        return int(self.pieces.max()) + 1 if self.pieces is not None and self.pieces.size else 0

    @property
    def verts(self):
        """(n, 3) float64 vertex positions, m."""
        return self.mesh.verts

    def binding(self):
        """The ``.mhclo`` beside the file when it binds exactly this garment's vertices, else None.

        A binding that cannot be read or binds another vertex count is left out with a warning
        (``warnings``): the garment is then treated as one without a binding.
        """
        if getattr(self, "_binding", False) is not False:
            return self._binding

        self._binding = None
        if self.mhclo_path is not None:
            try:
                b = parse_mhclo(self.mhclo_path)
            except (InputError, OSError, ValueError) as exc:
                self.warnings.append(f"ignored its binding: {exc}")
            else:
                if b.n_verts == self.mesh.n_verts:
                    self._binding = b
                else:
                    self.warnings.append(f"ignored {self.mhclo_path.name}: it binds {b.n_verts} vertices, the "
                                         f"garment has {self.mesh.n_verts}")
        return self._binding


def choose_units(height, body_height_m=None):
    """Guess the unit of a garment whose bounding-box height (Y extent) is ``height`` file units.

    Candidates are the units of ``units.LENGTH_UNITS`` whose garment/body height ratio lies in
    ``HEIGHT_RATIO_RANGE``; the ratio closest to ``TYPICAL_HEIGHT_RATIO`` in log scale wins. If none
    is plausible the closest overall is returned with ``plausible=False``.

    Parameters
    ----------
    height : float
        Garment height in file units.
    body_height_m : float or None
        Body height, m (default 1.7 m).

    Returns
    -------
    (unit, plausible) : (str, bool)
    """
    body = DEFAULT_BODY_HEIGHT_M if body_height_m is None else float(body_height_m)
    lo, hi = HEIGHT_RATIO_RANGE

    def score(u):
        return abs(np.log(height * LENGTH_UNITS[u] / body / TYPICAL_HEIGHT_RATIO))

    ok = [u for u in LENGTH_UNITS if lo <= height * LENGTH_UNITS[u] / body <= hi]
    if ok:
        return min(ok, key=score), True
    return min(LENGTH_UNITS, key=score), False


def _small_for_units(verts, height, units, body, body_height_m):
    """A warning (a list of at most one) for a garment whose every extent is under :data:`SMALL_SIZE_RATIO` of
    the body in the ``units`` given while its height reads as a garment in another unit: a decimetre suit read
    in cm is 13 cm tall, inside the height range, and drapes to a 1,400 % strain."""
    size = float(np.ptp(verts, axis=0).max()) * LENGTH_UNITS[units]
    guess, plausible = choose_units(height, body_height_m)
    if size >= SMALL_SIZE_RATIO * body or guess == units or not plausible:
        return []
    return [f"garment is at most {size:.3g} m across read in {units}, small for a garment on a {body:.2g} m body "
            f"(its height says {guess}: {height * LENGTH_UNITS[guess]:.3g} m tall); check --units (a cap or a sock "
            "can be this small)"]


def piece_labels(n_verts, edges):
    """(n,) int64 connected-component label of every vertex; labels ordered by first vertex."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    g = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n_verts, n_verts))
    _, lab = connected_components(g, directed=False)
    # relabel so piece 0 holds vertex 0, piece 1 the next unseen vertex ... (file order, stable)
    _, first = np.unique(lab, return_index=True)
    order = np.argsort(first)
    remap = np.empty_like(order)
    remap[order] = np.arange(order.size)
    return remap[lab].astype(np.int64)


def degenerate_faces(mesh, rel_area=1e-12):
    """(m,) bool: faces with a repeated vertex index or (numerically) zero area.

    Zero area means the fan-triangulated area is below ``rel_area`` times the squared
    bounding-box diagonal.
    """
    sizes = mesh.face_sizes()
    fv = mesh.face_verts
    face_of_corner = np.repeat(np.arange(mesh.n_faces), sizes)
    # repeated index inside a face: sort (face, vertex) pairs and look for equal neighbours
    order = np.lexsort((fv, face_of_corner))
    f_s, v_s = face_of_corner[order], fv[order]
    dup = (f_s[1:] == f_s[:-1]) & (v_s[1:] == v_s[:-1])
    bad = np.zeros(mesh.n_faces, dtype=bool)
    bad[f_s[1:][dup]] = True
    tris = mesh.triangles()
    tface = mesh.triangle_face()
    v = mesh.verts
    cross = np.cross(v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]])
    area = np.zeros(mesh.n_faces)
    np.add.at(area, tface, 0.5 * np.linalg.norm(cross, axis=1))
    diag2 = float(np.sum((v.max(0) - v.min(0)) ** 2)) if v.size else 0.0
    bad |= area <= rel_area * max(diag2, 1e-300)
    return bad


def find_mhclo(path):
    """A ``.mhclo`` beside ``path`` that binds it: same stem first, else one whose obj_file names it."""
    path = Path(path)
    same = path.with_suffix(".mhclo")
    if same.is_file():
        return same
    try:
        candidates = sorted(path.parent.glob("*.mhclo"))
    except OSError:
        return None
    for c in candidates:
        try:
            with open(c, encoding="utf-8", errors="replace") as f:
                for line in f:
                    words = line.split()
                    if words and words[0] == "obj_file" and len(words) > 1:
                        if Path(" ".join(words[1:])).name == path.name:
                            return c
                        break
                    if words and words[0] == "verts":
                        break
        except OSError:
            continue
    return None


def _check_manifold(mesh, path):
    """InputError naming the first edge shared by more than two triangles (of the faces' fans): the fit table's
    sections through it are ambiguous, and the drape would fail there, after all its work."""
    tris = mesh.triangles()
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    keys, counts = np.unique(e[:, 0] * mesh.n_verts + e[:, 1], return_counts=True)
    over = np.flatnonzero(counts > 2)
    if over.size:
        i, j = divmod(int(keys[over[0]]), mesh.n_verts)
        i, j = i + 1, j + 1
        more = f" (and {over.size - 1} more such edges)" if over.size > 1 else ""
        raise InputError(f"{path}: the edge between vertices {i} and {j} is shared by {counts[over[0]]} triangles, "
                         f"more than two{more}: a non-manifold mesh; remove the duplicate or extra faces there or "
                         "split the vertices")


def load_garment(path, units="auto", body_height_m=None, max_verts=MAX_VERTS):
    """Read a garment OBJ/PLY, convert it to metres and validate it.

    Parameters
    ----------
    path : str or Path
    units : {"auto", "m", "dm", "cm", "mm"}
        ``auto`` uses ``choose_units`` on the garment's Y extent (MakeHuman clothes -> ``dm``).
    body_height_m : float or None
        Height of the body the garment is for, m; sharpens the ``auto`` guess.
    max_verts : int

    Returns
    -------
    Garment

    Raises
    ------
    InputError
        Unreadable or garbled file, no vertices or faces, NaN/inf coordinates or beyond
        ``MAX_COORDINATE``, more than ``max_verts`` vertices, an unknown unit, every face degenerate,
        two vertices joined by an edge at the same point, or an edge shared by more than two triangles.
    """
    path = Path(path)
    if units != "auto" and units not in LENGTH_UNITS:
        raise InputError(f"unknown garment unit {units!r}; use auto, {', '.join(LENGTH_UNITS)}")
    if not path.is_file():
        raise InputError(f"garment file not found: {path}")
    mesh = read_mesh(path, max_verts=max_verts)
    if mesh.n_verts == 0:
        raise InputError(f"{path}: garment has no vertices")
    if not np.all(np.isfinite(mesh.verts)):
        bad = int(np.argmax(~np.all(np.isfinite(mesh.verts), axis=1)))
        raise InputError(f"{path}: vertex {bad + 1} has a NaN or infinite coordinate")
    far = np.abs(mesh.verts) > MAX_COORDINATE
    if far.any():
        bad = int(np.argmax(far.any(axis=1)))
        raise InputError(f"{path}: vertex {bad + 1} has a coordinate of {mesh.verts[bad][far[bad]][0]:.3g}, beyond "
                         f"+-{MAX_COORDINATE:g} file units (1 km in mm): not a garment; check the export")
    if mesh.n_faces == 0:
        raise InputError(f"{path}: garment has no faces")
    warnings = []
    height = float(np.ptp(mesh.verts[:, 1]))
    if height <= 0:  # flat in Y: no unit makes it hang on a body (and a ratio of 0 has no logarithm)
        raise InputError(f"{path}: garment has zero height (every vertex at y = {mesh.verts[0, 1]:g}); vfit "
                         "drapes garments modelled Y up, as worn: export it with Y up")
    if units == "auto":
        units, plausible = choose_units(height, body_height_m)
        if not plausible:
            warnings.append(
                f"garment height {height:g} file units is implausible in every unit; assumed {units}"
            )
    else:
        body = DEFAULT_BODY_HEIGHT_M if body_height_m is None else float(body_height_m)
        if not HEIGHT_RATIO_RANGE[0] <= height * LENGTH_UNITS[units] / body <= HEIGHT_RATIO_RANGE[1]:
            guess, plausible = choose_units(height, body_height_m)
            hint = f"its height says {guess}" if plausible else "no unit makes it garment-sized"
            warnings.append(f"garment is {height * LENGTH_UNITS[units]:.3g} m tall read in {units}, implausible "
                            f"for a garment on a {body:.2g} m body ({hint}); check --units")
        else:
            warnings.extend(_small_for_units(mesh.verts, height, units, body, body_height_m))
    mesh.verts = np.ascontiguousarray(mesh.verts * LENGTH_UNITS[units])
    bad = degenerate_faces(mesh)
    if bad.all():
        raise InputError(f"{path}: every face of the garment is degenerate")
    if bad.any():
        warnings.append(f"dropped {int(bad.sum())} degenerate faces (repeated vertex or zero area)")
        mesh = mesh.select_faces(~bad)
    e = mesh.edges()
    flat = np.all(mesh.verts[e[:, 0]] == mesh.verts[e[:, 1]], axis=1)
    if flat.any():
        i, j = e[int(np.argmax(flat))] + 1
        raise InputError(f"{path}: vertices {i} and {j} are at the same point but joined by an edge (coincident "
                         "vertices): merge them or move one apart")
    _check_manifold(mesh, path)
    used = np.zeros(mesh.n_verts, dtype=bool)
    used[mesh.face_verts] = True
    if not used.all():
        warnings.append(f"{int((~used).sum())} vertices are not used by any face (kept, they stay free)")
    pieces = piece_labels(mesh.n_verts, e)
    n_pieces = int(pieces.max()) + 1 if pieces.size else 0
    if n_pieces > SOUP_PIECES and n_pieces * SOUP_FACES_PER_PIECE > mesh.n_faces:
        warnings.append(f"{n_pieces} unconnected pieces for {mesh.n_faces} faces: a triangle soup (faces that share "
                        "no vertices)? Each piece drapes and is pinned on its own; weld the coincident vertices")
    return Garment(
        mesh=mesh,
        units=units,
        source=path,
        warnings=warnings,
        pieces=pieces,
        mhclo_path=find_mhclo(path),
    )
