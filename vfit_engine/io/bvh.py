"""BVH (Biovision hierarchy) motion files: a reader, a writer and forward kinematics, NumPy only.

Holds
    :class:`Motion` (skeleton + channel values per frame), :func:`read_bvh` and :func:`write_bvh`.

Conventions
    * Joints are kept in file order (depth-first, a parent before its children); ``End Site``
      blocks are not joints, their offsets go to ``Motion.end_sites``. One ROOT per file.
    * Lengths are in the file's units (MakeHuman poses: decimetres), angles in degrees, time in s.
    * A joint's rotation channels compose in the order the CHANNELS line lists them:
      ``Zrotation Xrotation Yrotation`` gives ``R = Rz @ Rx @ Ry`` (intrinsic rotations, scipy's
      ``Rotation.from_euler("ZXY", angles, degrees=True)``), right-handed, for column vectors.
    * A joint's local transform maps its frame into its parent's:
      ``v_parent = T(offset + position channels) @ R @ v_local``; world = parent world @ local.
    * Position channels add to OFFSET (they do not replace it), whichever joint carries them.
    * Values are written with the shortest digits that read back to the same float64, so a
      read -> write -> read round trip is exact.
    * A file is read line by line, never whole, and capped like a mesh (:data:`MAX_BVH_FRAMES`,
      :data:`MAX_BVH_JOINTS`): a hostile ``Frames: 1000000`` is refused at its header line, and
      ``read_bvh(path, frame=k)`` keeps one frame of a long file.
"""
from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vfit_engine.errors import InputError
from vfit_engine.io.atomic import atomic_write

#: channel name -> (kind, axis); kind 0 = position, 1 = rotation; axis 0, 1, 2 = X, Y, Z.
CHANNELS = {f"{a}{kind}": (k, i) for k, kind in enumerate(("position", "rotation")) for i, a in enumerate("XYZ")}
_CANONICAL = {name.lower(): name for name in CHANNELS}
#: Most frames vfit reads from a BVH file (a cap against absurd inputs, as ``io.mesh.MAX_VERTS`` for meshes):
#: over 4 minutes at CMU's 120 frames per second, 16 at 30; a full-rig file this long holds 29 M values (235 MB).
MAX_BVH_FRAMES = 30_000
#: Most joints vfit reads from a BVH file: the default rig has 163, CMU's skeleton 31.
MAX_BVH_JOINTS = 1_000
#: Longest line read from a BVH file, characters (a frame of the full rig, 978 values, is about 10,000).
_MAX_LINE = 1 << 20


