"""``vfit measure``: measure a body mesh with hm08 topology."""
import click

from ._common import FILE_UNITS, EngineChoice, Gender, check_output_path, fmt_table, handle_errors, write_json
from ._outdir import check_outputs
from ._progress import Progress


@click.command()
@click.argument("body", type=click.Path(dir_okay=False))
@click.option("--definition", type=EngineChoice("vfit_engine.body.measure:DEFINITIONS"), default="iso",
              show_default=True,
              help="iso = horizontal tape girths (convex hull of the torso section), makehuman = MakeHuman's "
                   "20 rulers, spline = profile curve through the section.")
@click.option("--units", type=FILE_UNITS, default="auto", show_default=True,
              help="Units of the file (auto: from the body's height; MakeHuman exports are dm, vfit writes m).")
@click.option("--gender", type=Gender(), default=None,
              help="The body's gender (female, male or a blend 0..1): a man's bust is his chest girth, taken under "
                   "the armpits (ISO 8559-1 / EN 13402-1). Not given: the bust, across the bust points.")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write the figures as JSON.")
@handle_errors
def measure(body, definition, units, gender, json_path):
    """Measure BODY (.obj or .ply with hm08 body topology: vfit's output or a MakeHuman export).

    Prints every measurement in cm, the plane height of each tape girth, and the
    body mass from its volume.

    \b
    Example:
      vfit measure body.obj --definition makehuman
      vfit measure man.obj --gender male
    """
    import os

    from vfit_engine.errors import InputError

    if not os.path.isfile(body):
        raise InputError(f"{body}: no such file")
    if json_path:
        check_output_path(json_path, (".json",))
    check_outputs(None, (), {"BODY": body}, extra_outputs=[json_path])
    from vfit_engine.body.bodyio import read_body
    from vfit_engine.body.measure import DENSITY, Measurer
    from vfit_engine.body.model import BodyModel

    model = BodyModel.load()
    verts, used_units = read_body(body, model, units)
    with Progress(True, command="vfit measure").compiling():  # only a first run's compiles
        meas = Measurer(model).measure(verts, definition, gender=gender)
    values = meas.cm()
    ground = float(verts[:, 1].min())
    rows = [[f"{k} (cm)", f"{v:.2f}",
             f"{(meas.planes[k] - ground) * 100:.1f}" if k in meas.planes else ""] for k, v in values.items()]
    rows.append(["mass (kg)", f"{meas.mass_kg:.2f}", ""])
    click.echo(f"vfit measure: {body} (read as {used_units}), definition '{definition}'")
    click.echo(fmt_table(rows, ["measurement", "value", "plane above sole (cm)"]))
    if json_path:
        write_json(json_path, {
            "command": "measure", "file": body, "file_units": used_units, "definition": definition, "gender": gender,
            "units": {"length": "cm", "mass": "kg"}, "density_kg_m3": DENSITY,
            "values": values, "mass_kg": round(meas.mass_kg, 3),
            "planes_above_sole_cm": {k: round((y - ground) * 100, 2) for k, y in meas.planes.items()},
        })
        click.echo(f"wrote {json_path}")
