"""Which size? A sewing pattern graded into a size run, each size sewn on the customer, and the size to buy.

The size method of :mod:`vfit_engine.sizes` (the EN 13402 size bodies at the customer's height, the sizes
tried in parallel processes, the fit tables, :func:`vfit_engine.sizes.recommend`), with a pattern in place
of a garment mesh:

1. **The body the pattern was made for** (:func:`vfit_engine.pattern.grade.made_for`): its own, when the
   pattern names one (GarmentCode's body measurements beside the file), built by vfit's morph; else the
   default body of the customer's gender (female when not given, as ``vfit drape PATTERN`` takes it),
   said to be assumed. The pattern as given is the size whose centre bust/chest is nearest that body's
   (:func:`vfit_engine.sizes.garment_size`).
2. **Grading** (:func:`vfit_engine.pattern.grade.grade_to_body`): size X is the pattern graded from that
   body to size X's body by the rule of :mod:`vfit_engine.pattern.grade` (:data:`~vfit_engine.pattern.grade.RULE`),
   on its curves, before meshing, and validated.
3. **Trying on**: each graded pattern is sewn and draped on the customer as ``vfit drape PATTERN`` does
   (:func:`vfit_engine.drape.sew.prepare_pattern_drape` on the projective solver, then
   :func:`vfit_engine.drape.run_drape`), judged by the fit table; sizes with no pattern of their own are
   never draped twice.
"""
from __future__ import annotations

import time

from vfit_engine import process_cache
from vfit_engine.body.measure import Measurer
from vfit_engine.body.model import BodyModel
from vfit_engine.drape import DrapeSettings
from vfit_engine.drape.settings import projective
from vfit_engine.drape.sew import prepare_pattern_drape
from vfit_engine.errors import VfitError
from vfit_engine.pattern.grade import RULE as GRADING_RULE
from vfit_engine.pattern.grade import grade_to_body, made_for
from vfit_engine.pattern.load import load
from vfit_engine.pattern.mesh import DEFAULT_SPACING
from vfit_engine.sim.materials import resolve_material
from vfit_engine.sizes import (SIZE_NAMES, blank_result, collect_sizes, customer_body, drape_and_judge, garment_size,
                               lap_timer, parse_sizes, recommend, size_body, size_gender, size_run, sizing_customer,
                               submit_sizes)
from vfit_engine.worker_pool import default_workers, worker_pool

#: Frame limit of each size's sewn drape: sewing takes its first 40 frames, and the shared patterns settle
#: in 400-620 frames on the default body (docs/patterns.md); a size not settled by then is judged on its
#: last frame, as a garment's is.
PATTERN_MAX_FRAMES = 600


def try_pattern_size(job):
    """Grade the pattern to one size, sew it on the customer and judge its fit (a worker's job).

    Parameters
    ----------
    job : dict
        ``pattern`` (path), ``seams`` (a DXF's sidecar or None), ``spacing`` (m), ``arrange``, ``made_for``
        (:class:`vfit_engine.pattern.grade.MadeFor`), ``gender`` (of the size table), ``size``, ``height_m``
        (of the size body), ``customer`` (a spec with ``verts``), ``material``, ``max_frames``.

    Returns
    -------
    dict
        :func:`vfit_engine.sizes.try_size`'s fields, and ``grading``: the rule's ``levels`` and ``arms``
        (:class:`vfit_engine.pattern.grade.Graded`).
    """
    t0 = time.perf_counter()
    out = blank_result(job)
    lap = lap_timer(out["times_s"], t0)
    try:
        model = job["model"] if job.get("model") is not None else process_cache.model()
        lap("start")
        pattern, _ = load(job["pattern"], job.get("seams"))
        body_x = size_body(model, job["gender"], job["size"], job.get("height_m"))
        lap("size_body")
        graded = grade_to_body(pattern, job["made_for"], body_x, model, arrange=job.get("arrange", "auto"))
        out["grading"] = dict(levels=graded.levels, arms=graded.arms)
        lap("grade")
        customer = customer_body(model, job["customer"])
        settings = projective(DrapeSettings(max_frames=job.get("max_frames") or PATTERN_MAX_FRAMES))
        setup = prepare_pattern_drape(graded.pattern, customer, model, material=job.get("material", "cotton"),
                                      spacing=job.get("spacing", DEFAULT_SPACING), arrange=job.get("arrange", "auto"),
                                      settings=settings)
        drape_and_judge(out, setup, settings, model, customer, lap)
    except VfitError as exc:
        out.update(status="failed", message=str(exc))
    finally:
        out["wall_s"] = round(time.perf_counter() - t0, 3)
    return out


