"""DXF-AAMA (ASTM D6673), the apparel industry's pattern exchange file: read into a ``model.Pattern``, and write.

Each piece is a BLOCK (inserted in the model space) whose entities say what they are by their layer: the
boundary (layer 1), turn points (2: the outline's corners, where one edge ends and the next begins), notches
(4), the grain line (7), internal lines (8) and the sew line (14), with the piece's texts (``Piece Name:``,
``Quantity:``, ``Category:``); the style's texts (``Units: METRIC`` or ``ENGLISH``) stand in the model space.
Layers, texts, what is read from where and what is assumed are in ``docs/pattern-formats.md``.

AAMA carries no seams: they come from the sidecar of :mod:`vfit_engine.pattern.seams`, and ``write`` writes
one so that ``read(write(pattern))`` is the same garment: the outlines within 0.1 mm (curves are written as
polylines of that chord error), the same edges (each corner a turn point) and the same stitches. Read edges
are polylines; a piece's frame is its block's (the INSERT's placement is the marker's, not the garment's).
"""

import re
from dataclasses import dataclass
from pathlib import Path

import ezdxf
import numpy as np
from ezdxf import path as dxfpath

from vfit_engine.errors import InputError
from vfit_engine.io.atomic import atomic_write

from . import curves, model, seams

BOUNDARY, TURN, NOTCH, GRAIN, INTERNAL, SEW = 1, 2, 4, 7, 8, 14
#: Metres per unit of the style text ``Units:`` and of the header's $INSUNITS.
UNITS_TEXT = {"METRIC": 0.001, "ENGLISH": 0.0254}
INSUNITS_M = {1: 0.0254, 2: 0.3048, 4: 0.001, 5: 0.01, 6: 1.0}
#: Writing: a curve becomes a polyline whose chords stray at most this far from it (m).
CHORD_M = 1e-4
#: Reading: outline pieces whose ends are this close are joined, and a turn point this close to the outline is
#: on it (m); an outline whose ends are further apart is open.
JOIN_M = 5e-4
#: Reading an outline with no turn points: its corners are where it turns by more than this (degrees).
CORNER_DEG = 30.0
NOTCH_DEPTH_M = 0.005  # the slit written for a notch, into the piece
TEXT_MM = 10.0
_CURVES = ("LINE", "LWPOLYLINE", "POLYLINE", "SPLINE", "ARC", "CIRCLE", "ELLIPSE")


# ---------------------------------------------------------------------------------------------- writing
def write(pattern, path, seams_path=None):
    """Write ``pattern`` as DXF-AAMA in millimetres; with ``seams_path``, its stitches as a seams sidecar.

    Parameters
    ----------
    pattern : model.Pattern
    path : str or Path
        The DXF (R2000, ASCII) to write.
    seams_path : str or Path, optional
        Where to write the seams sidecar (``seams.write``); turn point k of a piece is its edge k's start.
    """
    doc = ezdxf.new("R2000", setup=False)
    doc.header["$INSUNITS"] = 4  # millimetres
    doc.header["$MEASUREMENT"] = 1  # metric
    for layer in (BOUNDARY, TURN, NOTCH, GRAIN, INTERNAL):
        doc.layers.add(str(layer))
    msp = doc.modelspace()
    msp.add_text(f"Style Name: {Path(str(pattern.source)).stem or 'pattern'}",
                 dxfattribs={"layer": "1", "height": TEXT_MM, "insert": (0.0, -3 * TEXT_MM)})
    msp.add_text("Units: METRIC", dxfattribs={"layer": "1", "height": TEXT_MM, "insert": (0.0, -5 * TEXT_MM)})
    cursor, used = 0.0, set()
    for name, panel in pattern.panels.items():
        _check_loop(panel, pattern.source)
        outline = _boundary(panel) * 1000.0
        block = doc.blocks.new(_block_name(name, used))
        block.add_polyline2d([tuple(p) for p in outline], close=True, dxfattribs={"layer": "1"})
        for e in panel.edges:  # turn point k: edge k's start (the sidecar counts on it)
            block.add_point(tuple(panel.vertices[e.start] * 1000.0), dxfattribs={"layer": "2"})
        g0, g1 = _grain_line(panel.grain, outline)
        block.add_line(tuple(g0), tuple(g1), dxfattribs={"layer": "7"})
        for notch in np.asarray(panel.notches, float).reshape(-1, 2) * 1000.0:
            inward = _inward(outline, notch) * NOTCH_DEPTH_M * 1000.0
            block.add_line(tuple(notch), tuple(notch + inward), dxfattribs={"layer": "4"})
        for line in panel.internal_lines:
            block.add_polyline2d([tuple(p) for p in np.asarray(line, float) * 1000.0], dxfattribs={"layer": "8"})
        lo, hi = outline.min(axis=0), outline.max(axis=0)
        texts = [f"Piece Name: {name}", "Quantity: 1"] + ([f"Category: {panel.label}"] if panel.label else [])
        for k, text in enumerate(texts):
            at = (lo[0] + 0.1 * (hi[0] - lo[0]), 0.5 * (lo[1] + hi[1]) - 1.5 * k * TEXT_MM)
            block.add_text(text, dxfattribs={"layer": "1", "height": TEXT_MM, "insert": at})
        # pieces side by side in the model space, so a viewer or a plotter does not show a pile
        msp.add_blockref(block.name, (cursor - lo[0], -lo[1]))
        cursor += hi[0] - lo[0] + 50.0
    with atomic_write(path) as f:
        doc.write(f)
    if seams_path is not None:
        seams.write(pattern, seams_path)


