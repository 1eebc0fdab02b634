"""The motion of an animated fitting: a clip of the rig's rotations over time, blended in from the A pose, and
the body (and the garment's pins) posed by it frame after frame.

::

    clip = load_clip(model, "walk", speed=1.3)              # or a BVH file: load_clip(model, "sit01.bvh")
    poser = Poser(model, body.verts, pin_points=targets, pin_body=body.surface)
    rot, root = clip.sample(t, blend=min(t / 0.5, 1.0))     # (b, 3, 3) local rotations, (3,) m
    verts, pins = poser.pose(rot, root)

**Clips.** ``walk`` is the built-in stride (:func:`vfit_engine.body.gait.walk_motion`), looping; a BVH file
names the default rig's bones (MakeHuman's poses) or CMU's skeleton (the CMU motion-capture database's BVH
conversions, ``cmu_mb``'s names among them): :data:`CMU_JOINTS` maps them, a JSON file of ``{"file joint":
"rig bone"}`` maps any other. A clip samples its file at any time (rotations interpolated between frames);
a one-frame file is a still pose; a clip with more frames plays once and holds its last frame.

**Another skeleton's rest pose.** A BVH's rotations turn its own rest skeleton; CMU's rests in a T pose,
the rig in MakeHuman's A pose (arms ~45 degrees down). For a mapped file each mapped bone's world rotation is
the file joint's times the rotation that turns the rig's rest bone onto the file's rest bone
(``G_rig = G_file A``, ``A d_rig = d_file``), so the bones point where the file's do; the rig's own names
need no such step.

**Root motion.** The body moves in place (the file's root translation is dropped, as the seed system did)
unless ``travel``: then the walk goes forward at its speed and a file's root moves as recorded (scaled from
the file's skeleton to this body's legs).

**Blending.** ``sample(t, blend=w)`` turns every bone by ``w`` of its rotation (the rotation vector scaled:
the shortest way from the rest pose), so an animation starts from the A pose the garment was draped in.

**Posing.** :class:`Poser` keeps what does not change from frame to frame (the body's joints, the rig's
order, the skin weights) and skins the body by dual quaternions; the pins are skinned with the weights of
the body point under them (the weights of its triangle's corners, blended by barycentric coordinates), so
they follow the body as its surface does.
"""
from __future__ import annotations

import copy
import json
import os
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.spatial.transform import Rotation

from vfit_engine.body.gait import walk_motion
from vfit_engine.body.model import N_BODY
from vfit_engine.body.pose import body_joints, bone_rotations, file_axes, joint_naming, rig_order, skinning_for
from vfit_engine.body.segment import bone_positions
from vfit_engine.body.skinning import Skinning
from vfit_engine.collide.body_mesh import MeshCollider
from vfit_engine.errors import InputError
from vfit_engine.io.bvh import read_bvh

#: CMU motion-capture skeletons (the BVH conversions of the CMU database, and the MotionBuilder-friendly
#: ``cmu_mb`` names) -> the default rig's bones. A joint carries the rotation of the bone that starts at it:
#: CMU's ``LeftUpLeg`` sits at the hip and turns the thigh, as the rig's ``upperleg01.L`` does.
CMU_JOINTS = {
    "Hips": "root", "LowerBack": "spine05", "Spine": "spine03", "Spine1": "spine01", "Spine2": "spine01",
    "Neck": "neck01", "Neck1": "neck02", "Head": "head",
}
for _side, _s in (("Left", "L"), ("Right", "R")):
    CMU_JOINTS.update({f"{_s}HipJoint": f"pelvis.{_s}", f"{_side}UpLeg": f"upperleg01.{_s}",
                       f"{_side}Leg": f"lowerleg01.{_s}", f"{_side}Foot": f"foot.{_s}",
                       f"{_side}ToeBase": f"toe1-1.{_s}", f"{_side}Shoulder": f"clavicle.{_s}",
                       f"{_side}Arm": f"upperarm01.{_s}", f"{_side}ForeArm": f"lowerarm01.{_s}",
                       f"{_side}Hand": f"wrist.{_s}"})
del _side, _s


