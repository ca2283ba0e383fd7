"""``calibrate``: keypoints in, calibrated mirror out (the rig of one camera and one mirror).

The run, step for step as :mod:`.rig`'s for a rig:

    observations (read, undistort, pair person and reflection, :mod:`mirrorgraph.initial.pairing`)
    -> initialisation (reflective RANSAC, :mod:`mirrorgraph.initial.estimators`; the
       reflection check)
    -> solve (the one graph, :func:`.solve.refine_mirror`; optional)
    -> completion (:func:`mirrorgraph.completion.complete_mirror_joints`)
    -> scale (the stature, :mod:`.scale`)
    -> result (:class:`~mirrorgraph.result.mirror.Calibration`, judged by
       :func:`.judge.judge_mirror`)

Each step lives in its own module; this one only strings them together and collects
what a user should know about the run (warnings, counts).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..result.mirror import Calibration
from ..completion import complete_mirror_joints
from ..errors import DegenerateGeometryError, InputError
from ..initial.estimators import estimate_mirror
from .judge import judge_mirror, median_ray_angle_deg, motion_px
from .options import CalibrateOptions
from ..initial.reflection_check import GREY_QUANTILE, check_reflection
from .solve import refine_mirror
from ..graph.sensitivity import prior_weights
from ..graph.uncertainty import region_rotation_deg
from ..intrinsics import Intrinsics, estimated_intrinsics, intrinsics_from_fov
from ..io import read_keypoints
from ..joint_sets import mirror_joints
from ..keypoints import MIN_PAIRS, PairedKeypoints, RawDetections
from ..initial.left_right import fix_left_right
from ..initial.pair_candidates import PairingOptions
from ..initial.pair_scores import frame_scores
from ..initial.pairing import pair_detections
from ..preprocess import check_image_size, resolve_fps, undistort_keypoints



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
    obs = observe(keypoints, intrinsics, opts, step)                        # observations
    init = initialise(obs, opts, step, ransac_progress)                     # initialisation
    run = initial_run(obs, init, opts)
    if opts.refine:                             # solve, completion, scale (refine_run)
        step("factor-graph refinement")
        # without intrinsics the focal length and principal point are always variables of
        # the graph: about the 60 deg guess with a wide prior (estimated), or about the
        # user's field of view with that guess's own spread (--fov)
        refine_run(run, opts, iteration_progress, estimate_focal=intrinsics is None,
                   focal_rel_sigma=None if focal_estimated(opts) else
                   opts.graph.focal.guess_rel_sigma)
    elif opts.subject_height is not None:
        run.calibration.warnings.append(
            "subject_height needs the refinement (it scales the body); without it the "
            "distance stays unknown")
    calib = run.calibration                                                 # result
    rays = (median_ray_angle_deg(run.joints3d, run.valid3d, calib.normal,
                                 calib.distance if calib.distance is not None else 1.0)
            if opts.refine else float("nan"))
    est = init.estimate
    judge_mirror(calib, est.residuals[est.inliers],
                 motion_px(obs.paired, obs.joints, opts.min_confidence), init.check, rays)
    return run


@dataclass
class Observations:
    """A single mirror's observations, ready for the initialisation (:func:`observe`).

    Attributes:
        keypoints: the input as read (raw pixels).
        data: the same, undistorted with ``intrinsics``.
        paired: person and reflection paired, the reflection's labels in the person's.
        joints: ``(k,)`` the joints the run uses.
        intrinsics: the camera's (given, or the field-of-view guess).
        fps, fps_source: the frame rate of the 3D motion and where it came from.
        pairing: the pairing's options (threshold, confidence, seed).
        warnings: what reading them found worth saying.
        seconds: the pairing's wall time.
    """

    keypoints: RawDetections | PairedKeypoints
    data: RawDetections | PairedKeypoints
    paired: PairedKeypoints
    joints: np.ndarray
    intrinsics: Intrinsics
    fps: float
    fps_source: str
    pairing: PairingOptions
    warnings: list[str]
    seconds: float


def observe(keypoints: RawDetections | PairedKeypoints | str | os.PathLike,
            intrinsics: Intrinsics | None, opts: CalibrateOptions,
            step: Callable[[str], None] = lambda _name: None) -> Observations:
    """Read the keypoints, resolve the joints, frame rate and intrinsics, undistort, and
    pair person and reflection (:mod:`mirrorgraph.initial.pairing`): the observations of
    the rig of one camera and one mirror."""
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
    return Observations(keypoints, data, paired, joints, intr, fps, fps_source, pair_opts,
                        warnings, time.perf_counter() - clock)


@dataclass
class Initial:
    """A single mirror's initialisation (:func:`initialise`).

    Attributes:
        estimate: the robust estimator's mirror (:func:`mirrorgraph.initial.estimators.
            estimate_mirror`), over the pairs ``pairs``.
        valid: ``(T, J)`` the pairs offered (both seen above the confidence, run joints).
        pairs: ``(t_idx, j_idx)`` of the offered pairs, in ``estimate``'s order.
        inliers: ``(T, J)`` the pairs it kept.
        candidates: ``(T, J)`` the pairs handed to the graph (:data:`REFINE_GATE_FACTOR`).
        check: the verdict on the reflection
            (:func:`mirrorgraph.initial.reflection_check.check_reflection`).
        seconds: wall time.
    """

    estimate: object
    valid: np.ndarray
    pairs: tuple[np.ndarray, np.ndarray]
    inliers: np.ndarray
    candidates: np.ndarray
    check: object
    seconds: float


def initialise(obs: Observations, opts: CalibrateOptions,
               step: Callable[[str], None] = lambda _name: None,
               ransac_progress: Callable[[int, int], None] | None = None) -> Initial:
    """The first mirror from the pairs alone: the reflective RANSAC (or the estimator
    ``opts`` names) and the check that the reflection is no second person.

    Raises:
        DegenerateGeometryError: too few pairs, too few agreeing on one mirror, or a second
            person where the reflection should be.
    """
    paired = obs.paired
    valid = paired.valid(opts.min_confidence)
    valid[:, np.setdiff1d(np.arange(paired.skeleton.num_joints), obs.joints)] = False
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
        est = estimate_mirror(u, um, obs.intrinsics.K, estimator=opts.estimator,
                              threshold_px=opts.threshold_px, seed=opts.seed,
                              progress=ransac_progress)
    except DegenerateGeometryError as exc:
        raise DegenerateGeometryError(f"{paired.source}: {exc}") from None
    inliers = np.zeros_like(valid)
    inliers[t_idx[est.inliers], j_idx[est.inliers]] = True
    gate = est.residuals < REFINE_GATE_FACTOR * opts.threshold_px
    candidates = np.zeros_like(valid)
    candidates[t_idx[gate], j_idx[gate]] = True
    seconds = time.perf_counter() - clock
    if np.count_nonzero(inliers) < MIN_PAIRS:
        raise DegenerateGeometryError(
            f"{paired.source}: only {np.count_nonzero(inliers)} pairs agree on one mirror "
            f"within {opts.threshold_px:g} px: the reflection may be another person, or the "
            "threshold too tight")
    scores = frame_scores(obs.data, est.epipole, obs.joints, obs.pairing,
                          quantile=(0.5, GREY_QUANTILE))
    check = check_reflection(scores[0], opts.threshold_px, scores[1])
    if check.verdict == "second_person":
        raise DegenerateGeometryError(f"{paired.source}: {check.describe()}")
    return Initial(est, valid, (t_idx, j_idx), inliers, candidates, check, seconds)


def initial_run(obs: Observations, init: Initial, opts: CalibrateOptions) -> CalibrationRun:
    """The run's record after the initialisation: the :class:`Calibration` of the initial
    mirror (no scale yet) and what the later steps need."""
    paired, est, inliers, joints = obs.paired, init.estimate, init.inliers, obs.joints
    calib = Calibration(
        normal=est.normal, distance=None, scale="unknown", estimator=opts.estimator,
        intrinsics=obs.intrinsics, initial_normal=est.normal.copy(), refined=False,
        frames_read=paired.frames_read or len(paired),
        frames_paired=int(np.count_nonzero(init.valid.any(1))),
        frames_used=int(np.count_nonzero(inliers.any(1))), pairs_total=int(len(init.pairs[0])),
        pairs_used=int(np.count_nonzero(inliers)), lr_fixes=paired.lr_fixes,
        ransac_iterations=est.iterations,
        input={"source": paired.source, "format": paired.format,
               "skeleton": paired.skeleton.name,
               "joints": [paired.skeleton.joints[j] for j in joints],
               "min_confidence": opts.min_confidence, "threshold_px": opts.threshold_px,
               "seed": opts.seed, "fps": obs.fps, "fps_source": obs.fps_source,
               "subject_height": opts.subject_height, "scale_from": opts.graph.scale_from,
               "read_notes": obs.keypoints.read_notes.as_dict()},
        warnings=obs.warnings)
    calib.refinement = {"initial_epipolar_median_px": float(np.median(est.residuals[est.inliers]))}
    calib.input["reflection_check"] = init.check.to_dict()
    return CalibrationRun(calibration=calib, paired=paired, inliers=inliers, joints=joints,
                          candidates=init.candidates, fps=obs.fps, fps_source=obs.fps_source,
                          timings={"pairing": obs.seconds, "initialisation": init.seconds})


def refine_run(run: CalibrationRun, opts: CalibrateOptions,
               iteration_progress: Callable[[int, float], None] | None = None,
               estimate_focal: bool = False, focal_rel_sigma: float | None = None) -> None:
    """Solve, complete and scale ``run`` in place (the graph of :func:`.solve.refine_mirror`
    from its pairs; ``estimate_focal``: the intrinsics a guess, estimated)."""
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
        "scale_source": res.scale_source,
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
