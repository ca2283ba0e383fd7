"""Frames for a live run: a keypoint input replayed, a video file, or a camera.

Each source yields :class:`SourceFrame` (frame number, time in seconds, every person's
keypoints ``(P, J, 3)``) and says its skeleton, image size and frame rate up front
(:class:`Source`). :func:`open_source` chooses by what ``SOURCE`` is:

* an integer (``0``): a camera, read with OpenCV as fast as it delivers, each frame
  detected with BlazePose (:mod:`mirrorgraph.video`, the ``video`` extra); a camera that
  cannot be opened is refused in one line;
* a video file: its frames detected the same way, played at the file's frame rate
  (a frame whose time has passed while the detector was busy is dropped and counted,
  as a live feed would), or flat out with ``realtime=False``;
* anything :func:`mirrorgraph.io.read_keypoints` reads: replayed frame by frame at the
  input's frame rate, or flat out. Paired input (``.npz``) becomes two detections a
  frame, the reflection in the detector's own (mirrored) labels.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = ["SourceFrame", "Source", "open_source", "is_camera"]


@dataclass
class SourceFrame:
    """One frame: its number, its time (s) and every person's keypoints ``(P, J, 3)``."""

    frame_id: int
    time: float
    people: np.ndarray


@dataclass
class Source:
    """A stream of frames and what is known of it before the first.

    Attributes:
        name: what was opened.
        kind: ``"camera"``, ``"video"`` or ``"keypoints"``.
        skeleton: the keypoint layout.
        image_size: ``(width, height)`` or ``None``.
        fps: frame rate, or ``None``.
        frames: the iterator of :class:`SourceFrame`.
        total: frames expected (``None``: unknown, a camera).
        stats: counts the source keeps (``dropped``: frames a real-time video skipped).
    """

    name: str
    kind: str
    skeleton: object
    image_size: tuple[int, int] | None
    fps: float | None
    frames: Iterator[SourceFrame]
    total: int | None = None
    stats: dict = field(default_factory=dict)


def is_camera(source: str | int) -> bool:
    """A camera index: an integer, or a string of digits."""
    return isinstance(source, int) or (isinstance(source, str) and source.strip().isdigit())


def _paced(items, fps: float | None, realtime: bool, stats: dict):
    """Yield ``(frame_id, time, x)`` no earlier than the frame's time after the first."""
    start = None
    for fid, t, x in items:
        if realtime and fps:
            now = time.perf_counter()
            if start is None:
                start = now - t
            wait = start + t - now
            if wait > 0:
                time.sleep(wait)
        yield fid, t, x


def _keypoint_source(path, skeleton, fps: float | None, realtime: bool) -> Source:
    from ..io import read_keypoints
    from ..keypoints import PairedKeypoints

    data = read_keypoints(path, skeleton=skeleton)
    rate = fps or data.fps or 30.0
    ids = np.asarray(data.frame_ids, dtype=np.int64)
    if isinstance(data, PairedKeypoints):
        flip = data.skeleton.flip

        def people_of(t):
            both = np.stack([data.real[t], data.mirror[t][flip]])
            return both[(both[..., 2] > 0).any(1)]
        count = len(data)
    else:
        def people_of(t):
            return np.asarray(data.people[t], dtype=float)
        count = len(data.people)
    stats: dict = {}
    items = ((int(ids[t]), (int(ids[t]) - int(ids[0])) / rate, t) for t in range(count))
    frames = (SourceFrame(fid, t, people_of(i)) for fid, t, i in _paced(items, rate, realtime,
                                                                        stats))
    return Source(str(path), "keypoints", data.skeleton, data.image_size, rate, frames,
                  total=count, stats=stats)


def _detections(tracker, rgb: np.ndarray, t: int, width: int, height: int) -> np.ndarray:
    from ..skeletons import BLAZEPOSE

    found = tracker.step(rgb, t)
    kp = np.zeros((len(found), BLAZEPOSE.num_joints, 3))
    for i, tp in enumerate(found):
        kp[i, :, :2] = tp.pose.xy
        kp[i, :, 2] = np.clip(tp.pose.visibility, 0.0, 1.0)
    out = ((kp[..., 0] < 0) | (kp[..., 0] > width - 1) | (kp[..., 1] < 0)
           | (kp[..., 1] > height - 1))
    kp[out] = (np.nan, np.nan, 0.0)
    return kp


def _tracker(threads: int):
    from ..video.blazepose import BlazePoseModels
    from ..video.track import PoseTracker

    return PoseTracker(BlazePoseModels(threads=threads))


def _video_source(path, realtime: bool, threads: int) -> Source:
    from ..skeletons import BLAZEPOSE
    from ..video.reader import frames, probe

    info = probe(path)
    tracker = _tracker(threads)
    fps = info.fps or 30.0
    stats = {"dropped": 0}

    def gen():
        start = time.perf_counter()
        for t, rgb in frames(info.path):
            when = t / fps
            if realtime:
                now = time.perf_counter() - start
                if now > when + 1.0 / fps:          # its time has passed: a live feed drops it
                    stats["dropped"] += 1
                    continue
                if when > now:
                    time.sleep(when - now)
            yield SourceFrame(t, when, _detections(tracker, rgb, t, info.width, info.height))

    return Source(str(path), "video", BLAZEPOSE, (info.width, info.height), fps, gen(),
                  total=info.frame_count or None, stats=stats)


def _camera_source(index: int, threads: int) -> Source:
    import cv2

    from ..skeletons import BLAZEPOSE

    from ..video.reader import quiet_stderr

    with quiet_stderr():                       # OpenCV's own warnings: one line is ours
        cap = cv2.VideoCapture(int(index))
    if not cap.isOpened():
        cap.release()
        raise InputError("cannot be opened (no such device, or it is busy)",
                         source=f"camera {index}")
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    fps = float(cap.get(cv2.CAP_PROP_FPS)) or None
    tracker = _tracker(threads)

    def gen():
        start = time.perf_counter()
        t = 0
        try:
            while True:
                ok, bgr = cap.read()
                if not ok:
                    return
                rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                yield SourceFrame(t, time.perf_counter() - start,
                                  _detections(tracker, rgb, t, w, h))
                t += 1
        finally:
            cap.release()

    return Source(f"camera {index}", "camera", BLAZEPOSE, (w, h), fps, gen())


def open_source(source: str | int | os.PathLike, *, skeleton=None, fps: float | None = None,
                realtime: bool = True, threads: int = 2) -> Source:
    """Open a camera index, a video file or a keypoint input (see the module docstring).

    Raises:
        InputError: a camera that cannot be opened, a file that cannot be read.
        MissingExtraError: a camera or video without the ``video`` extra.
    """
    if is_camera(source):
        return _camera_source(int(source), threads)
    from ..io import is_video_input

    if is_video_input(source):
        return _video_source(source, realtime, threads)
    return _keypoint_source(source, skeleton, fps, realtime)
