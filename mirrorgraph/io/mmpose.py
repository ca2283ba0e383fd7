"""MMPose predictions: one JSON file for a whole video, or one per image.

Layouts, as MMPose writes them (``mmpose/apis/inferencers/base_mmpose_inferencer.py``,
``mmpose/structures/utils.py`` ``split_instances``, the demo scripts'
``--save-predictions``)::

    # MMPoseInferencer(..., pred_out_dir=...) on a video: one file, frame_id from 0
    [{"frame_id": t,
      "instances": [{"keypoints": [[x, y], ...],        # (J, 2) pixels
                     "keypoint_scores": [s, ...],        # (J,), optional
                     "bbox": [[x1, y1, x2, y2]], "bbox_score": s}]},   # ignored
     ...]
    # the demo scripts on a video: the same list (frame_id from 1) under
    {"meta_info": {...}, "instance_info": [...]}
    # on images: one file per image (000012.json) holding its list of instances

``mirrorgraph detect`` writes the demo layout with its own ``meta_info`` (:mod:`.meta`);
the reader takes ``image_size`` and ``fps`` from any ``meta_info`` that holds them. A
single file of instances is one frame (id 0); a folder of per-image files is read like
an OpenPose folder (frame id = last number in the file name, one file at a time).

Scores (``mmpose/codecs/utils/post_processing.py``): heat-map peaks and RTMPose's SimCC
logit maxima exceed 1, and a keypoint not found has a score ``<= 0``
(https://github.com/open-mmlab/mmpose/issues/884, /2755, /3207). So a finite score above
1 is clipped to 1 and a score ``<= 0`` is missing, whatever the coordinates; both are
counted (:class:`~mirrorgraph.keypoints.ReadNotes`). Missing ``keypoint_scores`` mean
confidence 1. A non-finite number is an error naming file, frame and field; other keys
are ignored; an empty ``instances`` is a frame with nobody.

The layout is COCO-17 for the usual body models, taken from the keypoint count unless
given. The writer writes missing joints as ``[0, 0]`` with score 0. Frames are sorted by
``frame_id``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..keypoints import RawDetections
from ..skeletons import COCO_17, Skeleton
from ._common import (JointCount, ProgressCallback, ScorePolicy, Tally, bbox_of,
                      check_frame_ids, clean_keypoints, drop_empty_people, dump_json,
                      frame_files, holds_bool, json_type, load_json, numeric_array,
                      require, to_skeleton, zero_missing)
from .atomic import atomic_write_text
from .meta import meta_info, read_meta_info

FORMAT = "mmpose"

#: Heat-map peaks or SimCC logits: unbounded above, ``<= 0`` when not found, no NaN.
SCORES = ScorePolicy(negative_missing=True, max_confidence=np.inf)


def read_mmpose(path: str | os.PathLike, *,
                skeleton: Skeleton | str | None = None) -> RawDetections:
    """Read an MMPose predictions JSON file (see the module docstring)."""
    return detections_from_mmpose(load_json(path), source=str(path), skeleton=skeleton)


def is_instance_list(obj: Any) -> bool:
    """Whether a parsed document is one image's list of instances (empty, or its first
    entry an object with ``keypoints`` and no ``instances``)."""
    return isinstance(obj, list) and (not obj or (
        isinstance(obj[0], dict) and "keypoints" in obj[0] and "instances" not in obj[0]
        and "frame_id" not in obj[0]))


def detections_from_mmpose(obj: Any, *, source: str,
                           skeleton: Skeleton | str | None = None) -> RawDetections:
    """Convert parsed MMPose predictions to :class:`RawDetections`.

    Args:
        obj: the parsed JSON: a list of frames, ``{"instance_info": [...]}`` of
            frames, or one image's instances (either way; frame id 0).
        source: the file name, for error messages and ``RawDetections.source``.
        skeleton: the keypoint layout; by default found from the keypoint count.
    """
    frames = require(obj, "instance_info", list, source=source) if isinstance(obj, dict) else obj
    size, fps = None, None
    if isinstance(obj, dict) and "meta_info" in obj:
        size, fps = read_meta_info(obj["meta_info"], source=source)
    if not isinstance(frames, list):
        raise InputError(f"expected a list of frames, got {json_type(obj)}", source=source)
    if frames and is_instance_list(frames):          # one image
        frames = [{"frame_id": 0, "instances": frames}]
    out = _read_at_once(frames, skeleton, source)
    if out is None:                                  # something to name: frame by frame
        out = _read_frames(frames, skeleton, source)
    out.image_size, out.fps = size, fps
    return out


def _read_frames(frames: list, skeleton: Skeleton | str | None, source: str) -> RawDetections:
    """:func:`detections_from_mmpose`'s frames read one at a time, every entry checked (the
    error names the first wrong one: frame, person, field)."""
    counter = JointCount(to_skeleton(skeleton, source=source), default=COCO_17)
    tally = Tally()
    ids: list[int] = []
    people: list[np.ndarray | None] = []
    for i, frame in enumerate(frames):
        if not isinstance(frame, dict):
            raise InputError(f"frame entry {i} is {json_type(frame)}, not an object",
                             source=source)
        t = require(frame, "frame_id", int, source=source, context=f" in frame entry {i}")
        instances = require(frame, "instances", list, source=source, frame=t)
        ids.append(t)
        people.append(_frame(instances, counter, tally, source=source, frame=t))
    frame_ids, order = check_frame_ids(ids, source=source)
    return _detections(people, order, frame_ids, counter, tally, source)


def _read_at_once(frames: list, skeleton: Skeleton | str | None, source: str
                  ) -> RawDetections | None:
    """:func:`_read_frames` vectorised over every instance of the file, where every frame
    entry and instance is well formed (the usual file: ~10x faster on 16,000 frames);
    ``None`` where anything is not (the frame-by-frame reading then names it).

    Every instance's keypoints and scores are converted as one array and cleaned at once
    (:func:`~._common.clean_keypoints`: the same elementwise rules and counts), the
    people without a joint seen dropped, and the rows split back into frames.
    """
    ids: list[int] = []
    counts: list[int] = []
    xy_lists: list = []
    score_lists: list = []
    for frame in frames:
        if type(frame) is not dict:
            return None
        t, instances = frame.get("frame_id"), frame.get("instances")
        if type(t) is not int or type(instances) is not list:
            return None
        ids.append(t)
        counts.append(len(instances))
        for inst in instances:
            if type(inst) is not dict:
                return None
            xy = inst.get("keypoints")
            sc = inst["keypoint_scores"] if "keypoint_scores" in inst else [1.0] * len(xy or ())
            if type(xy) is not list or type(sc) is not list:
                return None
            xy_lists.append(xy)
            score_lists.append(sc)
    if not xy_lists:
        return None
    try:
        xy, sc = np.asarray(xy_lists), np.asarray(score_lists)
    except (ValueError, TypeError):
        return None
    if (xy.dtype.kind not in "iuf" or sc.dtype.kind not in "iuf" or xy.ndim != 3
            or xy.shape[2] != 2 or sc.shape != xy.shape[:2]
            or holds_bool(xy_lists, xy.shape) or holds_bool(score_lists, sc.shape)):
        return None
    counter = JointCount(to_skeleton(skeleton, source=source), default=COCO_17)
    tally = Tally()
    try:
        frame_ids, order = check_frame_ids(ids, source=source)
        counter.check(xy.shape[1], source=source, frame=None, field="instances")
        kp = clean_keypoints(np.concatenate([xy, sc[..., None]], axis=-1).astype(float),
                             source=source, frame=None, field="instances", policy=SCORES,
                             tally=tally)
    except InputError:
        return None
    seen = (kp[..., 2] > 0).any(-1)
    tally.no_joints += int(np.count_nonzero(~seen))
    frame_of = np.repeat(np.arange(len(counts)), counts)
    kept, rows = np.bincount(frame_of[seen], minlength=len(counts)), kp[seen]
    edges = np.concatenate([[0], np.cumsum(kept)]).tolist()
    people: list[np.ndarray | None] = [rows[a:b] if b > a else None
                                       for a, b in zip(edges[:-1], edges[1:])]
    return _detections(people, order, frame_ids, counter, tally, source)


def read_mmpose_folder(folder: str | os.PathLike, *, skeleton: Skeleton | str | None = None,
                       progress: ProgressCallback | None = None) -> RawDetections:
    """Read a folder of the inferencer's per-image predictions (see the module docstring).

    Each ``*.json`` holds one image's list of instances; the frame id is the last
    number of its name. A file holding anything else is refused as a mixed folder.
    """
    folder = Path(folder)
    counter = JointCount(to_skeleton(skeleton, source=folder), default=COCO_17)
    frame_ids, files = frame_files(folder)
    tally = Tally()
    people: list[np.ndarray | None] = []
    for i, (t, file) in enumerate(zip(frame_ids.tolist(), files)):
        if progress is not None:
            progress(i + 1, len(files))
        obj = load_json(file)
        if not is_instance_list(obj):
            raise InputError("not an MMPose per-image predictions file (a list of "
                             f"instances); folder {folder} mixes formats or holds other "
                             "JSON files", source=file)
        people.append(_frame(obj, counter, tally, source=str(file), frame=t,
                             field="instances"))
    return _detections(people, np.arange(len(files)), frame_ids, counter, tally, str(folder))


def _frame(instances: list, counter: JointCount, tally: Tally, *, source: str, frame: int,
           field: str = "instances") -> np.ndarray | None:
    """``(P, J, 3)`` cleaned keypoints of one frame's instances (``None`` if nobody)."""
    persons = [_person(inst, p, counter, source=source, frame=frame, field=field)
               for p, inst in enumerate(instances)]
    if not persons:
        return None
    kp = drop_empty_people(clean_keypoints(np.stack(persons), source=source, frame=frame,
                                           field=field, policy=SCORES, tally=tally), tally)
    return kp if len(kp) else None


