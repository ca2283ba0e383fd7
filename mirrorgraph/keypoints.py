"""Containers for 2D keypoints: raw detections per frame, and paired person/reflection.

Conventions shared by every module:

* pixel coordinates, origin at the top-left corner of the image, x to the right,
  y down; ``(..., 3)`` arrays hold ``x, y, confidence``;
* a missing joint has confidence ``0`` and coordinates ``NaN``; confidences lie
  in ``[0, 1]``;
* ``frame_ids`` are the video frame numbers (ints, strictly increasing), which
  may have gaps.

What a reader had to interpret to get there (the formats' own "missing" markers,
scores above 1) is counted in :class:`ReadNotes`, the ``read_notes`` of both
containers.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from .skeletons import Skeleton

#: Keypoints whose detector confidence is below this are ignored by default
#: (``--min-confidence``; one home for every module that filters on it).
DEFAULT_MIN_CONFIDENCE = 0.3

#: Fewest joint/reflection pairs (joints seen in two views) a calibration needs.
MIN_PAIRS = 12


@dataclass(frozen=True)
class ReadNotes:
    """What a keypoint reader treated as missing or changed, counted over the input.

    Detectors and annotation tools mark an undetected joint in their own ways;
    each reader turns every marker into mirrorgraph's one convention (confidence
    ``0``, ``NaN`` coordinates) and counts it here, so that a run can say what it
    read (``calibration.json`` ``input``, ``--verbose``). Which marker each format
    uses, and where that was read, is in the reader's module docstring
    (:mod:`mirrorgraph.io`).

    Attributes:
        joints_missing_zero_confidence: joints of confidence exactly ``0`` (how
            OpenPose, EasyMocap and mirrorgraph's writers write "not detected",
            usually ``[0, 0, 0]``).
        joints_missing_negative_confidence: joints of negative confidence, read
            as missing whatever their coordinates: EasyMocap / Mirrored-Human
            annotations write a joint the annotator left out as ``[0, 0, -1]``;
            RTMPose's SimCC decoder (MMPose, and RTMLib through Pose2Sim) gives
            scores ``<= 0`` to keypoints it did not find.
        joints_missing_nan: joints written as ``NaN, NaN, NaN`` (Pose2Sim's
            OpenPose-style files, for tracked people not seen in a frame).
        scores_clipped_above_1: confidences above 1 set to 1 (heat-map peaks and
            SimCC logits are no probabilities and exceed 1).
        max_confidence_read: the largest finite confidence in the input, before
            clipping; ``None`` if no joint had one.
        people_without_keypoints: person entries with no body keypoints at all
            (EasyMocap annotations holding only a ``bbox``, OpenPose's empty
            ``pose_keypoints_2d`` when the body detector is off), left out.
        people_without_joints: person entries whose every joint is missing, left
            out (no detection to pair).
        frames_without_people: frames listing nobody (after leaving those out).
    """

    joints_missing_zero_confidence: int = 0
    joints_missing_negative_confidence: int = 0
    joints_missing_nan: int = 0
    scores_clipped_above_1: int = 0
    max_confidence_read: float | None = None
    people_without_keypoints: int = 0
    people_without_joints: int = 0
    frames_without_people: int = 0

    def as_dict(self) -> dict[str, int | float | None]:
        """The counts by name, JSON-ready (for ``calibration.json`` ``input``)."""
        return asdict(self)

    def summary(self) -> str:
        """One line for people: what was read as missing or clipped (``""`` if nothing
        beyond joints of confidence 0)."""
        parts = []
        if self.joints_missing_negative_confidence:
            parts.append(f"{self.joints_missing_negative_confidence} joints of negative "
                         "confidence read as missing")
        if self.joints_missing_nan:
            parts.append(f"{self.joints_missing_nan} joints written as NaN read as missing")
        if self.scores_clipped_above_1:
            parts.append(f"{self.scores_clipped_above_1} confidences above 1 clipped to 1 "
                         f"(largest {self.max_confidence_read:.4g})")
        if self.people_without_keypoints:
            parts.append(f"{self.people_without_keypoints} people without body keypoints "
                         "left out")
        if self.people_without_joints:
            parts.append(f"{self.people_without_joints} people with every joint missing "
                         "left out")
        return "; ".join(parts)


@dataclass
class RawDetections:
    """What a reader returns: for each frame, every person the detector found.

    Attributes:
        skeleton: the keypoint layout.
        frame_ids: ``(T,)`` int frame numbers, strictly increasing.
        people: ``T`` arrays, each ``(P_t, J, 3)`` float (x px, y px, confidence);
            ``P_t`` may be 0, 1, 2 or more. The order of people is arbitrary.
        source: path of the file or folder read.
        format: ``"mmpose"``, ``"openpose"`` or ``"easymocap"``.
        image_size: ``(width, height)`` in pixels if the input carries it.
        fps: frames per second if the input carries it.
        read_notes: what the reader read as missing or clipped (:class:`ReadNotes`;
            all zero for detections not read from a file).
    """

    skeleton: Skeleton
    frame_ids: np.ndarray
    people: list[np.ndarray]
    source: str = ""
    format: str = ""
    image_size: tuple[int, int] | None = None
    fps: float | None = None
    read_notes: ReadNotes = field(default_factory=ReadNotes)

    def __len__(self) -> int:
        return len(self.people)


@dataclass
class PairedKeypoints:
    """Person and reflection, paired per frame, labels of the reflection flipped.

    ``mirror[t, j]`` is the image *in the mirror* of the same physical joint
    whose direct image is ``real[t, j]``: the detector's anatomical labels of the
    reflection have already been swapped left/right (see
    :attr:`mirrorgraph.skeletons.Skeleton.flip`).

    Attributes:
        skeleton: the keypoint layout.
        frame_ids: ``(T,)`` int frame numbers, strictly increasing.
        real: ``(T, J, 3)`` float: direct view, x px, y px, confidence.
        mirror: ``(T, J, 3)`` float: mirror view, same layout.
        source: path of the input.
        format: input format name.
        image_size: ``(width, height)`` in pixels if known.
        fps: frames per second if known.
        lr_fixes: number of frames whose left/right labels were found crossed by the
            detector and corrected (the reflection's by the pairing, either view's by the
            whole clip's decision, :mod:`mirrorgraph.initial.clip_left_right`).
        frames_read: number of frames in the input before pairing.
        notes: free-text remarks.
        read_notes: what the reader read as missing or clipped (:class:`ReadNotes`;
            filled by the ``.npz`` reader, all zero after pairing detections: the
            detections' own ``read_notes`` hold theirs).
    """

    skeleton: Skeleton
    frame_ids: np.ndarray
    real: np.ndarray
    mirror: np.ndarray
    source: str = ""
    format: str = ""
    image_size: tuple[int, int] | None = None
    fps: float | None = None
    lr_fixes: int = 0
    frames_read: int = 0
    notes: list[str] = field(default_factory=list)
    read_notes: ReadNotes = field(default_factory=ReadNotes)

    def __len__(self) -> int:
        return int(self.real.shape[0])

    def valid(self, min_confidence: float = 0.0) -> np.ndarray:
        """``(T, J)`` bool: joint seen in both views above ``min_confidence``."""
        ok = (self.real[..., 2] > min_confidence) & (self.mirror[..., 2] > min_confidence)
        ok &= np.isfinite(self.real[..., :2]).all(-1) & np.isfinite(self.mirror[..., :2]).all(-1)
        return ok
