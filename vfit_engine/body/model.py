"""The hm08 body model: base mesh, sparse blend-shape targets, MakeHuman macro interpolation.

A body is ``base + sum_i w_i * target_i`` over all 19,158 vertices (body
0..13,379 plus the helper geometry that garment bindings and joints use).
Everything here is in metres, Y up, +Z front, +X the body's left.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from dataclasses import dataclass, field
from functools import cached_property
from importlib.resources import files
from pathlib import Path

import numpy as np

N_VERTS = 19158
N_BODY = 13380
_DM = 0.1  # metres per MakeHuman unit

ETHNICITIES = ("african", "asian", "caucasian")


def data_dir() -> Path:
    """Where the body data lives: inside the installed package, else the source tree's ``data/``."""
    try:
        p = Path(str(files("vfit_engine.data")))
        if (p / "hm08.npz").exists():
            return p
    except ModuleNotFoundError:
        pass
    return Path(__file__).resolve().parents[2] / "data"


def cache_dir() -> Path:
    """Where vfit keeps files between runs, outside the repository: ``$VFIT_CACHE``, else
    ``$XDG_CACHE_HOME/vfit``, else ``~/.cache/vfit``."""
    if os.environ.get("VFIT_CACHE"):
        return Path(os.environ["VFIT_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "vfit"


def _inflated(path: Path) -> Path:
    """An uncompressed copy of the .npz ``path`` in :func:`cache_dir`, made the first time; ``path`` itself
    where the cache cannot be written.

    hm08.npz is deflated (8.3 MB of 15.6): inflating it took ~80 ms of every load, reading the copy ~20 ms.
    The copy is named by the source's path, size and modification time, so a rebuilt or moved source gets a
    new one (the copies of an older source of the same path are removed); it is written under a temporary
    name and renamed, so a process never reads half a copy.
    """
    try:
        st = path.stat()
        tag = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:12]
        prefix = f"{path.stem}-{tag}-"
        out = cache_dir() / f"{prefix}{st.st_size}-{st.st_mtime_ns}.npz"
        if out.exists():
            return out
        out.parent.mkdir(parents=True, exist_ok=True)
        with np.load(path, allow_pickle=False) as d:
            arrays = {k: d[k] for k in d.files}
        fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=out.name, suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, **arrays)
            os.replace(tmp, out)
        except BaseException:
            os.unlink(tmp)
            raise
        for old in out.parent.glob(f"{prefix}*.npz"):
            if old != out:
                old.unlink(missing_ok=True)
        return out
    except OSError:
        return path


def _tri_weights(value: float) -> tuple[float, float, float]:
    """MakeHuman's macro split of a [0, 1] slider into (min, average, max) weights.

    min = max(0, 1 - 2v), max = max(0, 2v - 1), average = 1 - min - max, as in
    MakeHuman's ``human.py`` (_setMuscleVals, _setWeightVals, _setHeightVals ...).
    """
    lo = max(0.0, 1.0 - 2.0 * value)
    hi = max(0.0, 2.0 * value - 1.0)
    return lo, 1.0 - lo - hi, hi


