"""Atomic file writes: a result file is either complete or absent, never half written."""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from vfit_engine.errors import InputError

#: The temporary files :func:`atomic_write` makes beside its target (".NAME.RANDOM.tmp").
TEMP_GLOB = ".*.tmp"
#: Characters of the target's name in its temporary file's: a name near the file system's limit (255 bytes)
#: must not fail only because its temporary file's name is longer (4 bytes a character at most in UTF-8).
TEMP_NAME_CHARS = 40


def _temp_prefix(path):
    return f".{path.name[:TEMP_NAME_CHARS]}."


@contextlib.contextmanager
def atomic_write(path, mode="w", encoding="utf-8", newline="\n"):
    """Open a temporary file beside ``path``; on success ``os.replace`` it onto ``path``.

    On any exception inside the block the temporary file is removed and ``path`` is left as it was
    (absent, or the previous version). The temporary file is in the same directory so the final
    rename never crosses file systems.

    Parameters
    ----------
    path : str or Path
    mode : {"w", "wb"}
    encoding, newline : str
        For text mode; ``newline="\\n"`` writes the same bytes on every platform.

    Yields
    ------
    file object

    Raises
    ------
    InputError
        ``cannot write <path>: <reason>`` when the directory is missing or not writable.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_write mode must be 'w' or 'wb', not {mode!r}")
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=".tmp", dir=directory)  # TEMP_GLOB
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        if mode == "wb":
            f = os.fdopen(fd, "wb")
        else:
            # backslashreplace: a file name not in UTF-8 (os gives its bytes as surrogates) in a header comment
            f = os.fdopen(fd, "w", encoding=encoding, newline=newline, errors="backslashreplace")
        with f:
            yield f
        # mkstemp creates 0600; give the result the permissions a plain open() would
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, InputError):
            raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise


def check_writable(path):
    """Raise InputError unless :func:`atomic_write` to ``path`` can succeed now: make and remove its temporary
    file and, when ``path`` is absent, ``path`` itself. Finds, before any work, what the write would find after
    it: a name longer than the file system allows, a directory that takes no files (``/proc``), one not
    writable, a directory where the file goes.

    Parameters
    ----------
    path : str or Path
        In an existing directory.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if os.path.isdir(path):  # not Path.is_dir: it raises on a name too long
        raise InputError(f"cannot write {path}: it is a directory; remove it or choose another path")
    try:
        fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=".tmp", dir=directory)
        os.close(fd)
        os.unlink(tmp)
        if not os.path.lexists(path):
            os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
            os.unlink(path)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}; choose another path") from None


def remove_orphans(directory):
    """Remove the temporary files of :func:`atomic_write` left in ``directory``: a signal that lands between
    the temporary file's creation and the ``with`` block that owns it (inside ``mkstemp``, or in
    contextlib's ``__enter__``) skips the clean-up. Only for a directory one process holds (a command's
    OUTDIR under its lock), where every such file is an orphan once that process is done with it."""
    for tmp in Path(directory).glob(TEMP_GLOB):
        with contextlib.suppress(OSError):
            tmp.unlink()
