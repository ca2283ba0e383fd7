"""Every person's 3D motion out (:func:`write_people_joints3d`): one ``.npz`` with a person
axis, or one motion file per person, or one ``.trc`` / ``.c3d`` with prefixed labels.

=============== ================================================================
layout          content
=============== ================================================================
``.npz``        the keys of :func:`~.motion.write_joints3d_npz` with a person axis
                first: ``joints3d`` ``(P, T, J, 3)`` float (NaN where invalid),
                ``valid`` ``(P, T, J)`` bool; ``frame_ids`` ``(T,)``,
                ``joint_names`` ``(J,)``, ``fps``, ``unit``, ``frame`` as there;
                ``people`` ``(P,)`` str, each person's name (``P0``, ``P1``, ...,
                in the order of the run's people: first seen first); where given,
                ``joints_std``, ``joints_std_shape`` ``(P, T, J)`` (NaN where
                invalid) and ``scale_rel_std`` (one for every person).
``"files"``     any other suffix: one file a person, ``<stem>_P<p><suffix>``
                (``motion.trc`` -> ``motion_P0.trc``, ``motion_P1.trc``), each as
                :func:`~.motion.write_joints3d` writes one person.
``"prefixed"``  ``.trc`` / ``.c3d``: one file, every person's markers with their
                name as a prefix, ``P0_LKnee``, ``P1_LKnee`` (the marker naming of
                multi-subject C3D files: a subject's prefix on each of its labels).
=============== ================================================================
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from .archive import savez
from .atomic import atomic_path
from .motion import write_joints3d
from .motion_base import CAMERA_FRAME, trc_marker_names
from .motion_base import check_arrays as _check

__all__ = ["person_paths", "write_people_joints3d"]

LAYOUTS = ("files", "prefixed")


def person_paths(path: str | os.PathLike, count: int) -> list[Path]:
    """The per-person files of ``path``: ``<stem>_P<p><suffix>``, ``p = 0 .. count-1``."""
    p = Path(path)
    return [p.with_name(f"{p.stem}_P{k}{p.suffix}") for k in range(count)]


def write_people_joints3d(path: str | os.PathLike, joints3d: np.ndarray,
                          valid: np.ndarray | None, frame_ids: np.ndarray | None,
                          joint_names: Sequence[str], fps: float | None, unit: str = "m", *,
                          layout: str = "files", joints_std: np.ndarray | None = None,
                          joints_std_shape: np.ndarray | None = None,
                          scale_rel_std: float | None = None) -> list[Path]:
    """Write every person's joints over time (the module docstring).

    Args:
        path: the file (``.npz``: one file with a person axis; else per ``layout``).
        joints3d: ``(P, T, J, 3)`` joints in the real camera frame.
        valid: ``(P, T, J)`` bool (``None``: every finite joint).
        frame_ids: ``(T,)`` frame numbers (``None``: ``0 .. T-1``).
        joint_names: ``(J,)`` one person's canonical joint names.
        fps: frame rate in Hz, or ``None``.
        unit: the unit of ``joints3d`` (as :func:`~.motion.write_joints3d`).
        layout: ``"files"`` (one file a person) or ``"prefixed"`` (``.trc`` / ``.c3d``:
            one file, prefixed labels).
        joints_std: ``(P, T, J)`` each joint's std in ``unit`` (the metric scale's share
            in it), as :func:`~.motion.write_joints3d` writes one person's (``.npz``;
            C3D's residual channel); ``None``: not written.
        joints_std_shape, scale_rel_std: ``.npz`` and one file a person only:
            ``joints_std`` without the metric scale's share ``(P, T, J)``, and that
            share's relative std (as :func:`~.motion.write_joints3d`).

    Returns:
        The files written.

    Raises:
        InputError: an unknown layout, ``"prefixed"`` for a format without marker labels,
            or what :func:`~.motion.write_joints3d` refuses.
        ValueError: arrays of inconsistent shapes.
    """
    X = np.asarray(joints3d, dtype=float)
    if X.ndim != 4 or X.shape[-1] != 3:
        raise ValueError(f"joints3d must be (P, T, J, 3), got {X.shape}")
    P, T, J = X.shape[:3]
    ok = (np.isfinite(X).all(-1) if valid is None
          else np.asarray(valid, dtype=bool) & np.isfinite(X).all(-1))
    if ok.shape != (P, T, J):
        raise ValueError(f"valid must be {(P, T, J)}, got {ok.shape}")
    stds = []
    for key, value in (("joints_std", joints_std), ("joints_std_shape", joints_std_shape)):
        std = None if value is None else np.asarray(value, dtype=float)
        if std is not None and std.shape != (P, T, J):
            raise ValueError(f"{key} must be {(P, T, J)}, got {std.shape}")
        stds.append(std)
    std, std_shape = stds
    if layout not in LAYOUTS:
        raise InputError(f"must be one of {', '.join(LAYOUTS)}, got {layout!r}",
                         field="layout")
    suffix = Path(path).suffix.lower()
    names = [f"P{k}" for k in range(P)]
    if suffix == ".npz":
        checked = [_check(X[k], ok[k], frame_ids, joint_names, fps) for k in range(P)]
        _, _, ids, jnames, fps = checked[0]
        extra = {}
        for key, value in (("joints_std", std), ("joints_std_shape", std_shape)):
            if value is not None:
                extra[key] = np.where(ok, value, np.nan)
        if scale_rel_std is not None:
            extra["scale_rel_std"] = np.float64(scale_rel_std)
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                savez(fh, dict(
                    joints3d=np.stack([c[0] for c in checked]),
                    valid=np.stack([c[1] for c in checked]), frame_ids=ids,
                    joint_names=np.array(jnames, dtype=str),
                    fps=np.float64(np.nan if fps is None else fps),
                    unit=np.array(str(unit)), frame=np.array(CAMERA_FRAME),
                    people=np.array(names, dtype=str), **extra))
        return [Path(path)]
    if layout == "prefixed":
        if suffix not in (".trc", ".c3d"):
            raise InputError(f"prefixed labels need .trc or .c3d, not {suffix!r}",
                             source=path, field="layout")
        markers = trc_marker_names(joint_names)
        labels = [f"{n}_{m}" for n in names for m in markers]
        flat = np.moveaxis(X, 0, 1).reshape(T, P * J, 3)
        flat_ok = np.moveaxis(ok, 0, 1).reshape(T, P * J)
        write_joints3d(path, flat, flat_ok, frame_ids,
                       [f"{j}@{n}" for n in names for j in joint_names], fps, unit,
                       marker_names=labels,
                       joints_std=None if std is None else np.moveaxis(std, 0, 1).reshape(T, P * J))
        return [Path(path)]
    out = person_paths(path, P)
    for k, p in enumerate(out):
        write_joints3d(p, X[k], ok[k], frame_ids, joint_names, fps, unit,
                       joints_std=None if std is None else std[k],
                       joints_std_shape=None if std_shape is None else std_shape[k],
                       scale_rel_std=scale_rel_std)
    return out
