"""Morph-target deltas stored as normalized integers (glTF's ``KHR_mesh_quantization``), exactly enough.

An animated GLB holds one morph target per frame, so its size is the targets' size. Quantization halves it:
a POSITION delta as normalized SHORT takes 8 bytes per vertex instead of 12 (6 bytes of data padded to 8,
since every vertex-attribute element must start on a 4-byte boundary), a NORMAL delta as normalized BYTE 4
instead of 12 (3 padded to 4).

Why these choices (KHR_mesh_quantization, "Extending Morph Target Attributes"):

- POSITION deltas may be BYTE or SHORT, normalized or not. Normalized SHORT reads back as
  ``max(c / 32767, -1)`` metres, so it covers [-1, 1] m in steps of 1/32767 m = 0.031 mm: a rounding error of
  at most 0.015 mm, well under what anyone sees, with no scale to carry (glTF has nowhere to put a per-target
  scale: a node scale would scale the base mesh too). A target with any component beyond 1 m (a walk with
  ``--travel`` that leaves frame 0 far behind) cannot be stored so and stays float32: exact, only larger.
- NORMAL deltas may only be normalized BYTE or SHORT, so they too must lie in [-1, 1]; a normal turned by
  more than 60 degrees can have a component change up to 2 (a fold of cloth turning over). The spec says such
  deltas "need to use FLOAT storage", and that is what is done, target by target: a target with one such vertex
  keeps float32 normals. Measured on the walk: no body target, but 13 of 60 garment targets (150 of 360 in the
  361-frame walk, 1 to 3 vertices each, turned 64-85 degrees: 2.8 MB of its 22.8 MB). Storing a shorter vector
  in the normal's direction for those vertices (``lam * n - n0`` fits for lam >= 0.67 there) would save that,
  but only for viewers that renormalize after morphing, and with the int8 error grown by 1/lam; a float target
  is exact everywhere.
- BYTE rather than SHORT for the normals: 1/127 per component moves a unit normal by at most 0.4 degrees,
  below anything shading shows, for half of SHORT's bytes.

Sparse accessors (store only the vertices that move) were measured and do not pay here: in the 60-frame walk
a target leaves at most 0.7 % of its vertices unmoved (mean 0.01 %), and a sparse element (2-byte index and
6 bytes of values) costs as much as a dense padded one. Identical targets are shared instead (``_Buffer.add``).

The decoded value of ``c`` is the spec's ``max(c / 32767, -1)`` (``/ 127`` for BYTE); the encoder rounds
``f * 32767`` to nearest and never writes -32768, so the ``max`` never acts.
"""
from __future__ import annotations

import numpy as np

EXTENSION = "KHR_mesh_quantization"
#: Largest |component| a normalized integer holds: 1 m for a position delta, 1 for a normal delta.
_RANGE = 1.0


def position_delta(pos, base):
    """Encode one morph target's POSITION deltas, quantized when they all fit.

    Parameters
    ----------
    pos : (N, 3) float, m
        The frame's positions at the glTF vertices.
    base : (N, 3) float32, m
        The base positions as written (the deltas are taken from these, so the float32 rounding of the base
        does not add to the error).

    Returns
    -------
    delta : (N, 3) int16 or float32
        int16 ``c`` with ``c / 32767`` m the delta (error <= 0.5/32767 m = 0.015 mm), or float32 metres when a
        component exceeds 1 m.
    normalized : bool
        True for the int16 encoding.
    """
    d = np.asarray(pos, dtype=np.float64) - np.asarray(base, dtype=np.float64)
    return _encode(d, np.int16)


def normal_delta(normals, base):
    """Encode one morph target's NORMAL deltas: normalized int8 when they all fit in [-1, 1], else float32.

    Parameters
    ----------
    normals : (N, 3) float
        The frame's unit normals at the glTF vertices.
    base : (N, 3) float32
        The base normals as written.

    Returns
    -------
    delta : (N, 3) int8 or float32
        int8 ``c`` with ``c / 127`` the delta (per-component error <= 0.5/127, under 0.4 degrees of the
        normal's direction), or float32 (exact) when a component exceeds 1.
    normalized : bool
        True for the int8 encoding.
    """
    d = np.asarray(normals, dtype=np.float64) - np.asarray(base, dtype=np.float64)
    return _encode(d, np.int8)


def _encode(d, dtype):
    """``round(d * max)`` as ``dtype`` if every |component| of ``d`` is <= 1, else ``d`` as float32."""
    if d.size and np.abs(d).max() > _RANGE:
        return np.ascontiguousarray(d, dtype=np.float32), False
    top = np.iinfo(dtype).max
    return np.ascontiguousarray(np.rint(d * top), dtype=dtype), True
