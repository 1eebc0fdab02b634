"""Read a GarmentCode or Garment-Pattern-Generator (GPG) ``specification`` JSON into a ``model.Pattern``.

Both projects (MIT, M. Korosteleva) write one dialect: ``{"pattern": {"panels", "stitches", "panel_order"},
"properties": {"units_in_meter", "curvature_coords", ...}, "parameters", ...}`` (a bare ``{"panels", "stitches"}``
is read too). Lengths are in pattern units (``units_in_meter`` of them make a metre: GarmentCode writes 100, the
GPG templates 300); everything is converted to metres here, once.

Curvature of an edge from ``start`` to ``end`` (pattern units, ``d = end - start``, ``perp = [-d_y, d_x]``, the
edge turned a quarter counter-clockwise, as long as the edge):

- legacy ``"curvature": [x, y]``: one quadratic Bezier control point;
- ``{"type": "quadratic", "params": [[x, y]]}``, ``{"type": "cubic", "params": [[x0, y0], [x1, y1]]}``;
- with ``curvature_coords: "relative"`` (the default) a control point is ``start + x d + y perp``; with
  ``"absolute"`` it is a point of the panel frame;
- ``{"type": "circle", "params": [radius, large_arc, right]}`` (SVG-like, the radius in pattern units): the arc's
  midpoint is at relative ``(0.5, cy)``, ``cy = (r -+ sqrt(r^2 - c^2 / 4)) / c`` (small / large arc, c the chord),
  negated when ``right``: GarmentCode's ``CircleEdgeFactory.from_points_radius``. The model keeps that midpoint.

Stitches are lists of two ``{"panel", "edge"}`` sides, optionally followed by the string ``"right_wrong"``
(GarmentCode's flag for a seam joining a right side to a wrong side); other extra strings are ignored. Neither
format says which way the two edges run against each other, so ``Stitch.opposed`` is None: placement decides.

The frame (``Pattern.frame``): GarmentCode's pygarment writes ``properties.normalized_edge_loops`` into every
specification and leaves ``parameters`` empty; GPG's templates lack that key and carry their parametric template
(``parameters`` whose entries have ``influence`` lists). So a file is "gpg" when it has GPG's parameters or lacks
``normalized_edge_loops``, else "garmentcode" (floor at y = 0, Y up); None when no panel has a ``translation``.
The shared files agree: the GarmentCode panels sit at y = 0.11 to 1.11 m above the floor, the GPG skirt's at
y = -0.35 m (SMPL's origin is at the pelvis).

Nothing here validates the pattern's geometry (closed loops, crossings, seam lengths): ``validate.validate`` does,
for every format. This module refuses only what cannot be read at all.
"""

import json
import math
from pathlib import Path

import numpy as np
import yaml

from ..errors import InputError
from . import model

_DEFAULT_UNITS = 100.0  # GarmentCode's default when a file does not say (pygarment's template: cm)
_BODY_KEYS = ("height", "bust", "waist", "hips")  # a YAML beside the file is a GarmentCode body if it has these


class _Where:
    """Where in the file a value is, for one-line errors: file, panel, edge (or stitch)."""

    def __init__(self, path, panel=None, edge=None, stitch=None):
        self.path, self.panel, self.edge, self.stitch = path, panel, edge, stitch

    def error(self, problem, fix):
        parts = [str(self.path)]
        if self.stitch is not None:
            parts.append(f"stitch {self.stitch}")
        if self.panel is not None:
            parts.append(f"panel '{self.panel}'")
        if self.edge is not None:
            parts.append(f"edge {self.edge}")
        return InputError(f"{': '.join(parts)}: {problem}; fix: {fix}")


def read(path):
    """Read a GarmentCode / GPG specification JSON.

    Parameters
    ----------
    path : str or Path
        The ``.json`` file.

    Returns
    -------
    model.Pattern
        Panels in the file's order (``panel_order`` when given), in metres; stitches; ``units_in_meter``;
        ``frame`` ("garmentcode", "gpg" or None); ``body`` (GarmentCode measurements in cm from a body YAML
        beside the file, for a "garmentcode" pattern; else empty).

    Raises
    ------
    InputError
        Unreadable JSON, or a field that cannot be read (named by file, panel and edge or stitch).
    """
    path = Path(path)
    where = _Where(path)
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise where.error(f"not a readable JSON file ({str(exc).splitlines()[0]})",
                          "give a GarmentCode specification .json") from None
    if not isinstance(spec, dict):
        raise where.error("the top level is not an object", "give a GarmentCode specification .json")
    pattern = spec.get("pattern", spec)
    props = spec.get("properties", pattern.get("properties", {})) if isinstance(pattern, dict) else {}
    if not isinstance(pattern, dict) or not isinstance(pattern.get("panels"), dict) or not pattern["panels"]:
        raise where.error("no 'panels' object", "a specification has {\"pattern\": {\"panels\": {...}}}")
    if not isinstance(props, dict):
        raise where.error("'properties' is not an object", "give properties as {\"units_in_meter\": 100, ...}")
    units = _units(props, where)
    relative = _coords(props, where)
    names = _panel_order(pattern, where)
    panels = {name: _panel(name, pattern["panels"][name], units, relative, path) for name in names}
    stitches = [_stitch(i, s, panels, path) for i, s in enumerate(_list(pattern, "stitches", where))]
    frame = _frame(spec, props, pattern)
    body = _body_beside(path) if frame == "garmentcode" else {}
    return model.Pattern(panels=panels, stitches=stitches, source=str(path), units_in_meter=units,
                         frame=frame, body=body)


