"""The calibration pipeline: keypoints in, calibrated mirror out.

    read -> undistort -> pair person and reflection -> robust initialisation
         -> factor-graph refinement (optional) -> :class:`~mirrorgraph.calibration.Calibration`

Each step lives in its own module; this one only strings them together and
collects what a user should know about the run (warnings, counts).
"""

from __future__ import annotations

import os
import time
import warnings as _warnings
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from . import geometry as geo
from .calibration import Calibration
from .errors import DegenerateGeometryError, InputError
from .estimators import DEFAULT_THRESHOLD_PX, ESTIMATORS, estimate_mirror
from .intrinsics import DEFAULT_FOV_DEG, Intrinsics, intrinsics_from_fov
from .keypoints import PairedKeypoints, RawDetections
from .pairing import PairingOptions, fix_left_right, pair_detections

#: Fewest inlier pairs accepted for a calibration.
MIN_PAIRS = 12


@dataclass
class CalibrateOptions:
    """Options of :func:`calibrate`.

    Attributes:
        estimator: initial estimator, one of ``reflective`` (default),
            ``eightpoint`` (MirrorCalib's Baseline1), ``reflective8`` (the
            paper's 6-unknown eight-point with RANSAC).
        threshold_px: inlier threshold on the epipolar distance, pixels.
        min_confidence: joints below this detector confidence are ignored.
        joints: names of the joints used; ``None`` = the skeleton's default
            (no face, hands or feet, as MirrorCalib).
        refine: run the factor-graph refinement after the initialisation.
        subject_height: subject's standing height in metres (metric prior).
        seed: seed of every random choice (RANSAC).
        fov_deg: horizontal field of view assumed when no intrinsics are given.
        image_size: ``(width, height)`` used when no intrinsics are given and
            the input does not carry it.
        refine_options: :class:`mirrorgraph.graph.RefineOptions` (weights, kernel).
    """

    estimator: str = "reflective"
    threshold_px: float = DEFAULT_THRESHOLD_PX
    min_confidence: float = 0.3
    joints: tuple[str, ...] | None = None
    refine: bool = True
    subject_height: float | None = None
    seed: int = 0
    fov_deg: float = DEFAULT_FOV_DEG
    image_size: tuple[int, int] | None = None
    refine_options: object | None = None


@dataclass
class CalibrationRun:
    """Everything a run produced: the calibration and the data behind it.

    Attributes:
        calibration: the result.
        paired: undistorted, paired keypoints.
        inliers: ``(T, J)`` bool, pairs kept by the initialisation (after the
            refinement: the pairs its final solve used).
        candidates: ``(T, J)`` bool, the pairs handed to the refinement: epipolar
            distance under :data:`REFINE_GATE_FACTOR` thresholds (see there).
        joints: ``(k,)`` joint indices used.
        joints3d: ``(T, J, 3)`` refined 3D joints (metres with a metric prior,
            else in units of the mirror distance), NaN where not estimated;
            ``None`` without refinement.
        valid3d: ``(T, J)`` bool mask of ``joints3d``.
        timings: wall seconds per step (``pairing``, ``initialisation``,
            ``build``, ``solve``, ``marginals``); kept out of the JSON so that
            the same input gives byte-identical output.
    """

    calibration: Calibration
    paired: PairedKeypoints
    inliers: np.ndarray
    joints: np.ndarray
    candidates: np.ndarray | None = None
    joints3d: np.ndarray | None = None
    valid3d: np.ndarray | None = None
    timings: dict[str, float] = field(default_factory=dict)


