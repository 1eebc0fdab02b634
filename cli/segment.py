"""``vfit segment``: colour a body by part (head, torso, arms, hands, legs, feet ...)."""
import click

from ._common import FILE_UNITS, Quantity, check_output_path, fmt_table, handle_errors, write_json
from ._outdir import check_outputs

#: One colour per part of ``vfit_engine.body.segment.PARTS`` (left/right in related shades).
PALETTE = (
    (230, 200, 160), (200, 120, 80), (60, 120, 200), (90, 170, 220), (150, 90, 180),
    (220, 60, 60), (160, 30, 30), (240, 150, 40), (180, 100, 20), (250, 230, 60), (190, 170, 20),
    (60, 180, 80), (30, 120, 50), (100, 220, 200), (40, 150, 140), (240, 110, 170), (170, 60, 120),
)


@click.command()
@click.argument("body", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default="parts.ply", show_default=True, type=click.Path(dir_okay=False),
              help="Coloured body to write: .ply (binary, per-vertex colours); metres, Y up.")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write per-part vertex counts, skin-weight agreement, voxel size and timings.")
@click.option("--units", type=FILE_UNITS, default="auto", show_default=True,
              help="Length unit of BODY (auto: guessed from its height).")
@click.option("--voxel", type=Quantity("mm", 1, 50), default=5.0, show_default=True,
              help="Voxel size of the region growing, mm.")
@click.option("-q", "--quiet", is_flag=True, help="Print only where the result was written.")
@handle_errors
def segment(body, output, json_path, units, voxel, quiet):
    """Segment a body with hm08 topology into 17 parts by region growing from its bones.

    The body is voxelised, seeded along the rig's bones and all parts grow at
    once through the solid; each vertex takes its nearest voxel's part. The
    agreement printed is the share of vertices whose part is also the part with
    the largest skin weight there.

    \b
    Example:
      vfit segment body.obj -o parts.ply --json parts.json
    """
    import os
    import time

    t0 = time.perf_counter()
    check_output_path(output, (".ply",))
    if json_path:
        check_output_path(json_path, (".json",))
    from vfit_engine.errors import InputError

    if not os.path.isfile(body):
        raise InputError(f"{body}: no such file")
    check_outputs(None, (), {"BODY": body}, extra_outputs=[output, json_path])

    import numpy as np

    from vfit_engine.body.bodyio import body_mesh, read_body
    from vfit_engine.body.model import N_BODY, BodyModel
    from vfit_engine.body.segment import segment as run_segment
    from vfit_engine.io.mesh import write_mesh

    model = BodyModel.load()
    verts, units_used = read_body(body, model, units)
    t_read = time.perf_counter() - t0
    seg = run_segment(model, verts, voxel=voxel / 1000.0)
    mesh = body_mesh(model, verts)
    mesh.colors = np.asarray(PALETTE, dtype=np.uint8)[seg.labels]
    write_mesh(output, mesh, header=[f"vfit segment: {body}, parts: " + " ".join(seg.names)])
    elapsed = time.perf_counter() - t0

    if not quiet:
        rows = [[name, seg.counts[name], "#%02x%02x%02x" % PALETTE[i]] for i, name in enumerate(seg.names)]
        click.echo(fmt_table(rows, ["part", "vertices", "colour"]))
        fs = seg.fill_stats
        click.echo(f"agreement with skin weights: {seg.agreement * 100:.1f} % of vertices")
        click.echo(f"voxels: {voxel:g} mm, grid {'x'.join(map(str, seg.grid_shape))}, {seg.solid_count} solid; "
                   f"span fill {fs['span']['pushes']} pushes vs {fs['stack']['pushes']} (plain)")
    click.echo(f"wrote {output} ({N_BODY:,} body vertices coloured by part) in {elapsed:.2f} s")
    if json_path:
        write_json(json_path, {
            "command": "segment",
            "body": body,
            "units_read": units_used,
            "voxel_mm": voxel,
            "parts": seg.names,
            "counts": seg.counts,
            "colors": {name: list(PALETTE[i]) for i, name in enumerate(seg.names)},
            "agreement_pct": round(seg.agreement * 100, 3),
            "grid_shape": list(seg.grid_shape),
            "solid_voxels": seg.solid_count,
            "fill_stats": seg.fill_stats,
            "timings_s": dict(seg.timings, read_s=round(t_read, 4), total_s=round(elapsed, 4)),
            "output": output,
        })
        if not quiet:
            click.echo(f"wrote {json_path}")
