"""A batch job: every garment (in each of its sizes) on every body, each task with a stable id.

A job file, JSON or YAML (paths relative to the job file)::

    garments:                           # garment files, or dicts with options
      - outfits/male_casualsuit02.obj
      - {path: shirt.obj, material: jersey, sizes: [S, M, L], units: dm}
      - {path: shirt.json, spacing: 25}  # a sewing pattern (GarmentCode JSON; cloth edge length in mm)
      - {path: pieces.dxf, seams: pieces.seams.json}   # DXF-AAMA with its seams sidecar
    bodies:                             # measurements as `vfit morph` takes them (cm, kg), or CSV files
      - {name: anna, gender: female, height: 168, bust: 90, waist: 72, hips: 98}
      - {gender: male}                  # the average man
      - {name: bob, body: bob.obj}      # a body file (hm08 topology)
      - customers.csv                   # columns: name, gender, height, weight, bust, waist, hips, ...
    drape: {frames: 600, collider: mesh, rest: garment}   # optional, for every task

The tasks are garments x sizes x bodies (a garment without ``sizes`` is draped as given). A sewing pattern is
sewn and draped as ``vfit drape PATTERN`` does (:func:`vfit_engine.drape.sew.prepare_pattern_drape`); it takes
no ``sizes`` or ``units`` (its file says them), and the job's garment-mesh drape options (``collider``, ``rest``,
``transfer``, ``pin``) other than their defaults do not go with it. A task's id is a hash of what decides its result: the bytes of
the garment file (and of its ``.mhclo``, and of a material or body file, and a pattern's seams sidecar), the
units, material, size, a pattern's spacing, the body's measurements and name, and the drape options. So a
re-run of the same job skips what is done, an edited garment runs again, and moving the job's folder changes
nothing. Structure errors (a missing file, an unknown key, a girth of -3 cm) are found here, before any
drape, naming the file and the element; a garment file that is there but broken fails its own tasks only.
"""
from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
from pathlib import Path

import yaml

from vfit_engine.body.gender import parse_gender
from vfit_engine.body.measure import DEFINITIONS
from vfit_engine.drape.colliders import COLLIDERS
from vfit_engine.drape.setup import REST_MODES
from vfit_engine.errors import InputError, VfitError
from vfit_engine.garment.mhclo import parse_mhclo
from vfit_engine.garment.transfer import METHODS
from vfit_engine.pattern.load import is_pattern
from vfit_engine.sim.materials import resolve_material
from vfit_engine.sizes import parse_sizes
from vfit_engine.units import LENGTH_UNITS

#: Body girths a body spec may give, cm (``vfit morph``'s options; tests hold the two lists equal).
GIRTHS = ("bust", "underbust", "waist", "hips", "neck", "upper_arm", "thigh", "calf")
#: Accepted ranges (as ``vfit morph`` checks them): height and girths in cm, weight in kg.
RANGES = dict(height=(50.0, 300.0), weight=(10.0, 500.0), **{g: (1.0, 400.0) for g in GIRTHS})
#: Keys of a body spec besides the measurements (``id`` and ``customer`` are CSV synonyms of ``name``).
BODY_KEYS = ("name", "gender", "definition", "body")
NAME_SYNONYMS = ("id", "customer")
#: Other names of a measurement: a man's chest is the girth a woman's bust is (``vfit morph --chest``).
GIRTH_SYNONYMS = {"chest": "bust"}
#: Keys of a garment entry and of the job's ``drape`` options.
GARMENT_KEYS = ("path", "material", "sizes", "units", "seams", "spacing")
DRAPE_KEYS = ("frames", "collider", "rest", "transfer", "pin")
#: Keys of a garment entry only a sewing pattern takes, and drape options only a garment mesh takes.
PATTERN_KEYS = ("seams", "spacing")
MESH_DRAPE_KEYS = dict(collider="mesh", rest="garment", transfer="auto", pin="auto")  # and their defaults
#: A pattern's cloth spacing (mm) as ``vfit drape --spacing`` takes it.
SPACING_MM = (3.0, 100.0)
JOB_KEYS = ("garments", "bodies", "drape")


