"""``vfit pose``: a body (a file, the default one, or one built to measurements) in a BVH pose."""
import click

from ._common import check_output_path, handle_errors, write_json
from .drape import body_targets, morph_options

#: Skinning methods (``vfit_engine.body.skinning``; listed here so --help imports no numpy).
SKINNING = ("dqs", "lbs")


@click.command()
@click.option("--body", "body_path", default=None, type=click.Path(dir_okay=False),
              help="Body to pose (.obj/.ply with hm08 topology, e.g. from vfit morph). Default: the average body "
                   "of --gender, or one built from the measurement options.")
@morph_options(garment=False)
@click.option("--pose", "pose_path", required=True, type=click.Path(dir_okay=False),
              help="A BVH file with the default rig's joint names (MakeHuman's poses; Z-up or Y-up files).")
@click.option("--frame", type=click.IntRange(0, None), default=0, show_default=True, help="Frame of the BVH to take.")
@click.option("--skinning", type=click.Choice(SKINNING), default="dqs", show_default=True,
              help="dqs = dual-quaternion skinning (keeps volume at twisted joints), lbs = linear blend skinning.")
@click.option("-o", "--output", default="posed.obj", show_default=True, type=click.Path(dir_okay=False),
              help="Posed body to write: .obj (with UVs) or .ply; metres, Y up, hm08 vertex order.")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write the joints' positions (posed, m) and what was done as JSON.")
@click.option("-q", "--quiet", is_flag=True, help="Print only where the body was written.")
@click.pass_context
@handle_errors
def pose(ctx, body_path, pose_path, frame, skinning, output, json_path, quiet, gender, height, weight, definition,
         **girths):
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
    """
    import os
    import time

    from vfit_engine.errors import InputError

    t0 = time.perf_counter()
    targets = body_targets(body_path, girths, height, weight)
    check_output_path(output, (".obj", ".ply"))
    if json_path:
        check_output_path(json_path, (".json",))
    if not os.path.isfile(pose_path):
        raise InputError(f"pose file not found: {pose_path}")

    from vfit_engine.body.bodyio import write_body
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.pose import pose_body
    from vfit_engine.body.resolve import resolve_body
    from vfit_engine.io.bvh import read_bvh

    motion = read_bvh(pose_path)
    if frame >= len(motion.frames):
        raise InputError(f"{pose_path}: frame {frame} asked for, the file has {len(motion.frames)} "
                         f"(use --frame 0..{len(motion.frames) - 1})")
    model = BodyModel.load()
    body = resolve_body(model, body_path, targets, weight, gender, definition)
    posed = pose_body(model, body.verts, motion, frame, method=skinning)
    write_body(output, model, posed.verts,
               header=[f"vfit pose: {os.path.basename(pose_path)} frame {frame}, {skinning}; metres, Y up"])
    elapsed = time.perf_counter() - t0
    if not quiet:
        click.echo(f"vfit pose: {os.path.basename(pose_path)} frame {frame} on the {body.description.get('source')} "
                   f"body: {posed.named} of the rig's {len(model.bone_names)} bones posed from the file, "
                   f"{skinning} skinning")
    click.echo(f"wrote {output} (13,380 body vertices, metres, Y up) in {elapsed:.2f} s")
    if json_path:
        write_json(json_path, dict(command="pose", pose=os.path.abspath(pose_path), frame=frame, skinning=skinning,
                                   body=body.description, units=dict(mesh="m", joints="m"),
                                   bones_posed=posed.named, joints={n: [round(float(c), 5) for c in p]
                                                                    for n, p in zip(model.bone_names, posed.heads)},
                                   output=output, time_s=round(elapsed, 3)))
        if not quiet:
            click.echo(f"wrote {json_path}")
