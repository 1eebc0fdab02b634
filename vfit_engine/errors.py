"""Exceptions that the CLI turns into a one-line message and an exit code."""


class VfitError(Exception):
    """Base class: a problem the user can act on. ``exit_code`` is what the CLI returns."""

    exit_code = 1


class InputError(VfitError):
    """Bad input: a missing or garbled file, NaN, an absurd or unreachable value. Exit 2."""

    exit_code = 2
