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
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import geometry as geo
from .calibration import Calibration
from .completion import complete_mirror_joints
from .errors import DegenerateGeometryError, InputError
from .estimators import estimate_mirror
from .graph.options import RefineOptions
from .pipelines.options import CalibrateOptions
from .graph.refine import refine_mirror
from .graph.sensitivity import prior_weights
from .graph.uncertainty import POORLY_DETERMINED_DEG, region_rotation_deg
from .intrinsics import Intrinsics, estimated_intrinsics, intrinsics_from_fov
from .io import read_keypoints
from .joint_sets import mirror_joints
from .keypoints import MIN_PAIRS, PairedKeypoints, RawDetections
from .pairing import PairingOptions, fix_left_right, frame_scores, pair_detections
from .preprocess import check_image_size, resolve_fps, undistort_keypoints



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
            else in units of the mirror distance), real camera frame, NaN where not
            estimated; the graph's joints plus the keypoints completed with the
            solved mirror (:attr:`completed`); ``None`` without refinement.
        valid3d: ``(T, J)`` bool mask of ``joints3d``.
        completed: ``(T, J)`` bool, the entries of ``joints3d`` triangulated after the
            graph (:mod:`mirrorgraph.completion`); ``None`` without refinement.
        fps: the frame rate of the 3D motion, Hz (:func:`mirrorgraph.preprocess.resolve_fps`).
        fps_source: where it came from: ``"option"``, ``"input"``, ``"video"`` or
            ``"default"``.
        timings: wall seconds per step (``pairing``, ``initialisation``,
            ``build``, ``solve``, ``marginals``, ``uncertainty``); kept out of the JSON
            so that the same input gives byte-identical output.
        refine_parts: the refinement's uncertainty figures with their covariances
            (:func:`mirrorgraph.graph.uncertainty.robust_normal_cov`); the JSON holds
            their standard deviations (``uncertainty.robust``).
    """

    calibration: Calibration
    paired: PairedKeypoints
    inliers: np.ndarray
    joints: np.ndarray
    candidates: np.ndarray | None = None
    joints3d: np.ndarray | None = None
    valid3d: np.ndarray | None = None
    completed: np.ndarray | None = None
    fps: float = 30.0
    fps_source: str = "default"
    timings: dict[str, float] = field(default_factory=dict)
    refine_parts: dict | None = None

    @property
    def joints_completed(self) -> int:
        """Entries of :attr:`joints3d` completed with the solved mirror (0 without)."""
        return 0 if self.completed is None else int(np.count_nonzero(self.completed))


def resolve_intrinsics(intrinsics: Intrinsics | None, data: RawDetections | PairedKeypoints,
                       options: CalibrateOptions, warnings: list[str]) -> Intrinsics:
    """The intrinsics to use: given ones, or a pinhole guess from the image size and FOV."""
    if intrinsics is not None:
        return intrinsics
    size = options.image_size or data.image_size
    if size is None:
        raise InputError("no intrinsics and no image size", source=data.source,
                         fix=("intrinsics", "image_size"))
    if not options.refine:
        warnings.append(f"no intrinsics given: assumed a {options.fov_deg:g} deg horizontal "
                        f"field of view with the principal point at the centre of "
                        f"{size[0]}x{size[1]}; the normal and distance are approximate (the "
                        "epipole in pixels is not)")
    return intrinsics_from_fov(size, options.fov_deg)


def focal_estimated(options: CalibrateOptions) -> bool:
    """Whether a run without intrinsics estimates the focal length (it needs the graph)."""
    return bool(options.estimate_focal and options.refine)


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
    opts = (options or CalibrateOptions()).checked()
    step = progress or (lambda _name: None)
    if not isinstance(keypoints, (RawDetections, PairedKeypoints)):
        step("reading keypoints")
        keypoints = read_keypoints(keypoints, skeleton=opts.skeleton, video=opts.detection)
    warnings: list[str] = []
    joints = mirror_joints(keypoints.skeleton, opts.joints, source=keypoints.source or None)
    fps_warnings: list[str] = []
    fps, fps_source = resolve_fps(keypoints, fps_warnings, fps=opts.fps, video=opts.video)
    if opts.refine:                      # the frame rate matters to the 3D motion only
        warnings.extend(fps_warnings)
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
    scores = frame_scores(data, est.epipole, joints, pair_opts,
                          quantile=(0.5, GREY_QUANTILE))
    check = check_reflection(scores[0], opts.threshold_px, scores[1])
    if check.verdict == "second_person":
        raise DegenerateGeometryError(f"{paired.source}: {check.describe()}")
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
               "seed": opts.seed, "fps": fps, "fps_source": fps_source,
               "subject_height": opts.subject_height, "scale_from": _scale_from(opts),
               "read_notes": keypoints.read_notes.as_dict()},
        warnings=warnings)
    run = CalibrationRun(calibration=calib, paired=paired, inliers=inliers, joints=joints,
                         candidates=candidates, fps=fps, fps_source=fps_source,
                         timings={"pairing": t_pairing, "initialisation": t_init})
    residual_median = float(np.median(est.residuals[est.inliers]))
    calib.refinement = {"initial_epipolar_median_px": residual_median}
    calib.input["reflection_check"] = check.to_dict()
    if opts.refine:
        step("factor-graph refinement")
        # without intrinsics the focal length and principal point are always variables of
        # the graph: about the 60 deg guess with a wide prior (estimated), or about the
        # user's field of view with that guess's own spread (--fov)
        _refine(run, opts, iteration_progress, estimate_focal=intrinsics is None,
                focal_rel_sigma=None if focal_estimated(opts) else
                (opts.refine_options or RefineOptions()).focal.guess_rel_sigma)
    elif opts.subject_height is not None:
        warnings.append("--subject-height needs the refinement (it scales the body); "
                        "without it the distance stays unknown")
    rays = (median_ray_angle_deg(run.joints3d, run.valid3d, calib.normal,
                                 calib.distance if calib.distance is not None else 1.0)
            if opts.refine else float("nan"))
    _judge(calib, est.residuals[est.inliers], opts,
           _motion_px(paired, joints, opts.min_confidence), check, rays)
    return run


def _scale_from(opts: CalibrateOptions) -> str:
    """How a subject height becomes a length (``RefineOptions.scale_from``)."""
    return (opts.refine_options or RefineOptions()).scale_from


def _refine(run: CalibrationRun, opts: CalibrateOptions,
            iteration_progress: Callable[[int, float], None] | None = None,
            estimate_focal: bool = False, focal_rel_sigma: float | None = None) -> None:
    ropts = opts.graph
    calib = run.calibration
    pairs = run.candidates if run.candidates is not None else run.inliers
    guess = calib.intrinsics
    res = refine_mirror(run.paired, guess.K, calib.normal, pairs,
                        joints=run.joints, options=ropts, progress=iteration_progress,
                        estimate_focal=estimate_focal, focal_rel_sigma=focal_rel_sigma)
    if estimate_focal:
        calib.intrinsics = estimated_intrinsics(guess, res.intrinsics, res.focal,
                                                opts.fov_deg, calib.warnings,
                                                user_guess=focal_rel_sigma is not None)
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
    parts = res.uncertainty_parts or {}
    run.refine_parts = parts
    calib.sensitivity = dict(res.sensitivity or {})
    if opts.sensitivity_priors and calib.sensitivity:
        def again(o):
            return refine_mirror(run.paired, guess.K, calib.initial_normal, pairs,
                                 joints=run.joints, options=o, estimate_focal=estimate_focal,
                                 focal_rel_sigma=focal_rel_sigma)
        clock = time.perf_counter()
        calib.sensitivity["prior_weights"] = prior_weights(again, res.normal, ropts, res.priors)
        run.timings["sensitivity"] = time.perf_counter() - clock
    calib.uncertainty = {
        "normal_cov": np.asarray(res.normal_cov).tolist(),
        "rotation_std_deg": float(res.rotation_std_deg),
        "rotation_90_deg": float(parts.get("rotation_90_deg",
                                           region_rotation_deg(res.normal_cov))),
        "distance_std": None if calib.distance is None else float(res.distance_std),
        "marginal_normal_cov": np.asarray(res.marginal_normal_cov).tolist()
        if res.marginal_normal_cov is not None else None,
        "marginal_rotation_std_deg": float(res.marginal_rotation_std_deg),
        "robust": {k: (v if isinstance(v, str) else float(v)) for k, v in parts.items()
                   if not k.endswith("_normal_cov") and k != "contributions"},
        "source": ("the largest of: the marginals of the mirror plane (iid noise) and the "
                   "cluster-robust sandwich over time segments and joint pairs "
                   "(mirrorgraph.graph.uncertainty)"),
    }
    if res.focal.get("estimated"):
        calib.uncertainty["focal_std_px"] = float(res.focal["std_px"])
        calib.uncertainty["focal_marginal_std_px"] = float(res.focal["marginal_std_px"])
        if "principal_point_std_px" in res.focal:
            calib.uncertainty["principal_point_std_px"] = list(res.focal["principal_point_std_px"])
        calib.uncertainty["contributions"] = {
            k: float(v) for k, v in (parts.get("contributions") or {}).items()}
        calib.uncertainty["source"] = (
            "with the intrinsics estimated: the largest of the marginals of the plane, "
            "the focal length, the principal point and the bone lengths together (the "
            "bones decide the focal length; the priors about the guess hold the spread of "
            "real cameras) and the sandwich over time segments with the priors' spread (the "
            "bones couple a frame's joints: no joint-pair clusters) "
            "(mirrorgraph.graph.uncertainty.frame_scores); contributions: the share of the "
            "rotation's variance each unknown intrinsic makes")
    run.joints3d, run.valid3d = res.joints3d, res.valid
    run.inliers = res.inliers
    if opts.complete_joints:
        clock = time.perf_counter()
        done = complete_mirror_joints(run.paired, calib.intrinsics.K, calib.normal,
                                      float(res.distance), res.joints3d, res.valid,
                                      joints=run.joints, min_confidence=opts.min_confidence,
                                      threshold_px=opts.threshold_px)
        run.joints3d, run.valid3d, run.completed = done.joints3d, done.valid, done.completed
        calib.refinement["completion"] = done.to_dict()
        run.timings["completion"] = time.perf_counter() - clock


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
#: Warn when the person's joints move less than this (median over joints of
#: the standard deviation of their image position over time, pixels).
MIN_MOTION_PX = 3.0


# ------------------------------------------------------------ a second person?
#: Frames a verdict on the reflection needs (frames holding a candidate pair).
CHECK_MIN_FRAMES = 30
#: Warn when fewer of the frames holding two detections or more pair up (their best
#: candidate's median epipolar distance under the threshold) ...
DOUBT_PAIRED_FRACTION = 0.80
#: ... or when more of them fall in the grey zone: fitting neither as a reflection nor
#: as an unrelated pair. The grey zone is read on a lower quantile of each frame's
#: epipolar distances, :data:`GREY_QUANTILE` (the median lets a detector's gross errors
#: on a few joints in: real reflections with 20 % outliers a view were in it in 39 of
#: 40 scenes with the median, 0 of 40 with the 0.3 quantile); its bounds are
#: :data:`GREY_LOW` times that score's median over the frames that pair, and
#: :data:`GREY_HIGH` times the threshold.
DOUBT_GREY_FRACTION = 0.08
GREY_QUANTILE = 0.3
GREY_LOW = 2.5
GREY_HIGH = 3.0
#: Refuse when both hold: the "reflection" pairs in fewer than this fraction of the
#: frames ...
REFUSE_PAIRED_FRACTION = 0.25
#: ... and more than this fraction lie in the grey zone.
REFUSE_GREY_FRACTION = 0.15


@dataclass(frozen=True)
class ReflectionCheck:
    """Is the detection paired with the person their reflection? (:func:`check_reflection`)

    Attributes:
        frames: frames holding a candidate pair (two detections or more).
        paired_fraction: of those, the fraction whose best pair fits the mirror (median
            epipolar distance under the threshold).
        grey_fraction: the fraction in the grey zone (see :func:`check_reflection`).
        median_px: median score of the frames that pair, pixels (NaN if none).
        verdict: ``"ok"``, ``"doubtful"`` (a warning), ``"second_person"`` (refused) or
            ``"too_few_frames"`` (no verdict).
    """

    frames: int
    paired_fraction: float
    grey_fraction: float
    median_px: float
    verdict: str

    def describe(self) -> str:
        """One line for the warnings or the error."""
        what = (f"the detection paired as the reflection fits one mirror in "
                f"{100 * self.paired_fraction:.0f}% of the {self.frames} frames holding two "
                f"people and fits badly in {100 * self.grey_fraction:.0f}% (a reflection "
                "fits in nearly all, at the detector's noise)")
        if self.verdict == "second_person":
            return what + ": it is a second person, not the reflection"
        return (what + ": the 'reflection' may be a second person, or the detector poor "
                "(gross errors on many joints, noise beyond --threshold), or the reflection "
                "often missing while somebody else is seen")

    def to_dict(self) -> dict:
        """The record in ``calibration.json`` (``input.reflection_check``)."""
        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None
        return {"frames": self.frames, "paired_fraction": num(self.paired_fraction),
                "grey_fraction": num(self.grey_fraction), "median_px": num(self.median_px),
                "verdict": self.verdict}


def check_reflection(scores: np.ndarray, threshold_px: float,
                     grey_scores: np.ndarray | None = None) -> ReflectionCheck:
    """Tell a reflection from a second person by how the frames fit the mirror.

    ``scores`` is, per frame, the best candidate pair's median epipolar distance to the
    estimated mirror (:func:`mirrorgraph.pairing.frame_scores`); ``grey_scores`` the
    same with the :data:`GREY_QUANTILE` quantile over joints instead of the median. A
    true reflection fits in nearly every frame holding it, at the detector's noise: the
    scores gather around one value (about 3 px for 4 px noise), and the frames that do
    not pair are frames without the reflection (the person and a bystander), scored by
    two unrelated poses, mostly far off. A second person taken for the reflection fits
    only by chance: in the frames where both stand in alike poses; elsewhere their
    poses differ by a little or a lot, and the scores spread from the noise to tens of
    pixels. Two fractions of the frames holding a candidate pair tell them apart:

    * ``paired``: ``scores`` under ``threshold_px``;
    * ``grey``: ``grey_scores`` above :data:`GREY_LOW` times their median over the
      paired frames and under :data:`GREY_HIGH` times ``threshold_px``: too far for
      noise, too close for most unrelated pairs.

    Verdicts: refused (``second_person``) when ``paired < REFUSE_PAIRED_FRACTION`` and
    ``grey > REFUSE_GREY_FRACTION``; doubtful (a warning) when
    ``paired < DOUBT_PAIRED_FRACTION`` or ``grey > DOUBT_GREY_FRACTION``; no verdict on
    fewer than :data:`CHECK_MIN_FRAMES` frames. Both fractions are ratios, free of the
    detector's noise level as long as the noise stays under the threshold.

    Measured with ``tests/test_second_person.py`` (its benchmark builds the scenes):
    ``make_scene``, seeds 0-39, mirror angle 10-60 deg, distance 2.5-4.5 m, field of
    view 50-75 deg, 4 px noise, 5-10 % outliers, 5 % left/right swaps, 300 frames unless
    said. False alarms on real reflections, warned / refused of 40 each:
    **0 / 0** with 4 px noise, 2 px, 8 px, AR(1) 0.95 correlated noise, a 2 px
    per-joint bias, BODY_25, 100 and 1000 frames, the mirror at 10 and at 60 deg, an
    unmodelled lens distortion (k1 = -0.2), 20 % outliers a view, 20 % and 40 % of
    the frames with a bystander (with 20 % missing the reflection or the person, 10 %
    missing joints); 30 % outliers a view: 40 / 0 (warned: the pairing loses 36-48 %
    of the frames, whose median joint is then an outlier).

    Second persons where the reflection should be, at the reflection's place and image
    height, caught (warned or refused) / refused of 40 each:

    ==================================================  ================  ================
    the "reflection" is                                 300 frames        100 frames
    ==================================================  ================  ================
    another person, moving                              40 / 16           34 / 14
    another person, standing still                      39 / 11           34 / 11
    the reflection's own detections 1-5 s late          32 / 9            16 / 4
    a still snapshot of the reflection                  30 / 6            15 / 1
    ==================================================  ================  ================

    Of those missed at 300 frames, the initial mirror was off by more than 0.5 deg in 0,
    1, 3 and 10 scenes.

    Not caught: a second person whose pose and place match the reflection's in nearly
    every frame (a snapshot of the reflection while the subject rests, somebody doing
    the same exercise in step), which no epipolar test tells from a reflection; short
    videos (3 s) hold too few frames where the poses differ.

    Args:
        scores: ``(T,)`` px; NaN for frames without a candidate pair, inf for pairs
            sharing too few joints.
        threshold_px: the pairing's threshold, pixels.
        grey_scores: ``(T,)`` px, the same frames scored by a lower quantile (default:
            ``scores``).

    Returns:
        :class:`ReflectionCheck`.
    """
    s = np.asarray(scores, dtype=float)
    g = s if grey_scores is None else np.asarray(grey_scores, dtype=float)
    has = ~np.isnan(s)
    s, g = s[has], g[has]
    n = int(s.size)
    if n == 0:
        return ReflectionCheck(0, float("nan"), float("nan"), float("nan"), "too_few_frames")
    ok = s < threshold_px
    paired = float(np.mean(ok))
    median = float(np.median(s[ok])) if ok.any() else float("nan")
    low = GREY_LOW * (float(np.median(g[ok])) if ok.any() else float(threshold_px))
    grey = float(np.mean((g > low) & (g < GREY_HIGH * threshold_px)))
    if n < CHECK_MIN_FRAMES:
        verdict = "too_few_frames"
    elif paired < REFUSE_PAIRED_FRACTION and grey > REFUSE_GREY_FRACTION:
        verdict = "second_person"
    elif paired < DOUBT_PAIRED_FRACTION or grey > DOUBT_GREY_FRACTION:
        verdict = "doubtful"
    else:
        verdict = "ok"
    return ReflectionCheck(n, paired, grey, median, verdict)


def _motion_px(paired: PairedKeypoints, joints: np.ndarray, min_confidence: float) -> float:
    """Median over joints of the std of the person's image position over time, pixels."""
    xy = paired.real[:, joints, :2].copy()
    xy[~(paired.real[:, joints, 2] > min_confidence)] = np.nan
    with np.errstate(invalid="ignore"), _warnings.catch_warnings():
        _warnings.simplefilter("ignore", RuntimeWarning)      # all-NaN joints
        spread = np.nanstd(xy, axis=0)                   # (k, 2)
        return float(np.nanmedian(np.hypot(spread[:, 0], spread[:, 1])))


