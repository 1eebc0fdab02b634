"""Body measurements, each with its definition. Values are in metres (the CLI prints cm).

Definitions (``definition=``), after ``shared/reference/MEASUREMENTS.md``:

``iso`` (default) - tailoring tape measures, ISO 8559-1 style
    * height: stature, max Y - min Y of the 13,380 body vertices.
    * bust (ISO 8559-1 / EN 13402-1 "bust girth"): the largest torso tape
      girth over planes from the bust points up to 3 cm above them, at most just
      under the armpits. A bust point is the most anterior point of the breast:
      on each side the most anterior vertex of those the rig's breast bone skins
      most; the band starts at their mean height (10 um below it, off their
      vertex row). It ends 3 cm higher or, lower, at the last plane, in 1 mm
      steps up from there, whose section still shows the torso and both arms
      apart (one loop spanning x = 0 and another wholly on each side of it). A
      woman's bust is then the girth at (or within millimetres of) her bust
      points.
    * a man's chest (``gender`` male, or a blend >= 0.5; ISO 8559-1 / EN
      13402-1 "chest girth": the tape under the armpits, across the shoulder
      blades), reported as ``bust``: the torso tape girth in the one plane just
      under the armpits, the last plane, in 1 mm steps up from the bust points'
      (as above, at most 15 cm), whose section shows the torso and both arms
      apart. A body of unknown gender (``gender=None``: a body file) gets the
      bust. The fit table measures a man's chest row in this plane too (its
      garment girth is the shirt's torso loop, the armholes and sleeves left
      out: docs/MEASUREMENTS.md).
    * both: where the arms have not separated from the torso even at the bust
      points (heavy bodies with a low armpit) the band is the one plane just
      under the armpits, the first, in 1 mm steps down, where they are apart.
    * underbust (ISO 8559-1 "underbust girth", just below the breasts): the
      smallest torso tape girth within +-2 cm of the mean height of the
      underbust ruler's vertices, the band kept at least 1 cm below the bust
      band's bottom (and 4 cm long), so a low bust can never put it above the
      bust; a man's chest, higher, leaves it where a woman's bust would.
    * waist: the smallest torso tape girth between the mean heights of the hips
      ruler and of the underbust ruler (the natural, narrowest waist).
    * hips: the largest torso tape girth within +-4 cm of the mean height of the
      hips ruler's vertices.
    * neck, upper-arm, thigh, calf: the MakeHuman rulers (no plane-based
      definition is specified for them yet).
    A *tape girth* is the perimeter of the convex hull of the horizontal
    cross-section's torso loop (a tape bridges hollows; arm loops cut by the same
    plane are ignored). Planes are searched at 1 mm steps, band ends included.

``makehuman`` - MakeHuman's Measure plugin rulers
    Each value is the length of the polyline through a fixed list of body
    vertices (``data/rulers.json``): bust = bust-circ, waist = waist-circ ...,
    and all 20 rulers are reported under their MakeHuman keys. Height as above.

``spline`` - the seed's feature profile curve
    As ``iso`` but each girth is the length of natural cubic splines through the
    front and back halves of the torso loop (it follows hollows instead of
    bridging them).

``mass_kg`` is reported with every definition: the body mesh's enclosed
volume times ``DENSITY``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vfit_engine.body.gradients import girth_gradient_dy, ruler_gradient, stature_gradient
from vfit_engine.body.model import N_BODY, BodyModel, gender_value
from vfit_engine.kernels.volume import enclosed_volume as volume
from vfit_engine.kernels.volume import volume_gradient
from vfit_engine.section import MeshSections
from vfit_engine.units import LENGTH_UNITS

DEFINITIONS = ("iso", "makehuman", "spline")
#: kg/m^3 used for body mass from volume (whole-body density of adults is about 985-1,000 kg/m^3).
DENSITY = 985.0
#: the measurements a user can ask for, in report order.
NAMES = ("height", "bust", "underbust", "waist", "hips", "neck", "upper-arm", "thigh", "calf")
#: measurement -> MakeHuman ruler key
RULER_OF = {"bust": "bust-circ", "underbust": "underbust-circ", "waist": "waist-circ", "hips": "hips-circ",
            "neck": "neck-circ", "upper-arm": "upperarm-circ", "thigh": "thigh-circ", "calf": "calf-circ"}
#: plane-based torso girths: (ruler whose mean height anchors the band, band below, band above, max or min)
_BANDS = {
    "underbust": ("underbust-circ", 0.02, 0.02, "min"),
    "hips": ("hips-circ", 0.04, 0.04, "max"),
}
#: the underbust band stays this far below the bust points' plane, and at least this long (m)
UNDERBUST_GAP, UNDERBUST_MIN_BAND = 0.01, 0.04
#: the bust band starts this far below the bust points' mean height (m), off their vertex row
BUST_PLANE_OFFSET = 1e-5
#: and reaches at most this far above them (m): a woman's bust is taken across her bust (module docstring)
BUST_BAND_ABOVE = 0.03
#: the armpit search: how far below (a man's chest: above) the bust points it looks for the arms apart, and its
#: step (m)
ARMPIT_SEARCH, ARMPIT_STEP = 0.15, 0.001
_BAND_STEPS = np.arange(round(BUST_BAND_ABOVE / ARMPIT_STEP) + 1) * ARMPIT_STEP  # 0, 1 .. 30 mm
_CHEST_STEPS = np.arange(round(ARMPIT_SEARCH / ARMPIT_STEP) + 1) * ARMPIT_STEP  # 0, 1 .. 150 mm
_ARMPIT_STEPS = np.arange(1, round(ARMPIT_SEARCH / ARMPIT_STEP) + 1) * ARMPIT_STEP  # 1 .. 150 mm
PLANE_STEP = 0.001  # m
_PLANE_GIRTHS = ("bust", "underbust", "waist", "hips")


@dataclass
class Measurement:
    """Measured values (m, mass in kg) and the planes (y, m) where the tape girths were taken."""

    definition: str
    values: dict
    planes: dict = field(default_factory=dict)
    mass_kg: float = float("nan")
    #: name -> near-extremal planes found by the band search, as fractions of the band (0 = lo, 1 = hi)
    candidates: dict = field(default_factory=dict)
    #: name -> the plane used, as a fraction of its band
    fractions: dict = field(default_factory=dict)
    #: name -> girths (m) at each of the fixed planes asked for (``planes=``), in their order
    at_planes: dict = field(default_factory=dict)

    def cm(self) -> dict:
        """Values in centimetres, rounded to 0.01 mm."""
        return {k: round(v / LENGTH_UNITS["cm"], 3) for k, v in self.values.items()}


def takes_chest(gender) -> bool:
    """True where a body's ``bust`` is a man's chest girth, under the armpits: ``gender`` "male" or a blend
    >= 0.5. None (a body file whose gender is not known) and women take the bust (module docstring)."""
    return gender is not None and gender_value(gender) >= 0.5


def band_limits(verts: np.ndarray, rulers: dict, bust: tuple = (np.inf, np.inf), chest: bool = False) -> dict:
    """(lo, hi, 'max'|'min') of every plane-based girth of a body, in metres.

    ``bust`` : (lo, hi) of the bust band (:meth:`Measurer.bust_band`); the underbust band is kept
    below its bottom (see the module docstring). ``chest``: a man's chest, the one plane at the band's top.
    """
    mean_y = {k: float(verts[rulers[k]["vertex_indices"], 1].mean()) for k in ("underbust-circ", "hips-circ")}
    out = {name: (mean_y[r] - below, mean_y[r] + above, mode) for name, (r, below, above, mode) in _BANDS.items()}
    out["bust"] = (bust[0], bust[1], "max")
    lo, hi, mode = out["underbust"]
    hi = min(hi, bust[0] - UNDERBUST_GAP)
    out["underbust"] = (min(lo, hi - UNDERBUST_MIN_BAND), hi, mode)
    if chest:
        out["bust"] = (bust[1], bust[1], "max")
    lo, hi = sorted((mean_y["hips-circ"], mean_y["underbust-circ"]))
    out["waist"] = (lo, hi, "min")
    return out


def breast_regions(model: BodyModel) -> tuple[np.ndarray, np.ndarray]:
    """Body vertices skinned most by the rig's ``breast.L`` and by its ``breast.R`` bone (weight > 0.5)."""
    bone, vert, weight = model.skin
    keep = vert < N_BODY
    bone, vert, weight = bone[keep], vert[keep], weight[keep]
    # per vertex the first of its heaviest weights (a loop keeping the first strict maximum; weights <= 0
    # never count)
    order = np.lexsort((np.arange(vert.size), -weight, vert))
    first = order[np.r_[True, vert[order][1:] != vert[order][:-1]]]
    first = first[weight[first] > 0]
    best = np.zeros(N_BODY)
    best_bone = np.full(N_BODY, -1)
    best[vert[first]], best_bone[vert[first]] = weight[first], bone[first]
    return tuple(np.flatnonzero((best_bone == model.bone_names.index(side)) & (best > 0.5))
                 for side in ("breast.L", "breast.R"))


