"""Progress of a long command on stderr: its stages, then the drape's frames with how much is still moving.

A drape ends when the cloth settles, not after a known number of frames, so no time is estimated from the
frame limit (a bar to 600 frames said 29 minutes for a 4 s drape and stopped at a third). Instead each line
says what is being done and, while settling, how much of the cloth still moves: the settle test's own
figure. On a terminal the settling line is rewritten in place; elsewhere (a log) a line every
``LOG_EVERY`` frames. ``quiet`` silences everything.
"""
import sys
import time

import click

#: Frames between settling lines when stderr is not a terminal.
LOG_EVERY = 30


def kernels_cached():
    """True when the cloth kernel's compiled code is in Numba's cache (else the first drape compiles it)."""
    from pathlib import Path

    import vfit_engine

    cache = Path(vfit_engine.__file__).parent / "kernels" / "__pycache__"
    return any(cache.glob("cloth.cloth_substeps-*.nbi"))


class Progress:
    """Stage lines and the settling line of one run (module docstring)."""

    def __init__(self, quiet, stream=None, command="vfit drape"):
        self.quiet = quiet
        self.command = command
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.t0 = time.perf_counter()
        self.open_line = False

    def stage(self, text):
        """Say what the run does now."""
        if not self.quiet:
            self._end_line()
            click.echo(f"{self.command}: {text} ({time.perf_counter() - self.t0:.1f} s)", file=self.stream)

    def frame(self, frame, moving, max_frames):
        """After frame ``frame``: ``moving``, the share of the cloth that moved more than the settle test's
        step in it (the settle test's own figure, :func:`vfit_engine.drape.run_drape`)."""
        if self.quiet:
            return
        text = (f"settling: frame {frame} (at most {max_frames}), {100 * moving:.1f} % of the cloth still moving "
                f"({time.perf_counter() - self.t0:.1f} s)")
        if self.tty:
            click.echo("\r" + text + "\033[K", file=self.stream, nl=False)
            self.open_line = True
        elif frame % LOG_EVERY == 0:
            click.echo(f"{self.command}: " + text, file=self.stream)

    def line(self, text, frame):
        """A line of a run that counts frames towards a known end (rewritten in place on a terminal)."""
        if self.quiet:
            return
        text = f"{text} ({time.perf_counter() - self.t0:.1f} s)"
        if self.tty:
            click.echo("\r" + text + "\033[K", file=self.stream, nl=False)
            self.open_line = True
        elif frame % LOG_EVERY == 0:
            click.echo(f"{self.command}: " + text, file=self.stream)

    def _end_line(self):
        if self.open_line:
            click.echo("", file=self.stream)
            self.open_line = False

    def done(self):
        """Close the settling line."""
        if not self.quiet:
            self._end_line()
