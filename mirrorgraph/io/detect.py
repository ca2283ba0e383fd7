"""Tell the keypoint format of a path from its name and contents.

* a file ending ``.npz``: paired keypoints (:mod:`.npz`);
* a file ending ``.json``: MMPose predictions (:mod:`.mmpose`), checked by
  structure: a list of ``{"frame_id", "instances"}`` (the first entry holding at least
  one of the two keys), ``{"instance_info": [...]}``, or one image's list of
  instances (the first entry holding ``keypoints``);
* a folder: its ``*.json`` files are per-frame OpenPose files (``people`` with
  ``pose_keypoints_2d``, :mod:`.openpose`; Pose2Sim writes the same), EasyMocap
  annotations (``annots``, :mod:`.easymocap`) or the MMPose inferencer's per-image
  predictions (a list of instances, :func:`.mmpose.read_mmpose_folder`). Only the
  first file is parsed here; the reader checks that every other file has the same
  format.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..errors import InputError
from ._common import json_folder, load_json
from .mmpose import is_instance_list

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
        if is_instance_list(obj):
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
        doc = load_json(first)
        if is_instance_list(doc):
            return "mmpose", None
        kind = classify_json(doc)
        if kind == "mmpose":
            raise InputError(f"folder's JSON files (e.g. {first.name}) are MMPose video "
                             "predictions: pass one predictions file, not a folder",
                             source=path)
        if kind not in ("openpose", "easymocap"):
            raise InputError(f"folder's JSON files (e.g. {first.name}) are neither OpenPose "
                             "('people'), EasyMocap ('annots') nor MMPose per-image "
                             "predictions (a list of instances)", source=path)
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
                         "'instances'}, an object with 'instance_info', or a list of "
                         "instances", source=path)
    return kind, obj
