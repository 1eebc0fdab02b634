"""Shared CLI pieces: validated number types, error handling, JSON output. Imports click only."""
from __future__ import annotations

import functools
import json
import math
import sys

import click

#: time.perf_counter() when the ``vfit`` program started its command (``main.run``); None when a command is
#: invoked in-process (a test's CliRunner): then a command counts from its own start
PROGRAM_START = None


def seconds_since_start(command_start):
    """Seconds since the program started (or since ``command_start``, a perf_counter, when in-process)."""
    import time

    return time.perf_counter() - (command_start if PROGRAM_START is None else PROGRAM_START)


class Quantity(click.ParamType):
    """A finite number in ``[lo, hi]`` with a unit, e.g. ``Quantity('cm', 1, 400)``."""

    name = "number"

    def __init__(self, unit: str, lo: float, hi: float):
        self.unit, self.lo, self.hi = unit, lo, hi

    def get_metavar(self, param, ctx=None):
        return self.unit.upper()

    def convert(self, value, param, ctx):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            x = float(value)
        else:
            try:
                x = float(str(value).strip())
            except ValueError:
                self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(x):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        if x <= 0:
            self.fail(f"{value} {self.unit} must be positive", param, ctx)
        if not self.lo <= x <= self.hi:
            self.fail(f"{value} {self.unit} is absurd (expected {self.lo:g}-{self.hi:g} {self.unit})", param, ctx)
        return x


class Gender(click.ParamType):
    """'female', 'male' or a number in 0..1 (0 female, 1 male)."""

    name = "gender"

    def get_metavar(self, param, ctx=None):
        return "female|male|0..1"

    def convert(self, value, param, ctx):
        from vfit_engine.body.gender import parse_gender

        try:
            return parse_gender(value)
        except ValueError as exc:
            self.fail(str(exc), param, ctx)


class EngineChoice(click.Choice):
    """A :class:`click.Choice` among the names an engine constant holds (a tuple, or a dict's keys), e.g.
    ``EngineChoice("vfit_engine.garment.transfer:METHODS")``: the command line offers what the engine takes,
    from the one list the engine checks.

    The constant is read when the choices are first wanted (a value to check, ``--help`` to write), from its
    module's source (:func:`engine_constant`): the engine imports its NumPy, SciPy and Numba at its modules'
    tops, and no help loads them. ``first``: names the command adds before the engine's (``"auto"``);
    ``without``: names it does not offer.
    """

    def __init__(self, constant: str, first: tuple = (), without: tuple = ()):
        self.constant, self.first, self.without = constant, tuple(first), tuple(without)
        self.case_sensitive = True

    @functools.cached_property
    def choices(self):
        names = engine_constant(*self.constant.split(":"))
        return self.first + tuple(n for n in names if n not in self.without)


def engine_constant(module, name):
    """The names an engine constant holds (a tuple's items, a dict's keys), read from the literal assigned to
    it in its module's source, so the engine is not imported; a constant that is not a literal there is
    imported (``module`` ``"vfit_engine.drape.setup"``, ``name`` ``"REST_MODES"``)."""
    import ast
    import importlib
    import importlib.util
    from pathlib import Path

    root = Path(importlib.util.find_spec("vfit_engine").origin).parent  # finds the package, runs nothing
    source = root.joinpath(*module.split(".")[1:]).with_suffix(".py").read_text(encoding="utf-8")
    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign) and [t.id for t in node.targets if isinstance(t, ast.Name)] == [name]:
            try:
                if isinstance(node.value, ast.Dict):
                    return tuple(ast.literal_eval(k) for k in node.value.keys)
                return tuple(ast.literal_eval(node.value))
            except ValueError:  # not a literal: the module's own value
                break
    return tuple(getattr(importlib.import_module(module), name))


#: ``--units`` of a mesh file: ``auto`` (from its height) or a unit of ``vfit_engine.units.LENGTH_UNITS``
FILE_UNITS = EngineChoice("vfit_engine.units:LENGTH_UNITS", first=("auto",))


