"""Cloth materials: what a fabric is, in the figures textile labs measure, and its presets.

A :class:`Material` holds a fabric's measurable properties (SI inside; the JSON file's keys carry
their units):

=========================  ==============================  ===========================================
JSON key                   field (SI)                      meaning
=========================  ==============================  ===========================================
``areal_density_g_m2``     ``areal_density`` kg/m^2        weight per area (g/m^2 / 1000)
``bending_rigidity_uN_m``  ``bending_rigidity`` (2,) N m   B, moment per width per curvature (KES-F B;
                                                           1 gf cm^2/cm = 98.1 uN m): one value or
                                                           [warp, weft]
``stretch_stiffness_N_m``  ``stretch_stiffness`` N/m       tension per width per strain along the yarns
                                                           (a 2-D modulus)
``shear_stiffness_N_m``    ``shear_stiffness`` N/m         in-plane shear modulus (tension per width per
                                                           radian)
``wearable_stretch``       ``wearable_stretch``            the stretch the fabric takes in wear
                                                           (fraction): the fit verdicts' limit
``friction``               ``friction``                    Coulomb coefficient against skin (recorded;
                                                           the drape's contacts take
                                                           ``ContactSettings.friction``)
``stretch_damping_N_s_m``  ``stretch_damping`` N s/m       optional (a 2-D viscosity)
``shear_damping_N_s_m``    ``shear_damping`` N s/m         optional
``bending_damping_s``      ``bending_damping`` s           optional: hinge damping / stiffness
=========================  ==============================  ===========================================

How each reaches the cloth: the weight is the vertices' masses (each its share of the polygons'
area); the bending rigidity is the hinges' stiffness (:mod:`vfit_engine.sim.bending`: exact on
cylinders at any mesh spacing); the stretch and shear stiffnesses are the springs' and
constraints' (:func:`vfit_engine.sim.springs.spring_constants`: ``k = K A_s / l0^2``, the same at any
spacing), a woven kept near-inextensible by its stretch constraints at any step
(:class:`vfit_engine.sim.solver_verlet.SolverVerlet`). ``friction`` is kept with the material but the drape's
contacts do not take it yet: they hold 0.8, skin's grip on cloth where it is warm (0.8-0.9 on the chest,
0.25-0.31 on a dry forearm: Temel et al. 2022), which keeps trousers up.

The presets' figures and their sources are in :data:`PRESETS`. The tests textile labs use --
the cantilever (ASTM D1388) and the Cusick drape test (BS 5058 / ISO 9073-9) -- run on any material:
``benchmarks/bench_cantilever.py`` and ``benchmarks/bench_cusick.py``.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from vfit_engine.errors import InputError

#: JSON key -> (field, factor to SI, min, max, unit as given, required). The ranges are wider than any
#: fabric's (chiffon ~0.5 uN m to a heavy canvas's ~100; a knit's 50 N/m of stretch stiffness to a
#: technical woven's 5e4), so what lies outside is a typo or a wrong unit.
KEYS = {
    "areal_density_g_m2": ("areal_density", 1e-3, 10.0, 1500.0, "g/m^2", True),
    "bending_rigidity_uN_m": ("bending_rigidity", 1e-6, 0.05, 2000.0, "uN m", True),
    "stretch_stiffness_N_m": ("stretch_stiffness", 1.0, 10.0, 1e5, "N/m", True),
    "shear_stiffness_N_m": ("shear_stiffness", 1.0, 0.1, 1e4, "N/m", True),
    "wearable_stretch": ("wearable_stretch", 1.0, 0.005, 2.0, "fraction", True),
    "friction": ("friction", 1.0, 0.0, 2.0, "", True),
    "stretch_damping_N_s_m": ("stretch_damping", 1.0, 0.0, 10.0, "N s/m", False),
    "shear_damping_N_s_m": ("shear_damping", 1.0, 0.0, 10.0, "N s/m", False),
    "bending_damping_s": ("bending_damping", 1.0, 0.0, 0.1, "s", False),
}
#: The old (unit-less) keys and what replaced them, for a clear refusal.
RENAMED = {"areal_density": "areal_density_g_m2 (g/m^2)", "bend_stiffness": "bending_rigidity_uN_m (uN m)",
           "stretch_stiffness": "stretch_stiffness_N_m", "shear_stiffness": "shear_stiffness_N_m",
           "max_strain": "wearable_stretch", "stretch_damping": "stretch_damping_N_s_m",
           "shear_damping": "shear_damping_N_s_m", "bend_damping": "bending_damping_s"}
#: The bend springs' share of the stretch stiffness (:attr:`Material.stiffness`): 1 %, the share the earlier
#: presets gave them (without it, cloth round an opening the body forces wider crumpled in its free
#: compression band while its neighbours stretched 50 %).
COMPRESSION_SHARE = 0.01
_DEFAULTS = {"stretch_damping_N_s_m": 0.02, "shear_damping_N_s_m": 0.01, "bending_damping_s": 0.0}


@dataclass(frozen=True)
class Material:
    """A fabric (module docstring; SI units). Build one with :func:`material_from_dict` from the JSON keys.

    Attributes
    ----------
    name : str
    areal_density : float, kg/m^2
    bending_rigidity : (warp, weft) float, N m
    stretch_stiffness, shear_stiffness : float, N/m
    wearable_stretch : float
        The stretch the fabric takes in wear (0.05 = 5 %).
    friction : float
    stretch_damping, shear_damping : float, N s/m
    bending_damping : float, s
    """

    name: str
    areal_density: float
    bending_rigidity: tuple
    stretch_stiffness: float
    shear_stiffness: float
    wearable_stretch: float
    friction: float
    stretch_damping: float = 0.02
    shear_damping: float = 0.01
    bending_damping: float = 0.0

    def __post_init__(self):
        b = self.bending_rigidity
        b = (b, b) if isinstance(b, (int, float)) and not isinstance(b, bool) else tuple(b)
        object.__setattr__(self, "bending_rigidity", b)
        if len(b) != 2:
            raise InputError(f"material {self.name!r}: bending_rigidity_uN_m takes one value or [warp, weft]")
        for key, (field, factor, lo, hi, unit, _) in KEYS.items():
            for value in (b if field == "bending_rigidity" else (getattr(self, field),)):
                _check(self.name, key, value, factor, lo, hi, unit)
        object.__setattr__(self, "bending_rigidity", tuple(float(v) for v in b))

    @property
    def stiffness(self):
        """(structural, shear, bend) 2-D moduli of the spring families, N/m. The bend springs (second
        neighbours) carry :data:`COMPRESSION_SHARE` of the stretch stiffness: they resist the cloth's
        in-plane compression, which the stretch constraints leave free (a fabric buckles rather than
        compresses, yet not for nothing); its bending is the hinges' (:mod:`vfit_engine.sim.bending`)."""
        return (self.stretch_stiffness, self.shear_stiffness, COMPRESSION_SHARE * self.stretch_stiffness)

    @property
    def damping(self):
        """(structural, shear, bend) 2-D viscosities of the spring families, N s/m."""
        return (self.stretch_damping, self.shear_damping, COMPRESSION_SHARE * self.stretch_damping)

    @property
    def bending_length(self):
        """Peirce's bending length c = (B / (w g))^(1/3) of the mean rigidity, m."""
        b = 0.5 * sum(self.bending_rigidity)
        return (b / (self.areal_density * 9.81)) ** (1.0 / 3.0)

    def to_dict(self):
        """The JSON keys with their values (what :func:`material_from_dict` reads)."""
        out = {"name": self.name}
        for key, (field, factor, *_rest) in KEYS.items():
            value = getattr(self, field)
            if field == "bending_rigidity":
                warp, weft = (round(v / factor, 6) for v in value)
                out[key] = warp if warp == weft else [warp, weft]
            else:
                out[key] = round(value / factor, 9)
        return out


