"""``vfit drape``: drape a garment on a body (the default one, a file, or one built to measurements)."""
import copy
from types import SimpleNamespace

import click

from . import morph as _morph
from ._common import (FILE_UNITS, EngineChoice, check_output_path, fit_table_lines, handle_errors, interruption,
                      write_json)
from ._outdir import OutdirLock, check_outdir, check_outputs, clear_outputs, wrote_line
from ._progress import Progress

#: ``vfit morph`` options reused here (same names, types and help), so the commands agree.
MORPH_OPTIONS = ("gender", "height", "weight") + _morph.GIRTH_OPTIONS + ("definition",)
#: Files a drape writes into OUTDIR (removed before a new run writes there, so none is left from an
#: earlier one).
OUTPUT_GLOBS = ("final.obj", "final.ply", "final.glb", "final_fine.*", "body.obj", "body.ply", "body.glb",
                "report.json", "preview.png", "fit.ply", "scene.glb", "drape.gif", "frame_*.obj", "frame_*.ply",
                "frame_*.glb")
#: An unpinned garment that did not settle and whose mean height fell by more than this (m) slid down the
#: body: the error says so.
FELL_M = 0.05
#: ``--gif`` keeps every GIF_EVERY-th frame and draws at most GIF_FRAMES of them.
GIF_EVERY = 2
GIF_FRAMES = 60


def morph_options(func=None, *, garment=True):
    """Add ``vfit morph``'s body options to a command (copies of its click parameters); ``garment``: the
    command has a garment, whose gender is the default."""
    if func is None:
        return lambda f: morph_options(f, garment=garment)
    params = {p.name: p for p in _morph.morph.params}
    for name in reversed(MORPH_OPTIONS):
        opt = copy.copy(params[name])
        if name == "gender" and garment:
            # here the default is the garment's own gender, not always female
            opt.show_default = False
            opt.help = "Body gender: female, male or a blend 0..1 [default: the garment's, from its .mhclo tags, else female]."
        func.__click_params__ = getattr(func, "__click_params__", [])
        func.__click_params__.append(opt)
    return func


#: ``vfit drape``'s options for a sewing pattern, reused by ``vfit animate`` (:func:`pattern_options`).
PATTERN_OPTIONS = ("seams", "spacing", "arrange")


def pattern_options(func):
    """Add ``vfit drape``'s options of a sewing pattern (:data:`PATTERN_OPTIONS`: copies of its click parameters)
    to another command."""
    params = {p.name: p for p in drape.params}
    for name in reversed(PATTERN_OPTIONS):
        func.__click_params__ = getattr(func, "__click_params__", [])
        func.__click_params__.append(copy.copy(params[name]))
    return func


def body_targets(body_path, girths, height, weight):
    """The measurement targets (name -> m) of ``morph_options``' values (cm); InputError when a body file is
    given with them."""
    from vfit_engine.errors import InputError

    targets = {k.replace("_", "-"): v / 100.0 for k, v in girths.items() if v is not None}
    if height is not None:
        targets["height"] = height / 100.0
    if body_path and (targets or weight is not None):
        raise InputError("give either --body or measurement options, not both")
    return targets


@click.command()
@click.argument("garment", type=click.Path(dir_okay=False))
@click.option("--body", "body_path", default=None, type=click.Path(dir_okay=False),
              help="Body to drape on (.obj/.ply with hm08 topology, e.g. from vfit morph). Default: the "
                   "average body of the garment's gender, or one built from the measurement options.")
@morph_options
@click.option("--material", default="cotton", show_default=True,
              help="silk, cotton, wool, denim, jersey, or a material .json file (keys with units: see README).")
@click.option("--rest", type=EngineChoice("vfit_engine.drape.setup:REST_MODES"), default="garment",
              show_default=True,
              help="The cloth's own size: garment = the garment as given (a size M shirt on a large body is "
                   "tight, and the report says where); graded = made to measure: the garment graded to this "
                   "body first (MakeHuman's refit), so it fits any body.")
@click.option("--transfer", type=EngineChoice("vfit_engine.garment.transfer:METHODS"), default="auto",
              show_default=True,
              help="How the garment is moved from the body it was made for to this one to start the drape "
                   "(only the start; the rest shape is --rest): auto = mhclo-delta when a .mhclo is beside "
                   "the garment and the body has its helper vertices, else dqs; none = start where it is.")
