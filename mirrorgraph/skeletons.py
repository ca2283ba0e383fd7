"""Skeleton definitions: joint names, the left/right flip map and the bone set.

A pose detector labels the mirrored person anatomically *as it sees them*: the
reflection of the real left wrist is labelled "right wrist". :attr:`Skeleton.flip`
is the permutation that turns the detector's labels of the reflection into the
labels of the real joints it images: ``mirror_flipped = mirror[..., skeleton.flip, :]``.

Joint names are canonical lower-case snake case (``left_wrist``, ``mid_hip``) for
every skeleton, so that code can ask for a joint by name whatever the detector.

The bone set follows MirrorCalib (Liao, Zheng and Mitchell), section
"Refining 2D joint locations": femur, tibia, humerus, ulna, scapular and hip, on
each side. Where a skeleton has no neck the scapular bones become the shoulder
width; where it has no mid-hip the hip bones become the hip width (both unpaired).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InputError


@dataclass(frozen=True)
class Skeleton:
    """A 2D keypoint layout.

    Attributes:
        name: layout name, e.g. ``"COCO_17"``.
        joints: ``(J,)`` canonical joint names in the detector's order.
        bones: bone name -> (proximal joint, distal joint), by joint name.
        symmetric_bones: pairs ``(left bone, right bone)`` of bone names.
        mid_hip: name of the mid-hip joint, or ``None`` where the layout has none.
        calibration_joint_names: joints used by default for calibration: the paper
            leaves out face, hands and feet.
    """

    name: str
    joints: tuple[str, ...]
    bones: dict[str, tuple[str, str]]
    symmetric_bones: tuple[tuple[str, str], ...]
    mid_hip: str | None
    calibration_joint_names: tuple[str, ...]
    _index: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_index", {n: i for i, n in enumerate(self.joints)})

    @property
    def num_joints(self) -> int:
        """Number of keypoints J."""
        return len(self.joints)

    def index(self, name: str) -> int:
        """Index of a joint by canonical name (``KeyError`` if absent)."""
        return self._index[name]

    def has(self, name: str) -> bool:
        """Whether the layout has a joint of this name."""
        return name in self._index

    @property
    def flip(self) -> np.ndarray:
        """``(J,)`` int permutation: index of each joint's left/right counterpart.

        Centre joints (nose, neck, mid-hip) map to themselves. Applying it twice
        is the identity.
        """
        out = np.arange(self.num_joints)
        for i, n in enumerate(self.joints):
            if n.startswith("left_"):
                out[i] = self._index["right_" + n[5:]]
            elif n.startswith("right_"):
                out[i] = self._index["left_" + n[6:]]
        return out

    @property
    def calibration_joints(self) -> np.ndarray:
        """``(K,)`` int indices of :attr:`calibration_joint_names`, ascending."""
        return np.array(sorted(self._index[n] for n in self.calibration_joint_names), dtype=int)

    @property
    def bone_index(self) -> np.ndarray:
        """``(B, 2)`` int joint indices of :attr:`bones`, in dict order."""
        return np.array([[self._index[a], self._index[b]] for a, b in self.bones.values()],
                        dtype=int).reshape(-1, 2)

    @property
    def bone_names(self) -> tuple[str, ...]:
        """``(B,)`` bone names, in the order of :attr:`bone_index`."""
        return tuple(self.bones)


_LIMBS = ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")
_CORE = tuple(f"{side}_{j}" for j in _LIMBS for side in ("left", "right"))


def _bones(has_neck: bool, has_mid_hip: bool) -> tuple[dict[str, tuple[str, str]],
                                                        tuple[tuple[str, str], ...]]:
    bones: dict[str, tuple[str, str]] = {}
    pairs: list[tuple[str, str]] = []
    for bone, (a, b) in {"femur": ("hip", "knee"), "tibia": ("knee", "ankle"),
                         "humerus": ("shoulder", "elbow"), "ulna": ("elbow", "wrist")}.items():
        for side in ("left", "right"):
            bones[f"{side}_{bone}"] = (f"{side}_{a}", f"{side}_{b}")
        pairs.append((f"left_{bone}", f"right_{bone}"))
    if has_neck:
        for side in ("left", "right"):
            bones[f"{side}_scapular"] = ("neck", f"{side}_shoulder")
        pairs.append(("left_scapular", "right_scapular"))
    else:
        bones["shoulder_width"] = ("left_shoulder", "right_shoulder")
    if has_mid_hip:
        for side in ("left", "right"):
            bones[f"{side}_pelvis"] = ("mid_hip", f"{side}_hip")
        pairs.append(("left_pelvis", "right_pelvis"))
    else:
        bones["hip_width"] = ("left_hip", "right_hip")
    return bones, tuple(pairs)


def _make(name: str, joints: tuple[str, ...]) -> Skeleton:
    has_neck, has_mid_hip = "neck" in joints, "mid_hip" in joints
    bones, pairs = _bones(has_neck, has_mid_hip)
    calib = _CORE + (("neck",) if has_neck else ()) + (("mid_hip",) if has_mid_hip else ())
    return Skeleton(name=name, joints=joints, bones=bones, symmetric_bones=pairs,
                    mid_hip="mid_hip" if has_mid_hip else None,
                    calibration_joint_names=calib)


#: COCO-17 keypoints (MMPose, HRNet, RTMPose, ViTPose).
COCO_17 = _make("COCO_17", (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle"))

#: OpenPose BODY_25 (also EasyMocap / Mirrored-Human annotations).
BODY_25 = _make("BODY_25", (
    "nose", "neck", "right_shoulder", "right_elbow", "right_wrist",
    "left_shoulder", "left_elbow", "left_wrist", "mid_hip",
    "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee", "left_ankle",
    "right_eye", "left_eye", "right_ear", "left_ear",
    "left_big_toe", "left_small_toe", "left_heel",
    "right_big_toe", "right_small_toe", "right_heel"))

#: OpenPose COCO-18 (the older OpenPose COCO model).
COCO_18 = _make("COCO_18", (
    "nose", "neck", "right_shoulder", "right_elbow", "right_wrist",
    "left_shoulder", "left_elbow", "left_wrist",
    "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee", "left_ankle",
    "right_eye", "left_eye", "right_ear", "left_ear"))

#: OpenPose's experimental BODY_25B model (Pose2Sim's default detector layout).
#: Order: OpenPose ``POSE_BODY_25B_BODY_PARTS`` (``src/openpose/pose/poseParameters.cpp``;
#: the model is described in ``openpose_train/experimental_models/README.md``) and
#: Pose2Sim's ``skeletons.BODY_25B``: the COCO-17 joints first, then OpenPose's
#: ``UpperNeck`` (Pose2Sim ``Neck``) and ``HeadTop`` (Pose2Sim ``Head``), then the feet.
#: Its neck is the *upper* neck, trained on MPII's "upper neck" label, not the
#: midpoint of the shoulders of BODY_25 (see :mod:`mirrorgraph.skeleton_guess`).
BODY_25B = _make("BODY_25B", (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle",
    "neck", "head_top",
    "left_big_toe", "left_small_toe", "left_heel",
    "right_big_toe", "right_small_toe", "right_heel"))

#: HALPE body, 26 keypoints (AlphaPose ``halpe26`` models, RTMPose ``body8-halpe26``;
#: Pose2Sim's ``HALPE_26``). Order: the Halpe-FullBody annotation
#: (github.com/Fang-Haoshu/Halpe-FullBody, body points 0-25), also MMPose's
#: ``configs/_base_/datasets/halpe26.py``: the COCO-17 joints, then ``Head`` (the top
#: of the head), ``Neck``, ``Hip`` (the pelvis centre), then big toes, small toes
#: and heels, each left before right.
HALPE_26 = _make("HALPE_26", (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle",
    "head_top", "neck", "mid_hip",
    "left_big_toe", "right_big_toe", "left_small_toe", "right_small_toe",
    "left_heel", "right_heel"))

#: MediaPipe BlazePose, 33 landmarks (``pose_landmark_full.tflite``; Pose2Sim's
#: ``BLAZEPOSE``). Order: MediaPipe's ``PoseLandmark`` enum
#: (``mediapipe/python/solutions/pose.py``; the topology figure
#: ``mediapipe/modules/pose_landmark/pose_landmark_topology.svg``) and Bazarevsky et al.,
#: "BlazePose: On-device Real-time Body Pose tracking", CVPR Workshops 2020, Fig. 4.
#: Canonical names: MediaPipe's ``MOUTH_LEFT`` is ``left_mouth`` (so that the flip map
#: finds its partner), ``FOOT_INDEX`` (the tip of the foot) is ``big_toe`` (Pose2Sim's
#: ``LBigToe``); ``pinky``, ``index`` and ``thumb`` are the hand's points. No neck and
#: no mid-hip: the bones are the shoulder and hip widths.
BLAZEPOSE = _make("BLAZEPOSE", (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer",
    "right_eye_inner", "right_eye", "right_eye_outer", "left_ear", "right_ear",
    "left_mouth", "right_mouth", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist",
    "left_pinky", "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb",
    "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
    "left_heel", "right_heel", "left_big_toe", "right_big_toe"))

#: Every layout by name.
SKELETONS: dict[str, Skeleton] = {s.name: s for s in (COCO_17, BODY_25, COCO_18, BODY_25B,
                                                      HALPE_26, BLAZEPOSE)}


def skeleton_by_name(name: str) -> Skeleton:
    """Look a layout up by name, case-insensitively, ``-`` for ``_`` (``"body_25b"``,
    ``"HALPE-26"``); :class:`~mirrorgraph.errors.InputError` (a ``ValueError``) if
    unknown. ``"COCO_17@3"`` names the layout of three people side by side
    (:func:`people_skeleton`)."""
    key = name.strip().upper().replace("-", "_")
    base, tag, count = key.partition(PERSON_TAG)
    if tag and base in SKELETONS and count.isdigit() and int(count) >= 2:
        return people_skeleton(SKELETONS[base], int(count))
    if key not in SKELETONS:
        raise InputError(f"unknown skeleton {name!r}; known: {', '.join(SKELETONS)}")
    return SKELETONS[key]


def skeletons_for_count(num_joints: int) -> tuple[Skeleton, ...]:
    """Every layout with this many keypoints, in :data:`SKELETONS` order.

    Empty if none; more than one where the count is ambiguous (25: ``BODY_25``
    and ``BODY_25B``, told apart from the data by
    :func:`mirrorgraph.skeleton_guess.guess_skeleton`).
    """
    return tuple(s for s in SKELETONS.values() if s.num_joints == num_joints)


def skeleton_for_count(num_joints: int) -> Skeleton | None:
    """The one layout with this many keypoints, or ``None`` if there is none.

    Raises:
        ValueError: several layouts have this count (25: ``BODY_25``, ``BODY_25B``);
            the count alone does not tell them apart (see :func:`skeletons_for_count`).
    """
    found = skeletons_for_count(num_joints)
    if len(found) > 1:
        raise ValueError(f"{num_joints} keypoints fit several skeletons: "
                         f"{' or '.join(s.name for s in found)}")
    return found[0] if found else None


def known_counts() -> str:
    """``"COCO_17: 17, BODY_25: 25, ..."``: every layout and its count, for messages."""
    return ", ".join(f"{s.name}: {s.num_joints}" for s in SKELETONS.values())


# --------------------------------------------------------------------------- several people
#: Separates a joint's or bone's name from its person's number in the layout of several
#: people (:func:`people_skeleton`): ``left_wrist@2``.
PERSON_TAG = "@"


def people_skeleton(skeleton: Skeleton, count: int) -> Skeleton:
    """The layout of ``count`` people side by side: one body per person in one array.

    Person ``p``'s joint ``j`` is joint ``p * J + j`` (``J`` of ``skeleton``), named
    ``f"{name}@{p}"``; each person has their own bones (``left_femur@p``), their own
    symmetric pairs and calibration joints, so that every body prior, bone length and
    left/right flip stays within one person. ``mid_hip`` is ``None`` (the hip prior
    names one mid-hip). One person: ``skeleton`` itself.

    Args:
        skeleton: one person's layout.
        count: people (>= 1).
    """
    if count == 1:
        return skeleton
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count}")

    def tag(name: str, p: int) -> str:
        return f"{name}{PERSON_TAG}{p}"

    people = range(count)
    return Skeleton(
        name=f"{skeleton.name}{PERSON_TAG}{count}",
        joints=tuple(tag(n, p) for p in people for n in skeleton.joints),
        bones={tag(b, p): (tag(a, p), tag(c, p)) for p in people
               for b, (a, c) in skeleton.bones.items()},
        symmetric_bones=tuple((tag(a, p), tag(b, p)) for p in people
                              for a, b in skeleton.symmetric_bones),
        mid_hip=None,
        calibration_joint_names=tuple(tag(n, p) for p in people
                                      for n in skeleton.calibration_joint_names))


def person_of(name: str) -> str:
    """The person's tag of a joint or bone name of :func:`people_skeleton` (``"@2"``), or
    ``""`` for a name of one person's layout."""
    i = name.rfind(PERSON_TAG)
    return "" if i < 0 else name[i:]
