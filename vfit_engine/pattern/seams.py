"""The seams sidecar: which stretches of which DXF pieces' outlines are sewn together (DXF-AAMA carries no seams).

A small JSON file beside the DXF (its format is in ``docs/pattern-formats.md``)::

    {"format": "vfit-seams", "version": 1,
     "seams": [{"a": {"piece": "front", "from": {"turn": 0}, "to": {"turn": 1}},
                "b": {"piece": "back", "from": {"notch": 2}, "to": {"xy": [310.0, 20.5]}, "backward": true}}]}

Each side names a stretch of a piece's outline: from its point ``from`` to its point ``to``, walking the
outline in its own direction (in the file's order of points), or against it with ``"backward": true``. A point
is a turn point or a notch by index (in the file's order, counting only those on the outline) or coordinates
``xy`` in the piece's frame in the DXF's units, snapped onto the outline when within ``SNAP_M``. The seam sews
``a.from`` to ``b.from`` and ``a.to`` to ``b.to``. Optional: ``"right_wrong": true`` (a right side sewn to a
wrong side), ``"opposed": null`` (the file does not say how the two run; the placement decides).

This module resolves those points to positions along the outlines (:class:`Outline`); ``dxf_aama`` splits the
outlines into edges there and makes the stitches.
"""

import json
from dataclasses import dataclass

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.io.atomic import atomic_write

#: A point given by coordinates snaps onto the outline when it is within this distance of it (m): a digitiser's
#: or a hand's error, far below a seam allowance (1 cm), so a point on the cut line is refused for a sew line.
SNAP_M = 0.002
#: A point this close along the outline to one of the outline's own points is taken as that point (m): no
#: edge of a fraction of a millimetre is made beside a corner.
MERGE_M = 0.0005
FORMAT = "vfit-seams"


@dataclass
class Outline:
    """A piece's closed outline as read from the DXF, in metres of the pattern.

    ``points`` (m, 2): the outline's points in its own direction, the first not repeated at the end.
    ``turns`` (t,) and ``notches`` (k,): positions along the outline (m from ``points[0]``) of its turn points
    and notches, in the file's order.
    """

    name: str
    points: np.ndarray
    turns: np.ndarray
    notches: np.ndarray

    def cumulative(self):
        """Position (m) of each point along the outline, and the closed outline's length as a last entry."""
        closed = np.vstack([self.points, self.points[:1]])
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])

    @property
    def length(self):
        return float(self.cumulative()[-1])

    def project(self, xy):
        """(position along the outline (m), distance of ``xy`` from it (m)) of the nearest point of the outline.

        A position within ``MERGE_M`` of one of the outline's points is moved onto it.
        """
        a = self.points
        b = np.roll(a, -1, axis=0)
        d = b - a
        seg2 = np.maximum((d * d).sum(axis=1), 1e-300)
        t = np.clip(((np.asarray(xy, float) - a) * d).sum(axis=1) / seg2, 0.0, 1.0)
        foot = a + t[:, None] * d
        dist = np.linalg.norm(foot - xy, axis=1)
        k = int(np.argmin(dist))
        cum = self.cumulative()
        pos = cum[k] + t[k] * np.sqrt(seg2[k])
        near = np.abs(cum - pos)
        j = int(np.argmin(near))
        if near[j] <= MERGE_M:
            pos = cum[j]
        return float(pos % cum[-1]), float(dist[k])

    def point_at(self, pos):
        """The outline's point at position ``pos`` (m along it): (2,)."""
        cum = self.cumulative()
        closed = np.vstack([self.points, self.points[:1]])
        pos = float(pos) % cum[-1]
        return np.array([np.interp(pos, cum, closed[:, 0]), np.interp(pos, cum, closed[:, 1])])


@dataclass(frozen=True)
class Side:
    """One side of a seam: the stretch of ``piece``'s outline from position ``start`` to ``end`` (m), walked in
    the outline's direction (so it may pass the outline's first point)."""

    piece: str
    start: float
    end: float


@dataclass(frozen=True)
class Seam:
    a: Side
    b: Side
    opposed: bool | None
    right_wrong: bool = False