@dataclass
class Clip:
    """A motion of the rig (module docstring).

    Attributes
    ----------
    rotations : (f, b, 3, 3) float64
        Each frame's local bone rotations in vfit's axes, ``model.bone_names`` order.
    root : (f, 3) float64, m
        The root's translation in each frame (zero unless travelling).
    frame_time : float, s
    looping : bool
        The walk: frame ``f`` is frame 0 again; otherwise the last frame holds.
    description : dict
        What the clip is (for the report).
    frames : int
        Frames of the whole clip when only its first ``f`` were posed (``load_clip(until=...)``: later times
        hold frame ``f - 1``); 0: ``f``.
    """

    rotations: np.ndarray
    root: np.ndarray
    frame_time: float
    looping: bool
    description: dict
    frames: int = 0

    @property
    def duration(self):
        """Seconds the clip plays before it loops or holds."""
        return ((self.frames or len(self.rotations)) - (0 if self.looping else 1)) * self.frame_time

    def sample(self, t, blend=1.0):
        """((b, 3, 3) local rotations, (3,) m root translation) at ``t`` s, turned ``blend`` (0..1) of the way
        from the rest pose."""
        f = len(self.rotations)
        x = max(float(t), 0.0) / self.frame_time
        if self.looping:
            x = x % f
            k0, a = int(x), x - int(x)
            k1 = (k0 + 1) % f
            laps = int(max(float(t), 0.0) / self.frame_time // f)
            root0 = self.root[k0] + laps * self._lap()
            root1 = self.root[k1] + (laps + (1 if k1 < k0 else 0)) * self._lap()
        else:
            x = min(x, f - 1.0)
            k0 = int(x)
            k1, a = min(k0 + 1, f - 1), x - k0
            root0, root1 = self.root[k0], self.root[k1]
        r0 = Rotation.from_matrix(self.rotations[k0])
        rel = (r0.inv() * Rotation.from_matrix(self.rotations[k1])).as_rotvec()
        rot = r0 * Rotation.from_rotvec(a * rel)
        if blend < 1.0:
            rot = Rotation.from_rotvec(float(blend) * rot.as_rotvec())
        return rot.as_matrix(), float(blend) * ((1.0 - a) * root0 + a * root1)

    def _lap(self):
        """The root's travel over one loop of a looping clip (m)."""
        f = len(self.root)
        step = self.root[-1] - self.root[-2] if f > 1 else np.zeros(3)
        return self.root[-1] - self.root[0] + step


def load_clip(model, source, speed=1.3, fps=30.0, travel=False, joint_map=None, until=None):
    """The clip ``source``: ``"walk"`` or a BVH file (module docstring).

    Parameters
    ----------
    model : BodyModel
    source : str
        ``"walk"`` or a path.
    speed : float, m/s
        The walk's speed.
    fps : float
        The walk's frame rate (a file keeps its own).
    travel : bool
        Keep the root's translation.
    joint_map : str, dict or None
        A JSON file or dict of file joint -> rig bone; None: the rig's names, else :data:`CMU_JOINTS`.
    until : float or None, s
        The last time the clip will be sampled at: a file's frames after it are not posed, so a long capture
        costs what the animation plays (:attr:`Clip.frames` keeps its length). None: every frame.

    Raises
    ------
    InputError
        A file that does not exist, does not read as BVH, or names too few of the rig's bones.
    """
    if source == "walk":
        motion = walk_motion(model, speed=speed, fps=fps)
        rot = np.stack([_rig_rotations(model, motion, k, np.eye(3)) for k in range(len(motion.frames))])
        root = np.zeros((len(rot), 3))
        if travel:
            root[:, 2] = speed * np.arange(len(rot)) / fps  # forward, +Z
        return Clip(rot, root, motion.frame_time, True, dict(motion="walk", speed_m_s=speed, frames=len(rot),
                                                              fps=fps, source="built-in gait (Winter 2009)"))
    if not os.path.isfile(source):
        raise InputError(f"motion file not found: {source} (or use --motion walk)")
    motion = read_bvh(source)
    if len(motion.frames) == 0:
        raise InputError(f"{source}: the BVH file has no frames")
    mapping, how = _joint_map(model, motion, source, joint_map)
    renamed = _renamed(motion, mapping)
    axes = file_axes(motion)
    n = len(motion.frames)
    posed = n if until is None else min(n, int(max(until, 0.0) / motion.frame_time) + 2)  # sample's k0 and k1
    rot = np.stack([_rig_rotations(model, renamed, k, axes) for k in range(posed)])
    if how != "rig names":
        rot = _retarget(model, renamed, axes, rot)
    root = np.zeros((len(rot), 3))
    if travel:
        root = _root_travel(model, motion, axes, posed)
    named = sorted(set(model.bone_names) & set(renamed.names))
    return Clip(rot, root, motion.frame_time, False,
                dict(motion=os.path.abspath(source), frames=n, fps=1.0 / motion.frame_time, joints=how,
                     bones_posed=len(named)), frames=n)


def _rig_rotations(model, motion, frame, axes):
    """(b, 3, 3) the rig's local rotations in vfit's axes from ``motion``'s joints named as rig bones."""
    return bone_rotations(model, motion, frame, axes)


def _joint_map(model, motion, source, joint_map):
    """(file joint -> rig bone, how the names were read)."""
    rig = set(model.bone_names)
    if joint_map is not None:
        if isinstance(joint_map, (str, os.PathLike)):
            try:
                with open(joint_map, encoding="utf-8") as fh:
                    joint_map = json.load(fh)
            except (OSError, ValueError) as exc:
                raise InputError(f"{joint_map}: not a JSON joint map ({exc})") from None
        if not isinstance(joint_map, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                                      for k, v in joint_map.items()):
            raise InputError("a joint map must be a JSON object of file joint name -> rig bone name")
        bad = sorted(v for v in joint_map.values() if v not in rig)
        if bad:
            raise InputError(f"joint map: {bad[0]!r} is not a bone of the default rig (e.g. upperleg01.L)")
        return dict(joint_map), "joint map"
    how = joint_naming(model, motion, source, {"CMU names": CMU_JOINTS},
                       fix="give --joint-map FILE.json ({\"file joint\": \"rig bone\"})")
    return ({} if how == "rig names" else dict(CMU_JOINTS)), how


def _renamed(motion, mapping):
    """``motion`` with its joints renamed by ``mapping`` (unmapped joints keep names the rig does not have)."""
    if not mapping:
        return motion
    out = copy.copy(motion)
    out.names = [mapping.get(n, "~" + n) for n in motion.names]
    return out


def _retarget(model, motion, axes, rot):
    """The mapped bones' local rotations with the rest poses aligned (module docstring)."""
    pos = bone_positions(model, model.default_verts("female"))
    order, parent = rig_order(model)
    index = {n: b for b, n in enumerate(model.bone_names)}
    rest = motion.rest_positions() @ axes.T
    children = {}
    for j, p in enumerate(motion.parents):
        children.setdefault(int(p), []).append(j)
    align = {}
    for j, name in enumerate(motion.names):
        b = index.get(name)
        if b is None or j not in children or parent[b] < 0:
            continue
        head, tail = (np.asarray(x, dtype=np.float64) for x in pos[name])
        # a bone runs from its joint to a child joint, in the file and in the rig alike: the child that is a rig
        # bone too, nearest the rig bone's tail (a spine's top joint has the neck and the shoulders as
        # children); else the file's child nearest the rig bone's direction, against the rig bone itself
        mapped = [c for c in children[j] if motion.names[c] in index]
        if mapped:
            c = min(mapped, key=lambda c: float(np.linalg.norm(np.asarray(pos[motion.names[c]][0]) - tail)))
            d_rig = np.asarray(pos[motion.names[c]][0]) - head
        else:
            d_rig = tail - head
            c = max(children[j], key=lambda c: float((rest[c] - rest[j]) @ d_rig)
                    / max(float(np.linalg.norm(rest[c] - rest[j])), 1e-300))
        d_file = rest[c] - rest[j]
        if np.linalg.norm(d_file) > 0 and np.linalg.norm(d_rig) > 0:
            align[b] = _turn(d_rig, d_file)
    out = np.empty_like(rot)
    glob = np.empty((len(model.bone_names), 3, 3))
    file_glob = np.empty_like(glob)
    for f in range(len(rot)):
        for b in order:  # the file's world rotations along the rig's chain (unmapped bones: identity)
            p = parent[b]
            file_glob[b] = rot[f, b] if p < 0 else file_glob[p] @ rot[f, b]
            glob[b] = file_glob[b] @ align[b] if b in align else (file_glob[b] if p < 0 else glob[p])
            out[f, b] = glob[b] if p < 0 else glob[p].T @ glob[b]
    return out


def _turn(a, b):
    """(3, 3) the smallest rotation taking direction ``a`` to direction ``b``."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.clip(a @ b, -1.0, 1.0))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        ortho = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        return Rotation.from_rotvec(np.pi * ortho / np.linalg.norm(ortho)).as_matrix()
    return Rotation.from_rotvec(axis / s * np.arctan2(s, c)).as_matrix()


def _root_travel(model, motion, axes, count):
    """(count, 3) m: the file root's translation from its first frame in its first ``count`` frames, scaled from
    the file's legs to the body's."""
    rest = motion.rest_positions() @ axes.T
    file_height = float(rest[:, 1].max() - rest[:, 1].min())
    joints = body_joints(model, model.default_verts("female"))
    body_height = float(joints[:, 1].max() - joints[:, 1].min())
    trans = np.stack([motion.local_translations(k)[0] for k in range(count)]) @ axes.T
    return (trans - trans[0]) * (body_height / max(file_height, 1e-12))


class Poser:
    """Poses one body (and points bound to it) by the rig, frame after frame (module docstring).

    Parameters
    ----------
    model : BodyModel
    verts : (19158, 3) or (13380, 3) float64, m
        The body (with its helpers the joints come from them).
    pin_points : (p, 3) float64, m, or None
        Points near the body (the garment's pins) to pose with it.
    method : {"dqs", "lbs"}
    """

    def __init__(self, model, verts, pin_points=None, method="dqs"):
        verts = np.ascontiguousarray(verts, dtype=np.float64)
        self.model, self.method = model, method
        self.joints = body_joints(model, verts)
        self.order, self.parent = rig_order(model)
        self.rest = np.ascontiguousarray(verts[:N_BODY])
        self.skin = skinning_for(model, N_BODY)
        self._out = np.empty_like(self.rest)
        pts = np.zeros((0, 3)) if pin_points is None else np.ascontiguousarray(pin_points, dtype=np.float64)
        self.pin_rest = pts
        self.pin_skin = self._point_skinning(pts) if len(pts) else None

    def _point_skinning(self, points):
        """A :class:`Skinning` of ``points``: each takes the weights of the body point nearest to it."""
        tris = self.model.body_tris
        _, foot, _, tri = MeshCollider(self.rest, tris).query(points, max_out=np.inf, max_in=np.inf)
        corners = self.rest[tris[tri]]
        bary = _barycentric(foot, corners)
        bone, vertex, weight = self.model.skin
        keep = vertex < len(self.rest)
        w = sparse.csr_matrix((weight[keep], (vertex[keep], bone[keep])),
                              shape=(len(self.rest), len(self.model.bone_names)))
        pick = sparse.csr_matrix((bary.ravel(), (np.repeat(np.arange(len(points)), 3), tris[tri].ravel())),
                                 shape=(len(points), len(self.rest)))
        pw = (pick @ w).tocoo()
        return Skinning(pw.col, pw.row, pw.data, len(points), len(self.model.bone_names))

    def matrices(self, rotations, root=None):
        """(b, 3, 4) skinning matrices of the body posed by local ``rotations`` (b, 3, 3), its root moved by
        ``root`` (3,) m (:func:`vfit_engine.body.pose.pose_matrices`, with the rig's order kept)."""
        heads, parent = self.joints, self.parent
        glob = np.empty_like(rotations)
        posed = np.empty_like(heads)
        for b in self.order:
            p = parent[b]
            if p < 0:
                glob[b] = rotations[b]
                posed[b] = heads[b] if root is None else heads[b] + root
            else:
                glob[b] = glob[p] @ rotations[b]
                posed[b] = posed[p] + glob[p] @ (heads[b] - heads[p])
        return np.concatenate([glob, (posed - np.einsum("bij,bj->bi", glob, heads))[:, :, None]], axis=2)

    def pose(self, rotations, root=None):
        """((13380, 3) body, (p, 3) pins) m, posed; the body array is a new copy."""
        return self.skin_all(self.matrices(rotations, root))

    def skin_all(self, mats):
        """((13380, 3) body, (p, 3) pins) m skinned by the matrices ``mats`` (:meth:`matrices`)."""
        body = self.skin.deform(self.rest, mats, method=self.method, out=np.empty_like(self.rest))
        pins = (self.pin_skin.deform(self.pin_rest, mats, method=self.method) if self.pin_skin is not None
                else np.zeros((0, 3)))
        return body, pins


def _barycentric(p, corners):
    """(n, 3) barycentric coordinates of points ``p`` (n, 3) on triangles ``corners`` (n, 3, 3)."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (np.einsum("ij,ij->i", x, y) for x, y in ((v0, v0), (v0, v1), (v1, v1)))
    d20, d21 = np.einsum("ij,ij->i", v2, v0), np.einsum("ij,ij->i", v2, v1)
    den = np.where(np.abs(d00 * d11 - d01 * d01) > 0, d00 * d11 - d01 * d01, 1.0)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    bary = np.clip(np.stack([1.0 - v - w, v, w], axis=1), 0.0, 1.0)
    return bary / np.maximum(bary.sum(axis=1, keepdims=True), 1e-300)