def try_pattern_sizes(pattern_path, customer, sizes=None, workers=None, progress=None, material="cotton",
                      max_frames=PATTERN_MAX_FRAMES, seams=None, spacing=DEFAULT_SPACING, arrange="auto",
                      model=None):
    """Grade the pattern to every size, sew each on the customer, recommend one (module docstring).

    Parameters
    ----------
    pattern_path : str or Path
        A GarmentCode JSON, or a DXF-AAMA file with its ``seams`` sidecar.
    customer : dict
        :func:`vfit_engine.sizes.try_sizes`'s spec; its ``gender`` (None: female) is also the one the
        pattern's body is built or assumed in.
    sizes, workers, progress, material :
        As :func:`vfit_engine.sizes.try_sizes`.
    max_frames : int
        Frame limit of each sewn drape.
    seams : str or Path or None;  spacing : float, m;  arrange : {"auto", "frame", "wrap"}
        As ``vfit drape PATTERN`` takes them.
    model : BodyModel or None

    Returns
    -------
    dict
        :func:`vfit_engine.sizes.try_sizes`'s fields (``garment`` the pattern's path, ``garment_size`` the
        pattern's own), and ``made_for`` (in words), ``grading_rule``, ``warnings`` (the pattern's).

    Raises
    ------
    InputError
        A bad pattern or body file, unknown sizes, a bad material, unreachable measurements (before any
        drape starts).
    """
    t0 = time.perf_counter()
    say = progress or (lambda text: None)
    names = parse_sizes(",".join(sizes)) if sizes else list(SIZE_NAMES)
    resolve_material(material)  # a bad material fails here, not in every worker
    pattern, warnings = load(pattern_path, seams)
    n_workers = max(1, min(int(workers or default_workers()), len(names)))
    with worker_pool(n_workers) as pool:  # the workers start while this process builds the bodies
        model = model or BodyModel.load()
        given = customer.get("gender") or "female"
        gender = given if isinstance(given, str) else size_gender(given)
        body, spec, height = sizing_customer(model, customer, gender, say)
        say("building the body the pattern was made for" if pattern.body else "loading the default body")
        measurer = Measurer(model)
        made = made_for(pattern, model, given, measurer)
        jobs = [dict(pattern=str(pattern_path), seams=None if seams is None else str(seams), spacing=spacing,
                     arrange=arrange, made_for=made, gender=gender, size=s, height_m=height, customer=spec,
                     material=material, max_frames=max_frames) for s in names]
        results = submit_sizes(pool, try_pattern_size, jobs, model)
        own = garment_size(made.body, gender, measurer)
        say(f"{made.text}; the pattern as given is size {own['size']} ({own['measure']} {own['body_cm']:.1f} cm; "
            f"centre {own['centre_cm']} cm); grading by the rule: {GRADING_RULE}; trying {', '.join(names)} on "
            f"{n_workers} process{'es' if n_workers > 1 else ''}")
        out = size_run(body, measurer, height, n_workers)
        done = collect_sizes(results, len(jobs), say)
    out.update(garment=str(pattern_path), gender=gender, garment_size=own, made_for=made.text,
               grading_rule=GRADING_RULE, warnings=list(warnings), sizes=[done[s] for s in names])
    out["recommended"], out["reason"] = recommend(out)
    out["wall_s"] = round(time.perf_counter() - t0, 3)
    return out
