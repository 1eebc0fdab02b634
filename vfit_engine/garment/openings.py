"""Garment openings (hems, cuffs, waistbands, necklines) against the body part they go round.

An opening is a closed boundary loop of the garment mesh. Where it encircles a body part (an
arm, a leg, the waist), the shortest loop that goes round that part is at least the perimeter of
the convex hull of the part's cross-section (a tape measure round it), plus ``2 pi skin`` for
the clearance the collider keeps. If the opening's rest length is shorter than that at its place
and a few centimetres either side along the part, the garment cannot be worn there without
stretching the opening by at least::

    required_strain = (min tape + 2 pi skin) / rest length - 1

which no drape can avoid: the figure bounds the strain any result must show (the MakeHuman
female suits' short sleeves, for one, are 214 and 225 mm round against >= 238 mm of arm).
The cross-sections are cut in the plane that fits the opening best (least squares), with the
body rotated so that plane is horizontal for :class:`vfit_engine.section.MeshSections`.
"""
from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import ConvexHull

from vfit_engine.geometry import closed_loops, winding_number
from vfit_engine.io.meshdata import MeshData
from vfit_engine.section import MeshSections, rotation_to_y


def _hull_perimeter(p):
    if len(p) < 3:
        return 0.0
    try:
        return float(ConvexHull(p).area)  # in 2-D, "area" is the perimeter
    except Exception:  # degenerate (collinear) section
        return 0.0


class BodyLoops:
    """The body's cross-sections round an opening: the body part it encircles, as a convex tape.

    Building it sorts the body's edges (~85 ms on hm08): build it once per body and pass it to
    :func:`check_openings` and :func:`fit_openings`."""

    def __init__(self, body_verts, body_tris):
        self.body = np.ascontiguousarray(body_verts, dtype=np.float64)
        self.sections = MeshSections(body_tris, self.body.shape[0])

    def tapes(self, p, offsets):
        """Convex hulls of the body loop the opening ``p`` (L, 3) encircles, in planes parallel to its
        best-fit plane shifted by ``offsets`` (m): ``[(offset, hull (h, 2), frame)]`` with the hull in the
        plane's coordinates and ``frame = (rotation (3, 3), centre (3,))`` mapping them back."""
        centre = p.mean(axis=0)
        _, _, vt = np.linalg.svd(p - centre)
        rot = rotation_to_y(vt[2])
        rb = self.body @ rot.T
        c2 = rot @ centre
        q = (p - centre) @ rot.T  # the opening in the plane's frame (y ~ 0)
        reach = float(np.max(np.linalg.norm(q[:, [0, 2]], axis=1)))
        out = []
        for off in offsets:
            for sec in self.sections.loops(rb, c2[1] + off):
                # the body loop this opening goes round: it winds round the opening's centre and
                # lies within its reach (not the torso round an arm's cuff)
                if len(sec) < 3 or np.max(np.linalg.norm(sec - c2[[0, 2]], axis=1)) > 1.5 * reach:
                    continue
                if abs(winding_number(sec, c2[[0, 2]])) > 0.5:
                    try:
                        hull = sec[ConvexHull(sec).vertices]
                    except Exception:  # degenerate (collinear) section
                        continue
                    out.append((off, hull, (rot, np.array([0.0, c2[1] + off, 0.0]))))
        return out


def _perimeter(poly):
    return float(np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1).sum()) if len(poly) >= 3 else 0.0


def _edge_rest_lengths(mesh, weld):
    """{(a, b): rest length (m)} of every edge of the sewn faces (``weld`` applied, a < b), from the face edge it
    comes from in ``mesh`` (a seam's edge has two, equal to the seam's ease: the first is kept)."""
    fo, fv, rest = mesh.face_offsets, mesh.face_verts, mesh.verts
    out = {}
    for f in range(len(fo) - 1):
        corners = fv[fo[f]:fo[f + 1]]
        for u, v in zip(corners, np.roll(corners, -1)):
            key = (min(weld[u], weld[v]), max(weld[u], weld[v]))
            if key not in out:
                out[key] = float(np.linalg.norm(rest[u] - rest[v]))
    return out