# ---------------------------------------------------------------------- the file's properties
def _units(props, where):
    units = props.get("units_in_meter", _DEFAULT_UNITS)
    if isinstance(units, bool) or not isinstance(units, (int, float)) or not math.isfinite(units) or units <= 0:
        raise where.error(f"properties.units_in_meter is {units!r}",
                          "give how many pattern units make a metre (100 for cm)")
    return float(units)


def _coords(props, where):
    coords = props.get("curvature_coords", "relative")
    if coords not in ("relative", "absolute"):
        raise where.error(f"properties.curvature_coords is {coords!r}", "use \"relative\" or \"absolute\"")
    return coords == "relative"


def _list(obj, key, where):
    value = obj.get(key, [])
    if not isinstance(value, list):
        raise where.error(f"'{key}' is not a list", f"give '{key}' as a JSON list")
    return value


def _panel_order(pattern, where):
    """The file's panel order: ``panel_order`` first (when given), then any panel it leaves out, in file order."""
    panels = pattern["panels"]
    order = pattern.get("panel_order") or []
    if not isinstance(order, list):
        raise where.error("'panel_order' is not a list", "give panel_order as a list of panel names")
    for name in order:
        if name not in panels:
            raise where.error(f"panel_order names panel {name!r}, which is not in 'panels'",
                              "remove it from panel_order or add the panel")
    listed = list(dict.fromkeys(order))
    return listed + [name for name in panels if name not in listed]


def _frame(spec, props, pattern):
    """"garmentcode", "gpg" or None, by the rule in the module docstring."""
    if not any(isinstance(p, dict) and "translation" in p for p in pattern["panels"].values()):
        return None
    params = spec.get("parameters")
    gpg_params = isinstance(params, dict) and any(isinstance(p, dict) and "influence" in p for p in params.values())
    if gpg_params or "normalized_edge_loops" not in props:
        return "gpg"
    return "garmentcode"


def _body_beside(path):
    """GarmentCode body measurements (cm) from the one body YAML beside ``path``; {} when none or several."""
    found = []
    for candidate in sorted(path.parent.glob("*.y*ml")):
        try:
            data = yaml.safe_load(candidate.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, yaml.YAMLError):
            continue
        body = data.get("body") if isinstance(data, dict) else None
        if isinstance(body, dict) and all(_finite_number(body.get(k)) for k in _BODY_KEYS):
            found.append({k: float(v) for k, v in body.items() if _finite_number(v)})
    return found[0] if len(found) == 1 else {}


def _finite_number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


# ---------------------------------------------------------------------- panels
def _point(value, where, what, dim=2):
    """A finite point of ``dim`` numbers, or a one-line error naming ``what``."""
    try:
        p = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        p = None
    if p is None or p.shape != (dim,):
        raise where.error(f"{what} is {value!r}, not {dim} numbers",
                          f"give {what} as {'[x, y]' if dim == 2 else '[x, y, z]'}")
    if not np.isfinite(p).all():
        raise where.error(f"{what} is not finite ({value!r})", f"give finite numbers for {what}")
    return p


def _panel(name, spec, units, relative, path):
    where = _Where(path, panel=name)
    if not isinstance(spec, dict):
        raise where.error("the panel is not an object", "give vertices, edges, translation and rotation")
    raw = spec.get("vertices")
    if not isinstance(raw, list) or len(raw) < 3:
        raise where.error("missing vertices (a panel needs at least 3)", "give 'vertices' as a list of [x, y]")
    vertices = np.array([_point(v, where, f"vertex {i}") for i, v in enumerate(raw)])
    edges_raw = spec.get("edges")
    if not isinstance(edges_raw, list) or not edges_raw:
        raise where.error("missing edges", "give 'edges' as the closed loop of {\"endpoints\": [i, j]}")
    edges = [_edge(e, vertices, relative, units, _Where(path, panel=name, edge=i)) for i, e in enumerate(edges_raw)]
    translation = _point(spec.get("translation", [0, 0, 0]), where, "translation", 3) / units
    rotation = _point(spec.get("rotation", [0, 0, 0]), where, "rotation", 3)
    label = spec.get("label")
    return model.Panel(name=name, vertices=vertices / units, edges=edges, translation=translation,
                       rotation=rotation, label=str(label) if label is not None else None)


