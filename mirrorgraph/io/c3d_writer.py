"""3D motion out as a C3D file, the biomechanics lab format (Vicon, Visual3D, OpenSim
through Pose2Sim's converters), written with the ``c3d`` package (the ``c3d`` extra).

What is in the file, as Pose2Sim's ``common.create_c3d_file`` writes it from a
``.trc`` (read, not copied):

* the points are the ``.trc``'s markers: Pose2Sim's marker names
  (:func:`mirrorgraph.io.motion.trc_marker_names`: ``LKnee``, ``CHip``, ...) and its
  axes, Y up (``(X, Y, Z) = (z, -y, x)`` of the real camera frame,
  :data:`mirrorgraph.io.motion.TRC_FROM_CAMERA`);
* in **millimetres** (``POINT:UNITS = "mm"``), ``POINT:X_SCREEN = +Z``,
  ``POINT:Y_SCREEN = +Y``; no analog channels;
* the point rate is the frame rate of the motion.

Two differences, both for fidelity: the points are stored as 32-bit floats
(``POINT:SCALE`` negative; Pose2Sim's ``point_scale=1.0`` stores 16-bit integers of
1 mm, which rounds every marker by up to 0.5 mm), and a joint missing in a frame
is written as C3D's invalid point (residual ``-1``) rather than NaN.

**Residuals**: given each joint's std (``joints_std``, the run's
:attr:`~mirrorgraph.pipelines.mirror.CalibrationRun.joints_std`), a valid point's
residual is that std in millimetres; otherwise 0 (C3D's "no estimate"). C3D stores a
residual as one byte times ``|POINT:SCALE|`` (the scale applies to nothing else for
float points), which readers (``c3d``, ``ezc3d``) return in the point's unit: the
scale is ``-s`` with ``s`` the smallest whole number of millimetres that holds the
largest std in 255 steps (``s = 1``: steps of 1 mm up to 255 mm), every residual at
least one step (a residual of 0 marks a modelled point). C3D counts
frames from 1 at the point rate: the first frame (``TRIAL:ACTUAL_START_FIELD`` and
the header) is ``f // step + 1`` for the input's first frame number ``f``, so that
C3D frame ``k`` is at time ``(k - 1) / rate`` as frame ``f`` is at ``f / fps``
(readers that count from 0, such as ezc3d, report ``f // step``).

C3D frames are evenly spaced: frame numbers with gaps (frames without a pair)
become rows with every marker invalid; frame numbers in steps of ``k``
(``--every k``) give a point rate of ``fps / k``
(:func:`mirrorgraph.io.motion.regular_frames`).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence

import numpy as np

from ..errors import InputError, extra_hint, require_extra
from .atomic import atomic_path

__all__ = ["C3D_INSTALL_HINT", "require_c3d", "write_c3d"]

#: How to get the C3D writer.
C3D_INSTALL_HINT = extra_hint("c3d")


def require_c3d():
    """The ``c3d`` module, or :class:`MissingExtraError` saying how to install it."""
    return require_extra("c3d", "c3d", "writing .c3d", what="the c3d package")


def write_c3d(path: str | os.PathLike, joints3d: np.ndarray, valid: np.ndarray | None,
              frame_ids: np.ndarray | None, joint_names: Sequence[str], fps: float | None,
              unit: str = "m", *, marker_names: Sequence[str] | None = None,
              joints_std: np.ndarray | None = None) -> None:
    """Write 3D joints as a C3D file (millimetres, Y up; see the module docstring).

    Args:
        path: the ``.c3d`` file to write (atomically).
        joints3d: ``(T, J, 3)`` joints in the real camera frame (or a rig's world
            frame), in ``unit``.
        valid: ``(T, J)`` bool joints to write (``None``: every finite one).
        frame_ids: ``(T,)`` increasing frame numbers (``None``: ``0 .. T-1``).
        joint_names: ``(J,)`` canonical joint names.
        fps: frame rate of the frame numbers, Hz (required).
        unit: ``m``, ``cm`` or ``mm`` (anything else is refused: C3D needs lengths).
        marker_names: marker names instead of Pose2Sim's.
        joints_std: ``(T, J)`` each joint's std in ``unit`` (NaN: unknown), written as
            the points' residuals (the module docstring); ``None``: residuals 0.

    Raises:
        InputError: no frame rate, or a non-metric unit.
        MissingExtraError: the ``c3d`` package is missing.
    """
    from .motion_base import (check_arrays, metres_factor, regular_frames, to_trc_axes,
                              trc_marker_names)

    X, ok, ids, names, fps = check_arrays(joints3d, valid, frame_ids, joint_names, fps)
    if fps is None:
        raise InputError("a .c3d file needs the frame rate", source=path, field="fps")
    factor = metres_factor(unit, path)
    markers = trc_marker_names(names) if marker_names is None else [str(m) for m in marker_names]
    if len(markers) != len(names):
        raise ValueError(f"{len(markers)} marker names for {len(names)} joints")
    if not len(ids):
        raise InputError("no frame to write", source=path, field="joints3d")
    c3d = require_c3d()
    rows, step = regular_frames(ids)
    T, J = len(rows), len(names)
    mm = np.zeros((T, J, 3))
    good = np.zeros((T, J), bool)
    at = (ids - rows[0]) // step
    mm[at] = 1000.0 * factor * to_trc_axes(np.where(ok[..., None], X, 0.0))
    good[at] = ok
    residual, scale = _residuals(joints_std, ok, at, (T, J), 1000.0 * factor)
    # per point: x, y, z, residual (-1: invalid), camera mask
    points = np.concatenate([mm, np.where(good, residual, -1.0)[..., None],
                             np.zeros((T, J, 1))], axis=-1)
    writer = c3d.Writer(point_rate=float(fps) / step, analog_rate=0, point_scale=-scale,
                        point_units="mm", gen_scale=1.0)
    writer.set_point_labels(markers)
    writer.set_screen_axis(X="+Z", Y="+Y")
    writer.add_frames([(p, np.zeros((0, 0))) for p in points])
    first = int(rows[0]) // step + 1
    writer.set_start_frame(first)
    writer._set_last_frame(first + T - 1)   # c3d's own setter of TRIAL:ACTUAL_END_FIELD
    with atomic_path(path) as tmp, open(tmp, "wb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")     # c3d warns about fields it fills itself
        writer.write(fh)


def _residuals(joints_std: np.ndarray | None, ok: np.ndarray, at: np.ndarray,
               shape: tuple[int, int], to_mm: float) -> tuple[np.ndarray, float]:
    """``(T, J)`` residuals in millimetres on C3D's byte grid and the grid's step ``s``
    (mm, ``POINT:SCALE = -s``): the stds rounded to steps of ``s``, at least one step; 0
    where unknown."""
    out = np.zeros(shape)
    if joints_std is None:
        return out, 1.0
    std = np.asarray(joints_std, dtype=float)
    if std.shape != ok.shape:
        raise ValueError(f"joints_std has shape {std.shape}, the joints {ok.shape}")
    mm = np.where(ok & np.isfinite(std), std * to_mm, np.nan)
    top = float(np.nanmax(mm)) if np.isfinite(mm).any() else 0.0
    scale = max(1.0, float(np.ceil(top / 255.0)))
    steps = np.where(np.isfinite(mm), np.clip(np.rint(mm / scale), 1, 255), 0.0)
    out[at] = steps * scale
    return out, scale
