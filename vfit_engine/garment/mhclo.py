"""MakeHuman ``.mhclo`` proxy files: parse the binding of a garment to the hm08 base mesh and evaluate it.

A ``.mhclo`` binds every garment vertex (in the garment OBJ's ``v`` order) to the body:

* ``v``                                     exact: the garment vertex sits on body vertex ``v``;
* ``v0 v1 v2 w0 w1 w2 [d0 d1 d2]``          barycentric: ``sum_i w_i * body[v_i] + S @ d``.

``S`` is MakeHuman's ``TMatrix`` scale: a diagonal matrix with, per axis ``n`` (x = 0, y = 1, z = 2),
``S[n, n] = |body[a_n][n] - body[b_n][n]| / ref_n`` from the lines ``x_scale a b ref`` etc.
(MakeHuman ``shared/proxy.py``: ``x_scale`` fills index 0, ``y_scale`` 1, ``z_scale`` 2, whatever their
order in the file; the distance is the absolute coordinate difference along that axis only, so there
is no sign convention to get wrong). Files without scale lines use the identity.

Units: the offsets ``d`` and the reference distances ``ref`` are in MakeHuman units (decimetres).
``evaluate_mhclo`` takes body vertices in metres, so it converts ``ref`` and ``d`` to metres
(``units.LENGTH_UNITS["dm"]``): the ratio ``S`` is then unit-free and the offsets come out in metres.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vfit_engine.body.model import N_VERTS
from vfit_engine.errors import InputError
from vfit_engine.units import LENGTH_UNITS

#: MakeHuman's length unit, in which offsets and reference distances are written.
MHCLO_UNIT = "dm"


@dataclass
class MhcloBinding:
    """A parsed ``.mhclo`` file.

    Attributes
    ----------
    name, uuid, basemesh, obj_file, material : str
    tags : list of str
        As written (case kept); see ``gender_from_tags``.
    ref_verts : (n, 3) int64
        Body vertex indices per garment vertex (an exact binding repeats its index three times).
    weights : (n, 3) float64
        Barycentric weights (exact binding: 1, 0, 0).
    offsets : (n, 3) float64, dm
        Offsets in MakeHuman units (exact binding: 0).
    scales : dict
        ``{"x": (a, b, ref_dm), "y": ..., "z": ...}`` for the axes present.
    z_depth : int or None
    delete_verts : (d,) int64
        Body vertices the garment hides (sorted, unique).
    path : Path or None
    """

    name: str = ""
    uuid: str = ""
    basemesh: str = ""
    obj_file: str = ""
    material: str = ""
    tags: list = field(default_factory=list)
    ref_verts: np.ndarray = None
    weights: np.ndarray = None
    offsets: np.ndarray = None
    scales: dict = field(default_factory=dict)
    z_depth: int | None = None
    delete_verts: np.ndarray = None
    path: Path | None = None

    @property
    def n_verts(self):
        """Number of bound garment vertices."""
        return int(self.ref_verts.shape[0])

    @property
    def top_vertex(self):
        """Highest body vertex index the binding reads (its references and its scale vertices)."""
        top = int(self.ref_verts.max())
        for a, b, _ in self.scales.values():
            top = max(top, int(a), int(b))
        return top

    @property
    def gender(self):
        """``"female"``, ``"male"`` or None from the tags."""
        return gender_from_tags(self.tags)

    @property
    def obj_path(self):
        """Path of the garment OBJ next to the .mhclo (None when unknown)."""
        if self.path is None or not self.obj_file:
            return None
        return Path(self.path).parent / self.obj_file


def gender_from_tags(tags):
    """``"female"`` / ``"male"`` when exactly one of them is among ``tags`` (case-insensitive), else None."""
    low = {str(t).strip().lower() for t in tags}
    female, male = "female" in low, "male" in low
    if female and not male:
        return "female"
    if male and not female:
        return "male"
    return None


def _parse_delete_verts(words, out):
    """MakeHuman's run syntax: ``a b - c`` means a and the range b..c inclusive."""
    prev = None
    run = False
    for w in words:
        if w == "-":
            run = True
            continue
        v = int(w)
        if run and prev is not None:
            out.extend(range(prev + 1, v + 1))
        else:
            out.append(v)
        run = False
        prev = v


def _check_line(path, lineno, verts, values, what):
    """InputError ``path:line: ...; fix`` for a body vertex outside the hm08 base mesh or a NaN/inf value:
    checked where they are read, as a later index error or NaN drape could not say which line was wrong."""
    out = [int(v) for v in verts if not 0 <= int(v) < N_VERTS]
    if out:
        raise InputError(f"{path}:{lineno}: body vertex {out[0]} is out of range, the hm08 base mesh has vertices "
                         f"0..{N_VERTS - 1}; fix the line (or the file binds another base mesh: re-export it "
                         "from MakeHuman for hm08)")
    bad = [v for v in values if not math.isfinite(v)]
    if bad:
        raise InputError(f"{path}:{lineno}: {what} {bad[0]} is not a finite number; fix the line (weights are "
                         "barycentric, summing to 1; offsets in dm)")


