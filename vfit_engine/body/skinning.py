"""Skinning of the hm08 body by its default rig: linear blend (LBS) and dual quaternions (DQS).

Every vertex follows the bones that carry it, by the skin weights of MakeHuman's default rig
(:attr:`vfit_engine.body.model.BodyModel.skin`; 163 bones, 1 to 12 influences per vertex). A bone's
skinning matrix ``M_k = posed_global_k @ inverse(rest_global_k)`` maps rest-pose world positions to
posed ones, so the identity leaves the body where it is.

LBS blends the transformed points::

    x' = sum_k w_k (R_k x + t_k)

It is a blend of matrices, and a blend of rotations is no rotation: two bones twisted by ``a``
about their common axis squeeze a half-and-half vertex towards the axis by ``cos(a / 2)``
(the "candy-wrapper" collapse; 0.26 of the radius at 150 degrees). DQS (Kavan et al. 2008,
"Geometric Skinning with Approximate Dual Quaternion Blending") blends unit dual quaternions
``q_k = r_k + eps d_k`` (``d_k = 0.5 (0, t_k) r_k``) instead, with their signs aligned to the
vertex's largest-weight bone, and normalises::

    b = sum_k sign(r_k . r_0) w_k q_k,   b <- b / |b_real|,   x' = R(b_real) x + 2 vec(b_dual b_real*)

The result is always a rigid transform of the vertex, so joints keep their volume when twisted
or bent. DQS only represents rigid motion: bone matrices with scale or shear are refused.

Weights: ``hm08.npz`` stores them as float32, so each vertex's sum is 1 only to ~5e-8; they are
renormalised here per vertex (a vertex without weights stays where it is).
Timings (2-core machine, full 19,158-vertex body, warm, median of 20 calls): serial kernels LBS
0.24 ms, DQS 0.71 ms (``deform`` 0.27 / 1.06 ms: the dual quaternions and the rigidity check are
NumPy). ``parallel=True`` (OpenMP, 2 threads) gave 0.20 / 0.37-0.53 ms on an idle machine but
8.0 ms for both while another process used the second core, so the kernels are serial.
"""
from __future__ import annotations

import numpy as np

from vfit_engine.kernels import skinning as kernels
from vfit_engine.rotations import rigid_to_dual_quat

#: Tolerance of the rigidity check for DQS: ``|R^T R - I|`` and ``|det R - 1|``.
RIGID_TOL = 1e-6

METHODS = ("lbs", "dqs")


class Skinning:
    """Sparse skin weights in CSR form, ready for the LBS/DQS kernels; built once per rig.

    Parameters
    ----------
    bone, vertex : (s,) int
        Bone and vertex of each influence (``0 .. bone_count - 1``, ``0 .. vertex_count - 1``).
    weight : (s,) float
        Finite, >= 0; zero weights are dropped and the rest normalised per vertex.
    vertex_count, bone_count : int

    Attributes
    ----------
    offsets : (vertex_count + 1,) int64
        Vertex ``i``'s influences are ``bones[offsets[i]:offsets[i + 1]]``.
    bones : (s',) int64
    weights : (s',) float64
        Summing to 1 per vertex with influences, largest first (the DQS sign reference).
    weight_sums : (vertex_count,) float64
        Each vertex's sum of weights as given, before normalising (0 without influences).
    """

    def __init__(self, bone, vertex, weight, vertex_count, bone_count):
        bone = np.asarray(bone, dtype=np.int64).ravel()
        vertex = np.asarray(vertex, dtype=np.int64).ravel()
        weight = np.asarray(weight, dtype=np.float64).ravel()
        if not len(bone) == len(vertex) == len(weight):
            raise ValueError("bone, vertex and weight must have the same length")
        if len(bone) and (bone.min() < 0 or bone.max() >= bone_count):
            raise ValueError(f"bone indices must be in 0..{bone_count - 1}")
        if len(vertex) and (vertex.min() < 0 or vertex.max() >= vertex_count):
            raise ValueError(f"vertex indices must be in 0..{vertex_count - 1}")
        if not (np.isfinite(weight).all() and (weight >= 0).all()):
            raise ValueError("weight must be finite and >= 0")
        self.vertex_count = int(vertex_count)
        self.bone_count = int(bone_count)
        keep = weight > 0
        bone, vertex, weight = bone[keep], vertex[keep], weight[keep]
        self.weight_sums = np.bincount(vertex, weights=weight, minlength=self.vertex_count)
        order = np.lexsort((bone, -weight, vertex))  # by vertex, then largest weight first
        self.bones = np.ascontiguousarray(bone[order])
        self.weights = np.ascontiguousarray(weight[order] / self.weight_sums[vertex[order]])
        counts = np.bincount(vertex, minlength=self.vertex_count)
        self.offsets = np.zeros(self.vertex_count + 1, dtype=np.int64)
        np.cumsum(counts, out=self.offsets[1:])

    @classmethod
    def from_model(cls, model):
        """The default rig's skinning of a :class:`~vfit_engine.body.model.BodyModel` (all vertices)."""
        bone, vertex, weight = model.skin
        return cls(bone, vertex, weight, len(model.base_verts), len(model.bone_names))

    def deform(self, rest_verts, bone_mats, method="lbs", out=None):
        """Skin ``rest_verts`` by the bones' world-space skinning matrices.

        Parameters
        ----------
        rest_verts : (vertex_count, 3) float, m
            The body in the rest pose of the rig (any shape of it).
        bone_mats : (bone_count, 4, 4) or (bone_count, 3, 4) float
            ``posed_global @ inverse(rest_global)`` per bone, translation in m; a 4x4's last row
            must be (0, 0, 0, 1). For ``"dqs"`` each must be rigid (``R`` orthonormal with
            det 1 within :data:`RIGID_TOL`).
        method : {"lbs", "dqs"}
        out : (vertex_count, 3) float64 C-contiguous array, optional
            Written and returned; may be ``rest_verts`` itself.

        Returns
        -------
        (vertex_count, 3) float64, m

        Raises
        ------
        ValueError
            Wrong shape, NaN/inf, an unknown method, or a non-rigid matrix with ``"dqs"``.
        """
        if method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, not {method!r}")
        rest = _as_finite(rest_verts, "rest_verts", (self.vertex_count, 3))
        mats = _bone_mats(bone_mats, self.bone_count)
        out = _check_out(out, self.vertex_count)
        if method == "lbs":
            kernels.lbs(rest, self.offsets, self.bones, self.weights, mats, out)
        else:
            _check_rigid(mats)
            real, dual = rigid_to_dual_quat(mats[:, :, :3], mats[:, :, 3])
            kernels.dqs(rest, self.offsets, self.bones, self.weights, np.ascontiguousarray(real),
                        np.ascontiguousarray(dual), out)
        return out


