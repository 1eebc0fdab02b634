"""Pin targets on a morphed body: pinned loops spread evenly, patches moved rigidly, the rest released.

A pin follows the body triangle it was attached to on the reference body
(:class:`PinAttachment`). On a wider body the triangles under a waistband
spread apart unevenly (the morph widens the sides more than the front), so the band between
pins would be stretched locally by far more than its mean stretch: 2-10 % against 8 % on
average for a +5 cm waist, and the release of over-stretched pins then leaves a few pins
holding the whole band (30 % local strain). A *pinned loop* (a boundary loop of the garment
whose vertices are pinned: a waistband) is therefore refitted as a whole (:func:`fit_loop`):

1. the band first uses up its ease: every pin's height above the body is lowered by the same
   amount (never below the skin) until the loop through the targets is no longer than the
   band's rest length, or the pins touch the skin;
2. the pins are then spread along that loop at the relative arc-length positions they have on
   the garment, rotated as a whole by the least tangential shift, so whatever stretch remains
   is shared evenly by every edge of the band;
3. a target the chords brought within the skin is lifted back out along its triangle's normal.

The other pins form *patches* (pins joined by springs: a shoulder). A patch some spring of which
following the triangles would stretch is moved rigidly instead (:func:`fit_patch`), so the cloth
between its pins keeps its length, and is lifted out of the body where the body grew.

Of two pins joined by a spring that would still be stretched more than ``pin_strain`` the later
one is released (:func:`release_stretched`). Pins of one refitted group are not released against
each other: a loop's stretch is even and is the least the body allows (dropping pins would not
shorten it), a rigid patch is stretched only where it was lifted out.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from vfit_engine.garment.pins import attach_to_body, attached_positions
from vfit_engine.geometry import closed_loops
from vfit_engine.sim.springs import build_springs


@dataclass
class PinAttachment:
    """Garment vertices bound to a body surface.

    Attributes
    ----------
    indices : (p,) int64
        Pinned garment vertices.
    tri : (p,) int64
        Body triangle of each pin.
    bary : (p, 3) float64
        Barycentric coordinates of the closest point (the foot) on that triangle.
    local : (p, 3) float64, m
        Pin minus foot in the triangle's frame (first edge, in-plane perpendicular, normal), so
        the pin turns and moves with its triangle.
    offset : (p,) float64, m
        The normal component of ``local``: the pin's height above the body surface.
    """

    indices: np.ndarray
    tri: np.ndarray
    bary: np.ndarray
    local: np.ndarray

    @property
    def offset(self):
        return self.local[:, 2]

    @classmethod
    def attach(cls, garment_pos, indices, body_verts, body_tris):
        """Bind ``garment_pos[indices]`` (m) to the body ``body_verts`` (m), ``body_tris``."""
        idx = np.asarray(indices, dtype=np.int64).ravel()
        pts = np.asarray(garment_pos, dtype=np.float64)[idx]
        tri, bary = attach_to_body(pts, body_verts, body_tris)
        foot = attached_positions(tri, bary, body_verts, body_tris)
        frame = _tri_frames(body_verts, body_tris, tri)
        return cls(idx, tri, bary, np.einsum("pij,pj->pi", frame, pts - foot))

    def select(self, keep):
        """The attachment of the pins where ``keep`` (p,) bool is true."""
        return PinAttachment(self.indices[keep], self.tri[keep], self.bary[keep], self.local[keep])

    def positions(self, body_verts, body_tris, min_offset=0.0):
        """(p, 3) float64 m: the pins on ``body_verts`` (same topology), height >= ``min_offset``."""
        foot = attached_positions(self.tri, self.bary, body_verts, body_tris)
        local = self.local.copy()
        local[:, 2] = np.maximum(local[:, 2], min_offset)
        return foot + np.einsum("pij,pi->pj", _tri_frames(body_verts, body_tris, self.tri), local)


def _tri_frames(verts, tris, which):
    """(p, 3, 3) orthonormal rows (edge direction, in-plane perpendicular, unit normal) of triangles."""
    t = np.asarray(tris, dtype=np.int64)[which]
    v = np.asarray(verts, dtype=np.float64)
    e1 = v[t[:, 1]] - v[t[:, 0]]
    n = np.cross(e1, v[t[:, 2]] - v[t[:, 0]])
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.stack([e1, np.cross(n, e1), n], axis=1)


def pinned_loops(mesh, idx, min_share=0.5):
    """Closed boundary loops of ``mesh`` that are mostly pinned.

    Parameters
    ----------
    mesh : MeshData
    idx : (p,) int64
        Sorted pinned vertices.
    min_share : float
        Least share of a loop's vertices that must be pinned.

    Returns
    -------
    list of ((q,) int64, (q,) float64)
        The pinned vertices of each loop in walking order and the rest arc length (m) from each
        to the next one along the loop (the last wraps to the first).
    """
    pinned = np.zeros(mesh.n_verts, dtype=bool)
    pinned[idx] = True
    out = []
    for ring in closed_loops(mesh):
        on = pinned[ring]
        if on.sum() < 3 or on.mean() < min_share:
            continue
        p = mesh.verts[ring]
        seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        at = np.flatnonzero(on)
        gaps = np.diff(np.append(arc[at], arc[-1] + arc[at[0]]))
        out.append((ring[at].astype(np.int64), gaps))
    return out


def _loop_length(p):
    return float(np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum())


def _lift_out(p, body_verts, body_tris, skin):
    """``p`` (q, 3) m with every point within ``skin`` of the body moved out along its triangle's normal."""
    tri, bary = attach_to_body(p, body_verts, body_tris)
    foot = attached_positions(tri, bary, body_verts, body_tris)
    n = _tri_frames(body_verts, body_tris, tri)[:, 2]
    h = np.einsum("ij,ij->i", p - foot, n)
    return p + np.maximum(skin - h, 0.0)[:, None] * n


