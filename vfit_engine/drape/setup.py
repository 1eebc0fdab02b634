"""Set up a drape: the garment placed on the body it was made for, moved to the target body, pinned.

:func:`prepare_drape` is the one set-up the CLI, the scripts, the benchmarks and the tests use:

1. **placement** (:func:`vfit_engine.garment.placement.place_garment`): the garment on the body it
   was made for (``reference``, MakeHuman's average body of its gender), as its file places it or,
   when the file is elsewhere, by its ``.mhclo`` binding; a garment away from the body without a
   binding is refused;
2. **start** (:func:`vfit_engine.garment.transfer.transfer_garment`): the placed garment moved to the
   target body (``auto``: by its binding's change, else by dual-quaternion skinning of the body's
   ARAP frames). This only makes the starting shape;
3. **rest shape**: the garment as given -- its own size (``rest="garment"``, the default: a size M
   shirt on a large body is tight, and the report says where) -- or, as an explicit
   made-to-measure mode, the garment graded to the body (``rest="graded"``: the moved garment);
4. **pins** (:mod:`vfit_engine.garment.pins`, :mod:`vfit_engine.garment.pin_fit`): the waistbands of
   bottoms and the shoulders of tops, attached to the body and fitted on it;
5. **openings** (:func:`vfit_engine.garment.openings.check_openings`): each opening smaller than the
   body part it goes round must stretch at least so much; the cloth round it may;
6. **colliders**: the exact body mesh (always built: the metrics and the untangling use it) and, on
   request, shapes fitted to the body (:mod:`vfit_engine.drape.colliders`); the ground under the body
   (:func:`ground_height`).
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from vfit_engine.body.resolve import default_body
from vfit_engine.body.segment import skin_parts
from vfit_engine.collide.body_mesh import MeshCollider
from vfit_engine.drape.colliders import COLLIDERS, fitted_collider
from vfit_engine.drape.settings import DrapeSettings
from vfit_engine.errors import InputError
from vfit_engine.garment.openings import BodyLoops, check_openings, fit_openings
from vfit_engine.garment.pin_fit import PinAttachment, fit_pins
from vfit_engine.garment.pins import auto_pins
from vfit_engine.garment.placement import made_on, place_garment
from vfit_engine.garment.transfer import transfer_garment
from vfit_engine.sim.materials import resolve_material

#: How the cloth's rest lengths are chosen (module docstring, step 3).
REST_MODES = ("garment", "graded")
#: The ground lies this much (m) more than twice the cloth's clearance below the body's lowest point: cloth caught
#: under a sole keeps its clearance from both, instead of being pushed to and fro between them.
GROUND_SLACK = 0.001


def ground_height(body_surface, skin):
    """Height (m, y) of the ground under ``body_surface`` (V, 3) m: ``2 skin + GROUND_SLACK`` below its lowest
    point (its soles, standing; whatever is lowest in another pose)."""
    return float(np.min(body_surface[:, 1])) - 2.0 * skin - GROUND_SLACK


@dataclass
class Pins:
    """Pinned garment vertices and where they go on the body.

    Attributes
    ----------
    indices : (p,) int64
    targets : (p, 3) float64, m
    info : dict
        ``mode``, ``count``, ``dropped_inside``, ``released_stretched``, ``refitted_groups``, per-piece
        ``pieces`` and ``gap_mm`` (max/mean distance of the started pins from their targets).
    """

    indices: np.ndarray
    targets: np.ndarray
    info: dict = field(default_factory=dict)


@dataclass
class DrapeSetup:
    """Everything a drape needs (:func:`prepare_drape`).

    Attributes
    ----------
    garment : Garment
        The garment as given (metres; its vertices give the garment's own size).
    rest : (n, 3) float64, m
        The cloth's rest shape: ``garment.verts`` or, graded, ``start``.
    start : (n, 3) float64, m
        Where the cloth starts on ``body``.
    body, reference : Body
        The body draped on; the body the garment was made for.
    body_tris : (T, 3) int64
    material : Material
    pins : Pins
    openings : list of dict
        :func:`vfit_engine.garment.openings.check_openings` of the rest shape at the start.
    zones : list of ((k,) int64, float)
        The cloth round each opening the body forces wider and the strain that opening must take
        (:func:`vfit_engine.garment.openings.fit_openings`, which also fitted the loop round the body).
    collider : MeshCollider
        The exact body.
    collider_kind : str
    spheres : (S, 4) float64 or None;  project : LimitedPush or None
        A fitted sphere set, or an ellipsoid/hull collider (``collider_kind`` other than ``mesh``).
    info : dict
        ``placement``, ``transfer``, ``rest``, ``made_on`` (the body size the garment was made for),
        ``setup_time_s``.
    body_parts : (V,) int64 or None
        The body part (index into :data:`vfit_engine.body.segment.PARTS`, -1 none) of every body
        surface vertex, to say where the cloth is tight.
    ground : float or None
        Height (m, y) of the ground plane under the body (:func:`ground_height`), None: none.
    seams : (s, 2) int64
        A sewing pattern's vertex pairs to sew (:mod:`vfit_engine.drape.sew`); none for a garment mesh.
    pattern : vfit_engine.drape.sew.PatternLabels or None
        A sewing pattern's panel and seam names and which seam each of ``seams`` belongs to (the per-seam and
        per-panel figures: :mod:`vfit_engine.fit.pattern_fit`); None for a garment mesh.
    """

    garment: object
    rest: np.ndarray
    start: np.ndarray
    body: object
    reference: object
    body_tris: np.ndarray
    material: object
    pins: Pins
    openings: list
    zones: list
    collider: object
    collider_kind: str = "mesh"
    spheres: np.ndarray | None = None
    project: object = None
    info: dict = field(default_factory=dict)
    body_parts: np.ndarray | None = None
    ground: float | None = None
    seams: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    pattern: object = None

    @property
    def rest_mesh(self):
        """MeshData of the rest shape."""
        return self.garment.mesh.with_verts(self.rest)


def garment_gender(garment):
    """"female", "male" or None: the garment's gender from its ``.mhclo`` tags."""
    b = garment.binding()
    return None if b is None else b.gender