@click.option("--collider", type=EngineChoice("vfit_engine.drape.colliders:COLLIDERS"), default="mesh",
              show_default=True,
              help="mesh = the exact body surface; spheres, bone-spheres, ellipsoids, hulls = shapes fitted "
                   "to the body: faster to move but approximate (BENCHMARKS.md: how far each lets cloth sink "
                   "in or float).")
@click.option("--pin", default="auto", show_default=True,
              help="auto (waistbands and shoulders, attached to the body), none, or a text file of garment "
                   "vertex indices (0-based, one per line).")
@click.option("--units", type=FILE_UNITS, default="auto", show_default=True,
              help="Units of the garment file (auto: from its height; MakeHuman clothes are dm).")
@click.option("--frames", type=click.IntRange(1, 100000), default=None,
              help="Most frames to simulate (60 per simulated second; 20 s) [default: 1200].")
@click.option("--refine", type=click.IntRange(0, 2), default=0, show_default=True,
              help="Simulate the cloth subdivided N times (each polygon into quads) and read the garment's own "
                   "vertices back from it: folds narrower than its polygons (silk on a coarse skirt); each level "
                   "costs ~3-5x the time. Also writes OUTDIR/final_fine.obj, the subdivided cloth.")
@click.option("--ground/--no-ground", default=True, show_default=True,
              help="A ground plane under the body's feet (5 mm below its lowest point) that the cloth rests on: "
                   "trousers or a dress longer than the legs pool on it.")
@click.option("--every", type=click.IntRange(0, 100000), default=10, show_default=True,
              help="Write frame_NNNN every K frames, frame_0000 being the start (0: none).")
@click.option("--format", "fmt", type=EngineChoice("vfit_engine.io.mesh:FORMATS"), default="obj", show_default=True,
              help="Mesh format of final, body and frame files (glb: glTF for viewers, vertices split at UV seams).")
@click.option("--preview", is_flag=True, help="Also write OUTDIR/preview.png: body and garment from the front, "
                                              "side and back, the garment coloured by --map, with a colour bar.")
@click.option("--map", "map_name", type=EngineChoice("vfit_engine.fit.outputs:PICTURE_MAPS"), default="strain",
              show_default=True,
              help="Fit map that colours the preview, the GIF and scene.glb: yarn strain (%), ease (mm from the "
                   "skin) or contact pressure (kPa).")
@click.option("--gif", is_flag=True, help="Also write OUTDIR/drape.gif: the drape frame by frame, from the front.")
@click.option("--seams", default=None, type=click.Path(dir_okay=False),
              help="A DXF-AAMA pattern's seams (JSON sidecar: docs/pattern-formats.md); AAMA carries none.")
@click.option("--spacing", type=click.FloatRange(3, 100), default=None,
              help="A pattern's cloth: edge length in mm (smaller: finer folds, slower) [default: 20].")
@click.option("--arrange", type=EngineChoice("vfit_engine.pattern.placement:ARRANGEMENTS"), default="auto",
              show_default=True,
              help="How a pattern's panels start round the body: frame = where its file places them (GarmentCode), "
                   "wrap = each wrapped round its body part (named by the panel), auto = frame when it can.")
@click.option("-o", "--output", "outdir", default="drape_out", show_default=True,
              type=click.Path(file_okay=False), help="Output directory (created if missing).")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write the report to this path (always written to OUTDIR/report.json).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary.")
