"""Check a pattern before anything is meshed or sewn: one-line errors for what cannot be sewn, warnings for the rest.

Every reader hands its ``model.Pattern`` here (the caller calls ``validate`` after reading, for every format), so
the rules are the same whatever the file was. Thresholds, and why:

- **Open loop**: an edge's end must be the next edge's start (the same vertex, or two vertices closer than
  ``CLOSE_M`` = 0.1 mm).
- **Zero-length edge**: shorter than ``CLOSE_M``. The shortest real edges in the shared patterns are 7 mm (a
  shoulder step of the GarmentCode shirt) and 11 mm (a waist piece of the pencil dress).
- **Self-crossing outline**: the outline as a polygon (lines as themselves, curves as ``CURVE_SEGMENTS`` chords)
  may not cross itself, touch itself at a point (closer than ``TOUCH_M`` = 0.01 mm between two segments that do
  not share a corner) nor fold back on itself.
- **Seam lengths**: the two edges of a stitch may differ by what a seam can ease or gather in. The shared patterns
  hold at most 6.66 cm (the pencil dress's loose bodice gathered onto the skirt's waist: 28.7 cm onto 22.0 cm, 23 %
  of the longer edge); a sleeve cap eases 1 to 4 cm into its armhole. Refused: more than ``EASE_ERROR_CM`` = 8 cm
  (the issue's 10 cm is an error), or more than ``EASE_RATIO_ERROR`` = 2 to 1 (beyond heavy gathering: the wrong
  edge named) when the difference is over ``EASE_NOTE_CM``. Warned: over ``EASE_NOTE_CM`` = 1 cm and over
  ``EASE_NOTE_FRACTION`` = 3 % of the longer edge (the GPG skirt's 0.83 cm side seams pass silently). The 8
  patterns of GarmentCode's repository hold at most 6.66 cm too (6.25 cm between two tiers of a circle skirt).
  Gathers on purpose exist: three of GPG's 23 templates gather a skirt or top into a waistband (66.7 cm onto
  30 cm, 43.3 cm onto 26 cm); ``gathers=True`` lets such seams through as warnings.
- **An edge stitched twice, or to itself**: each panel edge belongs to at most one stitch.
- **Implausible size** (the units were wrong): a panel more than ``PANEL_MAX_M`` = 4 m across (a floor-length
  circle skirt is about 3 m), a pattern whose largest panel is under ``GARMENT_MIN_M`` = 10 cm (a garment read
  in the wrong units: the 4 mm shirt), a panel under ``PANEL_MIN_M`` = 5 mm; warned under ``PANEL_NOTE_M`` = 2 cm.
"""

import numpy as np

from ..errors import InputError

CLOSE_M = 1e-4
TOUCH_M = 1e-5
CURVE_SEGMENTS = 32
EASE_ERROR_CM = 8.0
EASE_RATIO_ERROR = 2.0
EASE_NOTE_CM = 1.0
EASE_NOTE_FRACTION = 0.03
PANEL_MAX_M = 4.0
GARMENT_MIN_M = 0.10
PANEL_MIN_M = 0.005
PANEL_NOTE_M = 0.02

_BLOCK = 256  # rows of the segment-pair test at a time: (256, m) arrays whatever the outline's size


def validate(pattern, *, gathers=False):
    """Check ``pattern``; return warnings, raise on what cannot be sewn.

    Parameters
    ----------
    pattern : model.Pattern
        As a reader built it (panels in metres).
    gathers : bool
        Take seams whose edges differ beyond easing as gathered on purpose: warned, not refused.

    Returns
    -------
    list of str
        One line each: notable seam ease, very small panels.

    Raises
    ------
    InputError
        One line naming the file, the panel and the edge, and the fix: an open loop, a zero-length or non-finite
        edge, a self-crossing outline, a stitch naming a missing edge, an edge stitched twice or to itself, two
        stitched edges too different in length, a panel of implausible size.
    """
    source = pattern.source or "<pattern>"
    if not pattern.panels:
        raise InputError(f"{source}: the pattern has no panels; fix: give at least one closed panel outline")
    warnings = []
    for panel in pattern.panels.values():
        _check_loop(panel, source)
        warnings += _check_size(panel, source)
        _check_crossing(panel, source)
    _check_garment_size(pattern, source)
    _check_stitch_refs(pattern, source)
    warnings += _check_ease(pattern, source, gathers)
    return warnings


def _error(source, panel, edge, problem, fix):
    where = f"{source}: panel '{panel}'" + (f", edge {edge}" if edge is not None else "")
    return InputError(f"{where}: {problem}; fix: {fix}")