@dataclasses.dataclass(frozen=True)
class Task:
    """One drape of a batch: a garment (in a size) on a body.

    ``body`` is the canonical spec (cm, kg; ``body`` a file path), ``gender`` the body's gender (the spec's,
    else the garment's from its ``.mhclo`` tags, else female), ``drape`` the drape options; :meth:`payload`
    is what a worker gets.
    """

    id: str
    garment: str
    units: str
    material: str
    size: str | None
    body: dict
    gender: str | float
    drape: dict
    seams: str | None = None
    spacing_mm: float | None = None

    @property
    def garment_name(self):
        return Path(self.garment).stem

    @property
    def body_label(self):
        """The body's name, else its measurements in a few words."""
        b = self.body
        if b.get("name"):
            return b["name"]
        if b.get("body"):
            return Path(b["body"]).stem
        parts = [str(self.gender)] + [f"{k} {b[k]:g}" for k in ("height", "weight") + GIRTHS if k in b]
        return ", ".join(parts)

    def body_key(self):
        """What builds the body (not its name): tasks with the same key share one body."""
        spec = {k: v for k, v in self.body.items() if k != "name"}
        spec["gender"] = self.gender
        return _digest(spec)[:12]

    def payload(self, keep_meshes=False):
        """The worker's job (plain data; lengths converted to metres as the engine takes them)."""
        b = self.body
        targets = {k.replace("_", "-"): b[k] / 100.0 for k in GIRTHS if k in b}
        if "height" in b:
            targets["height"] = b["height"] / 100.0
        return dict(id=self.id, garment=self.garment, units=self.units, material=self.material, size=self.size,
                    body=dict(key=self.body_key(), path=b.get("body"), targets=targets, weight_kg=b.get("weight"),
                              gender=self.gender, definition=b.get("definition", "iso")),
                    drape=dict(self.drape), keep_meshes=bool(keep_meshes), seams=self.seams,
                    spacing_m=None if self.spacing_mm is None else self.spacing_mm / 1000.0)


@dataclasses.dataclass
class Job:
    """A parsed job: its file, its tasks (duplicates dropped) and what was said about it."""

    path: str
    tasks: list
    garments: int
    bodies: int
    warnings: list