@click.pass_context
@handle_errors
def drape(ctx, garment, body_path, material, rest, transfer, collider, pin, units, frames, refine, ground, every,
          fmt, preview, map_name, gif, seams, spacing, arrange, outdir, json_path, quiet, gender, height, weight,
          definition, **girths):
    """Drape GARMENT (.obj/.ply, or a sewing pattern: GarmentCode .json, DXF-AAMA .dxf with --seams) on a body
    and write the result to OUTDIR.

    A pattern's panels are meshed, placed round the body and sewn there, then
    the garment drapes as any garment does; its strain is against the flat
    pattern, and final.obj carries the panels' coordinates as UVs (m) and a
    group per panel. Its report adds, per seam, the gap left between its sewn
    points (mm; pulled open over 2 mm) and its line's stretch (%), and per
    panel its strain (%), its area on the body (%) and its share of each
    region's ease (cm); the 5 worst seams and every panel are printed.

    The garment keeps its own size: on a bigger body it is stretched, on a
    smaller one it hangs loose, and the report says where and by how much
    (--rest graded grades it to the body instead). Writes OUTDIR/final.obj (the
    garment's vertex order, faces and UVs; metres, Y up), OUTDIR/body.obj,
    OUTDIR/report.json (with a fit table per body region), OUTDIR/fit.ply (the
    fit maps per vertex: strain, shear_deg, ease_mm, pressure_kpa, contact),
    OUTDIR/scene.glb (body and garment coloured by --map) and, with --every K,
    OUTDIR/frame_NNNN.obj. Exit 3 when
    the cloth has not settled within --frames, 4 when the simulation diverged
    (the last good frame is kept).

    \b
    Examples:
      vfit drape shirt.obj
      vfit drape suit.obj --waist 75 --hips 100 --material denim -o out/
      vfit drape suit.obj --body body.obj --every 10 --preview
    """
    import os
    import time

    from vfit_engine.errors import InputError

    t_start = time.perf_counter()
    targets = body_targets(body_path, girths, height, weight)
    if not os.path.isfile(garment):
        raise InputError(f"garment file not found: {garment}")
    check_outdir(outdir)
    if json_path:
        check_output_path(json_path, (".json",), outdir=outdir)
    check_outputs(outdir, OUTPUT_GLOBS, {**user_files(garment, body_path, pin, material), "--seams": seams},
                  extra_outputs=[json_path])
    gender_given = ctx.get_parameter_source("gender") != click.core.ParameterSource.DEFAULT
    pattern_only(ctx, garment, seams=seams, spacing=spacing, arrange=arrange)
    opts = SimpleNamespace(garment=garment, body_path=body_path, material=material, rest=rest, transfer=transfer,
                           seams=seams, spacing=spacing, arrange=arrange,
                           collider=collider, pin=pin, units=units, frames=frames, refine=refine, ground=ground,
                           every=every, fmt=fmt,
                           preview=preview, map_name=map_name, gif=gif, outdir=outdir, json_path=json_path, quiet=quiet,
                           gender=gender if gender_given else None, weight=weight, definition=definition,
                           targets=targets, t_start=t_start, cleared=False)
    opts.progress = Progress(quiet)
    try:
        with OutdirLock(outdir), opts.progress.compiling():  # a first run's compiles, shown where they happen
            code = _drape(opts)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM (the vfit group's) outside the drape and its outputs
        name, code = interruption(exc)
        if opts.cleared:  # after the earlier run's outputs were removed: say what is there
            click.echo(f"Error: interrupted by {name}; {_kept(outdir) or 'no output'} in {outdir}", err=True)
        else:
            click.echo(f"Error: interrupted by {name} before the drape started; nothing written", err=True)
    if code:
        ctx.exit(code)


#: options that only a garment mesh takes, and their defaults: a pattern is sewn, not placed, moved or pinned
MESH_ONLY = dict(rest="garment", transfer="auto", collider="mesh", pin="auto", units="auto", refine=0)


def pattern_only(ctx, garment, **given):
    """Refuse the options that do not go with GARMENT's kind (mesh or pattern), naming them."""
    from vfit_engine.errors import InputError
    from vfit_engine.pattern.load import is_pattern

    source = lambda name: ctx.get_parameter_source(name) != click.core.ParameterSource.DEFAULT
    if is_pattern(garment):  # (of the options the command has)
        bad = [n for n in MESH_ONLY if n in ctx.params and source(n) and ctx.params[n] != MESH_ONLY[n]]
        if bad:
            raise InputError(f"{garment}: --{bad[0]} is for a garment mesh; a pattern is sewn round the body "
                             "(its seams hold it) and keeps the flat pattern's size")
    else:
        bad = [n for n in given if source(n)]
        if bad:
            raise InputError(f"{garment}: --{bad[0]} is for a sewing pattern (.json, .dxf), not a garment mesh")


def user_files(garment, body_path=None, pin=None, material=None):
    """The files a drape reads that the user named (or that go with one): what (for the message) -> path."""
    import os

    from vfit_engine.garment.garment import find_mhclo

    files = {"garment": garment, "the garment's binding": find_mhclo(garment) if os.path.isfile(garment) else None,
             "--body": body_path}
    if pin not in (None, "auto", "none"):
        files["--pin"] = pin
    if material is not None and os.path.isfile(material):  # else a built-in material's name
        files["--material"] = material
    return files


def _kept(outdir):
    """The outputs present in OUTDIR, as a user reads them: 'final.obj, report.json and 3 frame files'."""
    import glob
    import os

    names = sorted({os.path.basename(p) for pattern in OUTPUT_GLOBS
                    for p in glob.glob(os.path.join(glob.escape(outdir), pattern))})
    frames = [n for n in names if n.startswith("frame_")]
    parts = [n for n in names if not n.startswith("frame_")]
    if frames:
        parts.append(f"{len(frames)} frame file{'s' if len(frames) > 1 else ''}")
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1] if parts else ""


