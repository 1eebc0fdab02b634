"""The ``vfit`` command group.

Commands are registered explicitly. Their modules import only click at import
time (numpy, scipy and numba are imported inside the callbacks), so ``vfit
--help`` and ``vfit COMMAND --help`` answer at once.
"""
import click

from . import measure, morph
from . import drape


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="vfit", prog_name="vfit")
def cli():
    """vfit - virtual fitting: a body built to a customer's measurements, a garment draped on it.

    Lengths on the command line are centimetres, masses kilograms; meshes are
    written in metres, Y up. Exit codes: 0 ok, 2 bad input or unreachable
    target, 3 not converged, 4 simulation diverged.
    """


cli.add_command(morph.morph)
cli.add_command(measure.measure)
cli.add_command(drape.drape)


if __name__ == "__main__":  # pragma: no cover
    cli()