def read(path, outlines, scale):
    """Resolve the sidecar at ``path`` against the pieces read from the DXF.

    Parameters
    ----------
    path : str or Path
    outlines : dict of str -> Outline
        The pieces by name.
    scale : float
        Metres per unit of the DXF (for points given as coordinates).

    Returns
    -------
    list of Seam
        Sides as positions along the outlines; ``opposed`` is True when exactly one side is walked backward.
    """
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except OSError as exc:
        raise InputError(f"cannot read seams file {path}: {exc.strerror or exc}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a JSON seams file ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("seams"), list):
        raise InputError(f"{path}: a seams file is a JSON object with a list \"seams\" (see docs/pattern-formats.md)")
    seams = []
    for k, seam in enumerate(data["seams"]):
        where = f"{path}: seam {k}"
        if not isinstance(seam, dict) or not isinstance(seam.get("a"), dict) or not isinstance(seam.get("b"), dict):
            raise InputError(f"{where}: give its two sides as objects \"a\" and \"b\"")
        a, back_a = _side(seam["a"], f"{where} side a", outlines, scale)
        b, back_b = _side(seam["b"], f"{where} side b", outlines, scale)
        opposed = seam["opposed"] if "opposed" in seam else back_a != back_b
        if opposed not in (None, True, False):
            raise InputError(f"{where}: \"opposed\" is true, false or null, not {opposed!r}")
        seams.append(Seam(a, b, opposed, bool(seam.get("right_wrong", False))))
    return seams


def _side(side, where, outlines, scale):
    """(Side, backward) of one side of a seam."""
    name = side.get("piece")
    if name not in outlines:
        raise InputError(f"{where}: piece {name!r} is not in the DXF (its pieces: {', '.join(map(repr, outlines))})")
    outline = outlines[name]
    ends = [_position(side.get(key), f"{where} ({name!r}) \"{key}\"", outline, scale) for key in ("from", "to")]
    backward = side.get("backward", False)
    if backward not in (True, False):
        raise InputError(f"{where}: \"backward\" is true or false, not {backward!r}")
    if abs(ends[0] - ends[1]) <= MERGE_M or outline.length - abs(ends[0] - ends[1]) <= MERGE_M:
        raise InputError(f"{where} ({name!r}): \"from\" and \"to\" are the same point of the outline, an empty "
                         "edge; name two different points")
    start, end = (ends[1], ends[0]) if backward else (ends[0], ends[1])
    return Side(name, start, end), backward


def _position(point, where, outline, scale):
    """Position along ``outline`` (m) of a sidecar point: {"turn": i}, {"notch": i} or {"xy": [x, y]}."""
    if not isinstance(point, dict) or len(point) != 1:
        raise InputError(f"{where}: a point is {{\"turn\": i}}, {{\"notch\": i}} or {{\"xy\": [x, y]}}, "
                         f"not {point!r}")
    (kind, value), = point.items()
    if kind in ("turn", "notch"):
        table = outline.turns if kind == "turn" else outline.notches
        if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < len(table):
            raise InputError(f"{where}: no {kind} {value!r} on this piece (it has {len(table)}, numbered from 0)")
        return float(table[value])
    if kind == "xy":
        try:
            xy = np.asarray(value, float).reshape(2) * scale
        except (TypeError, ValueError):
            raise InputError(f"{where}: \"xy\" is two numbers [x, y] in the DXF's units, not {value!r}") from None
        if not np.isfinite(xy).all():
            raise InputError(f"{where}: \"xy\" {value!r} is not finite")
        pos, dist = outline.project(xy)
        if dist > SNAP_M:
            raise InputError(f"{where}: the point {value} is {dist * 1000:.1f} mm off the piece's outline (at most "
                             f"{SNAP_M * 1000:.0f} mm): give a point on the outline (the sew line when there is one)")
        return pos
    raise InputError(f"{where}: unknown point kind {kind!r} (turn, notch or xy)")


def write(pattern, path):
    """Write the sidecar for ``pattern``'s stitches, by turn point: those ``dxf_aama.write`` writes, turn point
    ``k`` of a piece being the start of its edge ``k``.

    A stitch whose edges run against each other (``opposed``) has its side b walked backward; one whose
    direction is unknown says ``"opposed": null``.
    """
    seams = []
    for st in pattern.stitches:
        seam = {"a": _write_side(pattern, st.a, False), "b": _write_side(pattern, st.b, bool(st.opposed))}
        if st.opposed is None:
            seam["opposed"] = None
        if st.right_wrong:
            seam["right_wrong"] = True
        seams.append(seam)
    head = json.dumps({"format": FORMAT, "version": 1, "source": str(pattern.source)})[:-1]
    with atomic_write(path) as f:  # one seam a line: a file to read and edit by hand
        f.write(head + ', "seams": [\n' + ",\n".join(" " + json.dumps(s) for s in seams) + "\n]}\n")


def _write_side(pattern, ref, backward):
    n = len(pattern.panels[ref.panel].edges)
    ends = [ref.edge, (ref.edge + 1) % n]
    if backward:
        ends.reverse()
    side = {"piece": ref.panel, "from": {"turn": ends[0]}, "to": {"turn": ends[1]}}
    if backward:
        side["backward"] = True
    return side