def _check(name, key, value, factor, lo, hi, unit):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"material {name!r}: {key} must be a finite number, got {value!r}")
    shown = value / factor
    if not (lo * (1 - 1e-9) <= shown <= hi * (1 + 1e-9)):
        sp = " " if unit else ""
        raise InputError(f"material {name!r}: {key} {shown:g}{sp}{unit} is outside the physical range "
                         f"{lo:g}-{hi:g}{sp}{unit}")


def material_from_dict(data, name="custom"):
    """A :class:`Material` from a mapping of the JSON keys (module docstring), every value checked.

    Raises
    ------
    InputError
        Naming the key: a required one missing, an unknown one (an old unit-less key names its
        successor), a value not a finite number or outside its physical range.
    """
    if not isinstance(data, dict):
        raise InputError(f"material {name!r}: expected a JSON object")
    name = data.get("name", name)
    if not isinstance(name, str):
        raise InputError(f"material {name!r}: name must be a string")
    for key in data:
        if key != "name" and key not in KEYS:
            hint = f" (now {RENAMED[key]})" if key in RENAMED else f"; keys: {', '.join(KEYS)}"
            raise InputError(f"material {name!r}: unknown key {key!r}{hint}")
    missing = [k for k, spec in KEYS.items() if spec[5] and k not in data]
    if missing:
        raise InputError(f"material {name!r}: missing key(s) {', '.join(missing)}")
    values = {}
    for key, (field, factor, lo, hi, unit, _) in KEYS.items():
        value = data.get(key, _DEFAULTS.get(key))
        if field == "bending_rigidity" and isinstance(value, (list, tuple)):
            if len(value) != 2:
                raise InputError(f"material {name!r}: {key} takes one value or [warp, weft], got {value!r}")
            for v in value:
                _check(name, key, v, 1.0, lo, hi, unit)
            values[field] = tuple(float(v) * factor for v in value)
        else:
            _check(name, key, value, 1.0, lo, hi, unit)
            values[field] = float(value) * factor
    return Material(name, **values)


