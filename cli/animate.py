"""``vfit animate``: a garment on a body in motion (the built-in walk or a BVH file), frame by frame."""
from types import SimpleNamespace

import click

from ._common import FILE_UNITS, EngineChoice, check_output_path, handle_errors, interruption, write_json
from ._outdir import OutdirLock, check_outdir, check_outputs, clear_outputs, wrote_line
from ._progress import Progress
from .drape import body_targets, morph_options, pattern_only, pattern_options, pattern_setup, user_files

#: Files an animation writes into OUT (removed before a new run writes there).
#: Exit code when frames have the skin through the cloth (the simulation's fault: quality["simulation_frames"]).
SIMULATION_FAULT = 5
OUTPUT_GLOBS = ("frame_*.obj", "body_*.obj", "animation.glb", "preview.gif", "report.json")


@click.command()
@click.argument("garment", type=click.Path(dir_okay=False))
@pattern_options
@click.option("--body", "body_path", default=None, type=click.Path(dir_okay=False),
              help="Body to animate (.obj/.ply with hm08 topology). Default: the average body of the garment's "
                   "gender, or one built from the measurement options.")
@morph_options
@click.option("--motion", default="walk", show_default=True,
              help="walk (one stride of normative gait, looping) or a BVH file: the default rig's bone names "
                   "(MakeHuman's poses), CMU's skeleton, or any with --joint-map.")
@click.option("--speed", type=click.FloatRange(0.3, 2.5), default=1.3, show_default=True,
              help="Walking speed, m/s (--motion walk): the stride's time through cadence.")
@click.option("--joint-map", "joint_map", default=None, type=click.Path(dir_okay=False),
              help="JSON {\"file joint\": \"rig bone\"} for a BVH file in other joint names (README: CMU's).")
@click.option("--travel", is_flag=True, help="Move the body along the motion's root path (the walk goes forward "
                                             "at --speed); default: in place, the root's translation removed.")
@click.option("--frames", type=click.IntRange(1, 100000), default=60, show_default=True,
              help="Animation frames to simulate after the rest drape.")
@click.option("--fps", type=click.FloatRange(1.0, 240.0), default=30.0, show_default=True,
              help="Animation frames per second.")
@click.option("--every", type=click.IntRange(0, 100000), default=10, show_default=True,
              help="Write frame_NNNN.obj (garment) and body_NNNN.obj every K frames, 0 the rest drape (0: none).")
@click.option("--blend", type=click.FloatRange(0.0, 10.0), default=0.5, show_default=True,
              help="Seconds over which the motion is blended in from the A pose the garment is draped in.")
@click.option("--collider", type=EngineChoice("vfit_engine.animate.loop:COLLIDERS"), default="mesh", show_default=True,
              help="mesh = the exact body surface near the garment, moving every substep; bone-spheres = spheres "
                   "along the bones, spheres = the medial sphere cover, both following the bones (faster, "
                   "approximate).")
@click.option("--skinning", type=EngineChoice("vfit_engine.body.skinning:METHODS"), default="dqs", show_default=True,
              help="How the body follows its bones: dual quaternions or linear blend.")
@click.option("--material", default="cotton", show_default=True,
              help="silk, cotton, wool, denim, jersey, or a material .json file.")
@click.option("--pin", default="auto", show_default=True,
              help="auto (waistbands and shoulders, attached to the body; they move with it), none, or a file of "
                   "garment vertex indices.")
@click.option("--units", type=FILE_UNITS, default="auto", show_default=True,
              help="Units of the garment file (auto: from its height; MakeHuman clothes are dm).")
@click.option("--preview", is_flag=True, help="Also write OUT/preview.gif: the garment, coloured by yarn strain, "
                                              "on the moving body from the front and the side.")
@click.option("-o", "--output", "outdir", default="animate_out", show_default=True, type=click.Path(file_okay=False),
              help="Output directory (created if missing).")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write the report to this path (always written to OUT/report.json).")