def _drape(o):
    """The drape command's work inside its held OUTDIR (``o``: the options); returns the exit code (0, 3 not
    settled, 130 / 143 interrupted)."""
    import os

    from vfit_engine.body.model import BodyModel
    from vfit_engine.drape import DrapeSettings, prepare_drape
    from vfit_engine.drape.setup import garment_gender
    from vfit_engine.errors import InputError
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.garment.pins import read_pin_file
    from vfit_engine.pattern.load import is_pattern

    progress = o.progress
    progress.stage(f"reading {os.path.basename(o.garment)}")
    if is_pattern(o.garment):
        return _drape_pattern(o)
    g = load_garment(o.garment, units=o.units)
    sizes = g.mesh.face_sizes()
    if o.fmt == "ply" and sizes.size and sizes.max() > 255:  # found now, not when the first frame is written
        big = int(sizes.argmax())
        raise InputError(f"{o.garment}: face {big + 1} has {int(sizes[big])} vertices, more than a PLY face holds "
                         "(255): use --format obj or split the face")
    pins = o.pin if o.pin in ("auto", "none") else read_pin_file(o.pin, g.mesh.n_verts)
    model = BodyModel.load()
    tag_gender = garment_gender(g)
    for w in g.warnings:
        click.echo(f"Warning: {o.garment}: {w}", err=True)
    body = _body(o, model, tag_gender)
    settings = DrapeSettings(refine=o.refine, ground=o.ground,
                             **({} if o.frames is None else dict(max_frames=o.frames)))
    progress.stage("placing the garment, pinning it, building the body's collision grid")
    setup = prepare_drape(g, body, model, material=o.material, pin=pins, transfer=o.transfer, rest=o.rest,
                          collider=o.collider, settings=settings)
    for w in setup.pins.info.get("warnings", []):
        click.echo(f"Warning: {o.garment}: {w}", err=True)
    context = dict(garment=o.garment, garment_units=g.units, garment_vertices=g.mesh.n_verts,
                   garment_gender=tag_gender, warnings=list(g.warnings), body=body.description)
    return _run(setup, settings, model, o, g, context)


def _body(o, model, garment_gender):
    """The body a drape is on (``o``: the options), its stage said; the gender given, else the garment's, else
    female."""
    from vfit_engine.body.resolve import resolve_body

    o.progress.stage("building the body to the measurements" if o.targets or o.weight is not None else
                     f"reading the body {o.body_path}" if o.body_path else "loading the default body")
    return resolve_body(model, o.body_path, o.targets, o.weight, o.gender or garment_gender or "female", o.definition)


def _drape_pattern(o):
    """``_drape`` of a sewing pattern: read and checked, its panels meshed, placed and sewn on the body."""
    from vfit_engine.body.model import BodyModel
    from vfit_engine.drape import DrapeSettings
    from vfit_engine.drape.settings import projective

    model = BodyModel.load()
    # sewing closes the seams with the projective solver (drape.sew)
    settings = projective(DrapeSettings(ground=o.ground, **({} if o.frames is None else dict(max_frames=o.frames))))
    setup, context = pattern_setup(o, model, settings)
    return _run(setup, settings, model, o, setup.garment, context)