def _detections(people: list, order: np.ndarray, frame_ids: np.ndarray, counter: JointCount,
                tally: Tally, source: str) -> RawDetections:
    skel = counter.result(people, source=source)
    empty = np.empty((0, skel.num_joints, 3))
    tally.empty_frames = sum(p is None for p in people)
    return RawDetections(skeleton=skel, frame_ids=frame_ids,
                         people=[empty.copy() if people[i] is None else people[i] for i in order],
                         source=source, format=FORMAT, read_notes=tally.notes())


def _person(inst: Any, p: int, counter: JointCount, *, source: str, frame: int,
            field: str = "instances") -> np.ndarray:
    """``(J, 3)`` x, y, score of one instance, types and counts checked."""
    field = f"{field}[{p}]"
    if not isinstance(inst, dict):
        raise InputError(f"expected an object, got {json_type(inst)}", source=source,
                         frame=frame, field=field)
    xy = numeric_array(require(inst, "keypoints", list, source=source, frame=frame,
                               field=f"{field}.keypoints"),
                       2, source=source, frame=frame, field=f"{field}.keypoints")
    if xy.shape[1] != 2:
        raise InputError(f"expected [x, y] pairs, got rows of {xy.shape[1]}", source=source,
                         frame=frame, field=f"{field}.keypoints")
    counter.check(len(xy), source=source, frame=frame, field=f"{field}.keypoints")
    if "keypoint_scores" in inst:
        scores = numeric_array(inst["keypoint_scores"], 1, source=source, frame=frame,
                               field=f"{field}.keypoint_scores")
        if len(scores) != len(xy):
            raise InputError(f"{len(scores)} scores for {len(xy)} keypoints", source=source,
                             frame=frame, field=f"{field}.keypoint_scores")
    else:
        scores = np.ones(len(xy))
    return np.column_stack([xy, scores])


