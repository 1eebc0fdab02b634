"""The ``vfit`` command group.

Commands are registered explicitly (:data:`COMMANDS`), and a command's module is
imported only when that command runs or help lists it: building the options of
all nine took ~35 ms of every run. The modules import only click at import time
(numpy, scipy and numba are imported inside the callbacks), so ``vfit --help``
and ``vfit COMMAND --help`` answer at once.
"""
import importlib
import signal
import sys

import click

from ._common import Terminated, interruption

#: the commands; each is the function of its name in the module of its name in this package
COMMANDS = ("animate", "batch", "drape", "measure", "morph", "pattern", "pose", "segment", "size", "transfer")


class OneLineErrors(click.Group):
    """A group whose usage errors are one line on stderr (exit 2), not click's usage block, and whose
    commands (:data:`COMMANDS`) are imported when first asked for."""

    def list_commands(self, ctx):
        return sorted(set(COMMANDS) | set(self.commands))

    def get_command(self, ctx, cmd_name):
        if cmd_name not in self.commands and cmd_name in COMMANDS:
            module = importlib.import_module(f"{__package__}.{cmd_name}")
            self.add_command(getattr(module, cmd_name))
        return self.commands.get(cmd_name)

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        if not standalone_mode:  # a caller that handles click's exceptions itself
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        def on_term(signum, frame):  # SIGTERM ends a run like Ctrl-C does, with its own exit code
            raise Terminated

        try:
            previous = signal.signal(signal.SIGTERM, on_term)
        except ValueError:  # not the main thread
            previous = None
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except click.UsageError as exc:
            where = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
            click.echo(f"Error: {exc.format_message()}{where}", err=True)
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
        except click.Abort as exc:  # (click's form of KeyboardInterrupt)
            name, code = interruption(exc.__cause__)
            click.echo(f"Error: interrupted by {name}", err=True)
            sys.exit(code)
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)
        sys.exit(rv if isinstance(rv, int) else 0)


@click.group(cls=OneLineErrors, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="vfit", prog_name="vfit")
def cli():
    """vfit - virtual fitting: a body built to a customer's measurements, a garment draped on it.

    Lengths on the command line are centimetres, masses kilograms; meshes are
    written in metres, Y up. Exit codes: 0 ok, 2 bad input or unreachable
    target, 3 not converged, 4 simulation diverged, 5 a batch with failed
    tasks, 130 / 143 interrupted (Ctrl-C / SIGTERM).
    """


def run():
    """The ``vfit`` program: :func:`cli`, then the process ends (:func:`end`)."""
    import time

    from . import _common

    _common.PROGRAM_START = time.perf_counter()
    try:
        cli.main()
    except SystemExit as exc:  # cli.main always ends so (standalone mode)
        end(exc.code)
    end(0)


def end(code):
    """End the process with ``code`` (a SystemExit's: None, an int or a message), skipping Python's teardown
    where nothing needs it.

    With NumPy, SciPy and Numba loaded the interpreter's teardown takes ~0.3 s (measured: a process that loads
    the morph solver ends in 0.97 s this way against 1.30 s), a sixth of a `vfit morph`. Once a command has
    returned it has written and closed its outputs (every file is written through a context manager and an
    atomic rename), so the streams are flushed, logging is shut down and the process ends at once -- unless
    something still runs that the teardown waits for or cleans up: a thread that is not a daemon, a child
    process, or a Dask client (its cluster's workers are closed at exit). Then it ends as usual."""
    if code is None:
        code = 0
    elif not isinstance(code, int):
        print(code, file=sys.stderr)
        code = 1
    if _teardown_needed():
        sys.exit(code)
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed or broken pipe: nothing more can reach it
            pass
    if "logging" in sys.modules:
        sys.modules["logging"].shutdown()
    os._exit(code)


def _teardown_needed():
    import threading

    main = threading.main_thread()
    if any(t.is_alive() and not t.daemon and t is not main for t in threading.enumerate()):
        return True
    if "distributed" in sys.modules:
        return True
    mp = sys.modules.get("multiprocessing")
    return bool(mp is not None and mp.active_children())


if __name__ == "__main__":  # pragma: no cover
    run()