def pattern_setup(o, model, settings):
    """A sewing pattern's drape set up on its body (``o``: the options of ``vfit drape`` or ``vfit animate``: the
    pattern file, ``seams``, ``spacing`` (mm or None), ``arrange``, ``material`` and the body's), its warnings said;
    returns (DrapeSetup, the report's context). ``settings``: projective (sewing needs that solver)."""
    from vfit_engine.drape.sew import prepare_pattern_drape
    from vfit_engine.pattern.load import load
    from vfit_engine.pattern.mesh import DEFAULT_SPACING

    pat, warnings = load(o.garment, o.seams)
    for w in warnings:  # each names the file
        click.echo(f"Warning: {w}", err=True)
    body = _body(o, model, None)
    o.progress.stage("meshing the panels, placing them round the body, building the body's collision grid")
    spacing = DEFAULT_SPACING if o.spacing is None else o.spacing / 1000.0
    setup = prepare_pattern_drape(pat, body, model, material=o.material, spacing=spacing, arrange=o.arrange,
                                  settings=settings)
    context = dict(garment=o.garment, garment_units="m", garment_vertices=setup.garment.mesh.n_verts,
                   garment_gender=None, warnings=list(warnings), body=body.description, pattern=setup.info["pattern"])
    return setup, context


def _run(setup, settings, model, o, g, context):
    """Drape a set-up, write its outputs and say how it went; returns the exit code."""
    import os
    import time

    from vfit_engine.errors import InputError

    clear_outputs(o.outdir, OUTPUT_GLOBS)
    o.cleared = True
    result, written = _simulate(setup, settings, o, context)
    if isinstance(result, int):  # interrupted: its exit code
        return result
    try:
        report = _finish(setup, result, model, o, written, context, time.perf_counter() - o.t_start)
        write_json(os.path.join(o.outdir, "report.json"), report)
        if o.json_path:
            try:
                write_json(o.json_path, report)
            except InputError as exc:  # it was writable before the drape: not a reason to hide an exit 3
                if result.converged:
                    raise
                click.echo(f"Warning: {exc}; the report is in {os.path.join(o.outdir, 'report.json')}", err=True)
    except KeyboardInterrupt as exc:
        return _interrupted_writing(setup, result, o, written, context, exc)
    if not o.quiet:
        _summary(g, setup, result, report)
        click.echo(wrote_line(o.outdir, written + [os.path.join(o.outdir, "report.json")]))
    return 0 if result.converged else _unsettled(setup, result, settings, report)


def _interrupted_writing(setup, result, o, written, context, exc):
    """Ctrl-C or SIGTERM after the drape, while its outputs were written: a report marked interrupted (listing
    the outputs complete) and the error line naming them; returns the exit code (130 / 143)."""
    import os

    from vfit_engine.drape import drape_report

    name, code = interruption(exc)
    rep = drape_report(setup, outputs=written, interrupted=dict(signal=name, frames=result.frames),
                       interrupted_while="writing the outputs of the finished drape", **context)
    write_json(os.path.join(o.outdir, "report.json"), rep)
    if o.json_path:
        write_json(o.json_path, rep)
    click.echo(f"Error: interrupted by {name} after the drape ({result.frames} frames) while writing its outputs; "
               f"kept {_kept(o.outdir)} in {o.outdir} (report.json says interrupted)", err=True)
    return code


def _unsettled(setup, result, settings, report):
    """The exit-3 error line of a drape that did not settle; returns 3."""
    drop = float(setup.start[:, 1].mean() - result.pos[:, 1].mean())
    if setup.pins.indices.size == 0 and drop > FELL_M and not setup.seams.size:  # a sewn pattern has no pins
        # unpinned, it slides down the body (or falls off it): say so, not only that it kept moving
        click.echo(f"Error: the garment slid {100 * drop:.0f} cm down the body in {result.frames} frames and did "
                   f"not stop: {_no_pins(setup.pins.info)}", err=True)
        return 3
    click.echo(f"Error: the cloth did not settle within {settings.max_frames} frames: {report['settle']['test']} "
               f"failed (last frame: {100 * result.settle['share_moving']:.2f} % of the vertices moved more "
               f"than {1000 * settings.settle_step:g} mm, the fastest {result.settle['max_step_mm']:.2f} mm)", err=True)
    return 3


