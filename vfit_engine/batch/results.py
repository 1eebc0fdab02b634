"""A batch's results: ``OUTDIR/results.parquet``, one row per task, written as tasks finish.

``results.parquet`` is a Parquet dataset (a folder of part files, as Spark and Dask write them);
``pyarrow.parquet.read_table``, pandas, Polars and DuckDB read it as one table::

    import pyarrow.parquet as pq

from vfit_engine.io.atomic import atomic_write
    table = pq.read_table("OUTDIR/results.parquet")      # or duckdb: SELECT * FROM 'OUTDIR/results.parquet/*.parquet'

Each finished task is one part file, written to a temporary name and renamed (atomic), so a crash of
the client loses nothing already written and never leaves half a file. Every :data:`MERGE_EVERY` rows,
and at the end of a run, the one-row parts of the run are merged into one (:meth:`ResultStore.flush`),
so a job of a million tasks is a few thousand files, and a merge never rewrites earlier results. A
task has one row: reading keeps the newest row of a task id (a task re-run with ``--retry-failed``, or
parts left by a crash during a merge).

The columns are :data:`SCHEMA`: the task's inputs, its status and error, the drape's figures (surface
penetration, yarn strain, shear), the fit table (``fit``: a list of one struct per body region, as
``report.json``'s ``fit``; and flat columns for the key regions: ``bust_*`` is the bust of a woman and the
chest of a man), a sewing pattern's worst seam and panel (``worst_seam`` and its largest gap between sewn
points, ``worst_seam_gap_mm``; ``worst_panel`` and its yarn strain p99, ``worst_panel_p99_pct``; empty for a
garment mesh: :func:`vfit_engine.fit.pattern_fit.worst`), the timings (s) and the worker.
"""
from __future__ import annotations

import json
import time
import uuid
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from vfit_engine.errors import InputError
from vfit_engine.io.atomic import atomic_write

_FIT_ROW = pa.struct([("region", pa.string()), ("key", pa.bool_()), ("body_girth_cm", pa.float64()),
                      ("garment_girth_cm", pa.float64()), ("ease_cm", pa.float64()), ("girth_strain", pa.float64()),
                      ("max_strain", pa.float64()), ("pressure_kpa_max", pa.float64()),
                      ("required_strain", pa.float64()), ("verdict", pa.string()), ("estimated", pa.bool_())])
#: Timings per task (s): the worker's start (first task only), grading (sized tasks), the drape's set-up, the
#: drape, the fit table, the meshes (--keep-meshes), the whole task; ``body_s`` is the time its body took to
#: build, once for all the tasks on that body (the same in each of their rows, not part of ``task_s``).
TIMES = ("start", "body", "grade", "setup", "drape", "fit", "meshes", "task")
#: Key regions with flat columns (``bust`` = bust or chest).
KEY_REGIONS = ("bust", "waist", "hips")
_F, _S = pa.float64(), pa.string()
SCHEMA = pa.schema(
    [("task_id", _S), ("garment", _S), ("garment_name", _S), ("size", _S), ("material", _S), ("body", _S),
     ("body_key", _S), ("body_spec", _S), ("gender", _S), ("status", _S), ("error", _S), ("frames", pa.int32()),
     ("surface_inside_percent", _F), ("surface_max_depth_mm", _F), ("vertex_inside_percent", _F),
     ("max_strain", _F), ("p99_strain", _F), ("shear_p99_deg", _F), ("shear_max_deg", _F),
     ("tight_openings", pa.int32()), ("fit_summary", _S),
     ("worst_seam", _S), ("worst_seam_gap_mm", _F), ("worst_panel", _S), ("worst_panel_p99_pct", _F)]
    + [(f"{r}_{what}", t) for r in KEY_REGIONS
       for what, t in (("ease_cm", _F), ("strain", _F), ("verdict", _S), ("estimated", pa.bool_()))]
    + [("fit", pa.list_(_FIT_ROW))]
    + [(f"{t}_s", _F) for t in TIMES]
    + [("worker", _S), ("pid", pa.int32()), ("started_at", pa.timestamp("ms", tz="UTC")),
       ("finished_at", pa.timestamp("ms", tz="UTC")), ("final_mesh", _S), ("body_mesh", _S)])
#: One-row parts merged into one part file by :meth:`ResultStore.flush` (a run's rows per file).
MERGE_EVERY = 256
#: Units of the columns (the README's table of results.parquet says the same).
UNITS = dict(surface_inside_percent="%", surface_max_depth_mm="mm", vertex_inside_percent="%",
             max_strain="fraction", p99_strain="fraction", shear_p99_deg="deg", shear_max_deg="deg",
             ease_cm="cm", girth="cm", times="s", worst_seam_gap_mm="mm", worst_panel_p99_pct="%")


