"""Numba kernels: linear blend skinning (LBS) and dual-quaternion skinning (DQS) over CSR weights.

Vertex ``i``'s influences are ``bones[offsets[i]:offsets[i + 1]]`` with ``weights`` at the same
positions (weights summing to 1, largest first: :class:`vfit_engine.body.skinning.Skinning` builds
them). A vertex without influences is copied from ``rest`` unchanged.

LBS (Magnenat-Thalmann et al. 1988)::

    x' = sum_k w_k (R_k x + t_k)

DQS (Kavan et al. 2008, "Geometric Skinning with Approximate Dual Quaternion Blending", DLB)::

    s_k = sign(r_k . r_0)                  (antipodality: blend on the first bone's hemisphere)
    r + eps d = sum_k s_k w_k (r_k + eps d_k) / |sum_k s_k w_k r_k|
    x' = R(r) x + t,   t = 2 vec(d r*) = 2 (r_w d_v - d_w r_v + r_v x d_v)

Quaternions are (w, x, y, z), Hamilton, as in :mod:`vfit_engine.rotations`; the rotation of
``x`` by the unit ``r = (w, u)`` is ``x + 2 u x (u x x + w x)``.

The kernels are serial; see :mod:`vfit_engine.body.skinning` for the 2-core timings that decided it.
Every vertex is written once from scalars read first, so ``out`` may be ``rest`` itself.
"""
import math

from vfit_engine._jit import njit


@njit
def lbs(rest, offsets, bones, weights, mats, out):
    """Linear blend skinning: ``out_i = sum_k w_k (R_k rest_i + t_k)``, evaluated as
    ``rest_i + sum_k w_k ((R_k - I) rest_i + t_k)`` (equal for weights summing to 1).

    Parameters
    ----------
    rest : (n, 3) float64, m
    offsets : (n + 1,) int64
        CSR row pointers into ``bones`` / ``weights``.
    bones : (s,) int64
        Bone of each influence, in ``0 .. b - 1``.
    weights : (s,) float64
        Weights summing to 1 per vertex (assumed, not checked).
    mats : (b, 3, 4) float64
        ``[R | t]`` of each bone, t in m.
    out : (n, 3) float64, m
        Written; may alias ``rest``.
    """
    for i in range(rest.shape[0]):
        px = rest[i, 0]
        py = rest[i, 1]
        pz = rest[i, 2]
        a = offsets[i]
        e = offsets[i + 1]
        if a == e:
            out[i, 0] = px
            out[i, 1] = py
            out[i, 2] = pz
            continue
        # the displacement sum_k w_k ((R_k - I) x + t_k): with weights summing to 1 it is the same
        # blend, but the identity returns rest bit for bit and small motions lose fewer digits
        ox = 0.0
        oy = 0.0
        oz = 0.0
        for k in range(a, e):
            b = bones[k]
            w = weights[k]
            ox += w * ((mats[b, 0, 0] - 1.0) * px + mats[b, 0, 1] * py + mats[b, 0, 2] * pz + mats[b, 0, 3])
            oy += w * (mats[b, 1, 0] * px + (mats[b, 1, 1] - 1.0) * py + mats[b, 1, 2] * pz + mats[b, 1, 3])
            oz += w * (mats[b, 2, 0] * px + mats[b, 2, 1] * py + (mats[b, 2, 2] - 1.0) * pz + mats[b, 2, 3])
        out[i, 0] = px + ox
        out[i, 1] = py + oy
        out[i, 2] = pz + oz


@njit
def dqs(rest, offsets, bones, weights, real, dual, out):
    """Dual-quaternion skinning (Kavan et al. 2008, module docstring).

    Parameters
    ----------
    rest : (n, 3) float64, m
    offsets : (n + 1,) int64
        CSR row pointers; each vertex's first influence is its sign reference (the largest weight).
    bones : (s,) int64
    weights : (s,) float64
        > 0 (any sum: the blend is normalised).
    real : (b, 4) float64
        Unit rotation quaternion of each bone, (w, x, y, z).
    dual : (b, 4) float64, m
        ``0.5 (0, t) real``.
    out : (n, 3) float64, m
        Written; may alias ``rest``.
    """
    for i in range(rest.shape[0]):
        px = rest[i, 0]
        py = rest[i, 1]
        pz = rest[i, 2]
        a = offsets[i]
        e = offsets[i + 1]
        if a == e:
            out[i, 0] = px
            out[i, 1] = py
            out[i, 2] = pz
            continue
        b0 = bones[a]
        q0w = real[b0, 0]
        q0x = real[b0, 1]
        q0y = real[b0, 2]
        q0z = real[b0, 3]
        rw = 0.0
        rx = 0.0
        ry = 0.0
        rz = 0.0
        dw = 0.0
        dx = 0.0
        dy = 0.0
        dz = 0.0
        for k in range(a, e):
            b = bones[k]
            w = weights[k]
            # q and -q are the same rotation; blend on the hemisphere of the first bone's q
            if real[b, 0] * q0w + real[b, 1] * q0x + real[b, 2] * q0y + real[b, 3] * q0z < 0.0:
                w = -w
            rw += w * real[b, 0]
            rx += w * real[b, 1]
            ry += w * real[b, 2]
            rz += w * real[b, 3]
            dw += w * dual[b, 0]
            dx += w * dual[b, 1]
            dy += w * dual[b, 2]
            dz += w * dual[b, 3]
        # |b_real| >= w_0 > 0 after the sign alignment, so the division is safe
        inv = 1.0 / math.sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
        rw *= inv
        rx *= inv
        ry *= inv
        rz *= inv
        dw *= inv
        dx *= inv
        dy *= inv
        dz *= inv
        tx = 2.0 * (rw * dx - dw * rx + ry * dz - rz * dy)
        ty = 2.0 * (rw * dy - dw * ry + rz * dx - rx * dz)
        tz = 2.0 * (rw * dz - dw * rz + rx * dy - ry * dx)
        # x' = x + 2 u x (u x x + w x)
        cx = ry * pz - rz * py + rw * px
        cy = rz * px - rx * pz + rw * py
        cz = rx * py - ry * px + rw * pz
        out[i, 0] = px + 2.0 * (ry * cz - rz * cy) + tx
        out[i, 1] = py + 2.0 * (rz * cx - rx * cz) + ty
        out[i, 2] = pz + 2.0 * (rx * cy - ry * cx) + tz
