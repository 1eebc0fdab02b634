"""Panels to cloth: every panel of a sewing pattern meshed into triangles, stitched edges matched vertex for vertex.

Boundary. Each edge is sampled by arc length into ``n = ceil(L / spacing)`` segments; two stitched edges take the
same ``n`` (the larger), and so do all the edges joined through chains of stitches, so that their vertices pair
one for one; consecutive edges share their corner vertex.

Interior. A triangular lattice of side ``spacing`` with one family of edges along the panel's warp (``Panel.grain``)
and the other two at +-60 degrees to it. Not quads along warp and weft split into right triangles, because every
triangle edge becomes a structural spring of the same family (:mod:`vfit_engine.sim.springs`) and a hinge
(:mod:`vfit_engine.sim.bending`): a right-triangle grid adds the mesh's own anisotropy (its diagonals one way: up
to 2.9x the bending stiffness across them, a stiffer shear one way than the other), while near-equilateral
triangles bend and stretch alike in every direction (0.98-1.03 of the analytic bending energy in
``tests/test_bending.py``). The yarn directions the cloth model does use come from the UVs: warp along V, weft
along U (:func:`PatternMesh.yarn_uv`), not from the mesh's edges. A lattice with no four points on a circle also
gives scipy's Delaunay a unique triangulation. Lattice points closer than ``CLEARANCE`` spacings to the outline
are left out, so no interior point can lie in a boundary segment's diametral circle.

Triangulation. scipy's Delaunay (Qhull, BSD-like licence) of the boundary samples and the lattice (with four far
corners, so that no straight edge's samples lie on the hull, where Qhull makes flat triangles), then a check that
every boundary segment is a Delaunay edge: one that is not (the outline comes closer to itself than a spacing, or
an acute corner next to a short edge) refines its edge and every edge stitched to it, and the panels are meshed
again; a segment is never dropped. With every boundary segment an edge, no triangle crosses the outline, and
those whose centroid is outside it are removed. Faces are oriented counter-clockwise in the panel frame (normal
+z), whichever way the outline winds.

Seams. Each stitch pairs its edges' vertices one for one (``PatternMesh.seam_pairs``, direction by
:func:`_stitch_opposed`). A triangle that sewing would collapse or lay on another's three vertices (an ear at a
corner between two sewn edges, where an edge a few millimetres long meets the next, as in GarmentCode's
armholes) has its interior edge split first (:func:`vfit_engine.pattern.weld.split_for_sewing`);
:meth:`PatternMesh.welded` gives the sewn garment as one mesh.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay, QhullError

from vfit_engine.errors import InputError

from . import weld
from .model import EdgeRef

#: Target distance between neighbouring vertices, m. The MakeHuman suits vfit drapes have 2.0-4.0 k vertices on
#: 0.9-1.8 m^2 of cloth, median edges of 21-35 mm (male_casualsuit06: 4035 vertices, 20.8 mm); at 20 mm the
#: shared patterns weld to 1.7 k (GPG tee, 0.58 m^2), 1.8 k (GarmentCode shirt, 0.64 m^2), 2.2 k (GPG skirt,
#: 0.75 m^2) and 3.4 k vertices (GarmentCode pencil dress, 1.16 m^2): a shirt and skirt together, a suit, 4.0 k.
DEFAULT_SPACING = 0.02
#: Lattice points closer to the outline than this many spacings are left out: above 0.5 no interior point can
#: stand in the diametral circle of a boundary segment (at most a spacing long), and the band between the
#: lattice and the outline stays under about 1.6 spacings wide.
CLEARANCE = 0.6
#: More vertices than this is a spacing too fine for a garment (a cloth of a million particles does not drape).
MAX_VERTICES = 1_000_000
#: Refinements of the stitched edges' counts before a missing boundary segment is an error.
REFINE_ROUNDS = 8
_CHUNK = 4096  # points per block in the point-against-outline tests (bounds their (points x segments) arrays)


@dataclass(frozen=True, eq=False)
class PatternMesh:
    """A pattern meshed as cloth: every panel's triangles in its own flat frame.

    Attributes
    ----------
    panel_names : tuple of str
        The panels, in the pattern's order.
    uv : (n, 2) float64, m
        Every vertex in its panel's frame (the flat pattern).
    vertex_panel : (n,) int64
        Index into ``panel_names`` of each vertex's panel.
    faces : (m, 3) int64
        Triangles, counter-clockwise in their panel's frame; a panel's faces use only its own vertices.
    edge_vertices : dict of EdgeRef -> (k + 1,) int64
        The vertices along each panel edge, from its start to its end (corners shared by consecutive edges).
    seam_pairs : (s, 2) int64
        Vertex pairs to be sewn, stitch by stitch in the pattern's order, each stitch along its edge ``a``.
    seam_stitch : (s,) int64
        The stitch (index into ``Pattern.stitches``) of each row of ``seam_pairs``: a seam's figures after the
        drape (its gap, its line's stretch) are read per stitch.
    grain : (p, 2) float64
        Unit warp direction of each panel in its frame.
    xyz : (n, 3) float64 or None, m
        Every vertex where its panel's ``translation`` and ``rotation`` put it in the pattern's 3D frame
        (``Panel.to_3d``); None when the pattern has no placement.
    source : str
        The pattern's file, for messages.
    """

    panel_names: tuple
    uv: np.ndarray
    vertex_panel: np.ndarray
    faces: np.ndarray
    edge_vertices: dict
    seam_pairs: np.ndarray
    grain: np.ndarray
    xyz: np.ndarray | None = None
    source: str = ""
    seam_stitch: np.ndarray | None = None

    @property
    def vertex_count(self):
        return int(self.uv.shape[0])

    @property
    def face_panel(self):
        """(m,) int64: the panel of each face."""
        return self.vertex_panel[self.faces[:, 0]]

    def yarn_uv(self):
        """(n, 2) float64, m: the flat pattern turned, panel by panel, so that its warp runs along +V and its
        weft along +U (what :func:`vfit_engine.sim.bending.uv_is_pattern` reads); lengths and the faces'
        orientation are kept."""
        g = self.grain[self.vertex_panel]
        return np.column_stack([self.uv[:, 0] * g[:, 1] - self.uv[:, 1] * g[:, 0],
                                self.uv[:, 0] * g[:, 0] + self.uv[:, 1] * g[:, 1]])

    def quality(self):
        """(smallest angle in degrees, largest aspect ratio) over all triangles; the aspect is the longest edge
        squared over the area, scaled so that an equilateral triangle has 1."""
        angles, aspect = triangle_quality(self.uv, self.faces)
        return float(angles.min()), float(aspect.max())

    def welded(self):
        """The sewn garment as one mesh: every seam pair merged into one vertex (a corner in several seams once).

        Returns
        -------
        vfit_engine.pattern.weld.WeldedMesh

        Raises
        ------
        InputError
            When sewing would collapse a triangle (two of its corners sewn to one point) or lay two triangles on
            the same three vertices: the seams are shorter there than the spacing can follow.

        Notes
        -----
        The faces are oriented consistently across the seams, panel by panel (a panel's faces are all reversed
        or none), and outwards when the pattern is placed in 3D (their normals point away from the garment's
        middle on the whole); a pattern without placement keeps its first panel's orientation (+z of its frame,
        the face of a piece cut face up).
        """
        index = weld.weld_index(self.vertex_count, self.seam_pairs)
        faces = index[self.faces]
        self._refuse_collapsed(faces)
        count = int(index.max()) + 1 if index.size else 0
        flip, consistent = weld.panel_flips(faces, self.face_panel, len(self.panel_names))
        if self.xyz is not None and weld.outward(self.xyz, self.faces, flip[self.face_panel]) < 0:
            flip = ~flip
        reverse = flip[self.face_panel]
        order = np.where(reverse[:, None], [0, 2, 1], [0, 1, 2])
        corners = np.take_along_axis(self.faces, order, axis=1)
        on_seam = np.zeros(count, dtype=bool)
        on_seam[index[self.seam_pairs.ravel()]] = True
        return weld.WeldedMesh(count, index[corners], self.uv[corners], self.yarn_uv()[corners], index, on_seam,
                               self.face_panel, flip, consistent)

    def _refuse_collapsed(self, faces):
        """InputError naming the panel and the edges of the first face that sewing collapses or doubles."""
        flat, doubled = weld.sewing_faults(faces)
        bad = np.flatnonzero(flat | doubled)
        if not bad.size:
            return
        f = int(bad[0])
        on = sorted({f"{ref.panel!r} edge {ref.edge}" for ref, vs in self.edge_vertices.items()
                     if np.isin(self.faces[f], vs).any()})
        what = "collapses to a line" if flat[f] else "lands on another triangle's three vertices"
        where = self.uv[self.faces[f]].mean(axis=0)
        raise InputError(f"{_file(self.source)}panel {self.panel_names[self.face_panel[f]]!r}: the triangle at "
                         f"({where[0]:.3f}, {where[1]:.3f}) m {what} when its seams are sewn "
                         f"({', '.join(on) or 'no edge'}; {bad.size} such triangles): the stitches there join "
                         "points closer than the spacing; check those stitches or mesh with a smaller spacing")


def triangle_quality(uv, faces):
    """Per triangle: (smallest angle in degrees (m,), aspect ratio (m,)); the aspect is the longest edge squared
    over the area times sqrt(3) / 4, 1 for an equilateral triangle and growing without bound for a sliver."""
    p = np.asarray(uv, dtype=np.float64)[faces]
    e = np.stack([p[:, 2] - p[:, 1], p[:, 0] - p[:, 2], p[:, 1] - p[:, 0]], axis=1)   # opposite corner k
    ln = np.linalg.norm(e, axis=2)
    cross = np.abs(e[:, 1, 0] * e[:, 2, 1] - e[:, 1, 1] * e[:, 2, 0])
    area = 0.5 * cross
    angles = []
    for k in range(3):
        u, v = -e[:, (k + 1) % 3], e[:, (k + 2) % 3]   # the two edges leaving corner k
        angles.append(np.degrees(np.arctan2(np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]), np.sum(u * v, 1))))
    longest = ln.max(axis=1)
    aspect = np.divide(math.sqrt(3.0) / 4.0 * longest ** 2, area, out=np.full(area.shape, np.inf),
                       where=area > 0)
    return np.min(angles, axis=0), aspect


def mesh_pattern(pattern, spacing=DEFAULT_SPACING):
    """Mesh every panel of ``pattern`` as cloth (module docstring).

    Parameters
    ----------
    pattern : vfit_engine.pattern.model.Pattern
    spacing : float, m
        Target edge length: the boundary's segments are at most this long, the lattice's sides this long.

    Returns
    -------
    PatternMesh

    Raises
    ------
    InputError
        A spacing that is not a positive length or too fine for the pattern, a stitch naming no edge, an
        outline that is not a closed loop of edges or that crosses itself.
    """
    spacing = float(spacing)
    if not math.isfinite(spacing) or spacing <= 0:
        raise InputError(f"{_file(pattern.source)}the mesh spacing must be a positive length, not {spacing} m")
    refs, comp, counts = _edge_counts(pattern, spacing)
    where = {r: k for k, r in enumerate(refs)}
    for _ in range(REFINE_ROUNDS + 1):
        panels, missing = [], None
        for name, panel in pattern.panels.items():
            per_edge = [int(counts[comp[where[EdgeRef(name, i)]]]) for i in range(len(panel.edges))]
            result = _mesh_panel(pattern.source, name, panel, per_edge, spacing)
            if isinstance(result, int):                    # the edge of a missing boundary segment
                missing = missing or []
                missing.append(where[EdgeRef(name, result)])
                continue
            panels.append(result)
        if missing is None:
            break
        for k in set(comp[missing].tolist()):
            counts[k] = max(counts[k] + 1, math.ceil(1.5 * counts[k]))
    else:
        ref = refs[missing[0]]
        raise InputError(f"{_file(pattern.source)}panel {ref.panel!r}, edge {ref.edge}: its outline comes too close to "
                         f"itself (or crosses itself) for a mesh at a spacing of {spacing * 1000:.1f} mm even after "
                         f"{REFINE_ROUNDS} refinements of the edge; check the outline there or mesh with a smaller "
                         "spacing")
    return _assemble(pattern, panels)


# ---------------------------------------------------------------------- boundary counts and stitches
def _file(source):
    """The start of an error message: the pattern's file, when it has one."""
    return f"{source}: " if source else ""


