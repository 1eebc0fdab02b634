"""A walking body: a looping gait cycle of the default rig, from normative gait kinematics.

::

    motion = walk_motion(model, speed=1.3, fps=30)     # a BVH Motion of one stride, Y up, metres
    posed = pose_body(model, verts, motion, frame=k)

**The curves.** Joint angles over one stride (0-100 %, from the right heel's initial contact) as published
for adults walking at natural cadence: sagittal hip, knee and ankle angles (Winter D. A., *Biomechanics and
Motor Control of Human Movement*, 4th ed., Wiley 2009, ch. 4 and appendix A, ensemble averages of level
walking), pelvic tilt, obliquity and rotation, and shoulder and elbow flexion of the arm swing (Perry J.,
Burnfield J. M., *Gait Analysis: Normal and Pathological Function*, 2nd ed., SLACK 2010, ch. 4-7). The
key points below are read off those normative curves at the listed percentages (peaks, zero crossings,
the events of the cycle: loading response 0-10 %, mid stance 30 %, toe off 60 %, peak swing knee
flexion ~72 %), and a periodic cubic spline runs through them; the left side is the right one half a
cycle later. They are approximations of ensemble means (±1 SD in those sources is 5-8 degrees), good for a
garment that must move as a walking body does, not for clinical use.

**Speed.** The cycle time comes from the speed through cadence: 100 steps/min at 1.0 m/s rising to 120 at
1.6 m/s (natural cadence ~105-115 steps/min at 1.2-1.4 m/s in the same sources), clamped to 80-130; the
joint curves are those of natural cadence at any speed.

**Axes.** vfit's frame (+Y up, +Z front, +X the body's left); a bone's rotation is relative to its parent
in world-aligned frames (as a BVH's), so flexion of the hip (thigh forward) is a negative rotation about X,
flexion of the knee (shank back) a positive one, dorsiflexion of the ankle (toes up) a negative one.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from vfit_engine.body.pose import rig_motion
from vfit_engine.body.segment import bone_positions
from vfit_engine.errors import InputError

#: Right-side key points (% of the stride, degrees). Hip: + flexion; knee: + flexion; ankle: + dorsiflexion.
HIP_FLEXION = ((0, 30), (10, 28), (30, 10), (50, -10), (60, -4), (73, 22), (87, 33), (100, 30))
KNEE_FLEXION = ((0, 5), (15, 18), (40, 4), (60, 38), (72, 62), (85, 38), (97, 3), (100, 5))
ANKLE_DORSIFLEXION = ((0, 0), (7, -6), (30, 5), (48, 10), (62, -18), (75, -3), (90, 1), (100, 0))
#: Pelvis (degrees): tilt (+ anterior, about its mean), obliquity (+ right side up), rotation (+ right side
#: forward).
PELVIC_TILT = ((0, 0), (12, 1.5), (30, -1), (50, 0), (62, 1.5), (80, -1), (100, 0))
PELVIC_OBLIQUITY = ((0, 0), (15, 4), (35, 1), (50, 0), (65, -4), (85, -1), (100, 0))
PELVIC_ROTATION = ((0, 4), (25, 0), (50, -4), (75, 0), (100, 4))
#: Right arm: shoulder flexion (+ forward) against the right leg, elbow flexion.
SHOULDER_FLEXION = ((0, -12), (25, 0), (50, 12), (75, 0), (100, -12))
ELBOW_FLEXION = ((0, 20), (50, 38), (100, 20))
#: Cadence (steps/min) at 1.0 and 1.6 m/s, and its clamp.
CADENCE = ((1.0, 100.0), (1.6, 120.0))
CADENCE_RANGE = (80.0, 130.0)
#: Bones driven (rig names; ``.R`` / ``.L``), and their curves with a sign in vfit's axes:
#: (bone, curve, axis "X"/"Y"/"Z", sign).
LEG_ARM = (("upperleg01", HIP_FLEXION, "X", -1.0), ("lowerleg01", KNEE_FLEXION, "X", 1.0),
           ("foot", ANKLE_DORSIFLEXION, "X", -1.0), ("upperarm01", SHOULDER_FLEXION, "X", -1.0),
           ("lowerarm01", ELBOW_FLEXION, "X", -1.0))


def curve(points, phase):
    """The periodic cubic spline through ``points`` ((%, degrees), first and last equal) at ``phase`` (0..1,
    array), degrees."""
    x, y = np.array(points, dtype=np.float64).T
    return CubicSpline(x / 100.0, y, bc_type="periodic")(np.mod(phase, 1.0))


def stride_time(speed):
    """Seconds per stride (two steps) at ``speed`` m/s (module docstring)."""
    (v0, c0), (v1, c1) = CADENCE
    cadence = np.clip(c0 + (c1 - c0) * (float(speed) - v0) / (v1 - v0), *CADENCE_RANGE)
    return 2.0 * 60.0 / cadence


def rest_angles(heads):
    """Each driven bone's flexion in the rig's rest pose (degrees, right side; the curves are measured
    from the straight limb, the rig's rest is MakeHuman's A pose: elbows ~38 degrees bent, hips ~5)."""
    def direction(a, b):
        v = heads[b + ".R"][0] - heads[a + ".R"][0]
        return v / np.linalg.norm(v)

    def forward(v):  # forward angle from straight down, in the side view (+Z front, +Y up)
        return np.degrees(np.arctan2(v[2], -v[1]))

    thigh, shank = direction("upperleg01", "lowerleg01"), direction("lowerleg01", "foot")
    upper, fore = direction("upperarm01", "lowerarm01"), direction("lowerarm01", "wrist")
    return {"upperleg01": forward(thigh), "lowerleg01": forward(thigh) - forward(shank),
            "lowerarm01": np.degrees(np.arccos(np.clip(upper @ fore, -1.0, 1.0))), "foot": 0.0, "upperarm01": 0.0}


def walk_angles(phase, rest=None):
    """Joint angles at ``phase`` (f,) of the stride, relative to the rig's rest pose (``rest``:
    :func:`rest_angles`; None: the curves as published): dict (bone name -> (f, 3) degrees about X, Y, Z)."""
    phase = np.asarray(phase, dtype=np.float64)
    rest = rest or {}
    out = {}
    for side, shift in ((".R", 0.0), (".L", 0.5)):
        for bone, points, axis, sign in LEG_ARM:
            a = np.zeros((phase.size, 3))
            a[:, "XYZ".index(axis)] = sign * (curve(points, phase - shift) - rest.get(bone, 0.0))
            out[bone + side] = a
    pelvis = np.zeros((phase.size, 3))
    pelvis[:, 0] = -curve(PELVIC_TILT, phase)  # anterior tilt tips the top forward: negative about X
    pelvis[:, 2] = curve(PELVIC_OBLIQUITY, phase)  # right side up: positive about Z (+X is the body's left)
    pelvis[:, 1] = -curve(PELVIC_ROTATION, phase)  # right side forward: negative about Y
    out["root"] = pelvis
    return out


def walk_motion(model, speed=1.3, fps=30.0, cycles=1):
    """One or more strides of walking as a BVH :class:`~vfit_engine.io.bvh.Motion` of the rig (Y up, metres;
    frames at ``fps``, looping: frame ``k`` and ``k + frames`` are the same pose).

    Every rig bone is a joint (rest offsets from the default female body; :func:`vfit_engine.body.pose.
    pose_body` places the joints on the body it poses and takes only the rotations), with channels
    ``Zrotation Xrotation Yrotation``; the bones the gait does not drive stay at rest.
    """
    if not (np.isfinite(speed) and 0.3 <= speed <= 2.5):
        raise InputError(f"walking speed {speed} m/s is not a walk; use 0.3-2.5 m/s")
    period = stride_time(speed)
    n = max(int(round(period * fps)), 2)
    phase = np.arange(n * int(cycles)) / n
    angles = walk_angles(phase, rest_angles(bone_positions(model, model.default_verts("female"))))
    return rig_motion(model, angles, n_frames=phase.size, fps=fps)
