"""Move a garment made for one body onto another body of the same (hm08) topology.

Methods
-------
mhclo
    Re-evaluate the garment's MakeHuman ``.mhclo`` binding on the target body (MakeHuman's own
    proxy fitting). The garment's input positions are not used, only their count: the result is the
    binding's fit, which differs from the authored OBJ by the binding's residual (2-3 cm for the
    shared MakeHuman suits on vfit's default bodies).
mhclo-delta
    ``x + fit(target) - fit(source)``: the binding's displacement added to the garment as given, so a
    garment that was edited or draped keeps its shape and ``source == target`` is exactly the identity.
lbs, dqs
    ARAP frames + skinning (as in garment adaptation for high-end customisation). Every body vertex
    i gets a rigid transform: the rotation ``R_i`` that maps its cotangent-weighted 1-ring from the
    source body to the target as rigidly as possible (``arap.arap_rotations``) about the source
    vertex ``p_i``, then the target position ``q_i``. A garment vertex x bound to its K nearest
    source-body vertices with weights w_i moves to ``sum_i w_i (R_i (x - p_i) + q_i)`` by linear
    blend skinning (lbs), or by dual-quaternion skinning (dqs, Kavan et al. 2008), which blends the
    same transforms without LBS's shrinking where the rotations differ.
none
    The garment unchanged (a baseline).

Only the 13,380 visible body vertices and the body quads (triangulated) drive lbs/dqs; helper
vertices, when given, are ignored there.
"""
from __future__ import annotations

import time
from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree

from vfit_engine.body.model import N_BODY, N_VERTS, BodyModel
from vfit_engine.collide.body_mesh import mesh_normals
from vfit_engine.errors import InputError
from vfit_engine.garment.arap import arap_rotations, check_points, cotangent_weights, edge_incidence
from vfit_engine.garment.mhclo import evaluate_mhclo
from vfit_engine.rotations import dual_quat_to_rigid, rigid_to_dual_quat

METHODS = ("auto", "mhclo", "mhclo-delta", "dqs", "lbs", "none")
#: Nearest body vertices per garment vertex; 6 is the sweet spot found by the garment-adaptation seed.
DEFAULT_K = 6
MAX_K = 64


@lru_cache(maxsize=1)
def _default_model():
    return BodyModel.load()


