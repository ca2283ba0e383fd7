"""Writers of a calibrated rig: Pose2Sim's ``calibration.toml`` and the rig JSON.

The TOML holds one section per real camera, named after it: ``name``, ``size``,
``matrix``, ``distortions`` (as given), ``rotation`` (Rodrigues vector) and
``translation`` of the world-to-camera transform, ``fisheye = false``. Pose2Sim
reads it as a checkerboard calibration (``[metadata] adjusted = false``).
With ``with_virtual``, every view of a camera through a mirror is added as the
camera of the horizontally flipped image, section ``<camera>_<mirror>``: matrix
``K'`` with ``cx -> W - cx``, distortion with ``p2`` negated
(:mod:`mirrorgraph.export`), extrinsics :func:`mirrorgraph.rigs.virtual_extrinsics`.
Its keypoints are the reflection flipped the same way
(:func:`mirrorgraph.export.flip_mirror_keypoints`).

Translations are in metres when the rig was calibrated with a subject height;
otherwise in units of the subject's height, which the header says.
"""

from __future__ import annotations

import os

import numpy as np

from ..export import rig_cameras
from ..rigs.result import RigCalibration
from .calibration import write_json
from .camera_toml import TomlCamera, write_camera_toml

__all__ = ["rig_toml_cameras", "write_rig_toml", "write_rig_json"]


def rig_toml_cameras(calib: RigCalibration, *, with_virtual: bool = False) -> list[TomlCamera]:
    """The cameras of the TOML file, in order (real cameras, then virtual ones): the one
    construction of every camera file, :func:`mirrorgraph.export.rig_cameras`, in
    Pose2Sim's style with the first camera's frame as the world.

    Raises:
        InputError: a camera without an image size (Pose2Sim needs it).
    """
    return rig_cameras(calib, "pose2sim", with_virtual=with_virtual)


def write_rig_toml(calib: RigCalibration, path: str | os.PathLike, *,
                   with_virtual: bool = False) -> None:
    """Write Pose2Sim's ``calibration.toml`` of the rig (atomically)."""
    cams = rig_toml_cameras(calib, with_virtual=with_virtual)
    rms = [c.reprojection_rms_px for c in calib.cameras if np.isfinite(c.reprojection_rms_px)]
    unit = ("metres" if calib.scale == "subject_height"
            else "subject heights (no subject height given: NOT metres)")
    header = (f"Calibrated by mirrorgraph from the people in view ({calib.source}).\n"
              f"World frame: camera {calib.cameras[0].name}. Translation unit: {unit}.")
    if with_virtual:
        header += ("\nSections <camera>_<mirror> are virtual cameras of the horizontally "
                   "flipped image (u -> W - u); give them the reflection's keypoints flipped "
                   "the same way, left/right labels swapped.")
    write_camera_toml(path, cams, "pose2sim", error=float(np.mean(rms)) if rms else 0.0,
                      header=header)


def write_rig_json(calib: RigCalibration, path: str | os.PathLike) -> None:
    """Write the rig JSON (:meth:`RigCalibration.to_dict`), atomically."""
    write_json(path, calib.to_dict())
