"""Motion capture as the motion of a synthetic person (:mod:`mirrorgraph.synth`).

The bridge from a BVH take (:mod:`mirrorgraph.io.bvh`) to the body model:
:func:`body_joints` maps a CMU skeleton to the 25 joints of the synthetic body model
(:data:`~mirrorgraph.synth.body.FULL_JOINTS`; the mapping is in its docstring);
:func:`skeleton_height` measures the skeleton's standing height; :func:`load_motion`
drops a leading reference pose, resamples, maps, scales to metres (CMU:
``units x 0.0254 / 0.45``) and puts the floor at ``y = 0`` (:class:`MocapMotion`);
:meth:`MocapMotion.clip` cuts a number of frames (back and forth when the take is
shorter) and moves them into the body frame of
:func:`~mirrorgraph.synth.motion.generate_motion` (``x`` left, ``y`` up, ``z``
forward, the person over the origin and facing ``+z`` in the first frame);
:func:`motion_for_scene` returns that in units of height for
:func:`~mirrorgraph.synth.make_scene` (``motion=...``).

The CMU skeleton's rest pose already stands in that frame (Y up, the left hip at
``+x``, the toes towards ``+z``), so only a turn about ``y`` and a shift are needed; a
skeleton whose head is not above its hips in the rest pose is refused.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io.bvh import BvhMotion, axis_rotation, read_bvh
from .body import EXTRA_FRACTION, FOOT_OFFSETS, FULL_INDEX, FULL_JOINTS, HEAD_OFFSETS


# --------------------------------------------------------------------------- CMU -> body
#: Metres per CMU unit (the CMU ASF scale: inches / 0.45).
CMU_UNIT_M = 0.0254 / 0.45

#: File name of the CMU take shipped as package data (``mirrorgraph/data``).
CMU_EXAMPLE = "cmu_01_01.bvh"


def cmu_example_path() -> Path:
    """Path of the CMU motion-capture take shipped with mirrorgraph.

    ``mirrorgraph/data/cmu_01_01.bvh``: CMU Graphics Lab Motion Capture Database,
    subject 01, trial 01, 2,752 frames at 120 fps, CMU skeleton (the BVH conversion
    of facebookresearch/fairmotion's test data; source and licence in
    ``mirrorgraph/data/README.md``). The default take of the tests and benchmarks,
    for :func:`load_motion` and ``make_scene(motion=...)``.
    """
    return Path(str(files("mirrorgraph") / "data" / CMU_EXAMPLE))


#: Roles used by :func:`body_joints` -> joint names of the CMU skeleton (as in the
#: CMU BVH conversions, e.g. ``cmu_01_01.bvh``). The toe and head roles need an
#: End Site (or a first child) under them.
CMU_JOINT_NAMES: dict[str, str] = {
    "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg",
    "left_knee": "LeftLeg", "right_knee": "RightLeg",
    "left_ankle": "LeftFoot", "right_ankle": "RightFoot",
    "left_toe": "LeftToeBase", "right_toe": "RightToeBase",
    "left_shoulder": "LeftArm", "right_shoulder": "RightArm",
    "left_elbow": "LeftForeArm", "right_elbow": "RightForeArm",
    "left_wrist": "LeftHand", "right_wrist": "RightHand",
    "head": "Head",
}

#: Joint speeds above this (m/s) between the first frames are a jump to a
#: reference pose, not motion (see :func:`load_motion`).
MAX_JOINT_SPEED = 25.0


def _tip_offset(motion: BvhMotion, name: str) -> np.ndarray:
    """Rest offset of the segment that ``name`` rotates: its End Site or first child."""
    kids = [motion.index(c) for c in motion.children(name)]
    if not kids:
        raise InputError(f"joint {name!r} has no End Site or child: cannot tell the length "
                         "and direction of its segment", source=motion.source)
    ends = [k for k in kids if motion.end_site[k]]
    return motion.offsets[(ends or kids)[0]].copy()


def _resolve(motion: BvhMotion, names: dict[str, str]) -> dict[str, int]:
    missing = [f"{role} ({n!r})" for role, n in names.items() if not motion.has(n)]
    need = [r for r in CMU_JOINT_NAMES if r not in names]
    if need:
        raise ValueError(f"the joint-name map lacks the role(s) {', '.join(need)}")
    if missing:
        raise InputError("no joint for " + ", ".join(missing) + "; the file's joints are "
                         + ", ".join(motion.joint_names), source=motion.source)
    return {role: motion.index(n) for role, n in names.items()}


def skeleton_height(motion: BvhMotion, names: dict[str, str] | None = None) -> float:
    """Standing height of the skeleton in file units (floor to top of the head).

    ``(thigh + shank + height of the top of the head above the hip joints in the
    rest pose) / (1 - 0.039)``: straight vertical legs (the mean of both sides),
    the trunk and head as the rest pose holds them, the top of the head at the
    head's End Site, and the ankle above the floor by the body model's 0.039 of
    the height (a BVH skeleton has no heel).

    Raises:
        InputError: a joint is missing, or the skeleton is not Y-up (the head's
            top not above the hips in the rest pose).
    """
    J = _resolve(motion, CMU_JOINT_NAMES if names is None else names)
    rest = motion.rest_positions()
    leg = 0.0
    for s in ("left", "right"):
        leg += np.linalg.norm(rest[J[f"{s}_knee"]] - rest[J[f"{s}_hip"]])
        leg += np.linalg.norm(rest[J[f"{s}_ankle"]] - rest[J[f"{s}_knee"]])
    leg /= 2.0
    hip_y = (rest[J["left_hip"], 1] + rest[J["right_hip"], 1]) / 2.0
    top_y = rest[J["head"], 1] + _tip_offset(motion, motion.names[J["head"]])[1]
    if not top_y - hip_y > 0.5 * leg:
        raise InputError("the top of the head is not above the hips in the rest pose: "
                         "a Y-up skeleton standing upright is expected", source=motion.source)
    return float((leg + top_y - hip_y) / (1.0 - EXTRA_FRACTION["ankle_height"]))


def body_joints(motion: BvhMotion, positions: np.ndarray, rotations: np.ndarray,
                height: float, names: dict[str, str] | None = None) -> np.ndarray:
    """The 25 joints of :data:`~mirrorgraph.synth.body.FULL_JOINTS` from BVH poses.

    Args:
        motion: the skeleton (names, offsets).
        positions: ``(F, N, 3)`` world positions of its nodes (file units).
        rotations: ``(F, N, 3, 3)`` world rotations of its nodes.
        height: the subject's standing height in file units (scales the head and
            foot points), e.g. :func:`skeleton_height`.
        names: role -> joint name (default :data:`CMU_JOINT_NAMES`).

    Returns:
        ``(F, 25, 3)`` positions in the frame and units of ``positions``.

    The mapping (``H`` = height; offsets are the body model's,
    :data:`~mirrorgraph.synth.body.HEAD_OFFSETS` and ``FOOT_OFFSETS``, given for
    the left side, mirrored in ``x`` for the right):

    * shoulders, elbows, wrists = ``LeftArm``, ``LeftForeArm``, ``LeftHand`` (and
      right); hips, knees, ankles = ``LeftUpLeg``, ``LeftLeg``, ``LeftFoot``;
    * ``neck`` = midpoint of the shoulders and ``mid_hip`` = midpoint of the hips
      (the OpenPose definitions the body model uses; the CMU ``Hips`` root lies
      about 0.1 m above the hip joints and is not used);
    * heel = ankle + ``R_foot`` (heel offset) ``H``, ``R_foot`` the world
      rotation of ``LeftFoot`` (its rest frame is the body frame, the foot
      pointing forward);
    * big toe = the toe tip (``LeftToeBase``'s End Site) moved medially by
      0.010 ``H``; small toe = ``LeftToeBase`` + a quarter of the toe segment,
      moved laterally by 0.022 ``H``; both in the toe segment's frame (they bend
      with the toes) and lowered so that in the rest pose they lie 0.033 ``H``
      below the ankle, as in the body model;
    * eyes, ears, nose = head pivot + ``R_head`` (head offset) ``H``, where
      ``R_head`` is the world rotation of ``Head`` and the pivot lies 0.110 ``H``
      (the body model's pivot-to-vertex distance) below the head's End Site (the
      top of the head) along the head's axis: roughly the top of the neck.
      ``Neck1`` is not needed: the head segment's pose carries the face.
    """
    J = _resolve(motion, CMU_JOINT_NAMES if names is None else names)
    P = np.asarray(positions, dtype=float)
    G = np.asarray(rotations, dtype=float)
    out = np.empty(P.shape[:1] + (len(FULL_JOINTS), 3))
    I = FULL_INDEX
    for s in ("left", "right"):
        for role in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle"):
            out[:, I[f"{s}_{role}"]] = P[:, J[f"{s}_{role}"]]
    out[:, I["neck"]] = (P[:, J["left_shoulder"]] + P[:, J["right_shoulder"]]) / 2.0
    out[:, I["mid_hip"]] = (P[:, J["left_hip"]] + P[:, J["right_hip"]]) / 2.0

    def attach(node: int, offset: np.ndarray) -> np.ndarray:
        return P[:, node] + G[:, node] @ offset

    for s, sx in (("left", 1.0), ("right", -1.0)):
        mirror = np.array([sx, 1.0, 1.0])
        a, toe = J[f"{s}_ankle"], J[f"{s}_toe"]
        out[:, I[f"{s}_heel"]] = attach(a, np.array(FOOT_OFFSETS["heel"]) * mirror * height)
        toe_off = motion.offsets[toe]                  # ankle -> toe base, rest
        tip = _tip_offset(motion, motion.names[toe])   # toe base -> toe tip, rest
        for pt, along in (("big_toe", 1.0), ("small_toe", 0.25)):
            o = tip * along
            o = o + np.array([FOOT_OFFSETS[pt][0] * sx * height, 0.0, 0.0])
            o[1] += FOOT_OFFSETS[pt][1] * height - toe_off[1] - tip[1] * along
            out[:, I[f"{s}_{pt}"]] = attach(toe, o)

    h = J["head"]
    top = _tip_offset(motion, motion.names[h])
    pivot = np.array([0.0, top[1] - 0.110 * height, top[2]])
    for pt in ("eye", "ear"):
        for s, sx in (("left", 1.0), ("right", -1.0)):
            o = pivot + np.array(HEAD_OFFSETS[pt]) * np.array([sx, 1.0, 1.0]) * height
            out[:, I[f"{s}_{pt}"]] = attach(h, o)
    out[:, I["nose"]] = attach(h, pivot + np.array(HEAD_OFFSETS["nose"]) * height)
    return out


def _leading_rest_frames(positions: np.ndarray, fps: float, unit: float) -> int:
    """Number of leading frames followed by a jump faster than :data:`MAX_JOINT_SPEED`."""
    k = 0
    limit = MAX_JOINT_SPEED / fps / unit
    while k + 1 < len(positions):
        step = np.linalg.norm(positions[k + 1] - positions[k], axis=-1).max()
        if step <= limit:
            break
        k += 1
    return k


@dataclass(frozen=True)
class MocapMotion:
    """A motion-capture take mapped to the synthetic body's joints, in metres.

    Attributes:
        joints: ``(F, 25, 3)`` joints of :data:`~mirrorgraph.synth.body.FULL_JOINTS`,
            metres, the BVH world's axes (Y up) with the floor moved to ``y = 0``.
        fps: frame rate of ``joints``.
        height: the skeleton's standing height, metres (:func:`skeleton_height`).
        source: the BVH file.
        source_fps: the file's frame rate.
        source_frames: frames in the file.
        skipped: leading frames of the file left out (a reference pose).
        floor: height of the floor in the BVH world, metres (see :func:`load_motion`).
    """

    joints: np.ndarray
    fps: float
    height: float
    source: str
    source_fps: float
    source_frames: int
    skipped: int
    floor: float

    def __len__(self) -> int:
        return int(self.joints.shape[0])

    def clip(self, frames: int, start: int = 0) -> np.ndarray:
        """``frames`` frames from ``start`` in the body frame of the procedural motion.

        The body frame of :func:`~mirrorgraph.synth.motion.generate_motion`:
        ``x`` left, ``y`` up, ``z`` forward, floor at ``y = 0``, metres here. At the
        clip's first frame the person faces ``+z`` (the horizontal normal of the
        line from the right to the left hip and shoulder) and the mid-hip is
        straight above the origin.

        A take shorter than ``start + frames`` plays back and forth (ping-pong:
        ``0, 1, .., F-1, F-2, .., 0, 1, ..``): the motion stays continuous (no jump
        back to the start; the velocity reverses at the turns).
        """
        T = int(frames)
        if T < 1:
            raise ValueError(f"frames must be >= 1, got {frames}")
        X = self.joints[pingpong_indices(len(self), T, start)]
        I = FULL_INDEX
        first = X[0]
        left = (first[I["left_hip"]] - first[I["right_hip"]]
                + first[I["left_shoulder"]] - first[I["right_shoulder"]])
        fwd = np.array([-left[2], 0.0, left[0]])            # left x up
        yaw = np.arctan2(fwd[0], fwd[2])
        R = axis_rotation(1, -yaw)                          # turns fwd onto +z
        origin = np.array([first[I["mid_hip"], 0], 0.0, first[I["mid_hip"], 2]])
        return (X - origin) @ R.T


def pingpong_indices(n: int, frames: int, start: int = 0) -> np.ndarray:
    """Frame indices ``(frames,)`` playing ``n`` frames back and forth from ``start``."""
    k = np.arange(int(frames)) + int(start)
    if n <= 1:
        return np.zeros_like(k)
    period = 2 * (n - 1)
    m = k % period
    return np.where(m < n, m, period - m)


def load_motion(path: str | os.PathLike | BvhMotion, fps: float = 30.0, *,
                unit: float = CMU_UNIT_M, names: dict[str, str] | None = None,
                skip_reference_pose: bool = True) -> MocapMotion:
    """Read a BVH take and map it to the synthetic body's 25 joints, in metres.

    Steps: parse; leave out leading frames that jump to the next one faster than
    :data:`MAX_JOINT_SPEED` (CMU conversions start with a reference T-pose: in
    ``cmu_01_01.bvh`` frame 0, 0.7 m from frame 1) when
    ``skip_reference_pose``; resample to ``fps`` (see the module docstring);
    map the joints (:func:`body_joints`); scale by ``unit`` (metres per file
    unit; CMU: 0.0254 / 0.45); move the floor to ``y = 0``.

    The floor is the level the feet stand on: the lowest heel or toe point of
    each frame, median over the take (at the file's rate; in most frames a foot
    stands on the floor). In ``cmu_01_01.bvh`` it lies 3 cm above the capture's
    ``y = 0``; the toes touch it when standing, a few landings dip up to 6 cm
    below, and the heels stand about 3 cm above it (the CMU ankle centre lies
    about 0.07 of the height above the floor, the body model's heel offset
    assumes 0.039).

    Args:
        path: BVH file (or an already parsed :class:`BvhMotion`).
        fps: frame rate wanted.
        unit: metres per file unit.
        names: role -> joint name (default :data:`CMU_JOINT_NAMES`).
        skip_reference_pose: leave out a leading reference pose.

    Raises:
        InputError: unreadable or malformed file, joints missing, not Y-up.
    """
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if not unit > 0:
        raise ValueError(f"unit must be positive, got {unit}")
    motion = path if isinstance(path, BvhMotion) else read_bvh(path)
    names = CMU_JOINT_NAMES if names is None else names
    height = skeleton_height(motion, names)
    P, G = motion.forward_kinematics()
    skipped = _leading_rest_frames(P, motion.fps, unit) if skip_reference_pose else 0
    if skipped:
        P, G = P[skipped:], G[skipped:]
        motion = motion.select(slice(skipped, None))
    full = body_joints(motion, P, G, height, names)
    feet = [FULL_INDEX[f"{s}_{p}"] for s in ("left", "right")
            for p in ("heel", "big_toe", "small_toe")]
    floor = float(np.median(full[:, feet, 1].min(1)))
    del P, G, full
    if motion.fps == fps:
        P, G = motion.forward_kinematics()
    else:
        P, G = motion.resample(fps)
    X = body_joints(motion, P, G, height, names)
    X[..., 1] -= floor
    X *= unit
    return MocapMotion(joints=X, fps=float(fps), height=height * unit, source=motion.source,
                       source_fps=motion.fps, source_frames=motion.frames + skipped,
                       skipped=skipped, floor=floor * unit)


def motion_for_scene(path: str | os.PathLike, frames: int, fps: float = 30.0,
                     **kwargs: Any) -> tuple[np.ndarray, MocapMotion]:
    """The first ``frames`` frames of a take for :func:`~mirrorgraph.synth.make_scene`.

    Returns:
        ``(local, take)``: ``local`` ``(frames, 25, 3)`` in units of the skeleton's
        height in the body frame (exactly what
        :func:`~mirrorgraph.synth.motion.generate_motion` returns; see
        :meth:`MocapMotion.clip`), and the take (:func:`load_motion`; its
        ``height`` in metres turns ``local`` back into metres).
    """
    take = load_motion(path, fps, **kwargs)
    return take.clip(frames) / take.height, take