def _no_pins(info):
    """Why nothing held the garment up, and what to do, from the pins' summary (``Pins.info``): --pin auto
    in use is not the advice for a garment it could not pin."""
    mode, inside = info.get("mode"), info.get("dropped_inside", 0)
    if mode == "none":
        return "nothing holds it up without pins; use --pin auto or a pin file"
    let_go = f" (its {inside} pin(s) lay inside the body and were let go)" if inside else ""
    found = "--pin auto held nothing" if mode == "auto" else "the pin file held nothing"
    return (f"{found}{let_go}; give a pin file of the vertices that rest on the body (a waistband, the "
            "shoulders), or check that the garment is made to be worn on this body")


def _simulate(setup, settings, o, context):
    """Run the drape, writing frames and its progress; returns (result, written files).

    On divergence the last good frame and a report are written and DrapeDiverged re-raised; on Ctrl-C or
    SIGTERM the frames so far stay, a report marked ``interrupted`` is written, and the result is the exit
    code (130 / 143).
    """
    import os

    from vfit_engine.drape import DrapeDiverged, drape_report, run_drape

    written, done = [], [0]
    o.gif_frames = [setup.start.astype("float32")] if o.gif else None

    def save(name, verts):
        path = os.path.join(o.outdir, f"{name}.{o.fmt}")
        _write_garment(path, setup, verts, context)
        written.append(path)

    def report(**what):
        rep = drape_report(setup, outputs=written, **what, **context)
        write_json(os.path.join(o.outdir, "report.json"), rep)
        if o.json_path:
            write_json(o.json_path, rep)

    o.progress.stage(f"settling (up to {settings.max_frames} frames; it ends when the cloth stops moving)")

    def on_frame(frame, pos, moving):
        done[0] = frame
        if o.every and frame % o.every == 0:
            save(f"frame_{frame:04d}", pos)
        if o.gif_frames is not None and frame % GIF_EVERY == 0:
            o.gif_frames.append(pos.astype("float32"))
        o.progress.frame(frame, moving, settings.max_frames)

    try:
        if o.every:
            save("frame_0000", setup.start)
        return run_drape(setup, settings, on_frame=on_frame), written
    except DrapeDiverged as exc:
        if exc.last_good is not None:
            save(f"frame_{exc.last_good_frame:04d}", exc.last_good)
        report(diverged=exc)
        raise
    except KeyboardInterrupt as exc:
        name, code = interruption(exc)
        report(interrupted=dict(signal=name, frames=done[0]))
        click.echo(f"Error: interrupted by {name} after {done[0]} frames; kept "
                   f"{len(written)} frame file(s) and report.json in {o.outdir}", err=True)
        return code, written
    finally:
        o.progress.done()


def _finish(setup, result, model, o, written, context, elapsed):
    """Write the final garment, the body, the fit maps and scene and (asked for) the pictures; return the
    report (with the fit table)."""
    import os

    from vfit_engine.body.bodyio import write_body
    from vfit_engine.drape import drape_report
    from vfit_engine.fit.maps import MAP_UNITS, fit_maps
    from vfit_engine.fit.outputs import write_fit_ply, write_preview, write_scene
    from vfit_engine.fit.pattern_fit import pattern_block
    from vfit_engine.fit.table import FitTable
    from vfit_engine.fit.verdict import summary_line, too_tight
    from vfit_engine.io.mesh import write_mesh

    if result.fine is not None:  # the subdivided cloth as simulated (no UVs: its vertices are not the garment's)
        fine = os.path.join(o.outdir, f"final_fine.{o.fmt}")
        write_mesh(fine, result.fine, header=["vfit drape: the subdivided cloth as simulated (--refine); metres, Y up"])
        written.append(fine)
    final = os.path.join(o.outdir, f"final.{o.fmt}")
    _write_garment(final, setup, result.pos, context)
    written.append(final)
    body_file = os.path.join(o.outdir, f"body.{o.fmt}")
    write_body(body_file, model, setup.body.verts,
               header=[f"vfit drape: the body draped on ({setup.body.description.get('source')}); metres, Y up"])
    written.append(body_file)
    o.progress.stage("measuring the fit: maps, the table per body region, the scene")
    maps = fit_maps(setup, result.pos)
    rows = FitTable(setup.body, model).rows(setup, result.pos, maps)
    paths = {name: os.path.join(o.outdir, name) for name in ("fit.ply", "scene.glb", "preview.png", "drape.gif")}
    write_fit_ply(paths["fit.ply"], setup, result.pos, maps)
    written.append(paths["fit.ply"])
    write_scene(paths["scene.glb"], setup, result.pos, model, maps, o.map_name)
    written.append(paths["scene.glb"])
    if o.preview:
        write_preview(paths["preview.png"], setup, result.pos, model, maps, o.map_name, rows=rows)
        written.append(paths["preview.png"])
    if o.gif:
        _write_gif(paths["drape.gif"], setup, model, o.gif_frames + [result.pos])
        written.append(paths["drape.gif"])
    fit = dict(fit=rows, fit_summary=summary_line(rows),
               too_tight=too_tight(rows, setup.material.wearable_stretch),
               fit_units=dict(girth="cm", ease="cm", strain="fraction", pressure="kPa"),
               fit_maps=dict(file="fit.ply", properties=MAP_UNITS))
    block = pattern_block(setup, result.pos, maps, rows)
    if block is not None:  # a sewn pattern: its seams and panels beside what set it up
        context = {**context, "pattern": {**context["pattern"], **block}}
    return drape_report(setup, result, outputs=written, total_time_s=elapsed, **fit, **context)