def prepare_drape(garment, body, model, reference=None, material="cotton", pin="auto", transfer="auto",
                  rest="garment", collider="mesh", settings=None):
    """Set up the drape of ``garment`` on ``body`` (module docstring).

    Parameters
    ----------
    garment : Garment
        :func:`vfit_engine.garment.garment.load_garment`.
    body : Body
        :func:`vfit_engine.body.resolve.resolve_body`.
    model : BodyModel
    reference : Body or None
        The body the garment was made for; None: MakeHuman's average body of the garment's gender
        (its ``.mhclo`` tags), else of the body's, else female.
    material : str, Path or Material
    pin : "auto", "none" or (p,) int
        Garment vertex indices to pin, or ``auto`` (waistbands and shoulders) or ``none``.
    transfer : {"auto", "mhclo", "mhclo-delta", "dqs", "lbs", "none"}
    rest : {"garment", "graded"}
    collider : {"mesh", "spheres", "bone-spheres", "ellipsoids", "hulls"}
    settings : DrapeSettings or None

    Returns
    -------
    DrapeSetup
    """
    t0 = time.perf_counter()
    st = settings or DrapeSettings()
    if rest not in REST_MODES:
        raise InputError(f"unknown rest shape {rest!r}; use {' or '.join(REST_MODES)}")
    if collider not in COLLIDERS:
        raise InputError(f"unknown collider {collider!r}; use one of {', '.join(COLLIDERS)}")
    mat = resolve_material(material)
    binding = garment.binding()
    if reference is None:
        gender = garment_gender(garment) or (body.gender if isinstance(body.gender, str) else None) or "female"
        reference = default_body(model, gender)
    tris = model.body_tris
    with ThreadPoolExecutor(1) as pool:
        # the collider's build runs in Numba kernels that release the GIL: it overlaps the placement,
        # pins and openings, which do not need it
        building = pool.submit(MeshCollider, body.surface, tris, skin=st.contact.skin, friction=st.contact.friction)
        placed, placement = place_garment(garment.verts, reference, binding, name=garment.source.name)
        start, tinfo = transfer_garment(placed, reference.verts, body.verts, tris, transfer, binding)
        moved = not (tinfo["identity"] or tinfo["method"] == "none")
        graded = rest == "graded" and moved
        rest_pos = start if graded else garment.verts
        pins = _pins(garment, rest_pos, placed, start, body, reference, tris, pin, graded, st)
        rest_mesh = garment.mesh.with_verts(rest_pos)
        loops = BodyLoops(body.surface, tris)
        openings = check_openings(rest_mesh, body.surface, tris, skin=st.contact.skin, pos=start, loops=loops)
        start, zones = fit_openings(rest_mesh, start, openings, body.surface, tris, st.contact.skin,
                                    st.stretch_zone, pins.indices, loops=loops)
        parts = skin_parts(model)  # while the collider builds (the set-up ends waiting for it)
        collide = building.result()
    spheres = project = None
    if collider != "mesh":
        spheres, project = fitted_collider(collider, model, body, collide, st)
    ground = ground_height(body.surface, st.contact.skin) if st.ground else None
    info = dict(placement=placement, transfer=tinfo, rest="graded" if graded else "garment",
                made_on=made_on(binding, reference, body), ground_y_m=ground, setup_time_s=time.perf_counter() - t0)
    return DrapeSetup(garment, np.ascontiguousarray(rest_pos), np.ascontiguousarray(start), body, reference, tris,
                      mat, pins, openings, zones, collide, collider, spheres, project, info, parts, ground)