def _bisect(too_long, lo, hi, steps=40):
    """Smallest x in [lo, hi] with ``too_long(x)`` false (``hi`` if none), for a monotone predicate."""
    if not too_long(lo):
        return lo
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if too_long(mid):
            lo = mid
        else:
            hi = mid
    return hi


def fit_loop(att, body_verts, body_tris, rest_gaps, skin):
    """Targets (q, 3) m of one pinned loop on ``body_verts`` (module docstring, steps 1-3).

    Parameters
    ----------
    att : PinAttachment
        The loop's pins, in walking order.
    body_verts : (N, 3) float64, m
    body_tris : (T, 3) int64
    rest_gaps : (q,) float64, m
        Rest arc length from each pin to the next.
    skin : float, m
        Least height of a pin above the body.
    """
    rest = float(np.sum(rest_gaps))
    off = att.offset
    foot = attached_positions(att.tri, att.bary, body_verts, body_tris)
    frames = _tri_frames(body_verts, body_tris, att.tri)

    def targets(drop):
        local = att.local.copy()
        local[:, 2] = np.maximum(off - drop, skin)
        return foot + np.einsum("pij,pi->pj", frames, local)

    drop = _bisect(lambda d: _loop_length(targets(d)) > rest, 0.0, max(float(off.max()) - skin, 0.0))
    q = targets(drop)
    seg = np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    total = arc[-1]
    want = np.concatenate([[0.0], np.cumsum(rest_gaps)[:-1]]) * (total / rest)
    # the rotation of the whole band that moves the pins least along the loop
    shift = (arc[:-1] - want + 0.5 * total) % total - 0.5 * total
    s = (want + float(np.mean(shift))) % total
    k = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, len(q) - 1)
    t = ((s - arc[k]) / np.where(seg[k] > 0, seg[k], 1.0))[:, None]
    return _lift_out(q[k] + t * (np.roll(q, -1, axis=0)[k] - q[k]), body_verts, body_tris, skin)


def release_stretched(mesh, idx, target, pin_strain, groups=None, springs=None):
    """Pins to release so that no spring between two kept pins is stretched over ``pin_strain``.

    Parameters
    ----------
    mesh : MeshData
        The garment as given (rest lengths).
    idx : (p,) int64;  target : (p, 3) float64, m
        Pins and their targets.
    pin_strain : float
    groups : (p,) int64 or None
        Pins sharing a group >= 0 (one refitted loop or patch) are not checked against each other.
    springs : (s, 2) int64 or None
        The garment's spring pairs (built when None).

    Returns
    -------
    (p,) bool
    """
    # every spring pair (edges, quad diagonals, second neighbours), so that a released pin
    # is not left between two pins that are still too far apart
    edges = build_springs(mesh.face_verts, mesh.face_offsets, mesh.verts).indices if springs is None else springs
    slot = np.full(mesh.n_verts, -1, dtype=np.int64)
    slot[idx] = np.arange(idx.size)
    both = edges[(slot[edges[:, 0]] >= 0) & (slot[edges[:, 1]] >= 0)]
    release = np.zeros(idx.size, dtype=bool)
    if both.size:
        a, b = slot[both[:, 0]], slot[both[:, 1]]
        if groups is not None:
            same = (groups[a] >= 0) & (groups[a] == groups[b])
            a, b, both = a[~same], b[~same], both[~same]
        rest = np.linalg.norm(mesh.verts[both[:, 1]] - mesh.verts[both[:, 0]], axis=1)
        strain = np.linalg.norm(target[b] - target[a], axis=1) / np.maximum(rest, 1e-12) - 1.0
        release[np.maximum(a, b)[strain > pin_strain]] = True
    return release


