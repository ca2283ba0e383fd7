"""EasyMocap / Mirrored-Human 2D annotations: a folder of one JSON file per frame.

File ``{frame:06d}.json`` (``annots/<camera>/`` of an EasyMocap dataset)::

    {"filename": "images/<camera>/000012.jpg", "height": H, "width": W,
     "annots": [{"personID": 0,
                 "bbox": [x1, y1, x2, y2, c],          # 5 numbers, or 7 (Mirrored-Human)
                 "keypoints": [[x, y, c], ...],        # (J, 3) pixels
                 "isKeyframe": false, ...}],           # other keys ignored
     "isKeyframe": false}

As EasyMocap's tools (``annot2string``, ``read_annot``, ``load_openpose``) and
Mirrored-Human's ``data/sample-videos.zip`` write it:

* the layout is BODY_25 (``doc/dataset.md``); COCO-17 and COCO-18 are accepted by count;
* ``[0, 0, 0]``, confidence 0, or a negative confidence (Mirrored-Human's ``-1`` for a
  joint the annotator left out) is missing, whatever the coordinates, and counted
  (:class:`~mirrorgraph.keypoints.ReadNotes`);
* confidences up to 1.5 are clipped to 1 and counted (heat-map peaks; Mirrored-Human up
  to 1.057), beyond that refused;
* a person entry without ``keypoints`` (nor ``keypoints2d``) holds only a ``bbox``: left
  out and counted, as a person whose every joint is missing;
* ``bbox``, ``personID`` (mirrorgraph tells the person from the reflection itself),
  hands, face and other keys are ignored; an empty ``annots`` is a frame with nobody;
* any non-finite number is an error naming file, frame and field.

The frame id is the last number in the file name; ``width``/``height`` give the image
size (optional, but equal across files). Files are read in frame order, one at a time.
Sources in full: ``docs/internals.md``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..keypoints import RawDetections
from ..skeletons import BODY_25, Skeleton
from ._common import (MAX_IMAGE_SIDE, JointCount, ScorePolicy, Tally, bbox_of,
                      check_writable_ids, clean_keypoints, drop_empty_people, dump_json,
                      frame_files, iter_frame_documents, json_type, numeric_array, require,
                      to_skeleton, zero_missing)
from ._common import ProgressCallback
from .atomic import atomic_dir

FORMAT = "easymocap"

#: Heat-map confidences, ``[0, 0, -1]`` for a joint left out, no NaN.
SCORES = ScorePolicy(negative_missing=True)

#: Keys of a person's body keypoints, in the order ``read_annot`` looks for them.
KEYPOINT_KEYS = ("keypoints", "keypoints2d")


def read_easymocap(folder: str | os.PathLike, *,
                   skeleton: Skeleton | str | None = None,
                   progress: ProgressCallback | None = None) -> RawDetections:
    """Read an EasyMocap annots folder (see the module docstring)."""
    folder = Path(folder)
    counter = JointCount(to_skeleton(skeleton, source=folder), default=BODY_25)
    frame_ids, files = frame_files(folder)
    people: list[np.ndarray | None] = []
    image_size: tuple[int, int] | None = None
    tally = Tally()
    for t, file, obj in iter_frame_documents(folder, files, frame_ids, "EasyMocap", "annots",
                                             progress):
        size = _image_size(obj, source=str(file), frame=t)
        if size is not None:
            if image_size is not None and size != image_size:
                raise InputError(f"image size {size[0]}x{size[1]} differs from "
                                 f"{image_size[0]}x{image_size[1]} in earlier files",
                                 source=file, frame=t,
                                 field="width" if size[0] != image_size[0] else "height")
            image_size = size
        annots = require(obj, "annots", list, source=file, frame=t)
        people.append(_frame(annots, counter, tally, source=str(file), frame=t))
    skel = counter.result(people, source=folder)
    empty = np.empty((0, skel.num_joints, 3))
    tally.empty_frames = sum(p is None for p in people)
    return RawDetections(skeleton=skel, frame_ids=frame_ids,
                         people=[empty.copy() if p is None else p for p in people],
                         source=str(folder), format=FORMAT, image_size=image_size,
                         read_notes=tally.notes())


def _image_size(obj: dict, *, source: str, frame: int) -> tuple[int, int] | None:
    """``(width, height)`` if the file has both, checked to be positive ints."""
    if "width" not in obj and "height" not in obj:
        return None
    w = require(obj, "width", int, source=source, frame=frame)
    h = require(obj, "height", int, source=source, frame=frame)
    if w <= 0 or h <= 0:
        raise InputError(f"image size {w}x{h} is not positive", source=source, frame=frame,
                         field="width" if w <= 0 else "height")
    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE:
        raise InputError(f"image size {w}x{h} is beyond {MAX_IMAGE_SIDE} px", source=source,
                         frame=frame, field="width" if w > MAX_IMAGE_SIDE else "height")
    return w, h


def _frame(annots: list, counter: JointCount, tally: Tally, *, source: str,
           frame: int) -> np.ndarray | None:
    """``(P, J, 3)`` keypoints of one file's ``annots`` (``None`` if nobody is left)."""
    rows = []
    for p, annot in enumerate(annots):
        if not isinstance(annot, dict):
            raise InputError(f"expected an object, got {json_type(annot)}",
                             source=source, frame=frame, field=f"annots[{p}]")
        key = next((k for k in KEYPOINT_KEYS if k in annot), None)
        if key is None:                      # a bounding box only
            tally.no_keypoints += 1
            continue
        field = f"annots[{p}].{key}"
        kp = numeric_array(require(annot, key, list, source=source, frame=frame,
                                   field=field), 2, source=source, frame=frame, field=field)
        if kp.shape[1] != 3:
            raise InputError(f"expected [x, y, c] triples, got rows of {kp.shape[1]}",
                             source=source, frame=frame, field=field)
        counter.check(len(kp), source=source, frame=frame, field=field)
        rows.append(kp)
    if not rows:
        return None
    kp = drop_empty_people(clean_keypoints(np.stack(rows), source=source, frame=frame,
                                           field="annots", policy=SCORES, tally=tally), tally)
    return kp if len(kp) else None


def write_easymocap(detections: RawDetections, folder: str | os.PathLike) -> None:
    """Write one ``{frame:06d}.json`` per frame into ``folder``, atomically as a whole.

    ``height``/``width`` are written when ``detections.image_size`` is known.
    """
    check_writable_ids(detections.frame_ids)
    size = {}
    if detections.image_size is not None:
        size = {"height": int(detections.image_size[1]), "width": int(detections.image_size[0])}
    with atomic_dir(folder) as tmp:
        for t, people in zip(detections.frame_ids, detections.people):
            z = zero_missing(people)
            annots = [{"personID": p, "keypoints": z[p].tolist(),
                       "bbox": [*bbox_of(people[p]), 1.0], "isKeyframe": False}
                      for p in range(len(z))]
            doc = {"filename": f"images/{int(t):06d}.jpg", **size, "annots": annots}
            (tmp / f"{int(t):06d}.json").write_text(dump_json(doc))
