"""``vfit size``: which size of a garment or a sewing pattern to buy -- a size run graded from it, each size tried
on the customer."""
from types import SimpleNamespace

import click

from ._common import (FILE_UNITS, EngineChoice, check_output_path, fit_table_lines, handle_errors, interruption,
                      write_json)
from ._outdir import check_outputs
from ._progress import Progress, cloth_kernels_cached
from .drape import body_targets, morph_options, user_files

#: The sizes (``vfit_engine.sizes.SIZE_NAMES``; listed here so --help imports no numpy).
SIZE_NAMES = ("XS", "S", "M", "L", "XL")
#: Exit code when no size could be judged (every drape diverged or failed), as a drape that did not converge.
NOT_JUDGED = 3


@click.command()
@click.argument("garment", type=click.Path(dir_okay=False))
@click.option("--body", "body_path", default=None, type=click.Path(dir_okay=False),
              help="The customer's body (.obj/.ply with hm08 topology, e.g. from vfit morph). Default: the "
                   "average body of the garment's gender, or one built from the measurement options.")
@morph_options
@click.option("--sizes", "sizes_text", default=",".join(SIZE_NAMES), show_default=True,
              help="Comma-separated EN 13402 letter sizes to try.")
@click.option("--material", default="cotton", show_default=True,
              help="silk, cotton, wool, denim, jersey, or a material .json file (keys with units: see README).")
@click.option("--units", type=FILE_UNITS, default="auto", show_default=True,
              help="Units of the garment file (auto: from its height; MakeHuman clothes are dm).")
@click.option("--seams", default=None, type=click.Path(dir_okay=False),
              help="A DXF-AAMA pattern's seams (JSON sidecar: docs/pattern-formats.md).")
@click.option("--spacing", type=click.FloatRange(3, 100), default=None,
              help="A pattern's cloth: edge length in mm [default: 20].")
@click.option("--arrange", type=EngineChoice("vfit_engine.pattern.placement:ARRANGEMENTS"), default="auto",
              show_default=True,
              help="How a pattern's panels start round the body (as vfit drape).")
@click.option("--workers", type=click.IntRange(1, 256), default=None,
              help="Sizes tried at once, each in its own process [default: the cores available].")
@click.option("--json", "json_path", default=None, type=click.Path(dir_okay=False),
              help="Also write the fit of every size and the recommendation as JSON.")