def _band_anchors(name: str, fraction: float):
    """(ruler, d plane / d ruler-mean-height) pairs: how a girth's plane moves with its band."""
    if name == "waist":  # from the hips ruler's mean height (0) to the underbust ruler's (1)
        return (("hips-circ", 1.0 - fraction), ("underbust-circ", fraction))
    return ((_BANDS[name][0], 1.0),)


def ruler_length(verts: np.ndarray, indices) -> float:
    """Length (m) of the polyline through ``verts[indices]`` in order (MakeHuman's Ruler.getMeasure)."""
    p = verts[np.asarray(indices)]
    return float(np.sqrt(((p[1:] - p[:-1]) ** 2).sum(axis=1)).sum())


def stature(verts: np.ndarray) -> float:
    """Max Y - min Y of the body vertices (m)."""
    y = verts[:N_BODY, 1]
    return float(y.max() - y.min())


def enclosed_volume(verts: np.ndarray, tris: np.ndarray) -> float:
    """Volume (m^3) enclosed by a closed, outward-oriented triangle mesh (divergence theorem)."""
    a, b, c = (verts[tris[:, k]] for k in range(3))
    o = verts[tris[:, 0]].mean(axis=0)  # a nearby origin keeps round-off small
    return float(np.einsum("ij,ij->i", a - o, np.cross(b - o, c - o)).sum() / 6.0)