def resolve_intrinsics(intrinsics: Intrinsics | None, data: RawDetections | PairedKeypoints,
                       options: CalibrateOptions, warnings: list[str]) -> Intrinsics:
    """The intrinsics to use: given ones, or a pinhole guess from the image size and FOV."""
    if intrinsics is not None:
        return intrinsics
    size = options.image_size or data.image_size
    if size is None:
        raise InputError("no intrinsics and no image size: pass --intrinsics FILE or "
                         "--image-size WxH", source=data.source)
    warnings.append(f"no intrinsics given: assumed a {options.fov_deg:g} deg horizontal field "
                    f"of view with the principal point at the centre of {size[0]}x{size[1]}; "
                    "the normal and distance are approximate (the epipole in pixels is not)")
    return intrinsics_from_fov(size, options.fov_deg)


#: Keypoints count as outside the image beyond this margin (fraction of each side).
IMAGE_MARGIN = 0.10


def _fraction_outside(data: RawDetections | PairedKeypoints, size: tuple[int, int]) -> float:
    """Fraction of detected joints outside the image enlarged by :data:`IMAGE_MARGIN`."""
    if isinstance(data, PairedKeypoints):
        pts = np.concatenate([data.real.reshape(-1, 3), data.mirror.reshape(-1, 3)])
    else:
        pts = np.concatenate([p.reshape(-1, 3) for p in data.people] or [np.empty((0, 3))])
    pts = pts[(pts[:, 2] > 0) & np.isfinite(pts[:, :2]).all(1)]
    if len(pts) == 0:
        return 0.0
    w, h = size
    lo = -IMAGE_MARGIN * np.array([w, h])
    hi = (1 + IMAGE_MARGIN) * np.array([w, h])
    return float(np.mean(((pts[:, :2] < lo) | (pts[:, :2] > hi)).any(1)))


def check_image_size(data: RawDetections | PairedKeypoints, intr: Intrinsics,
                     warnings: list[str]) -> None:
    """Compare the keypoints with the image size the intrinsics belong to.

    Most keypoints outside the image mean the keypoints and K are not in the
    same pixels (a resized video, the wrong camera file). With real intrinsics
    that is a warning (the result stands if K is right for the keypoints);
    with a K guessed from that very size it is an :class:`InputError`.
    """
    if intr.image_size is None:
        return
    frac = _fraction_outside(data, intr.image_size)
    if frac <= 0.5:
        return
    w, h = intr.image_size
    msg = (f"{100 * frac:.0f}% of the keypoints lie outside the {w}x{h} image: the keypoints "
           "and the intrinsics do not seem to be in the same pixels")
    if intr.approximate:
        raise InputError(msg + "; give the video's real size", source=data.source,
                         field="image_size")
    warnings.append(msg + " (resized video? wrong camera file?)")


def undistort_keypoints(data: RawDetections | PairedKeypoints, intr: Intrinsics
                        ) -> RawDetections | PairedKeypoints:
    """The keypoints with the lens distortion of ``intr`` removed (pixels in, pixels out;
    the input itself when there is no distortion)."""
    if intr.dist is None or not np.any(intr.dist):
        return data
    if isinstance(data, PairedKeypoints):
        real, mirror = data.real.copy(), data.mirror.copy()
        real[..., :2] = intr.undistort_points(real[..., :2])
        mirror[..., :2] = intr.undistort_points(mirror[..., :2])
        return replace(data, real=real, mirror=mirror)
    people = []
    for p in data.people:
        p = np.array(p, dtype=float, copy=True)
        if len(p):
            p[..., :2] = intr.undistort_points(p[..., :2])
        people.append(p)
    return replace(data, people=people)


def _joint_indices(skeleton, names: tuple[str, ...] | None) -> np.ndarray:
    if names is None:
        return skeleton.calibration_joints
    missing = [n for n in names if not skeleton.has(n)]
    if missing:
        raise InputError(f"unknown joint(s) {', '.join(missing)} for skeleton {skeleton.name}; "
                         f"known: {', '.join(skeleton.joints)}", field="joints")
    return np.array(sorted(skeleton.index(n) for n in names), dtype=int)


