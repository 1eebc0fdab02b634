"""The fit table: how a draped garment fits each body region (``report.json["fit"]``).

One row per region the garment goes round -- bust (men: chest), underbust (women), waist, hips, neck,
upper arms, thighs -- and per garment opening that goes round the body (hems, cuffs, waistbands,
necklines). A region is measured in one plane:

* bust, underbust, waist and hips: the horizontal plane of vfit's tape girth (ISO 8559-1 style, the
  plane the band search chose; :class:`vfit_engine.body.measure.Measurer`);
* neck, upper arms and thighs: the plane that fits MakeHuman's ruler loop best (least squares; the left
  side's loop is MakeHuman's, the right side's its mirror image);
* an opening: its own loop, against the body part it encircles
  (:func:`vfit_engine.garment.openings.check_openings` at the draped position).

Figures of a row: ``body_girth_cm`` (a tape round the body in the plane: the convex hull of the loop
round the region), ``garment_girth_cm`` (a tape round the draped garment in the same plane, over its
outside: the convex hull of the garment's own loop round the region, :func:`.loops.garment_girth` -- the torso
loop of a shirt, not its sleeves or armholes, the sleeve round an arm, not the torso it joins; for an
opening, its draped length), ``ease_cm`` (their difference: a garment stretched round the body has an
ease of 2 pi times its gap to the skin, 1-2 cm for the drape's few millimetres), ``girth_strain`` (how
far the cloth round the region is stretched along that tape's line: its draped length over its length as
made, step by step across the triangles the plane cuts, over the steps under tension -- cloth bunched
into a fold at a seam carries nothing round the body --, :func:`.loops.loop_strain`, and no more than
``max_strain``, the yarns' there (the line crosses sheared triangles, whose shear it would read as stretch);
where the line has no step,
sum l / sum l0 - 1 over the garment's yarn edges that run round the region within ``BAND`` of the plane;
for an opening, its draped length over its length as given), ``garment_made_cm`` (the garment's own
girth there as made: ``garment_girth_cm`` times the line's whole length as made over its draped length;
a size run's sizes differ in it as the grading says, where a tight size's draped girth is the body's),
``max_strain`` (the largest yarn strain
among those band edges, >= 3 mm long, no higher than where the body's arms join its torso: a man's chest
is taken just under the armpits, and above them a shirt's edges run round its armholes and sleeve caps),
``pressure_kpa_max`` (:mod:`.maps`), ``estimated`` (the customer did not give this girth: the body model
estimated it from the others) and ``verdict``: too tight to wear, tight, fitted, loose or too loose, by the
one rule of :mod:`.verdict` (which every other output reads).

A body region's ``girth_strain`` is the stretch the region puts on the cloth round it (:func:`region_stretch`):
where the garment as made is longer round the region than the body's girth plus 2 pi times the gap the drape
keeps between cloth and skin, the garment goes round the region without stretching, and what stretches its
line there is other cloth (a shirt's collar held open by the shoulders round a neck it stands clear of: 3.7 %
with 15 cm of ease; a trouser leg pulled from the seat round a thigh it is 3 cm bigger than): it reads no
more than 0. The yarns' peaks stay in ``max_strain``. An opening is judged so against ``body_girth_here_cm``,
the body's tape in its own plane (a neckline pulled open by the shoulders round a neck it has room round).

``key`` marks the girths letter sizes are labelled by (EN 13402: bust/chest, waist and hips; every
region's verdict decides ``vfit size``'s choice). A girth the customer gave that
the garment does not go round has its row all the same (verdict ``not covered``, no garment figures).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from vfit_engine.body.measure import Measurer
from vfit_engine.body.segment import PARTS
from vfit_engine.drape.settings import DrapeSettings
from vfit_engine.fit.loops import garment_girth, hull_of, loop_steps, loop_strain, round_together
from vfit_engine.fit.maps import fit_maps
from vfit_engine.fit.verdict import uncovered_row, verdict
from vfit_engine.garment.openings import BodyLoops, check_openings
from vfit_engine.pattern.weld import sewn_to
from vfit_engine.geometry import winding_number
from vfit_engine.section import MeshSections, rotation_to_y

#: Half-width of the band round a region's plane whose edges give its strain, m.
BAND = 0.02
#: An edge runs round the region when its direction is within 60 degrees of the plane.
ROUND_COS = 0.5
#: Torso regions (vfit's tape girths) and limb regions (MakeHuman rulers), in table order.
TORSO = ("bust", "underbust", "waist", "hips")
LIMBS = (("neck", "neck-circ"), ("upper arm", "upperarm-circ"), ("thigh", "thigh-circ"))
KEY_REGIONS = ("bust", "chest", "waist", "hips")
#: Limbs a garment fits only with a part of its own (a sleeve, a trouser leg): a loop that goes round the limb
#: together with another body part (a skirt round both thighs) gives the limb no row.
ALONE = ("upper arm", "thigh")
#: A region's measurement as the body is built to it (``vfit morph``'s names: a man's chest is ``bust``).
TARGET_NAME = {"bust": "bust", "chest": "bust", "underbust": "underbust", "waist": "waist", "hips": "hips",
               "neck": "neck", "upper arm": "upper-arm", "thigh": "thigh"}


class _Plane:
    """A cutting plane through ``centre`` with unit ``normal``, and the frame that makes it horizontal."""

    def __init__(self, centre, normal):
        self.centre = np.asarray(centre, dtype=np.float64)
        self.normal = np.asarray(normal, dtype=np.float64) / np.linalg.norm(normal)
        self.rot = rotation_to_y(self.normal)
        c = self.rot @ self.centre
        self.height, self.centre_xz = float(c[1]), c[[0, 2]]

    def section(self, sections, verts):
        """The section loops (k, 2) of a mesh (``verts`` (n, 3) m) in the plane, in its horizontal frame, and
        whether each is closed."""
        return sections.loops(np.ascontiguousarray(verts @ self.rot.T), self.height, return_closed=True)

    def body_part(self, sections, verts, reach):
        """(own loop, its hull's perimeter m, the other loops) of the body's smallest section loop that
        goes round the centre with no point farther than ``reach`` (m) from it; None when none does."""
        loops = [lp for lp in self.section(sections, verts)[0] if len(lp) >= 3]
        round_ = [(h[1], i) for i, lp in enumerate(loops)
                  if np.max(np.linalg.norm(lp - self.centre_xz, axis=1)) <= reach
                  and abs(winding_number(lp, self.centre_xz)) > 0.5 and (h := hull_of(lp)) is not None]
        if not round_:
            return None
        girth, i = min(round_)
        return loops[i], girth, loops[:i] + loops[i + 1:]


def _limb_planes(model, verts):
    """(name, side, plane, reach) of the neck and both upper arms and thighs, from MakeHuman's rulers."""
    tree = cKDTree(verts)
    out = []
    for name, ruler in LIMBS:
        idx = np.asarray(model.rulers[ruler]["vertex_indices"], dtype=np.int64)
        p = verts[idx]
        sides = [("", p)]
        if name != "neck":
            mirror = verts[tree.query(p * np.array([-1.0, 1.0, 1.0]))[1]]
            own = "left" if p[:, 0].mean() > 0 else "right"  # +X is the body's left
            sides = [(own, p), ("right" if own == "left" else "left", mirror)]
        for side, q in sides:
            centre = q.mean(axis=0)
            normal = np.linalg.svd(q - centre)[2][2]
            reach = 1.5 * float(np.max(np.linalg.norm(q - centre, axis=1)))
            out.append((name, side, _Plane(centre, normal), reach))
    return out


def _round_edges(edges, pos, plane, hull_eq, margin=0.01, above=BAND, band=BAND, across=False):
    """Mask of the yarn edges that run round the region: both ends within ``band`` of the plane (and at
    most ``above`` over it), the edge within 60 degrees of it, and its midpoint inside the garment's hull
    (+ ``margin``); with ``across``, the edges the plane cuts instead, their midpoints inside the hull."""
    a, b = pos[edges[:, 0]], pos[edges[:, 1]]
    off_a, off_b = (a - plane.centre) @ plane.normal, (b - plane.centre) @ plane.normal
    d = b - a
    length = np.linalg.norm(d, axis=1)
    along = np.abs(d @ plane.normal) <= ROUND_COS * np.maximum(length, 1e-12)
    mid = (0.5 * (a + b)) @ plane.rot.T
    inside = np.all(mid[:, [0, 2]] @ hull_eq[:, :2].T + hull_eq[:, 2] <= margin, axis=1)
    if across:
        return ((off_a > 0.0) != (off_b > 0.0)) & inside
    return ((np.abs(off_a) <= band) & (np.abs(off_b) <= band) & (off_a <= above) & (off_b <= above) & along
            & inside)


class FitTable:
    """Builds the fit table of drapes on one body (the body's sections and planes are built once)."""

    def __init__(self, body, model):
        self.measurer = Measurer(model)
        model = self.measurer.model  # loaded by the Measurer when not given
        self.body_verts = np.ascontiguousarray(body.surface, dtype=np.float64)
        self.gender = body.gender
        # a body built to measurements: the girths not given are the body model's estimates from the others
        d = body.description or {}
        given = d.get("targets_cm") if d.get("source") == "morph" else None
        self.estimated = set() if given is None else {k for k, t in TARGET_NAME.items() if t not in given}
        self.given = set() if given is None else {k for k, t in TARGET_NAME.items() if t in given}
        # a man's chest row in his chest girth's plane, under the armpits: the figure he gives (its garment
        # girth is his shirt's torso loop, its armholes and sleeves left out; docs/MEASUREMENTS.md)
        m = self.measurer.measure(self.body_verts, names=TORSO, mass=False, gender=self.gender)
        self.regions = []  # (region, side, plane, reach, body girth m, body part's loop, other body loops)
        self._above = {}  # torso region -> how far above its plane its cloth counts (m)
        self.chest_y = float(m.planes["bust"])
        g = self.gender
        # a body file's gender is unknown (None): women's names (bust, underbust), which measure a man too
        female = g is None or g == "female" or (not isinstance(g, str) and float(g) < 0.5)
        for name in TORSO:
            if name == "underbust" and not female:
                continue
            centre, own, others = self._torso_loops(m.planes[name])
            label = "chest" if name == "bust" and not female else name
            self.regions.append((label, "", _Plane(centre, (0.0, 1.0, 0.0)), 1.0, float(m.values[name]), own, others))
            # only a bust/chest plane reaches the armholes (lower, hanging forearms can touch a heavy waist)
            self._above[label] = self._below_armpits(m.planes[name]) if name == "bust" else BAND
        # the body's sections round the openings, built once for every drape on this body
        self.loops = BodyLoops(self.body_verts, model.body_tris)
        for name, side, plane, reach in _limb_planes(model, self.body_verts):
            part = plane.body_part(self.measurer.sections, self.body_verts, reach)
            if part is not None:
                self.regions.append((name, side, plane, reach, part[1], part[0], part[2]))

    def _below_armpits(self, y):
        """How far above a torso plane at ``y`` the cloth round it counts: ``BAND``, or less where the body's
        arms join its torso sooner (a chest taken just under the armpits): above there a garment's edges run
        round its armholes and sleeve caps, not round the chest."""
        steps = np.arange(1, int(round(BAND / 0.001)) + 1) * 0.001
        apart = self.measurer.sections.apart(self.body_verts, y + steps)
        below = self.measurer.sections.apart(self.body_verts, [y])[0]
        return float(steps[int(np.argmin(apart))] - 0.001) if below and not apart.all() else BAND

    def _torso_loops(self, y):
        """(centre (3,) of the torso loop's hull, the torso loop (k, 2), the body's other loops) at height
        ``y``: the torso's is the largest loop spanning x = 0."""
        loops = [lp for lp in self.measurer.sections.loops(self.body_verts, y) if len(lp) >= 3]
        best, at = None, None
        for i, loop in enumerate(loops):
            h = hull_of(loop)
            if h is not None and loop[:, 0].min() <= 0.0 <= loop[:, 0].max() and (best is None or h[1] > best[1]):
                best, at = h, i
        if best is None:
            return np.array([0.0, y, 0.0]), np.zeros((0, 2)), []
        c = best[0].mean(axis=0)
        return np.array([c[0], y, c[1]]), loops[at], loops[:at] + loops[at + 1:]

    def rows(self, setup, pos, maps=None):
        """The table (module docstring) of ``setup``'s garment at ``pos``: list of dict."""
        pos = np.ascontiguousarray(pos, dtype=np.float64)
        maps = maps if maps is not None else fit_maps(setup, pos)
        mesh = setup.garment.mesh
        sections = MeshSections(mesh.triangles(), mesh.n_verts)
        edges = mesh.edges()
        l0 = np.linalg.norm(mesh.verts[edges[:, 1]] - mesh.verts[edges[:, 0]], axis=1)
        length = np.linalg.norm(pos[edges[:, 1]] - pos[edges[:, 0]], axis=1)
        limit = float(setup.material.wearable_stretch)
        out = []
        tris = mesh.triangles()
        for name, side, plane, reach, body_girth, own, others in self.regions:
            reach = max(reach, 3.0 * body_girth / (2 * np.pi))
            loops, closed = plane.section(sections, pos)
            if name in ALONE and round_together(loops, closed, plane.centre_xz, others):
                continue  # a skirt round both thighs: no garment part of this limb (a tailor gives it no row)
            tape = garment_girth(loops, plane.centre_xz, own, others, reach, closed)
            if tape is None:
                continue  # the garment does not go round this region
            hull, girth, eq = tape
            for band in (BAND, 2 * BAND):  # coarse cloth (a suit's waist: rings 4 cm apart) has none within BAND
                above = self._above.get(name, BAND)
                sel = _round_edges(edges, pos, plane, eq, above=above if above < BAND else band, band=band) & (l0 > 0)
                if sel.any():
                    break
            if not sel.any():  # a coarse mesh whose rows miss the band: the edges the plane cuts
                sel = _round_edges(edges, pos, plane, eq, across=True) & (l0 > 0)
            if not sel.any():
                continue
            strain = length[sel] / l0[sel] - 1.0
            long_ = l0[sel] >= 0.003
            verts = np.unique(edges[sel])
            # the stretch along the tape's own line; the band's edges where that line has no step
            steps = loop_steps(tris, mesh.verts, pos, plane, own, others, reach)
            hoop = loop_strain(tris, mesh.verts, pos, plane, own, others, reach, steps=steps)
            ratio = hoop[1] if hoop is not None else float(length[sel].sum() / l0[sel].sum())
            top = float(strain[long_].max()) if long_.any() else 0.0
            # no more than the yarns there are stretched: a line cut across sheared triangles reads their shear
            # as stretch (a skirt hanging 47 cm clear of a thigh read 3.0 % round it, its yarns at most 1.5 %)
            hoop_strain = min(hoop[0], top) if hoop is not None and long_.any() else None
            stretch = region_stretch(hoop_strain if hoop_strain is not None else ratio - 1.0, girth / ratio, body_girth)
            row = _row(name, side, body_girth, girth, stretch, top, float(maps["pressure_kpa"][verts].max()), limit)
            row["garment_made_cm"] = round(100.0 * girth / ratio, 2)
            row["estimated"] = name in self.estimated
            if setup.pattern is not None:  # the panels the tape's line crosses (a pattern's region by panel)
                row["panels"] = setup.pattern.loop_panels(steps[2], steps[0], steps[1]) if steps is not None else []
            out.append(row)
        # a girth the customer gave has its row, also where the garment does not go round it
        have = {r["region"] for r in out}
        out += [uncovered_row(name, side, body_girth, name in KEY_REGIONS)
                for name, side, _, _, body_girth, _, _ in self.regions
                if name in self.given and f"{side} {name}".strip() not in have]
        out += self._opening_rows(setup, pos, maps, limit)
        return out

    def _opening_rows(self, setup, pos, maps, limit):
        """Rows of the garment's openings that go round a body part, at the draped position (a sewn pattern's:
        those of the garment its seams make, not its panels' outlines)."""
        piece, weld = setup.garment.pieces, None
        if setup.seams.size:  # the sewn garment is one piece
            weld = sewn_to(setup.garment.mesh.n_verts, setup.seams)
            piece = np.zeros_like(piece)
        rows = []
        for o in check_openings(setup.garment.mesh, self.body_verts, setup.body_tris, pos=pos, loops=self.loops,
                                weld=weld):
            loop = o["indices"]
            draped = float(np.linalg.norm(pos[loop] - np.roll(pos[loop], -1, axis=0), axis=1).sum())
            rest = o["rest_length_mm"] / 1000.0
            part = None
            if setup.body_parts is not None:
                near = int(np.argmin(np.linalg.norm(self.body_verts - pos[loop].mean(axis=0), axis=1)))
                k = int(setup.body_parts[near])
                part = PARTS[k] if k >= 0 else None
            name, side = _opening_name(part, pos[piece == piece[loop[0]]], pos[loop], self.chest_y)
            strain, here = (draped / rest - 1.0 if rest > 0 else 0.0), o["body_tape_here_mm"]
            if here is not None and rest > 0:  # the body where the opening lies, not the smallest tape near it
                strain = region_stretch(strain, rest, here / 1000.0)
            row = _row(name, side, o["body_tape_mm"] / 1000.0, draped, strain, float(maps["strain"][loop].max()),
                       float(maps["pressure_kpa"][loop].max()), limit, need=o["required_strain"])
            row["body_girth_here_cm"] = None if here is None else round(here / 10.0, 2)
            row["estimated"] = False  # the body's own girth under the opening, not a customer's measurement
            if setup.pattern is not None:
                row["panels"] = setup.pattern.opening_panels(loop, pos, setup.rest, weld)
            rows.append(row)
        return rows


def _opening_name(part, piece, loop, chest_y):
    """(name, side) of an opening ``loop`` (L, 3) m of the garment piece ``piece`` (k, 3) m round body
    ``part``: sleeve hem, leg hem, neckline (a top's opening above the chest plane ``chest_y``), waistband
    or hem."""
    side = ""
    if part and part.endswith((".L", ".R")):
        side = "left" if part.endswith(".L") else "right"
    base = (part or "").split(".")[0]
    if base in ("upperarm", "lowerarm", "hand"):
        return "sleeve hem", side
    if base in ("thigh", "shin", "foot"):
        return "leg hem", side
    if base in ("neck", "head"):
        return "neckline", ""
    # round the torso: a waistband when the garment hangs below it, a hem when it rises above it
    y = loop[:, 1].mean()
    if np.mean(piece[:, 1] > y) > 0.5:
        return "hem", ""
    return ("neckline" if y > chest_y else "waistband"), ""


def region_stretch(line_stretch, made_m, body_m, gap=None):
    """The stretch a body region puts on the cloth round it (module docstring), fraction.

    Parameters
    ----------
    line_stretch : float
        How far the cloth along the region's tape line is stretched (:func:`.loops.loop_strain`), fraction.
    made_m, body_m : float, m
        The garment's girth there as made and the body's.
    gap : float or None, m
        The gap the drape keeps between cloth and skin; default the drape's contact skin
        (``DrapeSettings().contact.skin``).

    Returns
    -------
    float
        ``line_stretch``, or no more than 0 where the garment as made goes round the body with that gap to spare
        (``made_m - body_m >= 2 pi gap``): the body does not stretch it there.
    """
    gap = DrapeSettings().contact.skin if gap is None else float(gap)
    return min(float(line_stretch), 0.0) if made_m - body_m >= 2.0 * np.pi * gap else float(line_stretch)


def _row(name, side, body_m, garment_m, girth_strain, max_strain, pressure, limit, need=None):
    """One row of the table with its verdict (:func:`.verdict.verdict`)."""
    ease_cm = 100.0 * (garment_m - body_m)
    row = dict(region=f"{side} {name}".strip(), body_girth_cm=round(100.0 * body_m, 2),
               garment_girth_cm=round(100.0 * garment_m, 2), ease_cm=round(ease_cm, 2),
               girth_strain=round(girth_strain, 5), max_strain=round(max_strain, 5),
               pressure_kpa_max=round(pressure, 3), verdict=verdict(name, girth_strain, ease_cm, limit, need),
               key=name in KEY_REGIONS)
    if need is not None:
        row["required_strain"] = round(float(need), 5)
    return row


def fit_table(setup, pos, model=None, maps=None):
    """The fit table (module docstring) of a drape of ``setup`` ending at ``pos`` (n, 3) m."""
    return FitTable(setup.body, model).rows(setup, pos, maps)