@dataclass(frozen=True)
class Macro:
    """MakeHuman macro settings for a young adult (age fixed at 25 years, MakeHuman's 0.5).

    gender : 0 female ... 1 male; muscle, weight, height, proportions : 0 ... 1,
    0.5 average; ethnic : (african, asian, caucasian) shares summing to 1.
    """

    gender: float = 0.0
    muscle: float = 0.5
    weight: float = 0.5
    height: float = 0.5
    proportions: float = 0.5
    ethnic: tuple = (1 / 3, 1 / 3, 1 / 3)

    def target_weights(self) -> dict[str, float]:
        """Target name -> weight, following MakeHuman's ``macro.json`` combinations."""
        out: dict[str, float] = {}
        genders = {"female": 1.0 - self.gender, "male": self.gender}
        muscles = dict(zip(("minmuscle", "averagemuscle", "maxmuscle"), _tri_weights(self.muscle)))
        weights = dict(zip(("minweight", "averageweight", "maxweight"), _tri_weights(self.weight)))
        hlo, _, hhi = _tri_weights(self.height)
        plo, _, phi = _tri_weights(self.proportions)
        for g, gw in genders.items():
            if gw <= 0:
                continue
            for race, rw in zip(ETHNICITIES, self.ethnic):
                if rw > 0:
                    out[f"macrodetails/{race}-{g}-young"] = gw * rw
            for m, mw in muscles.items():
                for w, ww in weights.items():
                    base = gw * mw * ww
                    if base <= 0:
                        continue
                    out[f"macrodetails/universal-{g}-young-{m}-{w}"] = base
                    for name, hw in (("minheight", hlo), ("maxheight", hhi)):
                        if hw > 0:
                            out[f"macrodetails/height/{g}-young-{m}-{w}-{name}"] = base * hw
                    for name, pw in (("uncommonproportions", plo), ("idealproportions", phi)):
                        if pw > 0:
                            out[f"macrodetails/proportions/{g}-young-{m}-{w}-{name}"] = base * pw
        return out


def gender_value(gender) -> float:
    """'female' -> 0, 'male' -> 1, or a number in [0, 1]."""
    if isinstance(gender, str):
        key = gender.strip().lower()
        if key in ("female", "f"):
            return 0.0
        if key in ("male", "m"):
            return 1.0
        value = float(key)
    else:
        value = float(gender)
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"gender must be female, male or a number in 0..1, got {gender!r}")
    return value