@click.option("-q", "--quiet", is_flag=True, help="No progress lines and no tables: only the recommendation.")
@click.pass_context
@handle_errors
def size(ctx, garment, body_path, sizes_text, material, units, seams, spacing, arrange, workers, json_path, quiet,
         gender, height, weight, definition, **girths):
    """Say which size of GARMENT (.obj/.ply, or a sewing pattern: GarmentCode
    .json, DXF-AAMA .dxf with --seams) fits the customer, and why.

    Makes a size run of the garment by grading it (made to measure) from the
    body it was made on to bodies at the centre of each EN 13402 size (bust,
    men: chest, with waist and hips; at the customer's height, since the
    letter size is a girth size); the garment as given is the size whose
    centre is nearest its own body (it says which). Each size is draped at its
    own size on the customer's body, the sizes in parallel; it prints the fit
    of every size (region, body and garment girth, ease, the stretch of the
    cloth round it, verdict; * marks the girths sizes are labelled by,
    "estimated" a girth the customer did not give), which regions reject a
    size too small, and the recommended size.

    The rule: the smallest size whose every region is at least fitted: no
    tight verdict (tight or too tight to wear) at any region of its table
    (chest/bust, waist, hips, neck, upper arms, thighs, the openings). If
    every size is tight somewhere, the largest, saying where it is tight.
    Exit 3 when no size could be judged (every drape diverged or failed).

    A pattern is graded from the body it was made for (its own when it names
    one, else the default body of the customer's gender, said to be assumed)
    by one rule, which it prints: the girth change at the bust, waist and
    hips spread over the panels crossing each in proportion to their width,
    linear in height between them; sleeves across by the upper arm's change,
    their caps kept to their armholes; lengths as made. Each size is sewn and
    draped as vfit drape PATTERN does.

    \b
    Examples:
      vfit size male_casualsuit02.obj --gender male --height 180 --chest 98
      vfit size suit.obj --body customer.obj --sizes S,M,L --json fit.json
      vfit size shirt.json --height 172 --bust 99.8 --waist 84.3 --hips 103.5
    """
    import os
    import time

    from vfit_engine.errors import InputError
    from vfit_engine.sizes import parse_sizes

    t_start = time.perf_counter()
    names = parse_sizes(sizes_text)
    targets = body_targets(body_path, girths, height, weight)
    if not os.path.isfile(garment):
        raise InputError(f"garment file not found: {garment}")
    if body_path and not os.path.isfile(body_path):
        raise InputError(f"body file not found: {body_path}")
    if json_path:
        check_output_path(json_path, (".json",))
    pattern = _check_kind(ctx, garment, seams)
    check_outputs(None, (), {**user_files(garment, body_path, material=material), "--seams": seams},
                  extra_outputs=[json_path])
    gender_given = ctx.get_parameter_source("gender") != click.core.ParameterSource.DEFAULT
    o = SimpleNamespace(garment=garment, names=names, material=material, units=units, workers=workers,
                        json_path=json_path, quiet=quiet, t_start=t_start, pattern=pattern, seams=seams,
                        spacing=spacing, arrange=arrange,
                        customer=dict(path=body_path, targets=targets, weight_kg=weight,
                                      gender=gender if gender_given else None, definition=definition))
    try:
        code = _size(o)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM (the vfit group's)
        name, code = interruption(exc)
        click.echo(f"Error: interrupted by {name}; nothing written", err=True)
    if code:
        ctx.exit(code)


def _check_kind(ctx, garment, seams):
    """Whether GARMENT is a pattern; InputError for the options of the other kind, a missing seams file, and a
    pattern that cannot be read or sewn (in one line, before any notice or process)."""
    import os

    from vfit_engine.errors import InputError
    from vfit_engine.pattern.load import is_pattern, load

    given = [n for n in ("units", "seams", "spacing", "arrange")
             if ctx.get_parameter_source(n) != click.core.ParameterSource.DEFAULT]
    pattern = is_pattern(garment)
    bad = [n for n in given if (n == "units") == pattern]
    if bad:
        what = ("a garment mesh; a pattern's units are its file's" if pattern
                else "a sewing pattern (.json, .dxf), not a garment mesh")
        raise InputError(f"{garment}: --{bad[0]} is for {what}")
    if seams and not os.path.isfile(seams):
        raise InputError(f"seams file not found: {seams}")
    if pattern:
        load(garment, seams)
    return pattern


def _size(o):
    """The size command's work (``o``: the options); returns the exit code."""
    import time

    from vfit_engine.pattern_sizes import try_pattern_sizes
    from vfit_engine.sizes import try_sizes

    def progress(text):
        if not o.quiet:
            click.echo(f"vfit size: {text} ({time.perf_counter() - o.t_start:.1f} s)", err=True)

    if not cloth_kernels_cached():  # the workers compile them, each its own copy, out of this process's sight
        click.echo("vfit size: the first run compiles the cloth kernels in every process that drapes: a wait of a "
                   "few minutes, once (later runs load them from the cache)", err=True)
    with Progress(True, command="vfit size").compiling():  # this process's own (measuring the customer)
        if o.pattern:
            res = try_pattern_sizes(o.garment, o.customer, sizes=o.names, workers=o.workers, progress=progress,
                                    material=o.material, seams=o.seams, arrange=o.arrange,
                                    **({} if o.spacing is None else dict(spacing=o.spacing / 1000.0)))
            for w in res["warnings"]:  # each names the file
                click.echo(f"Warning: {w}", err=True)
        else:
            res = try_sizes(o.garment, o.customer, sizes=o.names, workers=o.workers, progress=progress,
                            units=o.units, material=o.material)
    res["wall_s"] = round(time.perf_counter() - o.t_start, 3)
    if not o.quiet:
        _tables(res)
    if o.json_path:
        write_json(o.json_path, res)
    if res["recommended"] is None:
        click.echo(f"Error: {res['reason']}", err=True)
        return NOT_JUDGED
    click.echo(f"recommended size: {res['recommended']} -- {res['reason']}")
    if o.json_path and not o.quiet:
        click.echo(f"wrote {o.json_path}")
    return 0


def _tables(res):
    """The fit of every size, as people read it, and what rejected each size smaller than the one recommended."""
    from vfit_engine.sizes import rejection

    own, c, pick = res["garment_size"], res["customer"], res["recommended"]
    chest = "chest" if res["gender"] == "male" else "bust"
    est = set(res.get("customer_estimated") or ())

    def given(name, label):
        return f"{label} {c[name]:.1f}" + (" (estimated)" if name in est else "")

    if res.get("made_for"):  # a pattern
        click.echo(f"vfit size: {res['garment']}: {res['made_for']}; the pattern as given is size {own['size']} "
                   f"({own['measure']} {own['body_cm']:.1f} cm; centre of {own['size']}: {own['centre_cm']} cm)")
        click.echo(f"graded by the rule: {res['grading_rule']}")
    else:
        click.echo(f"vfit size: {res['garment']}: the garment as given is size {own['size']} (made on a "
                   f"{own['measure']} of {own['body_cm']:.1f} cm; centre of {own['size']}: {own['centre_cm']} cm)")
    at_height = ("size bodies at that height, the pattern's lengths as made" if res.get("made_for")
                 else "sizes graded at that height")
    click.echo(f"customer: {given('bust', chest)}, {given('waist', 'waist')}, {given('hips', 'hips')}, height "
               f"{c['height']:.1f} cm; {at_height}; {len(res['sizes'])} sizes in "
               f"{res['wall_s']:.1f} s on {res['workers']} process{'es' if res['workers'] > 1 else ''}")
    for s in res["sizes"]:
        cc = s["centre_cm"]
        click.echo("")
        title = (f"size {s['size']} ({chest} {cc['bust']:g}, waist {cc['waist']:g}, hips {cc['hips']:g} cm): "
                 f"{s['status']}")
        if s["status"] in ("settled", "not settled"):
            title += f", {s['frames']} frames, {s['wall_s']:.1f} s"
        if s.get("message"):
            title += f" ({s['message']})"
        click.echo(title)
        if s.get("grading"):
            click.echo(f"  graded: {_grading(s['grading'])}")
        if not s.get("fit"):
            continue
        click.echo("\n".join("  " + line for line in fit_table_lines(s["fit"])))
        click.echo(f"  {s['summary']}")
        why = rejection(s)
        if why and pick in SIZE_NAMES and SIZE_NAMES.index(s["size"]) < SIZE_NAMES.index(pick):
            click.echo(f"  rejected {s['size']}: {why}")  # the rule passed over it: the regions that decided
    click.echo("")


def _grading(g):
    """"bust 109.8 cm x 1.073 (body +8.0 cm), ...; sleeves x 1.047 across, cap x 0.874": what the rule did."""
    parts = [f"{name} {r['garment_cm']:.1f} cm x {r['scale']:.3f} (body {r['body_change_cm']:+.1f} cm)"
             for name, r in g["levels"].items()]
    for a in g["arms"][:1]:  # both arms alike
        parts.append(f"sleeves {a['girth_cm']:.1f} cm x {a['scale']:.3f} across (upper arm {a['change_cm']:+.1f} cm"
                     f"{'' if a['width_by'] == 'upper arm' else ', held to the armhole'}), cap height x "
                     f"{a['cap_scale']:.3f}")
    return "; ".join(parts)
