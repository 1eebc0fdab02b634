"""Which size? A size run of a garment, each size tried on the customer, and the size to buy.

(A sewing pattern's size run, graded by its own rule and sewn on the customer: :mod:`vfit_engine.pattern_sizes`,
which takes its size bodies, processes, tables and rule from here.)

::

    results = try_sizes("suit.obj", {"targets": {"height": 1.80, "bust": 0.98}, "gender": "male"})
    size, reason = recommend(results)

1. **The size run.** The sizes are the EN 13402-3 letter sizes XS ... XL (:data:`SIZES`: the centre of
   each size's bust -- men: chest -- interval, with waist and hips stepped alongside, as
   ``scripts/pipeline_sizes.py`` drapes them). A *size body* is the garment's own body (MakeHuman's
   average body of its gender, the body a MakeHuman garment is made on) built to a size's centre
   girths (:func:`size_body`) **at the customer's height**: the letter size is a girth size, and
   body length is a separate dimension of EN 13402 (a shop sells the lengths of a size apart), so
   every size is cut in the customer's length and the sizes differ only in their girths. The garment
   as given is the size whose centre bust/chest is nearest that of its own body
   (:func:`garment_size`: 96.7 cm for the male garments, size M; 84.5 cm for the female ones, S).
2. **Grading.** Size X is the garment graded from its own body to size X's body by the
   made-to-measure transfer of the drape set-up (:func:`grade`: ``prepare_drape(..., rest="graded")``,
   i.e. its ``.mhclo`` binding's change between the two bodies, else dual-quaternion skinning). Every
   size, the garment's own included, is graded to its centre, so neighbouring sizes differ only by
   the steps between the centres.
3. **Trying on.** Size X is draped *at its own size* on the customer
   (``prepare_drape(garment_X, customer, reference=size_body_X, rest="garment")``, then
   ``run_drape``): the graded garment sits on its size body as a MakeHuman garment sits on its own,
   so its binding places it and carries it to the customer. The fit table
   (:func:`vfit_engine.fit.table.fit_table`) says, per body region, too tight to wear, tight, fitted,
   loose or too loose.
   The sizes run in parallel processes (:func:`try_sizes`; one Numba thread each).
4. **The rule** (:func:`recommend`): the smallest size whose every region is at least ``fitted``: no
   ``tight`` or ``too tight to wear`` verdict (:func:`vfit_engine.fit.verdict.is_tight`, the one rule's
   verdicts of the fit table) at any row of its table -- chest/bust, waist, hips, neck, upper arms,
   thighs and the garment's openings (waistband, neckline, hems); a size too small is *rejected* by the
   rows that are tight (:func:`rejection`: "tight at the left upper arm ..."). If every size is tight
   somewhere, the largest, saying that it is still tight and where. A size whose drape diverged or
   failed has no verdict and is passed over (the reason says so); one that did not settle within the
   frame limit is judged on its last frame (the reason says so).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from vfit_engine import process_cache
from vfit_engine.body.measure import Measurer, stature
from vfit_engine.body.model import BodyModel
from vfit_engine.body.resolve import Body, default_body, resolve_body
from vfit_engine.drape import DrapeDiverged, DrapeSettings, prepare_drape, run_drape
from vfit_engine.drape.setup import garment_gender
from vfit_engine.errors import InputError, VfitError
from vfit_engine.fit.verdict import is_tight, stretch, summary_line
from vfit_engine.garment.garment import load_garment
from vfit_engine.garment.placement import place_garment
from vfit_engine.garment.transfer import transfer_garment
from vfit_engine.sim.materials import resolve_material
from vfit_engine.worker_pool import default_workers, pool_results, worker_pool

#: EN 13402-3 letter sizes: (size, bust/chest, waist, hips) in cm, the middle of each size's interval
#: (women's bust XS 74-82 ... XL 107-119, men's chest XS 78-86 ... XL 110-118; waist and hips stepped
#: alongside; ../shared/reference/MEASUREMENTS.md).
SIZES = {
    "female": (("XS", 78, 62, 86), ("S", 86, 70, 94), ("M", 94, 78, 102), ("L", 102, 86, 110), ("XL", 113, 95, 119)),
    "male": (("XS", 82, 70, 84), ("S", 90, 78, 91), ("M", 98, 86, 98), ("L", 106, 94, 105), ("XL", 114, 102, 112)),
}
#: The sizes, smallest first.
SIZE_NAMES = tuple(s[0] for s in SIZES["female"])
#: The rule of :func:`recommend`, in words (``vfit size --help`` and the JSON say it).
RULE = ("the smallest size whose every region is at least fitted: no tight verdict (tight or too tight to wear) at "
        "any region of its fit table (chest/bust, waist, hips, neck, upper arms, thighs, openings); if every size is "
        "tight somewhere, the largest, saying where it is tight")
#: Statuses of a tried size: judged on its settled drape, on its last frame, or not judged.
STATUSES = ("settled", "not settled", "diverged", "failed")
#: Statuses whose fit table counts.
JUDGED = ("settled", "not settled")
#: Frame limit of each size's drape (5 s simulated; ``vfit drape``'s is 1200). The sizes that settle do so
#: in 70-160 frames on the shared outfits; one the body stretches far beyond its size creeps on for
#: the whole 600 frames (30 s of the run) and its verdicts at frame 150 already equal those at 600
#: (XS of male_casualsuit02 on a chest of 90 cm): it is judged on its last frame, marked not settled.
SIZE_MAX_FRAMES = 300


def size_gender(gender):
    """"female" or "male": the size table of a gender ("female", "male" or a blend 0..1, male >= 0.5)."""
    if isinstance(gender, str):
        if gender not in SIZES:
            raise InputError(f"unknown gender {gender!r}; use female, male or a number in 0..1")
        return gender
    return "male" if float(gender) >= 0.5 else "female"


def size_centres(gender):
    """The EN 13402 centre girths of every size.

    Parameters
    ----------
    gender : "female", "male" or float in 0..1

    Returns
    -------
    dict
        Size name (smallest first) -> ``{"bust": m, "waist": m, "hips": m}`` (men's chest is ``bust``,
        the name :meth:`vfit_engine.body.morph.Morpher.solve` takes).
    """
    return {name: {"bust": b / 100.0, "waist": w / 100.0, "hips": h / 100.0}
            for name, b, w, h in SIZES[size_gender(gender)]}


def parse_sizes(text):
    """Size names from ``"XS,S,M"`` (any case, any order), smallest first; InputError naming a bad one."""
    names = [t.strip().upper() for t in str(text).split(",") if t.strip()]
    bad = [n for n in names if n not in SIZE_NAMES]
    if bad or not names:
        what = f"unknown size {bad[0]!r}" if bad else "no size given"
        raise InputError(f"{what}; use a comma-separated list of {', '.join(SIZE_NAMES)}")
    return [n for n in SIZE_NAMES if n in names]


def garment_size(reference, gender, measurer=None):
    """The size of the garment as given: the size whose centre bust/chest is nearest its body's.

    Parameters
    ----------
    reference : Body
        The body the garment was made on (:func:`vfit_engine.body.resolve.default_body` of its gender).
    gender : "female", "male" or float in 0..1
    measurer : Measurer or None

    Returns
    -------
    dict
        ``size``, ``measure`` ("bust" or "chest"), ``body_cm`` (the body's iso bust/chest girth),
        ``centre_cm`` (that size's centre).
    """
    measurer = measurer or Measurer()
    key = size_gender(gender)
    bust = 100.0 * measurer.measure(reference.verts, names=("bust",), mass=False, gender=key).values["bust"]
    name, centre = min(((s[0], s[1]) for s in SIZES[key]), key=lambda s: abs(s[1] - bust))
    return dict(size=name, measure="chest" if key == "male" else "bust", body_cm=round(bust, 2), centre_cm=centre)


def size_body(model, gender, size, height_m=None):
    """The body at the centre of ``size`` (:data:`SIZES`), ``height_m`` tall (None: the average body's)."""
    targets = dict(size_centres(gender)[size])
    if height_m is not None:
        targets["height"] = float(height_m)
    return resolve_body(model, targets=targets, gender=gender, definition="iso")


def grade(garment, size_body, model, reference=None):
    """The garment graded from the body it was made on to ``size_body`` (the made-to-measure transfer).

    This is the rest shape ``prepare_drape(garment, size_body, model, reference, rest="graded")`` drapes
    (its steps 1-3: placed on ``reference``, moved to ``size_body`` by its ``.mhclo`` binding's change,
    else by dual-quaternion skinning, clearance restored), without the pins, openings and collider the
    drape set-up also builds (tests/test_size.py holds the two equal).

    Parameters
    ----------
    garment : Garment
    size_body : Body
        With the helper vertices when the garment has a ``.mhclo`` binding (a body vfit builds).
    model : BodyModel
    reference : Body or None
        The body the garment was made on (None: the average body of its gender, as ``prepare_drape``).

    Returns
    -------
    Garment
        A copy whose vertices are the graded garment on ``size_body`` (metres); the same faces, UVs and
        ``.mhclo`` binding, which still places it: the graded garment lies on ``size_body`` as the
        garment as given lies on its own body, so ``prepare_drape(graded, body, model,
        reference=size_body)`` places it as the file gives it and moves it by the binding's change.
    """
    binding = garment.binding()
    if reference is None:
        gender = garment_gender(garment) or (size_body.gender if isinstance(size_body.gender, str) else None)
        reference = default_body(model, gender or "female")
    placed, _ = place_garment(garment.verts, reference, binding, name=garment.source.name)
    verts, _ = transfer_garment(placed, reference.verts, size_body.verts, model.body_tris, "auto", binding)
    return dataclasses.replace(garment, mesh=garment.mesh.with_verts(verts), warnings=list(garment.warnings))


def customer_body(model, customer):
    """The customer's Body from a spec (:func:`try_sizes`)."""
    if customer.get("verts") is not None:
        return Body(np.ascontiguousarray(customer["verts"], dtype=np.float64), dict(customer.get("description") or {}),
                    customer.get("gender"))
    return resolve_body(model, customer.get("path"), customer.get("targets"), customer.get("weight_kg"),
                        customer.get("gender") or "female", customer.get("definition", "iso"))


def lap_timer(times, t0):
    """``lap(stage)``: record in ``times`` (dict) the seconds since the last lap, the first since ``t0``."""
    last = [t0]

    def lap(stage):
        now = time.perf_counter()
        times[stage] = round(now - last[0], 3)
        last[0] = now

    return lap


def try_size(job):
    """Grade the garment to one size and drape it on the customer (one worker's job of :func:`try_sizes`).

    Parameters
    ----------
    job : dict
        ``garment`` (path), ``units``, ``gender`` (of the size table), ``size``, ``height_m`` (of the size
        body), ``customer`` (a spec, see :func:`try_sizes`; here with ``verts``), ``material``,
        ``max_frames`` (None: the drape's default).

    Returns
    -------
    dict
        ``size``, ``centre_cm``, ``status`` (:data:`STATUSES`), ``message`` (why not settled / diverged /
        failed, else None), ``fit`` (the fit table's rows, None when not judged), ``summary``, ``frames``,
        ``max_strain``, ``p99_strain`` (yarn strain against the graded size), ``tight_openings`` (how many
        openings the customer's body forces wider), ``wall_s`` (the whole job) and ``times_s`` (its stages:
        ``start`` -- loading the body model and the kernels, the first job of a process --, ``size_body``,
        ``grade``, ``setup``, ``drape``, ``fit``).
    """
    t0 = time.perf_counter()
    out = blank_result(job)
    lap = lap_timer(out["times_s"], t0)
    try:
        model = job["model"] if job.get("model") is not None else process_cache.model()
        lap("start")
        garment = load_garment(job["garment"], units=job.get("units", "auto"))
        body_x = size_body(model, job["gender"], job["size"], job.get("height_m"))
        lap("size_body")
        graded = grade(garment, body_x, model)
        lap("grade")
        customer = customer_body(model, job["customer"])
        settings = DrapeSettings() if job.get("max_frames") is None else DrapeSettings(max_frames=job["max_frames"])
        setup = prepare_drape(graded, customer, model, reference=body_x, material=job.get("material", "cotton"),
                              rest="garment", settings=settings)
        drape_and_judge(out, setup, settings, model, customer, lap)
    except VfitError as exc:
        out.update(status="failed", message=str(exc))
    finally:
        out["wall_s"] = round(time.perf_counter() - t0, 3)
    return out


def drape_and_judge(out, setup, settings, model, customer, lap):
    """Run the drape of ``setup`` on ``customer`` and put its status and fit table into ``out`` (a
    :func:`try_size` result; ``lap(stage)`` times the stages setup, drape and fit)."""
    out["tight_openings"] = sum(1 for o in setup.openings if o["required_strain"] > 0)
    lap("setup")
    try:
        result = run_drape(setup, settings)
    except DrapeDiverged as exc:
        out.update(status="diverged", message=str(exc), frames=exc.frame)
        return
    finally:
        lap("drape")
    rows = [plain_row(r) for r in process_cache.fit_table(model, customer).rows(setup, result.pos)]
    lap("fit")
    m = result.metrics
    out.update(status="settled" if result.converged else "not settled", fit=rows, summary=summary_line(rows),
               frames=result.frames, max_strain=_num(m.get("max_strain")), p99_strain=_num(m.get("p99_strain")))
    if not result.converged:
        out["message"] = (f"not settled within {settings.max_frames} frames, judged on the last "
                          f"({100 * result.settle['share_moving']:.2f} % of the cloth still moving)")


def blank_result(job, message=None):
    """The result of ``job`` before it ran (or when its process died: status failed, ``message``)."""
    size = job["size"]
    return dict(size=size, centre_cm={k: round(100 * v, 1) for k, v in size_centres(job["gender"])[size].items()},
                status="failed", message=message, fit=None, summary=None, frames=None, max_strain=None,
                p99_strain=None, tight_openings=None, wall_s=None, times_s={})


def _num(x):
    return None if x is None else float(x)


def plain_row(row):
    """A fit-table row with plain Python numbers (JSON, pickling)."""
    out = {}
    for k, v in row.items():
        if isinstance(v, np.generic):
            v = v.item()
        out[k] = v
    return out


def try_sizes(garment_path, customer, sizes=None, workers=None, progress=None, units="auto", material="cotton",
              max_frames=SIZE_MAX_FRAMES, model=None):
    """Grade the garment to every size, try each at its own size on the customer, recommend one.

    Parameters
    ----------
    garment_path : str or Path
        A garment OBJ/PLY (with its ``.mhclo`` beside it for MakeHuman clothes).
    customer : dict
        Picklable spec of the customer's body: ``path`` (a body file) or ``targets`` (measurement name
        -> m, as :func:`vfit_engine.body.resolve.resolve_body` takes them) and ``weight_kg``; ``gender``
        (None: the garment's, from its ``.mhclo`` tags, else female); ``definition`` (default ``iso``).
    sizes : list of str or None
        Size names (:data:`SIZE_NAMES`; None: all), tried and reported smallest first.
    workers : int or None
        Processes (None: the cores available). With 1 the sizes run one after the other in this
        process; else each in a spawned process with one Numba thread (set before Numba is imported).
    progress : callable or None
        ``progress(text)`` with a line on each step and each size done.
    units : {"auto", "m", "dm", "cm", "mm"}
        Of the garment file.
    material : str
    max_frames : int or None
        Frame limit of each drape (:data:`SIZE_MAX_FRAMES`; None: the drape's default, 1200).
    model : BodyModel or None

    Returns
    -------
    dict
        ``recommended`` (size or None), ``reason``, ``rule``, ``garment`` (path), ``gender``,
        ``garment_size`` (:func:`garment_size`), ``size_height_cm``, ``customer`` (its iso girths, cm),
        ``sizes`` (per size, smallest first: :func:`try_size`'s dicts), ``workers``, ``wall_s``.

    Raises
    ------
    InputError
        A bad garment or body file, unknown sizes, unreachable customer measurements (before any
        drape starts).
    """
    t0 = time.perf_counter()
    say = progress or (lambda text: None)
    names = parse_sizes(",".join(sizes)) if sizes else list(SIZE_NAMES)
    resolve_material(material)  # a bad material fails here, not in every worker
    garment = load_garment(garment_path, units=units)
    n_workers = max(1, min(int(workers or default_workers()), len(names)))
    with worker_pool(n_workers) as pool:  # the workers start while this process builds the customer
        model = model or BodyModel.load()
        gender = garment_gender(garment) or customer.get("gender") or "female"
        if not isinstance(gender, str):
            gender = size_gender(gender)
        body, spec, height = sizing_customer(model, customer, gender, say)
        jobs = [dict(garment=str(garment_path), units=units, gender=gender, size=s, height_m=height, customer=spec,
                     material=material, max_frames=max_frames) for s in names]
        # the workers start on the sizes while this process measures the customer and the garment's body
        results = submit_sizes(pool, try_size, jobs, model)
        measurer = Measurer(model)
        own = garment_size(default_body(model, gender), gender, measurer)
        say(f"the garment as given is size {own['size']} (made on a {own['measure']} of {own['body_cm']:.1f} cm; "
            f"centre {own['centre_cm']} cm); trying {', '.join(names)} on {n_workers} "
            f"process{'es' if n_workers > 1 else ''}")
        out = size_run(body, measurer, height, n_workers)
        done = collect_sizes(results, len(jobs), say)
    out.update(garment=str(garment_path), gender=gender, garment_size=own, sizes=[done[s] for s in names])
    out["recommended"], out["reason"] = recommend(out)
    out["wall_s"] = round(time.perf_counter() - t0, 3)
    return out


def sizing_customer(model, customer, gender, say):
    """The customer of a size run: (Body, the picklable spec the workers rebuild it from, height m).

    ``customer`` is :func:`try_sizes`'s spec; ``gender`` the one its size table is read in (a body file
    without one takes the customer's gender, else this)."""
    spec = dict(customer)
    spec["gender"] = customer.get("gender") or gender
    say("building the customer's body" if spec.get("targets") or spec.get("weight_kg") is not None
        else "reading the customer's body" if spec.get("path") else "loading the customer's body")
    body = customer_body(model, spec)
    if body.gender is None:  # a body file: the gender asked for, else the garment's (chest or bust)
        body.gender = spec["gender"]
    return body, dict(verts=body.verts, description=body.description, gender=body.gender), stature(body.verts)


def submit_sizes(pool, job_fn, jobs, model):
    """The results of ``job_fn`` on every job as they finish: on the pool's processes, else here one by one."""
    if pool is not None:
        return pool_results({pool.submit(job_fn, job): job for job in jobs}, blank_result)
    return (job_fn(dict(job, model=model)) for job in jobs)


def collect_sizes(results, total, say):
    """{size: result} of the tried sizes, saying each as it is done."""
    done = {}
    for r in results:
        done[r["size"]] = r
        what = r["status"] if r["status"] in JUDGED else f"{r['status']}: {r['message']}"
        took = "" if r["wall_s"] is None else f" in {r['wall_s']:.1f} s"  # None: its process died
        say(f"size {r['size']}: {what}{took} ({len(done)}/{total})")
    return done


def size_run(body, measurer, height, n_workers):
    """A size run's result before its garment's fields and sizes: the rule and the customer's figures."""
    meas = measurer.measure(body.verts, names=("height", "bust", "waist", "hips"), mass=False, gender=body.gender)
    return dict(recommended=None, reason=None, rule=RULE, size_height_cm=round(100 * height, 2),
                customer={k: round(100 * v, 2) for k, v in meas.values.items()},
                customer_estimated=estimated_girths(body.description, ("bust", "waist", "hips")), workers=n_workers)


def _where(rows):
    """"the chest (ease -2.1 cm, stretched 4.2 %) and waist (...)": the tight rows of a size."""
    parts = []
    for r in rows:
        bits = []
        if r.get("ease_cm") is not None:
            bits.append(f"ease {r['ease_cm']:+.1f} cm")
        s = stretch(r)  # the one the rule reads (an opening's: at least the stretch the body forces on it)
        if s is not None:
            bits.append(f"stretched {100 * s:.1f} %")
        if r.get("verdict") == "too tight to wear":  # the rule's word where "tight" says too little
            bits.insert(0, r["verdict"])
        parts.append(_region(r["region"]) + (f" ({', '.join(bits)})" if bits else ""))
    return "the " + _join(parts)


def estimated_girths(description, names):
    """Which of ``names`` the customer did not give (the body model estimated them): a body built to
    measurements (``description``: :class:`vfit_engine.body.resolve.Body`'s) gives those not among its targets."""
    if description.get("source") != "morph":
        return []
    return [n for n in names if n not in (description.get("targets_cm") or {})]


def _region(name):
    return str(name).replace("_", " ")


def _join(words):
    words = list(words)
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def rejection(size):
    """Why a tried size is too small (:data:`RULE`): ``"tight at the chest (ease +3.4 cm, stretched 3.7 %) and left
    thigh (...)"``, the rows of its fit table whose verdict is tight or too tight to wear; None when it has none
    (or no fit table)."""
    rows = [r for r in size.get("fit") or () if is_tight(r)]
    return f"tight at {_where(rows)}" if rows else None


def recommend(results):
    """The size to buy and why (the rule: module docstring, :data:`RULE`).

    Parameters
    ----------
    results : dict or list of dict
        :func:`try_sizes`'s result, or its ``sizes``: per size, smallest first, ``size``, ``status``
        (:data:`STATUSES`) and ``fit`` (rows with ``region``, ``verdict``, ``ease_cm``, ``girth_strain``),
        ``message``.

    Returns
    -------
    (size, reason) : (str or None, str)
        None when no size could be judged.
    """
    sizes = results["sizes"] if isinstance(results, dict) else list(results)
    sizes = sorted(sizes, key=lambda s: SIZE_NAMES.index(s["size"]) if s["size"] in SIZE_NAMES else len(SIZE_NAMES))
    judged = [s for s in sizes if s.get("status") in JUDGED and s.get("fit") is not None]
    notes = [f"{s['size']} not judged ({s.get('status')}: {s.get('message')})" for s in sizes if s not in judged]
    if not judged:
        return None, "no size could be judged: " + "; ".join(notes)
    pick = next((s for s in judged if rejection(s) is None), None)
    if pick is None:
        pick = judged[-1]
        reason = f"{pick['size']}: every size tried is tight somewhere; the largest, {pick['size']}, is still " \
                 f"{rejection(pick)}"
    else:
        covered = any(r.get("garment_girth_cm") is not None for r in pick["fit"])
        where = "every region at least fitted" if covered else "not tight (it covers no region of the table)"
        smaller = [s for s in judged if SIZE_NAMES.index(s["size"]) < SIZE_NAMES.index(pick["size"])]
        reason = f"{pick['size']}: the smallest size with {where}"
        if smaller:
            below = smaller[-1]
            reason += f" ({below['size']} is {rejection(below)})"
        else:
            reason += " (the smallest size tried)"
    if pick.get("status") == "not settled":
        notes.append(f"{pick['size']} judged on its last frame: {pick.get('message')}")
    return pick["size"], reason + ("; " + "; ".join(notes) if notes else "")