@dataclass
class Motion:
    """A skeleton and the values of its channels over ``f`` frames.

    Attributes
    ----------
    names : list of str, (j,)
        Joint names in file order (depth-first); End Sites are not joints.
    parents : (j,) int array
        Index of each joint's parent, ``-1`` for the root (index 0); ``parents[i] < i``.
    offsets : (j, 3) float64
        OFFSET of each joint from its parent, file units.
    channels : list of tuple of str, (j,)
        Channel names of each joint in file order, e.g. ``("Zrotation", "Xrotation", "Yrotation")``.
    end_sites : dict int -> (3,) float64
        Joint index -> OFFSET of the End Site inside that joint.
    frames : (f, c) float64
        All channel values of each frame, joints in order, ``c = sum(len(ch) for ch in channels)``;
        positions in file units, rotations in degrees.
    frame_time : float
        Seconds between frames.
    """

    names: list
    parents: np.ndarray
    offsets: np.ndarray
    channels: list
    end_sites: dict = field(default_factory=dict)
    frames: np.ndarray = field(default_factory=lambda: np.zeros(0))
    frame_time: float = 1.0 / 30.0

    def __post_init__(self):
        self.names = list(self.names)
        self.parents = np.asarray(self.parents, dtype=np.intp).reshape(-1)
        self.offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        self.channels = [tuple(ch) for ch in self.channels]
        self.end_sites = {int(k): np.asarray(v, dtype=np.float64).reshape(3) for k, v in self.end_sites.items()}
        self.frames = np.asarray(self.frames, dtype=np.float64)
        if self.frames.ndim < 2 and self.frames.size == 0:  # "no frames" still needs its c columns
            self.frames = self.frames.reshape(0, sum(map(len, self.channels)))
        self.frame_time = float(self.frame_time)
        self.check()

    def check(self):
        """Raise ValueError when the fields disagree with each other (a caller's bug, not a file's)."""
        j, width = len(self.names), sum(map(len, self.channels))
        if j == 0 or self.parents.shape != (j,) or self.offsets.shape != (j, 3) or len(self.channels) != j:
            raise ValueError(f"Motion needs j >= 1 names, (j,) parents, (j, 3) offsets, j channel tuples; got "
                             f"{j}, {self.parents.shape}, {self.offsets.shape}, {len(self.channels)}")
        if self.parents[0] != -1 or np.any(self.parents[1:] < 0) or np.any(self.parents >= np.arange(j)):
            raise ValueError("Motion.parents must be -1 for joint 0 only and parents[i] < i for the others")
        if any(c not in CHANNELS or ch.count(c) > 1 for ch in self.channels for c in ch):
            raise ValueError(f"Motion.channels: use names from {list(CHANNELS)}, each at most once per joint")
        if self.frames.ndim != 2 or self.frames.shape[1] != width or not set(self.end_sites) <= set(range(j)):
            raise ValueError(f"Motion.frames must be (f, {width}) and end_sites keys joint indices")

    def channel_slices(self):
        """Columns of ``frames`` that belong to each joint: a list of ``j`` slices."""
        stops = np.cumsum([len(ch) for ch in self.channels])
        return [slice(int(stop) - len(ch), int(stop)) for stop, ch in zip(stops, self.channels)]

    def _gather(self, kind, frame):
        """(j, 3) values and axes of each joint's position (kind 0) or rotation (kind 1) channels in
        file order. Missing slots get 0 (about X), the identity, so no joint needs a special case."""
        cols = np.full((len(self.names), 3), self.frames.shape[1], dtype=np.intp)  # the appended 0
        axes = np.zeros((len(self.names), 3), dtype=np.intp)
        for i, (sl, ch) in enumerate(zip(self.channel_slices(), self.channels)):
            found = [(sl.start + n, CHANNELS[c][1]) for n, c in enumerate(ch) if CHANNELS[c][0] == kind]
            for slot, (col, axis) in enumerate(found):
                cols[i, slot], axes[i, slot] = col, axis
        return np.append(self.frames[frame], 0.0)[cols], axes

    def local_rotations(self, frame):
        """Rotation matrix of each joint relative to its parent, for one frame.

        Parameters
        ----------
        frame : int
            Frame index (negative counts from the end).

        Returns
        -------
        (j, 3, 3) float64
            ``R = R_first @ R_second @ R_third`` in the order of the joint's CHANNELS line.
        """
        angles, axes = self._gather(1, frame)
        m = _axis_rotations(axes.reshape(-1), angles.reshape(-1)).reshape(-1, 3, 3, 3)
        return m[:, 0] @ m[:, 1] @ m[:, 2]

    def local_translations(self, frame):
        """(j, 3) float64: each joint's OFFSET plus its position channels in ``frame``, file units."""
        values, axes = self._gather(0, frame)
        shift = np.zeros((len(self.names), 3))
        np.add.at(shift, (np.arange(len(self.names))[:, None], axes), values)  # add: empty slots add 0
        return self.offsets + shift

    def global_transforms(self, frame):
        """(j, 4, 4) float64 world matrices of the joints in ``frame`` by forward kinematics.

        ``G[i] = G[parent] @ [[R_i, t_i], [0, 1]]``; ``G[i][:3, 3]`` is the joint's world position.
        """
        local = np.zeros((len(self.names), 4, 4))
        local[:, :3, :3] = self.local_rotations(frame)
        local[:, :3, 3] = self.local_translations(frame)
        local[:, 3, 3] = 1.0
        world = np.empty_like(local)
        for i, p in enumerate(self.parents):  # parents come first, so world[p] is ready
            world[i] = local[i] if p < 0 else world[p] @ local[i]
        return world

    def rest_positions(self):
        """(j, 3) float64 world positions with every channel zero: the sum of OFFSETs to the root."""
        pos = self.offsets.copy()
        for i, p in enumerate(self.parents):
            if p >= 0:
                pos[i] += pos[p]
        return pos


