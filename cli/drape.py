"""``vfit drape``: drape a garment on a body (the default one, a file, or one built to measurements)."""
import copy

import click

from . import morph as _morph
from ._common import check_output_path, handle_errors, write_json

#: Garment transfer methods (``vfit_engine.garment.transfer.METHODS``; listed here so --help imports no numpy).
TRANSFER_METHODS = ("auto", "mhclo", "mhclo-delta", "dqs", "lbs", "none")
#: ``vfit morph`` options reused here (same names, types and help), so the two commands agree.
MORPH_OPTIONS = ("gender", "height", "weight") + _morph.GIRTH_OPTIONS + ("definition",)


def morph_options(func):
    """Add ``vfit morph``'s body options to a command (copies of its click parameters)."""
    params = {p.name: p for p in _morph.morph.params}
    for name in reversed(MORPH_OPTIONS):
        opt = copy.copy(params[name])
        if name == "gender":
            # here the default is the garment's own gender, not always female
            opt.show_default = False
            opt.help = "Body gender: female, male or a blend 0..1 [default: the garment's, from its .mhclo tags, else female]."
        func.__click_params__ = getattr(func, "__click_params__", [])
        func.__click_params__.append(opt)
    return func


@click.command()
@click.argument("garment", type=click.Path(dir_okay=False))
@click.option("--body", "body_path", default=None, type=click.Path(dir_okay=False),
              help="Body to drape on (.obj/.ply with hm08 topology, e.g. from vfit morph). Default: the "
                   "average body of the garment's gender, or one built from the measurement options.")
@morph_options
@click.option("--material", default="cotton", show_default=True,
              help="cotton, denim, silk, jersey, or a material .json file.")
@click.option("--collider", type=click.Choice(["mesh", "spheres", "bone-spheres", "ellipsoids", "hulls"]),
              default="mesh", show_default=True,
              help="mesh = the exact body surface; spheres (covering the body), bone-spheres (4 per bone, radii "
                   "from the body's sections), ellipsoids (one per body part) or hulls (convex hulls per part + "
                   "joint spheres) = shapes fitted to the body: approximate, see BENCHMARKS.md for how far each "
                   "lets cloth sink in or float.")
@click.option("--pin", default="auto", show_default=True,
              help="auto (waistbands and shoulders, attached to the body), none, or a text file of garment "
                   "vertex indices (0-based, one per line).")
@click.option("--transfer", type=click.Choice(TRANSFER_METHODS), default="auto", show_default=True,
              help="Move the garment from the body it was made on (the default body of its gender) to the "
                   "target body before draping: auto = mhclo-delta when a .mhclo is beside the garment and "
                   "the body has its helper vertices (built from measurements or the default), else dqs; "
                   "none = start where it is. On the default body every method but mhclo changes nothing.")
@click.option("--rest", type=click.Choice(["transferred", "garment"]), default="transferred", show_default=True,
              help="Rest lengths of the cloth when the garment was transferred to another body: transferred = "
                   "the garment graded to that body (MakeHuman's convention: clothes are refitted to every "
                   "body); garment = the garment as given, a fixed size that the body stretches. The report "
                   "gives the strain against the garment as given either way.")
@click.option("--units", type=click.Choice(["auto", "m", "dm", "cm", "mm"]), default="auto", show_default=True,
              help="Units of the garment file (auto: from its height; MakeHuman clothes are dm).")
@click.option("--frames", type=click.IntRange(1, 100000), default=None,
              help="Most frames to simulate (60 per simulated second) [default: 300].")
@click.option("--every", type=click.IntRange(0, 100000), default=10, show_default=True,
              help="Write frame_NNNN every K frames, frame_0000 being the start (0: none).")
@click.option("--format", "fmt", type=click.Choice(["obj", "ply"]), default="obj", show_default=True,
              help="Mesh format of the outputs.")
@click.option("-o", "--output", "outdir", default="drape_out", show_default=True,
              type=click.Path(file_okay=False), help="Output directory (created if missing).")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write the report to this path (always written to OUTDIR/report.json).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary.")