def flat_row(row, task):
    """A worker's row (:func:`vfit_engine.batch.task.run_task`) with the task's inputs, as :data:`SCHEMA`'s
    columns."""
    out = {name: row.get(name) for name in SCHEMA.names}
    out.update(task_id=task.id, garment=task.garment, garment_name=task.garment_name, size=task.size,
               material=task.material, body=task.body_label, body_key=task.body_key(),
               body_spec=json.dumps(task.body, sort_keys=True))
    fit = row.get("fit") or []
    out["fit"] = [{f.name: r.get(f.name) for f in _FIT_ROW} for r in fit]
    for key in KEY_REGIONS:
        names = ("bust", "chest") if key == "bust" else (key,)
        r = next((r for r in fit if r["region"] in names), None)
        if r is not None:
            out.update({f"{key}_ease_cm": r["ease_cm"], f"{key}_strain": r["girth_strain"],
                        f"{key}_verdict": r["verdict"], f"{key}_estimated": bool(r.get("estimated"))})
    for t in TIMES:
        out[f"{t}_s"] = (row.get("times_s") or {}).get(t)
    return out


class ResultStore:
    """The results of a batch in ``outdir`` (module docstring)."""

    def __init__(self, outdir):
        self.outdir = Path(outdir)
        self.path = self.outdir / "results.parquet"
        self.fresh = []  # the one-row parts this store wrote since its last merge
        if self.path.exists() and not self.path.is_dir():
            raise InputError(f"{self.path} is a file, not vfit's results folder: use another -o OUTDIR")

    def parts(self):
        return sorted(self.path.glob("part-*.parquet")) if self.path.is_dir() else []

    def read(self, columns=None):
        """The results: one row per task id (the newest), as a pyarrow Table (empty with no results);
        ``columns`` (names) reads only those."""
        parts = self.parts()
        schema = SCHEMA if columns is None else pa.schema([SCHEMA.field(c) for c in columns])
        cols = None if columns is None else list(dict.fromkeys(list(columns) + ["task_id", "finished_at"]))
        if not parts:
            return schema.empty_table()
        table = pa.concat_tables([pq.read_table(p, schema=SCHEMA, columns=cols) for p in parts])
        ids, ends = table.column("task_id").to_pylist(), table.column("finished_at").to_pylist()
        newest = {}
        for i, (tid, end) in enumerate(zip(ids, ends)):  # parts are named in time order; later rows win ties
            best = newest.get(tid)
            if best is None or (end or 0) >= (ends[best] or 0):
                newest[tid] = i
        return table.take(sorted(newest.values())).select(schema.names)

    def statuses(self):
        """task id -> status of the rows so far."""
        table = self.read(["task_id", "status"])
        return dict(zip(table.column("task_id").to_pylist(), table.column("status").to_pylist()))

    def add(self, rows):
        """Write ``rows`` (flat rows, :func:`flat_row`) as one part file, atomically; every
        :data:`MERGE_EVERY` of them, merge this run's parts (:meth:`flush`)."""
        path = self._write(rows)
        if path is not None:
            self.fresh.append(path)
            if len(self.fresh) >= MERGE_EVERY:
                self.flush()
        return path

    def flush(self):
        """Merge the parts this store wrote since its last merge into one; they are removed after the merged
        file is in place (a crash between leaves duplicate rows, which :meth:`read` drops)."""
        fresh, self.fresh = self.fresh, []
        if len(fresh) <= 1:
            return
        merged = self._write(pa.concat_tables([pq.read_table(p, schema=SCHEMA) for p in fresh]).to_pylist())
        for p in fresh:
            p.unlink(missing_ok=True)
        return merged

    def _write(self, rows):
        if not rows:
            return None
        self.path.mkdir(parents=True, exist_ok=True)
        table = pa.Table.from_pylist(rows, schema=SCHEMA)
        path = self.path / f"part-{_stamp()}-{uuid.uuid4().hex[:8]}.parquet"
        with atomic_write(path, "wb") as f:
            pq.write_table(table, f)
        return path

    def keep_meshes(self, task, meshes):
        """Write a task's meshes (file name -> bytes) under ``meshes/TASK_ID/`` and its body once under
        ``bodies/BODY_KEY.obj``; returns (final mesh, body mesh) relative to OUTDIR."""
        folder = self.outdir / "meshes" / task.id
        folder.mkdir(parents=True, exist_ok=True)
        for name in ("final.obj", "fit.ply"):
            with atomic_write(folder / name, "wb") as f:
                f.write(meshes[name])
        body = self.outdir / "bodies" / f"{task.body_key()}.obj"
        if not body.exists():
            body.parent.mkdir(parents=True, exist_ok=True)
            with atomic_write(body, "wb") as f:
                f.write(meshes["body.obj"])
        return str(folder.relative_to(self.outdir) / "final.obj"), str(body.relative_to(self.outdir))


def _stamp():
    return f"{time.time_ns():020d}"
