"""The keypoints and the camera before any geometry: the size check, the lens, the frame rate.

What both front ends (:func:`mirrorgraph.calibrate` and
:func:`mirrorgraph.calibrate_rig`) do to what they read before any geometry:
:func:`check_image_size` (keypoints and intrinsics in the same pixels),
:func:`undistort_keypoints` (the lens removed: pixels in, pixels out), and
:func:`resolve_fps` (the frame rate of the 3D motion, :func:`fps_from_video`).
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from .errors import InputError
from .intrinsics import Intrinsics
from .keypoints import PairedKeypoints, RawDetections

__all__ = ["DEFAULT_FPS", "DEFAULT_FPS_WARNING", "FPS_TOLERANCE", "IMAGE_MARGIN",
           "VIDEO_FPS_RANGE", "check_image_size", "fps_from_video", "fraction_outside",
           "resolve_fps", "undistort_keypoints"]


#: Keypoints count as outside the image beyond this margin (fraction of each side).
IMAGE_MARGIN = 0.10


def fraction_outside(data: RawDetections | PairedKeypoints, size: tuple[int, int]) -> float:
    """Fraction of detected joints outside the image enlarged by :data:`IMAGE_MARGIN`."""
    if isinstance(data, PairedKeypoints):
        pts = np.concatenate([data.real.reshape(-1, 3), data.mirror.reshape(-1, 3)])
    else:
        pts = np.concatenate([p.reshape(-1, 3) for p in data.people] or [np.empty((0, 3))])
    pts = pts[(pts[:, 2] > 0) & np.isfinite(pts[:, :2]).all(1)]
    if len(pts) == 0:
        return 0.0
    w, h = size
    lo = -IMAGE_MARGIN * np.array([w, h])
    hi = (1 + IMAGE_MARGIN) * np.array([w, h])
    return float(np.mean(((pts[:, :2] < lo) | (pts[:, :2] > hi)).any(1)))


def check_image_size(data: RawDetections | PairedKeypoints, intr: Intrinsics,
                     warnings: list[str]) -> None:
    """Compare the keypoints with the image size the intrinsics belong to.

    Most keypoints outside the image mean the keypoints and K are not in the same
    pixels (a resized video, the wrong camera file): the normal found with that K
    would be wrong, so it is one rule for a size given on the command line and one
    read from a camera file: an :class:`InputError` naming the size and the field.

    Raises:
        InputError: over half the detected keypoints lie outside the image (enlarged
            by 10 % each side).
    """
    if intr.image_size is None:
        return
    frac = fraction_outside(data, intr.image_size)
    if frac <= 0.5:
        return
    w, h = intr.image_size
    msg = (f"{100 * frac:.0f}% of the keypoints lie outside the {w}x{h} image: the keypoints "
           "and the intrinsics do not seem to be in the same pixels")
    if intr.approximate:
        raise InputError(msg + "; give the video's real size", source=data.source,
                         field="image_size")
    raise InputError(msg + " (a resized video? the wrong camera file?); if K is right for "
                     "these keypoints, fix or remove image_size",
                     source=intr.source or data.source, field="image_size")


def undistort_keypoints(data: RawDetections | PairedKeypoints, intr: Intrinsics
                        ) -> RawDetections | PairedKeypoints:
    """The keypoints with the lens distortion of ``intr`` removed (pixels in, pixels out;
    the input itself when there is no distortion)."""
    if intr.dist is None or not np.any(intr.dist):
        return data
    if isinstance(data, PairedKeypoints):
        real, mirror = data.real.copy(), data.mirror.copy()
        real[..., :2] = intr.undistort_points(real[..., :2])
        mirror[..., :2] = intr.undistort_points(mirror[..., :2])
        return replace(data, real=real, mirror=mirror)
    people = []
    for p in data.people:
        p = np.array(p, dtype=float, copy=True)
        if len(p):
            p[..., :2] = intr.undistort_points(p[..., :2])
        people.append(p)
    return replace(data, people=people)


#: Frame rate assumed when neither the options, the input nor a video give one (Hz).
DEFAULT_FPS = 30.0
#: Frame rates a video may declare, ``[low, high)``; OpenCV reports 0, or a container's
#: time base (1000, 90000), where a file has no usable rate: those count as none.
VIDEO_FPS_RANGE = (1.0, 1000.0)
#: What to say when the 3D motion is written at :data:`DEFAULT_FPS` for want of a rate.
DEFAULT_FPS_WARNING = (f"frame rate unknown: the 3D motion is written at the default "
                       f"{DEFAULT_FPS:g} fps; pass --fps HZ or --video FILE to set it")
#: Two frame rates that differ by more than this fraction are named in a warning.
FPS_TOLERANCE = 0.005


def fps_from_video(path: str | os.PathLike) -> float | None:
    """The frame rate a video file declares (OpenCV ``CAP_PROP_FPS``), Hz.

    Args:
        path: the video.

    Returns:
        The rate, or ``None`` where the file declares none usable (outside
        :data:`VIDEO_FPS_RANGE`).

    Example:
        >>> fps_from_video("clip.mp4")        # doctest: +SKIP
        25.0

    Raises:
        InputError: the file does not exist or OpenCV cannot open it (field ``video``).
    """
    if not Path(path).is_file():
        raise InputError("no such video file", source=os.fspath(path), field="video")
    cap = cv2.VideoCapture(os.fspath(path))
    try:
        if not cap.isOpened():
            raise InputError("cannot be read as a video (OpenCV)", source=os.fspath(path),
                             field="video")
        fps = float(cap.get(cv2.CAP_PROP_FPS))
    finally:
        cap.release()
    lo, hi = VIDEO_FPS_RANGE
    return fps if math.isfinite(fps) and lo <= fps < hi else None


def resolve_fps(data: RawDetections | PairedKeypoints, warnings: list[str], *,
                fps: float | None = None, video: str | os.PathLike | None = None
                ) -> tuple[float, str]:
    """The frame rate of the 3D motion and where it comes from.

    In this order: ``fps`` (the user's), the input's own (``.npz`` ``fps``;
    a reader sets :attr:`RawDetections.fps` where its format carries one), the rate
    ``video`` declares (:func:`fps_from_video`), else :data:`DEFAULT_FPS`.
    Sources that disagree by more than :data:`FPS_TOLERANCE` are named in a warning.
    The default is only reported (``"default"``): a frame rate matters to the 3D
    motion written out, and whoever writes it warns (:data:`DEFAULT_FPS_WARNING`).

    Args:
        data: the keypoints read.
        fps: the user's frame rate, Hz (``CalibrateOptions.fps``).
        video: the video the keypoints come from (``CalibrateOptions.video``).
        warnings: the run's warnings, appended to.

    Returns:
        ``(fps Hz, source)``, source one of ``"option"``, ``"input"``, ``"video"``,
        ``"default"``.

    Raises:
        InputError: ``fps`` is not a positive number, or the video cannot be read.
    """
    given = []
    if fps is not None:
        f = fps
        if isinstance(f, bool) or not isinstance(f, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(float(f)) and float(f) > 0):
            raise InputError(f"frame rate must be a positive number, got {f!r}", field="fps")
        given.append((float(f), "option", "fps"))
    if data.fps is not None and math.isfinite(float(data.fps)) and float(data.fps) > 0:
        given.append((float(data.fps), "input", f"the input ({data.source})"))
    if video is not None:
        f = fps_from_video(video)
        if f is not None:
            given.append((f, "video", f"the video ({os.fspath(video)})"))
        else:
            warnings.append(f"the video {os.fspath(video)} declares no frame rate")
    if not given:
        return DEFAULT_FPS, "default"
    rate, source, name = given[0]
    for other, _src, other_name in given[1:]:
        if abs(other - rate) > FPS_TOLERANCE * rate:
            warnings.append(f"frame rate: {name} gives {rate:g} fps but {other_name} "
                            f"{other:g} fps; using {rate:g}")
    return rate, source