def _axis_rotations(axes, degrees):
    """(n, 3, 3) right-handed rotations by ``degrees`` (n,) about ``axes`` (n,) in {0, 1, 2} = X, Y, Z."""
    rad = np.radians(degrees)
    c, s = np.cos(rad), np.sin(rad)
    n = np.arange(len(axes))
    i, k = (axes + 1) % 3, (axes + 2) % 3  # the plane the axis turns, in right-handed order
    m = np.zeros((len(axes), 3, 3))
    m[n, axes, axes] = 1.0
    m[n, i, i], m[n, k, k], m[n, i, k], m[n, k, i] = c, c, -s, s
    return m


def _floats(fail, ln, tokens, what):
    """(n,) float64 of ``tokens`` (n,), or the InputError ``fail(ln, ...)`` naming the first bad one."""
    try:
        values = np.array(tokens, dtype=np.float64)  # C speed; the loop below only words an error
        if np.all(np.isfinite(values)):
            return values
    except ValueError:
        pass
    for n, t in enumerate(tokens):
        try:
            finite = np.isfinite(float(t))
        except ValueError:
            raise fail(ln, f"{what}: {t!r} is not a number; write plain decimal numbers") from None
        if not finite:
            raise fail(ln, f"{what}: {t!r} (value {n + 1}) is not finite; replace NaN/inf with a finite number")
    return np.array([float(t) for t in tokens])  # numpy refused what Python accepts, e.g. "1_000"