#: A mirror whose normal is within this angle of the optical axis is "seen square-on"
#: (the epipole near the image centre, the person in front of their reflection) ...
SQUARE_ON_DEG = 15.0
#: ... and beyond this one "edge-on" (the epipole far outside the image), in the words
#: of the warnings (:func:`poor_mirror_cause`).
EDGE_ON_DEG = 65.0
#: A joint's two rays (direct and through the mirror) meeting at a median angle under
#: this is "low parallax" in the warnings (each ray's depth error is ~1/sin of it).
LOW_PARALLAX_DEG = 20.0
#: The share of a rotation's variance (:func:`~mirrorgraph.graph.uncertainty.
#: intrinsics_contributions`) above which an unknown intrinsic is named as the cause.
DOMINANT_SHARE = 0.5


def poor_mirror_cause(uncertainty: dict, normal: np.ndarray, ray_angle_deg: float = np.nan,
                      motion_px: float = np.inf, frames: int | None = None) -> str:
    """The cause of a poorly determined mirror, in words, from what dominates its std.

    The unknown focal length or principal point where its share of the rotation's
    variance (``uncertainty["contributions"]``) is the largest and above
    :data:`DOMINANT_SHARE`; else the joint pairs' disagreement where the joint-pair
    clusters gave the figure (a detector's per-joint bias); else what the geometry
    shows: rays meeting at small angles (``ray_angle_deg``, the median angle between a
    joint's two rays), a mirror seen edge-on or square-on (the normal's angle to the
    optical axis), a person who hardly moves (``motion_px``), few frames.
    """
    share = {k: v for k, v in (uncertainty.get("contributions") or {}).items()
             if np.isfinite(v)}
    what = {"focal_length": "the unknown focal length", "principal_point":
            "the unknown principal point (the image centre +- the spread of real cameras)"}
    if share:
        top = max(share, key=share.get)
        if share[top] > DOMINANT_SHARE:
            rest = [f"{what[k].split(' (')[0]} {100 * v:.0f}%" for k, v in share.items()]
            return (f"{what[top]} dominates it ({', '.join(rest)} of its variance); "
                    "pass --intrinsics FILE (a calibrated camera matrix) to remove it")
    robust = uncertainty.get("robust") or {}
    if robust.get("chosen") in ("joint", "two_way", "jack_joint"):
        return ("the joint pairs disagree about the mirror (a detector placing some joints "
                "consistently off: more frames do not help; see sensitivity.leave_out.joint_pairs)")
    causes = []
    if np.isfinite(ray_angle_deg) and ray_angle_deg < LOW_PARALLAX_DEG:
        causes.append(f"low parallax (a joint's two rays meet at a median {ray_angle_deg:.0f} "
                      "deg: the person near the line from the camera to the mirror)")
    angle = float(np.degrees(np.arccos(min(abs(float(np.asarray(normal)[2])), 1.0))))
    if angle < SQUARE_ON_DEG:
        causes.append(f"a mirror seen square-on ({angle:.0f} deg off the optical axis)")
    elif angle > EDGE_ON_DEG:
        causes.append(f"a mirror seen edge-on ({angle:.0f} deg off the optical axis)")
    if motion_px < 3 * MIN_MOTION_PX:
        causes.append(f"too little motion (joints move {motion_px:.1f} px)")
    if frames is not None and frames < 100:
        causes.append(f"few frames ({frames})")
    if causes:
        return "; ".join(causes)
    return ("a mirror seen almost edge-on or square-on, too few frames or too little motion; "
            "more frames and motion help")