def parse_mhclo(path):
    """Parse a ``.mhclo`` file.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    MhcloBinding

    Raises
    ------
    InputError
        Unreadable file, a garbled binding line, a body vertex outside the hm08 base mesh, a NaN/inf weight,
        offset or scale, or no binding at all; one line naming the file and line.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    b = MhcloBinding(path=path)
    refs, weights, offsets, deleted = [], [], [], []
    status = None
    axis = {"x_scale": "x", "y_scale": "y", "z_scale": "z"}
    for lineno, line in enumerate(text.splitlines(), 1):
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        key = words[0]
        try:
            if key == "name":
                b.name = " ".join(words[1:])
            elif key == "uuid":
                b.uuid = " ".join(words[1:])
            elif key == "basemesh":
                b.basemesh = words[1]
            elif key == "tag":
                b.tags.append(" ".join(words[1:]))
            elif key == "obj_file":
                b.obj_file = " ".join(words[1:])
            elif key == "material":
                b.material = " ".join(words[1:])
            elif key == "z_depth":
                b.z_depth = int(words[1])
            elif key in axis:
                b.scales[axis[key]] = (int(words[1]), int(words[2]), float(words[3]))
                _check_line(path, lineno, [int(words[1]), int(words[2])], [float(words[3])], "reference distance")
                if not float(words[3]) > 0:
                    raise InputError(f"{path}:{lineno}: {key} reference distance {words[3]} is not positive; "
                                     "write the rest distance between the two vertices (dm)")
            elif key == "verts":
                status = "verts"
            elif key == "delete_verts":
                status = "delete"
            elif key == "weights":
                status = "weights"  # per-bone weights of rigged proxies: not used by vfit
            elif status == "verts" and key[0].isdigit():
                if len(words) == 1:
                    v = int(words[0])
                    refs.append((v, v, v))
                    weights.append((1.0, 0.0, 0.0))
                    offsets.append((0.0, 0.0, 0.0))
                else:
                    refs.append((int(words[0]), int(words[1]), int(words[2])))
                    weights.append((float(words[3]), float(words[4]), float(words[5])))
                    if len(words) >= 9:
                        offsets.append((float(words[6]), float(words[7]), float(words[8])))
                    else:
                        offsets.append((0.0, 0.0, 0.0))
                _check_line(path, lineno, refs[-1], weights[-1] + offsets[-1], "weight or offset")
            elif status == "delete" and (key[0].isdigit() or key == "-"):
                _check_line(path, lineno, [int(w) for w in words if w != "-"], [], "")  # before a run expands
                _parse_delete_verts(words, deleted)
            # other keywords (material details, shear, special_pose, ...) do not affect fitting
        except (ValueError, IndexError):
            raise InputError(f"{path}:{lineno}: cannot read .mhclo line {line.strip()[:60]!r}; fix or remove "
                             "the line") from None
    if not refs:
        raise InputError(f"{path}: no vertex binding ('verts' block) in the .mhclo file")
    b.ref_verts = np.asarray(refs, dtype=np.int64)
    b.weights = np.asarray(weights, dtype=np.float64)
    b.offsets = np.asarray(offsets, dtype=np.float64)
    b.delete_verts = np.unique(np.asarray(deleted, dtype=np.int64))
    return b


def scale_matrix(binding, body_verts):
    """Per-axis scale (3,) of ``binding`` on ``body_verts`` (m): MakeHuman's TMatrix diagonal.

    Parameters
    ----------
    binding : MhcloBinding
    body_verts : (N, 3) float64, m

    Returns
    -------
    (3,) float64
        Unit-free ratio |body[a][n] - body[b][n]| / ref_n (ref converted from dm to m).
    """
    s = np.ones(3, dtype=np.float64)
    for n, ax in enumerate("xyz"):
        if ax in binding.scales:
            a, b, ref = binding.scales[ax]
            ref_m = ref * LENGTH_UNITS[MHCLO_UNIT]
            s[n] = abs(body_verts[a, n] - body_verts[b, n]) / ref_m
    return s


def evaluate_mhclo(binding, body_verts):
    """Garment vertex positions fitted to a body (MakeHuman proxy fitting).

    ``x_j = sum_i w_ji * body[r_ji] + S * (d_j * 0.1)`` with ``S`` from ``scale_matrix``.

    Parameters
    ----------
    binding : MhcloBinding
    body_verts : (19158, 3) float64, m
        hm08 vertices including the helper geometry (clothes bind to the helpers, e.g. ``tights``).

    Returns
    -------
    (n, 3) float64, m
        In the garment OBJ's vertex order.
    """
    body_verts = np.ascontiguousarray(body_verts, dtype=np.float64)
    top = int(binding.ref_verts.max())
    if body_verts.ndim != 2 or body_verts.shape[1] != 3 or body_verts.shape[0] <= top:
        raise InputError(
            f"mhclo binding needs body vertices up to index {top}, got an array of shape {body_verts.shape}"
        )
    s = scale_matrix(binding, body_verts)
    pos = np.einsum("ni,nik->nk", binding.weights, body_verts[binding.ref_verts])
    return pos + binding.offsets * LENGTH_UNITS[MHCLO_UNIT] * s
