"""MMPose inferencer predictions: one JSON file for a whole video.

Layout (``MMPoseInferencer(..., pred_out_dir=...)`` on a video)::

    [{"frame_id": t,
      "instances": [{"keypoints": [[x, y], ...],        # (J, 2) pixels
                     "keypoint_scores": [s, ...],        # (J,) in [0, 1], optional
                     "bbox": [[x1, y1, x2, y2]],         # pixels, ignored on reading
                     "bbox_score": s}]},                 # ignored on reading
     ...]

MMPose's demo scripts write the same list under ``"instance_info"`` of a top
level object (next to ``"meta_info"``, which is ignored); both are read.

The keypoint layout is COCO-17 for the usual body models; it is taken from the
keypoint count unless given. Missing ``keypoint_scores`` mean confidence 1. A
joint of score 0 is missing (``NaN`` coordinates); the writer writes missing
joints as ``[0, 0]`` with score 0. Frames are sorted by ``frame_id``.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..errors import InputError
from ..keypoints import RawDetections
from ..skeletons import COCO_17, Skeleton
from ._common import (JointCount, bbox_of, check_frame_ids, clean_keypoints, dump_json,
                      json_type, load_json, numeric_array, require, to_skeleton,
                      zero_missing)
from .atomic import atomic_write_text

FORMAT = "mmpose"


def read_mmpose(path: str | os.PathLike, *,
                skeleton: Skeleton | str | None = None) -> RawDetections:
    """Read an MMPose predictions JSON file (see the module docstring)."""
    return detections_from_mmpose(load_json(path), source=str(path), skeleton=skeleton)


def detections_from_mmpose(obj: Any, *, source: str,
                           skeleton: Skeleton | str | None = None) -> RawDetections:
    """Convert parsed MMPose predictions to :class:`RawDetections`.

    Args:
        obj: the parsed JSON (list of frames, or ``{"instance_info": [...]}``).
        source: the file name, for error messages and ``RawDetections.source``.
        skeleton: the keypoint layout; by default found from the keypoint count.
    """
    frames = require(obj, "instance_info", list, source=source) if isinstance(obj, dict) else obj
    if not isinstance(frames, list):
        raise InputError(f"expected a list of frames, got {json_type(obj)}", source=source)
    counter = JointCount(to_skeleton(skeleton, source=source), default=COCO_17)
    ids: list[int] = []
    people: list[np.ndarray | None] = []
    for i, frame in enumerate(frames):
        if not isinstance(frame, dict):
            raise InputError(f"frame entry {i} is {json_type(frame)}, not an object",
                             source=source)
        t = require(frame, "frame_id", int, source=source, context=f" in frame entry {i}")
        instances = require(frame, "instances", list, source=source, frame=t)
        persons = [_person(inst, p, counter, source=source, frame=t)
                   for p, inst in enumerate(instances)]
        ids.append(t)
        people.append(clean_keypoints(np.stack(persons), source=source, frame=t,
                                      field="instances") if persons else None)
    frame_ids, order = check_frame_ids(ids, source=source)
    skel = counter.result(people, source=source)
    empty = np.empty((0, skel.num_joints, 3))
    return RawDetections(skeleton=skel, frame_ids=frame_ids,
                         people=[empty.copy() if people[i] is None else people[i] for i in order],
                         source=source, format=FORMAT)


def _person(inst: Any, p: int, counter: JointCount, *, source: str, frame: int) -> np.ndarray:
    """``(J, 3)`` x, y, score of one instance, types and counts checked."""
    field = f"instances[{p}]"
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


def write_mmpose(detections: RawDetections, path: str | os.PathLike) -> None:
    """Write :class:`RawDetections` as an MMPose predictions JSON file, atomically."""
    frames = []
    for t, people in zip(detections.frame_ids, detections.people):
        z = zero_missing(people)
        frames.append({"frame_id": int(t), "instances": [
            {"keypoints": z[p, :, :2].tolist(), "keypoint_scores": z[p, :, 2].tolist(),
             "bbox": [bbox_of(people[p])], "bbox_score": 1.0} for p in range(len(z))]})
    atomic_write_text(path, dump_json(frames))