@dataclass
class BodyModel:
    """The hm08 body: base mesh, targets, topology, groups and rig, loaded from ``data/hm08.npz``.

    Attributes
    ----------
    base_verts : (19158, 3) float64, m
        The raw MakeHuman base mesh (no macro applied).
    body_quads : (13378, 4) int64
        Quads of the visible body; indices < 13,380.
    body_quad_uvs : (13378, 4) int64
        ``uvs`` index of each quad corner.
    uvs : (t, 2) float64
        Texture coordinates.
    """

    base_verts: np.ndarray
    body_quads: np.ndarray
    body_quad_uvs: np.ndarray
    uvs: np.ndarray
    target_names: tuple
    _target_offsets: np.ndarray
    _target_index: np.ndarray
    _target_delta_q: np.ndarray
    group_names: tuple
    _group_offsets: np.ndarray
    _group_ranges: np.ndarray
    bone_names: tuple
    skin: tuple  # (bone (s,), vertex (s,), weight (s,))
    _target_id: dict = field(init=False, repr=False)  # target name -> its row, made from target_names
    _dense_cache: dict = field(default_factory=dict, repr=False)
    _tail_cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        self._target_id = {n: i for i, n in enumerate(self.target_names)}

    @classmethod
    def load(cls, path: Path | None = None) -> "BodyModel":
        """Load the compact model (about 0.05 s); ``path`` defaults to the packaged ``hm08.npz``, read from
        its uncompressed copy in the user's cache (:func:`_inflated`)."""
        path = Path(path) if path is not None else _inflated(data_dir() / "hm08.npz")
        with np.load(path, allow_pickle=False) as d:
            model = cls(
                base_verts=d["base_verts_q"].astype(np.float64) * (1e-4 * _DM),
                body_quads=d["body_quads"].astype(np.int64),
                body_quad_uvs=d["body_quad_uvs"].astype(np.int64),
                uvs=d["uvs"],
                target_names=tuple(d["target_names"].tolist()),
                _target_offsets=d["target_offsets"],
                _target_index=d["target_index"].astype(np.int64),
                _target_delta_q=d["target_delta_q"],
                group_names=tuple(d["group_names"].tolist()),
                _group_offsets=d["group_offsets"],
                _group_ranges=d["group_ranges"],
                bone_names=tuple(d["bone_names"].tolist()),
                skin=(d["skin_bone"].astype(np.int64), d["skin_vertex"].astype(np.int64),
                      d["skin_weight"].astype(np.float64)),
            )
        return model

    # ------------------------------------------------------------------ topology
    @cached_property
    def body_tris(self) -> np.ndarray:
        """(2F, 3) int64: each body quad (a, b, c, d) split into (a, b, c) and (a, c, d)."""
        q = self.body_quads
        return np.ascontiguousarray(np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]))

    def group(self, name: str) -> np.ndarray:
        """Vertex indices of a vertex group (e.g. ``'helper-tights'``, ``'joint-l-knee'``)."""
        i = self.group_names.index(name)
        ranges = self._group_ranges[self._group_offsets[i]:self._group_offsets[i + 1]]
        return np.concatenate([np.arange(a, b + 1) for a, b in ranges]).astype(np.int64)

    @cached_property
    def rig(self) -> dict:
        """Default rig bones: parent, roll and head/tail placement (joint cube, vertex or mean)."""
        return json.loads((data_dir() / "rig_default.json").read_text())

    @cached_property
    def rulers(self) -> dict:
        """MakeHuman Measure-plugin rulers: key -> {kind, closed, vertex_indices}."""
        return json.loads((data_dir() / "rulers.json").read_text())["rulers"]

    def joint_centres(self, verts: np.ndarray) -> dict[str, np.ndarray]:
        """Centre of every ``joint-*`` helper cube of a shaped body (m)."""
        return {g: verts[self.group(g)].mean(axis=0) for g in self.group_names if g.startswith("joint-")}

    # ------------------------------------------------------------------ targets
    def target(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Sparse target: (vertex index (k,) int64, delta (k, 3) float64 m)."""
        try:
            i = self._target_id[name]
        except KeyError:
            raise KeyError(f"unknown target {name!r}") from None
        a, b = self._target_offsets[i], self._target_offsets[i + 1]
        return self._target_index[a:b], self._target_delta_q[a:b].astype(np.float64) * (1e-3 * _DM)

    def dense_target(self, name: str, n_verts: int = N_VERTS) -> np.ndarray:
        """(n_verts, 3) float64 m: the target's delta on the first ``n_verts`` vertices (cached)."""
        key = (name, n_verts)
        if key not in self._dense_cache:
            idx, delta = self.target(name)
            out = np.zeros((n_verts, 3))
            keep = idx < n_verts
            out[idx[keep]] = delta[keep]
            out.flags.writeable = False
            self._dense_cache[key] = out
        return self._dense_cache[key]

    def shape(self, weights: dict[str, float], base: np.ndarray | None = None, first: int = 0) -> np.ndarray:
        """``base + sum w * target`` over all vertices; ``base`` defaults to the raw base mesh.

        ``first`` > 0 shapes only the vertices from ``first`` on (those before are ``base``'s), with
        the same sums as a full shape: the morph replaces the body's by its dense blend and needs only
        the helpers', whose part of each target is kept (dequantizing whole targets cost ~9 ms a body).
        """
        verts = np.array(self.base_verts if base is None else base, dtype=np.float64, copy=True)
        for name, w in weights.items():
            if w == 0.0:
                continue
            if first:
                key = (name, first)
                if key not in self._tail_cache:
                    idx, delta = self.target(name)
                    keep = idx >= first
                    self._tail_cache[key] = (idx[keep], delta[keep])
                idx, delta = self._tail_cache[key]
            else:
                idx, delta = self.target(name)
            verts[idx] += w * delta  # indices within a target are unique, so += is a true sum
        return verts

    def macro_verts(self, macro: Macro) -> np.ndarray:
        """(19158, 3) float64 m: the base mesh shaped by the macro targets of ``macro``."""
        return self.shape(macro.target_weights())

    def default_verts(self, gender="female") -> np.ndarray:
        """The young-adult average body of a gender ('female', 'male' or 0..1)."""
        return self.macro_verts(Macro(gender=gender_value(gender)))