def _check_loop(panel, source):
    n = len(panel.edges)
    for k, e in enumerate(panel.edges):
        if e.end != panel.edges[(k + 1) % n].start:
            raise InputError(f"{source}: panel {panel.name!r} edge {k} ends at vertex {e.end} but edge "
                             f"{(k + 1) % n} starts at {panel.edges[(k + 1) % n].start}: the edges do not make "
                             "a closed loop in order; order them along the outline")


def _block_name(name, used):
    """A DXF block name from a piece name: characters DXF forbids in names replaced, unique in the file."""
    base = re.sub(r'[<>/\\":;?*|=`,\s]', "_", str(name)) or "piece"
    candidate, k = base, 2
    while candidate.upper() in used:
        candidate, k = f"{base}_{k}", k + 1
    used.add(candidate.upper())
    return candidate


def _boundary(panel):
    """The closed outline, edge after edge, each edge's end left to the next edge's start: (m, 2) metres."""
    return np.concatenate([curves.chords(e.kind, panel.edge_ends(i), e.controls, CHORD_M)[:-1]
                           for i, e in enumerate(panel.edges)])


def _grain_line(grain, outline):
    """Ends of the grain line: through the outline's centre along ``grain``, over 60 % of its extent that way."""
    g = np.asarray(grain, float)
    g = g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 1.0])
    centre = 0.5 * (outline.min(axis=0) + outline.max(axis=0))
    half = 0.3 * np.ptp(outline @ g)
    return centre - half * g, centre + half * g


def _signed_area(points):
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _inward(outline, point):
    """Unit normal into the closed outline (m, 2) at its segment nearest ``point``."""
    a, b = outline, np.roll(outline, -1, axis=0)
    d = b - a
    t = np.clip(((point - a) * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), 1e-300), 0.0, 1.0)
    k = int(np.argmin(np.linalg.norm(a + t[:, None] * d - point, axis=1)))
    tangent = d[k] / max(np.linalg.norm(d[k]), 1e-300)
    left = np.array([-tangent[1], tangent[0]])
    return left if _signed_area(outline) > 0 else -left


# ---------------------------------------------------------------------------------------------- reading
@dataclass
class _Raw:
    """A piece's entities before they are understood: from a block, or from the model space round an outline."""

    where: str  # "block 'NAME'" or "model space outline 3", for messages
    name: str
    entities: list