def fit_pins(mesh, idx, att, body_verts, body_tris, skin, pin_strain, fit_strain, chord_skin=None):
    """Targets of all pins on ``body_verts`` (module docstring).

    Parameters
    ----------
    mesh : MeshData
        Garment as given.
    idx : (p,) int64;  att : PinAttachment
        Pins (sorted) and their attachment to the reference body.
    body_verts : (N, 3) float64, m;  body_tris : (T, 3) int64
    skin : float, m
    pin_strain : float
    fit_strain : float
        A pinned loop or patch is refitted only when a spring between two of its pins would be
        stretched more than this by following the triangles (a body the garment fits keeps them).
    chord_skin : float or None, m
        Clearance of the edges between pins (:func:`lift_chords`; default ``skin / 2``).

    Returns
    -------
    idx : (k,) int64;  att : PinAttachment;  target : (k, 3) float64, m
        The pins kept.
    info : dict
        ``released_stretched``, ``refitted_groups`` (loops and patches) and ``lifted_for_chords``
        (:func:`lift_chords`) counts.
    """
    target = att.positions(body_verts, body_tris, min_offset=skin)
    groups = np.full(idx.size, -1, dtype=np.int64)
    refitted = 0
    for ring, gaps in pinned_loops(mesh, idx):
        at = np.searchsorted(idx, ring)
        t = target[at]
        strain = np.linalg.norm(np.roll(t, -1, axis=0) - t, axis=1) / np.maximum(gaps, 1e-12) - 1.0
        if strain.max() <= fit_strain:
            continue
        keep = np.zeros(idx.size, dtype=bool)
        keep[at] = True
        fitted = fit_loop(_reorder(att.select(keep), at), body_verts, body_tris, gaps, skin)
        target[at] = fitted
        groups[at] = refitted
        refitted += 1
    springs = build_springs(mesh.face_verts, mesh.face_offsets, mesh.verts).indices
    for comp in _patches(springs, idx, groups):
        strain = _pair_strain(mesh, springs, idx[comp], target[comp])
        if strain.size == 0 or strain.max() <= fit_strain:
            continue
        target[comp] = fit_patch(mesh.verts[idx[comp]], target[comp], body_verts, body_tris, skin)
        groups[comp] = refitted
        refitted += 1
    release = release_stretched(mesh, idx, target, pin_strain, groups, springs)
    idx, att, target = idx[~release], att.select(~release), target[~release]
    chord_skin = 0.5 * skin if chord_skin is None else chord_skin
    target, lifted = lift_chords(mesh, idx, target, body_verts, body_tris, chord_skin)
    return (idx, att, target, dict(released_stretched=int(np.count_nonzero(release)), refitted_groups=refitted,
                                   lifted_for_chords=lifted))


#: Points along each edge between two pins that :func:`lift_chords` keeps out of the body, and its rounds.
CHORD_SAMPLES = 7
CHORD_ROUNDS = 3
#: A pin is lifted at most this far in all (m): an edge deeper in than a bulge can explain (through an arm)
#: is not the pins' to fix.
CHORD_MAX_LIFT = 0.01


