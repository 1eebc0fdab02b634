"""``vfit morph``: build a body to a customer's measurements."""
import click

from ._common import (EngineChoice, Gender, Quantity, check_output_path, fmt_table, handle_errors, seconds_since_start,
                      write_json)
from ._progress import Progress

#: seconds after the program starts by which a failure's searches for the ranges reachable end (a search still
#: running is cut): with cutting it, writing the error, ending the process (~0.2 s) and Python's own start
#: (~0.1 s), a failure answers within ~3 s
FAILURE_SECONDS = 2.6

#: option name -> measurement name (all in cm on the command line)
GIRTH_OPTIONS = ("bust", "underbust", "waist", "hips", "neck", "upper_arm", "thigh", "calf")


#: other names of an option: a man's chest is the girth a woman's bust is (one measurement, one target)
ALIASES = {"bust": ("--chest",)}


def girth_option(name, help_text):
    return click.option(f"--{name.replace('_', '-')}", *ALIASES.get(name, ()), name, type=Quantity("cm", 1, 400),
                        default=None, help=help_text)


@click.command()
@click.option("--gender", type=Gender(), default="female", show_default=True,
              help="female, male, or a blend 0..1 (0 female, 1 male).")
@click.option("--height", type=Quantity("cm", 50, 300), default=None, help="Stature (top of head to sole), cm.")
@click.option("--weight", type=Quantity("kg", 10, 500), default=None,
              help="Body mass, kg (met through body volume x 985 kg/m^3).")
@girth_option("bust", "Bust girth, cm (a man's: his chest girth, under the armpits; --chest is the same option).")
@girth_option("underbust", "Underbust girth, cm.")
@girth_option("waist", "Waist girth, cm.")
@girth_option("hips", "Hip girth, cm.")
@girth_option("neck", "Neck girth, cm (MakeHuman ruler).")
@girth_option("upper_arm", "Upper arm girth, cm (MakeHuman ruler).")
@girth_option("thigh", "Thigh girth, cm (MakeHuman ruler).")
@girth_option("calf", "Calf girth, cm (MakeHuman ruler).")
@click.option("--definition", type=EngineChoice("vfit_engine.body.measure:DEFINITIONS"), default="iso",
              show_default=True,
              help="How girths are measured: iso = horizontal tape (convex hull of the torso section), "
                   "makehuman = MakeHuman's rulers, spline = profile curve through the section.")
@click.option("--search-time", "search_time", type=click.FloatRange(0.0, 600.0), default=None,
              help="Seconds after the solve starts by which targets that cannot be met have had the ranges "
                   "reachable with the others searched [default: until 2.6 s after vfit started, so that a failure "
                   "answers within ~3 s]; a range cut short says so: give more to get it.")
@click.option("-o", "--output", default="body.obj", show_default=True, type=click.Path(dir_okay=False),
              help="Body mesh to write: .obj (with UVs) or .ply; metres, Y up, hm08 vertex order.")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write the figures as JSON.")
