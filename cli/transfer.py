"""``vfit transfer``: move a garment made for one body onto another body."""
import click

from ._common import FILE_UNITS, EngineChoice, check_output_path, handle_errors
from ._outdir import check_outputs
from .drape import morph_options, user_files


@click.command()
@click.argument("garment", type=click.Path(dir_okay=False))
@click.option("--from", "from_path", default=None, type=click.Path(dir_okay=False),
              help="Body the garment fits now (.obj/.ply, hm08 topology). Default: the average body of the "
                   "garment's gender (from its .mhclo tags, else --gender).")
@click.option("--to", "to_path", default=None, type=click.Path(dir_okay=False),
              help="Body to move the garment to (.obj/.ply, hm08 topology); or give measurement options "
                   "instead and vfit builds it.")
@morph_options
# every transfer method but none (the garment would stay where it is: that is vfit drape --transfer none)
@click.option("--method", type=EngineChoice("vfit_engine.garment.transfer:METHODS", without=("none",)), default="auto",
              show_default=True,
              help="mhclo = re-fit the garment's .mhclo binding on the target (needs a body vfit builds from "
                   "measurements: a body file lacks the helper vertices); mhclo-delta = the garment plus the "
                   "binding's displacement; dqs / lbs = ARAP frames of the body with dual-quaternion / linear "
                   "blend skinning. auto: mhclo-delta when possible (as vfit drape), else dqs. "
                   "Every method but mhclo then gives back any clearance from the skin the garment lost.")
@click.option("--k", "k", type=click.IntRange(1, 64), default=6, show_default=True,
              help="Body vertices each garment vertex follows (dqs/lbs).")
@click.option("--units", type=FILE_UNITS, default="auto", show_default=True,
              help="Units of the garment file (auto: from its height; MakeHuman clothes are dm).")
@click.option("-o", "--output", default="transferred.obj", show_default=True, type=click.Path(dir_okay=False),
              help="Garment to write (.obj or .ply): the input's vertex order, faces and UVs, in metres.")