# ---------------------------------------------------------------------- one panel
def _check_loop(panel, source):
    """Closed loop, finite, no zero-length edge."""
    n_edges = len(panel.edges)
    if n_edges < 2:
        raise _error(source, panel.name, None, f"the outline has {n_edges} edge(s)",
                     "close the outline with at least two edges")
    vertices = np.asarray(panel.vertices, float)
    for i, edge in enumerate(panel.edges):
        if not (0 <= edge.start < len(vertices) and 0 <= edge.end < len(vertices)):
            raise _error(source, panel.name, i, f"vertex index out of range ({edge.start}, {edge.end})",
                         f"use vertices 0 to {len(vertices) - 1}")
        points = np.array([vertices[edge.start], vertices[edge.end], *edge.controls], float)
        if not np.isfinite(points).all():
            raise _error(source, panel.name, i, "a point of the edge is not finite", "give finite coordinates")
        following = panel.edges[(i + 1) % n_edges]
        gap = float(np.linalg.norm(vertices[edge.end] - vertices[following.start]))
        if edge.end != following.start and gap > CLOSE_M:
            raise _error(source, panel.name, i, f"open loop: the edge ends {gap * 100:.2f} cm from where edge "
                         f"{(i + 1) % n_edges} starts", "make each edge end at the next edge's start vertex")
        length = panel.edge_length(i)
        if length < CLOSE_M:
            raise _error(source, panel.name, i, f"zero-length edge ({length * 1000:.3f} mm)",
                         "remove the edge or move its end vertex")


def _polygon(panel):
    """The outline as a closed polygon (m, 2) and the edge each of its segments belongs to (m,)."""
    pieces, owner = [], []
    for i, edge in enumerate(panel.edges):
        # chords of about a millimetre or more, so that two chords of one tiny curve never look like a touch
        k = 1 if edge.kind == "line" else int(np.clip(panel.edge_length(i) / 1e-3, 2, CURVE_SEGMENTS))
        pieces.append(panel.edge_points(i, np.arange(k) / k))
        owner += [i] * k
    return np.concatenate(pieces), np.array(owner)


def _check_size(panel, source):
    poly, _ = _polygon(panel)
    size = float(np.ptp(poly, axis=0).max())
    if size > PANEL_MAX_M:
        raise _error(source, panel.name, None, f"the panel is {size:.1f} m across",
                     "check the file's units (GarmentCode: properties.units_in_meter)")
    if size < PANEL_MIN_M:
        raise _error(source, panel.name, None, f"the panel is {size * 1000:.2f} mm across",
                     "check the file's units (GarmentCode: properties.units_in_meter)")
    if size < PANEL_NOTE_M:
        return [f"{source}: panel '{panel.name}' is only {size * 100:.1f} cm across; check the units"]
    return []


def _check_garment_size(pattern, source):
    sizes = {name: float(np.ptp(_polygon(p)[0], axis=0).max()) for name, p in pattern.panels.items()}
    largest = max(sizes, key=sizes.get)
    if sizes[largest] < GARMENT_MIN_M:
        raise _error(source, largest, None, f"the largest panel is {sizes[largest] * 100:.1f} cm across: "
                     "no garment is that small", "check the file's units (GarmentCode: properties.units_in_meter)")


def _check_crossing(panel, source):
    poly, owner = _polygon(panel)
    pair = _first_crossing(poly)
    if pair is not None:
        a, b = sorted((int(owner[pair[0]]), int(owner[pair[1]])))
        what = f"crosses or touches edge {b}" if a != b else "crosses or touches itself"
        raise _error(source, panel.name, a, f"the outline is self-crossing: the edge {what}",
                     "move the vertices so the outline is a simple closed loop")