@click.option("-q", "--quiet", is_flag=True, help="Print only where the body was written.")
@handle_errors
def morph(gender, height, weight, definition, search_time, output, json_path, quiet, **girths):
    """Build a body with exactly the given measurements (each met to 1 mm).

    Starts from MakeHuman's young-adult average body of the chosen gender and
    solves all targets at once. Girths and mass you do not give follow the
    population (ANSUR II regressions on what you give; marked "(estimated)",
    with the regression's standard error); a height you do not give stays
    the average body's. Values outside the population's 1st-99th percentile
    build with a warning; values no adult body has are refused. Lengths in
    cm, mass in kg.

    \b
    Examples:
      vfit morph --waist 72 --bust 90 --hips 98 --height 168 -o body.obj
      vfit morph --height 165 --weight 90      (typical bust, waist, hips shown)
    """
    import time

    t0 = time.perf_counter()
    check_output_path(output, (".obj", ".ply"))
    if json_path:
        check_output_path(json_path, (".json",))
    targets = {k.replace("_", "-"): v / 100.0 for k, v in girths.items() if v is not None}
    if height is not None:
        targets["height"] = height / 100.0

    from vfit_engine.body.bodyio import write_body
    from vfit_engine.body.measure import NAMES
    from vfit_engine.body.model import N_BODY
    from vfit_engine.body.morph import Morpher

    with Progress(True, command="vfit morph").compiling():  # only a first run's compiles (the table says the rest)
        morpher = Morpher()
        if search_time is None:  # the searches end FAILURE_SECONDS after the program started, however long it took
            search_time = max(0.0, FAILURE_SECONDS - seconds_since_start(t0))
        res = morpher.solve(targets, gender=gender, definition=definition, weight_kg=weight,
                            search_seconds=search_time)
    gender_text = gender if isinstance(gender, str) else f"{gender:g} (0 female, 1 male)"
    header = [f"vfit morph: {gender_text} body, definition {definition}, units metres, Y up",
              "targets (cm/kg): " + ", ".join(f"{k}={v * 100:g}" for k, v in targets.items())
              + (f", weight={weight:g}" if weight else "")]
    write_body(output, morpher.model, res.verts, header=header)
    elapsed = time.perf_counter() - t0

    achieved = res.measurement.cm()
    start = res.start.cm()
    male = gender == "male" or (not isinstance(gender, str) and float(gender) >= 0.5)
    rows = _table_rows(res, targets, weight, achieved, start, NAMES, male)
    for line in res.warnings:
        click.echo(f"warning: {line}", err=True)
    if not quiet:
        click.echo(f"vfit morph: {gender_text} body, definition '{definition}'")
        click.echo(fmt_table(rows, ["measurement", "target", "achieved", "error (mm)", "start"]))
        if res.estimated:
            click.echo(f"(estimated): not given, so the population's value for the rest of this body "
                       f"(± its standard error; {_source()})")
    click.echo(f"wrote {output} ({N_BODY:,} body vertices, metres, Y up) in {elapsed:.2f} s")
    if json_path:
        write_json(json_path, {
            "command": "morph",
            "gender": gender,
            "definition": definition,
            "units": {"length": "cm", "mass": "kg", "mesh": "m"},
            "density_kg_m3": _density(),
            "targets": {k: round(v * 100, 4) for k, v in targets.items()},
            "target_weight_kg": weight,
            "achieved": achieved,
            "achieved_weight_kg": round(res.measurement.mass_kg, 3),
            "error_mm": {k: round((achieved[k] - v * 100) * 10, 4) for k, v in targets.items()},
            "estimated": {k: {"value": round(v * (1.0 if k == "mass" else 100.0), 3),
                              "standard_error": round(v * sd * (1.0 if k == "mass" else 100.0), 3),
                              "unit": "kg" if k == "mass" else "cm"} for k, (v, sd) in res.estimated.items()},
            "population": _source(),
            "warnings": list(res.warnings),
            "start": start,
            "start_weight_kg": round(res.start.mass_kg, 3),
            "planes_cm": {k: round(v * 100, 2) for k, v in res.measurement.planes.items()},
            "macro": {"gender": res.macro.gender, "height": res.macro.height, "weight": res.macro.weight,
                      "muscle": res.macro.muscle},
            "channels": {k: round(v, 6) for k, v in res.channels.items()},
            "output": output,
            "time_s": round(elapsed, 3),
        })
        if not quiet:
            click.echo(f"wrote {json_path}")


def _density():
    from vfit_engine.body.measure import DENSITY

    return DENSITY


def _estimate(res, name, scale):
    """Target cell of a value not given: the population's estimate, ± its standard error, or '-'."""
    if name not in res.estimated:
        return "-"
    value, sd = res.estimated[name]
    return f"{value * scale:.1f} ±{value * sd * scale:.1f} (estimated)"


def _source():
    from vfit_engine.body.population import CITATION

    return CITATION


def _table_rows(res, targets, weight, achieved, start, names, male=False):
    """The printed table: target (or the estimate), achieved, error and start of every measurement (a man's bust
    named chest)."""
    rows = []
    for k in names:
        want = targets.get(k)
        rows.append([f"{'chest' if male and k == 'bust' else k} (cm)", f"{want * 100:.2f}" if want is not None else _estimate(res, k, 100.0),
                     f"{achieved[k]:.2f}", f"{(achieved[k] - want * 100) * 10:+.2f}" if want is not None else "",
                     f"{start[k]:.2f}"])
    rows.append(["mass (kg)", f"{weight:.2f}" if weight else _estimate(res, "mass", 1.0),
                 f"{res.measurement.mass_kg:.2f}",
                 f"{(res.measurement.mass_kg / weight - 1) * 100:+.2f} %" if weight else "",
                 f"{res.start.mass_kg:.2f}"])
    return rows