def _pins(garment, rest_pos, placed, start, body, reference, tris, pin, graded, st):
    """Pins (indices, targets on ``body``) of the garment (module docstring, step 4)."""
    mesh = garment.mesh
    info = None
    if isinstance(pin, str) and pin == "auto":
        idx, info = auto_pins(mesh.with_verts(start), body.surface, tris, pieces=garment.pieces)
    elif isinstance(pin, str) and pin == "none":
        idx = np.zeros(0, np.int64)
    elif isinstance(pin, str):
        raise InputError(f"unknown pin mode {pin!r}; use auto, none or a pin file")
    else:
        idx = np.unique(np.asarray(pin, dtype=np.int64).ravel())
        if idx.size and (idx[0] < 0 or idx[-1] >= mesh.n_verts):
            raise InputError(f"pin index out of range 0..{mesh.n_verts - 1}")
    summary = dict(mode=pin if isinstance(pin, str) else "file", dropped_inside=0, released_stretched=0,
                   refitted_groups=0,
                   pieces=None if info is None else [{k: p[k] for k in ("piece", "kind", "method", "n_pins")}
                                                     for p in info["pieces"]],
                   warnings=[] if info is None else list(info.get("warnings", [])))
    targets = np.zeros((0, 3))
    if idx.size:
        # graded: the moved garment is the pattern on this body, pinned where it is on it; else the
        # pins are bound to the body the garment was made for and follow it onto this one
        src_pos, src_body = (start, body.surface) if graded else (placed, reference.surface)
        att = PinAttachment.attach(src_pos, idx, src_body, tris)
        # a pin inside (or within the skin of) the body would be moved out while its pinned
        # neighbours stay put, stretching the cloth between them: it stays free instead
        keep = att.offset >= st.contact.skin
        summary["dropped_inside"] = int(np.count_nonzero(~keep))
        idx, att = idx[keep], att.select(keep)
    if idx.size:
        idx, att, targets, fit = fit_pins(mesh.with_verts(rest_pos), idx, att, body.surface, tris, st.contact.skin,
                                          st.pin_strain, st.pin_fit_strain, chord_skin=st.contact.surface_skin)
        summary.update(fit)
    summary["count"] = int(idx.size)
    if idx.size:
        gap = 1000.0 * np.linalg.norm(start[idx] - targets, axis=1)
        summary["gap_mm"] = dict(max=float(gap.max()), mean=float(gap.mean()))
    return Pins(np.ascontiguousarray(idx, dtype=np.int64), np.ascontiguousarray(targets, dtype=np.float64), summary)