class _Hierarchy:
    """The HIERARCHY section read line by line; one method per keyword keeps each one short."""

    def __init__(self, path):
        self.path, self.names, self.parents, self.lines, self.index = path, [], [], [], {}  # index: name -> joint
        self.offsets, self.channels, self.end_sites = [], [], {}
        self.stack = []  # open blocks: a joint index, or "end" for an End Site
        self.header = None  # (what, line, block) of a ROOT/JOINT/End Site whose "{" has not come yet

    def fail(self, ln, why):
        return InputError(f"{self.path}:{ln}: {why}")

    def joint(self, ln, key, tok):
        name, top = " ".join(tok[1:-1] if tok[-1] == "{" else tok[1:]), (self.stack[-1] if self.stack else None)
        if not name or (key == "ROOT") == bool(self.names) or key == "JOINT" and not isinstance(top, int):
            raise self.fail(ln, f"'{' '.join(tok)}' out of place; a file has one 'ROOT name' and every "
                                "'JOINT name' sits inside the ROOT's or another joint's braces")
        if name in self.index:
            first = self.lines[self.index[name]]
            raise self.fail(ln, f"joint {name!r} already named on line {first}; rename one")
        if len(self.names) == MAX_BVH_JOINTS:
            raise self.fail(ln, f"more than {MAX_BVH_JOINTS} joints, the limit (a body's rig has a few hundred at "
                                "most); check the file, or remove the joints no body needs")
        self.index[name] = len(self.names)
        self.parents.append(-1 if key == "ROOT" else top)
        self.names.append(name), self.lines.append(ln), self.offsets.append(None), self.channels.append(None)
        self.header = (f"{key} {name}", ln, len(self.names) - 1)
        self.braces(ln, tok[-1:] if tok[-1] == "{" else [])

    def end_site(self, ln, tok):
        top = self.stack[-1] if self.stack else None
        if tok[1:2] != ["Site"] or not isinstance(top, int) or top in self.end_sites:
            raise self.fail(ln, "expected one 'End Site' per joint, inside the joint's braces; fix or remove it")
        self.end_sites[top] = None
        self.header = ("End Site", ln, "end")
        self.braces(ln, tok[2:])

    def offset(self, ln, tok):
        if len(tok) != 4 or not self.stack:
            raise self.fail(ln, f"OFFSET needs 3 numbers inside a block, got {len(tok) - 1}; write 'OFFSET x y z'")
        xyz = _floats(self.fail, ln, tok[1:], "OFFSET")
        if self.stack[-1] == "end":
            self.end_sites[self.stack[-2]] = xyz
        else:
            self.offsets[self.stack[-1]] = xyz

    def channel_list(self, ln, tok):
        if not self.stack or self.stack[-1] == "end" or not tok[1:2] or not tok[1].isdecimal():
            raise self.fail(ln, "expected 'CHANNELS n name1 .. namen' inside a ROOT or JOINT block")
        if int(tok[1]) != len(tok) - 2:
            raise self.fail(ln, f"CHANNELS says {tok[1]} but lists {len(tok) - 2} names; make them agree")
        unknown = [t for t in tok[2:] if t.lower() not in _CANONICAL]
        if unknown or len({t.lower() for t in tok[2:]}) != len(tok) - 2:
            raise self.fail(ln, f"unknown or repeated channel {(unknown or tok[2:])[0]!r}; "
                                f"use each of {', '.join(CHANNELS)} at most once")
        self.channels[self.stack[-1]] = tuple(_CANONICAL[t.lower()] for t in tok[2:])

    def braces(self, ln, tok):
        for b in tok:
            if b == "{" and self.header is not None:
                self.stack.append(self.header[2])
                self.header = None
            elif b == "}" and self.stack and self.header is None:
                block = self.stack.pop()
                if block == "end" and self.end_sites[self.stack[-1]] is None or block != "end" and (
                        self.offsets[block] is None or self.channels[block] is None):
                    raise self.fail(ln, "the block closed here lacks its OFFSET (or a joint's CHANNELS) line; add it")
            else:
                raise self.fail(ln, f"unbalanced braces: unexpected {b!r}; every block is 'NAME {{ ... }}'")

    def parse(self, lines):
        """Read the numbered ``lines`` (after HIERARCHY) up to MOTION; return MOTION's line number."""
        last = 1  # the last line that is not blank: where an end-of-file error points
        for ln, line in lines:
            tok = line.split()
            if not tok:
                continue
            last = ln
            if self.header is not None and tok[0] != "{":
                raise self.fail(ln, f"expected '{{' after {self.header[0]} on line {self.header[1]}; open its block")
            if tok[0] in ("ROOT", "JOINT"):
                self.joint(ln, tok[0], tok)
            elif tok[0] in ("End", "OFFSET", "CHANNELS"):
                {"End": self.end_site, "OFFSET": self.offset, "CHANNELS": self.channel_list}[tok[0]](ln, tok)
            elif tok[0] in ("{", "}"):
                self.braces(ln, tok)
            elif tok[0] == "MOTION" and self.stack:
                raise self.fail(ln, f"unbalanced braces: {len(self.stack)} block(s) open at MOTION; add the '}}'")
            elif tok[0] == "MOTION":
                if not self.names:
                    raise self.fail(ln, "empty hierarchy: no ROOT before MOTION; add 'ROOT name { OFFSET .. }'")
                return ln
            else:
                raise self.fail(ln, f"unknown keyword {tok[0]!r} in the hierarchy; expected ROOT, JOINT, End Site, "
                                    "OFFSET, CHANNELS, braces or MOTION")
        why = f"unbalanced braces: {len(self.stack)} block(s) never closed" if self.stack else "no MOTION section"
        raise self.fail(last, f"{why} at the end of the file; complete the file")