def calibrate(keypoints: RawDetections | PairedKeypoints | str | os.PathLike,
              intrinsics: Intrinsics | None = None, options: CalibrateOptions | None = None,
              *, progress: Callable[[str], None] | None = None,
              iteration_progress: Callable[[int, float], None] | None = None,
              ransac_progress: Callable[[int, int], None] | None = None
              ) -> CalibrationRun:
    """Calibrate the mirror seen in a video from its 2D keypoints.

    Args:
        keypoints: a path to any supported keypoint input (see
            :func:`mirrorgraph.io.read_keypoints`), or what a reader returned.
        intrinsics: camera intrinsics; ``None`` assumes a pinhole camera from the
            image size and ``options.fov_deg`` (and says so in the warnings).
        options: :class:`CalibrateOptions`.
        progress: optional callback receiving the name of each step.
        iteration_progress: optional ``(iteration, error)`` callback of the
            graph's solver, after every iteration.
        ransac_progress: optional ``(iteration, planned)`` callback of the
            robust initialisation's RANSAC.

    Returns:
        A :class:`CalibrationRun` holding the :class:`Calibration`.

    Raises:
        InputError: unusable input (the message names file, frame or field).
        DegenerateGeometryError: the data cannot determine the mirror.
    """
    opts = options or CalibrateOptions()
    if opts.estimator not in ESTIMATORS:
        raise InputError(f"unknown estimator {opts.estimator!r}; choose one of "
                         f"{', '.join(ESTIMATORS)}", field="estimator")
    if isinstance(opts.seed, bool) or not isinstance(opts.seed, (int, np.integer)) or opts.seed < 0:
        raise InputError(f"must be a non-negative integer, got {opts.seed!r}", field="seed")
    if opts.subject_height is not None and not (0.5 < opts.subject_height < 2.8):
        raise InputError(f"subject height {opts.subject_height} m is not a human height "
                         "(0.5 to 2.8 m)", field="subject_height")
    step = progress or (lambda _name: None)
    if not isinstance(keypoints, (RawDetections, PairedKeypoints)):
        from .io import read_keypoints
        step("reading keypoints")
        keypoints = read_keypoints(keypoints)
    warnings: list[str] = []
    joints = _joint_indices(keypoints.skeleton, opts.joints)
    intr = resolve_intrinsics(intrinsics, keypoints, opts, warnings)
    check_image_size(keypoints, intr, warnings)
    data = undistort_keypoints(keypoints, intr)
    pair_opts = PairingOptions(min_confidence=opts.min_confidence,
                               threshold_px=opts.threshold_px, seed=opts.seed)
    step("pairing person and reflection")
    clock = time.perf_counter()
    if isinstance(data, PairedKeypoints):
        paired = fix_left_right(data, joints, pair_opts)
    else:
        paired = pair_detections(data, joints, pair_opts)

    t_pairing = time.perf_counter() - clock
    valid = paired.valid(opts.min_confidence)
    valid[:, np.setdiff1d(np.arange(paired.skeleton.num_joints), joints)] = False
    t_idx, j_idx = np.nonzero(valid)
    if len(t_idx) < MIN_PAIRS:
        raise DegenerateGeometryError(
            f"{paired.source}: only {len(t_idx)} joint/reflection pairs above confidence "
            f"{opts.min_confidence}; at least {MIN_PAIRS} are needed")
    u = paired.real[t_idx, j_idx, :2]
    um = paired.mirror[t_idx, j_idx, :2]
    step(f"initial estimate ({opts.estimator})")
    clock = time.perf_counter()
    try:
        est = estimate_mirror(u, um, intr.K, estimator=opts.estimator,
                              threshold_px=opts.threshold_px, seed=opts.seed,
                              progress=ransac_progress)
    except DegenerateGeometryError as exc:
        raise DegenerateGeometryError(f"{paired.source}: {exc}") from None
    inliers = np.zeros_like(valid)
    inliers[t_idx[est.inliers], j_idx[est.inliers]] = True
    gate = est.residuals < REFINE_GATE_FACTOR * opts.threshold_px
    candidates = np.zeros_like(valid)
    candidates[t_idx[gate], j_idx[gate]] = True
    t_init = time.perf_counter() - clock
    if np.count_nonzero(inliers) < MIN_PAIRS:
        raise DegenerateGeometryError(
            f"{paired.source}: only {np.count_nonzero(inliers)} pairs agree on one mirror "
            f"within {opts.threshold_px:g} px: the reflection may be another person, or the "
            "threshold too tight")
    frames_paired = int(np.count_nonzero(valid.any(1)))
    calib = Calibration(
        normal=est.normal, distance=None, scale="unknown", estimator=opts.estimator,
        intrinsics=intr, initial_normal=est.normal.copy(), refined=False,
        frames_read=paired.frames_read or len(paired), frames_paired=frames_paired,
        frames_used=int(np.count_nonzero(inliers.any(1))), pairs_total=int(len(t_idx)),
        pairs_used=int(np.count_nonzero(inliers)), lr_fixes=paired.lr_fixes,
        ransac_iterations=est.iterations,
        input={"source": paired.source, "format": paired.format,
               "skeleton": paired.skeleton.name,
               "joints": [paired.skeleton.joints[j] for j in joints],
               "min_confidence": opts.min_confidence, "threshold_px": opts.threshold_px,
               "seed": opts.seed},
        warnings=warnings)
    run = CalibrationRun(calibration=calib, paired=paired, inliers=inliers, joints=joints,
                         candidates=candidates,
                         timings={"pairing": t_pairing, "initialisation": t_init})
    residual_median = float(np.median(est.residuals[est.inliers]))
    calib.refinement = {"initial_epipolar_median_px": residual_median}
    if opts.refine:
        step("factor-graph refinement")
        _refine(run, opts, iteration_progress)
    elif opts.subject_height is not None:
        warnings.append("--subject-height needs the refinement (it scales the body); "
                        "without it the distance stays unknown")
    _judge(calib, est.residuals[est.inliers], opts,
           _motion_px(paired, joints, opts.min_confidence))
    return run


