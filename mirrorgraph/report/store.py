"""The run behind a calibration, kept for the report: ``<calibration>.report.npz``.

``calibration.json`` holds the mirror, not the data it was found from; the
report's figures need that data: the paired, undistorted keypoints, the pairs
the calibration kept and the 3D joints of its factor graph. ``mirrorgraph
calibrate`` writes them beside the calibration (``c.json`` -> ``c.report.npz``,
named in ``c.json`` under :data:`KEY`) so that ``mirrorgraph report`` draws the
very figures ``calibrate --report`` draws.

The file (NumPy ``.npz``, :func:`mirrorgraph.io.archive.savez`, no pickles) holds:

* ``real``, ``mirror``: ``(T, J, 3)`` paired keypoints (x px, y px, confidence),
  undistorted, the reflection's labels flipped, as the calibration used them;
  ``frame_ids`` ``(T,)``, ``skeleton``, ``image_size`` (``[-1, -1]`` unknown),
  ``fps`` (NaN unknown), ``source``, ``format``, ``lr_fixes``, ``frames_read``;
* ``inliers`` ``(T, J)`` the pairs the calibration kept, ``joints`` ``(k,)`` the
  joint indices used, ``candidates`` ``(T, J)`` the pairs handed to the graph;
* ``joints3d`` ``(T, J, 3)`` and ``valid3d`` ``(T, J)``: the graph's 3D joints
  (absent without refinement);
* ``completed`` ``(T, J)``, ``run_fps``, ``fps_source``: the joints completed after
  the graph and the frame rate of the 3D motion, where the run has them;
* ``normal``, ``initial_normal``, ``distance`` (NaN for an unknown scale): the
  calibration the run belongs to, checked against ``calibration.json`` on reading.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..result.mirror import write_calibration
from ..errors import InputError
from ..io.archive import savez
from ..io.atomic import atomic_path
from ..io.calibration import write_json
from ..keypoints import PairedKeypoints
from ..skeletons import skeleton_by_name

__all__ = ["KEY", "SUFFIX", "read_run", "report_data_path",
           "save_run", "write_calibration_and_run", "write_run"]

#: Suffix of the file beside the calibration: ``c.json`` -> ``c.report.npz``.
SUFFIX = ".report.npz"
#: Key of ``calibration.json`` naming the file (relative to the calibration's folder).
KEY = "report_data"
#: Layout version written in the file.
FORMAT_VERSION = 1

_REQUIRED = ("format_version", "normal", "initial_normal", "distance", "skeleton",
             "frame_ids", "real", "mirror", "inliers", "joints")


def report_data_path(calibration_path: str | os.PathLike) -> Path:
    """Where the run of the calibration at ``calibration_path`` is kept.

    Example:
        >>> report_data_path("out/calibration.json").as_posix()
        'out/calibration.report.npz'
    """
    return Path(calibration_path).with_suffix(SUFFIX)


def save_run(file: str | os.PathLike, run) -> None:
    """Write what the report needs of ``run`` to ``file`` (not atomic; see :func:`write_run`).

    Args:
        file: path to write (its suffix should be ``.npz``).
        run: a :class:`~mirrorgraph.pipelines.mirror.CalibrationRun`.
    """
    calib, p = run.calibration, run.paired
    arrays: dict[str, Any] = {
        "format_version": np.int64(FORMAT_VERSION),
        "normal": np.asarray(calib.normal, float),
        "initial_normal": np.asarray(calib.initial_normal, float),
        "distance": np.float64(np.nan if calib.distance is None else calib.distance),
        "skeleton": np.str_(p.skeleton.name),
        "frame_ids": np.asarray(p.frame_ids, np.int64),
        "real": np.asarray(p.real, float),
        "mirror": np.asarray(p.mirror, float),
        "source": np.str_(p.source or ""),
        "format": np.str_(p.format or ""),
        "image_size": np.asarray(p.image_size if p.image_size is not None else (-1, -1),
                                 np.int64),
        "fps": np.float64(np.nan if p.fps is None else p.fps),
        "lr_fixes": np.int64(p.lr_fixes),
        "frames_read": np.int64(p.frames_read),
        "inliers": np.asarray(run.inliers, bool),
        "joints": np.asarray(run.joints, np.int64),
    }
    if run.candidates is not None:
        arrays["candidates"] = np.asarray(run.candidates, bool)
    if run.joints3d is not None:
        arrays["joints3d"] = np.asarray(run.joints3d, float)
        arrays["valid3d"] = (np.asarray(run.valid3d, bool) if run.valid3d is not None
                             else np.isfinite(run.joints3d).all(-1))
    if run.completed is not None:
        arrays["completed"] = np.asarray(run.completed, bool)
    arrays["run_fps"] = np.float64(run.fps)
    arrays["fps_source"] = np.str_(run.fps_source)
    savez(file, arrays)


def write_run(path: str | os.PathLike, run) -> Path:
    """Write what the report needs of ``run`` to ``path`` atomically; returns ``path``."""
    with atomic_path(path) as tmp:
        save_run(tmp, run)
    return Path(path)


def write_calibration_and_run(out: str | os.PathLike, run) -> Path:
    """Write ``calibration.json`` and, beside it, the run its report draws from.

    ``c.json`` names ``c.report.npz`` under :data:`KEY`. Both are written to
    temporaries first and renamed into place one after the other: a failed write
    leaves both files as they were.

    Args:
        out: the calibration JSON to write.
        run: the :class:`~mirrorgraph.pipelines.mirror.CalibrationRun` it comes from.

    Returns:
        The path of the ``.report.npz`` written.
    """
    out = Path(out)
    sidecar = report_data_path(out)
    with atomic_path(sidecar) as tmp:
        save_run(tmp, run)
        doc = run.calibration.to_dict()
        if KEY in doc:                        # the calibration names it itself
            write_calibration(out, run.calibration)
        else:
            doc[KEY] = sidecar.name
            write_json(out, doc)
    return sidecar


def read_run(path: str | os.PathLike, calibration):
    """The :class:`~mirrorgraph.pipelines.mirror.CalibrationRun` kept in ``path`` for ``calibration``.

    Args:
        path: the ``.report.npz`` file.
        calibration: the :class:`~mirrorgraph.result.mirror.Calibration` read from
            ``calibration.json``; it becomes the run's calibration.

    Raises:
        InputError: the file is missing, unreadable, incomplete, or belongs to
            another calibration (its mirror differs from ``calibration``'s); the
            message names the file.
    """
    from ..pipelines.mirror import CalibrationRun     # GTSAM: at first use, not on importing

    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputError("no such file", source=str(path)) from None
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"cannot be read as the report's data ({type(exc).__name__})",
                         source=str(path)) from None
    missing = [k for k in _REQUIRED if k not in arrays]
    if missing:
        raise InputError(f"missing {', '.join(missing)}", source=str(path))
    if int(arrays["format_version"]) > FORMAT_VERSION:
        raise InputError(f"written by a newer mirrorgraph (layout {int(arrays['format_version'])})",
                         source=str(path), field="format_version")
    d = float(arrays["distance"])
    same = (np.array_equal(arrays["normal"], np.asarray(calibration.normal, float))
            and np.array_equal(arrays["initial_normal"],
                               np.asarray(calibration.initial_normal, float))
            and ((np.isnan(d) and calibration.distance is None)
                 or (calibration.distance is not None and d == float(calibration.distance))))
    if not same:
        raise InputError("belongs to another calibration (its mirror is not the file's: "
                         "calibrated again since it was written)", source=str(path))
    try:
        skeleton = skeleton_by_name(str(arrays["skeleton"]))
    except ValueError as exc:
        raise InputError(str(exc), source=str(path), field="skeleton") from None
    real, mirror = arrays["real"], arrays["mirror"]
    T = len(arrays["frame_ids"])
    shape = (T, skeleton.num_joints)
    if real.shape != shape + (3,) or mirror.shape != real.shape or arrays["inliers"].shape != shape:
        raise InputError(f"arrays of the wrong shape for {T} frames of {skeleton.name}",
                         source=str(path))
    size = tuple(int(v) for v in arrays.get("image_size", (-1, -1)))
    fps = float(arrays.get("fps", np.nan))
    paired = PairedKeypoints(
        skeleton=skeleton, frame_ids=arrays["frame_ids"], real=real, mirror=mirror,
        source=str(arrays.get("source", "")), format=str(arrays.get("format", "")),
        image_size=None if min(size) <= 0 else size, fps=None if np.isnan(fps) else fps,
        lr_fixes=int(arrays.get("lr_fixes", 0)), frames_read=int(arrays.get("frames_read", 0)))
    extra = {}                     # fields of newer runs, where this mirrorgraph has them
    if "completed" in arrays:
        extra["completed"] = arrays["completed"].astype(bool)
    if "run_fps" in arrays:
        extra["fps"] = float(arrays["run_fps"])
        extra["fps_source"] = str(arrays.get("fps_source", ""))
    known = {f.name for f in dataclasses.fields(CalibrationRun)}
    return CalibrationRun(
        calibration=calibration, paired=paired, inliers=arrays["inliers"].astype(bool),
        joints=arrays["joints"].astype(int),
        candidates=arrays["candidates"].astype(bool) if "candidates" in arrays else None,
        joints3d=arrays.get("joints3d"),
        valid3d=arrays["valid3d"].astype(bool) if "valid3d" in arrays else None,
        **{k: v for k, v in extra.items() if k in known})