class BodyFrames:
    """The source body prepared once (cotangent weights, 1-ring incidence, nearest-vertex tree).

    Parameters
    ----------
    source_body : (13380 or 19158, 3) float64, m
        Only the first 13,380 (visible body) vertices are used.
    tris : (t, 3) int64
        Body triangles (``BodyModel.body_tris``), indices < 13,380.
    """

    def __init__(self, source_body, tris):
        source_body = check_points(source_body, "source body", (N_BODY, N_VERTS))
        self.source = np.ascontiguousarray(source_body[:N_BODY])
        self.tris = np.ascontiguousarray(tris, dtype=np.int64)
        if self.tris.ndim != 2 or self.tris.shape[1] != 3 or self.tris.max() >= N_BODY or self.tris.min() < 0:
            raise InputError("body triangles must be (t, 3) indices into the 13,380 body vertices")
        self.edges, self.weights = cotangent_weights(self.source, self.tris)
        self.incidence = edge_incidence(self.edges, N_BODY)
        self._tree = None

    @property
    def tree(self):
        """scipy cKDTree over the source body vertices (built on first use)."""
        if self._tree is None:
            self._tree = cKDTree(self.source)
        return self._tree

    def rotations(self, target_body):
        """(13380, 3, 3) float64: ARAP rotation of every body vertex from the source to ``target_body``."""
        target_body = check_points(target_body, "target body", (N_BODY, N_VERTS))
        return arap_rotations(self.source, target_body[:N_BODY], self.edges, self.weights, self.incidence)

    def bind(self, points, k=DEFAULT_K):
        """Bind points to their ``k`` nearest source-body vertices.

        Distances are normalised by the distance ``d_{k+1}`` to the (k+1)-th nearest vertex,
        ``r_i = d_i / d_{k+1}``, and ``w_i = (1 - r_i^2)^2`` (then summed to 1): a vertex's weight
        falls to zero just as it leaves the k nearest, so the binding is continuous over the garment.

        Parameters
        ----------
        points : (n, 3) float64, m
        k : int

        Returns
        -------
        idx : (n, k) int64
        weights : (n, k) float64, rows summing to 1
        """
        d, idx = self.tree.query(points, k=k + 1)
        r = d[:, :k] / np.maximum(d[:, k:k + 1], 1e-300)
        w = (1.0 - np.minimum(r, 1.0) ** 2) ** 2
        s = w.sum(axis=1, keepdims=True)
        # ties at the (k+1)-th distance can zero every weight: fall back to equal weights there
        w = np.where(s > 0, w / np.where(s > 0, s, 1.0), 1.0 / k)
        return np.ascontiguousarray(idx[:, :k], dtype=np.int64), w

    def transfer(self, points, target_body, method="dqs", k=DEFAULT_K, rotations=None, binding=None):
        """Move ``points`` from the source body to ``target_body`` by ``lbs`` or ``dqs``.

        Parameters
        ----------
        points : (n, 3) float64, m
        target_body : (13380 or 19158, 3) float64, m
        method : {"dqs", "lbs"}
        k : int
        rotations : (13380, 3, 3) or None
            ``self.rotations(target_body)`` when already computed.
        binding : (idx, weights) or None
            ``self.bind(points, k)`` when already computed.

        Returns
        -------
        (n, 3) float64, m
        """
        target = check_points(target_body, "target body", (N_BODY, N_VERTS))[:N_BODY]
        rot = self.rotations(target) if rotations is None else rotations
        idx, w = self.bind(points, k) if binding is None else binding
        if method == "lbs":
            return blend_lbs(points, idx, w, rot, self.source, target)
        if method == "dqs":
            return blend_dqs(points, idx, w, rot, self.source, target)
        raise InputError(f"unknown skinning method {method!r}; use lbs or dqs")


def blend_lbs(points, idx, weights, rot, source, target):
    """Linear blend skinning: ``x' = sum_i w_i (R_i (x - p_i) + q_i)``.

    Parameters
    ----------
    points : (n, 3) float64, m
    idx : (n, k) int64;  weights : (n, k) float64
    rot : (v, 3, 3) float64
    source, target : (v, 3) float64, m
        ``p`` and ``q``.

    Returns
    -------
    (n, 3) float64, m
    """
    local = points[:, None, :] - source[idx]  # (n, k, 3)
    moved = np.einsum("nkij,nkj->nki", rot[idx], local) + target[idx]
    return np.einsum("nk,nki->ni", weights, moved)


def blend_dqs(points, idx, weights, rot, source, target, dq=None):
    """Dual-quaternion skinning of the transforms ``x -> R_i x + (q_i - R_i p_i)`` (Kavan et al. 2008).

    Each transform becomes a unit dual quaternion; per point they are summed with weights ``w_i``
    and the sign of each aligned to the first one's rotation (q and -q are the same rotation, the
    shorter path wins), normalised by the real part's length and applied.

    Parameters
    ----------
    points, idx, weights, rot, source, target
        As ``blend_lbs``.
    dq : (real, dual) each (v, 4), or None
        ``rigid_to_dual_quat`` of all body transforms, when already computed.

    Returns
    -------
    (n, 3) float64, m
    """
    if dq is None:
        trans = target - np.einsum("vij,vj->vi", rot, source)
        dq = rigid_to_dual_quat(rot, trans)
    real, dual = dq[0][idx], dq[1][idx]  # (n, k, 4)
    sign = np.where(np.einsum("nkc,nc->nk", real, real[:, 0]) < 0, -1.0, 1.0)
    sw = (weights * sign)[:, :, None]
    r, t = dual_quat_to_rigid((sw * real).sum(axis=1), (sw * dual).sum(axis=1))
    return np.einsum("nij,nj->ni", r, points) + t


def _mhclo_fit(binding, body, which):
    top = binding.top_vertex
    if body.shape[0] <= top:
        raise InputError(
            f"the .mhclo binding uses helper vertices (up to index {top}) that the {which} body lacks "
            f"({body.shape[0]} vertices): mhclo needs the full {N_VERTS}-vertex hm08 body with helpers, "
            f"as vfit builds it from measurements (body files hold only the body); else use dqs")
    return evaluate_mhclo(binding, body)