@click.pass_context
@handle_errors
def drape(ctx, garment, body_path, material, collider, pin, transfer, rest, units, frames, every, fmt, outdir, json_path,
          quiet, gender, height, weight, definition, **girths):
    """Drape GARMENT (.obj/.ply) on a body and write the result to OUTDIR.

    Writes OUTDIR/final.obj (the garment's vertex order, faces and UVs; metres,
    Y up), OUTDIR/body.obj (the body it was draped on), OUTDIR/report.json
    and, with --every K, OUTDIR/frame_NNNN.obj. Exit 3 when the cloth has not
    settled within --frames, 4 when the simulation diverged (the last good
    frame is kept).

    \b
    Examples:
      vfit drape shirt.obj
      vfit drape suit.obj --waist 75 --hips 100 --material denim -o out/
      vfit drape suit.obj --body body.obj --every 10
    """
    import os
    import sys

    from vfit_engine.errors import InputError

    morph_given = {k: v for k, v in girths.items() if v is not None}
    if height is not None:
        morph_given["height"] = height
    if body_path and (morph_given or weight is not None):
        raise InputError("give either --body or measurement options, not both")
    if not os.path.isfile(garment):
        raise InputError(f"garment file not found: {garment}")
    _prepare_outdir(outdir)
    if json_path:
        check_output_path(json_path, (".json",))
    gender_given = ctx.get_parameter_source("gender") != click.core.ParameterSource.DEFAULT

    import time

    import numpy as np

    from vfit_engine.body.model import N_BODY, BodyModel
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.io.mesh import write_mesh
    from vfit_engine.garment.transfer import transfer_garment
    from vfit_engine.sim.drape import DrapeDiverged, DrapeSettings, drape_garment, read_pin_file
    from vfit_engine.sim.materials import resolve_material
    from vfit_engine.sim.report import drape_report

    t_start = time.perf_counter()
    mat = resolve_material(material)
    g = load_garment(garment, units=units)
    for w in g.warnings:
        click.echo(f"Warning: {garment}: {w}", err=True)
    pins = pin if pin in ("auto", "none") else read_pin_file(pin, g.mesh.n_verts)

    binding = _garment_binding(g)
    tag_gender = binding.gender if binding is not None else None
    body_gender = gender if gender_given else (tag_gender or "female")
    model = BodyModel.load()
    # all 19,158 vertices: the mhclo transfers read the helpers; the drape uses the first N_BODY
    reference_full = model.default_verts(tag_gender or body_gender)
    reference = reference_full[:N_BODY]
    if body_path:
        from vfit_engine.body.bodyio import read_body

        if not os.path.isfile(body_path):
            raise InputError(f"body file not found: {body_path}")
        body, _ = read_body(body_path, model, "auto")
        body_full = body
        body_desc = {"source": body_path}
    elif morph_given or weight is not None:
        from vfit_engine.body.morph import Morpher

        targets = {k.replace("_", "-"): v / 100.0 for k, v in morph_given.items()}
        res = Morpher(model).solve(targets, gender=body_gender, definition=definition, weight_kg=weight)
        body_full = res.verts
        body = body_full[:N_BODY]
        body_desc = {"source": "morph", "gender": body_gender, "definition": definition,
                     "targets_cm": {k: round(v * 100, 4) for k, v in targets.items()}, "weight_kg": weight}
    else:
        body, body_full = reference, reference_full
        body_desc = {"source": "default", "gender": body_gender}
    body = np.ascontiguousarray(body)
    start, transfer_info = transfer_garment(g.mesh.verts, reference_full, body_full, model.body_tris, transfer,
                                            binding)
    moved = not (transfer_info["identity"] or transfer_info["method"] == "none")
    transfer_info["rest"] = rest if moved else "garment"

    settings = DrapeSettings() if frames is None else DrapeSettings(max_frames=frames)
    ext = "." + fmt
    header = [f"vfit drape: {os.path.basename(garment)} on the {body_desc['source']} body; metres, Y up"]
    written = []

    def save(name, verts):
        path = os.path.join(outdir, name + ext)
        write_mesh(path, g.mesh.with_verts(verts), header=header)
        written.append(path)

    bar = None
    if not quiet and sys.stderr.isatty():
        bar = click.progressbar(length=settings.max_frames, label="draping", file=sys.stderr)
        bar.__enter__()

    def on_frame(frame, pos, state):
        if every and frame % every == 0:
            save(f"frame_{frame:04d}", pos)
        if bar is not None:
            bar.update(1)

    if every:
        save("frame_0000", start)
    segments = bones = None
    if collider in ("ellipsoids", "hulls"):
        from vfit_engine.body.segment import segment

        seg = segment(model, body_full)
        segments = (seg.labels, seg.names)
    elif collider == "bone-spheres":
        from vfit_engine.collide.bone_spheres import skeleton_bones

        bones = skeleton_bones(model, body_full)
    context = dict(garment=garment, garment_units=g.units, garment_vertices=g.mesh.n_verts,
                   garment_gender=tag_gender, warnings=list(g.warnings), body=body_desc, material=mat.name,
                   collider=collider, transfer=transfer_info)
    try:
        result = drape_garment(g.mesh, g.pieces, body, reference, model.body_tris, material=mat, pin=pins,
                               collider=collider, settings=settings, on_frame=on_frame,
                               start_verts=start if moved else None, rest=rest, segments=segments,
                               bones=bones)
    except DrapeDiverged as exc:
        if exc.transfer and "pin_gap_mm" in exc.transfer:
            transfer_info["pin_gap_mm"] = exc.transfer["pin_gap_mm"]
        if bar is not None:
            bar.__exit__(None, None, None)
        if exc.last_good is not None:
            save(f"frame_{exc.last_good_frame:04d}", exc.last_good)
        report = drape_report(diverged=exc, outputs=written, **context)
        write_json(os.path.join(outdir, "report.json"), report)
        if json_path:
            write_json(json_path, report)
        raise
    if bar is not None:
        bar.__exit__(None, None, None)
    if "pin_gap_mm" in result.settings["transfer"]:
        transfer_info["pin_gap_mm"] = result.settings["transfer"]["pin_gap_mm"]
    result.settings["transfer"] = transfer_info
    save("final", result.pos)
    from vfit_engine.body.bodyio import write_body

    body_file = os.path.join(outdir, "body" + ext)
    write_body(body_file, model, body, header=[f"vfit drape: the body draped on ({body_desc['source']}); metres, Y up"])
    written.append(body_file)
    report = drape_report(result, outputs=written, total_time_s=time.perf_counter() - t_start, **context)
    write_json(os.path.join(outdir, "report.json"), report)
    if json_path:
        write_json(json_path, report)
    if not quiet:
        click.echo(f"vfit drape: {g.mesh.n_verts} vertices, {result.frames} frames ({result.steps} steps, "
                   f"{result.sim_time:.2f} s simulated) in {result.wall_time:.2f} s; "
                   f"{'settled' if result.converged else 'NOT settled'}")
        click.echo(f"  max penetration {report['max_penetration_mm']:.2f} mm, {report['inside_count']} vertices "
                   f"inside; strain p99 {100 * report['p99_strain']:.2f} %, max {100 * report['max_strain']:.2f} %")
        if transfer_info["rest"] == "transferred":
            click.echo(f"  against the garment as given (before grading to this body): strain p99 "
                       f"{100 * report['garment_p99_strain']:.2f} %, max {100 * report['garment_max_strain']:.2f} %")
        for o in report["tight_openings"]:
            x, y, z = (100 * c for c in o["centre_m"])
            click.echo(f"  tight: the opening of {o['vertices']} vertices at ({x:.1f}, {y:.1f}, {z:.1f}) cm is "
                       f"{o['rest_length_mm'] / 10:.1f} cm round, the body under it {o['body_tape_mm'] / 10:.1f} cm: "
                       f"it must stretch >= {100 * o['required_strain']:.1f} %")
        click.echo(f"wrote {os.path.join(outdir, 'final' + ext)}, {body_file}, {os.path.join(outdir, 'report.json')}")
    if not result.converged:
        click.echo(f"Error: the cloth did not settle within {settings.max_frames} frames "
                   f"(fastest particle {result.max_speed * 1000:.1f} mm/s)", err=True)
        sys.exit(3)


def _prepare_outdir(outdir):
    """Create OUTDIR and check it is writable, before any long computation."""
    import os

    from vfit_engine.errors import InputError

    if os.path.exists(outdir) and not os.path.isdir(outdir):
        raise InputError(f"cannot write to {outdir}: not a directory")
    try:
        os.makedirs(outdir, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create output directory {outdir}: {exc.strerror or exc}") from None
    if not os.access(outdir, os.W_OK | os.X_OK):
        raise InputError(f"cannot write to {outdir}: permission denied")


def _garment_binding(g):
    """The garment's parsed .mhclo (for its gender tags and the mhclo transfers), else None."""
    if g.mhclo_path is None:
        return None
    from vfit_engine.errors import InputError
    from vfit_engine.garment.mhclo import parse_mhclo

    try:
        return parse_mhclo(g.mhclo_path)
    except (InputError, OSError, ValueError):
        return None
