"""A command's output directory: checked before any work, held by one run at a time, cleared of an earlier run.

``with OutdirLock(outdir):`` creates OUTDIR if it is missing, takes its lock (an ``flock`` on ``.vfit.lock``,
which records the run's pid, host and start time) and on leaving removes the temporary files an interrupted
atomic write left in it, releases it and removes OUTDIR again if this run created it and left nothing in it (an
early error leaves no empty directory behind). A second run into the same OUTDIR fails at once with
:class:`InputError` naming the first one's pid. The kernel releases the lock when its process ends, however it
ends: a lock file left by a killed run is not locked, and the next run takes it over (its recorded pid may by
now belong to another process: it is not asked).
"""
import glob
import os
import socket
import time

from vfit_engine.errors import InputError

try:
    import fcntl
except ImportError:  # Windows: msvcrt's byte-range lock, also released when the process ends
    fcntl = None
    import msvcrt

LOCK_NAME = ".vfit.lock"


def check_outdir(outdir):
    """Fail early, before any long computation, on an OUTDIR that cannot be written (a missing one is created
    and removed again)."""
    if os.path.exists(outdir) and not os.path.isdir(outdir):
        raise InputError(f"cannot write to {outdir}: not a directory")
    existing = os.path.abspath(outdir)
    while not os.path.exists(existing):  # created later with its parents: the nearest existing one decides
        existing = os.path.dirname(existing)
    if not os.path.isdir(existing):
        raise InputError(f"cannot create {outdir}: {existing} is not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"cannot write to {outdir}: permission denied")
    made = []
    missing = os.path.abspath(outdir)
    while not os.path.exists(missing):
        made.append(missing)
        missing = os.path.dirname(missing)
    try:  # what OutdirLock will create, created and removed now: a name too long, a file system without files
        os.makedirs(outdir, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create output directory {outdir}: {exc.strerror or exc}; choose another -o") from None
    finally:
        for d in made:  # deepest first
            try:
                os.rmdir(d)
            except OSError:
                pass


def check_outputs(outdir, globs, inputs, extra_outputs=()):
    """Refuse, before any work, a run that would delete or overwrite a file the user gave it, or that would
    write an output file where a directory is.

    The run removes an earlier run's outputs (the files of OUTDIR matching ``globs``) and writes its own
    there and to ``extra_outputs`` (``--json``): an input among them (the same file, also through a link)
    would be gone or replaced, so it is refused.

    Parameters
    ----------
    outdir : str or None
    globs : sequence of str
        The names the command writes into OUTDIR (``clear_outputs`` removes them); empty for a command
        without an OUTDIR.
    inputs : dict
        What the input is (``"garment"``, ``"--body"`` ...) -> its path, or None when not given.
    extra_outputs : sequence of str
        Other files the run writes (may be absent).
    """
    doomed = [p for pattern in globs for p in glob.glob(os.path.join(glob.escape(outdir), pattern))]
    for path in doomed:
        if os.path.isdir(path) and not os.path.islink(path):
            raise InputError(f"cannot write {path}: it is a directory; remove it or choose another -o")
    doomed += [p for p in extra_outputs if p and os.path.exists(p)]
    stats = {}
    for path in doomed:
        try:
            st = os.stat(path)
        except OSError:  # a dangling link: nothing of the user's behind it
            continue
        stats[(st.st_dev, st.st_ino)] = path
    for what, path in inputs.items():
        try:
            st = os.stat(path) if path else None
        except OSError:  # a missing input is reported where it is read
            continue
        if st is not None and (st.st_dev, st.st_ino) in stats:
            out = stats[(st.st_dev, st.st_ino)]
            same = "" if os.path.abspath(out) == os.path.abspath(path) else f" ({out})"
            raise InputError(f"{what} {path} is one of this run's outputs{same}, which it would delete or overwrite: "
                             "copy it elsewhere or choose another -o / --json")


def clear_outputs(outdir, globs):
    """Remove an earlier run's outputs (files matching ``globs``) from OUTDIR (``check_outputs`` has made sure
    that none is an input of this run or a directory)."""
    for pattern in globs:
        for path in glob.glob(os.path.join(glob.escape(outdir), pattern)):
            if not os.path.isdir(path):
                os.remove(path)


def _lock(fd):
    """Lock the open file ``fd`` without waiting; BlockingIOError when another process holds it."""
    if fcntl is not None:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # BlockingIOError when held
        return
    try:
        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except OSError:
        raise BlockingIOError("locked by another process") from None


def _take(lock):
    """Open and lock the file ``lock`` (created if missing); returns its descriptor, BlockingIOError when held.

    A run that lets go removes the file before it closes it; one that opened the file just before that would
    then lock a name no longer in the directory while a third run creates and locks a new file: so the lock
    counts only if the name still leads to the file locked."""
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            _lock(fd)
            if os.path.samestat(os.fstat(fd), os.stat(lock)):
                return fd
        except FileNotFoundError:  # removed between the lock and the stat: try the new one
            pass
        except OSError:
            os.close(fd)
            raise
        os.close(fd)


class OutdirLock:
    """Hold OUTDIR for this run (module docstring)."""

    def __init__(self, outdir):
        self.outdir = outdir
        self.lock = os.path.join(outdir, LOCK_NAME)
        self.created = False
        self.fd = None

    def __enter__(self):
        self.created = not os.path.isdir(self.outdir)
        try:
            os.makedirs(self.outdir, exist_ok=True)
        except OSError as exc:
            reason = exc.strerror or exc
            raise InputError(f"cannot create output directory {self.outdir}: {reason}; choose another -o") from None
        try:
            self.fd = _take(self.lock)
        except OSError as exc:
            self._tidy()
            if isinstance(exc, BlockingIOError):
                raise InputError(f"{self.outdir} is in use by another vfit run ({self._owner()}); wait for it or "
                                 "choose another -o") from None
            raise InputError(f"cannot lock {self.lock}: {exc.strerror or exc}") from None
        record = f"{os.getpid()} {socket.gethostname()} {time.strftime('%Y-%m-%dT%H:%M:%S%z')}\n".encode()
        os.ftruncate(self.fd, 0)
        os.write(self.fd, record)  # for people and for the message of a run refused
        return self

    def _owner(self):
        """'pid N' of the run holding the lock, from its record."""
        try:
            with open(self.lock) as f:
                words = f.read().split()
            return f"pid {int(words[0])}" + (f" on {words[1]}" if len(words) > 1 and words[1] != socket.gethostname()
                                             else "")
        except (OSError, ValueError, IndexError):  # being written: it holds the lock all the same
            return "pid unknown"

    def _tidy(self):
        """Remove OUTDIR if this run created it and nothing is in it."""
        if self.created:
            try:
                os.rmdir(self.outdir)
            except OSError:
                pass

    def __exit__(self, *exc):
        if self.fd is not None:
            from vfit_engine.io.atomic import remove_orphans

            remove_orphans(self.outdir)  # an interrupted write's temporary file (see remove_orphans)
            if fcntl is not None:  # removed while still held (see _take); Windows removes no open file
                _remove(self.lock)
            os.close(self.fd)
            self.fd = None
            if fcntl is None:
                _remove(self.lock)
        self._tidy()
        return False


def _remove(path):
    try:
        os.remove(path)
    except OSError:
        pass


#: The outputs a user opens, in the order the "wrote" line names them (the rest are counted, not listed).
OPENED = ("report.json", "preview.png", "drape.gif", "preview.gif", "scene.glb", "animation.glb", "final.obj",
          "final.ply", "final.glb")


def wrote_line(outdir, paths):
    """The line that says what a run wrote: its folder and the few files a user opens, the rest counted, e.g.
    ``wrote out/: report.json, scene.glb and final.obj (and 42 more: body.obj, fit.ply, 40 frame files)``."""
    names = [os.path.basename(p) for p in paths]
    opened = [n for n in OPENED if n in names]
    rest = [n for n in names if n not in opened]
    frames = [n for n in rest if n.startswith(("frame_", "body_")) and n[-8:-4].isdigit()]
    others = [n for n in rest if n not in frames] + ([f"{len(frames)} frame files"] if frames else [])
    head = f"wrote {os.path.join(outdir, '')}: " + _and(opened or others)
    if opened and rest:
        head += f" (and {len(rest)} more: {', '.join(others)})"
    return head


def _and(words):
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]
