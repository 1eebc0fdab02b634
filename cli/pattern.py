"""``vfit pattern``: look at a sewing pattern and convert it (GarmentCode JSON, DXF-AAMA with a seams sidecar)."""
import click

from ._common import check_output_path, fmt_table, handle_errors

SEAMS_HELP = ("The seams sidecar of a DXF-AAMA file (JSON: which piece edges are sewn together; "
              "docs/pattern-formats.md). AAMA itself carries no seams.")


@click.group()
def pattern():
    """Sewing patterns: draw one, or export it as DXF-AAMA.

    \b
    Examples:
      vfit pattern show shirt.json -o shirt.png
      vfit pattern export shirt.json -o shirt.dxf        (also writes shirt.seams.json)
      vfit pattern show shirt.dxf --seams shirt.seams.json -o shirt.png
    """


def _load(path, seams):
    from vfit_engine.pattern.load import load

    pat, warnings = load(path, seams)
    for w in warnings:
        click.echo(f"Warning: {w}", err=True)  # each names the file
    return pat


def _summary(pat):
    """The panels (size, outline) and the seams (both lengths, their difference) as two tables, in cm."""
    import numpy as np

    rows = []
    for name, p in pat.panels.items():
        ext = np.ptp(p.outline(), axis=0) * 100
        length = sum(p.edge_length(i) for i in range(len(p.edges))) * 100
        rows.append([name, f"{ext[0]:.1f} x {ext[1]:.1f}", len(p.edges), f"{length:.1f}"])
    out = [fmt_table(rows, ["panel", "width x height (cm)", "edges", "outline (cm)"])]
    rows = []
    for s in pat.stitches:
        la, lb = pat.edge_length(s.a) * 100, pat.edge_length(s.b) * 100
        rows.append([f"{s.a.panel}:{s.a.edge}", f"{s.b.panel}:{s.b.edge}", f"{la:.1f}", f"{lb:.1f}",
                     f"{la - lb:+.1f}"])
    out.append(fmt_table(rows, ["edge", "sewn to", "length (cm)", "its length (cm)", "difference (cm)"]))
    return "\n\n".join(out)


@pattern.command()
@click.argument("pattern_file", metavar="PATTERN", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "png", required=True, type=click.Path(dir_okay=False),
              help="The PNG to write: the flat panels side by side, seams numbered in pairs, grain lines, edge "
                   "lengths in cm, a 10 cm scale bar.")
@click.option("--seams", default=None, type=click.Path(dir_okay=False), help=SEAMS_HELP)
@handle_errors
def show(pattern_file, png, seams):
    """Draw PATTERN's flat panels into a PNG and print its panels and seams (cm)."""
    check_output_path(png, (".png",))
    pat = _load(pattern_file, seams)
    from vfit_engine.pattern.draw import draw_pattern

    draw_pattern(pat, png)
    click.echo(f"vfit pattern show: {pattern_file}: {len(pat.panels)} panels, {len(pat.stitches)} seams")
    if not pat.stitches and seams is None and pattern_file.lower().endswith(".dxf"):
        click.echo("(DXF-AAMA carries no seams: give them with --seams SEAMS.json, docs/pattern-formats.md)")
    click.echo(_summary(pat))
    click.echo(f"wrote {png}")


@pattern.command()
@click.argument("pattern_file", metavar="PATTERN", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "dxf", required=True, type=click.Path(dir_okay=False),
              help="The DXF-AAMA file to write (millimetres): one block per panel, for a plotter or a CAD system.")
@click.option("--seams", default=None, type=click.Path(dir_okay=False), help=SEAMS_HELP)
@click.option("--seams-out", default=None, type=click.Path(dir_okay=False),
              help="Where to write the seams sidecar  [default: beside the DXF, NAME.seams.json]")
@handle_errors
def export(pattern_file, dxf, seams, seams_out):
    """Write PATTERN as DXF-AAMA, with its seams in a sidecar JSON (so it can be read back and sewn)."""
    import os

    from vfit_engine.errors import InputError

    check_output_path(dxf, (".dxf",))
    seams_out = seams_out or os.path.splitext(dxf)[0] + ".seams.json"
    check_output_path(seams_out, (".json",))
    for out in (dxf, seams_out):
        for given in (pattern_file, seams):
            if given and os.path.exists(given) and os.path.exists(out) and os.path.samefile(given, out):
                raise InputError(f"{out}: is an input; write the export elsewhere")
    pat = _load(pattern_file, seams)
    from vfit_engine.pattern import dxf_aama

    dxf_aama.write(pat, dxf, seams_out)
    click.echo(f"vfit pattern export: {pattern_file}: {len(pat.panels)} panels, {len(pat.stitches)} seams")
    click.echo(f"wrote {dxf} and {seams_out}")