def _as_finite(a, name, shape):
    """``a`` as a C-contiguous float64 array of ``shape`` with finite values, else ValueError."""
    try:
        a = np.ascontiguousarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers of shape {shape}") from None
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} contains NaN or infinite values")
    return a


def _bone_mats(bone_mats, bone_count):
    """(b, 3, 4) float64 ``[R | t]`` from (b, 4, 4) or (b, 3, 4) skinning matrices (validated)."""
    a = np.asarray(bone_mats)
    if a.ndim != 3 or a.shape[1] not in (3, 4):
        raise ValueError(f"bone_mats must have shape ({bone_count}, 4, 4) or ({bone_count}, 3, 4), "
                         f"got {a.shape}")
    a = _as_finite(a, "bone_mats", (bone_count, a.shape[1], 4))
    if a.shape[1] == 4:
        bad = np.flatnonzero(np.abs(a[:, 3] - (0.0, 0.0, 0.0, 1.0)).max(axis=1) > RIGID_TOL)
        if len(bad):
            raise ValueError(f"bone_mats[{bad[0]}] is not affine: its last row must be (0, 0, 0, 1)")
        a = np.ascontiguousarray(a[:, :3])
    return a


def _check_out(out, vertex_count):
    """``out`` if it is a writable C-contiguous float64 (vertex_count, 3) array; a new one for None."""
    if out is None:
        return np.empty((vertex_count, 3))
    if not (isinstance(out, np.ndarray) and out.dtype == np.float64 and out.shape == (vertex_count, 3)
            and out.flags.c_contiguous and out.flags.writeable):
        raise ValueError(f"out must be a writable C-contiguous float64 array of shape ({vertex_count}, 3)")
    return out


def _check_rigid(mats):
    """ValueError naming the first bone whose rotation part is not a rotation (DQS cannot scale)."""
    rot = mats[:, :, :3]
    ortho = np.abs(np.einsum("bji,bjk->bik", rot, rot) - np.eye(3)).max(axis=(1, 2))
    det = np.abs(np.linalg.det(rot) - 1.0)
    bad = np.flatnonzero((ortho > RIGID_TOL) | (det > RIGID_TOL))
    if len(bad):
        k = bad[0]
        raise ValueError(f"bone_mats[{k}] is not rigid (|R^T R - I| = {ortho[k]:.2g}, det R = "
                         f"{np.linalg.det(rot[k]):.6g}): dual-quaternion skinning needs rotations and "
                         "translations only; use method='lbs' for scale or shear")