def _refine(run: CalibrationRun, opts: CalibrateOptions,
            iteration_progress: Callable[[int, float], None] | None = None) -> None:
    from .graph import RefineOptions, refine_mirror

    ropts = opts.refine_options or RefineOptions()
    if opts.subject_height is not None:
        ropts = replace(ropts, subject_height=opts.subject_height)
    calib = run.calibration
    pairs = run.candidates if run.candidates is not None else run.inliers
    res = refine_mirror(run.paired, calib.intrinsics.K, calib.normal, pairs,
                        joints=run.joints, options=ropts, progress=iteration_progress)
    calib.normal = np.asarray(res.normal, dtype=float)
    calib.refined = True
    if res.scale == "subject_height":
        calib.distance, calib.scale = float(res.distance), "subject_height"
    calib.pairs_used = int(np.count_nonzero(res.inliers))
    calib.frames_used = int(np.count_nonzero(res.inliers.any(1)))
    calib.refinement.update({
        "priors": res.priors,
        "iterations": int(res.iterations),
        "final_error": float(res.final_error),
        "rms_direct_px": float(res.rms_direct_px),
        "rms_mirror_px": float(res.rms_mirror_px),
        "bone_lengths": {k: float(v) for k, v in res.bone_lengths.items()},
        "scale_source": res.scale,
        "scale_method": res.scale_source,
        "stature": res.stature,
    })
    if res.scale == "subject_height" and res.stature is None and ropts.scale_from == "stature":
        calib.warnings.append(f"scale: {res.scale_source}")
    run.timings.update({k: float(v) for k, v in res.timings.items() if k != "total"})
    calib.uncertainty = {
        "normal_cov": np.asarray(res.normal_cov).tolist(),
        "rotation_std_deg": float(res.rotation_std_deg),
        "distance_std": None if calib.distance is None else float(res.distance_std),
        "source": "gtsam.Marginals of the mirror plane at the solution",
    }
    run.joints3d, run.valid3d = res.joints3d, res.valid
    run.inliers = res.inliers