def _check_ref(pattern, ref, k):
    panel = pattern.panels.get(ref.panel)
    if panel is None:
        raise InputError(f"{_file(pattern.source)}stitch {k} names panel {ref.panel!r}, which the pattern does not have")
    if not 0 <= ref.edge < len(panel.edges):
        raise InputError(f"{_file(pattern.source)}stitch {k} names edge {ref.edge} of panel {ref.panel!r}, which has "
                         f"edges 0 to {len(panel.edges) - 1}")


def _edge_counts(pattern, spacing):
    """Every edge, its stitch component and the segment count of each component (the largest of its edges').

    Returns (refs: list of EdgeRef, comp: (e,) int64 component of each ref, counts: (c,) int64 per component).
    """
    refs = [EdgeRef(name, i) for name, p in pattern.panels.items() for i in range(len(p.edges))]
    where = {r: k for k, r in enumerate(refs)}
    lengths = np.array([pattern.edge_length(r) for r in refs], dtype=np.float64)
    for r, length in zip(refs, lengths):
        if not length > spacing * 1e-6:
            raise InputError(f"{_file(pattern.source)}panel {r.panel!r}, edge {r.edge} has no length ({length} m); "
                             "remove it or move its ends apart")
    area = sum(abs(_signed_area(p.outline())) for p in pattern.panels.values())
    estimate = 1.2 * area / spacing ** 2 + lengths.sum() / spacing
    if estimate > MAX_VERTICES:
        raise InputError(f"{_file(pattern.source)}a spacing of {spacing * 1000:g} mm would give about "
                         f"{estimate:,.0f} vertices (more than {MAX_VERTICES:,}); use a larger spacing")
    for k, s in enumerate(pattern.stitches):
        _check_ref(pattern, s.a, k)
        _check_ref(pattern, s.b, k)
    comp = weld.components(len(refs), [(where[s.a], where[s.b]) for s in pattern.stitches])
    own = np.maximum(1, np.ceil(lengths / spacing - 1e-9)).astype(np.int64)
    counts = np.zeros(comp.max() + 1 if len(comp) else 0, dtype=np.int64)
    np.maximum.at(counts, comp, own)
    return refs, comp, counts