def _filled(lines):
    """The (line number, line) of ``lines`` that are not blank."""
    return ((ln, line) for ln, line in lines if line.strip())


def _parse_frames(fail, lines, motion_line, width, frame, max_frames):
    """``(frames, frame_time)`` from the numbered ``lines`` after MOTION (on line ``motion_line``): every frame
    (f, width), or only ``frame`` (1, width) when it is not None; the file's other frame lines are counted, never
    split or kept, so the memory is one frame's."""
    heads = []
    for pattern in (r"Frames:\s*(\S+)", r"Frame\s+Time:\s*(\S+)"):
        ln, line = next(_filled(lines), (motion_line, ""))
        if not re.fullmatch(pattern, line.strip()):
            raise fail(ln, "MOTION must be followed by the lines 'Frames: N' and 'Frame Time: seconds'; add them")
        heads.append((ln, re.fullmatch(pattern, line.strip())[1]))
    (count_line, count), (time_line, time_text) = heads
    if not count.isdecimal():
        raise fail(count_line, f"'Frames: {count}' is not a whole number; write the number of frame lines")
    n = int(count)
    if n > max_frames:
        raise fail(count_line, f"'Frames: {n}' is more than the limit of {max_frames} frames; cut the motion to the "
                               "part you need (or keep every k-th frame and scale 'Frame Time' by k)")
    frame_time = _floats(fail, time_line, [time_text], "Frame Time")[0]
    if frame is not None and not 0 <= frame < n:
        raise fail(count_line, f"frame {frame} asked for, the file has {n}; "
                               + (f"ask for one of 0..{n - 1}" if n else "add a frame line"))
    frames = np.zeros((n if frame is None else 1, width))
    rows = _filled(lines)
    f = 0
    for ln, line in rows:
        if f == n:  # count what follows up to the cap: a huge file is not read to its end to word the error
            seen = n + 1 + sum(1 for _ in itertools.islice(rows, max(max_frames - n, 0)))
            said = f"more than {max_frames}" if seen > max_frames else str(seen)
            raise fail(count_line, f"'Frames: {n}' but {said} frame lines follow; make them agree")
        if frame is None or f == frame:
            tok = line.split()
            if len(tok) != width:
                raise fail(ln, f"frame {f + 1}: expected {width} values (one per channel), got {len(tok)}; "
                               "fix the line")
            frames[0 if frame is not None else f] = _floats(fail, ln, tok, f"frame {f + 1}")
        f += 1
    if f != n:
        raise fail(count_line, f"'Frames: {n}' but {f} frame lines follow; make them agree")
    return frames, float(frame_time)


def _numbered_lines(fh, path):
    """(line number from 1, line) of the open text file ``fh``, read one at a time (a file is never held whole);
    a line longer than :data:`_MAX_LINE` is refused before it fills the memory."""
    for ln in itertools.count(1):
        line = fh.readline(_MAX_LINE)
        if not line:
            return
        if len(line) == _MAX_LINE and not line.endswith("\n"):
            raise InputError(f"{path}:{ln}: a line longer than {_MAX_LINE} characters, more than a BVH file's "
                             "lines hold; check that this is a BVH file")
        yield ln, line


