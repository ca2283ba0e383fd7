"""Containers for 2D keypoints: raw detections per frame, and paired person/reflection.

Conventions shared by every module:

* pixel coordinates, origin at the top-left corner of the image, x to the right,
  y down; ``(..., 3)`` arrays hold ``x, y, confidence``;
* a missing joint has confidence ``0`` and coordinates ``NaN``; confidences lie
  in ``[0, 1]``;
* ``frame_ids`` are the video frame numbers (ints, strictly increasing), which
  may have gaps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .skeletons import Skeleton


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
    """

    skeleton: Skeleton
    frame_ids: np.ndarray
    people: list[np.ndarray]
    source: str = ""
    format: str = ""
    image_size: tuple[int, int] | None = None
    fps: float | None = None

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
        lr_fixes: number of frames whose reflection's left/right labels were
            found swapped by the detector and corrected.
        frames_read: number of frames in the input before pairing.
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

    def __len__(self) -> int:
        return int(self.real.shape[0])

    def valid(self, min_confidence: float = 0.0) -> np.ndarray:
        """``(T, J)`` bool: joint seen in both views above ``min_confidence``."""
        ok = (self.real[..., 2] > min_confidence) & (self.mirror[..., 2] > min_confidence)
        ok &= np.isfinite(self.real[..., :2]).all(-1) & np.isfinite(self.mirror[..., :2]).all(-1)
        return ok