class Terminated(KeyboardInterrupt):
    """Raised by the ``vfit`` group's SIGTERM handler: a SIGTERM ends a run as Ctrl-C does, and whoever
    catches KeyboardInterrupt can tell the two apart (exit 143 against 130)."""


def interruption(exc):
    """(signal name, exit code) of a KeyboardInterrupt: SIGTERM (143) if it is a :class:`Terminated`, else
    SIGINT (130)."""
    return ("SIGTERM", 143) if isinstance(exc, Terminated) else ("SIGINT", 130)


def handle_errors(func):
    """Turn vfit's own errors into one line on stderr and their exit code (2 for bad input)."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from vfit_engine.errors import VfitError

        try:
            return func(*args, **kwargs)
        except VfitError as exc:
            click.echo(f"Error: {exc}", err=True)
            sys.exit(exc.exit_code)
        except MemoryError:
            click.echo("Error: out of memory (input too large?)", err=True)
            sys.exit(2)

    return wrapper


def check_output_path(path: str, suffixes: tuple, outdir: str | None = None) -> None:
    """Fail early (before any long computation) on an output path that cannot be written: its suffix, its
    directory, then a file made and removed there (``vfit_engine.io.atomic.check_writable``).

    ``outdir``: the command's output directory, which it creates before writing: ``path`` may be in it while
    it does not exist yet (then it is made for the check and removed again).
    """
    import os

    from vfit_engine.errors import InputError
    from vfit_engine.io.atomic import check_writable

    ext = os.path.splitext(path)[1].lower()
    if ext not in suffixes:
        raise InputError(f"cannot write {path}: use one of {', '.join(suffixes)}")
    d = os.path.dirname(os.path.abspath(path))
    made = []
    if not os.path.isdir(d):
        if outdir is None or d != os.path.abspath(outdir):
            raise InputError(f"cannot write {path}: directory {d} does not exist")
        missing = d
        while not os.path.exists(missing):
            made.append(missing)
            missing = os.path.dirname(missing)
        try:
            os.makedirs(d)
        except OSError as exc:
            raise InputError(f"cannot write {path}: cannot create {d}: {exc.strerror or exc}") from None
    try:
        check_writable(path)
    finally:
        for m in made:  # deepest first
            try:
                os.rmdir(m)
            except OSError:
                pass


def write_json(path: str, payload: dict) -> None:
    """Write a JSON report atomically."""
    from vfit_engine.io.atomic import atomic_write

    with atomic_write(path) as f:
        json.dump(payload, f, indent=2, sort_keys=False)
        f.write("\n")


def fmt_table(rows: list, header: list) -> str:
    """A plain aligned text table."""
    cols = [header] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cols) for i in range(len(header))]
    line = lambda r: "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))
    return "\n".join([line(header), line(["-" * w for w in widths])] + [line(r) for r in cols[1:]])


def fit_table_lines(rows):
    """The fit table (report.json's ``fit``) as people read it, one line per region: body and garment girth (draped,
    round the body), the garment's own girth there as made (its size; a size run's grow as graded), ease, the
    stretch of the cloth round it and the verdict (vfit_engine.fit.verdict's rule); * marks the girths sizes are
    labelled by (EN 13402: chest/bust, waist, hips), "(estimated)" a girth the customer did not give, "-" a figure
    a region the garment does not go round has not."""
    from vfit_engine.fit.verdict import stretch

    def num(x, fmt):  # + 0.0: no "-0.0" for a figure that rounds to nothing
        return "-" if x is None else format(round(x, 1) + 0.0, fmt)

    table = [[r["region"] + ("*" if r.get("key") else ""),
              f"{r['body_girth_cm']:.1f}" + (" (estimated)" if r.get("estimated") else ""),
              num(r["garment_girth_cm"], ".1f"), num(r.get("garment_made_cm"), ".1f"), num(r["ease_cm"], "+.1f"),
              num(None if stretch(r) is None else 100 * stretch(r), ".1f"), r["verdict"]] for r in rows]
    return fmt_table(table, ["region", "body cm", "garment cm", "made cm", "ease cm", "stretch %",
                             "verdict"]).splitlines()