def _edge(spec, vertices, relative, units, where):
    """One edge, its control points converted to absolute metres."""
    if not isinstance(spec, dict):
        raise where.error("the edge is not an object", "give {\"endpoints\": [i, j]}")
    ends = spec.get("endpoints")
    n = len(vertices)
    if (not isinstance(ends, list) or len(ends) != 2
            or not all(isinstance(i, int) and not isinstance(i, bool) for i in ends)):
        raise where.error(f"endpoints is {ends!r}", "give two vertex indices [i, j]")
    if not all(0 <= i < n for i in ends):
        raise where.error(f"endpoint index out of range ({ends}; the panel has {n} vertices)",
                          f"use indices 0 to {n - 1}")
    a, b = vertices[ends[0]], vertices[ends[1]]
    kind, controls = _curvature(spec.get("curvature"), a, b, relative, where)
    label = spec.get("label")
    return model.Edge(start=ends[0], end=ends[1], kind=kind,
                      controls=tuple(tuple(float(x) for x in c / units) for c in controls),
                      label=str(label) if label is not None else None)


def _curvature(curv, a, b, relative, where):
    """(kind, absolute control points in pattern units) of an edge from ``a`` to ``b`` (pattern units)."""
    if curv is None:
        return "line", []
    if isinstance(curv, list):  # the legacy form: one quadratic control point
        return "quadratic", [_control(_point(curv, where, "curvature"), a, b, relative)]
    if not isinstance(curv, dict):
        raise where.error(f"curvature is {curv!r}", "give [x, y] or {\"type\": ..., \"params\": [...]}")
    kind, params = curv.get("type"), curv.get("params")
    if kind not in ("quadratic", "cubic", "circle"):
        raise where.error(f"unknown curvature type {kind!r}", "use quadratic, cubic or circle")
    if not isinstance(params, list):
        raise where.error(f"{kind} curvature has no 'params' list", f"give the {kind} curve's params")
    if kind == "circle":
        return "circle", [_arc_midpoint(params, a, b, where)]
    want = 1 if kind == "quadratic" else 2
    if kind == "quadratic" and len(params) == 2 and all(_finite_number(x) for x in params):
        params = [params]  # a bare [x, y]: one control point written without its list
    if len(params) != want:
        raise where.error(f"{kind} curvature has {len(params)} control points, not {want}",
                          f"give {want} control point{'s' if want > 1 else ''} [x, y]")
    return kind, [_control(_point(p, where, f"control point {k}"), a, b, relative) for k, p in enumerate(params)]


def _control(p, a, b, relative):
    """A control point in pattern units: ``a + x d + y perp`` when relative, else as given."""
    if not relative:
        return p
    d = b - a
    return a + p[0] * d + p[1] * np.array([-d[1], d[0]])


def _arc_midpoint(params, a, b, where):
    """The midpoint of the arc ``[radius, large_arc, right]`` from ``a`` to ``b`` (pattern units)."""
    if len(params) != 3 or not all(_finite_number(x) for x in params):
        raise where.error(f"circle params are {params!r}", "give [radius, large_arc (0/1), right (0/1)]")
    r, large, right = float(params[0]), bool(params[1]), bool(params[2])
    d = b - a
    c = float(np.hypot(*d))
    if c == 0.0:
        raise where.error("a circle arc whose two ends coincide", "give the arc two distinct ends")
    # GarmentCode takes a radius a hair short of half the chord as a half circle; more than that is refused
    if r < 0.5 * c * (1.0 - 1e-3):
        raise where.error(f"circle radius {r:g} is shorter than half the chord ({0.5 * c:g}, pattern units)",
                          "give a radius of at least half the distance between the edge's ends")
    h = math.sqrt(max(r * r - 0.25 * c * c, 0.0))
    cy = (r + h if large else r - h) / c
    if right:
        cy = -cy
    return a + 0.5 * d + cy * np.array([-d[1], d[0]])


# ---------------------------------------------------------------------- stitches
def _stitch(index, spec, panels, path):
    where = _Where(path, stitch=index)
    if not isinstance(spec, list):
        raise where.error(f"the stitch is {type(spec).__name__}, not a list",
                          "give [{\"panel\": ..., \"edge\": ...}, {\"panel\": ..., \"edge\": ...}]")
    sides = [s for s in spec if isinstance(s, dict)]
    if len(sides) != 2:
        raise where.error(f"the stitch has {len(sides)} sides, not 2", "give exactly two {panel, edge} sides")
    refs = [_side(side, panels, path, index) for side in sides]
    return model.Stitch(a=refs[0], b=refs[1], opposed=None, right_wrong="right_wrong" in spec)


def _side(side, panels, path, index):
    name, edge = side.get("panel"), side.get("edge")
    where = _Where(path, stitch=index, panel=name, edge=edge)
    if name not in panels:
        raise where.error(f"names panel {name!r}, which is not in the pattern", "name one of " + ", ".join(panels))
    count = len(panels[name].edges)
    if isinstance(edge, bool) or not isinstance(edge, int) or not 0 <= edge < count:
        raise where.error(f"names edge {edge!r}; the panel has edges 0 to {count - 1}", "name an existing edge")
    return model.EdgeRef(panel=name, edge=edge)