def check_openings(mesh, body_verts, body_tris, skin=0.002, offsets=(-0.03, -0.02, -0.01, 0.0, 0.01, 0.02, 0.03),
                   pos=None, loops=None, weld=None):
    """Each closed opening of the garment against the body part it encircles.

    Parameters
    ----------
    mesh : MeshData
        The garment; its vertices give the openings' rest lengths.
    pos : (n, 3) float64 m or None
        Where the garment is put on the body (default ``mesh.verts``).
    body_verts : (N, 3) float64, m;  body_tris : (T, 3) int64
    skin : float, m
        Clearance kept from the body.
    offsets : sequence of float, m
        Shifts of the cutting plane along its normal; the smallest tape over them is used.
    loops : BodyLoops or None
        The body's (default: built here).
    weld : (n,) int64 or None
        A sewn pattern's cloth (its seams' two sides are two vertices each): the vertex each vertex is sewn to
        (the smallest of its seam's), so that the openings are the sewn garment's, not the panels' outlines;
        each loop edge's rest length is then that of the face edge it comes from (its panel's flat length).

    Returns
    -------
    list of dict
        One per opening that encircles a body part: ``indices`` ((L,) int64, the loop),
        ``vertices`` (count), ``centre_m`` (3,), ``rest_length_mm``, ``body_tape_mm`` (smallest over
        ``offsets``), ``required_strain`` (fraction, <= 0 when the opening fits), ``body_tape_here_mm`` (the
        tape in the opening's own plane, offset 0, where the draped opening lies; None when ``offsets`` has no
        0 or the plane cuts no loop round its centre there).
    """
    rest = mesh.verts
    pos = rest if pos is None else np.asarray(pos, dtype=np.float64)
    loops = loops or BodyLoops(body_verts, body_tris)
    sewn = mesh if weld is None else MeshData(rest, mesh.face_offsets, np.asarray(weld, np.int64)[mesh.face_verts])
    edge_rest = None if weld is None else _edge_rest_lengths(mesh, weld)
    out = []
    for loop in closed_loops(sewn):
        found = loops.tapes(pos[loop], offsets)
        if not found:
            continue
        tape = min(_perimeter(hull) for _, hull, _ in found)
        # the body at the opening's own place (its plane), the larger loop where it cuts two
        here = max((_perimeter(hull) for off, hull, _ in found if off == 0.0), default=None)
        if edge_rest is None:
            length = float(np.linalg.norm(rest[loop] - np.roll(rest[loop], -1, axis=0), axis=1).sum())
        else:
            length = float(sum(edge_rest[(min(a, b), max(a, b))] for a, b in zip(loop, np.roll(loop, -1))))
        need = (tape + 2.0 * np.pi * skin) / length - 1.0 if length > 0 else 0.0
        out.append(dict(indices=loop, vertices=int(loop.size), centre_m=[float(v) for v in pos[loop].mean(axis=0)],
                        rest_length_mm=1000.0 * length, body_tape_mm=1000.0 * tape, required_strain=float(need),
                        body_tape_here_mm=None if here is None else 1000.0 * here))
    return out