def _stitch_opposed(pattern, stitch, placed, winding):
    """Whether edge ``b`` of the stitch runs against edge ``a``: ``Stitch.opposed`` when the file says (GarmentCode
    and GPG always do: their reader); else, for panels placed in 3D, the pairing whose ends are closer; else (no
    placement: pieces cut face up) opposed when the two outlines wind the same way."""
    if stitch.opposed is not None:
        return bool(stitch.opposed)
    if placed:
        pa, pb = pattern.panels[stitch.a.panel], pattern.panels[stitch.b.panel]
        a0, a1 = pa.to_3d(np.stack(pa.edge_ends(stitch.a.edge)))
        b0, b1 = pb.to_3d(np.stack(pb.edge_ends(stitch.b.edge)))
        # squared distances: their difference is -2 (a1 - a0).(b1 - b0), the edges' directions, which still
        # decides for a short edge on two panels far apart
        return bool(np.sum((a0 - b1) ** 2) + np.sum((a1 - b0) ** 2) <= np.sum((a0 - b0) ** 2) + np.sum((a1 - b1) ** 2))
    return bool(winding[stitch.a.panel] == winding[stitch.b.panel])


def _seam_pairs(pattern, edge_vertices):
    """(pairs (s, 2) int64, stitch (s,) int64): the vertex pairs of every stitch along its edge ``a``, its
    direction resolved (:func:`_stitch_opposed`), and the stitch of each pair."""
    placed = any(np.any(np.asarray(p.translation) != 0) for p in pattern.panels.values())
    winding = {name: np.sign(_signed_area(p.outline())) for name, p in pattern.panels.items()}
    pairs = []
    for s in pattern.stitches:
        va, vb = edge_vertices[s.a], edge_vertices[s.b]
        pairs.append(np.stack([va, vb[::-1] if _stitch_opposed(pattern, s, placed, winding) else vb], axis=1))
    if not pairs:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    stitch = np.repeat(np.arange(len(pairs), dtype=np.int64), [len(p) for p in pairs])
    return np.concatenate(pairs), stitch


