"""Files of the synthetic rigs of :mod:`.rig` (re-exported there).

:func:`write_rig` writes a rig as a user of ``mirrorgraph calibrate-rig`` would
have it (keypoints, ``Calib.toml``, ``rig.toml``) next to the ground truth
(world = camera 0's frame, metres; intrinsics in pixels);
:func:`read_rig_ground_truth` reads the ground truth back.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..io import write_keypoints
from ..io.atomic import atomic_path, atomic_write_text
from ..io.calibration import read_json, write_json
from ..io.camera_toml import TomlCamera, rotation_to_rodrigues, write_camera_toml
from ..io.toml_writer import format_value
from ..rigs.config import RIG_FILE
from .rig_types import SyntheticRig
from .writer import load_ground_truth_joints

__all__ = ["write_rig", "read_rig_ground_truth"]

JOINTS3D_NAME = "joints3d.npz"
GROUND_TRUTH_NAME = "ground_truth.json"
RIG_NAME = RIG_FILE
CALIB_NAME = "Calib.toml"
#: Keypoint formats :func:`write_rig` writes the cameras' detections in (``fmt``).
KEYPOINT_FORMATS = ("openpose", "mmpose", "easymocap")


def _keypoints_path(camera: str, fmt: str) -> str:
    return f"pose/{camera}.json" if fmt == "mmpose" else f"pose/{camera}_json"


def _rig_toml(rig: SyntheticRig, fmt: str, include_height: bool) -> str:
    """The text of ``rig.toml`` (arrays of tables written here: the package's TOML
    writer does not do them; every value goes through its ``format_value``)."""
    lines = [f"# synthetic {rig.kind} rig (mirrorgraph.synth.make_rig, seed {rig.seed}); "
             "paths relative to this file", ""]
    if include_height:
        lines += [f"subject_height = {format_value(float(rig.subject_height))}", ""]
    for name in rig.camera_names:
        entry: dict[str, Any] = dict(name=name, keypoints=_keypoints_path(name, fmt),
                                     intrinsics=CALIB_NAME, intrinsics_section=name,
                                     skeleton=rig.skeleton.name)
        if rig.sees[name]:
            entry["mirrors"] = list(rig.sees[name])
        entry["frame_offset"] = 0
        lines.append("[[cameras]]")
        lines += [f"{k} = {format_value(v)}" for k, v in entry.items()]
        lines.append("")
    for name in rig.mirror_names:
        lines += ["[[mirrors]]", f"name = {format_value(name)}", ""]
    return "\n".join(lines).rstrip("\n") + "\n"


def write_rig(rig: SyntheticRig, out_dir: str | os.PathLike, fmt: str = "openpose", *,
              include_height: bool = True) -> Path:
    """Write a rig as a user of ``mirrorgraph calibrate-rig`` would have it, with the truth.

    Writes into ``out_dir``:

    ========================  ==========================================================
    ``pose/<camera>_json/``   each camera's detections (``fmt`` ``"openpose"`` or
                              ``"easymocap"``); ``pose/<camera>.json`` for ``"mmpose"``
    ``Calib.toml``            every camera's intrinsics, Pose2Sim's format, one section
                              per camera named after it; rotation and translation are
                              zero (the extrinsics are what is to be found)
    ``rig.toml``              the rig file (``subject_height`` only with
                              ``include_height``)
    ``ground_truth.json``     kind, skeleton, subject height, camera poses
                              (camera-to-world and Pose2Sim's world-to-camera
                              ``rvec``/``tvec``), mirrors, what each camera sees
    ``joints3d.npz``          ``joints3d`` (T, J, 3) world metres, ``frame_ids``,
                              ``joint_names``; with bystanders also
                              ``bystanders_joints3d`` (B, T, J, 3)
    ========================  ==========================================================

    With bystanders ``ground_truth.json`` also lists them (``bystanders``: name,
    height, the frames they are in the room); their detections are in the
    keypoint files with the subject's, as a detector would give them.

    Returns:
        the path of ``rig.toml``.
    """
    if fmt not in KEYPOINT_FORMATS:
        raise ValueError(f"unknown keypoint format {fmt!r}; known: "
                         f"{', '.join(KEYPOINT_FORMATS)}")
    out = Path(out_dir)
    (out / "pose").mkdir(parents=True, exist_ok=True)
    for name in rig.camera_names:
        write_keypoints(rig.detections[name], out / _keypoints_path(name, fmt), fmt)

    write_camera_toml(
        out / CALIB_NAME,
        [TomlCamera(key=name, name=name, matrix=K, distortions=np.zeros(4),
                    size=tuple(rig.image_size)) for name, K in zip(rig.camera_names, rig.K)],
        "pose2sim",
        header="Intrinsics of the cameras of a synthetic rig (mirrorgraph.synth.write_rig).\n"
               "rotation and translation are placeholders (zero): the extrinsics are unknown.")

    extra = {}
    if rig.bystanders:                              # only then: rigs without them write no key
        extra["bystanders_joints3d"] = np.stack([b.joints3d for b in rig.bystanders])
    with atomic_path(out / JOINTS3D_NAME) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, joints3d=rig.joints3d,
                                frame_ids=np.asarray(rig.frame_ids, dtype=np.int64),
                                joint_names=np.array(rig.skeleton.joints), **extra)

    cameras = []
    for name, K, P in zip(rig.camera_names, rig.K, rig.poses):
        R, t = rig.world_to_camera(name)
        cameras.append({
            "name": name, "K": K, "image_size": list(rig.image_size),
            "camera_to_world": P, "R": R, "rvec": rotation_to_rodrigues(R), "tvec": t,
            "centre": P[:3, 3], "sees": list(rig.sees[name]),
            "keypoints": _keypoints_path(name, fmt),
            "frames_detected": {v.name: int(v.detected.sum())
                                for v in rig.views[name].values()},
        })
    mirrors = [{"name": name, "normal": n, "distance": d,
                "limits": [{"a": a, "b": b} for a, b in rig.mirror_limits.get(name, [])]}
               for name, (n, d) in zip(rig.mirror_names, rig.mirrors)]
    gt = {
        "kind": rig.kind,
        "skeleton": rig.skeleton.name,
        "subject_height": rig.subject_height,
        "frames": len(rig),
        "fps": rig.fps,
        "seed": rig.seed,
        "world": "camera 0's frame (x right, y down, z forward), metres; camera_to_world "
                 "maps camera to world coordinates; R, rvec, tvec: X_cam = R X + tvec "
                 "(Pose2Sim); mirror n . X = d, n pointing away from camera 0",
        "cameras": cameras,
        "mirrors": mirrors,
        "options": rig.options,
        "placement": rig.placement,
        "joints3d": JOINTS3D_NAME,
    }
    if rig.bystanders:
        gt["bystanders"] = [{"name": b.name, "height": b.height,
                             "frames_present": np.flatnonzero(b.present).tolist(),
                             "joints3d": f"{JOINTS3D_NAME}:bystanders_joints3d[{i}]"}
                            for i, b in enumerate(rig.bystanders)]
    write_json(out / GROUND_TRUTH_NAME, gt)
    rig_path = out / RIG_NAME
    atomic_write_text(rig_path, _rig_toml(rig, fmt, include_height))
    return rig_path


def read_rig_ground_truth(path: str | os.PathLike) -> dict[str, Any]:
    """Read a rig's ``ground_truth.json`` (or the folder holding it, or its ``rig.toml``).

    Returns:
        the JSON content plus NumPy arrays: ``camera_names`` (list),
        ``poses`` (C, 4, 4) camera-to-world, ``K`` (C, 3, 3), ``R`` (C, 3, 3) and
        ``tvec`` (C, 3) world-to-camera, ``rvec`` (C, 3), ``mirror_names``
        (list), ``normals`` (M, 3), ``distances`` (M,), ``sees`` (camera ->
        mirror names), ``joints3d`` (T, J, 3), ``frame_ids`` (T,),
        ``joint_names`` (J,), ``image_size`` (tuple); for a rig with bystanders
        also ``bystanders_joints3d`` (B, T, J, 3).
    """
    p = Path(path)
    if p.is_dir():
        p = p / GROUND_TRUTH_NAME
    elif p.suffix.lower() == ".toml":
        p = p.parent / GROUND_TRUTH_NAME
    gt = read_json(p)
    out = dict(gt)
    cams = gt["cameras"]
    out["camera_names"] = [c["name"] for c in cams]
    out["poses"] = np.array([c["camera_to_world"] for c in cams], dtype=float).reshape(-1, 4, 4)
    out["K"] = np.array([c["K"] for c in cams], dtype=float).reshape(-1, 3, 3)
    out["R"] = np.array([c["R"] for c in cams], dtype=float).reshape(-1, 3, 3)
    out["rvec"] = np.array([c["rvec"] for c in cams], dtype=float).reshape(-1, 3)
    out["tvec"] = np.array([c["tvec"] for c in cams], dtype=float).reshape(-1, 3)
    out["image_size"] = tuple(cams[0]["image_size"]) if cams else None
    out["sees"] = {c["name"]: list(c["sees"]) for c in cams}
    out["mirror_names"] = [m["name"] for m in gt["mirrors"]]
    out["normals"] = np.array([m["normal"] for m in gt["mirrors"]], dtype=float).reshape(-1, 3)
    out["distances"] = np.array([m["distance"] for m in gt["mirrors"]], dtype=float)
    out["subject_height"] = float(gt["subject_height"])
    out.update(load_ground_truth_joints(p.parent, gt.get("joints3d")))
    if gt.get("bystanders") and isinstance(gt.get("joints3d"), str):
        with np.load(p.parent / gt["joints3d"], allow_pickle=False) as z:
            out["bystanders_joints3d"] = z["bystanders_joints3d"]
    return out