def _first_crossing(poly):
    """A pair (i, j) of segments of the closed polygon ``poly`` that cross, touch or fold back; None if none.

    Segment k runs from ``poly[k]`` to ``poly[k + 1]`` (cyclic). Segments sharing a corner are only checked for
    folding back (the second running back along the first).
    """
    m = len(poly)
    d = np.roll(poly, -1, axis=0) - poly
    length2 = np.maximum((d * d).sum(axis=1), 1e-300)
    # folding back: consecutive segments antiparallel and collinear
    nxt = np.roll(d, -1, axis=0)
    cross_next = d[:, 0] * nxt[:, 1] - d[:, 1] * nxt[:, 0]
    dot_next = (d * nxt).sum(axis=1)
    fold = np.flatnonzero((dot_next < 0) & (np.abs(cross_next) <= 1e-9 * length2))
    if len(fold):
        return int(fold[0]), int((fold[0] + 1) % m)
    idx = np.arange(m)
    for lo in range(0, m, _BLOCK):
        rows = idx[lo:lo + _BLOCK]
        # o_p[r, s]: side of point r (and r + 1) of the block to segment s; dist_p: distance to it
        o_p, dist_p = _side_and_distance(poly[rows], poly, d, length2)
        o_q, dist_q = _side_and_distance(poly[(rows + 1) % m], poly, d, length2)
        # the other way: every point against the block's segments, transposed to (row, s)
        o_s, dist_s = _side_and_distance(poly, poly[rows], d[rows], length2[rows])
        o_t, dist_t = _side_and_distance(np.roll(poly, -1, axis=0), poly[rows], d[rows], length2[rows])
        crossing = (o_p * o_q < 0) & (o_s.T * o_t.T < 0)
        near = np.minimum(np.minimum(dist_p, dist_q), np.minimum(dist_s.T, dist_t.T)) < TOUCH_M
        sep = (idx[None, :] - rows[:, None]) % m
        bad = (crossing | near) & (sep > 1) & (sep < m - 1)
        hit = np.argwhere(bad)
        if len(hit):
            return int(rows[hit[0, 0]]), int(hit[0, 1])
    return None


def _side_and_distance(points, starts, d, length2):
    """For points (k, 2) against segments (starts (s, 2), directions d (s, 2)): the side (cross product, (k, s))
    and the distance to the segment (k, s)."""
    w = points[:, None, :] - starts[None, :, :]
    side = d[None, :, 0] * w[..., 1] - d[None, :, 1] * w[..., 0]
    t = np.clip((w * d[None]).sum(axis=-1) / length2[None], 0.0, 1.0)
    dist = np.linalg.norm(w - t[..., None] * d[None], axis=-1)
    return side, dist


# ---------------------------------------------------------------------- stitches
def _check_stitch_refs(pattern, source):
    """Every side names an existing edge; no edge is in two stitches or stitched to itself."""
    seen = {}
    for k, stitch in enumerate(pattern.stitches):
        for ref in (stitch.a, stitch.b):
            panel = pattern.panels.get(ref.panel)
            if panel is None:
                raise _error(source, ref.panel, ref.edge, f"stitch {k} names a panel the pattern does not have",
                             "name an existing panel")
            if not 0 <= ref.edge < len(panel.edges):
                raise _error(source, ref.panel, ref.edge, f"stitch {k} names an edge the panel does not have "
                             f"(edges 0 to {len(panel.edges) - 1})", "name an existing edge")
        if stitch.a == stitch.b:
            raise _error(source, stitch.a.panel, stitch.a.edge, f"stitch {k} sews the edge to itself",
                         "sew it to another edge")
        for ref in (stitch.a, stitch.b):
            if ref in seen:
                raise _error(source, ref.panel, ref.edge, f"the edge is stitched twice (stitches {seen[ref]} "
                             f"and {k})", "keep one of the two stitches or split the edge")
            seen[ref] = k


def _check_ease(pattern, source, gathers):
    """Refuse seams whose edges differ by more than easing can take (unless ``gathers``); list the notable ones."""
    warnings = []
    for k, stitch in enumerate(pattern.stitches):
        la, lb = pattern.edge_length(stitch.a), pattern.edge_length(stitch.b)
        long_, short = max(la, lb), min(la, lb)
        diff_cm = (long_ - short) * 100
        sides = (f"stitch {k}: edge {stitch.a.edge} ({la * 100:.2f} cm) and panel '{stitch.b.panel}' edge "
                 f"{stitch.b.edge} ({lb * 100:.2f} cm) differ by {diff_cm:.2f} cm")
        too_far = diff_cm > EASE_ERROR_CM or (diff_cm > EASE_NOTE_CM and long_ > EASE_RATIO_ERROR * short)
        if too_far and not gathers:
            raise _error(source, stitch.a.panel, stitch.a.edge, sides + ", more than a seam can ease "
                         f"(limit {EASE_ERROR_CM:g} cm, or {EASE_RATIO_ERROR:g} to 1)",
                         "stitch edges of matching length or split the longer edge (a gather on purpose: allow "
                         "gathers)")
        if diff_cm > EASE_NOTE_CM and diff_cm > EASE_NOTE_FRACTION * long_ * 100:
            how = "gathered beyond easing" if too_far else "eased or gathered"
            warnings.append(f"{source}: panel '{stitch.a.panel}', {sides}: {how} "
                            f"({diff_cm / (long_ * 100):.0%} of the longer edge)")
    return warnings