@click.option("-q", "--quiet", is_flag=True, help="Print only where the garment was written.")
@click.pass_context
@handle_errors
def transfer(ctx, garment, from_path, to_path, method, k, units, output, quiet, gender, height, weight, definition,
             **girths):
    """Move GARMENT (.obj/.ply) from one body onto another.

    The bodies share MakeHuman's hm08 topology: files written by vfit morph or
    exported from MakeHuman, or a body vfit builds from the measurement options.
    The garment keeps its vertex order, faces and UVs; it is written in metres.
    The result is a starting shape (it can still touch or cross the body):
    drape it with vfit drape for the final fit.

    \b
    Examples:
      vfit transfer suit.obj --waist 80 --hips 104 -o suit_fitted.obj
      vfit transfer suit.obj --from a.obj --to b.obj --method dqs -o suit_b.obj
    """
    import os
    import time

    from vfit_engine.errors import InputError

    t_start = time.perf_counter()
    morph_given = {key.replace("_", "-"): v / 100.0 for key, v in girths.items() if v is not None}
    if height is not None:
        morph_given["height"] = height / 100.0
    if to_path and (morph_given or weight is not None):
        raise InputError("give either --to or measurement options, not both")
    if not to_path and not (morph_given or weight is not None):
        raise InputError("no target body: give --to BODY or measurement options (e.g. --waist 80)")
    for path, what in ((garment, "garment"), (from_path, "body"), (to_path, "body")):
        if path and not os.path.isfile(path):
            raise InputError(f"{what} file not found: {path}")
    check_output_path(output, (".obj", ".ply"))
    check_outputs(None, (), dict(user_files(garment), **{"--from": from_path, "--to": to_path}),
                  extra_outputs=[output])
    gender_given = ctx.get_parameter_source("gender") != click.core.ParameterSource.DEFAULT

    from vfit_engine.body.model import BodyModel
    from vfit_engine.garment.garment import load_garment
    from vfit_engine.garment.transfer import transfer as transfer_verts
    from vfit_engine.io.mesh import write_mesh

    g = load_garment(garment, units=units)
    for w in g.warnings:
        click.echo(f"Warning: {garment}: {w}", err=True)
    binding = _binding(g, method)
    if binding is not None and binding.n_verts != g.mesh.n_verts:
        if method in ("mhclo", "mhclo-delta"):
            raise InputError(f"{g.mhclo_path}: binds {binding.n_verts} vertices but {garment} has {g.mesh.n_verts}")
        click.echo(f"Warning: {g.mhclo_path} does not match the garment's vertices; using dqs", err=True)
        binding = None

    model = BodyModel.load()
    tag_gender = binding.gender if binding is not None else None
    source_gender = tag_gender or (gender if gender_given else "female")
    body_gender = gender if gender_given else source_gender
    helpers = method in ("auto", "mhclo", "mhclo-delta")
    source = _read_body(from_path, model, helpers) if from_path else model.default_verts(source_gender)
    if to_path:
        target = _read_body(to_path, model, helpers)
    else:
        from vfit_engine.body.morph import Morpher

        target = Morpher(model).solve(morph_given, gender=body_gender, definition=definition,
                                      weight_kg=weight).verts

    if method == "auto":
        method = "dqs"
        if binding is not None:
            if min(source.shape[0], target.shape[0]) > binding.top_vertex:
                method = "mhclo-delta"
            else:
                click.echo("Warning: the target body file has no helper vertices, which the garment's .mhclo "
                           "needs; using dqs (build the body with measurement options for mhclo)", err=True)
    t0 = time.perf_counter()
    verts = transfer_verts(g.mesh.verts, source, target, method=method, k=k, mhclo=binding, model=model)
    restored = None
    if method != "mhclo":
        from vfit_engine.garment.transfer import restore_clearance

        verts, restored = restore_clearance(g.mesh.verts, verts, source, target, model.body_tris)
    t_transfer = time.perf_counter() - t0
    header = [f"vfit transfer: {os.path.basename(garment)} moved by {method}"
              + (f" (k={k})" if method in ("dqs", "lbs") else "") + "; metres, Y up"]
    write_mesh(output, g.mesh.with_verts(verts), header=header)
    if not quiet:
        import numpy as np

        moved = np.linalg.norm(verts - g.mesh.verts, axis=1)
        click.echo(f"vfit transfer: {g.mesh.n_verts} vertices by {method}"
                   + (f" (k={k})" if method in ("dqs", "lbs") else "")
                   + f" in {t_transfer:.3f} s; moved mean {moved.mean() * 1000:.1f} mm, "
                     f"max {moved.max() * 1000:.1f} mm"
                   + ("" if restored is None else f"; clearance given back to {int((restored > 0).sum())} "
                      f"vertices (max {restored.max() * 1000:.1f} mm)"))
    click.echo(f"wrote {output} (metres, Y up) in {time.perf_counter() - t_start:.2f} s")


def _binding(g, method):
    """The garment's .mhclo binding, or None (an error when the method needs one)."""
    from vfit_engine.errors import InputError
    from vfit_engine.garment.mhclo import parse_mhclo

    needs = method in ("mhclo", "mhclo-delta")
    if g.mhclo_path is None:
        if needs:
            raise InputError(f"method {method} needs a .mhclo binding beside {g.source}, found none")
        return None
    try:
        return parse_mhclo(g.mhclo_path)
    except InputError as exc:
        if needs:
            raise
        click.echo(f"Warning: {exc}; using dqs", err=True)
        return None


def _read_body(path, model, helpers):
    """Body vertices in metres: all ``N_VERTS`` (with MakeHuman's helpers) when ``helpers`` and the file has them,
    else the ``N_BODY`` body ones."""
    from vfit_engine.body.bodyio import read_body
    from vfit_engine.body.model import N_VERTS
    from vfit_engine.io.mesh import read_mesh
    from vfit_engine.units import LENGTH_UNITS

    verts, unit = read_body(path, model, "auto")
    if not helpers:
        return verts
    mesh = read_mesh(path)  # read_body keeps only the body vertices; the helpers are wanted for mhclo
    if mesh.n_verts == N_VERTS:
        import numpy as np

        return np.ascontiguousarray(mesh.verts * LENGTH_UNITS[unit])
    return verts
