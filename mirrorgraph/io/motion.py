"""3D motion out: joints over time as ``.npz``, ``.csv`` or OpenSim ``.trc``.

:func:`write_joints3d` picks the format from the file suffix; every write is
atomic.

=========== ================================================================
format      content
=========== ================================================================
``.npz``    ``joints3d`` ``(T, J, 3)`` float (NaN where invalid), ``valid``
            ``(T, J)`` bool, ``frame_ids`` ``(T,)`` int64, ``joint_names``
            ``(J,)`` str, ``fps`` float (NaN if unknown), ``unit`` str,
            ``frame`` str (the coordinate frame, in words). Real camera frame.
``.csv``    header ``frame,time,<joint>_x,<joint>_y,<joint>_z,...`` (canonical
            joint names), one row per frame; ``time = frame / fps`` (empty if
            the frame rate is unknown); empty fields where a joint is invalid.
            Real camera frame, the unit of the data.
``.trc``    OpenSim marker file as Pose2Sim writes it (below). Metres, Y up.
=========== ================================================================

TRC layout (tab-separated; Pose2Sim's ``make_trc`` structure)::

    PathFileType  4  (X/Y/Z)  <file name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame
        OrigNumFrames                                       (one line)
    <fps>  <fps>  <T>  <J>  m  <fps>  <first frame>  <T>
    Frame#  Time  <marker 1>      <marker 2> ...
                  X1  Y1  Z1  X2  Y2  Z2 ...
    <frame>  <time>  <x>  <y>  <z> ...

``Frame#`` is the input's frame number and ``Time = frame / fps`` (as Pose2Sim
does). A marker that is missing in a frame has its three fields left empty,
which OpenSim reads as a missing marker (NaN).

Marker names: Pose2Sim's / OpenSim's names for the detector keypoints,
``L``/``R`` prefix and CamelCase: ``left_knee -> LKnee``, ``right_hip -> RHip``,
``left_big_toe -> LBigToe``, ``nose -> Nose``, ``neck -> Neck``; the head top
(BODY_25B, HALPE_26) is ``Head``; the mid-hip is ``CHip`` in BODY_25 / COCO-18
and ``Hip`` in HALPE_26, as in Pose2Sim's skeletons and OpenSim marker sets (the
layouts with a head top are the ones that call it ``Hip``; pass ``marker_names``
to override, :func:`trc_marker_names`). COCO-17 has neither neck nor mid-hip;
Pose2Sim's COCO_17 model does not need them.

Axes: OpenSim's ground frame has Y up (X forward, Z to the right); the real
camera frame has y *down*. The ``.trc`` holds ``(X, Y, Z) = (z, -y, x)`` of the
camera frame: X is the depth away from the camera, Y up, Z to the right of
the image. It is a proper rotation (lengths and handedness kept) and exactly
what Pose2Sim writes (after its Z-up to Y-up step) when it triangulates with the
``world="z_up"`` export of :func:`mirrorgraph.export.export_calibration`. "Up"
is the camera's up: a tilted camera gives a correspondingly tilted ground.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from .atomic import atomic_path, atomic_write_text

__all__ = ["write_joints3d", "write_joints3d_npz", "write_joints3d_csv", "write_trc",
           "trc_marker_name", "trc_marker_names", "TRC_FROM_CAMERA", "CAMERA_FRAME"]

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


def _check(joints3d, valid, frame_ids, joint_names, fps):
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


def write_joints3d(path: str | os.PathLike, joints3d: np.ndarray, valid: np.ndarray | None,
                   frame_ids: np.ndarray | None, joint_names: Sequence[str],
                   fps: float | None, unit: str = "m", *,
                   marker_names: Sequence[str] | None = None) -> None:
    """Write 3D joints over time; the format follows the suffix of ``path``.

    Args:
        path: ``.npz``, ``.csv`` or ``.trc`` file (see the module docstring).
        joints3d: ``(T, J, 3)`` joints in the real camera frame.
        valid: ``(T, J)`` bool, joints to write (``None``: every finite one);
            non-finite joints are always invalid.
        frame_ids: ``(T,)`` frame numbers (``None``: ``0 .. T-1``).
        joint_names: ``(J,)`` canonical joint names (``left_knee``, ...).
        fps: frame rate in Hz, or ``None`` if unknown (refused for ``.trc``).
        unit: the unit of ``joints3d``: ``"m"`` with a metric scale, otherwise
            e.g. ``"mirror distance"``. ``.trc`` takes only ``m``, ``cm``, ``mm``
            (converted to metres).
        marker_names: ``.trc`` only: marker names to use instead of
            :func:`trc_marker_name` of ``joint_names``.

    Raises:
        InputError: unknown suffix, ``.trc`` without a frame rate or in a
            non-metric unit, bad frame rate.
        ValueError: arrays of inconsistent shapes.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".npz":
        write_joints3d_npz(path, joints3d, valid, frame_ids, joint_names, fps, unit)
    elif suffix == ".csv":
        write_joints3d_csv(path, joints3d, valid, frame_ids, joint_names, fps)
    elif suffix == ".trc":
        write_trc(path, joints3d, valid, frame_ids, joint_names, fps, unit,
                  marker_names=marker_names)
    else:
        raise InputError(f"unknown 3D motion format {suffix or '(no suffix)'!r}: use .npz, "
                         ".csv or .trc", source=path)