def read(path, seams_path=None):
    """Read a DXF-AAMA file (and its seams sidecar) into a ``model.Pattern`` in metres.

    Parameters
    ----------
    path : str or Path
    seams_path : str or Path, optional
        The seams sidecar (``seams``); without it the pattern has no stitches.

    Returns
    -------
    model.Pattern
        ``frame`` None and every panel at zero translation and rotation (a DXF has no placement); edges are
        polylines (lines for two points) between the outline's turn points and the seams' ends.
    """
    doc = _open(path)
    scale = _units(doc, path)
    warnings, outlines, extras = [], {}, {}
    for raw in _raw_pieces(doc, path, scale):
        outline, extra = _piece(raw, scale, path, warnings)
        name, k = outline.name, 2
        while name in outlines:  # two pieces of one name: the sidecar must tell them apart
            name, k = f"{outline.name} ({k})", k + 1
        if name != outline.name:
            warnings.append(f"two pieces are named {outline.name!r}: the second is read as {name!r}")
            outline.name = name
        outlines[name], extras[name] = outline, extra
    sides = seams.read(seams_path, outlines, scale) if seams_path is not None else []
    panels, edge_at = {}, {}
    for name, outline in outlines.items():
        cuts = _cuts(outline, [s for seam in sides for s in (seam.a, seam.b) if s.piece == name], seams_path)
        panels[name], edge_at[name] = _panel(outline, cuts, extras[name])
    stitches = [model.Stitch(model.EdgeRef(s.a.piece, edge_at[s.a.piece][s.a.start]),
                             model.EdgeRef(s.b.piece, edge_at[s.b.piece][s.b.start]), s.opposed, s.right_wrong)
                for s in sides]
    return model.Pattern(panels=panels, stitches=stitches, source=str(path), units_in_meter=1.0 / scale,
                         frame=None, warnings=warnings)