def lift_chords(mesh, idx, target, body_verts, body_tris, skin):
    """Targets with every garment edge between two pins ``skin`` clear of the body along its length.

    Pins sit above the body, but the straight edge between two of them cuts into it where the body
    bulges between them (a waistband's edge over a belly: 2-3 mm into a body 8-15 cm wider at the
    waist), and no contact can push it out -- both its ends are pinned. Each such edge's deepest
    sample below ``skin`` lifts both its ends by that much along their triangles' normals
    (``CHORD_ROUNDS`` times: a lift can bring a neighbouring edge in; at most ``CHORD_MAX_LIFT`` in
    all). ``skin`` is the clearance the contact points inside the cloth's triangles keep (half the
    vertices'), so the edges of pins the vertex clearance apart on a gently curved body stay as they are.

    Returns
    -------
    target : (p, 3) float64, m
    lifted : int
        Pins lifted.
    """
    target = np.array(target, dtype=np.float64)
    slot = np.full(mesh.n_verts, -1, dtype=np.int64)
    slot[idx] = np.arange(idx.size)
    e = mesh.edges()
    e = e[(slot[e[:, 0]] >= 0) & (slot[e[:, 1]] >= 0)]
    a, b = slot[e[:, 0]], slot[e[:, 1]]
    t = np.linspace(0.0, 1.0, CHORD_SAMPLES + 2)[1:-1]
    moved = np.zeros(idx.size, dtype=bool)
    total = np.zeros(idx.size)
    for _ in range(CHORD_ROUNDS if e.size else 0):
        pts = (target[a][:, None, :] * (1.0 - t)[None, :, None] + target[b][:, None, :] * t[None, :, None])
        tri, bary = attach_to_body(pts.reshape(-1, 3), body_verts, body_tris)
        foot = attached_positions(tri, bary, body_verts, body_tris)
        normal = _tri_frames(body_verts, body_tris, tri)[:, 2]
        height = np.einsum("ij,ij->i", pts.reshape(-1, 3) - foot, normal).reshape(len(e), -1)
        deficit = np.maximum(skin - height.min(axis=1), 0.0)
        if not np.any(deficit > 1e-6):
            break
        lift = np.zeros(idx.size)
        np.maximum.at(lift, a, deficit)
        np.maximum.at(lift, b, deficit)
        lift = np.minimum(lift, CHORD_MAX_LIFT - total)
        up = lift > 1e-9
        tri, bary = attach_to_body(target[up], body_verts, body_tris)
        target[up] += lift[up, None] * _tri_frames(body_verts, body_tris, tri)[:, 2]
        total += lift
        moved |= up
    return target, int(np.count_nonzero(moved))


def _pair_strain(mesh, springs, pins, target):
    """Strain of the springs joining two of ``pins`` (q,) whose ends are at ``target`` (q, 3)."""
    slot = np.full(mesh.n_verts, -1, dtype=np.int64)
    slot[pins] = np.arange(pins.size)
    both = springs[(slot[springs[:, 0]] >= 0) & (slot[springs[:, 1]] >= 0)]
    a, b = slot[both[:, 0]], slot[both[:, 1]]
    rest = np.linalg.norm(mesh.verts[both[:, 1]] - mesh.verts[both[:, 0]], axis=1)
    return np.linalg.norm(target[b] - target[a], axis=1) / np.maximum(rest, 1e-12) - 1.0


def _patches(springs, idx, groups):
    """Connected groups (index arrays into ``idx``) of the pins not yet in a group, joined by springs."""
    free = groups < 0
    slot = np.full(int(max(springs.max(), idx.max())) + 1, -1, dtype=np.int64)
    slot[idx[free]] = np.arange(int(free.sum()))
    e = slot[springs]
    e = e[(e[:, 0] >= 0) & (e[:, 1] >= 0)]
    k = int(free.sum())
    if k == 0:
        return []
    n, lab = connected_components(sparse.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(k, k)),
                                  directed=False)
    where = np.flatnonzero(free)
    return [where[lab == c] for c in range(n) if np.count_nonzero(lab == c) >= 3]


def fit_patch(rest_pos, follow, body_verts, body_tris, skin):
    """Targets (q, 3) m of a patch of pins moved rigidly (Kabsch 1976) onto where its triangles went.

    The rotation and translation best mapping the pins as given (``rest_pos``) onto their
    triangle-following targets (``follow``) keep every distance between the pins; a target then
    within the skin of the body is lifted out along its triangle's normal.
    """
    ca, cb = rest_pos.mean(axis=0), follow.mean(axis=0)
    u, _, vt = np.linalg.svd((rest_pos - ca).T @ (follow - cb))
    d = np.sign(np.linalg.det(u @ vt))
    rot = u @ np.diag([1.0, 1.0, d]) @ vt
    p = (rest_pos - ca) @ rot + cb
    tri, bary = attach_to_body(p, body_verts, body_tris)
    foot = attached_positions(tri, bary, body_verts, body_tris)
    n = _tri_frames(body_verts, body_tris, tri)[:, 2]
    h = np.einsum("ij,ij->i", p - foot, n)
    return p + np.maximum(skin - h, 0.0)[:, None] * n


def _reorder(sub, at):
    """``sub`` (pins in sorted order) rearranged into the loop order given by ``at``."""
    rank = np.argsort(np.argsort(at))  # position of each loop pin among the sorted selection
    return PinAttachment(sub.indices[rank], sub.tri[rank], sub.bary[rank], sub.local[rank])