#: The refinement gets every pair within this many RANSAC thresholds of the initial
#: mirror, not only the RANSAC inliers: an inlier set chosen against the initial
#: estimate truncates the noise about *that* estimate and pulls the refinement back
#: to it (measured on the paper's protocol, 12 seeds: RMS error / Cramer-Rao bound
#: 1.41 with the inliers, 1.10 with every pair). The gate only keeps gross outliers
#: (tens of pixels off their epipolar line) out of the first solve; the graph's
#: robust kernel and its own rejection (:mod:`mirrorgraph.graph.outliers`) do the rest.
REFINE_GATE_FACTOR = 3.0

#: Warn when the inliers' median epipolar distance exceeds this many pixels.
SUSPICIOUS_RESIDUAL_PX = 6.0
#: Warn when fewer of the pairs agree on one mirror: a true reflection, even
#: with 30% detector outliers, keeps about 70%; a second person mistaken for
#: the reflection keeps about half (chance alignments with a far epipole).
MIN_INLIER_RATIO = 0.6
#: Warn when the rotation's standard deviation from the marginals exceeds this
#: (degrees): a mirror seen almost edge-on or square-on, too few frames, or
#: too little motion leave the epipole ill-determined in one direction.
MAX_ROTATION_STD_DEG = 0.5
#: Warn when the person's joints move less than this (median over joints of
#: the standard deviation of their image position over time, pixels).
MIN_MOTION_PX = 3.0


def _motion_px(paired: PairedKeypoints, joints: np.ndarray, min_confidence: float) -> float:
    """Median over joints of the std of the person's image position over time, pixels."""
    xy = paired.real[:, joints, :2].copy()
    xy[~(paired.real[:, joints, 2] > min_confidence)] = np.nan
    with np.errstate(invalid="ignore"), _warnings.catch_warnings():
        _warnings.simplefilter("ignore", RuntimeWarning)      # all-NaN joints
        spread = np.nanstd(xy, axis=0)                   # (k, 2)
        return float(np.nanmedian(np.hypot(spread[:, 0], spread[:, 1])))


def _judge(calib: Calibration, inlier_residuals: np.ndarray, opts: CalibrateOptions,
           motion_px: float = np.inf) -> None:
    """Put doubts about the result into its warnings."""
    if calib.inlier_ratio < MIN_INLIER_RATIO:
        calib.warnings.append(
            f"only {100 * calib.inlier_ratio:.0f}% of the joint/reflection pairs agree on one "
            "mirror: the 'reflection' may be a second person, or the detector poor")
    med = float(np.median(inlier_residuals)) if inlier_residuals.size else np.inf
    if med > SUSPICIOUS_RESIDUAL_PX:
        calib.warnings.append(
            f"median epipolar distance of the inliers is {med:.1f} px, far above typical "
            "detector noise: the 'reflection' may be another person or the keypoints poor")
    if calib.uncertainty.get("rotation_std_deg", 0.0) > MAX_ROTATION_STD_DEG:
        calib.warnings.append(
            f"the mirror is poorly determined (rotation std "
            f"{calib.uncertainty['rotation_std_deg']:.2f} deg): a mirror seen almost edge-on or "
            "square-on, too few frames or too little motion; more frames and motion help")
    if motion_px < MIN_MOTION_PX:
        calib.warnings.append(
            f"the person hardly moves (joints move {motion_px:.1f} px): the calibration rests "
            "on a single pose, and its errors do not average out over frames")
    e_px = geo.epipole_pixels(calib.epipole)
    if e_px is None:
        calib.warnings.append("the epipole is at infinity (mirror parallel to the optical axis)")