def _open(path):
    try:
        return ezdxf.readfile(str(path))
    except OSError as exc:
        if exc.strerror:  # the file system's refusal (no such file, no permission)
            raise InputError(f"cannot read {path}: {exc.strerror}") from None
        raise InputError(f"{path}: not a readable DXF file ({exc}); export it again as ASCII DXF") from None
    except (ezdxf.DXFError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: not a readable DXF file ({exc}); export it again as ASCII DXF") from None


def _texts(layout):
    for e in layout:
        if e.dxftype() == "TEXT":
            yield e.dxf.text.strip()
        elif e.dxftype() == "MTEXT":
            yield e.plain_text().strip()


def _units(doc, path):
    """Metres per unit: the style text ``Units:`` wherever it stands, else $INSUNITS."""
    for layout in [doc.modelspace(), *doc.blocks]:
        for text in _texts(layout):
            m = re.match(r"units\s*:\s*(\S*)", text, re.I)
            if m:
                if m.group(1).upper() not in UNITS_TEXT:
                    raise InputError(f"{path}: unknown units {text!r}: AAMA says 'Units: METRIC' (mm) or "
                                     "'Units: ENGLISH' (inch)")
                return UNITS_TEXT[m.group(1).upper()]
    code = doc.header.get("$INSUNITS", 0)
    if code not in INSUNITS_M:
        raise InputError(f"{path}: no units: no 'Units: METRIC' or 'Units: ENGLISH' text and $INSUNITS is {code} "
                         "(not mm, cm, m, inch or foot); add the style text 'Units: METRIC' for millimetres")
    return INSUNITS_M[code]


def _layer(e):
    """The AAMA layer number of an entity (layer "1", "14"...), None for any other layer."""
    name = str(e.dxf.get("layer", "")).strip()
    return int(name) if name.isdigit() else None


def _raw_pieces(doc, path, scale):
    """Every piece: each block inserted in the model space that holds an outline, then any outlines drawn
    straight in the model space (each with the entities inside it or nearest to it)."""
    msp, raws, seen = doc.modelspace(), [], set()
    for ins in msp.query("INSERT"):
        name = ins.dxf.name
        block = doc.blocks.get(name)
        if name in seen or block is None:
            continue
        seen.add(name)
        entities = [e for e in block if _layer(e) is not None]
        if any(_layer(e) in (BOUNDARY, SEW) and e.dxftype() in _CURVES for e in entities):
            raws.append(_Raw(f"block {name!r}", name, entities))
    loose = [e for e in msp if e.dxftype() != "INSERT" and _layer(e) is not None]
    loops = _loops([_flat(e, scale) for e in loose if _layer(e) == BOUNDARY and e.dxftype() in _CURVES])
    if loops:
        groups = [[] for _ in loops]
        for e in loose:
            groups[_nearest_loop(loops, _anchor(e, scale))].append(e)
        raws += [_Raw(f"model space outline {k}", f"piece {k + 1}", g) for k, g in enumerate(groups)]
    if not raws:
        raise InputError(f"{path}: no pattern pieces: no block with an outline on layer 1 (boundary) or 14 (sew "
                         "line), and no closed outline on layer 1 in the model space")
    return raws


def _anchor(e, scale):
    """A point standing for an entity when pieces in the model space share it out (m)."""
    if e.dxftype() in ("TEXT", "MTEXT", "POINT"):
        return np.asarray(e.dxf.insert if e.dxftype() != "POINT" else e.dxf.location, float)[:2] * scale
    if e.dxftype() in _CURVES:
        pts = _flat(e, scale)
        return pts[len(pts) // 2]
    return np.zeros(2)


def _nearest_loop(loops, p):
    """Index of the loop containing ``p``, else of the loop nearest it."""
    best, best_d = 0, np.inf
    for k, loop in enumerate(loops):
        d = 0.0 if _inside(loop, p) else np.linalg.norm(loop - p, axis=1).min()
        if d < best_d:
            best, best_d = k, d
    return best


def _inside(loop, p):
    x, y = loop[:, 0], loop[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    crosses = (y > p[1]) != (y1 > p[1])
    xs = x + (p[1] - y) * (x1 - x) / np.where(y1 != y, y1 - y, 1.0)
    return bool(np.count_nonzero(crosses & (p[0] < xs)) % 2)


def _flat(e, scale):
    """A curve entity as points (k, 2) in metres, arcs and splines flattened to ``CHORD_M``."""
    return np.array([(v.x, v.y) for v in dxfpath.make_path(e).flattening(CHORD_M / scale)], float).reshape(-1, 2) \
        * scale


def _loops(chains):
    """Closed loops (m, 2) from polylines end to end (JOIN_M), each without its first point repeated;
    open chains are dropped."""
    chains = [c for c in chains if len(c) >= 2]
    loops = []
    while chains:
        cur = chains.pop(0)
        grown = True
        while grown and np.linalg.norm(cur[0] - cur[-1]) > JOIN_M:
            grown = False
            for k, c in enumerate(chains):
                for piece in (c, c[::-1]):
                    if np.linalg.norm(piece[0] - cur[-1]) <= JOIN_M:
                        cur, grown = np.vstack([cur, piece[1:]]), True
                        break
                if grown:
                    chains.pop(k)
                    break
        if len(cur) >= 4 and np.linalg.norm(cur[0] - cur[-1]) <= JOIN_M:
            keep = np.concatenate([[True], np.linalg.norm(np.diff(cur[:-1], axis=0), axis=1) > 1e-9])
            loops.append(cur[:-1][keep])
    return [loop for loop in loops if len(loop) >= 3]


def _piece(raw, scale, path, warnings):
    """(seams.Outline, extras for the panel) of one raw piece."""
    where = f"{path}: {raw.where}"
    for text in _texts(raw.entities):
        m = re.match(r"piece\s*name\s*:\s*(.*)", text, re.I)
        if m and m.group(1).strip():
            raw.name = m.group(1).strip()
            break
    where = f"{where} (piece {raw.name!r})"
    label = next((m.group(1).strip() for t in _texts(raw.entities)
                  if (m := re.match(r"category\s*:\s*(.+)", t, re.I))), None)
    curves = {}
    for e in raw.entities:
        if e.dxftype() in _CURVES:
            curves.setdefault(_layer(e), []).append(_flat(e, scale))
    sew = _loops(list(curves.get(SEW, [])))
    loops = sew or _loops(list(curves.get(BOUNDARY, [])))
    if not loops:
        if curves.get(BOUNDARY) or curves.get(SEW):
            gap = min(np.linalg.norm(c[0] - c[-1]) for c in curves.get(SEW, []) + curves.get(BOUNDARY, []))
            raise InputError(f"{where}: the outline on layer 1 is open (its ends are {gap * 1000:.1f} mm apart, "
                             f"at most {JOIN_M * 1000:.1f}): close the boundary")
        raise InputError(f"{where}: no outline: draw the boundary as a closed polyline on layer 1")
    if curves.get(SEW) and not sew:
        warnings.append(f"{raw.name}: the sew line (layer 14) is not closed: the cut line (layer 1) is sewn")
    points = max(loops, key=lambda loop: abs(_signed_area(loop)))
    outline = seams.Outline(raw.name, points, np.zeros(0), np.zeros(0))
    turns = []
    for e in raw.entities:
        if e.dxftype() == "POINT" and _layer(e) == TURN:
            pos, dist = outline.project(np.asarray(e.dxf.location, float)[:2] * scale)
            if dist <= JOIN_M and all(abs(pos - t) > 1e-9 for t in turns):  # others: turn points of other lines
                turns.append(pos)
    if not turns:
        turns = _corners(outline)
        warnings.append(f"{raw.name}: no turn points (layer 2) on its outline: its corners of more than "
                        f"{CORNER_DEG:.0f} degrees are taken as the edges' ends")
    notches = []
    for e in raw.entities:
        if _layer(e) == NOTCH and e.dxftype() in ("POINT", *_CURVES):
            pts = (np.asarray(e.dxf.location, float)[None, :2] * scale if e.dxftype() == "POINT"
                   else _flat(e, scale))
            notches.append(min((outline.project(p) for p in pts), key=lambda pd: pd[1])[0])
    outline.turns, outline.notches = np.array(turns, float), np.array(notches, float)
    grain = next((c for c in curves.get(GRAIN, []) if np.linalg.norm(c[-1] - c[0]) > 0), None)
    if grain is None:
        warnings.append(f"{raw.name}: no grain line (layer 7): the grain is taken as the piece's y axis")
        grain = np.array([[0.0, 0.0], [0.0, 1.0]])
    direction = (grain[-1] - grain[0]) / np.linalg.norm(grain[-1] - grain[0])
    return outline, dict(grain=direction, internal=curves.get(INTERNAL, []), label=label)


def _corners(outline):
    """Positions of the outline's corners (turns of more than CORNER_DEG); two at least, half its length apart."""
    p = outline.points
    d_in, d_out = p - np.roll(p, 1, axis=0), np.roll(p, -1, axis=0) - p
    cos = (d_in * d_out).sum(axis=1) / np.maximum(np.linalg.norm(d_in, axis=1) * np.linalg.norm(d_out, axis=1),
                                                  1e-300)
    cum = outline.cumulative()
    turns = list(cum[:-1][cos < np.cos(np.radians(CORNER_DEG))])
    if not turns:
        turns = [0.0]
    if len(turns) == 1:
        turns.append((turns[0] + 0.5 * cum[-1]) % cum[-1])
    return turns


def _cuts(outline, sides, seams_path):
    """Sorted positions where the outline is split into edges: the seams' ends, and the turn points that no seam
    runs past (a seam is one edge, whatever corners it turns)."""
    length = outline.length

    def inside(pos, side):
        return 1e-9 < (pos - side.start) % length < (side.end - side.start) % length - 1e-9

    ends = [p for s in sides for p in (s.start, s.end)]
    for s in sides:
        if any(inside(p, s) for p in ends):
            raise InputError(f"{seams_path}: a seam on piece {outline.name!r} (from "
                             f"{outline.point_at(s.start) * 1000} mm) runs past another seam's end: seams may not "
                             "overlap; end one where the other begins")
    cuts = ends + [t for t in outline.turns if not any(inside(t, s) for s in sides)]
    cuts = np.unique(np.round(np.asarray(cuts, float), 12))
    if len(cuts) < 2:
        cuts = np.unique(np.append(cuts, (cuts[0] + 0.5 * length) % length))
    return cuts


def _panel(outline, cuts, extra):
    """(model.Panel, {cut position: edge index}) of an outline split at ``cuts``."""
    cum = outline.cumulative()[:-1]
    n = len(cuts)
    vertices = np.array([outline.point_at(c) for c in cuts])
    edges, edge_at = [], {}
    for k in range(n):
        c0, c1 = cuts[k], cuts[(k + 1) % n]
        if c1 > c0:
            inner = np.flatnonzero((cum > c0 + 1e-9) & (cum < c1 - 1e-9))
        else:  # the edge over the outline's first point
            inner = np.concatenate([np.flatnonzero(cum > c0 + 1e-9), np.flatnonzero(cum < c1 - 1e-9)])
        controls = tuple(tuple(p) for p in outline.points[inner])
        edges.append(model.Edge(k, (k + 1) % n, "polyline" if controls else "line", controls))
        edge_at[c0] = k
    notches = np.array([outline.point_at(p) for p in outline.notches]).reshape(-1, 2)
    panel = model.Panel(name=outline.name, vertices=vertices, edges=edges, label=extra["label"],
                        grain=extra["grain"], notches=notches, internal_lines=list(extra["internal"]))
    return panel, _Lookup(edge_at)


class _Lookup(dict):
    """{cut position: edge index}, found within rounding (a seam side's start is one of the cuts)."""

    def __getitem__(self, pos):
        key = min(self, key=lambda c: abs(c - pos))
        return dict.__getitem__(self, key)