def _digest(obj):
    return hashlib.sha1(json.dumps(obj, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _file_digest(path):
    h = hashlib.sha1()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def read_document(path):
    """The job file as data (JSON by a .json name, else YAML, which also reads JSON)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"job file not found: {path}")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the job file ({exc})") from None
    try:
        if path.suffix.lower() == ".json":
            return json.loads(text)

        return yaml.safe_load(text)
    except ValueError as exc:  # json.JSONDecodeError
        raise InputError(f"{path}: not valid JSON ({exc})") from None
    except Exception as exc:  # yaml.YAMLError and its subclasses
        where = getattr(exc, "problem_mark", None)
        at = f" at line {where.line + 1}, column {where.column + 1}" if where is not None else ""
        raise InputError(f"{path}: not valid YAML{at} ({getattr(exc, 'problem', None) or exc})") from None


def load_job(path):
    """Parse and check a job file; returns a :class:`Job`. InputError naming the file and element."""
    path = Path(path)
    doc = read_document(path)
    if not isinstance(doc, dict):
        raise InputError(f"{path}: a job is a mapping with 'garments' and 'bodies' (see 'vfit batch --help')")
    _known(doc, JOB_KEYS, f"{path}")
    base = path.resolve().parent
    garments = _garments(doc.get("garments"), base, path)
    bodies = _bodies(doc.get("bodies"), base, path)
    drape = _drape_options(doc.get("drape") or {}, path)
    mesh_only = [k for k, default in MESH_DRAPE_KEYS.items() if drape.get(k, default) != default]
    pattern = next((i for i, g in enumerate(garments) if g.get("pattern")), None)
    if mesh_only and pattern is not None:
        raise InputError(f"{path}: drape: {mesh_only[0]!r} is for a garment mesh, and garments[{pattern}] is a "
                         "sewing pattern (sewn round the body, its seams hold it); drape patterns in a job of their "
                         "own")
    return make_job(str(path), garments, bodies, drape)


def make_job(path, garments, bodies, drape):
    """The tasks of checked garment entries x bodies (see :func:`load_job`)."""
    digests, tasks, seen, warnings = {}, [], set(), []
    for g in garments:
        key = _garment_digest(g, digests)
        for size in g["sizes"] or [None]:
            for b in bodies:
                body = {k: (_cached_digest(v, digests) if k == "body" else v) for k, v in b.items()}
                ident = dict(garment=key, units=g["units"], material=g["material_key"], size=size, body=body,
                             drape=drape)
                if g.get("pattern"):  # a mesh's id stays what it was before patterns were taken
                    ident.update(spacing_mm=g["spacing_mm"])
                tid = _digest(ident)[:16]
                if tid in seen:
                    warnings.append(f"{Path(g['path']).name} on {b} is listed twice; draped once")
                    continue
                seen.add(tid)
                gender = b.get("gender", g["gender"] or "female")
                tasks.append(Task(tid, g["path"], g["units"], g["material"], size, dict(b), gender, dict(drape),
                                  g.get("seams"), g.get("spacing_mm")))
    return Job(path, tasks, len(garments), len(bodies), warnings)


def _cached_digest(path, digests):
    if path not in digests:
        digests[path] = _file_digest(path)
    return digests[path]


def _garment_digest(g, digests):
    """The garment's content hash: its file and the .mhclo binding beside it, or a pattern's seams sidecar."""
    mhclo = Path(g["path"]).with_suffix(".mhclo")
    parts = [_cached_digest(g["path"], digests)] + ([_cached_digest(str(mhclo), digests)] if mhclo.is_file() else [])
    if g.get("seams"):
        parts.append(_cached_digest(g["seams"], digests))
    return "+".join(parts)


def _known(mapping, keys, where):
    bad = [k for k in mapping if k not in keys]
    if bad:
        raise InputError(f"{where}: unknown key {bad[0]!r}; expected {', '.join(keys)}")


def _garments(entries, base, path):
    if isinstance(entries, (str, dict)):
        entries = [entries]
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: 'garments' must be a non-empty list of garment files")
    out = []
    for i, e in enumerate(entries):
        where = f"{path}: garments[{i}]"
        e = {"path": e} if isinstance(e, str) else e
        if not isinstance(e, dict) or not isinstance(e.get("path"), str):
            raise InputError(f"{where}: give a file path, or a mapping with 'path'")
        _known(e, GARMENT_KEYS, where)
        file = (base / e["path"]).resolve()
        if not file.is_file():
            what = "is a folder, not a garment file" if file.is_dir() else "garment file not found"
            raise InputError(f"{where}: {what}: {file}")
        units = str(e.get("units", "auto"))
        if units != "auto" and units not in LENGTH_UNITS:
            raise InputError(f"{where}: unknown units {units!r}; use {', '.join(('auto', *LENGTH_UNITS))}")
        sizes = e.get("sizes")
        if sizes is not None:
            text = ",".join(sizes) if isinstance(sizes, list) else str(sizes)
            try:
                sizes = parse_sizes(text)
            except InputError as exc:
                raise InputError(f"{where}: {exc}") from None
        material, material_key = _material(e.get("material", "cotton"), base, where)
        g = dict(path=str(file), units=units, sizes=sizes, material=material, material_key=material_key,
                 gender=_tag_gender(file))
        if is_pattern(file):
            g.update(_pattern_entry(e, base, where))
        elif any(k in e for k in PATTERN_KEYS):
            raise InputError(f"{where}: {next(k for k in PATTERN_KEYS if k in e)!r} is for a sewing pattern "
                             f"(.json, .dxf), not a garment mesh")
        out.append(g)
    return out


def _pattern_entry(e, base, where):
    """A sewing pattern's own keys (its seams sidecar, absolute; its spacing, mm), checked."""
    for key in ("sizes", "units"):
        if e.get(key) not in (None, "auto"):
            raise InputError(f"{where}: {key!r} is for a garment mesh; a pattern's file gives its units, and "
                             "vfit batch does not grade a pattern (vfit size does)")
    seams = None
    if e.get("seams") is not None:
        file = (base / str(e["seams"])).resolve()
        if not file.is_file():
            raise InputError(f"{where}: seams file not found: {file}")
        seams = str(file)
    spacing = e.get("spacing")
    if spacing is not None:
        lo, hi = SPACING_MM
        if isinstance(spacing, bool) or not isinstance(spacing, (int, float)) or not lo <= spacing <= hi:
            raise InputError(f"{where}: spacing {spacing!r}; give the cloth's edge length in mm, {lo:g}-{hi:g}")
        spacing = float(spacing)
    return dict(pattern=True, seams=seams, spacing_mm=spacing)


def _tag_gender(file):
    """The garment's gender from the tags of the ``.mhclo`` beside it (None: none, or unreadable -- the
    worker then reports the garment's own error)."""
    mhclo = file.with_suffix(".mhclo")
    try:
        return parse_mhclo(mhclo).gender if mhclo.is_file() else None
    except (VfitError, OSError, ValueError):
        return None


def _material(spec, base, where):
    """(the material as the worker takes it, what identifies it in a task id)."""
    spec = str(spec)
    if spec.lower().endswith(".json"):
        file = (base / spec).resolve()
        if not file.is_file():
            raise InputError(f"{where}: material file not found: {file}")
        spec = str(file)
    try:
        resolve_material(spec)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    return spec, (_file_digest(spec) if spec.lower().endswith(".json") else spec.lower())


def _bodies(entries, base, path):
    if isinstance(entries, str):
        entries = [entries]
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: 'bodies' must be a non-empty list of measurement mappings or CSV files")
    out = []
    for i, e in enumerate(entries):
        where = f"{path}: bodies[{i}]"
        if isinstance(e, str):
            out += read_customers(base / e, where)
        elif isinstance(e, dict):
            out.append(body_spec(e, where, base))
        else:
            raise InputError(f"{where}: give a mapping of measurements (cm, kg) or a CSV file name")
    return out


def read_customers(path, where=None):
    """Body specs from a customers CSV: a header row (name, gender, height, weight, bust, waist, hips, ...;
    any case), one customer per row; an empty cell is a measurement not given."""
    path = Path(path).resolve()
    label = f"{where}: " if where else ""
    if not path.is_file():
        raise InputError(f"{label}customers file not found: {path}")
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{path}: cannot read the CSV ({exc})") from None
    rows = [r for r in rows if any(c.strip() for c in r)]
    if len(rows) < 2:
        raise InputError(f"{path}: no customers (a header row, then one row per customer)")
    head = [h.strip().lower().replace("-", "_").replace(" ", "_") for h in rows[0]]
    out = []
    for n, r in enumerate(rows[1:], start=2):
        if len(r) != len(head):
            raise InputError(f"{path}: line {n} has {len(r)} cells, the header {len(head)}")
        spec = {h: c.strip() for h, c in zip(head, r) if c.strip()}
        out.append(body_spec(spec, f"{path}: line {n}", path.parent))
    return out


def body_spec(spec, where, base):
    """A checked, canonical body spec (cm, kg; ``gender`` "female", "male" or a blend; ``body`` an absolute
    path) from a job's mapping or a CSV row."""
    spec = dict(spec)
    for syn in NAME_SYNONYMS:
        if syn in spec:
            spec["name"] = spec.pop(syn)
    spec = {k.replace("-", "_"): v for k, v in spec.items()}
    for syn, name in GIRTH_SYNONYMS.items():
        if syn in spec:
            if spec.get(name) not in (None, ""):
                raise InputError(f"{where}: both {syn!r} and {name!r}: they are one measurement, give one")
            spec[name] = spec.pop(syn)
    _known(spec, BODY_KEYS + tuple(RANGES), where)
    out = {}
    if spec.get("name") not in (None, ""):
        out["name"] = str(spec["name"])
    if spec.get("gender") not in (None, ""):
        out["gender"] = _gender(spec["gender"], where)
    if spec.get("definition") not in (None, ""):
        if spec["definition"] not in DEFINITIONS:
            raise InputError(f"{where}: definition {spec['definition']!r}; use {', '.join(DEFINITIONS)}")
        out["definition"] = spec["definition"]
    for key, (lo, hi) in RANGES.items():
        if spec.get(key) in (None, ""):
            continue
        unit = "kg" if key == "weight" else "cm"
        try:
            x = float(spec[key])
        except (TypeError, ValueError):
            raise InputError(f"{where}: {key} {spec[key]!r} is not a number ({unit})") from None
        if not (math.isfinite(x) and lo <= x <= hi):
            raise InputError(f"{where}: {key} {spec[key]!r} {unit} is absurd (expected {lo:g}-{hi:g} {unit})")
        out[key] = round(x, 3)
    if spec.get("body") not in (None, ""):
        file = (Path(base) / str(spec["body"])).resolve()
        if not file.is_file():
            raise InputError(f"{where}: body file not found: {file}")
        if any(k in out for k in RANGES):
            raise InputError(f"{where}: give either a body file or measurements, not both")
        out["body"] = str(file)
    return out


def _gender(value, where):
    try:
        return parse_gender(value)
    except ValueError as exc:
        raise InputError(f"{where}: gender {exc}") from None


def _drape_options(opts, path):
    where = f"{path}: drape"
    if not isinstance(opts, dict):
        raise InputError(f"{where}: give a mapping of drape options ({', '.join(DRAPE_KEYS)})")
    _known(opts, DRAPE_KEYS, where)
    out = dict(opts)
    choices = dict(collider=COLLIDERS, rest=REST_MODES, transfer=METHODS, pin=("auto", "none"))
    for key, allowed in choices.items():
        if key in out and out[key] not in allowed:
            raise InputError(f"{where}: {key} {out[key]!r}; use {', '.join(allowed)}")
    if "frames" in out:
        f = out["frames"]
        if isinstance(f, bool) or not isinstance(f, int) or not 1 <= f <= 100000:
            raise InputError(f"{where}: frames {f!r}; use a whole number 1-100000")
    return out
