"""What a keypoint file knows about its video: image size and frame rate.

``mirrorgraph detect`` writes them with the keypoints, so that ``calibrate`` and
``calibrate-rig`` read them back instead of asking (``--image-size``) or assuming
(30 fps):

* MMPose predictions: the demo scripts' layout ``{"meta_info": {...},
  "instance_info": [...]}`` (MMPose's ``demo/topdown_demo_with_mmdet.py``
  ``--save-predictions`` writes the pose model's ``dataset_meta`` there:
  ``dataset_name``, ``num_keypoints``, ``keypoint_id2name``, ``flip_indices``, ...;
  it holds no image size or frame rate). mirrorgraph writes those of its keys
  that apply and adds ``image_size`` ``[width, height]`` px, ``fps`` and
  ``source`` (the video);
* OpenPose folders (one file a frame, no place for either): a sidecar
  :data:`SIDECAR` in the folder holding the same object. Its name does not end in
  ``.json``, so that tools reading every ``*.json`` of the folder as a frame
  (Pose2Sim, mirrorgraph's own reader) pass it by.

Both keys are optional on reading; a present one must be valid (two positive
integers; a positive finite number), else one line names file and field.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..keypoints import RawDetections
from ._common import json_type

__all__ = ["SIDECAR", "meta_info", "read_meta_info"]

#: The sidecar of an OpenPose folder (a JSON object, see the module docstring).
SIDECAR = "meta_info.txt"


def meta_info(detections: RawDetections) -> dict:
    """The ``meta_info`` object of a file written from ``detections``: the skeleton
    in MMPose's ``dataset_meta`` keys, and image size, frame rate and source where
    ``detections`` carry them."""
    sk = detections.skeleton
    out: dict[str, Any] = {"dataset_name": sk.name, "num_keypoints": sk.num_joints,
                           "keypoint_id2name": {str(i): n for i, n in enumerate(sk.joints)},
                           "flip_indices": [int(i) for i in sk.flip]}
    if detections.image_size is not None:
        out["image_size"] = [int(v) for v in detections.image_size]
    if detections.fps is not None:
        out["fps"] = float(detections.fps)
    if detections.source:
        out["source"] = str(detections.source)
    return out


def read_meta_info(meta: Any, *, source: Any, field: str = "meta_info"
                   ) -> tuple[tuple[int, int] | None, float | None]:
    """``(image_size (w, h) or None, fps or None)`` of a parsed ``meta_info`` object.

    Raises:
        InputError: ``meta`` is no object, or a present ``image_size`` / ``fps`` is
            invalid (naming ``source`` and the field).
    """
    from ..intrinsics import check_size
    if not isinstance(meta, dict):
        raise InputError(f"expected an object, got {json_type(meta)}", source=source,
                         field=field)
    size = meta.get("image_size")
    if size is not None:
        if not isinstance(size, list) or len(size) != 2:
            raise InputError(f"expected [width, height], got {json_type(size)}"
                             + (f" of {len(size)}" if isinstance(size, list) else ""),
                             source=source, field=f"{field}.image_size")
        size = check_size(size[0], size[1], source, f"{field}.image_size")
    fps = meta.get("fps")
    if fps is not None:
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) \
                or not (math.isfinite(fps) and fps > 0):
            raise InputError(f"frame rate must be a positive number, got {fps!r}",
                             source=source, field=f"{field}.fps")
        fps = float(fps)
    return size, fps


def read_sidecar(folder: Path) -> tuple[tuple[int, int] | None, float | None]:
    """Image size and frame rate of a folder's :data:`SIDECAR` (``(None, None)``
    without one)."""
    from ._common import load_json
    path = Path(folder) / SIDECAR
    if not path.is_file():
        return None, None
    return read_meta_info(load_json(path), source=path, field="meta_info")