def write_mmpose(detections: RawDetections, path: str | os.PathLike, *,
                 track_ids: list[np.ndarray] | None = None, meta: bool = False) -> None:
    """Write :class:`RawDetections` as an MMPose predictions JSON file, atomically.

    ``track_ids`` (one int array a frame, one id a person) are written as each
    instance's ``track_id`` (the key MMPose's pose-tracking demo writes; the reader
    ignores it). With ``meta`` the file is the demo scripts' layout,
    ``{"meta_info", "instance_info"}``, ``meta_info`` holding the skeleton, image
    size and frame rate (:func:`.meta.meta_info`); else the inferencer's list of frames.
    """
    frames = []
    for i, (t, people) in enumerate(zip(detections.frame_ids, detections.people)):
        z = zero_missing(people)
        inst = [{"keypoints": z[p, :, :2].tolist(), "keypoint_scores": z[p, :, 2].tolist(),
                 "bbox": [bbox_of(people[p])], "bbox_score": 1.0} for p in range(len(z))]
        if track_ids is not None:
            for p, ident in enumerate(track_ids[i]):
                inst[p]["track_id"] = int(ident)
        frames.append({"frame_id": int(t), "instances": inst})
    doc = {"meta_info": meta_info(detections), "instance_info": frames} if meta else frames
    atomic_write_text(path, dump_json(doc))
