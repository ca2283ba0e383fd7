"""3D motion out: joints over time as ``.npz``, ``.csv``, OpenSim ``.trc``, C3D or BVH.

:func:`write_joints3d` picks the format from the file suffix; every write is atomic.

* ``.npz``: ``joints3d`` ``(T, J, 3)`` float (NaN where invalid), ``valid`` ``(T, J)``
  bool, ``frame_ids`` ``(T,)`` int64, ``joint_names`` ``(J,)`` str, ``fps`` float (NaN if
  unknown), ``unit`` str, ``frame`` str; with uncertainty, ``joints_std`` ``(T, J)``, and
  where the scale is the subject's, ``joints_std_shape`` ``(T, J)`` (the same without the
  metric scale's share) and ``scale_rel_std`` float (that share: the scale's relative std,
  one factor on every length). Real camera frame.
* ``.csv``: ``frame,time,<joint>_x,<joint>_y,<joint>_z,...``, one row a frame,
  ``time = frame / fps``, empty fields where a joint is invalid. Real camera frame.
* ``.trc``: OpenSim marker file as Pose2Sim's ``make_trc`` writes it, tab-separated,
  metres, Y up; ``Frame#`` the input's frame number, ``Time = frame / fps``; a missing
  marker has empty fields (OpenSim reads NaN). No field for a marker's uncertainty.
* ``.c3d``: the ``.trc``'s markers and axes in millimetres, each joint's std as its
  point's residual (:mod:`mirrorgraph.io.c3d_writer`, ``c3d`` extra).
* ``.bvh``: a hierarchy with one length a bone and joint rotations
  (:mod:`mirrorgraph.io.bvh_writer`).

Marker names (:func:`trc_marker_names`): Pose2Sim's / OpenSim's, ``L``/``R`` prefix and
CamelCase (``left_knee -> LKnee``, ``nose -> Nose``), the head top ``Head``, the mid-hip
``CHip`` (BODY_25, COCO-18) or ``Hip`` (HALPE_26).

Axes: the ``.trc`` holds ``(X, Y, Z) = (z, -y, x)`` of the real camera frame
(:data:`TRC_FROM_CAMERA`): X the depth away from the camera, Y up (the camera's up),
Z to the right; a proper rotation, what Pose2Sim writes with the ``world="z_up"`` export
of :func:`mirrorgraph.export.export_calibration`. The TRC header line by line:
``docs/internals.md``.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from .archive import savez
from .atomic import atomic_path, atomic_write_text
from .motion_base import (CAMERA_FRAME, TRC_FROM_CAMERA, metres_factor, regular_frames,
                          to_trc_axes, trc_marker_name, trc_marker_names)
from .motion_base import check_arrays as _check

__all__ = ["write_joints3d", "write_joints3d_npz", "write_joints3d_csv", "write_trc",
           "trc_marker_name", "trc_marker_names", "TRC_FROM_CAMERA", "CAMERA_FRAME",
           "MOTION_SUFFIXES", "METRIC_SUFFIXES", "check_motion_path", "metres_factor",
           "regular_frames", "to_trc_axes"]

#: The file suffixes :func:`write_joints3d` writes.
MOTION_SUFFIXES = (".npz", ".csv", ".trc", ".c3d", ".bvh")
#: Those whose format needs metres (a metric scale: a subject height).
METRIC_SUFFIXES = (".trc", ".c3d", ".bvh")
_FORMAT_NAMES = {".trc": "OpenSim .trc", ".c3d": "C3D", ".bvh": "BVH"}


def check_motion_path(path: str | os.PathLike, metric: bool | None) -> None:
    """Refuse, before a long run, a 3D joints file :func:`write_joints3d` cannot write:
    an unknown suffix, or a format in metres (:data:`METRIC_SUFFIXES`) when ``metric`` is
    ``False`` (no subject height; ``None``: not known yet), or ``.c3d`` without the
    ``c3d`` package."""
    suffix = Path(path).suffix.lower()
    if suffix not in MOTION_SUFFIXES:
        raise InputError("must end in " + ", ".join(MOTION_SUFFIXES[:-1]) + " or "
                         + MOTION_SUFFIXES[-1], source=path)
    if suffix in METRIC_SUFFIXES and metric is False:
        raise InputError(f"{_FORMAT_NAMES[suffix]} needs metres (a subject height)",
                         field="joints3d", fix=("subject_height",))
    if suffix == ".c3d":
        from .c3d_writer import require_c3d
        require_c3d()                    # MissingExtraError with the install hint


def write_joints3d(path: str | os.PathLike, joints3d: np.ndarray, valid: np.ndarray | None,
                   frame_ids: np.ndarray | None, joint_names: Sequence[str],
                   fps: float | None, unit: str = "m", *,
                   marker_names: Sequence[str] | None = None,
                   joints_std: np.ndarray | None = None,
                   joints_std_shape: np.ndarray | None = None,
                   scale_rel_std: float | None = None) -> None:
    """Write 3D joints over time; the format follows the suffix of ``path``.

    Args:
        path: ``.npz``, ``.csv``, ``.trc``, ``.c3d`` or ``.bvh`` file (see the module
            docstring).
        joints3d: ``(T, J, 3)`` joints in the real camera frame.
        valid: ``(T, J)`` bool, joints to write (``None``: every finite one);
            non-finite joints are always invalid.
        frame_ids: ``(T,)`` frame numbers (``None``: ``0 .. T-1``).
        joint_names: ``(J,)`` canonical joint names (``left_knee``, ...).
        fps: frame rate in Hz, or ``None`` if unknown (refused for ``.trc``, ``.c3d``,
            ``.bvh``).
        unit: the unit of ``joints3d``: ``"m"`` with a metric scale, otherwise
            e.g. ``"mirror distance"``. ``.trc``, ``.c3d`` and ``.bvh`` take only
            ``m``, ``cm``, ``mm`` (converted to their own unit).
        marker_names: ``.trc`` and ``.c3d`` only: marker names to use instead of
            :func:`trc_marker_name` of ``joint_names``.
        joints_std: ``(T, J)`` each joint's std in ``unit``: ``.npz`` (``joints_std``)
            and ``.c3d`` (the points' residuals) only; the other formats have no place
            for it.
        joints_std_shape, scale_rel_std: ``.npz`` only: ``joints_std`` without the
            metric scale's share ``(T, J)``, and that share, the scale's relative std
            (``joints_std^2 = joints_std_shape^2 + (scale_rel_std |X|)^2`` for a joint
            ``X``, the camera the scale's fixed point).

    Raises:
        InputError: unknown suffix, ``.trc`` / ``.c3d`` / ``.bvh`` without a frame
            rate or in a non-metric unit, bad frame rate.
        MissingExtraError: ``.c3d`` without the ``c3d`` package.
        ValueError: arrays of inconsistent shapes.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".npz":
        write_joints3d_npz(path, joints3d, valid, frame_ids, joint_names, fps, unit,
                           joints_std=joints_std, joints_std_shape=joints_std_shape,
                           scale_rel_std=scale_rel_std)
    elif suffix == ".csv":
        write_joints3d_csv(path, joints3d, valid, frame_ids, joint_names, fps)
    elif suffix == ".trc":
        write_trc(path, joints3d, valid, frame_ids, joint_names, fps, unit,
                  marker_names=marker_names)
    elif suffix == ".c3d":
        from .c3d_writer import write_c3d
        write_c3d(path, joints3d, valid, frame_ids, joint_names, fps, unit,
                  marker_names=marker_names, joints_std=joints_std)
    elif suffix == ".bvh":
        from .bvh_writer import write_bvh
        write_bvh(path, joints3d, valid, frame_ids, joint_names, fps, unit)
    else:
        raise InputError(f"unknown 3D motion format {suffix or '(no suffix)'!r}: use "
                         + ", ".join(MOTION_SUFFIXES), source=path)


def write_joints3d_npz(path: str | os.PathLike, joints3d: np.ndarray, valid: np.ndarray | None,
                       frame_ids: np.ndarray | None, joint_names: Sequence[str],
                       fps: float | None, unit: str = "m", *,
                       joints_std: np.ndarray | None = None,
                       joints_std_shape: np.ndarray | None = None,
                       scale_rel_std: float | None = None) -> None:
    """``.npz`` with ``joints3d``, ``valid``, ``frame_ids``, ``joint_names``, ``fps``,
    ``unit`` and ``frame``, and ``joints_std``, ``joints_std_shape``, ``scale_rel_std``
    where given (see the module docstring)."""
    X, ok, ids, names, fps = _check(joints3d, valid, frame_ids, joint_names, fps)
    extra = {}
    for key, value in (("joints_std", joints_std), ("joints_std_shape", joints_std_shape)):
        if value is not None:
            std = np.asarray(value, dtype=float)
            if std.shape != ok.shape:
                raise ValueError(f"{key} has shape {std.shape}, the joints {ok.shape}")
            extra[key] = np.where(ok, std, np.nan)
    if scale_rel_std is not None:
        extra["scale_rel_std"] = np.float64(scale_rel_std)
    with atomic_path(path) as tmp:
        savez(tmp, dict(joints3d=X, valid=ok, frame_ids=ids,
                        joint_names=np.array(names, dtype=str),
                        fps=np.float64(np.nan if fps is None else fps),
                        unit=np.array(str(unit)), frame=np.array(CAMERA_FRAME), **extra))


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
    factor = metres_factor(unit, path)
    markers = trc_marker_names(names) if marker_names is None \
        else [str(m) for m in marker_names]
    if len(markers) != len(names):
        raise ValueError(f"{len(markers)} marker names for {len(names)} joints")
    Y = factor * to_trc_axes(X)
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