# ---------------------------------------------------------------------- one panel
def _signed_area(poly):
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _boundary(source, name, panel, per_edge):
    """The outline sampled by arc length: points (b, 2) in loop order and each edge's indices into them."""
    k = len(panel.edges)
    if k < 2:
        raise InputError(f"{_file(source)}panel {name!r} has {k} edge(s); an outline needs a closed loop of edges")
    pts, index, at = [], [], 0
    for i, e in enumerate(panel.edges):
        nxt = panel.edges[(i + 1) % k]
        if e.end != nxt.start:
            raise InputError(f"{_file(source)}panel {name!r}, edge {i} ends at vertex {e.end} but edge {(i + 1) % k} "
                             f"starts at vertex {nxt.start}: the edges must follow each other round the outline")
        n = per_edge[i]
        pts.append(panel.edge_points(i, np.arange(n) / n))
        index.append(at + np.arange(n + 1))
        at += n
    return np.concatenate(pts), [ix % at for ix in index]


def _crossings(points, poly):
    """(p,) bool: inside the closed polygon ``poly`` (even-odd rule), in blocks of points."""
    a, b = poly, np.roll(poly, -1, axis=0)
    dy = b[:, 1] - a[:, 1]
    slope = np.divide(b[:, 0] - a[:, 0], dy, out=np.zeros_like(dy), where=dy != 0)
    out = np.zeros(len(points), dtype=bool)
    for lo in range(0, len(points), _CHUNK):
        p = points[lo:lo + _CHUNK]
        px, py = p[:, :1], p[:, 1:]
        spans = (a[:, 1] > py) != (b[:, 1] > py)
        x_at = a[:, 0] + (py - a[:, 1]) * slope
        out[lo:lo + _CHUNK] = np.sum(spans & (px < x_at), axis=1) % 2 == 1
    return out