def _write_gif(path, setup, model, frames):
    """``drape.gif`` of the garment ``frames`` on the body, at most ``GIF_FRAMES`` of them, evenly spread."""
    import numpy as np

    from vfit_engine.animation import write_gif

    pick = np.unique(np.linspace(0, len(frames) - 1, min(len(frames), GIF_FRAMES)).round().astype(int))
    write_gif(path, setup.body.surface, model.body_tris, [frames[k] for k in pick], setup.garment.mesh.triangles())


def _write_garment(path, setup, verts, context):
    import os

    from vfit_engine.io.mesh import write_mesh

    header = [f"vfit drape: {os.path.basename(context['garment'])} on the {setup.body.description.get('source')} "
              "body; metres, Y up"]
    write_mesh(path, setup.garment.mesh.with_verts(verts), header=header)


def _summary(g, setup, result, report):
    """The lines a user reads: settled or not, skin through the cloth, strain, shear, the fit table, a pattern's
    seams and panels, tight openings."""
    from vfit_engine.fit.pattern_fit import block_lines

    m = result.metrics
    click.echo(f"vfit drape: {g.mesh.n_verts} vertices, {result.frames} frames ({result.steps} steps, "
               f"{result.sim_time:.2f} s simulated) in {result.wall_time:.2f} s; "
               f"{'settled' if result.converged else 'NOT settled'}")
    click.echo(f"  cloth surface inside the body: {m['surface_inside_percent']:.2f} % of "
               f"{m['surface_samples']} samples, deepest {m['surface_max_depth_mm']:.2f} mm")
    against = "the flat pattern" if setup.info["rest"] == "pattern" else "the garment as given"
    click.echo(f"  yarn strain against {against}: p99 {100 * m['p99_strain']:.2f} %, "
               f"max {100 * m['max_strain']:.2f} %; shear p99 {m['shear_p99_deg']:.1f} deg, "
               f"max {m['shear_max_deg']:.1f} deg" + ("  (graded to this body: --rest graded)"
                                                      if setup.info["rest"] == "graded" else ""))
    _fit_table(report["fit"], setup.material)
    if (report.get("pattern") or {}).get("seams") is not None:
        click.echo("\n".join("  " + line for line in block_lines(report["pattern"], report["fit"])))
    for t in report["too_tight"]:
        need = t.get("required_strain") or 0.0
        click.echo(f"  too tight to wear at the {t['region']}: the cloth round it is stretched "
                   f"{100 * t['stretch']:.1f} %" + (f" (the body needs >= {100 * need:.1f} %)" if need > 0 else "")
                   + f", beyond the {100 * t['fabric_limit']:.0f} % {setup.material.name} gives: it cannot be worn")
    click.echo(f"  fit: {report['fit_summary']}")


def _fit_table(rows, material):
    """The fit table as people read it: one row per region, its verdict by the one rule (vfit_engine.fit.verdict)."""
    if not rows:
        return
    click.echo(f"  fit per region (* a girth sizes are labelled by; stretch of the cloth round it, {material.name} "
               f"gives {100 * material.wearable_stretch:.0f} %):")
    click.echo("\n".join("    " + line for line in fit_table_lines(rows)))