def median_ray_angle_deg(joints3d: np.ndarray | None, valid: np.ndarray | None,
                         normal: np.ndarray, distance: float) -> float:
    """Median angle between a joint's two rays, degrees: from the real camera (origin)
    and from the virtual one (``2 d n``), over the ``(T, J, 3)`` joints ``valid``
    (real camera frame, the unit of ``distance``); NaN without joints."""
    if joints3d is None or valid is None or not np.any(valid):
        return float("nan")
    X = np.asarray(joints3d, float)[np.asarray(valid, bool)]
    a = X / np.linalg.norm(X, axis=-1, keepdims=True)
    b = X - 2.0 * float(distance) * np.asarray(normal, float)
    b /= np.linalg.norm(b, axis=-1, keepdims=True)
    return float(np.degrees(np.median(np.arccos(np.clip(np.sum(a * b, -1), -1.0, 1.0)))))


def _judge(calib: Calibration, inlier_residuals: np.ndarray, opts: CalibrateOptions,
           motion_px: float = np.inf, check: ReflectionCheck | None = None,
           ray_angle_deg: float = np.nan) -> None:
    """Put doubts about the result into its warnings."""
    if check is not None and check.verdict == "doubtful":
        calib.warnings.append(check.describe())
    if calib.inlier_ratio < MIN_INLIER_RATIO:
        calib.warnings.append(
            f"only {100 * calib.inlier_ratio:.0f}% of the joint/reflection pairs agree on one "
            "mirror: the 'reflection' may be a second person, or the detector poor")
    med = float(np.median(inlier_residuals)) if inlier_residuals.size else np.inf
    if med > SUSPICIOUS_RESIDUAL_PX:
        calib.warnings.append(
            f"median epipolar distance of the inliers is {med:.1f} px, far above typical "
            "detector noise: the 'reflection' may be another person or the keypoints poor")
    if calib.uncertainty.get("rotation_std_deg", 0.0) > POORLY_DETERMINED_DEG:
        calib.warnings.append(
            f"the mirror is poorly determined (rotation std "
            f"{calib.uncertainty['rotation_std_deg']:.2f} deg): "
            + poor_mirror_cause(calib.uncertainty, calib.normal, ray_angle_deg, motion_px,
                                calib.frames_used))
    if motion_px < MIN_MOTION_PX:
        calib.warnings.append(
            f"the person hardly moves (joints move {motion_px:.1f} px): the calibration rests "
            "on a single pose, and its errors do not average out over frames")
    e_px = geo.epipole_pixels(calib.epipole)
    if e_px is None:
        calib.warnings.append("the epipole is at infinity (mirror parallel to the optical axis)")