def transfer(garment_verts, source_body, target_body, method="auto", k=DEFAULT_K, mhclo=None, model=None):
    """Move a garment from ``source_body`` to ``target_body``.

    Parameters
    ----------
    garment_verts : (n, 3) float64, m
        The garment as fitted to ``source_body``.
    source_body, target_body : (13380 or 19158, 3) float64, m
        hm08 bodies (19,158 vertices include the helpers mhclo bindings use). lbs/dqs use the first
        13,380 vertices of each, mhclo only the target, so the two counts may differ.
    method : {"auto", "mhclo", "mhclo-delta", "dqs", "lbs", "none"}
        ``auto``: mhclo when a binding is given, else dqs. See the module docstring.
    k : int
        Body vertices per garment vertex (lbs/dqs), 1..64.
    mhclo : MhcloBinding or None
        The garment's binding (required by mhclo and mhclo-delta).
    model : BodyModel or None
        For the body triangles; None loads the packaged model.

    Returns
    -------
    (n, 3) float64, m
        In the garment's vertex order.

    Raises
    ------
    InputError
        Bad shapes, NaN/inf, an unknown method, a bad k, a missing or mismatched binding, or a body
        without the helper vertices the binding needs.
    """
    if method not in METHODS:
        raise InputError(f"unknown transfer method {method!r}; use one of {', '.join(METHODS)}")
    pts = check_points(garment_verts, "garment vertices")
    if pts.shape[0] == 0:
        raise InputError("garment has no vertices")
    src = check_points(source_body, "source body", (N_BODY, N_VERTS))
    dst = check_points(target_body, "target body", (N_BODY, N_VERTS))
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= MAX_K:
        raise InputError(f"k must be an integer in 1..{MAX_K}, got {k!r}")
    if method == "auto":
        method = "mhclo" if mhclo is not None else "dqs"
    if method == "none":
        return pts.copy()
    if method in ("mhclo", "mhclo-delta"):
        if mhclo is None:
            raise InputError(f"method {method} needs the garment's .mhclo binding")
        if mhclo.n_verts != pts.shape[0]:
            raise InputError(f"the .mhclo binds {mhclo.n_verts} vertices but the garment has {pts.shape[0]}")
        fit = _mhclo_fit(mhclo, dst, "target")
        if method == "mhclo":
            return fit
        return pts + (fit - _mhclo_fit(mhclo, src, "source"))
    model = _default_model() if model is None else model
    frames = BodyFrames(src, model.body_tris)
    return frames.transfer(pts, dst, method=method, k=int(k))


def restore_clearance(garment_verts, moved_verts, reference_verts, body_verts, body_tris, band=0.03):
    """Give each moved garment vertex back the clearance it had from the source body, where it lost some.

    A transfer carries a garment vertex with the body vertices it is bound to, but where the body
    changes shape (a fuller upper arm next to a held girth) the garment can end deeper inside the
    new body than it was in the old one, and the drape must then stretch it out. Here the clearance
    of garment vertex i is measured against its nearest body vertex k on the source body,
    ``d = (x - v_k) . n_k`` (n the vertex normal), and the same vertex k on the target body;
    a vertex that lost clearance (``d_target < d_source``) is moved out along the target normal by
    the loss, at most by how far vertex k itself moved out. Only vertices within ``band`` of the
    source body whose vertex normal turned by less than 60 degrees are touched, and only outward.

    Parameters
    ----------
    garment_verts : (n, 3) float64, m
        The garment on the source body.
    moved_verts : (n, 3) float64, m
        The same garment after the transfer.
    reference_verts, body_verts : (N, 3) float64, m
        Source and target bodies (hm08 topology; the first 13,380 vertices are used).
    body_tris : (T, 3) int64
    band : float, m

    Returns
    -------
    out : (n, 3) float64, m
    restored : (n,) float64, m
        Distance each vertex was moved out.
    """
    ref = np.ascontiguousarray(reference_verts[:N_BODY], dtype=np.float64)
    body = np.ascontiguousarray(body_verts[:N_BODY], dtype=np.float64)
    src = np.asarray(garment_verts, dtype=np.float64)
    out = np.array(moved_verts, dtype=np.float64)
    dist, k = cKDTree(ref).query(src)
    n_src = mesh_normals(ref, body_tris)[3][k]
    n_dst = mesh_normals(body, body_tris)[3][k]
    d_src = np.einsum("ij,ij->i", src - ref[k], n_src)
    d_dst = np.einsum("ij,ij->i", out - body[k], n_dst)
    # the garment cannot have lost more clearance than the skin under it advanced; the cap also
    # keeps a point whose nearest vertex lies across a crease from being thrown out
    advance = np.einsum("ij,ij->i", body[k] - ref[k], n_dst)
    # where the skin turned over (a fold of the new body) the two distances do not compare
    ok = (dist < band) & (np.einsum("ij,ij->i", n_src, n_dst) > 0.5)
    restored = np.where(ok, np.clip(d_src - d_dst, 0.0, np.maximum(advance, 0.0)), 0.0)
    out += restored[:, None] * n_dst
    return out, restored


