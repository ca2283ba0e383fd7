"""Reading and writing keypoints, calibrations and other files.

:func:`read_keypoints` reads any supported detector output, telling the format
from the path (see :mod:`.detect`):

========== ============================================ ==========================
format     input                                        returns
========== ============================================ ==========================
mmpose     one ``.json`` file of inferencer or demo     :class:`RawDetections`
           predictions, or a folder of the inferencer's
           per-image ``.json`` files
openpose   folder of ``*_keypoints.json``, one a frame  :class:`RawDetections`
           (also Pose2Sim's ``*_{frame:06d}.json``)
easymocap  folder of ``{frame:06d}.json`` annotations   :class:`RawDetections`
           (EasyMocap, Mirrored-Human)
npz        ``.npz`` of paired ``real``/``mirror``       :class:`PairedKeypoints`
video      a video file (``.mp4``, ``.avi``, ``.mov``,  :class:`RawDetections`
           ...): detected by :mod:`mirrorgraph.video`
           (the ``video`` extra), or read back from
           its cache
========== ============================================ ==========================

Each reader reads its format as the tools write it, their "missing" markers
included (a module docstring each says what they are and where that was read):
joints of confidence ``<= 0`` (EasyMocap's ``[0, 0, -1]``), Pose2Sim's ``NaN``
joints, scores above 1 (clipped), people without keypoints. What it read as
missing or clipped is counted in ``read_notes``
(:class:`~mirrorgraph.keypoints.ReadNotes`) of what it returns. Malformed input
(broken JSON, wrong types or counts, non-finite numbers a format never writes) is
refused with :class:`~mirrorgraph.errors.InputError` naming file, frame and
field. :func:`write_keypoints` and :func:`write_paired_npz` are the exact
inverses; all writes are atomic.
"""

from __future__ import annotations

import os

from ..errors import InputError
from ..keypoints import PairedKeypoints, RawDetections
from ..skeletons import Skeleton
from ._common import ProgressCallback, is_video_input
from .atomic import atomic_dir, atomic_path, atomic_write_bytes, atomic_write_text
from .calibration import read_json, to_jsonable, write_json
from .detect import classify_json, detect_format, sniff
from .easymocap import read_easymocap, write_easymocap
from .mmpose import detections_from_mmpose, read_mmpose, read_mmpose_folder, write_mmpose
from .npz import read_paired_npz, write_paired_npz
from .openpose import read_openpose, write_openpose

__all__ = [
    "read_keypoints", "write_keypoints", "write_paired_npz", "read_paired_npz",
    "detect_format", "classify_json", "read_mmpose", "read_mmpose_folder", "write_mmpose",
    "read_openpose", "write_openpose", "read_easymocap", "write_easymocap", "atomic_path",
    "atomic_dir", "atomic_write_bytes", "atomic_write_text", "read_json", "write_json",
    "to_jsonable",
]

_WRITERS = {"mmpose": write_mmpose, "openpose": write_openpose, "easymocap": write_easymocap}


def read_keypoints(path: str | os.PathLike, *, skeleton: Skeleton | str | None = None,
                   progress: ProgressCallback | None = None, video=None
                   ) -> RawDetections | PairedKeypoints:
    """Read keypoints in any supported format, detected from ``path``.

    Args:
        path: an MMPose ``.json`` file, a paired ``.npz`` file, an OpenPose /
            EasyMocap / MMPose per-image folder, or a video file (see
            :func:`mirrorgraph.video.detect_video`).
        skeleton: the keypoint layout (a :class:`Skeleton` or its name); by
            default found from the keypoint count. A video's layout is its model's.
        progress: ``progress(done, total)`` called per file of a folder, per frame of
            a video.
        video (mirrorgraph.video.VideoOptions | None): for a video (frame range,
            model, cache); ``None``: the defaults.

    Returns:
        :class:`RawDetections` (``.format`` names the format), or
        :class:`PairedKeypoints` for ``.npz`` (mirror labels already flipped);
        ``.read_notes`` counts what was read as missing or clipped.

    Raises:
        InputError: unknown format, or any malformed content.
    """
    # mirrorgraph.video is the video extra's path: imported for a video only
    if is_video_input(path):
        from ..video.detect import detect_video
        return detect_video(path, video, progress=progress).to_raw()
    kind, obj = sniff(path)
    if kind == "npz":
        return read_paired_npz(path, skeleton=skeleton)
    if kind == "mmpose":
        if obj is None:                                     # a folder of per-image files
            return read_mmpose_folder(path, skeleton=skeleton, progress=progress)
        return detections_from_mmpose(obj, source=str(path), skeleton=skeleton)
    if kind == "openpose":
        return read_openpose(path, skeleton=skeleton, progress=progress)
    return read_easymocap(path, skeleton=skeleton, progress=progress)


def write_keypoints(detections: RawDetections, path: str | os.PathLike, fmt: str, *,
                    track_ids=None, meta: bool = False) -> None:
    """Write detections as ``fmt``: ``"mmpose"`` (a ``.json`` file), ``"openpose"``
    or ``"easymocap"`` (a folder, replaced as a whole). Missing joints are written
    the format's way (``0, 0`` with confidence 0). ``track_ids`` (one int array a
    frame) go into MMPose's ``track_id`` and OpenPose's ``person_id``. ``meta``
    writes the image size and frame rate the detections carry (MMPose's
    ``meta_info``, OpenPose's sidecar: :mod:`.meta`), read back by
    :func:`read_keypoints`."""
    if fmt not in _WRITERS:
        raise InputError(f"unknown keypoint format {fmt!r}; known: {', '.join(_WRITERS)}",
                         field="fmt")
    kw = {}
    if track_ids is not None:
        if fmt == "easymocap":
            raise InputError("EasyMocap annotations hold no track ids", field="track_ids")
        kw["track_ids"] = track_ids
    if meta:
        if fmt == "easymocap":
            raise InputError("EasyMocap annotations hold no image size or frame rate",
                             field="meta")
        kw["meta"] = True
    _WRITERS[fmt](detections, path, **kw)
