"""``vfit pose``: a body (a file, the default one, or one built to measurements) in a BVH pose."""
import click

from ._common import EngineChoice, check_output_path, handle_errors, write_json
from ._outdir import check_outputs
from .drape import body_targets, morph_options


@click.command()
@click.option("--body", "body_path", default=None, type=click.Path(dir_okay=False),
              help="Body to pose (.obj/.ply with hm08 topology, e.g. from vfit morph). Default: the average body "
                   "of --gender, or one built from the measurement options.")
@morph_options(garment=False)
@click.option("--pose", "pose_path", required=True, type=click.Path(dir_okay=False),
              help="A BVH file with the default rig's joint names (MakeHuman's poses; Z-up or Y-up files), or "
                   "'walk': one stride of a walk from normative gait kinematics (Winter 2009; Perry 2010).")
@click.option("--frame", type=click.IntRange(0, None), default=0, show_default=True,
              help="Frame of the motion to take (a walk: 0 = the right heel's contact, 30 frames per second).")
@click.option("--speed", type=click.FloatRange(0.3, 2.5), default=1.3, show_default=True,
              help="Walking speed, m/s (--pose walk): sets the stride's time through cadence.")
@click.option("--gif", "gif_path", default=None, type=click.Path(dir_okay=False),
              help="Also write every frame of the motion as an animated GIF (the body from the side).")
@click.option("--skinning", type=EngineChoice("vfit_engine.body.skinning:METHODS"), default="dqs", show_default=True,
              help="dqs = dual-quaternion skinning (keeps volume at twisted joints), lbs = linear blend skinning.")
@click.option("-o", "--output", default="posed.obj", show_default=True, type=click.Path(dir_okay=False),
              help="Posed body to write: .obj (with UVs) or .ply; metres, Y up, hm08 vertex order.")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write the joints' positions (posed, m) and what was done as JSON.")
@click.option("-q", "--quiet", is_flag=True, help="Print only where the body was written.")
@click.pass_context
@handle_errors
def pose(ctx, body_path, pose_path, frame, speed, gif_path, skinning, output, json_path, quiet, gender, height, weight,
         definition, **girths):
    """Pose a body with a BVH pose of the default rig and write it.

    The joints are placed on this body (as MakeHuman places them), so a pose
    fits any body vfit builds; only the pose's rotations are taken from the
    file, the bone lengths are the body's. The body is posed in place (its
    root stays where it was).

    \b
    Examples:
      vfit pose --pose sit01.bvh -o sitting.obj
      vfit pose --gender male --height 185 --pose run01.bvh --skinning lbs -o run.obj
      vfit pose --body customer.obj --pose standing02.bvh -o standing.obj
      vfit pose --pose walk --speed 1.4 --frame 10 -o step.obj --gif walk.gif
    """
    import os
    import time

    from vfit_engine.errors import InputError

    t0 = time.perf_counter()
    targets = body_targets(body_path, girths, height, weight)
    check_output_path(output, (".obj", ".ply"))
    if json_path:
        check_output_path(json_path, (".json",))
    if gif_path:
        check_output_path(gif_path, (".gif",))
    walk = pose_path == "walk"
    if not walk and not os.path.isfile(pose_path):
        raise InputError(f"pose file not found: {pose_path} (or use --pose walk)")
    check_outputs(None, (), {"--body": body_path, "--pose": None if walk else pose_path},
                  extra_outputs=[output, json_path, gif_path])

    from vfit_engine.body.bodyio import write_body
    from vfit_engine.body.gait import walk_motion
    from vfit_engine.body.model import N_BODY, BodyModel
    from vfit_engine.body.pose import joint_naming, pose_body, skinning_for
    from vfit_engine.body.resolve import resolve_body
    from vfit_engine.body.self_contact import lift_hands
    from vfit_engine.io.bvh import read_bvh

    model = BodyModel.load()
    one = not (walk or gif_path)  # one frame of the file is all the body needs: a long file is not held whole
    motion = walk_motion(model, speed=speed) if walk else read_bvh(pose_path, frame=frame if one else None)
    if not one and frame >= len(motion.frames):
        raise InputError(f"{pose_path}: frame {frame} asked for, the {'walk' if walk else 'file'} has "
                         f"{len(motion.frames)} (use --frame 0..{len(motion.frames) - 1})")
    if not walk:  # vfit animate's check: a file in other names would leave the body unposed
        joint_naming(model, motion, pose_path, fix="use a pose in the rig's bone names (MakeHuman's poses), or "
                                                   "vfit animate --motion FILE --joint-map MAP.json for another "
                                                   "skeleton")
    body = resolve_body(model, body_path, targets, weight, gender, definition)
    skin = skinning_for(model, len(body.verts))
    posed = pose_body(model, body.verts, motion, 0 if one else frame, method=skinning, skinning=skin)
    write_body(output, model, lift_hands(model, body.verts)(posed.verts),
               header=[f"vfit pose: {os.path.basename(pose_path)} frame {frame}, {skinning}; metres, Y up"])
    if gif_path:
        _gif(gif_path, model, body.verts, motion, skinning, skin)
    elapsed = time.perf_counter() - t0
    if not quiet:
        click.echo(f"vfit pose: {os.path.basename(pose_path)} frame {frame} on the {body.description.get('source')} "
                   f"body: {posed.named} of the rig's {len(model.bone_names)} bones posed from the file, "
                   f"{skinning} skinning")
    click.echo(f"wrote {output} ({N_BODY:,} body vertices, metres, Y up){' and ' + gif_path if gif_path else ''} in "
               f"{elapsed:.2f} s")
    if json_path:
        write_json(json_path, dict(command="pose", pose=os.path.abspath(pose_path), frame=frame, skinning=skinning,
                                   body=body.description, units=dict(mesh="m", joints="m"),
                                   bones_posed=posed.named, joints={n: [round(float(c), 5) for c in p]
                                                                    for n, p in zip(model.bone_names, posed.heads)},
                                   output=output, time_s=round(elapsed, 3)))
        if not quiet:
            click.echo(f"wrote {json_path}")


def _gif(path, model, verts, motion, method, skin):
    """Every frame of ``motion`` (at most the GIF's limit, evenly spread) on the body, from the side."""
    import numpy as np

    from vfit_engine.animation import MAX_FRAMES, write_gif
    from vfit_engine.body.model import N_BODY
    from vfit_engine.body.pose import body_joints, pose_body
    from vfit_engine.body.self_contact import lift_hands

    pick = np.unique(np.linspace(0, len(motion.frames) - 1, min(len(motion.frames), MAX_FRAMES)).round().astype(int))
    joints = body_joints(model, verts)  # the body's joints, the same in every frame
    lift = lift_hands(model, verts)
    frames = [lift(pose_body(model, verts, motion, int(k), method=method, skinning=skin, joints=joints).verts)[:N_BODY]
              for k in pick]
    write_gif(path, None, None, frames, model.body_tris, fps=min(1.0 / motion.frame_time, 50.0), view="side")