@click.option("-q", "--quiet", is_flag=True, help="No progress and no summary.")
@click.pass_context
@handle_errors
def animate(ctx, garment, body_path, motion, speed, joint_map, travel, frames, fps, every, blend, collider, skinning,
            material, pin, units, preview, outdir, json_path, quiet, gender, height, weight, definition, seams, spacing,
            arrange, **girths):
    """Drape GARMENT at rest, then simulate it on the body in motion.

    GARMENT is a garment mesh (.obj/.ply) or a sewing pattern (GarmentCode
    .json, DXF-AAMA .dxf with --seams): a pattern is sewn round the still body
    as vfit drape sews it, then moves with it on the same solver.

    The garment is draped on the still body first (as vfit drape does), the
    motion is blended in from the A pose over --blend seconds, and the cloth
    follows the body: the exact body surface moves at every substep and the
    pins move with the body. Writes OUT/frame_NNNN.obj and OUT/body_NNNN.obj
    every --every frames (metres, Y up), OUT/animation.glb (body and garment
    animated, for Blender or three.js), OUT/report.json (every frame's skin
    through the cloth, yarn strain and pressure, and the time per frame) and,
    with --preview, OUT/preview.gif. Exit 4 if the simulation diverged, 5 if
    frames have the skin through the cloth (the simulation's fault, not the
    garment's; a garment too tight for the motion is an answer: exit 0).

    \b
    Examples:
      vfit animate suit.obj --gender male --motion walk --frames 60 --every 20 -o walk/
      vfit animate skirt.obj --motion sit01.bvh --frames 90 --blend 1.5 -o sit/
      vfit animate suit.obj --motion capture.bvh --joint-map cmu.json --travel --preview
      vfit animate shirt.json --motion walk --frames 30 -o shirt_walk/
    """
    import os
    import time

    from vfit_engine.errors import InputError

    t_start = time.perf_counter()
    targets = body_targets(body_path, girths, height, weight)
    if not os.path.isfile(garment):
        raise InputError(f"garment file not found: {garment}")
    if motion != "walk" and not os.path.isfile(motion):
        raise InputError(f"motion file not found: {motion} (or use --motion walk)")
    if joint_map is not None and not os.path.isfile(joint_map):
        raise InputError(f"joint map not found: {joint_map}")
    check_outdir(outdir)
    if json_path:
        check_output_path(json_path, (".json",), outdir=outdir)
    inputs = dict(user_files(garment, body_path, pin, material), **{"--motion": None if motion == "walk" else motion,
                                                                    "--joint-map": joint_map})
    check_outputs(outdir, OUTPUT_GLOBS, dict(inputs, **{"--seams": seams}), extra_outputs=[json_path])
    pattern_only(ctx, garment, seams=seams, spacing=spacing, arrange=arrange)
    gender_given = ctx.get_parameter_source("gender") != click.core.ParameterSource.DEFAULT
    o = SimpleNamespace(garment=garment, seams=seams, spacing=spacing, arrange=arrange, body_path=body_path,
                        motion=motion, speed=speed, joint_map=joint_map,
                        travel=travel, frames=frames, fps=fps, every=every, blend=blend, collider=collider,
                        skinning=skinning, material=material, pin=pin, units=units, preview=preview, outdir=outdir,
                        json_path=json_path, quiet=quiet, gender=gender if gender_given else None, weight=weight,
                        definition=definition, targets=targets, t_start=t_start)
    o.progress = Progress(quiet, command="vfit animate")
    try:
        with OutdirLock(outdir), o.progress.compiling():  # a first run's compiles, shown where they happen
            code = _animate(o)
    except KeyboardInterrupt as exc:
        name, code = interruption(exc)
        click.echo(f"Error: interrupted by {name}", err=True)
    if code:
        ctx.exit(code)


