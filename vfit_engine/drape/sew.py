"""Set up the drape of a sewing pattern: its panels meshed as cloth, placed round the body, to be sewn there.

:func:`prepare_pattern_drape` is the pattern's counterpart of :func:`vfit_engine.drape.setup.prepare_drape` and
gives the same :class:`~vfit_engine.drape.setup.DrapeSetup`, so the frame loop, the report, the fit and the outputs
are a garment's:

1. **cloth** (:func:`vfit_engine.pattern.mesh.mesh_pattern`): each panel meshed along its grain, stitched edges
   matched vertex for vertex;
2. **start** (:func:`vfit_engine.pattern.placement.place`): each panel placed on the body, by the pattern's own
   frame or wrapped round the body part it belongs to;
3. **rest shape**: the flat pattern, each panel as cut, laid side by side in the plane z = 0. The cloth's rest
   lengths and angles are the pattern's, never the placed shape's, so the report's strain is against the flat
   pattern; the panels stay apart in the cloth (a seam's two sides are two vertices each);
4. **seams** (``DrapeSetup.seams``): the vertex pairs the frame loop sews. Over the first
   ``DrapeSettings.sew_frames`` frames, with gravity off, each seam may be no longer than a length that shrinks
   from its gap at the start to 0 (:meth:`vfit_engine.sim.solver_pd.SolverPD.close_seams`), so the panels close
   round the body at a pace its contacts hold (pulled shut at once, a back panel went through the body); then
   the garment hangs and settles as any garment, its seams held at length 0. Sewing needs the projective
   solver (``drape.settings.projective``).

No pins (the seams hold the garment together; the body holds it up), no openings fitted before the start (the
garment has no shape before it is sewn).
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vfit_engine.body.segment import skin_parts
from vfit_engine.collide.body_mesh import MeshCollider
from vfit_engine.drape.settings import DrapeSettings
from vfit_engine.drape.setup import DrapeSetup, Pins, ground_height
from vfit_engine.errors import InputError
from vfit_engine.garment.garment import Garment
from vfit_engine.io.meshdata import MeshData
from vfit_engine.pattern.mesh import DEFAULT_SPACING, mesh_pattern
from vfit_engine.pattern.placement import place
from vfit_engine.pattern.placement_body import BodyParts
from vfit_engine.sim.materials import resolve_material

#: Gap (m) between the panels laid side by side in the rest shape (they share no element: any gap would do).
REST_GAP = 0.1


@dataclass(frozen=True, eq=False)
class PatternLabels:
    """What names a sewn pattern's cloth as the pattern maker knows it (``DrapeSetup.pattern``).

    Attributes
    ----------
    panel_names : tuple of str
        The panels in the pattern's order (the garment's ``pieces`` index them).
    seam_names : tuple of str
        One per stitch of the pattern, in its order: its two edges as ``panel:edge``, the edge by its label in
        the file when it has one, else by its index in the panel's outline (``"front:1 <-> right:5"``).
    seam_stitch : (s,) int64
        The stitch (index into ``seam_names``) of each row of ``DrapeSetup.seams``; a stitch's rows run along
        its edge ``a``, one after the other.
    vertex_panel : (n,) int64
        The panel of every cloth vertex (index into ``panel_names``).
    """

    panel_names: tuple
    seam_names: tuple
    seam_stitch: np.ndarray
    vertex_panel: np.ndarray

    @classmethod
    def of(cls, pattern, cloth, keep):
        """The labels of ``pattern`` meshed as ``cloth`` (PatternMesh), its seam pairs ``keep`` (mask) sewn."""
        def edge(ref):
            label = pattern.panels[ref.panel].edges[ref.edge].label
            return f"{ref.panel}:{label or ref.edge}"
        return cls(tuple(cloth.panel_names), tuple(f"{edge(s.a)} <-> {edge(s.b)}" for s in pattern.stitches),
                   np.asarray(cloth.seam_stitch, dtype=np.int64)[keep], np.asarray(cloth.vertex_panel, np.int64))

    def loop_panels(self, vertex, draped, made):
        """The panels a line round the body crosses, as many figures per panel, largest share first.

        Parameters
        ----------
        vertex : (k,) int64
            For each step of the line, a cloth vertex of the triangle (or edge) it crosses.
        draped, made : (k,) float64, m
            Each step's length draped and on the flat pattern.

        Returns
        -------
        list of dict
            ``panel``, ``loop_share_pct`` (its share of the line's draped length, %), ``loop_draped_cm`` and
            ``loop_made_cm`` (its part of the line, draped and as cut, cm).
        """
        panel = self.vertex_panel[np.asarray(vertex, dtype=np.int64)]
        total = float(np.sum(draped))
        rows = []
        for k in np.unique(panel).tolist():
            sel = panel == k
            d, m = float(np.sum(draped[sel])), float(np.sum(made[sel]))
            share = 100.0 * d / total if total > 0 else 0.0
            rows.append(dict(panel=self.panel_names[k], loop_share_pct=round(share, 2),
                             loop_draped_cm=round(100.0 * d, 2), loop_made_cm=round(100.0 * m, 2)))
        return sorted(rows, key=lambda r: -r["loop_share_pct"])

    def opening_panels(self, loop, pos, rest, weld):
        """:meth:`loop_panels` of an opening of the sewn garment: ``loop`` (L,) its vertices in walking order,
        a seam's sides as one (``weld`` (n,): :func:`vfit_engine.pattern.weld.sewn_to`); ``pos`` and ``rest``
        (n, 3) m the cloth draped and flat. Each loop edge is the cloth edge of one panel: where its ends lie on
        two panels (one end a seam's), the end on the seam is taken on the other's panel (its sewn partner
        there), so that its length as made is a panel's own."""
        a = np.array(loop, dtype=np.int64)  # a copy: its seam ends are moved to their mates
        b = np.roll(a, -1)
        for k in np.flatnonzero(self.vertex_panel[a] != self.vertex_panel[b]).tolist():
            for end, other in ((a, b), (b, a)):
                mates = np.flatnonzero((weld == weld[end[k]]) & (self.vertex_panel == self.vertex_panel[other[k]]))
                if mates.size:
                    end[k] = mates[0]
                    break
        return self.loop_panels(a, np.linalg.norm(pos[b] - pos[a], axis=1), np.linalg.norm(rest[b] - rest[a], axis=1))


def flat_layout(uv, vertex_panel, n_panels):
    """The rest shape: panel-frame points ``uv`` (n, 2) m laid panel after panel along +x, z = 0: (n, 3)."""
    rest = np.zeros((uv.shape[0], 3))
    x0 = 0.0
    for k in range(n_panels):
        sel = vertex_panel == k
        if not sel.any():
            continue
        rest[sel, 0] = uv[sel, 0] - uv[sel, 0].min() + x0
        rest[sel, 1] = uv[sel, 1]
        x0 = float(rest[sel, 0].max()) + REST_GAP
    return rest


def pattern_garment(pattern, cloth):
    """The cloth of a meshed pattern as a :class:`Garment`: vertices at the flat pattern (m), a group per panel,
    UVs the panels' own coordinates (m of the pattern), pieces the panels."""
    faces = np.ascontiguousarray(cloth.faces, dtype=np.int64)
    face_panel = cloth.face_panel
    if np.any(np.diff(face_panel) < 0):  # a group per panel needs the panels' faces one after another
        order = np.argsort(face_panel, kind="stable")
        faces, face_panel = faces[order], face_panel[order]
    firsts = np.searchsorted(face_panel, np.arange(len(cloth.panel_names)))
    groups = [(name, int(f)) for name, f in zip(cloth.panel_names, firsts) if f < face_panel.size]
    rest = flat_layout(cloth.uv, cloth.vertex_panel, len(cloth.panel_names))
    mesh = MeshData(rest, np.arange(0, faces.size + 1, 3, dtype=np.int64), faces.ravel(),
                    uvs=np.ascontiguousarray(cloth.uv, dtype=np.float64), face_uvs=faces.ravel().copy(),
                    groups=groups)
    return Garment(mesh, "m", Path(pattern.source or "pattern"), pieces=np.asarray(cloth.vertex_panel, np.int64))


def prepare_pattern_drape(pattern, body, model, material="cotton", spacing=DEFAULT_SPACING, arrange="auto",
                          mapping=None, clearance=0.01, settings=None):
    """Set up the sewing and drape of ``pattern`` on ``body`` (module docstring).

    Parameters
    ----------
    pattern : vfit_engine.pattern.model.Pattern
        :func:`vfit_engine.pattern.load.load`.
    body : Body
        :func:`vfit_engine.body.resolve.resolve_body` (hm08, A-pose).
    model : BodyModel
    material : str, Path or Material
    spacing : float, m
        The cloth's edge length (:func:`vfit_engine.pattern.mesh.mesh_pattern`).
    arrange : {"auto", "frame", "wrap"};  mapping : dict or None;  clearance : float, m
        :func:`vfit_engine.pattern.placement.place`.
    settings : DrapeSettings or None

    Returns
    -------
    DrapeSetup
        ``reference`` is ``body`` (a pattern is not made on another body); ``seams`` the pairs to sew,
        ``pattern`` their names (:class:`PatternLabels`).
    """
    t0 = time.perf_counter()
    st = settings or DrapeSettings()
    if not (np.isfinite(spacing) and 0.003 <= spacing <= 0.1):
        raise InputError(f"cloth spacing {1000 * spacing:g} mm is outside 3-100 mm")
    mat = resolve_material(material)
    tris = model.body_tris
    with ThreadPoolExecutor(1) as pool:  # the collider builds in Numba (GIL released) while the pattern is meshed
        building = pool.submit(MeshCollider, body.surface, tris, skin=st.contact.skin, friction=st.contact.friction)
        cloth = mesh_pattern(pattern, spacing)
        placement = place(pattern, BodyParts.from_model(model, body.verts), mapping, clearance, arrange)
        start = np.zeros((cloth.vertex_count, 3))
        for k, name in enumerate(cloth.panel_names):
            sel = cloth.vertex_panel == k
            start[sel] = placement.to_body(name, cloth.uv[sel])
        garment = pattern_garment(pattern, cloth)
        parts = skin_parts(model)
        collide = building.result()
    seams = np.asarray(cloth.seam_pairs, dtype=np.int64).reshape(-1, 2)
    keep = seams[:, 0] != seams[:, 1]  # a dart's tip is sewn to itself: it is one vertex already
    seams = seams[keep]
    ground = ground_height(body.surface, st.contact.skin) if st.ground else None
    info = dict(placement=dict(method=dict(placement.method), pushed=dict(placement.pushed)),
                transfer=dict(identity=True, method="none"), rest="pattern", made_on=None, ground_y_m=ground,
                pattern=dict(source=str(pattern.source), panel_count=len(pattern.panels),
                             stitches=len(pattern.stitches), seam_pairs=int(seams.shape[0]),
                             spacing_mm=round(1000.0 * spacing, 3), frame=pattern.frame),
                setup_time_s=time.perf_counter() - t0)
    pins = Pins(np.zeros(0, np.int64), np.zeros((0, 3)), dict(mode="none", count=0, dropped_inside=0,
                                                                released_stretched=0, refitted_groups=0,
                                                                pieces=None, warnings=[]))
    return DrapeSetup(garment, np.ascontiguousarray(garment.verts), np.ascontiguousarray(start), body, body, tris,
                      mat, pins, [], [], collide, "mesh", None, None, info, parts, ground, seams,
                      PatternLabels.of(pattern, cloth, keep))
