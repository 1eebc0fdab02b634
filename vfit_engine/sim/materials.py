"""Cloth materials: presets, a JSON loader and the mapping to spring constants.

A :class:`Material` describes a fabric by membrane quantities that do not depend
on the mesh resolution:

``areal_density``  kg/m^2, mass per unit cloth area (shirting cotton ~0.12-0.15,
                   denim ~0.35-0.45, silk ~0.05-0.07, jersey knit ~0.15-0.20).
``stretch_stiffness``, ``shear_stiffness``, ``bend_stiffness``  N/m: the tension
                   per unit cloth width per unit strain that each spring family
                   would carry in a uniform strip (a 2-D modulus).
``stretch_damping``, ``shear_damping``, ``bend_damping``  N s/m: the same per unit
                   strain *rate* (a 2-D viscosity).

Mapping to one spring (documented here, implemented in
:func:`vfit_engine.garment.springs.spring_constants`)::

    k_s  = K_type * A_s / l0**2        (N/m)
    kd_s = D_type * A_s / l0**2        (N s/m)

where ``l0`` is the spring's rest length and ``A_s`` its share of cloth area
(:func:`vfit_engine.garment.springs.build_springs` documents ``A_s``). A strip of
width ``w`` and length ``l0`` under strain ``e`` carries ``F = K e w`` and
stretches by ``e l0``, so ``k = K w / l0 = K A_s / l0**2`` with ``A_s = w l0``. On a
square grid a structural spring gets ``A_s = h^2`` and therefore ``k = K`` at any
spacing ``h``: halving the mesh spacing does not change how the cloth stretches.

Bend springs resist folding only at second order in the hinge angle, so no
exact mapping from a bending rigidity (N m) exists; ``bend_stiffness`` is the
2-D modulus given to the bend-spring family, and the presets keep the order of
real bending rigidities (silk < jersey < cotton < denim). Treat it as a knob.

The stretch figures are of the order of published low-strain tensile
stiffnesses of woven fabrics; an explicit integrator cannot take them at
practical time steps, so :class:`vfit_engine.sim.solver_verlet.SolverVerlet`
softens springs stiffer than its step can carry and leaves inextensibility to
Provot strain limiting (``max_strain``). The presets are starting points, not
measurements of a particular fabric.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from vfit_engine.errors import InputError


#: Physical range of each field (min, max, unit): wider than any fabric's (10-2000 g/m^2; a knit's 100 N/m
#: to a technical woven's 1e4 N/m of stretch stiffness), so what lies outside is a typo or a wrong unit.
RANGES = {
    "areal_density": (0.01, 2.0, "kg/m^2"),
    "stretch_stiffness": (10.0, 1e5, "N/m"),
    "shear_stiffness": (0.1, 1e4, "N/m"),
    "bend_stiffness": (0.01, 1e3, "N/m"),
    "stretch_damping": (0.0, 10.0, "N s/m"),
    "shear_damping": (0.0, 10.0, "N s/m"),
    "bend_damping": (0.0, 10.0, "N s/m"),
    "max_strain": (0.01, 2.0, "fraction"),
}


@dataclass(frozen=True)
class Material:
    """A fabric's membrane properties (SI units; see the module docstring).

    Attributes
    ----------
    name : str
    areal_density : float, kg/m^2
    stretch_stiffness, shear_stiffness, bend_stiffness : float, N/m
    stretch_damping, shear_damping, bend_damping : float, N s/m
    max_strain : float
        Largest stretch of a structural spring the strain limiter allows
        (0.10 = 10 %); knits stretch further than wovens.
    """

    name: str
    areal_density: float
    stretch_stiffness: float
    shear_stiffness: float
    bend_stiffness: float
    stretch_damping: float
    shear_damping: float
    bend_damping: float
    max_strain: float = 0.10

    def __post_init__(self):
        for f in fields(self):
            if f.name == "name":
                continue
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InputError(f"material {self.name!r}: {f.name} must be a number, got {value!r}")
            if not math.isfinite(value) or value < 0:
                raise InputError(f"material {self.name!r}: {f.name} must be finite and >= 0, got {value!r}")
            lo, hi, unit = RANGES[f.name]
            if not lo <= value <= hi:
                raise InputError(f"material {self.name!r}: {f.name} {value:g} {unit} is outside the physical range "
                                 f"{lo:g}-{hi:g} {unit}")
            object.__setattr__(self, f.name, float(value))

    @property
    def stiffness(self):
        """(structural, shear, bend) 2-D moduli, N/m, indexed by spring type."""
        return (self.stretch_stiffness, self.shear_stiffness, self.bend_stiffness)

    @property
    def damping(self):
        """(structural, shear, bend) 2-D viscosities, N s/m, indexed by spring type."""
        return (self.stretch_damping, self.shear_damping, self.bend_damping)

    def to_dict(self):
        """The fields as a JSON-ready dict (what :func:`load_material` reads)."""
        return asdict(self)


#: Built-in fabrics. Densities are typical weights (cotton shirting 150 g/m^2,
#: denim 400 g/m^2 ~ 12 oz/yd^2, silk 60 g/m^2, cotton jersey 180 g/m^2).
PRESETS = {
    "cotton": Material("cotton", 0.15, 2000.0, 200.0, 20.0, 0.02, 0.01, 0.005, 0.10),
    "denim": Material("denim", 0.40, 6000.0, 600.0, 80.0, 0.05, 0.02, 0.01, 0.05),
    "silk": Material("silk", 0.06, 1000.0, 50.0, 2.0, 0.01, 0.005, 0.001, 0.10),
    "jersey": Material("jersey", 0.18, 300.0, 60.0, 8.0, 0.01, 0.005, 0.002, 0.30),
}

_REQUIRED = [f.name for f in fields(Material) if f.name not in ("name", "max_strain")]


def get_material(name):
    """Return the preset called ``name`` (``cotton``, ``denim``, ``silk``, ``jersey``)."""
    try:
        return PRESETS[name.lower()]
    except (KeyError, AttributeError):
        raise InputError(f"unknown material {name!r}; presets: {', '.join(sorted(PRESETS))}") from None


def material_from_dict(data, name="custom"):
    """Build a :class:`Material` from a mapping, validating every field.

    Raises
    ------
    InputError
        A required field is missing, a field is unknown, or a value is not a
        finite number >= 0 (NaN included).
    """
    if not isinstance(data, dict):
        raise InputError(f"material {name!r}: expected a JSON object")
    known = {f.name for f in fields(Material)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InputError(f"material {name!r}: unknown field(s) {', '.join(unknown)}")
    missing = [k for k in _REQUIRED if k not in data]
    if missing:
        raise InputError(f"material {name!r}: missing field(s) {', '.join(missing)}")
    values = dict(data)
    values.setdefault("name", name)
    if not isinstance(values["name"], str):
        raise InputError(f"material {name!r}: name must be a string")
    return Material(**values)


def load_material(path):
    """Read a material JSON file (the fields of :class:`Material`; ``name`` and
    ``max_strain`` optional). NaN/Infinity literals are rejected like negatives.

    Parameters
    ----------
    path : str or Path
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read material file {path}: {exc.strerror or exc}") from None
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise InputError(f"material file {path} is not valid JSON: {exc}") from None
    return material_from_dict(data, name=path.stem)


def resolve_material(spec):
    """A :class:`Material` from a preset name, a path to a ``.json`` file or a Material."""
    if isinstance(spec, Material):
        return spec
    spec = str(spec)
    if spec.lower() in PRESETS:
        return PRESETS[spec.lower()]
    if spec.lower().endswith(".json"):
        return load_material(spec)
    return get_material(spec)
