"""OpenPose ``--write_json`` output (and the tools writing its format): a folder of one JSON
file per frame.

File ``{stem}_{frame:012d}_keypoints.json`` (OpenPose) or ``{stem}_{frame:06d}.json``
(Pose2Sim)::

    {"version": 1.3,
     "people": [{"person_id": [-1],
                 "pose_keypoints_2d": [x0, y0, c0, x1, y1, c1, ...],   # 3 J numbers
                 "face_keypoints_2d": [], ...}],                      # other keys ignored
     "part_candidates": [...]}                                        # --part_candidates

As the tools write it (OpenPose's ``doc/02_output.md`` and ``fileStream.cpp``;
Pose2Sim's ``poseEstimation.py`` and ``common.py``; RTMLib's ``post_processings.py``):

* the layout is BODY_25 or BODY_25B (J = 25, told apart by
  :func:`mirrorgraph.skeleton_guess.guess_skeleton`), COCO-18, or from Pose2Sim / RTMLib
  COCO-17 or HALPE-26, by the count unless given;
* coordinates are pixels (OpenPose's default ``--keypoint_scale 0``);
* confidence 0 (OpenPose's ``0 0 0``) or negative (RTMLib) is missing, whatever the
  coordinates; a finite confidence above 1 (heat-map peaks up to ~1.41, OpenPose's
  https://github.com/CMU-Perceptual-Computing-Lab/openpose/issues/615; SimCC scores) is
  clipped to 1; both counted (:class:`~mirrorgraph.keypoints.ReadNotes`);
* Pose2Sim's ``NaN`` joints (a tracked person not seen) are missing, a person with
  nothing else is left out; any other non-finite number is an error naming file, frame
  and field;
* an empty ``pose_keypoints_2d`` is a person without body keypoints: left out, counted;
* an empty ``people`` is a frame with nobody.

The frame id is the last number in the file name; files are read in frame order, one at
a time. OpenPose files carry no image size and no frame rate; ``mirrorgraph detect
--format openpose`` writes both into a sidecar, :data:`.meta.SIDECAR` (not a ``.json``
name), read back here where present.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..keypoints import RawDetections
from ..skeletons import BODY_25, Skeleton
from ._common import (JointCount, ScorePolicy, Tally, check_writable_ids, clean_keypoints,
                      drop_empty_people, dump_json, frame_files, iter_frame_documents,
                      json_type, numeric_array, require, to_skeleton, zero_missing)
from ._common import ProgressCallback
from .atomic import atomic_dir
from .meta import SIDECAR, meta_info, read_sidecar

FORMAT = "openpose"
KEY = "pose_keypoints_2d"

#: OpenPose heat-map peaks or Pose2Sim's SimCC logits; Pose2Sim's NaN joints.
SCORES = ScorePolicy(negative_missing=True, max_confidence=np.inf, nan_missing=True)


def read_openpose(folder: str | os.PathLike, *,
                  skeleton: Skeleton | str | None = None,
                  progress: ProgressCallback | None = None) -> RawDetections:
    """Read an OpenPose JSON folder (see the module docstring)."""
    folder = Path(folder)
    counter = JointCount(to_skeleton(skeleton, source=folder), default=BODY_25)
    frame_ids, files = frame_files(folder)
    people: list[np.ndarray | None] = []
    tally = Tally()
    for t, file, obj in iter_frame_documents(folder, files, frame_ids, "OpenPose", "people",
                                             progress):
        persons = require(obj, "people", list, source=file, frame=t)
        people.append(_frame(persons, counter, tally, source=str(file), frame=t))
    skel = counter.result(people, source=folder)
    empty = np.empty((0, skel.num_joints, 3))
    tally.empty_frames = sum(p is None for p in people)
    size, fps = read_sidecar(folder)
    return RawDetections(skeleton=skel, frame_ids=frame_ids,
                         people=[empty.copy() if p is None else p for p in people],
                         source=str(folder), format=FORMAT, read_notes=tally.notes(),
                         image_size=size, fps=fps)


def _frame(persons: list, counter: JointCount, tally: Tally, *, source: str,
           frame: int) -> np.ndarray | None:
    """``(P, J, 3)`` keypoints of one file's ``people`` (``None`` if nobody is left)."""
    rows = []
    for p, person in enumerate(persons):
        field = f"people[{p}].{KEY}"
        if not isinstance(person, dict):
            raise InputError(f"expected an object, got {json_type(person)}",
                             source=source, frame=frame, field=f"people[{p}]")
        flat = numeric_array(require(person, KEY, list, source=source, frame=frame, field=field),
                             1, source=source, frame=frame, field=field)
        if len(flat) == 0:                   # body detector off: face / hands only
            tally.no_keypoints += 1
            continue
        if len(flat) % 3:
            raise InputError(f"{len(flat)} numbers, not a multiple of 3 (x, y, c)",
                             source=source, frame=frame, field=field)
        counter.check(len(flat) // 3, source=source, frame=frame, field=field)
        rows.append(flat.reshape(-1, 3))
    if not rows:
        return None
    kp = drop_empty_people(clean_keypoints(np.stack(rows), source=source, frame=frame,
                                           field="people", policy=SCORES, tally=tally), tally)
    return kp if len(kp) else None


def write_openpose(detections: RawDetections, folder: str | os.PathLike, *,
                   stem: str = "video", track_ids: list[np.ndarray] | None = None,
                   meta: bool = False) -> None:
    """Write one ``{stem}_{frame:012d}_keypoints.json`` per frame into ``folder``
    (with ``meta``, and the sidecar :data:`.meta.SIDECAR`: skeleton, image size, frame
    rate).

    ``track_ids`` (one int array a frame, one id a person) are written as each
    person's ``person_id`` (OpenPose's own tracker writes them there); without them
    ``person_id`` is ``[-1]``, OpenPose's "not tracked".

    The folder is built next to ``folder`` and renamed into place at the end, so a
    failure leaves no half-written output; an existing folder is replaced.
    """
    check_writable_ids(detections.frame_ids)
    empty_parts = {k: [] for k in ("face_keypoints_2d", "hand_left_keypoints_2d",
                                   "hand_right_keypoints_2d", "pose_keypoints_3d",
                                   "face_keypoints_3d", "hand_left_keypoints_3d",
                                   "hand_right_keypoints_3d")}
    with atomic_dir(folder) as tmp:
        for i, (t, people) in enumerate(zip(detections.frame_ids, detections.people)):
            z = zero_missing(people)
            ids = [-1] * len(z) if track_ids is None else [int(v) for v in track_ids[i]]
            doc = {"version": 1.3, "people": [
                {"person_id": [ids[p]], KEY: z[p].ravel().tolist(), **empty_parts}
                for p in range(len(z))]}
            (tmp / f"{stem}_{int(t):012d}_keypoints.json").write_text(dump_json(doc))
        if meta:
            (tmp / SIDECAR).write_text(dump_json(meta_info(detections)))
