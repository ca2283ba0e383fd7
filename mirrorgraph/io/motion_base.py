"""What the 3D motion writers share: the ``.trc`` axes, Pose2Sim's marker names, the
length units, evenly spaced frames and the checks of the arrays.

:mod:`mirrorgraph.io.motion` (``.npz``, ``.csv``, ``.trc`` and the dispatch on the
suffix), :mod:`mirrorgraph.io.c3d_writer` and :mod:`mirrorgraph.io.bvh_writer` use
these; the public names are re-exported by :mod:`mirrorgraph.io.motion`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

from ..errors import InputError

__all__ = ["CAMERA_FRAME", "TRC_FROM_CAMERA", "check_arrays", "metres_factor",
           "regular_frames", "to_trc_axes", "trc_marker_name", "trc_marker_names"]

#: ``(3, 3)`` rotation from the real camera frame to the ``.trc`` axes:
#: ``(X, Y, Z)_trc = TRC_FROM_CAMERA @ (x, y, z)_camera = (z, -y, x)``.
TRC_FROM_CAMERA = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])

#: The frame of ``.npz`` and ``.csv`` coordinates, in words.
CAMERA_FRAME = "real camera frame: x right, y down, z forward (OpenCV)"

#: Unit names accepted for ``.trc`` (always written in metres) and their factor to metres.
_METRES = {"m": 1.0, "metre": 1.0, "metres": 1.0, "meter": 1.0, "meters": 1.0,
           "cm": 0.01, "mm": 0.001}

#: Canonical names whose Pose2Sim / OpenSim marker name does not follow the general rule.
_MARKER_EXCEPTIONS = {"mid_hip": "CHip", "head_top": "Head"}


def trc_marker_name(joint: str) -> str:
    """Pose2Sim / OpenSim marker name of a canonical joint name.

    ``left_`` / ``right_`` become ``L`` / ``R``, the rest CamelCase
    (``left_small_toe -> LSmallToe``); ``mid_hip`` is ``CHip`` (BODY_25's name;
    :func:`trc_marker_names` gives HALPE_26's ``Hip``), ``head_top`` is ``Head``.
    """
    if joint in _MARKER_EXCEPTIONS:
        return _MARKER_EXCEPTIONS[joint]
    parts = [p for p in str(joint).split("_") if p]
    prefix = ""
    if parts and parts[0] in ("left", "right") and len(parts) > 1:
        prefix, parts = parts[0][0].upper(), parts[1:]
    return prefix + "".join(p[:1].upper() + p[1:] for p in parts)


def trc_marker_names(joint_names: Sequence[str]) -> list[str]:
    """Marker names of a whole layout (:func:`trc_marker_name` of each joint), with the
    mid-hip called ``Hip`` where the layout also has a head top (HALPE_26, as
    Pose2Sim names it) and ``CHip`` otherwise (BODY_25, COCO-18)."""
    names = [str(n) for n in joint_names]
    halpe = "head_top" in names
    return ["Hip" if (n == "mid_hip" and halpe) else trc_marker_name(n) for n in names]


def metres_factor(unit: str, path: str | os.PathLike | None = None) -> float:
    """The factor from ``unit`` (``m``, ``cm``, ``mm``, ...) to metres; a unit that is not a
    length (``"mirror distance"``, ``"subject height"``) raises :class:`InputError`."""
    factor = _METRES.get(str(unit).strip().lower())
    if factor is None:
        raise InputError(f"the 3D joints are in {unit!r}, not metres; this format needs metres "
                         "(calibrate with a metric prior such as the subject's height)",
                         source=path, field="unit")
    return factor


def to_trc_axes(X: np.ndarray) -> np.ndarray:
    """``(..., 3)`` camera-frame points in the ``.trc`` axes (Y up): ``(z, -y, x)``."""
    return np.asarray(X, float) @ TRC_FROM_CAMERA.T


def regular_frames(frame_ids: np.ndarray) -> tuple[np.ndarray, int]:
    """Evenly spaced frame numbers covering ``frame_ids`` (increasing), and their step.

    The step is the greatest common divisor of the gaps (``--every 3`` gives 3), so
    ``frame_ids`` is a subset of ``first, first + step, ..., last``; formats whose
    frames are evenly spaced in time (C3D, BVH) write one row for each.

    Returns:
        ``(rows, step)``: ``(T',)`` int64 frame numbers, int step >= 1.
    """
    ids = np.asarray(frame_ids, dtype=np.int64)
    gaps = np.diff(ids)
    if gaps.size and (gaps <= 0).any():
        raise ValueError("frame_ids must be increasing")
    step = int(np.gcd.reduce(gaps)) if gaps.size else 1
    step = max(step, 1)
    return np.arange(ids[0], ids[-1] + 1, step, dtype=np.int64), step


def check_arrays(joints3d, valid, frame_ids, joint_names, fps):
    """The writers' arguments checked: ``(X (T, J, 3) with NaN where invalid, ok (T, J),
    frame ids (T,) int64, names, fps or None)``; ``ValueError`` on inconsistent shapes,
    :class:`InputError` on a bad frame rate."""
    X = np.array(joints3d, dtype=float)
    if X.ndim != 3 or X.shape[2] != 3:
        raise ValueError(f"joints3d must have shape (T, J, 3), got {X.shape}")
    T, J = X.shape[:2]
    ok = np.isfinite(X).all(-1)
    if valid is not None:
        v = np.asarray(valid)
        if v.shape != (T, J):
            raise ValueError(f"valid must have shape {(T, J)}, got {v.shape}")
        ok &= v.astype(bool)
    if frame_ids is None:
        ids = np.arange(T, dtype=np.int64)
    else:
        ids = np.asarray(frame_ids)
        if ids.shape != (T,):
            raise ValueError(f"frame_ids must have shape {(T,)}, got {ids.shape}")
        if ids.dtype.kind not in "iu" and not np.all(np.mod(ids, 1) == 0):
            raise ValueError("frame_ids must be whole numbers")
        ids = ids.astype(np.int64)
    names = [str(n) for n in joint_names]
    if len(names) != J:
        raise ValueError(f"{len(names)} joint names for {J} joints")
    if fps is not None:
        fps = float(fps)
        if not (math.isfinite(fps) and fps > 0):
            raise InputError(f"frame rate must be a positive number, got {fps}", field="fps")
    X[~ok] = np.nan
    return X, ok, ids, names, fps
