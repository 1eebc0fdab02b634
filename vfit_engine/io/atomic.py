"""Atomic file writes: a result file is either complete or absent, never half written."""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from vfit_engine.errors import InputError

#: The temporary files :func:`atomic_write` makes beside its target (".NAME.RANDOM.tmp").
TEMP_GLOB = ".*.tmp"


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
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)  # TEMP_GLOB
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        if mode == "wb":
            f = os.fdopen(fd, "wb")
        else:
            f = os.fdopen(fd, "w", encoding=encoding, newline=newline)
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


def remove_orphans(directory):
    """Remove the temporary files of :func:`atomic_write` left in ``directory``: a signal that lands between
    the temporary file's creation and the ``with`` block that owns it (inside ``mkstemp``, or in
    contextlib's ``__enter__``) skips the clean-up. Only for a directory one process holds (a command's
    OUTDIR under its lock), where every such file is an orphan once that process is done with it."""
    for tmp in Path(directory).glob(TEMP_GLOB):
        with contextlib.suppress(OSError):
            tmp.unlink()
