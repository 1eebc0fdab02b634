"""One task of a batch, as a worker runs it: build (or reuse) the body, drape the garment, measure the fit.

::

    row = run_task(task.payload())        # on a Dask worker, or in this process

The drape is ``vfit drape``'s path (:func:`vfit_engine.drape.prepare_drape`, :func:`run_drape`, the
fit table of :mod:`vfit_engine.fit.table`) without its files; a task with a size first grades the
garment to that size as ``vfit size`` does (:func:`vfit_engine.sizes.grade`, the size body at the
customer's height); a task whose garment is a sewing pattern sews and drapes it as ``vfit drape PATTERN``
does (:func:`vfit_engine.drape.sew.prepare_pattern_drape` on the projective solver) and its row gets the
pattern's columns (the largest seam gap and panel strain, :func:`vfit_engine.fit.pattern_fit.worst`). On a
cluster the body is a task of its own (:func:`build_body`), built once for
all the drapes on it and handed to them by Dask; run alone, a task builds it. The worker keeps the body
model, the size bodies and the fit tables (:mod:`vfit_engine.process_cache`).

A drape that fails on its input (a broken garment file, an unreachable measurement, a diverged
simulation) returns a ``failed`` row with the message: it fails alone. Anything else (a bug, memory)
raises, so that Dask retries the task (``vfit batch --retries``).
"""
from __future__ import annotations

import datetime
import os
import socket
import tempfile
import time

from distributed import get_worker

from vfit_engine import process_cache
from vfit_engine.body.bodyio import write_body
from vfit_engine.body.measure import stature
from vfit_engine.body.resolve import resolve_body
from vfit_engine.drape import DrapeDiverged, DrapeSettings, prepare_drape, run_drape
from vfit_engine.drape.settings import projective
from vfit_engine.drape.setup import garment_gender
from vfit_engine.drape.sew import prepare_pattern_drape
from vfit_engine.errors import InputError, VfitError
from vfit_engine.fit.maps import fit_maps
from vfit_engine.fit.outputs import write_fit_ply
from vfit_engine.fit.pattern_fit import pattern_block, worst
from vfit_engine.fit.verdict import summary_line
from vfit_engine.garment.garment import load_garment
from vfit_engine.io.mesh import write_mesh
from vfit_engine.pattern.load import is_pattern, load
from vfit_engine.pattern.mesh import DEFAULT_SPACING
from vfit_engine.sizes import grade, size_body, size_gender

#: Statuses of a task: settled, not settled within the frame limit (judged on the last frame), failed.
STATUSES = ("ok", "not_converged", "failed")


def now_utc():
    return datetime.datetime.now(datetime.timezone.utc)


def worker_name():
    """The Dask worker's address, else host:pid."""
    try:
        return get_worker().address
    except ValueError:  # not in a Dask worker
        return f"{socket.gethostname()}:{os.getpid()}"


def blank_row(job, message=None):
    """The row of ``job`` before it ran (or when it could not: status failed, ``message``)."""
    return dict(task_id=job["id"], garment=job["garment"], size=job.get("size"), material=job["material"],
                status="failed", error=message, worker=None, pid=None, started_at=None, finished_at=now_utc(),
                times_s={})


def build_body(spec):
    """The body of ``spec`` (a payload's ``body``) as (Body or None, error message or None, seconds): a
    body that cannot be built (an unreachable measurement) is an answer, not an exception, so that its
    tasks fail with the message instead of Dask retrying it."""
    t0 = time.perf_counter()
    try:
        body = resolve_body(process_cache.model(), spec.get("path"), spec.get("targets"), spec.get("weight_kg"),
                            spec["gender"], spec.get("definition", "iso"))
    except VfitError as exc:
        return None, str(exc), time.perf_counter() - t0
    return body, None, time.perf_counter() - t0


def run_task(job, built=None):
    """Run one task (``job``: :meth:`vfit_engine.batch.job.Task.payload`) on its body (``built``: what
    :func:`build_body` returned; None: build it here); returns its row (a dict of the fields of
    :data:`vfit_engine.batch.results.SCHEMA`, ``meshes`` holding file bytes with ``keep_meshes``)."""
    if built is None:
        built = build_body(job["body"])
    t0 = time.perf_counter()  # the task's own time: its body is timed apart (built once for all its tasks)
    row = blank_row(job)
    row.update(worker=worker_name(), pid=os.getpid(), started_at=now_utc())
    times = row["times_s"]
    times["body"] = round(built[2], 3)

    def lap(stage, t=[t0]):
        now = time.perf_counter()
        times[stage] = round(now - t[0], 3)
        t[0] = now

    try:
        _drape(job, built, row, lap)
    except DrapeDiverged as exc:
        row.update(status="failed", error=f"the simulation diverged at frame {exc.frame}: {exc}")
    except VfitError as exc:
        row.update(status="failed", error=str(exc))
    finally:
        times["task"] = round(time.perf_counter() - t0, 3)
        row["finished_at"] = now_utc()
    return row


