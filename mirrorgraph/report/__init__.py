"""A report a person looks at: figures of a calibration run, and video overlays.

:func:`make_report` writes PNG figures of a :class:`~mirrorgraph.pipeline.CalibrationRun`:

* ``image_plane.png``: the image with the epipole and a sample of the
  joint-to-reflection lines through it, inliers and outliers coloured;
* ``residuals.png``: histograms of the epipolar and reprojection residuals
  before (initial normal) and after the factor-graph refinement;
* ``scene3d.png``: the real and the virtual camera, the mirror plane and the
  skeleton (with its reflection) at a few frames;
* ``bone_lengths.png``: every bone's length over time, before and after;
* ``uncertainty.png``: the covariance of the normal as ellipses around the epipole.

With ``video=`` the joints, their reflections and the epipolar lines are drawn
on a few sampled frames of the video (``overlay_<frame>.png``); with
``render=`` the whole overlay video is written (mp4, see :mod:`.video`).

"Before" is what the initial estimate alone gives: the joints triangulated with
``calibration.initial_normal`` and the final distance (the initial estimate has
no scale of its own). "After" uses the refined normal and ``run.joints3d``.

matplotlib is an optional dependency (``pip install 'mirrorgraph[plot]'``); it
is imported lazily, with the non-interactive Agg backend.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from .. import geometry as geo
from ..errors import InputError, MirrorgraphError

__all__ = ["ReportData", "make_report", "report_data", "require_matplotlib",
           "run_from_calibration"]

INSTALL_HINT = "pip install 'mirrorgraph[plot]'"


def require_matplotlib():
    """Import matplotlib with the Agg backend and return ``matplotlib.pyplot``.

    Raises:
        MirrorgraphError: matplotlib is not installed (the message says how to
            install it).
    """
    try:
        import matplotlib
    except ImportError:
        raise MirrorgraphError(f"the report needs matplotlib: {INSTALL_HINT}") from None
    # Agg unless a notebook (inline backend) or the user chose one already
    backend = str(matplotlib.get_backend()).lower()
    if "inline" not in backend and "ipympl" not in backend and "widget" not in backend:
        matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


# --------------------------------------------------------------------------- data
@dataclass
class ReportData:
    """Everything the figures show, computed once from a run.

    Attributes:
        K: ``(3, 3)`` intrinsics; image_size: ``(w, h)`` px.
        normal, initial_normal: ``(3,)`` refined and initial unit normals.
        distance: mirror distance used for 3D (metres, or 1 when unknown).
        unit: ``"m"`` or ``"mirror distance"``.
        epipole, initial_epipole: ``(2,)`` px, or ``None`` at infinity.
        epipole_cov: ``(2, 2)`` px^2 covariance of the epipole, or ``None``.
        t_idx, j_idx: ``(N,)`` frame and joint index of every usable pair.
        u, um: ``(N, 2)`` direct and mirror pixels (undistorted).
        inlier: ``(N,)`` bool, pair kept by the run.
        epi_before, epi_after: ``(N,)`` epipolar distances, px.
        reproj_before, reproj_after: ``(N, 2)`` reprojection error (direct,
            mirror view), px; NaN where no 3D joint.
        joints_before, joints_after: ``(T, J, 3)`` 3D joints.
        bone_names: ``(B,)``; bones_before, bones_after: ``(T, B)`` lengths.
        bone_reference: bone name -> length the refinement estimated (or empty).
    """

    K: np.ndarray
    image_size: tuple[int, int]
    normal: np.ndarray
    initial_normal: np.ndarray
    distance: float
    unit: str
    epipole: np.ndarray | None
    initial_epipole: np.ndarray | None
    epipole_cov: np.ndarray | None
    rotation_std_deg: float | None
    distance_std: float | None
    t_idx: np.ndarray
    j_idx: np.ndarray
    u: np.ndarray
    um: np.ndarray
    inlier: np.ndarray
    epi_before: np.ndarray
    epi_after: np.ndarray
    reproj_before: np.ndarray
    reproj_after: np.ndarray
    frame_ids: np.ndarray
    skeleton: object
    joints_before: np.ndarray
    joints_after: np.ndarray
    bone_names: tuple[str, ...]
    bones_before: np.ndarray
    bones_after: np.ndarray
    refined: bool
    bone_reference: dict | None = None


def epipole_covariance(K: np.ndarray, normal: np.ndarray, normal_cov: np.ndarray
                       ) -> np.ndarray | None:
    """``(2, 2)`` covariance in px^2 of the epipole ``pi(K n)``, first order, or ``None``."""
    e = np.asarray(K, float) @ np.asarray(normal, float)
    if abs(e[2]) < 1e-9 * np.linalg.norm(e):
        return None
    p = e[:2] / e[2]
    J = (np.hstack([np.eye(2), -p[:, None]]) / e[2]) @ np.asarray(K, float)
    return J @ np.asarray(normal_cov, float) @ J.T


def _reprojection(K, n, d, X, u, um) -> np.ndarray:
    """``(N, 2)`` reprojection errors (direct, mirror) in px of points ``X`` ``(N, 3)``."""
    r1 = np.linalg.norm(geo.project(K, X) - u, axis=-1)
    r2 = np.linalg.norm(geo.project(K, geo.reflect_points(X, n, d)) - um, axis=-1)
    return np.stack([r1, r2], axis=-1)


def _bone_lengths(joints: np.ndarray, bone_index: np.ndarray) -> np.ndarray:
    if len(bone_index) == 0:
        return np.empty(joints.shape[:1] + (0,))
    return np.linalg.norm(joints[:, bone_index[:, 0]] - joints[:, bone_index[:, 1]], axis=-1)


def report_data(run, *, min_confidence: float | None = None) -> ReportData:
    """Compute the before/after quantities of a run (see :class:`ReportData`)."""
    calib = run.calibration
    paired = run.paired
    K = calib.intrinsics.K
    size = calib.intrinsics.image_size or paired.image_size
    if size is None:  # no size anywhere: take the extent of the keypoints
        pts = np.concatenate([paired.real[..., :2].reshape(-1, 2),
                              paired.mirror[..., :2].reshape(-1, 2)])
        size = tuple(int(v) for v in np.ceil(np.nanmax(pts, axis=0)))
    n = np.asarray(calib.normal, float)
    n0 = np.asarray(calib.initial_normal, float)
    d = float(calib.distance) if calib.distance is not None else 1.0
    unit = "m" if calib.distance is not None else "mirror distance"
    conf = calib.input.get("min_confidence", 0.3) if min_confidence is None else min_confidence
    valid = paired.valid(conf)
    keep = np.zeros(paired.skeleton.num_joints, bool)
    keep[np.asarray(run.joints, int)] = True
    valid &= keep[None, :]
    t_idx, j_idx = np.nonzero(valid)
    u = paired.real[t_idx, j_idx, :2]
    um = paired.mirror[t_idx, j_idx, :2]
    inlier = np.asarray(run.inliers, bool)[t_idx, j_idx]

    e_after = geo.epipole_from_normal(K, n)
    e_before = geo.epipole_from_normal(K, n0)
    epi_after = geo.epipolar_distances(e_after, u, um)
    epi_before = geo.epipolar_distances(e_before, u, um)

    T, J = paired.real.shape[:2]
    joints_before = np.full((T, J, 3), np.nan)
    joints_before[t_idx, j_idx] = geo.triangulate_mirror(K, n0, d, u, um)
    if run.joints3d is not None:
        joints_after = np.array(run.joints3d, float)
        if run.valid3d is not None:
            joints_after[~np.asarray(run.valid3d, bool)] = np.nan
    else:
        joints_after = np.full((T, J, 3), np.nan)
        joints_after[t_idx, j_idx] = geo.triangulate_mirror(K, n, d, u, um)
    reproj_before = _reprojection(K, n0, d, joints_before[t_idx, j_idx], u, um)
    reproj_after = _reprojection(K, n, d, joints_after[t_idx, j_idx], u, um)
    # a joint the run dropped (outlier) has no 3D point in either
    joints_before[~np.isfinite(joints_after).all(-1)] = np.nan

    sk = paired.skeleton
    bi = sk.bone_index
    cov = calib.uncertainty.get("normal_cov") if calib.uncertainty else None
    return ReportData(
        K=np.asarray(K, float), image_size=(int(size[0]), int(size[1])), normal=n,
        initial_normal=n0, distance=d, unit=unit,
        epipole=geo.epipole_pixels(e_after), initial_epipole=geo.epipole_pixels(e_before),
        epipole_cov=None if cov is None else epipole_covariance(K, n, np.asarray(cov, float)),
        rotation_std_deg=calib.uncertainty.get("rotation_std_deg") if calib.uncertainty else None,
        distance_std=calib.uncertainty.get("distance_std") if calib.uncertainty else None,
        t_idx=t_idx, j_idx=j_idx, u=u, um=um, inlier=inlier,
        epi_before=epi_before, epi_after=epi_after,
        reproj_before=reproj_before, reproj_after=reproj_after,
        frame_ids=np.asarray(paired.frame_ids), skeleton=sk,
        joints_before=joints_before, joints_after=joints_after,
        bone_names=sk.bone_names, bones_before=_bone_lengths(joints_before, bi),
        bones_after=_bone_lengths(joints_after, bi), refined=bool(calib.refined),
        bone_reference=dict((calib.refinement or {}).get("bone_lengths") or {}))


# --------------------------------------------------------------------------- report
FIGURES = ("image_plane", "residuals", "scene3d", "bone_lengths", "uncertainty")


def make_report(run, out_dir: str | os.PathLike, *, video: str | os.PathLike | None = None,
                render: str | os.PathLike | None = None, max_frames: int = 6,
                progress: Callable[[str], None] | None = None,
                progress_bar: bool = True, dpi: int = 110) -> dict[str, Path]:
    """Write the report's PNG figures (and video overlays) of a calibration run.

    Args:
        run: a :class:`~mirrorgraph.pipeline.CalibrationRun` (from
            :func:`mirrorgraph.calibrate` or :func:`run_from_calibration`).
        out_dir: folder to write into (created if missing).
        video: the video the keypoints come from: draws the overlay on
            ``max_frames`` sampled frames (``overlay_<frame>.png``).
        render: ``.mp4`` to write the whole overlay video to (needs ``video``).
        max_frames: frames of the skeleton in the 3D view (at most 4) and of
            the video sampled for overlays.
        progress: optional callback receiving the name of each step.
        progress_bar: draw a progress bar on stderr while rendering (only on a
            terminal).
        dpi: resolution of the PNGs.

    Returns:
        Name -> path of every file written: ``image_plane``, ``residuals``,
        ``scene3d``, ``bone_lengths``, ``uncertainty``, ``overlay_<frame>``
        and ``video``.

    Raises:
        MirrorgraphError: matplotlib missing; InputError: unreadable video,
        ``render`` without ``video``.
    """
    if render is not None and video is None:
        raise InputError("needs the video to draw on: add --video FILE", field="--render")
    if render is not None and Path(render).suffix.lower() != ".mp4":
        raise InputError("must end in .mp4", source=str(render), field="--render")
    if video is not None and not Path(video).is_file():
        raise InputError("no such video file", source=str(video), field="--video")
    plt = require_matplotlib()
    from . import figures

    step = progress or (lambda _s: None)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError("is a file; give a folder for the report", source=str(out))
    out.mkdir(parents=True, exist_ok=True)
    step("report: computing residuals before and after refinement")
    data = report_data(run)
    written: dict[str, Path] = {}
    makers = {"image_plane": figures.image_plane, "residuals": figures.residuals,
              "scene3d": lambda dt: figures.scene3d(dt, frames=min(4, max(1, max_frames))),
              "bone_lengths": figures.bone_lengths, "uncertainty": figures.uncertainty}
    for name in FIGURES:
        step(f"report: {name}.png")
        fig = makers[name](data)
        path = out / f"{name}.png"
        fig.savefig(path, dpi=dpi)
        plt.close(fig)
        written[name] = path
    if video is not None:
        from . import video as vid
        step("report: overlays on sampled video frames")
        written.update(vid.overlay_samples(video, run, out, count=max_frames, data=data))
        if render is not None:
            step(f"report: rendering {render}")
            written["video"] = vid.render_video(video, run, render, data=data,
                                                progress_bar=progress_bar)
    return written


# --------------------------------------------------------------------------- from files
def run_from_calibration(calibration, keypoints, *, intrinsics=None, min_confidence=None,
                         threshold_px=None):
    """A :class:`~mirrorgraph.pipeline.CalibrationRun` from a ``calibration.json``
    and the keypoints it was made from, without calibrating again.

    The keypoints are read, undistorted and paired as the pipeline does; a pair
    is an inlier when its epipolar distance under the file's normal is below the
    threshold the calibration used; the 3D joints are triangulated with the
    file's plane (``joints3d`` of the run are not stored in the JSON, so
    "after" shows the plane's triangulation, not the graph's smoothed joints).

    Args:
        calibration: path of ``calibration.json`` (or its parsed dict).
        keypoints: a keypoint path or what :func:`mirrorgraph.read_keypoints` returned.
        intrinsics: overrides the intrinsics stored in the calibration.
        min_confidence, threshold_px: override the values stored in the file.
    """
    from dataclasses import replace

    from ..calibration import Calibration
    from ..estimators import DEFAULT_THRESHOLD_PX
    from ..export import _read_calibration
    from ..io._common import load_json
    from ..keypoints import PairedKeypoints, RawDetections
    from ..pairing import PairingOptions, fix_left_right, pair_detections
    from ..pipeline import CalibrationRun, _joint_indices

    obj = load_json(calibration) if isinstance(calibration, (str, os.PathLike)) else calibration
    n, d, intr, _src = _read_calibration(calibration)
    if intrinsics is not None:
        intr = intrinsics
    info = obj.get("input") or {}
    conf = float(min_confidence if min_confidence is not None else info.get("min_confidence", 0.3))
    thr = float(threshold_px if threshold_px is not None else info.get("threshold_px", DEFAULT_THRESHOLD_PX))
    if not isinstance(keypoints, (RawDetections, PairedKeypoints)):
        from ..io import read_keypoints
        keypoints = read_keypoints(keypoints, skeleton=info.get("skeleton"))
    names = info.get("joints")
    joints = _joint_indices(keypoints.skeleton, tuple(names) if names else None)
    if intr.has_distortion:
        if isinstance(keypoints, PairedKeypoints):
            real, mirror = keypoints.real.copy(), keypoints.mirror.copy()
            real[..., :2] = intr.undistort_points(real[..., :2])
            mirror[..., :2] = intr.undistort_points(mirror[..., :2])
            keypoints = replace(keypoints, real=real, mirror=mirror)
        else:
            people = []
            for p in keypoints.people:
                p = np.array(p, float, copy=True)
                if len(p):
                    p[..., :2] = intr.undistort_points(p[..., :2])
                people.append(p)
            keypoints = replace(keypoints, people=people)
    popts = PairingOptions(min_confidence=conf, threshold_px=thr,
                           seed=int(info.get("seed", 0) or 0))
    paired = (fix_left_right(keypoints, joints, popts) if isinstance(keypoints, PairedKeypoints)
              else pair_detections(keypoints, joints, popts))
    valid = paired.valid(conf)
    mask = np.zeros(paired.skeleton.num_joints, bool)
    mask[joints] = True
    valid &= mask[None, :]
    e = geo.epipole_from_normal(intr.K, n)
    inliers = np.zeros_like(valid)
    t_idx, j_idx = np.nonzero(valid)
    dist = geo.epipolar_distances(e, paired.real[t_idx, j_idx, :2],
                                  paired.mirror[t_idx, j_idx, :2])
    inliers[t_idx[dist < thr], j_idx[dist < thr]] = True
    dd = d if d is not None else 1.0
    X = np.full(paired.real.shape[:2] + (3,), np.nan)
    ti, ji = np.nonzero(inliers)
    X[ti, ji] = geo.triangulate_mirror(intr.K, n, dd, paired.real[ti, ji, :2],
                                       paired.mirror[ti, ji, :2])
    n0 = np.asarray(obj.get("initial_normal") or n, float)
    calib = Calibration(
        normal=n, distance=d, scale=str(obj.get("scale", "unknown")),
        estimator=str(obj.get("estimator", "")), intrinsics=intr,
        initial_normal=n0 / np.linalg.norm(n0), refined=bool(obj.get("refined", False)),
        input={**info, "min_confidence": conf, "threshold_px": thr},
        refinement=dict(obj.get("refinement") or {}),
        uncertainty=dict(obj.get("uncertainty") or {}),
        warnings=list(obj.get("warnings") or []))
    return CalibrationRun(calibration=calib, paired=paired, inliers=inliers, joints=joints,
                          joints3d=X, valid3d=inliers.copy())
