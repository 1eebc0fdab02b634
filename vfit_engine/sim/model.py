"""The fixed description of a mass-spring cloth (Newton-style ``Model``).

A :class:`Model` never changes during a simulation: rest positions, springs,
masses and pins. What changes each step lives in
:class:`vfit_engine.sim.state.State`; :class:`vfit_engine.sim.solver_verlet.SolverVerlet`
holds the model, its settings and its scratch buffers. Pure NumPy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.sim.bending import build_hinges
from vfit_engine.sim.materials import resolve_material
from vfit_engine.sim.springs import build_springs, polygon_corners, spring_constants, vertex_masses


def _frozen(a, dtype, shape_tail=None, name="array"):
    a = np.array(a, dtype=dtype, copy=True, order="C")
    if shape_tail is not None and (a.ndim != 1 + len(shape_tail) or a.shape[1:] != shape_tail):
        raise InputError(f"{name} must have shape (n, {', '.join(map(str, shape_tail))}), got {a.shape}")
    if dtype == np.float64 and not np.all(np.isfinite(a)):
        raise InputError(f"{name} contains NaN or infinity")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Model:
    """Particles and springs of a cloth. Arrays are copied and made read-only.

    Attributes
    ----------
    rest_pos : (n, 3) float64, m
        Rest (and default initial) positions.
    spring_indices : (s, 2) int64
        Vertex pairs.
    spring_rest : (s,) float64, m
    spring_k : (s,) float64, N/m
    spring_kd : (s,) float64, N s/m
    spring_type : (s,) int64
        ``STRUCTURAL`` 0, ``SHEAR`` 1, ``BEND`` 2 (:mod:`vfit_engine.sim.springs`).
    mass : (n,) float64, kg
    inv_mass : (n,) float64, 1/kg
        0 for pinned particles (and particles of zero mass, which cannot move).
    pin_indices : (p,) int64
        Pinned particles, in the order pin targets are given.
    max_strain : float
        The material's largest wearable stretch (0.10 = 10 %).
    corners : (k, 3) int64
        Polygon corners whose angle shear changes: (previous, corner, next) vertex of every corner of
        the polygons with 4 or more corners (:func:`vfit_engine.sim.springs.polygon_corners`).
    hinges : Hinges or None
        The bending hinges (:mod:`vfit_engine.sim.bending`); None: the bend springs bend the cloth.
    """

    rest_pos: np.ndarray
    spring_indices: np.ndarray
    spring_rest: np.ndarray
    spring_k: np.ndarray
    spring_kd: np.ndarray
    spring_type: np.ndarray
    mass: np.ndarray
    inv_mass: np.ndarray
    pin_indices: np.ndarray
    max_strain: float = 0.10
    corners: np.ndarray = None
    hinges: object = None

    @classmethod
    def create(cls, rest_pos, spring_indices, spring_rest, spring_k, spring_kd, spring_type, mass,
               pin_indices=(), max_strain=0.10, corners=None, hinges=None):
        """Validate raw arrays and build a model; ``inv_mass`` is 1/mass, 0 at pins.

        Parameters
        ----------
        rest_pos : (n, 3) float, m
        spring_indices : (s, 2) int
        spring_rest, spring_k, spring_kd : (s,) float (m, N/m, N s/m)
        spring_type : (s,) int
        mass : (n,) float, kg (> 0 except at pins)
        pin_indices : (p,) int
        max_strain : float
        corners : (k, 3) int or None
            Polygon corners (none when None).
        hinges : Hinges or None
        """
        pos = _frozen(rest_pos, np.float64, (3,), "rest_pos")
        n = pos.shape[0]
        idx = _frozen(np.asarray(spring_indices).reshape(-1, 2), np.int64, (2,), "spring_indices")
        s = idx.shape[0]
        if s and (idx.min() < 0 or idx.max() >= n):
            raise InputError("spring_indices refers to a particle that does not exist")
        if s and np.any(idx[:, 0] == idx[:, 1]):
            raise InputError("a spring joins a particle to itself")
        arrays = {}
        for name, value in (("spring_rest", spring_rest), ("spring_k", spring_k), ("spring_kd", spring_kd)):
            a = _frozen(np.asarray(value, dtype=np.float64).ravel(), np.float64, (), name)
            if a.shape != (s,):
                raise InputError(f"{name} needs {s} values, got {a.shape[0]}")
            if np.any(a < 0):
                raise InputError(f"{name} has negative values")
            arrays[name] = a
        stype = _frozen(np.asarray(spring_type).ravel(), np.int64, (), "spring_type")
        if stype.shape != (s,):
            raise InputError(f"spring_type needs {s} values")
        m = _frozen(np.asarray(mass, dtype=np.float64).ravel(), np.float64, (), "mass")
        if m.shape != (n,) or np.any(m < 0):
            raise InputError("mass needs one value >= 0 per particle")
        pins = np.array(np.asarray(pin_indices, dtype=np.int64).ravel())
        if np.unique(pins).size != pins.size:
            raise InputError("pin_indices has duplicates")
        if pins.size and (pins.min() < 0 or pins.max() >= n):
            raise InputError("pin_indices refers to a particle that does not exist")
        pins.setflags(write=False)
        w = np.zeros(n)
        np.divide(1.0, m, out=w, where=m > 0)
        w[pins] = 0.0
        w.setflags(write=False)
        if not (np.isfinite(max_strain) and max_strain >= 0):
            raise InputError("max_strain must be finite and >= 0")
        corners = _frozen(np.zeros((0, 3)) if corners is None else np.asarray(corners).reshape(-1, 3), np.int64, (3,),
                          "corners")
        if corners.size and (corners.min() < 0 or corners.max() >= n):
            raise InputError("corners refers to a particle that does not exist")
        if hinges is not None and hinges.count and (hinges.indices.min() < 0 or hinges.indices.max() >= n):
            raise InputError("a hinge refers to a particle that does not exist")
        return cls(pos, idx, arrays["spring_rest"], arrays["spring_k"], arrays["spring_kd"], stype,
                   m, w, pins, float(max_strain), corners, hinges)

    @classmethod
    def from_polygons(cls, face_verts, face_offsets, rest_pos, material, pin_indices=(), uvs=None, face_uvs=None):
        """Springs and masses of a polygon mesh made of ``material``.

        Parameters
        ----------
        face_verts : (k,) int64
        face_offsets : (m + 1,) int64
            Flat polygon list (:mod:`vfit_engine.sim.springs`).
        rest_pos : (n, 3) float64, m
        material : Material or str
            A :class:`vfit_engine.sim.materials.Material`, a preset name or a JSON path.
        pin_indices : (p,) int64
        uvs : (t, 2) float64 or None;  face_uvs : (k,) int64 or None
            Texture coordinates per face corner: warp and weft follow them where they are a sewing
            pattern (:mod:`vfit_engine.sim.bending`).
        """
        material = resolve_material(material)
        springs = build_springs(face_verts, face_offsets, rest_pos)
        k, kd = spring_constants(springs, material.stiffness, material.damping)
        mass = vertex_masses(face_verts, face_offsets, rest_pos, material.areal_density)
        hinges = build_hinges(face_verts, face_offsets, rest_pos, material.bending_rigidity, uvs, face_uvs,
                              damping=material.bending_damping)
        return cls.create(rest_pos, springs.indices, springs.rest, k, kd, springs.type, mass,
                          pin_indices, material.wearable_stretch, polygon_corners(face_verts, face_offsets), hinges)

    @property
    def particle_count(self):
        return int(self.rest_pos.shape[0])

    @property
    def spring_count(self):
        return int(self.spring_rest.shape[0])

    @property
    def pin_count(self):
        return int(self.pin_indices.shape[0])

    def spring_lengths(self, pos):
        """Length of every spring at ``pos`` (n, 3), m."""
        pos = np.asarray(pos, dtype=np.float64)
        return np.linalg.norm(pos[self.spring_indices[:, 1]] - pos[self.spring_indices[:, 0]], axis=1)

    def spring_strain(self, pos):
        """``l / l0 - 1`` of every spring at ``pos`` (s,); 0.1 = 10 % stretched."""
        return self.spring_lengths(pos) / self.spring_rest - 1.0

    def max_stretch(self, pos, spring_type=0):
        """Largest strain among springs of ``spring_type`` (default structural)."""
        sel = self.spring_type == spring_type
        return float(self.spring_strain(pos)[sel].max()) if np.any(sel) else 0.0