def write_joints3d_npz(path: str | os.PathLike, joints3d: np.ndarray, valid: np.ndarray | None,
                       frame_ids: np.ndarray | None, joint_names: Sequence[str],
                       fps: float | None, unit: str = "m") -> None:
    """``.npz`` with ``joints3d``, ``valid``, ``frame_ids``, ``joint_names``, ``fps``,
    ``unit`` and ``frame`` (see the module docstring)."""
    X, ok, ids, names, fps = _check(joints3d, valid, frame_ids, joint_names, fps)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, joints3d=X, valid=ok, frame_ids=ids,
                                joint_names=np.array(names, dtype=str),
                                fps=np.float64(np.nan if fps is None else fps),
                                unit=np.array(str(unit)), frame=np.array(CAMERA_FRAME))


def write_joints3d_csv(path: str | os.PathLike, joints3d: np.ndarray, valid: np.ndarray | None,
                       frame_ids: np.ndarray | None, joint_names: Sequence[str],
                       fps: float | None) -> None:
    """``.csv``: ``frame,time,<joint>_x,<joint>_y,<joint>_z,...``; empty where invalid."""
    X, ok, ids, names, fps = _check(joints3d, valid, frame_ids, joint_names, fps)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["frame", "time"] + [f"{n}_{a}" for n in names for a in "xyz"])
    for t in range(len(ids)):
        row = [str(int(ids[t])), "" if fps is None else repr(float(ids[t]) / fps)]
        for j in range(len(names)):
            row += [repr(float(v)) for v in X[t, j]] if ok[t, j] else ["", "", ""]
        w.writerow(row)
    atomic_write_text(path, buf.getvalue())


def write_trc(path: str | os.PathLike, joints3d: np.ndarray, valid: np.ndarray | None,
              frame_ids: np.ndarray | None, joint_names: Sequence[str], fps: float | None,
              unit: str = "m", *, marker_names: Sequence[str] | None = None) -> None:
    """OpenSim ``.trc`` in metres, Y up (see the module docstring for layout and axes)."""
    X, ok, ids, names, fps = _check(joints3d, valid, frame_ids, joint_names, fps)
    if fps is None:
        raise InputError("a .trc file needs the frame rate", source=path, field="fps")
    factor = _METRES.get(str(unit).strip().lower())
    if factor is None:
        raise InputError(f"the 3D joints are in {unit!r}, not metres; OpenSim needs metres "
                         "(calibrate with a metric prior such as the subject's height)",
                         source=path, field="unit")
    markers = trc_marker_names(names) if marker_names is None \
        else [str(m) for m in marker_names]
    if len(markers) != len(names):
        raise ValueError(f"{len(markers)} marker names for {len(names)} joints")
    Y = factor * (X @ TRC_FROM_CAMERA.T)
    T, J = len(ids), len(names)
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{Path(path).name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        "OrigDataStartFrame\tOrigNumFrames",
        "\t".join([f"{fps:g}", f"{fps:g}", str(T), str(J), "m", f"{fps:g}",
                   str(int(ids[0]) if T else 0), str(T)]),
        "Frame#\tTime\t" + "\t\t\t".join(markers) + "\t\t\t",
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, J + 1)) + "\t",
    ]
    for t in range(T):
        fields = [str(int(ids[t])), f"{ids[t] / fps:.6f}"]
        for j in range(J):
            fields += [f"{v:.6f}" for v in Y[t, j]] if ok[t, j] else ["", "", ""]
        lines.append("\t".join(fields))
    atomic_write_text(path, "\n".join(lines) + "\n")
