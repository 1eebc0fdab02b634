"""Panels to 3D on vfit's body: the pattern's own placement mapped onto it, or each panel wrapped round its part.

vfit's frame: metres, Y up, +Z the body's front, +X the body's left, soles at the body's lowest vertex (about
-0.82 m on the default bodies), arms in MakeHuman's A-pose (the upper arm about 48 degrees below horizontal).

Frame mapping (``Placement.method[panel] == "frame"``), for a pattern made for a body in the same pose family:

* ``garmentcode``: GarmentCode's frame is the same up to its floor and its body: metres (the reader converts),
  Y up, floor at y = 0, +Z front, +X the body's left, the body centred on x = z = 0, arms about 45 degrees
  down. A point of ``Panel.to_3d`` goes to vfit's body by
  - height: piecewise linear through the landmarks (floor, crotch, waist, armpit, shoulder line, top of the
    head) of the body the pattern names and of vfit's body, extended beyond both ends with the end pieces'
    slopes. The pattern body's landmarks follow GarmentCode's own rules (``waist = height - head_l -
    waist_line``, ``crotch = waist - hips_line - crotch_hip_diff``, ``armpit = height - head_l -
    armscye_depth``, shoulder line ``height - head_l``); vfit's come from its horizontal sections
    (:func:`vfit_engine.body.levels.body_levels`) and, for the shoulder line, the base of the neck bone.
  - widths: the horizontal offset from the body's vertical axis is scaled by ``s`` = vfit's torso girth over
    the pattern body's girth (bust, waist, hips) at the same landmark, linear in height between them and
    constant above the bust and below the hips; the axis moves to vfit's torso centre at that height.
  The mapping bends panels a little (it is not rigid) when the two bodies differ; the sewing pulls them to
  their flat lengths.

Automatic arrangement (``"wrapped: <part>"``), for any other frame (Garment-Pattern-Generator's T-pose, DXF
with no placement) or when asked: each panel is bent isometrically round a cylinder round the body part it
belongs to, as CLO's arrangement points on bounding cylinders. The part comes from ``mapping`` {panel: slot},
else from keywords in the panel's name, then its label, then the pattern's file name (the keyword table of
:mod:`vfit_engine.pattern.panel_slots`; e.g. ``left_ftorso`` = torso, front, left half; ``rbsleeve`` = right
sleeve, back; ``skirt_back``); a panel with no keyword that is sewn to a sleeve is a torso panel.

* A ring is the panels of one kind round one part. Its axis: the torso's vertical axis (torso, skirt,
  waistband, collar) or the principal axis of the arm or leg. Its radius: the part's largest distance from
  the axis over the ring's height, plus ``clearance``, and never less than the ring's panels' widths summed
  over 2 pi (so that the panels of a ring do not overlap).
* A panel's "up" is its +y (tailors draw with the grain vertical), except a sleeve's: towards its edges sewn
  to a non-sleeve panel (the cap), else its grain line. Up runs along the axis towards the part's top.
* Its top sits at the part's top landmark: the shoulder line (torso, sleeves: the top of the arm), the waist
  (skirts, trousers, the waistband's middle), the shoulder line for a collar's bottom, the wrist for a cuff's
  bottom (round the forearm).
* Round the axis, a front panel is centred on the front, a back on the back, a side panel on its side; a
  left or right half starts at the centre line and runs to its side. The panel's +x runs towards the body's
  left on front and back panels alike (GarmentCode's and Garment-Pattern-Generator's convention: a back panel
  is drawn as seen from the front), towards the back on the left side and the front on the right side.

* Which face a panel shows (its +x round one way or the other) is a drawing convention, so each panel shows
  the face that brings its stitched edges' ends nearest their partners' (:func:`_turned_faces`);
  ``Placement.opposed`` then tells, for a stitch whose file does not say, whether its edges run against each
  other as placed.

Both ways end the same: a point closer to the body than ``clearance`` (or inside it) is pushed out along the
body's normal at its closest point to ``clearance`` (``Placement.pushed`` counts them per panel).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.pattern.panel_slots import resolve_slots, slot_kind
from vfit_engine.pattern.placement_body import BodyParts

#: The body GarmentCode's shared patterns were made for (``garmentcode_body_mean_all.yaml``, cm): the one used
#: when a GarmentCode pattern names no body.
GARMENTCODE_MEAN_BODY = dict(height=171.99, head_l=26.3262, waist_line=36.8913, hips_line=23.4837,
                             crotch_hip_diff=8.81363, armscye_depth=12.8679, bust_line=25.6947,
                             bust=99.8407, waist=84.3338, hips=103.478)

#: Frames whose panels are placed by mapping their frame (same pose family as vfit's A-pose).
MAPPED_FRAMES = ("garmentcode",)

#: An arm's top is the highest arm vertex (along the arm's axis) within this distance (m) of the axis.
ARM_TOP_RADIUS = 0.04
#: Fraction of the arm's length, from its top, whose vertices give a sleeve's axis (the upper arm).
UPPER_ARM = 0.45
#: Fraction of the leg's length, from the sole, left out of its ring (the foot sticks out forwards).
FOOT = 0.1
#: Fraction of the arm's length (hand included), from its top, where the wrist is: a cuff's bottom.
WRIST_AT = 0.72
#: A ring's radius is at least its panels' widths summed over 2 pi times this (a small gap between them).
RING_SLACK = 1.05


# ---------------------------------------------------------------------------------------- frame mapping
def garmentcode_landmarks(body_cm):
    """Landmark heights (m) of a GarmentCode body (its measurements, cm) and its girths (m) at them."""
    b = {**GARMENTCODE_MEAN_BODY, **{k: float(v) for k, v in (body_cm or {}).items()
                                      if k in GARMENTCODE_MEAN_BODY}}
    shoulder = b["height"] - b["head_l"]
    waist = shoulder - b["waist_line"]
    hips = waist - b["hips_line"]
    heights = dict(floor=0.0, crotch=hips - b["crotch_hip_diff"], waist=waist, armpit=shoulder - b["armscye_depth"],
                   shoulder=shoulder, top=b["height"])
    girths = dict(bust=(shoulder - b["bust_line"], b["bust"]), waist=(waist, b["waist"]), hips=(hips, b["hips"]))
    return ({k: v / 100.0 for k, v in heights.items()},
            {k: (y / 100.0, g / 100.0) for k, (y, g) in girths.items()})


def _piecewise(x, xs, ys):
    """Piecewise linear through (xs, ys) (xs increasing), extended with the end pieces' slopes."""
    x = np.asarray(x, dtype=np.float64)
    y = np.interp(x, xs, ys)
    lo, hi = x < xs[0], x > xs[-1]
    y[lo] = ys[0] + (x[lo] - xs[0]) * (ys[1] - ys[0]) / (xs[1] - xs[0])
    y[hi] = ys[-1] + (x[hi] - xs[-1]) * (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
    return y


class FrameMap:
    """The map from a pattern body's frame (metres, Y up, floor at 0, +Z front, axis x = z = 0) to vfit's.

    Parameters
    ----------
    body : BodyParts
    heights : dict
        The pattern body's landmark heights (m): ``floor``, ``crotch``, ``waist``, ``armpit``, ``shoulder``,
        ``top``.
    girths : dict
        name -> (height m, girth m) of the pattern body at its bust, waist and hips.
    """

    LANDMARKS = ("floor", "crotch", "waist", "armpit", "shoulder", "top")

    def __init__(self, body, heights, girths):
        self.src = np.array([heights[k] for k in self.LANDMARKS])
        self.dst = np.array([body.levels[k] for k in self.LANDMARKS])
        if np.any(np.diff(self.src) <= 0) or np.any(np.diff(self.dst) <= 0):
            raise InputError("the pattern body's landmarks (floor, crotch, waist, armpit, shoulder, top) are not "
                             "in order; check its measurements")
        rows = sorted(girths.values())
        self.girth_y = np.array([y for y, _ in rows])
        scale, centre = [], []
        for y, g in rows:
            g_vfit, c = body.girth(float(self.height(np.array([y]))[0]))
            scale.append(g_vfit / g)
            centre.append(c)
        self.scale = np.array(scale)
        self.centre = np.array(centre)

    def height(self, y):
        return _piecewise(y, self.src, self.dst)

    def __call__(self, p):
        """Pattern-frame points (k, 3) m to vfit's frame (k, 3) m."""
        p = np.asarray(p, dtype=np.float64).reshape(-1, 3)
        s = np.interp(p[:, 1], self.girth_y, self.scale)
        cx = np.interp(p[:, 1], self.girth_y, self.centre[:, 0])
        cz = np.interp(p[:, 1], self.girth_y, self.centre[:, 1])
        return np.column_stack([cx + s * p[:, 0], self.height(p[:, 1]), cz + s * p[:, 2]])


# ---------------------------------------------------------------------------------------- wrapping
def panel_up(pattern, name, slot):
    """Unit 2D direction in the panel's frame that runs up the part (see the module docstring)."""
    panel = pattern.panels[name]
    if slot.kind == "sleeve":
        cap = [panel.edge_points(ref.edge, np.linspace(0.0, 1.0, 9))
               for st in pattern.stitches for ref, other in ((st.a, st.b), (st.b, st.a))
               if ref.panel == name and other.panel in pattern.panels and other.panel != name
               and slot_kind(pattern, other.panel) not in ("sleeve", "cuff")]
        if cap:
            v = np.concatenate(cap).mean(0) - panel.outline().mean(0)
            if np.linalg.norm(v) > 1e-9:
                return v / np.linalg.norm(v)
        g = np.asarray(panel.grain, dtype=np.float64)
        return g / np.linalg.norm(g)
    return np.array([0.0, 1.0])


@dataclass
class Ring:
    """A cylinder round a body part: its axis (point ``origin``, unit ``up``), the unit ``front`` across it,
    the position ``top`` (m along ``up`` from ``origin``) of the part's top landmark, and ``radius`` (m)."""

    origin: np.ndarray
    up: np.ndarray
    front: np.ndarray
    top: float
    radius: float

    def side(self, side):
        """(d, t): the unit direction a panel is centred on and the one its +x runs along there."""
        left = np.cross(self.up, self.front)
        d = {"front": self.front, "back": -self.front, "left": left, "right": -left}[side]
        t = left if side in ("front", "back") else np.cross(self.up, d)
        return d, t


def _ring(body, part, kind, height, width_sum, clearance):
    """The :class:`Ring` of ``kind`` panels round ``part``; ``height`` the tallest panel's, ``width_sum`` the
    panels' widths summed (m)."""
    lv = body.levels
    if part in ("torso", "hips", "neck"):
        level = {"torso": lv["armpit"], "hips": lv["waist"], "neck": lv["shoulder"]}[part]
        _, c = body.girth(level)
        origin, up, front = np.array([c[0], 0.0, c[1]]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
        top = {"torso": lv["shoulder"], "hips": lv["waist"], "neck": lv["shoulder"] + height}[part]
        if kind == "waistband":
            top = lv["waist"] + 0.5 * height
        verts = body.part_verts(*{"torso": ("torso",), "hips": ("torso", "leg.L", "leg.R"),
                                  "neck": ("torso", "head")}[part])
    else:
        verts = body.part_verts(part)
        verts, origin, up, top = _limb_axis(verts, part, kind, height, lv["waist"])
        front = np.array([0.0, 0.0, 1.0]) - up[2] * up
        front /= np.linalg.norm(front)
    s = (verts - origin) @ up
    span = verts[(s >= top - height) & (s <= top)]
    span = span if len(span) else verts
    radial = (span - origin) - np.outer((span - origin) @ up, up)
    r_body = float(np.linalg.norm(radial, axis=1).max())
    radius = max(r_body + clearance, RING_SLACK * width_sum / (2.0 * np.pi))
    return Ring(origin, up, front, float(top), radius)


def _limb_axis(verts, part, kind, height, waist):
    """The vertices (k, 3) that size a limb's ring, its axis (origin, unit up) and its top's position on it (m).

    A sleeve's axis is the upper arm's (the forearm bends forwards, the hand further), its top where the
    axis leaves the shoulder (the skin the axis runs into, not the far end of the part's cut against the
    torso, inside the chest's reach); a cuff's is the forearm's, its bottom at the wrist; a leg's is the
    leg's without the foot, its top at the waist.
    """
    origin, up = _principal_axis(verts)
    if not part.startswith("arm"):  # the leg without its foot, which sticks out forwards
        s = (verts - origin) @ up
        verts = verts[s >= s.min() + FOOT * np.ptp(s)]
        origin, up = _principal_axis(verts)
        return verts, origin, up, (waist - origin[1]) / up[1]
    s = (verts - origin) @ up
    length = np.ptp(s)
    if kind == "cuff":
        wrist = s.max() - WRIST_AT * length
        origin, up = _principal_axis(verts[(s <= s.max() - UPPER_ARM * length) & (s >= wrist)])
        at_wrist = verts[np.abs(s - wrist) < 0.01]
        return verts, origin, up, float((at_wrist.mean(0) - origin) @ up) + height
    origin, up = _principal_axis(verts[s >= s.max() - UPPER_ARM * length])
    s = (verts - origin) @ up
    near_axis = np.linalg.norm((verts - origin) - np.outer(s, up), axis=1) < ARM_TOP_RADIUS
    return verts, origin, up, float(s[near_axis].max())


def _principal_axis(verts):
    """Centroid and unit principal direction (pointing up) of points (k, 3)."""
    origin = verts.mean(0)
    up = np.linalg.svd(verts - origin, full_matrices=False)[2][0]
    return origin, (up if up[1] > 0 else -up)


class _Wrap:
    """The isometric wrap of one panel round its ring: panel frame (k, 2) -> vfit's frame (k, 3)."""

    def __init__(self, panel, slot, up2, ring, mirror=False):
        self.rot = np.array([[up2[1], -up2[0]], [up2[0], up2[1]]])  # panel xy -> (x', y') with up2 -> +y'
        if mirror:  # the panel seen from its other face: +x' runs the other way round
            self.rot[0] *= -1.0
        self.mirror = mirror
        box = panel.outline() @ self.rot.T
        x0, x1, self.y1 = box[:, 0].min(), box[:, 0].max(), box[:, 1].max()
        # a half panel starts at the centre line and runs to its side (+x' runs towards the body's left)
        self.anchor = {"left": x0, "right": x1}.get(slot.half, 0.5 * (x0 + x1))
        self.ring = ring
        self.d, self.t = ring.side(slot.side)

    def __call__(self, xy):
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2) @ self.rot.T
        r = self.ring
        th = (p[:, 0] - self.anchor) / r.radius
        s = r.top - (self.y1 - p[:, 1])
        return (r.origin + s[:, None] * r.up + r.radius * (np.cos(th)[:, None] * self.d
                                                           + np.sin(th)[:, None] * self.t))


def _local_box(panel, up2):
    rot = np.array([[up2[1], -up2[0]], [up2[0], up2[1]]])
    box = panel.outline() @ rot.T
    return np.ptp(box[:, 0]), np.ptp(box[:, 1])


def _wraps(pattern, body, slots, clearance):
    ups = {n: panel_up(pattern, n, slots[n]) for n in pattern.panels}
    rings = {}
    for n, slot in slots.items():
        w, h = _local_box(pattern.panels[n], ups[n])
        key = (slot.kind, slot.part)
        wsum, hmax = rings.get(key, (0.0, 0.0))
        rings[key] = (wsum + w, max(hmax, h))
    built = {key: _ring(body, key[1], key[0], h, w, clearance) for key, (w, h) in rings.items()}

    faces = {n: [_Wrap(pattern.panels[n], slot, ups[n], built[(slot.kind, slot.part)], m) for m in (False, True)]
             for n, slot in slots.items()}
    return {n: faces[n][int(m)] for n, m in _turned_faces(pattern, faces).items()}


def _turned_faces(pattern, faces):
    """{panel: mirrored?}: which face each wrapped panel shows.

    Which face a panel shows is a drawing convention (Garment-Pattern-Generator draws a back sleeve mirrored, a
    back bodice not), so the panels turn over, a panel or two sewn panels at a time and the move that gains
    most first, while that brings the ends of stitched edges nearer their partners' ends (turning the first
    panel that gains anything can leave both halves of a sleeve wrong). Ends pair as a stitch says, or against
    each other when it does not say (both formats' convention: panels cut face up are seamed with their
    outlines running opposite ways).
    """
    ends = {}
    touching = {n: [] for n in faces}
    for st in pattern.stitches:
        if st.a.panel not in faces or st.b.panel not in faces:
            continue
        for r in (st.a, st.b):
            e = pattern.panels[r.panel].edges[r.edge]
            ends[r] = pattern.panels[r.panel].vertices[[e.start, e.end]]
        touching[st.a.panel].append(st)
        if st.b.panel != st.a.panel:
            touching[st.b.panel].append(st)
    mirror = {n: False for n in faces}

    def gap(move, state):
        total = 0.0
        for st in {id(st): st for n in move for st in touching[n]}.values():
            a, b = (faces[r.panel][int(state[r.panel])](ends[r]) for r in (st.a, st.b))
            total += float(np.linalg.norm(a - (b if st.opposed is False else b[::-1]), axis=1).sum())
        return total

    # a move turns one panel, or two sewn together (two sleeve halves may each lose turning alone)
    moves = {(n,) for n in faces if touching[n]}
    moves |= {tuple(sorted((st.a.panel, st.b.panel)))
              for n in faces for st in touching[n] if st.a.panel != st.b.panel}
    for _ in range(2 * len(faces)):
        gains = {m: gap(m, mirror) - gap(m, {**mirror, **{n: not mirror[n] for n in m}}) for m in moves}
        best = max(sorted(gains), key=gains.get) if gains else None
        if best is None or gains[best] <= 1e-6:
            break
        mirror.update({n: not mirror[n] for n in best})
    return mirror


# ---------------------------------------------------------------------------------------- placement
@dataclass
class Placement:
    """Where each panel of a pattern sits on vfit's body.

    Attributes
    ----------
    body : BodyParts
    clearance : float, m
    method : dict
        panel -> ``"frame"`` or ``"wrapped: <part>"`` (a :data:`SIX_PARTS`-like part: torso, hips, neck,
        arm.L, leg.R ...).
    slots : dict
        panel -> :class:`vfit_engine.pattern.panel_slots.Slot` of the wrapped panels.
    maps : dict
        panel -> callable taking panel-frame points (k, 2) m to vfit's frame (k, 3) m, before the push out.
    pushed : dict
        panel -> how many points :meth:`to_body` has pushed out of the body so far.
    """

    body: BodyParts
    clearance: float
    method: dict
    slots: dict
    maps: dict = field(repr=False)
    pushed: dict = field(default_factory=dict)

    def raw(self, panel_name, xy):
        """Panel-frame points (k, 2) m to vfit's frame (k, 3) m, before the push out of the body."""
        if panel_name not in self.maps:
            raise InputError(f"no panel {panel_name!r} in the placed pattern")
        return self.maps[panel_name](np.asarray(xy, dtype=np.float64).reshape(-1, 2))

    def opposed(self, pattern, stitch):
        """Whether the two edges of ``stitch`` run against each other as placed (b's end at a's start).

        For a stitch whose file does not say (``Stitch.opposed`` None): the pairing of their ends that puts
        them closer together in 3D, before the push out of the body.
        """
        if stitch.opposed is not None:
            return stitch.opposed
        ends = []
        for ref in (stitch.a, stitch.b):
            e = pattern.panels[ref.panel].edges[ref.edge]
            ends.append(self.raw(ref.panel, pattern.panels[ref.panel].vertices[[e.start, e.end]]))
        (a0, a1), (b0, b1) = ends
        crossed = np.linalg.norm(a0 - b1) + np.linalg.norm(a1 - b0)
        return bool(crossed < np.linalg.norm(a0 - b0) + np.linalg.norm(a1 - b1))

    def to_body(self, panel_name, xy):
        """Panel-frame points (k, 2) m to vfit's frame (k, 3) m, at least ``clearance`` off the body."""
        p, n = self.body.push_out(self.raw(panel_name, xy), self.clearance)
        self.pushed[panel_name] = self.pushed.get(panel_name, 0) + n
        return p


#: How panels start round the body (:func:`place`): auto = the frame when it can be mapped, else wrapped.
ARRANGEMENTS = ("auto", "frame", "wrap")


def place(pattern, body, mapping=None, clearance=0.01, arrange="auto"):
    """Put the panels of ``pattern`` on vfit's ``body``.

    Parameters
    ----------
    pattern : Pattern
    body : BodyParts
        ``BodyParts.from_model(model, verts)``.
    mapping : dict or None
        panel -> Slot, or text naming its part ("torso front left", "sleeve right back", "skirt left"); for
        the automatic arrangement.
    clearance : float, m
        Gap kept between the panels and the body.
    arrange : {"auto", "frame", "wrap"}
        ``auto``: the frame mapping for a frame of :data:`MAPPED_FRAMES`, else the wrap.

    Returns
    -------
    Placement

    Raises
    ------
    InputError
        ``arrange="frame"`` on a frame that cannot be mapped; a panel whose part cannot be told (wrap).
    """
    if arrange not in ARRANGEMENTS:
        raise InputError(f"arrangement {arrange!r}: expected auto, frame or wrap")
    if not (np.isfinite(clearance) and 0.0 <= clearance <= 0.2):
        raise InputError(f"clearance {clearance} m is outside 0-0.2 m")
    by_frame = pattern.frame in MAPPED_FRAMES and arrange != "wrap"
    if arrange == "frame" and not by_frame:
        raise InputError(f"{pattern.source or 'pattern'}: its frame ({pattern.frame or 'none'}) cannot be mapped "
                         f"onto vfit's body; arrange it automatically (wrap)")
    if by_frame:
        fmap = FrameMap(body, *garmentcode_landmarks(pattern.body))
        maps = {n: (lambda xy, p=p: fmap(p.to_3d(xy))) for n, p in pattern.panels.items()}
        return Placement(body, clearance, {n: "frame" for n in pattern.panels}, {}, maps)
    slots = resolve_slots(pattern, mapping)
    maps = _wraps(pattern, body, slots, clearance)
    return Placement(body, clearance, {n: f"wrapped: {s.part}" for n, s in slots.items()}, slots, maps)