def load_material(path):
    """Read a material JSON file (the keys of the module docstring; ``name`` defaults to the file's stem).
    NaN / Infinity literals are refused like any value out of range.

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
    try:
        return material_from_dict(data, name=path.stem)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


#: Built-in fabrics: typical figures of each kind as measured on the Kawabata (KES-F) and FAST systems, the
#: cantilever and the Cusick test (:data:`SOURCES`). ``c`` is Peirce's bending length they give.
PRESETS = {m.name: m for m in (
    # habotai / crepe de chine, 60 g/m^2, B 0.02 gf cm^2/cm; c 1.5 cm
    material_from_dict({"name": "silk", "areal_density_g_m2": 60, "bending_rigidity_uN_m": 2.0,
                        "stretch_stiffness_N_m": 1500, "shear_stiffness_N_m": 15, "wearable_stretch": 0.10,
                        "friction": 0.3}),
    # cotton shirting (a firm poplin), 120 g/m^2, B 0.12 / 0.09 gf cm^2/cm; c 2.1 cm
    material_from_dict({"name": "cotton", "areal_density_g_m2": 120, "bending_rigidity_uN_m": [12.0, 9.0],
                        "stretch_stiffness_N_m": 2000, "shear_stiffness_N_m": 60, "wearable_stretch": 0.10,
                        "friction": 0.4}),
    # worsted wool suiting, 250 g/m^2, B 0.12 gf cm^2/cm; c 1.7 cm
    material_from_dict({"name": "wool", "areal_density_g_m2": 250, "bending_rigidity_uN_m": [13.0, 10.0],
                        "stretch_stiffness_N_m": 2500, "shear_stiffness_N_m": 50, "wearable_stretch": 0.10,
                        "friction": 0.4}),
    # denim, 400 g/m^2 (12 oz/yd^2), B 0.82 / 0.56 gf cm^2/cm; c 2.6 cm
    material_from_dict({"name": "denim", "areal_density_g_m2": 400, "bending_rigidity_uN_m": [80.0, 55.0],
                        "stretch_stiffness_N_m": 8000, "shear_stiffness_N_m": 200, "wearable_stretch": 0.05,
                        "friction": 0.5}),
    # cotton single jersey, 180 g/m^2, B 0.04 gf cm^2/cm; c 1.3 cm; stretches
    material_from_dict({"name": "jersey", "areal_density_g_m2": 180, "bending_rigidity_uN_m": 4.0,
                        "stretch_stiffness_N_m": 300, "shear_stiffness_N_m": 30, "wearable_stretch": 0.30,
                        "friction": 0.5}),
)}
#: Where each preset's figures come from. Measured sources are few at hand: the weights are typical of
#: each kind, the bending rigidities within the ranges FABRICS.md (``../shared/reference``) gathers; the
#: stretch and shear stiffnesses are of the order of KES-F tensile and shear tests (stretch ~1e3-1e4 N/m,
#: shear 10-200 N/m per radian, G (gf/cm deg) x 56) and not a particular fabric's.
SOURCES = {
    "silk": "weight: silk crepe de chine 12-16 momme = 52-69 g/m^2 (trade momme tables, x 4.34); B: chiffon "
            "~1 uN m, silks 1-3 (KES-F, FABRICS.md); Cusick 20-40 % (FABRICS.md)",
    "cotton": "weight: plain-weave cotton shirting 100-150 g/m^2 (Penava, Simic Penava & Knezic 2014, "
              "150 g/m^2); B: woven shirting 0.05-0.1 gf cm^2/cm = 5-10 uN m (KES-F, FABRICS.md), warp stiffer "
              "than weft; the preset (12 / 9 uN m) a firm poplin just above that range: this model, elastic, drapes "
              "the typical 7 / 5 at Cusick DC 0.44, below the published 60-76 % (Gan, Ly & Steven 1991, "
              "doi:10.1080/00405009108658741), and 12 / 9 at 0.58 (BENCHMARKS.md); friction on skin 0.25-0.31 dry forearm, "
              "0.8-0.9 chest (Temel, Johnson & Lloyd 2022, Tribology Letters 70)",
    "wool": "weight: wool plain weave 235 g/m^2 (Penava et al. 2014); B: suiting 0.1-0.15 gf cm^2/cm "
            "(KES-F men's suiting; FABRICS.md range); Cusick 40-70 % (FABRICS.md)",
    "denim": "weight: 11 oz denim 324 g/m^2 measured (Wang, O'Brien & Ramamoorthi 2011, doi:10.1145/2010324."
             "1964966), 12 oz = 407 g/m^2; B: light denims 14-22 uN m, with bending hysteresis 2HB 0.10-0.21 gf "
             "cm/cm (Kumari & Khurana 2016, doi:10.1155/2016/4614168), heavy denim tens of uN m (FABRICS.md): "
             "the preset (80 / 55 uN m, c 2.6 cm) is a rigid 12 oz; Cusick 70-90 % (FABRICS.md)",
    "jersey": "weight: a cotton interlock 187 g/m^2 measured (Wang et al. 2011); stretch: knits 20 % and more at "
              "wearing loads (FABRICS.md); B estimated (knits bend more easily than shirting)",
}


def get_material(name):
    """The preset called ``name`` (:data:`PRESETS`)."""
    try:
        return PRESETS[name.lower()]
    except (KeyError, AttributeError):
        raise InputError(f"unknown material {name!r}; presets: {', '.join(sorted(PRESETS))}") from None


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