def _crossing(poly, k):
    """Where segment ``k`` of the closed polyline ``poly`` properly crosses another of its segments, or None."""
    p, r = poly[k], poly[(k + 1) % len(poly)] - poly[k]
    a, b = poly, np.roll(poly, -1, axis=0)
    s = b - a
    den = r[0] * s[:, 1] - r[1] * s[:, 0]
    q = a - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (q[:, 0] * s[:, 1] - q[:, 1] * s[:, 0]) / den
        u = (q[:, 0] * r[1] - q[:, 1] * r[0]) / den
    eps = 1e-9
    hit = (np.abs(den) > 0) & (t > eps) & (t < 1 - eps) & (u > eps) & (u < 1 - eps)
    hit[[k - 1, k, (k + 1) % len(poly)]] = False
    if not hit.any():
        return None
    return p + t[np.flatnonzero(hit)[0]] * r


def _clearance(points, poly):
    """(p,) float64: the distance of each point to the closed polyline ``poly``."""
    a, b = poly, np.roll(poly, -1, axis=0)
    d = b - a
    dd = np.maximum(np.sum(d * d, axis=1), 1e-300)
    out = np.empty(len(points))
    for lo in range(0, len(points), _CHUNK):
        p = points[lo:lo + _CHUNK, None, :]
        t = np.clip(np.sum((p - a) * d, axis=2) / dd, 0.0, 1.0)
        out[lo:lo + _CHUNK] = np.sqrt(np.min(np.sum((a + t[..., None] * d - p) ** 2, axis=2), axis=1))
    return out


def _lattice(poly, grain, spacing):
    """Points of the triangular lattice along ``grain`` inside ``poly``, at least CLEARANCE spacings from it."""
    g = np.asarray(grain, dtype=np.float64)
    w = np.array([-g[1], g[0]])
    centre = poly.mean(axis=0)
    s, t = (poly - centre) @ g, (poly - centre) @ w
    row = spacing * math.sqrt(3.0) / 2.0
    j = np.arange(math.floor(t.min() / row), math.ceil(t.max() / row) + 1)
    i = np.arange(math.floor(s.min() / spacing) - 1, math.ceil(s.max() / spacing) + 2)
    jj, ii = np.meshgrid(j, i, indexing="ij")
    along = (ii + 0.5 * (jj % 2)) * spacing        # rows of warp-parallel edges, every other row shifted half
    pts = centre + along.reshape(-1, 1) * g + (jj * row).reshape(-1, 1) * w
    pts = pts[_crossings(pts, poly)]
    return pts[_clearance(pts, poly) >= CLEARANCE * spacing]


