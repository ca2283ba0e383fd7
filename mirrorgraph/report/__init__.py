"""A report a person looks at: figures of a calibration run, and video overlays.

:func:`make_report` writes PNG figures of a :class:`~mirrorgraph.pipelines.mirror.CalibrationRun`:

* ``image_plane.png``: the image with the epipole and a sample of the
  joint-to-reflection lines through it, inliers and outliers coloured;
* ``residuals.png``: histograms of the epipolar and reprojection residuals
  with the initial and with the refined mirror (each pair triangulated on its own in
  both), and the reprojection of the factor graph's joints beside them;
* ``scene3d.png``: the real and the virtual camera, the mirror and the skeleton
  (with its reflection) at a few frames, from above and seen along the mirror
  (orthographic, equal scales; metres or units of the mirror distance, said);
* ``bone_lengths.png``: every bone's length over time, before and after, with
  its spread over frames absolute and in % of its median;
* ``uncertainty.png``: the covariance of the normal as ellipses around the epipole.

With ``video=`` the joints, their reflections and the epipolar lines are drawn
on a few sampled frames of the video (``overlay_<frame>.png``); with
``render=`` the whole overlay video is written (mp4, see :mod:`.video`).

"Before" is what the initial estimate alone gives: the joints triangulated with
``calibration.initial_normal`` and the final distance (the initial estimate has
no scale of its own). "After" uses the refined normal and ``run.joints3d``, the
factor graph's joints.

The figures of a ``calibration.json`` drawn later (``mirrorgraph report``) are
those of the calibration itself: :func:`load_run` reads the run that
``mirrorgraph calibrate`` kept beside it (``c.report.npz``, :mod:`.store`), or
calibrates the keypoints again with the options the file records.

matplotlib is an optional dependency (:data:`INSTALL_HINT`, :mod:`.backend`); it is imported
lazily, with the non-interactive Agg backend.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from .. import geometry as geo
from ..result.mirror import read_calibration
from ..errors import InputError
from ..initial.estimators import DEFAULT_THRESHOLD_PX
from ..graph.options import RefineOptions
from ..io import read_keypoints
from ..io._common import load_json
from ..keypoints import DEFAULT_MIN_CONFIDENCE, PairedKeypoints, RawDetections
from ..progress import Progress
from .backend import INSTALL_HINT, require_matplotlib
from .store import KEY, read_run, report_data_path

if TYPE_CHECKING:                    # imported where used: the pipeline imports GTSAM
    from ..pipelines.options import CalibrateOptions

__all__ = ["FIGURES", "INSTALL_HINT", "LoadedRun", "ReportData", "load_run", "make_report",
           "options_from_calibration", "report_data", "require_matplotlib",
           "run_from_calibration"]

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
            mirror view), px, of each pair triangulated on its own with the initial
            and with the refined mirror (like with like: only the mirror differs).
        reproj_graph: ``(N, 2)`` the same of the 3D joints the run returns (the factor
            graph's, held to rigid bones and smooth motion); NaN where no 3D joint.
        joints_before, joints_after: ``(T, J, 3)`` 3D joints.
        bone_names: ``(B,)``; bones_before, bones_after: ``(T, B)`` lengths.
        bone_reference: bone name -> length the refinement estimated (or empty).
        marginal_epipole_cov: ``(2, 2)`` px^2 the same from the marginal (iid)
            covariance, or ``None``; marginal_rotation_std_deg: its rotation std.
        sensitivity: the calibration's ``sensitivity`` record (or empty).
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
    reproj_graph: np.ndarray
    frame_ids: np.ndarray
    skeleton: object
    joints_before: np.ndarray
    joints_after: np.ndarray
    bone_names: tuple[str, ...]
    bones_before: np.ndarray
    bones_after: np.ndarray
    refined: bool
    bone_reference: dict | None = None
    marginal_epipole_cov: np.ndarray | None = None
    marginal_rotation_std_deg: float | None = None
    sensitivity: dict | None = None


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
    conf = calib.input.get("min_confidence", DEFAULT_MIN_CONFIDENCE) if min_confidence is None else min_confidence
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
    else:   # no graph: the inlier pairs triangulated with the (initial) normal
        joints_after = np.full((T, J, 3), np.nan)
        joints_after[t_idx[inlier], j_idx[inlier]] = geo.triangulate_mirror(
            K, n, d, u[inlier], um[inlier])
    reproj_before = _reprojection(K, n0, d, joints_before[t_idx, j_idx], u, um)
    reproj_after = _reprojection(K, n, d, geo.triangulate_mirror(K, n, d, u, um), u, um)
    reproj_graph = _reprojection(K, n, d, joints_after[t_idx, j_idx], u, um)
    # a joint the run dropped (outlier) has no 3D point in either
    joints_before[~np.isfinite(joints_after).all(-1)] = np.nan

    sk = paired.skeleton
    bi = sk.bone_index
    cov = calib.uncertainty.get("normal_cov") if calib.uncertainty else None
    mcov = calib.uncertainty.get("marginal_normal_cov") if calib.uncertainty else None
    return ReportData(
        K=np.asarray(K, float), image_size=(int(size[0]), int(size[1])), normal=n,
        initial_normal=n0, distance=d, unit=unit,
        epipole=geo.epipole_pixels(e_after), initial_epipole=geo.epipole_pixels(e_before),
        epipole_cov=None if cov is None else epipole_covariance(K, n, np.asarray(cov, float)),
        rotation_std_deg=calib.uncertainty.get("rotation_std_deg") if calib.uncertainty else None,
        distance_std=calib.uncertainty.get("distance_std") if calib.uncertainty else None,
        t_idx=t_idx, j_idx=j_idx, u=u, um=um, inlier=inlier,
        epi_before=epi_before, epi_after=epi_after,
        reproj_before=reproj_before, reproj_after=reproj_after, reproj_graph=reproj_graph,
        frame_ids=np.asarray(paired.frame_ids), skeleton=sk,
        joints_before=joints_before, joints_after=joints_after,
        bone_names=sk.bone_names, bones_before=_bone_lengths(joints_before, bi),
        bones_after=_bone_lengths(joints_after, bi), refined=bool(calib.refined),
        bone_reference=dict((calib.refinement or {}).get("bone_lengths") or {}),
        marginal_epipole_cov=None if mcov is None
        else epipole_covariance(K, n, np.asarray(mcov, float)),
        marginal_rotation_std_deg=(calib.uncertainty or {}).get("marginal_rotation_std_deg"),
        sensitivity=dict(getattr(calib, "sensitivity", None) or {}))


# --------------------------------------------------------------------------- report
FIGURES = ("image_plane", "residuals", "scene3d", "bone_lengths", "uncertainty", "sensitivity")


def make_report(run, out_dir: str | os.PathLike, *, video: str | os.PathLike | None = None,
                render: str | os.PathLike | None = None, max_frames: int = 6,
                progress: Callable[[str], None] | None = None,
                progress_bar: bool = True, dpi: int = 110,
                warn: Callable[[str], None] | None = None) -> dict[str, Path]:
    """Write the report's PNG figures (and video overlays) of a calibration run.

    Args:
        run (mirrorgraph.pipelines.mirror.CalibrationRun): a calibration run (from
            :func:`mirrorgraph.calibrate` or :func:`run_from_calibration`).
        out_dir: folder to write into (created if missing).
        video: the video the keypoints come from: draws the overlay on
            ``max_frames`` sampled frames (``overlay_<frame>.png``).
        render: ``.mp4`` (H.264 where OpenCV has it, else ``mp4v``) or ``.webm`` (VP9,
            which browsers play) to write the whole overlay video to (needs ``video``).
        max_frames: frames of the skeleton in the 3D view (at most 4) and of
            the video sampled for overlays.
        progress: optional callback receiving the name of each step.
        progress_bar: draw progress bars on stderr while drawing the figures,
            sampling and rendering video frames (only on a terminal).
        warn: receives a line where the rendered video is in a codec browsers do not
            play (this OpenCV build without H.264).
        dpi: resolution of the PNGs.

    Returns:
        Name -> path of every file written: ``image_plane``, ``residuals``,
        ``scene3d``, ``bone_lengths``, ``uncertainty``, ``overlay_<frame>``
        and ``video``.

    Raises:
        MirrorgraphError: matplotlib missing.
        InputError: unreadable video, ``render`` without ``video``.
    """
    if render is not None and video is None:
        raise InputError("needs the video to draw on", field="render", fix=("video",))
    if render is not None and Path(render).suffix.lower() not in (".mp4", ".webm"):
        raise InputError("must end in .mp4 or .webm", source=str(render), field="render")
    if video is not None and not Path(video).is_file():
        raise InputError("no such video file", source=str(video), field="video")
    plt = require_matplotlib()
    # lazy: the figures are the plot extra's (matplotlib), and importing them adds
    # ~6 ms to `mirrorgraph --help`, which imports this package
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
              "bone_lengths": figures.bone_lengths, "uncertainty": figures.uncertainty,
              "sensitivity": figures.sensitivity}
    with Progress("drawing the report", total=len(FIGURES), enabled=progress_bar) as bar:
        for name in FIGURES:
            step(f"report: {name}.png")
            fig = makers[name](data)
            path = out / f"{name}.png"
            fig.savefig(path, dpi=dpi)
            plt.close(fig)
            written[name] = path
            bar.update(info=f"{name}.png")
    if video is not None:
        from . import video as vid  # lazy, as figures: only with a video (~2 ms)
        step("report: overlays on sampled video frames")
        written.update(vid.overlay_samples(video, run, out, count=max_frames, data=data,
                                           progress_bar=progress_bar))
        if render is not None:
            step(f"report: rendering {render}")
            written["video"] = vid.render_video(video, run, render, data=data,
                                                progress_bar=progress_bar, warn=warn)
    return written


# --------------------------------------------------------------------------- from files
@dataclass
class LoadedRun:
    """A calibration's run, read back for its report (see :func:`load_run`).

    Attributes:
        run: the :class:`~mirrorgraph.pipelines.mirror.CalibrationRun` to draw.
        origin: ``"stored"`` (read from the ``.report.npz`` beside the calibration)
            or ``"recomputed"`` (calibrated again from the keypoints).
        message: one sentence saying where the figures' data come from.
        warnings: doubts, e.g. a stale ``.report.npz`` or a recomputation whose
            mirror is not the file's.
        path: the ``.report.npz`` read, or ``None``.
    """

    run: object
    origin: str
    message: str
    warnings: list[str]
    path: Path | None = None


def options_from_calibration(obj) -> CalibrateOptions:
    """The :class:`~mirrorgraph.pipelines.mirror.CalibrateOptions` a ``calibration.json`` records.

    Estimator, threshold, minimum confidence, seed, joints and whether the graph
    ran come from the file; the subject height and ``scale_from`` from ``input``
    where recorded there, else from what the refinement reports (the height its
    gauge used, and whether the limbs were asked for). The intrinsics (and so the
    field of view or image size of a guess) are the file's own.

    Args:
        obj: the parsed ``calibration.json``.
    """
    from ..pipelines.options import CalibrateOptions    # GTSAM: at first use
    from ..stature import LIMB_CHOSEN

    info = obj.get("input") or {}
    ref = obj.get("refinement") or {}
    height = info.get("subject_height")
    if height is None and obj.get("scale") == "subject_height":
        gauge = (ref.get("priors") or {}).get("length_sum_gauge") or {}
        height = gauge.get("height_m") or (ref.get("stature") or {}).get("height")
    scale_from = info.get("scale_from")
    if scale_from is None:
        # a file without input.scale_from: what its scale records
        said = ref.get("scale_source" if "schema_version" in obj else "scale_method", "")
        scale_from = "limbs" if str(said) == LIMB_CHOSEN else "stature"
    names = info.get("joints")
    return CalibrateOptions(
        estimator=str(obj.get("estimator") or "reflective"),
        threshold_px=float(info.get("threshold_px", DEFAULT_THRESHOLD_PX)),
        min_confidence=float(info.get("min_confidence", DEFAULT_MIN_CONFIDENCE)),
        joints=tuple(names) if names else None, refine=bool(obj.get("refined", False)),
        subject_height=None if height is None else float(height),
        seed=int(info.get("seed", 0) or 0),
        refine_options=RefineOptions(scale_from=scale_from,
                                     keypoint_offset=info.get("keypoint_offset")))


def _stored_path(obj, calibration_path: Path) -> Path:
    name = obj.get(KEY) if isinstance(obj, dict) else None
    if isinstance(name, str) and name and (calibration_path.parent / name).exists():
        return calibration_path.parent / name
    return report_data_path(calibration_path)   # also where a renamed pair is found


def recorded_keypoints(obj, calibration_path: Path | None) -> Path | None:
    """The keypoints a ``calibration.json`` records as its input (``input.source``), where
    that file or folder exists: as written (absolute, or relative to the working folder
    the calibration ran in, taken to be this one), else beside the calibration.

    Args:
        obj: the parsed ``calibration.json``; calibration_path: its path, or ``None``.
    """
    source = (obj.get("input") or {}).get("source") if isinstance(obj, dict) else None
    if not isinstance(source, str) or not source or source.startswith("live window"):
        return None
    candidates = [Path(source)]
    if calibration_path is not None and not Path(source).is_absolute():
        candidates += [calibration_path.parent / source, calibration_path.parent / Path(source).name]
    return next((c for c in candidates if c.exists()), None)


def load_run(calibration, keypoints=None, *, report_data="auto", intrinsics=None,
             overrides: dict | None = None, skeleton: str | None = None, progress: Callable[[str], None] | None = None,
             iteration_progress: Callable[[int, float], None] | None = None,
             ransac_progress: Callable[[int, int], None] | None = None) -> LoadedRun:
    """The run of a ``calibration.json``, for figures that are the calibration's own.

    The run kept beside the calibration (``c.report.npz``, which ``mirrorgraph
    calibrate`` writes, see :mod:`.store`) is read when it is there and belongs
    to this calibration. Otherwise the keypoints are calibrated again with the
    very pipeline and options the file records (:func:`options_from_calibration`,
    the file's intrinsics): the pipeline is deterministic, so that gives the
    same pairs, inliers and 3D joints, which is checked (the recomputed mirror
    must be the file's, else a warning says by how much they differ).

    Args:
        calibration: path of ``calibration.json`` (or its parsed dict: then only
            ``report_data`` given as a path is read).
        keypoints: a keypoint path or what :func:`mirrorgraph.read_keypoints`
            returned; needed only when there is no usable stored run, and then by
            default the ones the calibration records (:func:`recorded_keypoints`).
        report_data: ``"auto"`` (the file beside the calibration), a path, or
            ``None`` to recompute whatever is stored.
        intrinsics: overrides the intrinsics stored in the calibration (recomputes).
        overrides: :class:`~mirrorgraph.pipelines.mirror.CalibrateOptions` fields to change
            (recomputes; the mirror then need not be the file's).
        skeleton: keypoint layout to read ``keypoints`` with (default: the one
            the calibration records).
        progress, iteration_progress, ransac_progress: callbacks of the
            recomputation, as :func:`mirrorgraph.calibrate` takes them.

    Returns:
        A :class:`LoadedRun` (the run, where it came from, doubts).

    Raises:
        InputError: no usable stored run and no keypoints; unreadable files.

    Example:
        >>> loaded = load_run("calibration.json", "keypoints.json")   # doctest: +SKIP
        >>> loaded.origin, loaded.run.inliers.mean()                 # doctest: +SKIP
        ('stored', 0.9)
    """
    path = Path(calibration) if isinstance(calibration, (str, os.PathLike)) else None
    obj = load_json(calibration) if path is not None else dict(calibration)
    src = str(path) if path is not None else None
    calib = read_calibration(calibration if path is not None else obj)
    warnings: list[str] = []
    forced = intrinsics is not None or bool(overrides)
    stored = None
    if report_data == "auto":
        stored = _stored_path(obj, path) if path is not None else None
    elif report_data is not None:
        stored = Path(report_data)
    if stored is not None and not forced and (stored.exists() or report_data != "auto"):
        try:
            run = read_run(stored, calib)
            return LoadedRun(run=run, origin="stored", path=stored, warnings=warnings,
                             message=f"figures of the run stored in {stored}")
        except InputError as exc:
            if keypoints is None:
                keypoints = recorded_keypoints(obj, path)
            if keypoints is None:
                raise InputError(f"{exc}; give the keypoints the calibration was made "
                                 "from to draw it from them (mirrorgraph report "
                                 f"{src or 'CALIBRATION'} KEYPOINTS --out DIR), or calibrate "
                                 "again with --report") from None
            warnings.append(f"{exc}; recomputing the run from {keypoints} instead")
    if keypoints is None:
        keypoints = recorded_keypoints(obj, path)
    if keypoints is None:
        where = f" ({stored} is missing)" if stored is not None else ""
        recorded = (obj.get("input") or {}).get("source")
        seen = f" (the recorded {recorded} is not there)" if recorded else ""
        raise InputError(f"no stored run to draw{where}: give the keypoints the "
                         f"calibration was made from{seen}, to recompute it",
                         source=src, field="keypoints")
    from ..pipelines.mirror import calibrate

    opts = options_from_calibration(obj)
    if overrides:
        opts = replace(opts, **overrides)
    if not isinstance(keypoints, (RawDetections, PairedKeypoints)):
        keypoints = read_keypoints(keypoints,
                                   skeleton=skeleton or (obj.get("input") or {}).get("skeleton"))
    run = calibrate(keypoints, intrinsics if intrinsics is not None else calib.intrinsics, opts,
                    progress=progress, iteration_progress=iteration_progress,
                    ransac_progress=ransac_progress)
    new = run.calibration
    angle = float(np.degrees(np.arccos(np.clip(abs(float(np.dot(new.normal, calib.normal))),
                                               -1.0, 1.0))))
    same_d = ((new.distance is None) == (calib.distance is None)) and (
        calib.distance is None or abs(new.distance - calib.distance) <= 1e-9 * calib.distance)
    name = src or "the calibration"
    if angle <= 1e-7 and same_d:
        message = (f"figures of the run recomputed from {run.paired.source or 'the keypoints'} "
                   f"with the options {name} records (the same mirror)")
    else:
        message = (f"figures of the run recomputed from {run.paired.source or 'the keypoints'}")
        what = f"{angle:.3g} deg from" if angle > 1e-7 else "at another distance than"
        warnings.append(f"the recomputed mirror is {what} the one in {name} (other keypoints, "
                        "options or mirrorgraph version?): the figures show the recomputation")
    return LoadedRun(run=run, origin="recomputed", message=message, warnings=warnings)


def run_from_calibration(calibration, keypoints=None, *, intrinsics=None, min_confidence=None,
                         threshold_px=None):
    """The :class:`~mirrorgraph.pipelines.mirror.CalibrationRun` of a ``calibration.json``.

    The run stored beside the calibration when there is one, else the keypoints
    calibrated again with the options the file records; see :func:`load_run`
    (which also says which of the two it did).

    Args:
        calibration: path of ``calibration.json`` (or its parsed dict).
        keypoints: a keypoint path or what :func:`mirrorgraph.read_keypoints` returned.
        intrinsics: overrides the intrinsics stored in the calibration.
        min_confidence, threshold_px: override the values stored in the file.
    """
    overrides = {k: v for k, v in (("min_confidence", min_confidence),
                                   ("threshold_px", threshold_px)) if v is not None}
    return load_run(calibration, keypoints, intrinsics=intrinsics, overrides=overrides).run
