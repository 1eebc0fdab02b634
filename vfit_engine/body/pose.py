"""Posing a body with the default rig: the joints of that body, a BVH pose's rotations, skinning matrices.

::

    motion = read_bvh("sit01.bvh")
    posed = pose_body(model, body_verts, motion, frame=0)          # .verts, .heads (the posed joints)
    # its steps: bone_rotations(model, motion, 0) -> pose_matrices(model, body_verts, rotations) ->
    # skinning_for(model, n).deform(body_verts, mats, "dqs")

**Joints from the body.** A rig bone's head and tail are placed on *this* body as MakeHuman places them
(:func:`vfit_engine.body.segment.bone_positions`: the centre of a joint's helper cube, or a vertex), so a pose
fits any body vfit builds: a longer leg rotates about its own knee.

**Rotations from the BVH.** A BVH joint's frame is aligned with the world at rest (the file's OFFSETs are
world vectors), so its channel rotation R_j is a rotation in world axes, composed down the hierarchy:
``G_b = G_parent(b) @ R_b``. MakeHuman's poses are written Z up in decimetres; vfit's frame is Y up in
metres (+Z front): a file vector (x, y, z) is (x, z, -y) here (:data:`Z_UP`; its fit of the poses' rest
skeleton to vfit's default body: scale 0.104, median joint residual 16 mm), so a rotation becomes
``C R C^T``. A file that is Y up already (CMU, most mocap) is taken as it is (:func:`file_axes` tells them
apart by the rest skeleton's tallest extent). Only rotations are taken from the file; its bone lengths are
the body's.

**Skinning matrices.** Bone b's head moves with its parent: ``p_b = p_parent + G_parent (h_b - h_parent)``
(the root stays where it is: the body is posed in place, as the seed system did; ``root_translation``
moves it), and the bone's matrix maps a rest point x to ``G_b (x - h_b) + p_b``.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from vfit_engine.body.segment import bone_positions
from vfit_engine.body.skinning import Skinning
from vfit_engine.errors import InputError
from vfit_engine.io.bvh import Motion

#: File axes -> vfit axes for a Z-up file (MakeHuman's poses): (x, y, z) -> (x, z, -y).
Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: A BVH file naming at least this many of the rig's bones is in the rig's own names (MakeHuman's poses name
#: all 163); one naming fewer would leave most of the body in its rest pose and is refused.
RIG_NAMES_MIN = 10


def file_axes(motion):
    """The rotation taking the file's axes to vfit's: :data:`Z_UP` when the rest skeleton is tallest along
    Z, else the identity (a Y-up file)."""
    rest = motion.rest_positions()
    extent = rest.max(axis=0) - rest.min(axis=0)
    return Z_UP.copy() if int(np.argmax(extent)) == 2 else np.eye(3)


def rig_order(model):
    """Bone indices (``model.bone_names`` order) sorted so that every parent comes before its children, and
    each bone's parent index (-1 for the root)."""
    names = list(model.bone_names)
    index = {n: i for i, n in enumerate(names)}
    parent = np.array([index.get(model.rig[n].get("parent"), -1) if model.rig[n].get("parent") else -1
                       for n in names], dtype=np.int64)
    order, seen = [], set()

    def visit(i):
        if i in seen:
            return
        if parent[i] >= 0:
            visit(parent[i])
        seen.add(i)
        order.append(i)

    for i in range(len(names)):
        visit(i)
    return np.array(order, dtype=np.int64), parent


def joint_naming(model, motion, source, namings=None, fix="rename its joints to the rig's bones"):
    """How ``motion``'s joints name the rig's bones: ``"rig names"`` when at least :data:`RIG_NAMES_MIN` of them
    are bones of the rig, else the first key of ``namings`` ({how: {file joint: rig bone}}, e.g. CMU's names)
    whose mapping knows as many. The one check of ``vfit pose`` and ``vfit animate``.

    Raises
    ------
    InputError
        ``source: ...; fix`` when no naming fits: how many joints each naming knows (the rig's bones among them
        named: a file's ``root`` is the rig's root bone), and the joints none knows.
    """
    joints, rig = set(motion.names), set(model.bone_names)
    known = {"rig names": rig, **{how: set(mapping) for how, mapping in (namings or {}).items()}}
    for how, names in known.items():
        if len(joints & names) >= RIG_NAMES_MIN:
            return how
    bones = [n for n in motion.names if n in rig]
    other = [n for n in motion.names if not any(n in names for names in known.values())]
    counts = [f"{len(bones)} are bones of the default rig" + (f" ({_listed(bones)})" if bones else "")]
    counts += [f"{len(joints & names)} are {how}" for how, names in known.items() if how != "rig names"]
    raise InputError(f"{source}: of its {len(motion.names)} joints {', '.join(counts)}"
                     + (f", and {_listed(other)} {'is' if len(other) == 1 else 'are'} neither" if other else "")
                     + f"; at least {RIG_NAMES_MIN} are needed to pose the body: {fix}")


def _listed(names, most=4):
    """``a, b, c, d, ...``: the first ``most`` of ``names``."""
    return ", ".join(names[:most]) + (", ..." if len(names) > most else "")