def _mesh_panel(source, name, panel, per_edge, spacing):
    """(uv (v, 2), faces (f, 3) local, edge indices) of one panel, or the index of an edge whose boundary
    segment the Delaunay triangulation missed (the caller refines it)."""
    bnd, edge_index = _boundary(source, name, panel, per_edge)
    if not np.all(np.isfinite(bnd)):
        raise InputError(f"{_file(source)}panel {name!r}: its outline has coordinates that are not numbers")
    grain = np.asarray(panel.grain, dtype=np.float64)
    norm = float(np.linalg.norm(grain))
    if not (math.isfinite(norm) and norm > 0):
        raise InputError(f"{_file(source)}panel {name!r}: its grain line has no direction ({panel.grain})")
    pts = np.concatenate([bnd, _lattice(bnd, grain / norm, spacing)])
    b, n = len(bnd), len(pts)
    # four far corners round the panel, so that no point of it lies on the convex hull: collinear points on a
    # hull (a straight edge's samples) give Qhull flat triangles and T-junctions
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    far = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) * 3.0 * (hi - lo).max() + lo - (hi - lo).max()
    try:
        tri = Delaunay(np.concatenate([pts, far]))
    except QhullError as exc:
        raise InputError(f"{_file(source)}panel {name!r}: its outline encloses no area ({str(exc).splitlines()[0]})") \
            from None
    if len(tri.coplanar):
        v = int(tri.coplanar[0, 0])
        raise InputError(f"{_file(source)}panel {name!r}: its outline passes twice through ({pts[v, 0]:.4f}, "
                         f"{pts[v, 1]:.4f}) m; an outline must not touch itself")
    faces = tri.simplices.astype(np.int64)
    faces = faces[np.all(faces < n, axis=1)]
    seg = np.stack([np.arange(b), (np.arange(b) + 1) % b], axis=1)
    have = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    found = np.isin(np.sort(seg, axis=1) @ [n, 1], have @ [n, 1])
    if not found.all():
        gone = int(np.flatnonzero(~found)[0])
        edge = next(i for i, ix in enumerate(edge_index) if gone in ix[:-1])
        crossing = _crossing(bnd, gone)
        if crossing is not None:
            raise InputError(f"{_file(source)}panel {name!r}, edge {edge}: the outline crosses itself near "
                             f"({crossing[0]:.3f}, {crossing[1]:.3f}) m; fix the crossing edges")
        return edge
    faces = faces[_crossings(pts[faces].mean(axis=1), bnd)]
    p = pts[faces]
    signed = 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                    - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    faces[signed < 0] = faces[signed < 0][:, [0, 2, 1]]
    signed = np.abs(signed)
    outline = abs(_signed_area(bnd))
    if abs(signed.sum() - outline) > 1e-9 * outline or not signed.min() > 1e-9 * spacing ** 2:
        raise InputError(f"{_file(source)}panel {name!r}: its outline crosses itself (the triangles inside it cover "
                         f"{signed.sum():.4f} m^2, the outline's area is {outline:.4f} m^2); "
                         "fix the crossing edges")
    return pts, faces, edge_index


def _assemble(pattern, panels):
    """One PatternMesh from the panels' meshes, their vertices numbered panel after panel."""
    uv, vp, faces, edge_vertices, grain, at = [], [], [], {}, [], 0
    for k, ((name, panel), (pts, f, edge_index)) in enumerate(zip(pattern.panels.items(), panels)):
        uv.append(pts)
        vp.append(np.full(len(pts), k, dtype=np.int64))
        faces.append(f + at)
        for i, ix in enumerate(edge_index):
            edge_vertices[EdgeRef(name, i)] = ix + at
        g = np.asarray(panel.grain, dtype=np.float64)
        grain.append(g / np.linalg.norm(g))
        at += len(pts)
    seam_pairs, seam_stitch = _seam_pairs(pattern, edge_vertices)
    uv, vp, faces = weld.split_for_sewing(np.concatenate(uv), np.concatenate(vp), np.concatenate(faces), seam_pairs)
    # the split edges' midpoints back among their panels' vertices, so that a panel's vertices stay consecutive
    order = np.argsort(vp, kind="stable")
    new = np.empty_like(order)
    new[order] = np.arange(len(order))
    faces = new[faces]
    faces = faces[np.lexsort((np.arange(len(faces)), vp[order][faces[:, 0]]))]
    edge_vertices = {ref: new[ix] for ref, ix in edge_vertices.items()}
    uv, vp = uv[order], vp[order]
    xyz = None
    if any(np.any(np.asarray(p.translation) != 0) for p in pattern.panels.values()):
        xyz = np.zeros((len(uv), 3))
        for k, panel in enumerate(pattern.panels.values()):
            xyz[vp == k] = panel.to_3d(uv[vp == k])
    return PatternMesh(tuple(pattern.panels), uv, vp, faces, edge_vertices, new[seam_pairs],
                       np.array(grain).reshape(-1, 2), xyz, str(pattern.source), seam_stitch)