def _sized(garment, model, body, gender, size):
    """The garment graded to ``size`` at the customer's height, and that size's body (its reference)."""
    key_gender = size_gender(gender)
    height = round(stature(body.verts), 4)
    body_x, _ = process_cache.body(("size", key_gender, size, height),
                                   lambda: size_body(model, key_gender, size, height))
    return grade(garment, body_x, model), body_x


def _drape(job, built, row, lap):
    """The task's work, filling ``row``; ``lap(stage)`` records a stage's time."""
    body, error, _ = built
    model = process_cache.model()
    lap("start")
    if error is not None:
        raise InputError(error)
    row["gender"] = str(job["body"]["gender"])
    setup, settings = (_pattern_setup if is_pattern(job["garment"]) else _mesh_setup)(job, body, model, lap)
    lap("setup")
    result = run_drape(setup, settings)
    lap("drape")
    maps = fit_maps(setup, result.pos)
    fit = process_cache.fit_table(model, body).rows(setup, result.pos, maps)
    lap("fit")
    row.update(worst(pattern_block(setup, result.pos, maps, fit)))
    m = result.metrics
    row.update(status="ok" if result.converged else "not_converged", frames=result.frames,
               fit=fit, fit_summary=summary_line(fit), tight_openings=sum(1 for o in setup.openings
                                                                          if o["required_strain"] > 0),
               **{k: m.get(k) for k in ("surface_inside_percent", "surface_max_depth_mm", "vertex_inside_percent",
                                        "max_strain", "p99_strain", "shear_p99_deg", "shear_max_deg")})
    if not result.converged:
        st = result.settle
        row["error"] = (f"not settled within {settings.max_frames} frames (last frame: {100 * st['share_moving']:.2f} % "
                        f"of the vertices moved more than {1000 * settings.settle_step:g} mm, the fastest "
                        f"{st['max_step_mm']:.2f} mm); figures of the last frame")
    if job.get("keep_meshes"):
        row["meshes"] = _mesh_bytes(setup, result.pos, maps, model)
        lap("meshes")


def _settings(job, pattern=False):
    """The drape settings of a task (its ``frames``; a pattern's on the projective solver, which sews)."""
    frames = job["drape"].get("frames")
    settings = DrapeSettings() if frames is None else DrapeSettings(max_frames=int(frames))
    return projective(settings) if pattern else settings


def _mesh_setup(job, body, model, lap):
    """(DrapeSetup, DrapeSettings) of a garment mesh's task, graded to its size first when it has one."""
    garment = load_garment(job["garment"], units=job["units"])
    reference = None
    if job.get("size"):
        garment, reference = _sized(garment, model, body, garment_gender(garment) or job["body"]["gender"],
                                    job["size"])
        lap("grade")
    opts, settings = job["drape"], _settings(job)
    return prepare_drape(garment, body, model, reference=reference, material=job["material"],
                         pin=opts.get("pin", "auto"), transfer=opts.get("transfer", "auto"),
                         rest=opts.get("rest", "garment"), collider=opts.get("collider", "mesh"),
                         settings=settings), settings


def _pattern_setup(job, body, model, lap):
    """(DrapeSetup, DrapeSettings) of a sewing pattern's task: read and checked (with its seams sidecar),
    meshed, placed round the body, to be sewn (``vfit drape PATTERN``'s path)."""
    pattern, _ = load(job["garment"], job.get("seams"))
    settings = _settings(job, pattern=True)
    return prepare_pattern_drape(pattern, body, model, material=job["material"],
                                 spacing=job.get("spacing_m") or DEFAULT_SPACING, settings=settings), settings


def _mesh_bytes(setup, pos, maps, model):
    """final.obj, fit.ply and body.obj of the drape as bytes (the client writes them: a remote worker
    need not share a file system with it)."""
    out = {}
    with tempfile.TemporaryDirectory(prefix="vfit-task-") as tmp:
        paths = {name: os.path.join(tmp, name) for name in ("final.obj", "fit.ply", "body.obj")}
        write_mesh(paths["final.obj"], setup.garment.mesh.with_verts(pos),
                   header=[f"vfit batch: {os.path.basename(str(setup.garment.source))}; metres, Y up"])
        write_fit_ply(paths["fit.ply"], setup, pos, maps)
        write_body(paths["body.obj"], model, setup.body.verts, header=["vfit batch: the body; metres, Y up"])
        for name, path in paths.items():
            with open(path, "rb") as f:
                out[name] = f.read()
    return out
