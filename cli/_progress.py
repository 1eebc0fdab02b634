"""Progress of a long command on stderr: its stages, then the drape's frames with how much is still moving.

A drape ends when the cloth settles, not after a known number of frames, so no time is estimated from the
frame limit (a bar to 600 frames said 29 minutes for a 4 s drape and stopped at a third). Instead each line
says what is being done and, while settling, how much of the cloth still moves: the settle test's own
figure. On a terminal the settling line is rewritten in place; elsewhere (a log) a line every
``LOG_EVERY`` frames. ``quiet`` silences all that.

A first run compiles the kernels (a minute or more for the cloth's; later runs load them from Numba's
cache): :meth:`Progress.compiling` says so when and while it happens, even when quiet, with the seconds
ticking (on a terminal a line rewritten every second, elsewhere a line every ``COMPILE_LOG_EVERY`` s), and
how long it took in all.
"""
import contextlib
import sys
import threading
import time

import click

#: Frames between settling lines when stderr is not a terminal.
LOG_EVERY = 30
#: Seconds between the compile notice's lines when stderr is not a terminal.
COMPILE_LOG_EVERY = 10


def cloth_kernels_cached():
    """Whether the cloth kernel has fresh code in Numba's cache (else a first drape compiles it, for a minute or
    more). Imports numba."""
    from vfit_engine.kernel_compiles import is_cached
    from vfit_engine.kernels.cloth import cloth_substeps

    return is_cached(cloth_substeps)


class Progress:
    """Stage lines and the settling line of one run (module docstring)."""

    def __init__(self, quiet, stream=None, command="vfit drape"):
        self.quiet = quiet
        self.command = command
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.t0 = time.perf_counter()
        self.open_line = None  # the kind of line a terminal shows unfinished: "progress", "compile" or None
        self.lock = threading.RLock()  # compiles may run in a worker thread (the collider's set-up)
        self.compile_s = 0.0  # seconds spent compiling, the compile under way not counted
        self.compile_t0 = None  # when the compile under way started
        self.compile_cut = False  # a compile failed or was interrupted (its kernel is not cached)

    @contextlib.contextmanager
    def compiling(self):
        """Within the context, show the kernels' compiles where they happen (module docstring); quiet or not.

        A compile happens only when a kernel's cached code is missing or stale
        (:func:`vfit_engine.kernel_compiles.watching_compiles`): a warm run prints nothing. Importing numba here
        (not at this module's import) keeps ``vfit --help`` light.
        """
        from vfit_engine.kernel_compiles import watching_compiles

        stop = threading.Event()
        ticker = threading.Thread(target=self._tick, args=(stop,), daemon=True)
        try:
            with watching_compiles(self._compile_start, self._compile_end):
                ticker.start()
                yield
        finally:
            stop.set()
            if ticker.ident is not None:
                ticker.join()
            with self.lock:
                if self.compile_s:
                    self._end_line()
                    click.echo(f"{self.command}: " + (
                        f"compiled kernels for {self.compile_s:.0f} s, the last one cut short: the next run "
                        "compiles it again" if self.compile_cut else
                        f"compiled the kernels in {self.compile_s:.0f} s; later runs load them from the cache and "
                        "start at once"), file=self.stream)

    def _compile_start(self):
        with self.lock:
            self.compile_t0 = time.perf_counter()
            if self.tty:
                self._show_compile()
            elif not self.compile_s:
                self._end_line()
                click.echo(f"{self.command}: compiling the kernels, once: later runs load them from the cache "
                           f"({self.compile_t0 - self.t0:.1f} s)", file=self.stream)

    def _compile_end(self, done):
        with self.lock:
            self.compile_cut = not done
            self.compile_s += time.perf_counter() - self.compile_t0
            self.compile_t0 = None
            if self.tty:
                self._show_compile()

    def _tick(self, stop):
        """Every second on a terminal (``COMPILE_LOG_EVERY`` s elsewhere) until ``stop``: the compile's seconds."""
        while not stop.wait(1.0 if self.tty else COMPILE_LOG_EVERY):
            with self.lock:
                if self.compile_t0 is not None:
                    self._show_compile()

    def _show_compile(self):
        seconds = self.compile_s + (time.perf_counter() - self.compile_t0 if self.compile_t0 is not None else 0.0)
        if self.tty:
            if self.open_line == "progress":
                self._end_line()
            click.echo(f"\r{self.command}: compiling the kernels, once (later runs load them from the cache): "
                       f"{seconds:.0f} s\033[K", file=self.stream, nl=False)
            self.open_line = "compile"
        else:
            click.echo(f"{self.command}: compiling the kernels: {seconds:.0f} s so far", file=self.stream)

    def stage(self, text):
        """Say what the run does now."""
        if not self.quiet:
            with self.lock:
                self._end_line()
                click.echo(f"{self.command}: {text} ({time.perf_counter() - self.t0:.1f} s)", file=self.stream)

    def frame(self, frame, moving, max_frames):
        """After frame ``frame``: ``moving``, the share of the cloth that moved more than the settle test's
        step in it (the settle test's own figure, :func:`vfit_engine.drape.run_drape`)."""
        if self.quiet:
            return
        text = (f"settling: frame {frame} (at most {max_frames}), {100 * moving:.1f} % of the cloth still moving "
                f"({time.perf_counter() - self.t0:.1f} s)")
        self._rewrite(text, frame)

    def line(self, text, frame):
        """A line of a run that counts frames towards a known end (rewritten in place on a terminal)."""
        if self.quiet:
            return
        self._rewrite(f"{text} ({time.perf_counter() - self.t0:.1f} s)", frame)

    def _rewrite(self, text, frame):
        """A line rewritten in place on a terminal; elsewhere one every ``LOG_EVERY`` frames."""
        with self.lock:
            if self.tty:
                if self.open_line == "compile":
                    self._end_line()
                click.echo("\r" + text + "\033[K", file=self.stream, nl=False)
                self.open_line = "progress"
            elif frame % LOG_EVERY == 0:
                click.echo(f"{self.command}: " + text, file=self.stream)

    def _end_line(self):
        if self.open_line:
            click.echo("", file=self.stream)
            self.open_line = None

    def done(self):
        """Close the settling line (and a compile line a terminal still shows unfinished)."""
        with self.lock:
            if not self.quiet or self.open_line == "compile":
                self._end_line()