def _animate(o):
    """The work inside the held OUT; returns the exit code."""
    import os
    import time

    import numpy as np

    from vfit_engine.animate.loop import AnimateSettings, animate_garment
    from vfit_engine.animate.motion import load_clip
    from vfit_engine.animate.outputs import FRAME_KEYS, animation_report
    from vfit_engine.drape import DrapeDiverged
    from vfit_engine.body.bodyio import write_body
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import resolve_body
    from vfit_engine.drape import DrapeSettings, prepare_drape
    from vfit_engine.drape.settings import projective
    from vfit_engine.drape.setup import garment_gender
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.garment.pins import read_pin_file
    from vfit_engine.io.mesh import write_mesh
    from vfit_engine.pattern.load import is_pattern

    progress = o.progress
    progress.stage(f"reading {os.path.basename(o.garment)} and the motion")
    model = BodyModel.load()
    settings = AnimateSettings(fps=o.fps, frames=o.frames, blend_s=o.blend, skinning=o.skinning, collider=o.collider)
    clip = load_clip(model, o.motion, speed=o.speed, fps=o.fps, travel=o.travel, joint_map=o.joint_map,
                     until=o.frames / o.fps)  # the last frame's time (animate.loop.pose_frames)
    if is_pattern(o.garment):  # sewn and animated on the projective solver (sewing needs it: drape.sew)
        dst = projective(DrapeSettings())
        setup, context = pattern_setup(o, model, dst)
        g, body_description = setup.garment, context["body"]
        context = dict(pattern=context["pattern"])
    else:
        g = load_garment(o.garment, units=o.units)
        for w in g.warnings:  # as vfit drape says them: a unit that makes the garment absurd, an ignored binding
            click.echo(f"Warning: {o.garment}: {w}", err=True)
        pins = o.pin if o.pin in ("auto", "none") else read_pin_file(o.pin, g.mesh.n_verts)
        tag_gender = garment_gender(g)
        progress.stage("building the body to the measurements" if o.targets or o.weight is not None else
                       f"reading the body {o.body_path}" if o.body_path else "loading the default body")
        body = resolve_body(model, o.body_path, o.targets, o.weight, o.gender or tag_gender or "female",
                            o.definition)
        dst = DrapeSettings()
        progress.stage("placing and pinning the garment")
        setup = prepare_drape(g, body, model, material=o.material, pin=pins, settings=dst)
        body_description, context = body.description, {}
    clear_outputs(o.outdir, OUTPUT_GLOBS)
    progress.stage("draping at rest (it ends when the cloth settles)")
    written, bodies, cloth = [], [], []
    header = [f"vfit animate: {os.path.basename(o.garment)}, {os.path.basename(o.motion)}; metres, Y up"]

    def save(k, body_verts, pos, force=False):
        if force or (o.every and k % o.every == 0):
            for name, mesh in ((f"frame_{k:04d}.obj", g.mesh.with_verts(pos)), (f"body_{k:04d}.obj", None)):
                path = os.path.join(o.outdir, name)
                if mesh is None:
                    write_body(path, model, body_verts, header=header)
                else:
                    write_mesh(path, mesh, header=header)
                written.append(path)

    def on_drape_frame(frame, pos, moving):
        progress.frame(frame, moving, dst.max_frames)

    def on_frame(k, body_verts, pos, fig, travel):
        if k == 0:
            progress.done()
            progress.stage(f"animating {o.frames} frames")
        bodies.append(body_verts + travel)
        cloth.append(pos + travel)
        save(k, bodies[-1], cloth[-1])
        progress.line(f"frame {k} of {o.frames}: skin through the cloth {fig['surface_max_depth_mm']:.1f} mm deep, "
                      f"strain p99 {100 * fig['p99_strain']:.1f} %", k)

    try:
        drape, anim = animate_garment(setup, clip, model, settings, dst, on_drape_frame=on_drape_frame,
                                      on_frame=on_frame)
    except DrapeDiverged as exc:  # keep the last good frame and say what the frames so far measured
        progress.done()
        if getattr(exc, "figures", None) is not None and cloth:
            save(exc.last_good_frame, bodies[-1], cloth[-1], force=True)
            write_json(os.path.join(o.outdir, "report.json"),
                       dict(command="animate", garment=o.garment, diverged=dict(frame=exc.frame, message=str(exc)),
                            frame_figures=[dict(frame=k, **{key: f[key] for key in FRAME_KEYS})
                                           for k, f in enumerate(exc.figures)], outputs=written))
        raise
    progress.done()
    progress.stage("writing animation.glb" + (" and preview.gif" if o.preview else ""))
    written += _write_animation(o, setup, model, np.stack(bodies), np.stack(cloth))
    context = dict(garment=o.garment, garment_vertices=g.mesh.n_verts, body=body_description, material=o.material,
                   travel=o.travel, outputs=written, total_time_s=round(time.perf_counter() - o.t_start, 3), **context)
    report = animation_report(drape, anim, settings, limit=setup.material.wearable_stretch, **context)
    write_json(os.path.join(o.outdir, "report.json"), report)
    if o.json_path:
        write_json(o.json_path, report)
    if not o.quiet:
        _summary(report)
        click.echo(wrote_line(o.outdir, written + [os.path.join(o.outdir, "report.json")]))
    if report["quality"]["simulation_frames"]:
        click.echo(f"Error: {report['quality']['simulation_frames']} frame(s) with the skin through the cloth: the "
                   "simulation's fault, not the garment's (report.json: quality)", err=True)
        return SIMULATION_FAULT
    return 0


def _write_animation(o, setup, model, bodies, cloth):
    """``animation.glb`` and, asked for, ``preview.gif``; returns their paths."""
    import os

    from vfit_engine.animate.outputs import write_animation, write_preview_gif

    paths = [os.path.join(o.outdir, "animation.glb")]
    write_animation(paths[0], setup, model, bodies, cloth, o.fps)
    if o.preview:
        paths.append(os.path.join(o.outdir, "preview.gif"))
        write_preview_gif(paths[1], setup, model, bodies, cloth, o.fps)
    return paths


def _summary(report):
    ms, q, mx = report["ms_per_frame"], report["quality"], report["maxima"]
    click.echo(f"vfit animate: {report['frames']} frames ({report['duration_s']:.2f} s) of "
               f"{report['motion'].get('motion') if isinstance(report['motion'].get('motion'), str) else 'motion'}; "
               f"{ms['simulation']:.0f} ms per frame (posing {ms['posing']:.0f}, collision {ms['collision']:.0f}, "
               f"cloth {ms['cloth']:.0f}; collision {100 * report['collision_share']:.0f} %)")
    click.echo(f"  worst frame: skin through the cloth {mx['surface_max_depth_mm']:.2f} mm deep, "
               f"{mx['surface_inside_percent']:.2f} % of the surface inside; yarn strain p99 "
               f"{100 * mx['p99_strain']:.1f} %, max {100 * mx['max_strain']:.1f} %; pressure up to "
               f"{mx['pressure_max_kpa']:.1f} kPa")
    if q["passed"]:
        click.echo("  every frame meets the quality bars (<= 2 mm deep, <= 1 % inside, strain p99 <= 8 %)")
    else:
        click.echo(f"  {len(q['failed_frames'])} frame(s) miss the quality bars: {q['verdict']}")
    if report.get("settled") is not None:
        click.echo(f"  {'settled' if report['settled'] else 'NOT settled'} in the final pose")
