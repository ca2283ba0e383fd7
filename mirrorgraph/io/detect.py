"""Tell the keypoint format of a path from its name and contents.

* a file ending ``.npz``: paired keypoints (:mod:`.npz`);
* a file ending ``.json``: MMPose predictions (:mod:`.mmpose`), checked by
  structure: a list of ``{"frame_id", "instances"}`` (the first entry holding at least
  one of the two keys) or ``{"instance_info": [...]}``;
* a folder: its ``*.json`` files are per-frame OpenPose files (``people`` with
  ``pose_keypoints_2d``, :mod:`.openpose`) or EasyMocap annotations (``annots``,
  :mod:`.easymocap`). Only the first file is parsed here; the reader checks that
  every other file has the same format.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..errors import InputError
from ._common import json_folder, load_json

FORMATS = ("mmpose", "openpose", "easymocap", "npz")


def classify_json(obj: Any) -> str | None:
    """The format of one parsed JSON document, or ``None`` if it is none of ours."""
    if isinstance(obj, dict):
        if "instance_info" in obj:
            return "mmpose"
        if "people" in obj:
            return "openpose"
        if "annots" in obj:
            return "easymocap"
    elif isinstance(obj, list):
        # a first entry with either key is MMPose's: the reader then names what is missing
        if not obj or (isinstance(obj[0], dict) and ("instances" in obj[0]
                                                      or "frame_id" in obj[0])):
            return "mmpose"
    return None


def detect_format(path: str | os.PathLike) -> str:
    """``"mmpose"``, ``"openpose"``, ``"easymocap"`` or ``"npz"``; InputError otherwise."""
    return sniff(path)[0]


def sniff(path: str | os.PathLike) -> tuple[str, Any]:
    """``(format, parsed JSON or None)``: the parsed document of a ``.json`` file is
    returned so that it need not be parsed twice."""
    path = Path(path)
    if path.is_dir():
        first = json_folder(path)[0]
        kind = classify_json(load_json(first))
        if kind not in ("openpose", "easymocap"):
            raise InputError(f"folder's JSON files (e.g. {first.name}) are neither OpenPose "
                             "('people') nor EasyMocap ('annots') frame files", source=path)
        return kind, None
    if not path.exists():
        raise InputError("no such file or folder", source=path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return "npz", None
    if suffix != ".json":
        raise InputError("unknown keypoint format: expected an MMPose .json file, a paired "
                         ".npz file, or an OpenPose / EasyMocap folder", source=path)
    obj = load_json(path)
    kind = classify_json(obj)
    if kind in ("openpose", "easymocap"):
        raise InputError(f"a single {kind} frame file: pass the folder holding every frame",
                         source=path)
    if kind is None:
        raise InputError("not MMPose predictions: expected a list of {'frame_id', "
                         "'instances'} or an object with 'instance_info'", source=path)
    return kind, obj
