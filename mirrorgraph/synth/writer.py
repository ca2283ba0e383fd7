"""Writing a synthetic scene to disk, and reading its ground truth back.

:func:`write_scene` produces, in ``out_dir``:

==============================  =====================================================
name (key of the returned dict)  content
==============================  =====================================================
``keypoints_mmpose.json``        detections, MMPose inferencer format (``"mmpose"``)
``openpose/``                    detections, one OpenPose JSON per frame (``"openpose"``)
``easymocap/``                   detections, EasyMocap annotations (``"easymocap"``)
``keypoints.npz``                the ground-truth pairing as the detector labelled it:
                                 mirror in the detector's labels, left/right swaps
                                 left in (``"npz"``)
``camera.json``                  ``{"K", "image_size", "dist"}`` (``dist`` only with
                                 distortion), readable by
                                 :func:`mirrorgraph.intrinsics.load_intrinsics`
``ground_truth.json``            mirror, virtual camera, K, subject, options, ...
``ground_truth_joints3d.npz``    ``joints3d`` (T, J, 3) m, ``frame_ids``, ``joint_names``
==============================  =====================================================
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..io import write_keypoints, write_paired_npz
from ..io.atomic import atomic_path
from ..io.calibration import read_json, write_json
from .camera import D_FLIP
from .scene import SyntheticScene

FORMATS = ("mmpose", "openpose", "easymocap", "npz")
_NAMES = {"mmpose": "keypoints_mmpose.json", "openpose": "openpose",
          "easymocap": "easymocap", "npz": "keypoints.npz"}
JOINTS3D_NAME = "ground_truth_joints3d.npz"


def write_scene(scene: SyntheticScene, out_dir: str | os.PathLike,
                formats: tuple[str, ...] | list[str] = FORMATS) -> dict[str, Path]:
    """Write the detections in ``formats``, the camera and the ground truth.

    Returns:
        paths by name: each format name, ``"camera"``, ``"ground_truth"`` and
        ``"joints3d"``.
    """
    unknown = [f for f in formats if f not in FORMATS]
    if unknown:
        raise ValueError(f"unknown format(s) {', '.join(map(repr, unknown))}; "
                         f"known: {', '.join(FORMATS)}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    for fmt in formats:
        p = out / _NAMES[fmt]
        if fmt == "npz":
            write_paired_npz(scene.paired(fix_lr=False), p, mirror_flipped=False)
        else:
            write_keypoints(scene.detections, p, fmt)
        paths[fmt] = p

    camera: dict[str, Any] = {"K": scene.K, "image_size": list(scene.image_size)}
    if scene.dist is not None:
        camera["dist"] = scene.dist
    paths["camera"] = out / "camera.json"
    write_json(paths["camera"], camera)

    paths["joints3d"] = out / JOINTS3D_NAME
    with atomic_path(paths["joints3d"]) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, joints3d=scene.joints3d,
                                frame_ids=np.asarray(scene.frame_ids, dtype=np.int64),
                                joint_names=np.array(scene.skeleton.joints))

    gt = {
        "mirror": {"normal": scene.normal, "distance": scene.distance},
        "virtual_camera": {"R": scene.virtual_R, "t": scene.virtual_t, "D": D_FLIP},
        "K": scene.K,
        "dist": scene.dist,
        "image_size": list(scene.image_size),
        "subject_height": scene.subject_height,
        "skeleton": scene.skeleton.name,
        "frames": len(scene),
        "fps": scene.fps,
        "seed": scene.seed,
        "options": scene.options,
        "joints3d": JOINTS3D_NAME,
        "truth": {
            "lr_swapped_frames": np.asarray(scene.frame_ids)[scene.lr_swapped],
            "lr_swapped_real_frames": np.asarray(scene.frame_ids)[scene.lr_swapped_real],
            "outlier_rate_real": float(scene.outlier_mask_real.mean()),
            "outlier_rate_mirror": float(scene.outlier_mask_mirror.mean()),
            "epipolar_outlier_rate_real": float(scene.epipolar_outlier_mask_real.mean()),
            "epipolar_outlier_rate_mirror": float(scene.epipolar_outlier_mask_mirror.mean()),
            "geometry": scene.placement.get("geometry"),
            "frames_without_person": int((~scene.real_detected).sum()),
            "frames_without_reflection": int((~scene.mirror_detected).sum()),
            "frames_with_extra_person": int(scene.extra_person.sum()),
            "facing": scene.placement.get("facing"),
        },
    }
    paths["ground_truth"] = out / "ground_truth.json"
    write_json(paths["ground_truth"], gt)
    return paths


def read_ground_truth(path: str | os.PathLike) -> dict[str, Any]:
    """Read ``ground_truth.json`` (or the folder holding it) with the 3D joints.

    Returns:
        the JSON content plus NumPy arrays: ``normal`` (3,), ``distance``,
        ``R`` (3, 3), ``t`` (3,), ``D`` (3, 3), ``K`` (3, 3), ``dist`` (5,) or
        ``None``, ``joints3d`` (T, J, 3), ``frame_ids`` (T,), ``joint_names`` (J,).
    """
    p = Path(path)
    if p.is_dir():
        p = p / "ground_truth.json"
    gt = read_json(p)
    out = dict(gt)
    out["normal"] = np.asarray(gt["mirror"]["normal"], dtype=float)
    out["distance"] = float(gt["mirror"]["distance"])
    vc = gt["virtual_camera"]
    out["R"] = np.asarray(vc["R"], dtype=float)
    out["t"] = np.asarray(vc["t"], dtype=float)
    out["D"] = np.asarray(vc.get("D", D_FLIP), dtype=float)
    out["K"] = np.asarray(gt["K"], dtype=float)
    out["dist"] = None if gt.get("dist") is None else np.asarray(gt["dist"], dtype=float)
    out["image_size"] = tuple(gt["image_size"])
    out.update(load_ground_truth_joints(p.parent, gt.get("joints3d")))
    return out


def load_ground_truth_joints(folder: Path, name: Any) -> dict[str, np.ndarray]:
    """``joints3d`` ``(T, J, 3)``, ``frame_ids`` and ``joint_names`` of the ground-truth
    ``.npz`` that a ``ground_truth.json`` names (``{}`` when it names none)."""
    if not isinstance(name, str):
        return {}
    with np.load(Path(folder) / name, allow_pickle=False) as z:
        return {"joints3d": z["joints3d"], "frame_ids": z["frame_ids"],
                "joint_names": z["joint_names"]}
