"""Frames of a video file, with its frame rate and size (OpenCV's FFmpeg reader).

:func:`probe` reads what the container declares; :func:`frames` yields the
frames of a range, every ``every``-th, as RGB. Frame numbers count from 0 in
decoding order. A file OpenCV cannot open is an
:class:`~mirrorgraph.errors.InputError` naming it; a video that ends before the
frame count its container declares simply ends (the frames read are counted).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError

__all__ = ["VideoInfo", "probe", "frames", "is_video", "VIDEO_SUFFIXES", "quiet_stderr"]

#: File name endings read as videos wherever keypoints are expected.
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv")


def is_video(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a video file by its ending (see :data:`VIDEO_SUFFIXES`)."""
    return Path(path).suffix.lower() in VIDEO_SUFFIXES


@dataclass(frozen=True)
class VideoInfo:
    """What a video declares.

    Attributes:
        path: the file.
        width, height: frame size in pixels.
        fps: frames per second (``None`` where the container gives none).
        frame_count: number of frames the container declares (may be approximate).
    """

    path: Path
    width: int
    height: int
    fps: float | None
    frame_count: int


@contextmanager
def quiet_stderr():
    """Silence file descriptor 2 for a moment: FFmpeg (opening a file that is no video)
    and LiteRT (allocating tensors) print from C code straight to it, and the CLI
    says what went wrong in one line of its own."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):          # no real descriptor (a captured stream)
        yield
        return
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 2)
        os.close(null)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _open(path: Path):
    if not path.is_file():
        raise InputError("no such video file", source=path)
    with quiet_stderr():
        cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise InputError("cannot be read as a video (OpenCV's FFmpeg reader cannot open it)",
                         source=path)
    return cap


def probe(path: str | os.PathLike) -> VideoInfo:
    """Size, frame rate and frame count of a video (InputError if it cannot be read)."""
    path = Path(path)
    cap = _open(path)
    try:
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()
    if w <= 0 or h <= 0:
        raise InputError("has no video frames (width or height 0)", source=path)
    return VideoInfo(path=path, width=w, height=h,
                     fps=fps if np.isfinite(fps) and 0 < fps < 10000 else None,
                     frame_count=max(n, 0))


def frames(path: str | os.PathLike, *, start: int = 0, end: int | None = None,
           every: int = 1) -> Iterator[tuple[int, np.ndarray]]:
    """``(frame number, (H, W, 3) uint8 RGB)`` for frames ``start, start + every, ...``
    below ``end`` (``None``: to the last frame).

    Frames before ``start`` and between the ones kept are decoded but not converted
    (``grab``), so that frame numbers are exact whatever the codec's seeking.
    """
    path = Path(path)
    if start < 0 or every < 1 or (end is not None and end <= start):
        raise InputError(f"empty frame range: start {start}, end {end}, every {every}",
                         source=path, field="start")
    cap = _open(path)
    try:
        t = 0
        while end is None or t < end:
            if t < start or (t - start) % every:
                if not cap.grab():
                    return
            else:
                ok, bgr = cap.read()
                if not ok:
                    return
                yield t, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            t += 1
    finally:
        cap.release()