def transfer_garment(garment_verts, reference_verts, body_verts, body_tris, method="auto", mhclo=None,
                     clearance=True):
    """Move a garment from the body it was modelled on to the body it will be draped on.

    Parameters
    ----------
    garment_verts : (n, 3) float64, m
        The garment as modelled on ``reference_verts``.
    reference_verts, body_verts : (13380 or 19158, 3) float64, m
        hm08 bodies; mhclo methods need the 19,158 vertices with helpers.
    body_tris : (T, 3) int64
    method : {"auto", "mhclo", "mhclo-delta", "dqs", "lbs", "none"}
        :func:`vfit_engine.garment.transfer.transfer`; ``auto`` is ``mhclo-delta`` when a binding is
        given and both bodies have the helper vertices it reads, else ``dqs``.
    mhclo : MhcloBinding or None
    clearance : bool
        After a transfer to another body, :func:`restore_clearance` (skipped for the identity).

    Returns
    -------
    verts : (n, 3) float64, m
    info : dict
        ``requested``, ``method`` used, ``identity`` (same body: every method but mhclo is the
        identity and is not evaluated), ``time_s``, ``max_move_mm``, ``mean_move_mm``,
        ``clearance_restored_mm`` (max and mean over the vertices moved out; None when skipped).
    """
    if method not in METHODS:
        raise InputError(f"unknown transfer method {method!r}; use one of {', '.join(METHODS)}")
    t0 = time.perf_counter()
    pts = np.ascontiguousarray(garment_verts, dtype=np.float64)
    ref = np.ascontiguousarray(reference_verts, dtype=np.float64)
    body = np.ascontiguousarray(body_verts, dtype=np.float64)
    used = method
    if method == "auto":
        fits = mhclo is not None and min(ref.shape[0], body.shape[0]) > mhclo.top_vertex
        used = "mhclo-delta" if fits else "dqs"
    n = min(ref.shape[0], body.shape[0], N_BODY)
    identity = used != "mhclo" and ref.shape[1:] == body.shape[1:] and np.array_equal(ref[:n], body[:n])
    if identity or used == "none":
        out = pts.copy()
    elif used in ("dqs", "lbs"):
        out = BodyFrames(ref, body_tris).transfer(pts, body, method=used)
    else:
        out = transfer(pts, ref, body, method=used, mhclo=mhclo)
    restored_mm = None
    if clearance and not identity and used != "none" and pts.size:
        out, restored = restore_clearance(pts, out, ref, body, body_tris)
        hit = restored > 0
        restored_mm = dict(max=1000.0 * float(restored.max()), mean=1000.0 * float(restored[hit].mean()) if hit.any()
                           else 0.0, vertices=int(hit.sum()))
    move = np.linalg.norm(out - pts, axis=1) if pts.size else np.zeros(1)
    return out, dict(requested=method, method=used, identity=bool(identity), time_s=time.perf_counter() - t0,
                     max_move_mm=1000.0 * float(move.max()), mean_move_mm=1000.0 * float(move.mean()),
                     clearance_restored_mm=restored_mm)
