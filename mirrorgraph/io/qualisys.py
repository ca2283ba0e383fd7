"""Qualisys Track Manager camera calibrations (``.qca.txt``), as ground truth.

The Pose2Sim demo trials ship their cameras' Qualisys calibration; the real-data
benchmark (``bench/bench_real.py``) and the video tests compare with it. The file
is XML: one ``<camera serial=...>`` a camera with

* ``<fov_video left top right bottom>``: the video window on the sensor, px;
* ``<transform x y z r11 ... r33>``: the camera's position in the world (mm) and a
  rotation whose rows, as written, turned 180 deg about the camera's x axis, are
  the world -> camera rotation of an OpenCV camera (x right, y down, z forward);
* ``<intrinsic focalLengthU/V centerPointU/V radialDistortion1-3
  tangentalDistortion1-2>``: focal length and principal point in 1/64 px of the
  sensor (the principal point is taken relative to the video window), distortion
  coefficients.

These are the conventions of Pose2Sim's converter (``Pose2Sim/calibration.py``,
``read_qca`` and ``calib_qca_fun``: rows transposed twice, ``world_to_camera_persp``,
``rotate_cam(ang_x=pi)``), read there and written here anew. Pose2Sim also divides
the distortion coefficients by 64; ``distortion_divisor`` reproduces that (on the
demo videos the difference moves the reprojection of detected joints by < 0.1 px).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["QualisysCamera", "read_qca"]


@dataclass(frozen=True)
class QualisysCamera:
    """One camera of a Qualisys calibration, in OpenCV's conventions.

    Attributes:
        name: the camera's serial (``cam01``).
        K: ``(3, 3)`` camera matrix, px.
        dist: ``(4,)`` ``k1, k2, p1, p2``.
        R: ``(3, 3)`` world -> camera rotation.
        t: ``(3,)`` world -> camera translation, metres.
        size: ``(width, height)`` of the video window, px.
    """

    name: str
    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    size: tuple[int, int]

    @property
    def centre(self) -> np.ndarray:
        """``(3,)`` camera centre in the world, metres."""
        return -self.R.T @ self.t

    @property
    def pose(self) -> np.ndarray:
        """``(4, 4)`` camera-to-world."""
        P = np.eye(4)
        P[:3, :3], P[:3, 3] = self.R.T, self.centre
        return P

    @property
    def projection(self) -> np.ndarray:
        """``(3, 4)`` ``K [R | t]`` (undistorted pixels)."""
        return self.K @ np.hstack([self.R, self.t[:, None]])


def _num(attrs: dict, key: str, source: Path, where: str) -> float:
    try:
        v = float(attrs[key])
    except KeyError:
        raise InputError("missing", source=source, field=f"{where}.{key}") from None
    except ValueError:
        raise InputError(f"not a number: {attrs[key]!r}", source=source,
                         field=f"{where}.{key}") from None
    if not np.isfinite(v):
        raise InputError("not finite", source=source, field=f"{where}.{key}")
    return v


def read_qca(path: str | os.PathLike, *, distortion_divisor: float = 1.0
             ) -> dict[str, QualisysCamera]:
    """Every camera of a ``.qca.txt`` file by serial, in file order (see the module
    docstring). InputError names the file and field of anything malformed."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise InputError("no such file", source=path) from None
    except ET.ParseError as exc:
        raise InputError(f"not valid XML: {exc}", source=path) from None
    turn = np.diag([1.0, -1.0, -1.0])                   # 180 deg about the camera's x axis
    out: dict[str, QualisysCamera] = {}
    for i, cam in enumerate(root.iter("camera")):
        name = cam.attrib.get("serial") or f"camera{i + 1}"
        parts = {k: cam.find(k) for k in ("fov_video", "transform", "intrinsic")}
        for k, el in parts.items():
            if el is None:
                raise InputError("missing", source=path, field=f"{name}.{k}")
        fov, tr, it = (parts[k].attrib for k in ("fov_video", "transform", "intrinsic"))
        n = lambda a, k, w: _num(a, k, path, f"{name}.{w}")  # noqa: E731
        R_rows = np.array([[n(tr, f"r{r}{c}", "transform") for c in (1, 2, 3)] for r in (1, 2, 3)])
        centre = np.array([n(tr, k, "transform") for k in "xyz"]) / 1000.0
        R = turn @ R_rows
        left, top = n(fov, "left", "fov_video"), n(fov, "top", "fov_video")
        size = (int(round(n(fov, "right", "fov_video") - left + 1)),
                int(round(n(fov, "bottom", "fov_video") - top + 1)))
        K = np.array([[n(it, "focalLengthU", "intrinsic") / 64, 0.0,
                       n(it, "centerPointU", "intrinsic") / 64 - left],
                      [0.0, n(it, "focalLengthV", "intrinsic") / 64,
                       n(it, "centerPointV", "intrinsic") / 64 - top],
                      [0.0, 0.0, 1.0]])
        dist = np.array([n(it, k, "intrinsic") for k in
                         ("radialDistortion1", "radialDistortion2", "tangentalDistortion1",
                          "tangentalDistortion2")]) / distortion_divisor
        out[name] = QualisysCamera(name=name, K=K, dist=dist, R=R, t=-R @ centre, size=size)
    if not out:
        raise InputError("holds no <camera>", source=path)
    return out