class Measurer:
    """Measures bodies with hm08 body topology. Build once, measure many bodies.

    Parameters
    ----------
    model : BodyModel, optional
        Supplies the topology and ruler lists; loaded if not given.
    """

    def __init__(self, model: BodyModel | None = None):
        self.model = model or BodyModel.load()
        self.rulers = self.model.rulers
        self.tris = self.model.body_tris
        self.sections = MeshSections(self.tris, N_BODY)
        self.breasts = breast_regions(self.model)
        self._bust_memo = None  # (verts, held points, chest, bust_band(verts)) of the last body
        #: bust points (two vertex indices) to use instead of the most anterior breast vertices: the morph's
        #: inner solve holds them, as it holds the planes (the argmax jumps between vertex rows of a flat
        #: chest, moving a lean man's chest band by 13 mm under a change of 1e-7 in one channel)
        self.held_points = None

    def bust_band(self, verts, gender=None) -> tuple[float, float, np.ndarray]:
        """(lo, hi, points): the bust band (m) and the vertices its planes follow (the two bust points;
        none where the band is held under the armpits). See the module docstring. For a man's chest
        (:func:`takes_chest` of ``gender``) the band runs from the bust points up to just under the
        armpits, and the chest is taken at its top (:func:`band_limits`).

        The last body's band is kept: the morph measures and differentiates one body several times (a
        measurement, then one gradient per girth)."""
        verts = np.asarray(verts)[:N_BODY]
        memo, held, chest = self._bust_memo, self.held_points, takes_chest(gender)
        if (memo is not None and np.array_equal(memo[0], verts) and np.array_equal(memo[1], held)
                and memo[2] == chest):
            return memo[3]
        band = self._bust_band(verts, chest)
        self._bust_memo = (verts.copy(), None if held is None else held.copy(), chest, band)
        return band

    def _bust_band(self, verts, chest):
        verts = np.ascontiguousarray(verts, dtype=np.float64)
        points = self.bust_points(verts) if self.held_points is None else self.held_points
        y = float(verts[points, 1].mean()) - BUST_PLANE_OFFSET
        # every plane of the 1 mm grid is looked at (one kernel call), as the definition says: a coarse
        # walk could step over an arm touching the chest for a few millimetres
        steps = _CHEST_STEPS if chest else _BAND_STEPS
        up = self.sections.apart(verts, y + steps)
        if up[0]:
            n = int(np.argmin(up)) if not up.all() else up.size  # the first plane where they touch
            return y, y + steps[n - 1], points
        down = self.sections.apart(verts, y - _ARMPIT_STEPS)  # the arms join the torso here: go down
        if down.any():
            y -= _ARMPIT_STEPS[int(np.argmax(down))]
        return y, y, points[:0]

    def bust_points(self, verts) -> np.ndarray:
        """The two bust points: per side, the most anterior vertex of those its breast bone skins most."""
        return np.array([idx[np.argmax(verts[idx, 2])] for idx in self.breasts])

    def _girth_method(self, definition):
        return "spline" if definition == "spline" else "hull"

    def torso_girth(self, verts, y, definition="iso") -> float:
        """Tape girth (m) of the torso loop at height ``y`` (m)."""
        return float(self.sections.girth(np.asarray(verts)[:N_BODY], y, method=self._girth_method(definition)))

    def scan_girth(self, verts, lo, hi, mode, definition="iso"):
        """Largest (``mode='max'``) or smallest torso girth over ``[lo, hi]``.

        Planes are ``ceil((hi - lo) / 1 mm) + 1`` evenly spaced, both band ends
        included. Returns (girth, y, candidates): ``candidates`` are the heights
        of the local extrema within 5 mm of the best, where the extremum may jump
        to when the body changes a little (the morph solver watches them all).
        """
        ys, g = self.sections.scan(verts, lo, hi, step=PLANE_STEP, method=self._girth_method(definition))
        ok = np.isfinite(g)
        if not ok.any():
            return float("nan"), float("nan"), np.array([np.nan])
        sign = 1.0 if mode == "max" else -1.0
        f = np.where(ok, sign * g, -np.inf)
        i = int(np.argmax(f))
        left = np.concatenate([[-np.inf], f[:-1]])
        right = np.concatenate([f[1:], [-np.inf]])
        local = np.flatnonzero((f >= left) & (f >= right) & (f >= f[i] - 0.005))
        order = np.argsort(-f[local])[:3]
        return float(g[i]), float(ys[i]), ys[local[order]]

    def gradient(self, verts, name, definition="iso", fraction=None, gender=None):
        """Sparse gradient of one measurement w.r.t. the vertices: (idx (k,), d/dv (k, 3)).

        A tape girth is differentiated at the plane a ``fraction`` of the way up
        its band, including the band's own motion with its ruler vertices
        (``dg/dy`` by a central difference). The ``spline`` girth has no
        analytic gradient here (returns None). ``gender``: as :meth:`measure`.
        """
        verts = np.ascontiguousarray(np.asarray(verts)[:N_BODY], dtype=np.float64)
        if name == "height":
            return stature_gradient(verts, N_BODY)
        if definition == "makehuman" or name not in _PLANE_GIRTHS:
            return ruler_gradient(verts, self.rulers[RULER_OF[name]]["vertex_indices"])
        if definition == "spline":
            return None
        b_lo, b_hi, points = self.bust_band(verts, gender)
        lo, hi, _ = band_limits(verts, self.rulers, (b_lo, b_hi), takes_chest(gender))[name]
        y = lo + fraction * (hi - lo)
        anchors = () if name == "bust" else _band_anchors(name, fraction)
        eps = 1e-6  # local: g(y) has kinks where the plane passes vertex rows, often within 10 um
        idx, grad, (g_lo, g_hi) = girth_gradient_dy(self.sections, verts, y, eps)
        dg_dy = (g_hi - g_lo) / (2 * eps)
        parts_i, parts_g = [idx], [grad]
        if name == "bust" and points.size:
            # the whole band follows the bust points' mean height: its top is a whole number of
            # millimetres above its bottom, a count that a small change of the body leaves alone
            g = np.zeros((points.size, 3))
            g[:, 1] = dg_dy / points.size
            parts_i.append(points)
            parts_g.append(g)
        for ruler, weight in anchors:
            r_idx = np.asarray(self.rulers[ruler]["vertex_indices"], dtype=np.int64)
            g = np.zeros((r_idx.size, 3))
            g[:, 1] = dg_dy * weight / r_idx.size
            parts_i.append(r_idx)
            parts_g.append(g)
        return np.concatenate(parts_i), np.concatenate(parts_g)

    def mass(self, verts) -> float:
        """Body mass (kg): enclosed volume of the body mesh times ``DENSITY`` (a Numba kernel;
        :func:`enclosed_volume` is its NumPy reference)."""
        return volume(np.ascontiguousarray(np.asarray(verts)[:N_BODY], dtype=np.float64), self.tris) * DENSITY

    def mass_gradient(self, verts) -> np.ndarray:
        """(13380, 3) float64: d mass / d vertex (kg per m)."""
        grad = np.empty((N_BODY, 3))
        volume_gradient(np.ascontiguousarray(np.asarray(verts)[:N_BODY], dtype=np.float64), self.tris, grad)
        return grad * DENSITY

    def measure(self, verts, definition="iso", planes=None, names=NAMES, mass=True, gender=None) -> Measurement:
        """Measure a body.

        Parameters
        ----------
        verts : (n >= 13380, 3) float64, m
            Body vertices in hm08 order, Y up.
        definition : {'iso', 'makehuman', 'spline'}
        planes : dict, optional
            name -> fraction or array of fractions of the band (0 = its lower
            end, 1 = its upper end): take those girths at these planes (the
            extremum over them) instead of searching their bands (the morph
            solver's inner loop). Fractions keep a plane in the band while the
            band moves with the body.
        names : iterable of str
            Which of ``NAMES`` to measure (``makehuman`` always adds all rulers).
        mass : bool
            Also compute ``mass_kg`` (NaN otherwise).
        gender : 'female', 'male', 0..1 or None
            The body's: a man's ``bust`` is his chest girth, under the armpits (:func:`takes_chest`); None
            (unknown) takes the bust.
        """
        if definition not in DEFINITIONS:
            raise ValueError(f"unknown definition {definition!r}; choose from {', '.join(DEFINITIONS)}")
        verts = np.ascontiguousarray(np.asarray(verts)[:N_BODY], dtype=np.float64)
        values, used, cand, frac = {}, {}, {}, {}
        bands = None
        fixed = {}  # name -> girths at its fixed planes: all names' planes cut in one kernel call
        held = [n for n in names if planes is not None and n in planes and n in _PLANE_GIRTHS
                and definition != "makehuman"]
        if held:
            bands = band_limits(verts, self.rulers, self.bust_band(verts, gender)[:2], takes_chest(gender))
            ts = [np.atleast_1d(planes[n]) for n in held]
            ys = np.concatenate([bands[n][0] + t * (bands[n][1] - bands[n][0]) for n, t in zip(held, ts)])
            g = self.sections.girths(verts, ys, method=self._girth_method(definition))
            fixed = dict(zip(held, np.split(g, np.cumsum([t.size for t in ts])[:-1])))
        for name in names:
            if name == "height":
                values[name] = stature(verts)
            elif definition == "makehuman" or name not in _PLANE_GIRTHS:
                values[name] = ruler_length(verts, self.rulers[RULER_OF[name]]["vertex_indices"])
            else:
                if bands is None:
                    bands = band_limits(verts, self.rulers, self.bust_band(verts, gender)[:2],
                                        takes_chest(gender))
                lo, hi, mode = bands[name]
                span = (hi - lo) or 1.0  # a one-plane band (the bust held under the armpits)
                if planes is not None and name in planes:
                    # fixed planes, given as fractions of the band: they move with the band
                    ts, g = np.atleast_1d(planes[name]), fixed[name]
                    k = int(np.nanargmax(g) if mode == "max" else np.nanargmin(g))
                    values[name], used[name], frac[name] = g[k], lo + ts[k] * (hi - lo), float(ts[k])
                else:
                    values[name], used[name], ys = self.scan_girth(verts, lo, hi, mode, definition)
                    cand[name] = (ys - lo) / span
                    frac[name] = (used[name] - lo) / span
        if definition == "makehuman" and planes is None:
            for key, r in self.rulers.items():
                values.setdefault(key, ruler_length(verts, r["vertex_indices"]))
        return Measurement(definition, values, used, self.mass(verts) if mass else float("nan"), cand, frac,
                           fixed)
