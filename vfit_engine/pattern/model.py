"""A sewing pattern as read from its file: panels (flat outlines in metres), their placement, and the stitches.

Every reader (GarmentCode JSON, DXF-AAMA) builds these objects and every later stage (validation, meshing,
placement, export, drawing) reads them; nothing downstream knows which file format a pattern came from.

Frames. A panel's outline lives in its own 2D frame (x, y in metres of the pattern). ``translation`` (m) and
``rotation`` (XYZ Euler angles, degrees, applied as R = Rz @ Ry @ Rx as GarmentCode does) put that plane (z = 0)
into the pattern's 3D frame; ``Pattern.frame`` says which body that frame was made for, so placement can map it
onto vfit's body, or arrange the panels itself when the frame is unknown.
"""

from dataclasses import dataclass, field

import numpy as np

from . import curves


@dataclass(frozen=True)
class Edge:
    """One edge of a panel's closed outline: from vertex ``start`` to vertex ``end`` along a curve.

    ``controls`` are absolute 2D points in the panel frame (m): one for a quadratic Bezier, two for a cubic, the
    arc's midpoint for a circle, none for a line. ``label`` is the pattern's own name for the edge, if any.
    """

    start: int
    end: int
    kind: str = "line"
    controls: tuple = ()
    label: str | None = None


@dataclass(frozen=True)
class EdgeRef:
    panel: str
    edge: int


@dataclass(frozen=True)
class Stitch:
    """Two panel edges sewn together.

    ``opposed``: True when ``b`` runs against ``a`` (b's end meets a's start: two panels cut face up and seamed
    edge to edge), False when they run the same way, None when the file does not say and the panels' placement
    must decide. ``right_wrong`` is GarmentCode's flag for a seam joining a right side to a wrong side.
    """

    a: EdgeRef
    b: EdgeRef
    opposed: bool | None = None
    right_wrong: bool = False


@dataclass
class Panel:
    """A flat piece of cloth: vertices (n, 2) in metres of the pattern and the closed loop of edges over them."""

    name: str
    vertices: np.ndarray
    edges: list
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    label: str | None = None
    grain: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0]))  # warp direction in the panel frame
    notches: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    internal_lines: list = field(default_factory=list)  # polylines (k, 2), drawn and exported, not sewn

    def edge_ends(self, i):
        e = self.edges[i]
        return self.vertices[e.start], self.vertices[e.end]

    def edge_length(self, i):
        """Length of edge ``i`` along its curve, metres."""
        e = self.edges[i]
        return curves.length(e.kind, self.edge_ends(i), e.controls)

    def edge_points(self, i, s):
        """Points at arc-length fractions ``s`` of edge ``i``, from its start to its end: (len(s), 2) metres."""
        e = self.edges[i]
        return curves.sample(e.kind, self.edge_ends(i), e.controls, s)

    def outline(self, per_edge=32):
        """The closed outline as a polygon (m, 2), each edge's end left to the next edge's start."""
        s = np.linspace(0.0, 1.0, per_edge + 1)[:-1]
        return np.concatenate([self.edge_points(i, s) for i in range(len(self.edges))])

    def rotation_matrix(self):
        """R = Rz @ Ry @ Rx of ``rotation`` (degrees): panel frame to pattern frame, before ``translation``."""
        rx, ry, rz = np.radians(self.rotation)
        cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
        Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        return Rz @ Ry @ Rx

    def to_3d(self, xy):
        """Panel-frame points (k, 2) to the pattern's 3D frame (k, 3), metres."""
        xy = np.asarray(xy, float)
        p = np.column_stack([xy, np.zeros(len(xy))])
        return p @ self.rotation_matrix().T + self.translation


@dataclass
class Pattern:
    """Panels by name (in the file's order), the stitches, and where the pattern came from.

    ``frame``: "garmentcode" (GarmentCode's body frame: Y up, floor at y = 0), "gpg" (Garment-Pattern-Generator's
    T-pose SMPL frame) or None (no placement in the file: DXF, or translation/rotation absent).
    ``body`` is the body the pattern names (measurements in cm), when it names one. ``warnings``: what a reader
    assumed for the user to check (a missing grain line taken as vertical), one line each.
    """

    panels: dict
    stitches: list
    source: str = ""
    units_in_meter: float = 1.0
    frame: str | None = None
    body: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    def edge_length(self, ref):
        return self.panels[ref.panel].edge_length(ref.edge)
