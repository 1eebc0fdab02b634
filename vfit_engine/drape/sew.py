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
        ``reference`` is ``body`` (a pattern is not made on another body); ``seams`` the pairs to sew.
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
    seams = seams[seams[:, 0] != seams[:, 1]]  # a dart's tip is sewn to itself: it is one vertex already
    ground = ground_height(body.surface, st.contact.skin) if st.ground else None
    info = dict(placement=dict(method=dict(placement.method), pushed=dict(placement.pushed)),
                transfer=dict(identity=True, method="none"), rest="pattern", made_on=None, ground_y_m=ground,
                pattern=dict(source=str(pattern.source), panels=len(pattern.panels), stitches=len(pattern.stitches),
                             seam_pairs=int(seams.shape[0]), spacing_mm=round(1000.0 * spacing, 3),
                             frame=pattern.frame),
                setup_time_s=time.perf_counter() - t0)
    pins = Pins(np.zeros(0, np.int64), np.zeros((0, 3)), dict(mode="none", count=0, dropped_inside=0,
                                                                released_stretched=0, refitted_groups=0,
                                                                pieces=None, warnings=[]))
    return DrapeSetup(garment, np.ascontiguousarray(garment.verts), np.ascontiguousarray(start), body, body, tris,
                      mat, pins, [], [], collide, "mesh", None, None, info, parts, ground, seams)
