"""A command's output directory: checked before any work, held by one run at a time, cleared of an earlier run.

``with OutdirLock(outdir):`` creates OUTDIR if it is missing, takes its lock file (``.vfit.lock``, holding the
run's pid) and on leaving removes the temporary files an interrupted atomic write left in it, releases it and
removes OUTDIR again if this run created it and left nothing in it (an early error leaves no empty directory
behind). A second run into the same OUTDIR fails at once with
:class:`InputError` naming the first one's pid; a lock whose process is gone (killed) is taken over.
"""
import glob
import os

from vfit_engine.errors import InputError

LOCK_NAME = ".vfit.lock"


def check_outdir(outdir):
    """Fail early, before any long computation, on an OUTDIR that cannot be written."""
    if os.path.exists(outdir) and not os.path.isdir(outdir):
        raise InputError(f"cannot write to {outdir}: not a directory")
    existing = os.path.abspath(outdir)
    while not os.path.exists(existing):  # created later with its parents: the nearest existing one decides
        existing = os.path.dirname(existing)
    if not os.path.isdir(existing):
        raise InputError(f"cannot create {outdir}: {existing} is not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"cannot write to {outdir}: permission denied")


def clear_outputs(outdir, globs):
    """Remove an earlier run's outputs (files matching ``globs``) from OUTDIR."""
    for pattern in globs:
        for path in glob.glob(os.path.join(outdir, pattern)):
            os.remove(path)


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


class OutdirLock:
    """Hold OUTDIR for this run (module docstring)."""

    def __init__(self, outdir):
        self.outdir = outdir
        self.lock = os.path.join(outdir, LOCK_NAME)
        self.created = False
        self.held = False

    def __enter__(self):
        self.created = not os.path.isdir(self.outdir)
        try:
            os.makedirs(self.outdir, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create output directory {self.outdir}: {exc.strerror or exc}") from None
        try:
            fd = os.open(self.lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            pid = self._owner()
            if pid is not None and pid != os.getpid() and _alive(pid):
                self._tidy()
                raise InputError(f"{self.outdir} is in use by another vfit run (pid {pid}); wait for it or choose "
                                 "another -o") from None
            # the run that held it is gone (killed): take it over
            tmp = f"{self.lock}.{os.getpid()}"
            with open(tmp, "w") as f:
                f.write(f"{os.getpid()}\n")
            os.replace(tmp, self.lock)
        else:
            with os.fdopen(fd, "w") as f:
                f.write(f"{os.getpid()}\n")
        self.held = True
        return self

    def _owner(self):
        try:
            with open(self.lock) as f:
                return int(f.read().split()[0])
        except (OSError, ValueError, IndexError):
            return None

    def _tidy(self):
        """Remove OUTDIR if this run created it and nothing is in it."""
        if self.created:
            try:
                os.rmdir(self.outdir)
            except OSError:
                pass

    def __exit__(self, *exc):
        if self.held and self._owner() == os.getpid():
            from vfit_engine.io.atomic import remove_orphans

            remove_orphans(self.outdir)  # an interrupted write's temporary file (see remove_orphans)
            try:
                os.remove(self.lock)
            except OSError:
                pass
        self.held = False
        self._tidy()
        return False