def bone_rotations(model, motion, frame=0, axes=None):
    """(b, 3, 3) each rig bone's local rotation in vfit's axes from ``motion`` at ``frame`` (identity for a
    bone the file does not name), ``model.bone_names`` order."""
    axes = file_axes(motion) if axes is None else np.asarray(axes, dtype=np.float64)
    local = motion.local_rotations(frame)
    out = np.tile(np.eye(3), (len(model.bone_names), 1, 1))
    joint = {n: j for j, n in enumerate(motion.names)}
    for b, name in enumerate(model.bone_names):
        j = joint.get(name)
        if j is not None:
            out[b] = axes @ local[j] @ axes.T
    return out


def body_joints(model, verts):
    """(b, 3) m: the rig's bone heads (joints) placed on the body ``verts``, ``model.bone_names`` order
    (:func:`vfit_engine.body.segment.bone_positions`); the same for every pose of that body."""
    pos = bone_positions(model, verts)
    return np.array([pos[n][0] for n in model.bone_names])


def pose_matrices(model, verts, rotations, root_translation=None, joints=None):
    """Skinning matrices of the body ``verts`` posed by local bone ``rotations`` (module docstring).

    Parameters
    ----------
    model : BodyModel
    verts : (19158, 3) or (13380, 3) float64, m
        The body (with its helper vertices the joints come straight from them).
    rotations : (b, 3, 3) float64
        Each bone's rotation relative to its parent, in vfit's axes (:func:`bone_rotations`).
    root_translation : (3,) float64, m, or None
    joints : (b, 3) float64, m, or None
        :func:`body_joints` of ``verts``, when already computed (posing one body in many frames).

    Returns
    -------
    (b, 3, 4) float64
        ``[G_b | p_b - G_b h_b]`` per bone, ``model.bone_names`` order: a rest point x of bone b goes to
        ``M_b[:, :3] @ x + M_b[:, 3]``.
    heads : (b, 3) float64, m
        The posed bone heads (joint positions).
    """
    heads = body_joints(model, verts) if joints is None else joints
    order, parent = rig_order(model)
    glob = np.zeros((len(heads), 3, 3))
    posed = np.zeros_like(heads)
    for b in order:
        p = parent[b]
        if p < 0:
            glob[b] = rotations[b]
            posed[b] = heads[b] + (0.0 if root_translation is None else np.asarray(root_translation, float))
        else:
            glob[b] = glob[p] @ rotations[b]
            posed[b] = posed[p] + glob[p] @ (heads[b] - heads[p])
    mats = np.concatenate([glob, (posed - np.einsum("bij,bj->bi", glob, heads))[:, :, None]], axis=2)
    return mats, posed


@dataclasses.dataclass
class PosedBody:
    """A posed body: ``verts`` (n, 3) m in the input's vertex order, ``heads`` (b, 3) m the posed joints
    (``model.bone_names`` order), ``named`` how many of the rig's bones the file posed (the others keep
    their parent's rotation)."""

    verts: np.ndarray
    heads: np.ndarray
    named: int


def skinning_for(model, n_verts):
    """The rig's :class:`~vfit_engine.body.skinning.Skinning` of the first ``n_verts`` vertices (the whole
    model with its helpers, or the 13,380 vertices of a body file)."""
    bone, vertex, weight = model.skin
    keep = vertex < n_verts
    return Skinning(bone[keep], vertex[keep], weight[keep], n_verts, len(model.bone_names))


def pose_body(model, verts, motion, frame=0, method="dqs", skinning=None, joints=None):
    """``verts`` (a body of ``model``'s topology, with or without its helper vertices) in the pose of
    ``motion`` at ``frame``, skinned by ``method`` ("dqs" or "lbs"); returns a :class:`PosedBody`.
    ``skinning`` (:func:`skinning_for`) and ``joints`` (:func:`body_joints`) are the body's, when
    already built (posing one body in many frames)."""
    verts = np.ascontiguousarray(verts, dtype=np.float64)
    rotations = bone_rotations(model, motion, frame)
    mats, heads = pose_matrices(model, verts, rotations, joints=joints)
    skinning = skinning or skinning_for(model, len(verts))
    named = len(set(model.bone_names) & set(motion.names))
    return PosedBody(skinning.deform(verts, mats, method=method), heads, named)


def rig_motion(model, angles=None, n_frames=1, fps=30.0):
    """A Y-up BVH :class:`~vfit_engine.io.bvh.Motion` of the rig itself: every bone a joint, parents first,
    offsets from the default female body (m), channels ``Zrotation Xrotation Yrotation``; all angles zero
    but ``angles`` (bone name -> (n_frames, 3) or (3,) degrees about X, Y, Z). :func:`pose_body` places the
    joints on the body it poses, so only the rotations of such a motion matter."""
    heads = body_joints(model, model.default_verts("female"))
    order, parent = rig_order(model)
    index = {b: i for i, b in enumerate(order)}
    names = [model.bone_names[b] for b in order]
    parents = np.array([index[parent[b]] if parent[b] >= 0 else -1 for b in order])
    offsets = np.array([heads[b] - (heads[parent[b]] if parent[b] >= 0 else 0.0) for b in order])
    frames = np.zeros((int(n_frames), 3 * len(names)))
    for name, a in (angles or {}).items():
        i = names.index(name)
        xyz = np.broadcast_to(np.asarray(a, dtype=np.float64), (int(n_frames), 3))
        frames[:, 3 * i:3 * i + 3] = xyz[:, [2, 0, 1]]  # the channels' order: Z, X, Y
    return Motion(names=names, parents=parents, offsets=offsets,
                  channels=[("Zrotation", "Xrotation", "Yrotation")] * len(names), frames=frames,
                  frame_time=1.0 / fps)