def read_bvh(path, frame=None, max_frames=MAX_BVH_FRAMES):
    """Read a BVH file: one ROOT, tabs or spaces, LF/CRLF/CR line ends, any channel order.

    Parameters
    ----------
    path : str or Path
    frame : int or None
        Read only this frame (0-based): the other frame lines are counted, not parsed or kept, so one frame of
        a long file costs the memory of one frame. None: every frame.
    max_frames : int
        A ``Frames:`` count above this raises InputError before any frame is read (:data:`MAX_BVH_FRAMES`).

    Returns
    -------
    Motion
        ``frames`` is (f, c), f = the ``Frames:`` count (may be 0), or (1, c) with ``frame``.

    Raises
    ------
    InputError
        One line, ``<path>:<line>: <what is wrong>; <how to fix it>``: missing file, not BVH,
        unbalanced braces, unknown channel, wrong number of values in a frame, a non-finite number,
        ``Frames:`` not matching the frame lines, empty hierarchy, more joints or frames than the caps
        (:data:`MAX_BVH_JOINTS`, ``max_frames``), ``frame`` not in the file.
    """
    try:  # -sig: drop a Windows BOM; newline=None reads LF, CRLF and CR line ends alike
        fh = open(path, encoding="utf-8-sig", errors="replace", newline=None)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc}); check the path") from None
    with fh:
        lines = _numbered_lines(fh, path)
        first, line = next(_filled(lines), (1, ""))
        if line.split() != ["HIERARCHY"]:
            raise InputError(f"{path}:{first}: not a BVH file: it must start with 'HIERARCHY'; check the file")
        h = _Hierarchy(path)
        motion_line = h.parse(lines)
        frames, frame_time = _parse_frames(h.fail, lines, motion_line, sum(map(len, h.channels)), frame, max_frames)
    return Motion(h.names, h.parents, np.array(h.offsets), h.channels, h.end_sites, frames, frame_time)


def _row(values):
    # shortest digits that read back to the same float64, never an exponent (some readers reject one)
    return " ".join(np.format_float_positional(v, unique=True, trim="-") for v in np.ravel(values))


def write_bvh(path, motion):
    """Write ``motion`` as a BVH file, atomically; :func:`read_bvh` reads back the same values.

    Parameters
    ----------
    path : str or Path
    motion : Motion
        Joints in depth-first order (each joint's subtree right after it), as BVH stores them.

    Raises
    ------
    InputError
        NaN/inf values, or a directory that cannot be written.
    ValueError
        Inconsistent arrays, joints not depth-first, or names that would not read back the same.
    """
    motion.check()
    if any(not n or n != " ".join(n.split()) or "{" in n or "}" in n for n in motion.names):
        raise ValueError("joint names must be non-empty, without braces, line breaks or repeated/edge spaces")
    values = [motion.offsets, motion.frames, [motion.frame_time], *motion.end_sites.values()]
    if not all(np.all(np.isfinite(v)) for v in values):
        raise InputError(f"refusing to write {path}: the motion has NaN or infinite values")
    out, stack = ["HIERARCHY"], []  # stack: the open joints, root first

    def close(k):  # End Site (if any) and closing brace of joint k, at depth len(stack)
        pad = "\t" * len(stack)
        if k in motion.end_sites:
            out.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {_row(motion.end_sites[k])}",
                        f"{pad}\t}}"])
        out.append(pad + "}")

    for i, name in enumerate(motion.names):
        while stack and stack[-1] != motion.parents[i]:
            close(stack.pop())
        if i and not stack:  # the parent was closed already: the file would nest i elsewhere
            raise ValueError(f"joint {i} ({name!r}) is not right after its parent's subtree; order them depth-first")
        pad, ch = "\t" * len(stack), motion.channels[i]
        out.extend([f"{pad}{'JOINT' if stack else 'ROOT'} {name}", pad + "{",
                    f"{pad}\tOFFSET {_row(motion.offsets[i])}", f"{pad}\tCHANNELS {len(ch)} {' '.join(ch)}".rstrip()])
        stack.append(i)
    while stack:
        close(stack.pop())
    out.extend(["MOTION", f"Frames: {len(motion.frames)}", f"Frame Time: {_row(motion.frame_time)}"])
    out.extend(_row(row) for row in motion.frames)
    with atomic_write(path, "w") as f:
        f.write("\n".join(out) + "\n")