def zone_distance(mesh, loop, width):
    """Distance (m, along the rest edges) of every vertex from ``loop`` within ``width``; inf beyond.

    Returns
    -------
    dist : (n,) float64
    source : (n,) int64
        The loop vertex each zone vertex is nearest to (-1 beyond ``width``).
    """
    e = mesh.edges()
    n = mesh.n_verts
    length = np.linalg.norm(mesh.verts[e[:, 1]] - mesh.verts[e[:, 0]], axis=1)
    graph = sparse.coo_matrix((length, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    dist, _, source = dijkstra(graph, directed=False, indices=np.asarray(loop), limit=width, min_only=True,
                               return_predecessors=True)
    return dist, np.where(np.isfinite(dist), source, -1).astype(np.int64)


#: Shifts (m) of the plane along the arm (or leg ...) within which a tight opening is put where the body
#: part is thinnest.
FIT_OFFSETS = (-0.01, 0.0, 0.01)


def fit_openings(mesh, start, openings, body_verts, body_tris, skin, width, pinned=(), loops=None):
    """Openings the body forces wider start fitted round the body part, evenly.

    A hem smaller than the arm it goes round has to stretch: where the garment starts (partly inside
    the arm), the stretch would land wherever the collider first pushed the hem out and stay there,
    uneven. So each such loop is put on the body's tape round it -- the convex hull of the body's
    section in the loop's plane, ``skin`` outside it -- its vertices at the arc-length fractions of
    their rest gaps (every edge stretched alike), turned round the tape to move them least; the cloth
    within ``width`` of it follows, the move fading linearly with the distance along the cloth.

    Parameters
    ----------
    mesh : MeshData
        The garment's rest shape (its edge lengths are the rest lengths).
    start : (n, 3) float64, m
        Where the garment starts on the body.
    openings : list of dict
        :func:`check_openings`.
    body_verts : (N, 3) float64, m;  body_tris : (T, 3) int64
    skin : float, m
    width : float, m
        Width of the cloth round each opening that follows it (and may stretch as far).
    pinned : (p,) int64
        Pinned vertices: a loop holding one is left where it is.
    loops : BodyLoops or None
        The body's (default: built here when an opening needs it).

    Returns
    -------
    start : (n, 3) float64, m
    zones : list of ((k,) int64, float)
        The vertices within ``width`` of each opening that must stretch, and the strain it takes where
        it was put (at least its ``required_strain``).
    """
    out = np.array(start, dtype=np.float64)
    pinned = set(np.asarray(pinned, dtype=np.int64).tolist())
    zones = []
    for o in openings:
        if o["required_strain"] <= 0:
            continue
        loop = np.asarray(o["indices"], dtype=np.int64)
        dist, source = zone_distance(mesh, loop, width)
        zone = np.flatnonzero(np.isfinite(dist))
        strain = float(o["required_strain"])
        tapes = []
        if not pinned.intersection(loop.tolist()):
            loops = loops or BodyLoops(body_verts, body_tris)
            tapes = loops.tapes(out[loop], FIT_OFFSETS)
        if tapes:
            # a tight band slides to where the body part is thinnest within reach of where it is
            tapes = [min(tapes, key=lambda t: _perimeter(t[1]))]
            gaps = np.linalg.norm(mesh.verts[np.roll(loop, -1)] - mesh.verts[loop], axis=1)
            move = np.zeros((mesh.n_verts, 3))
            move[loop] = _on_tape(out[loop], tapes[0], gaps, skin) - out[loop]
            fade = np.clip(1.0 - dist[zone] / width, 0.0, 1.0)
            out[zone] += fade[:, None] * move[source[zone]]
            # where it is put the loop goes round a tape longer than the smallest within reach
            strain = max(strain, (_perimeter(tapes[0][1]) + 2.0 * np.pi * skin) / np.sum(gaps) - 1.0)
        zones.append((zone, strain))
    return out, zones


def _on_tape(p, tape, gaps, skin):
    """The loop ``p`` (L, 3) put on ``tape`` (from :meth:`BodyLoops.tapes`) ``skin`` outside it, its
    points at the arc-length fractions of ``gaps`` (L,), turned round it to move them least."""
    _, hull, (rot, origin) = tape
    # the hull offset outward by skin (a convex polygon's offset: edges moved out, corners rounded)
    edge = np.roll(hull, -1, axis=0) - hull
    normal = np.stack([edge[:, 1], -edge[:, 0]], axis=1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    if np.sum(normal * (hull - hull.mean(axis=0))) < 0:
        normal = -normal
    corner = normal + np.roll(normal, 1, axis=0)
    corner /= np.maximum(np.linalg.norm(corner, axis=1, keepdims=True), 1e-300)
    ring = hull + skin * corner
    seg = np.linalg.norm(np.roll(ring, -1, axis=0) - ring, axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    total = arc[-1]
    want = np.concatenate([[0.0], np.cumsum(gaps)[:-1]]) / np.sum(gaps) * total
    # the garment's points in the plane, as arc positions of their nearest ring points
    q = ((p - (rot.T @ origin)) @ rot.T)[:, [0, 2]]
    dense = ring[:, None, :] + (np.roll(ring, -1, axis=0) - ring)[:, None, :] * np.linspace(0, 1, 8, endpoint=False)[None, :, None]
    dense_arc = (arc[:-1, None] + seg[:, None] * np.linspace(0, 1, 8, endpoint=False)[None, :]).ravel()
    near = dense_arc[np.argmin(np.linalg.norm(q[:, None, :] - dense.reshape(-1, 2)[None], axis=2), axis=1)]
    # the same walking direction as the garment loop, then the rotation that moves them least
    if np.sum(np.diff(np.unwrap(near / total * 2 * np.pi))) < 0:
        want = -want
    shift = np.angle(np.mean(np.exp(1j * 2 * np.pi * (near - want) / total))) / (2 * np.pi) * total
    s = (want + shift) % total
    k = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, len(ring) - 1)
    t = (s - arc[k]) / np.where(seg[k] > 0, seg[k], 1.0)
    xy = ring[k] + t[:, None] * (np.roll(ring, -1, axis=0)[k] - ring[k])
    local = np.stack([xy[:, 0], np.zeros(len(xy)), xy[:, 1]], axis=1) + origin
    return local @ rot
