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
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..result.mirror import Calibration
from ..anthropometry import height_from_bone_lengths
from ..completion import complete_mirror_joints
from ..errors import DegenerateGeometryError, InputError
from ..initial.estimators import estimate_mirror
from .judge import judge_mirror, low_parallax_warning, median_ray_angle_deg, motion_px
from .options import CalibrateOptions
from ..initial.reflection_check import GREY_QUANTILE, check_reflection
from .lines import (disagreement_warning, focal_sources, fuse_gaussians, lines_witness,
                    searched_near, video_of)
from .solve import refine_mirror
from ..graph.sensitivity import prior_weights
from ..graph.uncertainty import region_rotation_deg
from ..intrinsics import Intrinsics, estimated_intrinsics, intrinsics_from_fov
from ..io import read_keypoints
from ..joint_sets import mirror_joints
from ..keypoints import MIN_PAIRS, PairedKeypoints, RawDetections
from ..initial.body_left_right import undo_body_swaps
from ..initial.clip_left_right import clip_left_right
from ..initial.left_right import fix_left_right
from ..initial.pair_candidates import PairingOptions
from ..initial.pair_scores import frame_scores
from ..initial.pairing import pair_detections
from ..preprocess import check_image_size, resolve_fps, undistort_keypoints
from ..geometry import triangulate_mirror
from ..graph.joints_uncertainty import (mirror_plane_projections, position_std,
                                       triangulated_covariance, with_disagreement, with_scale)

if TYPE_CHECKING:
    from ..initial.vanishing import LinesFocal



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
            ``build``, ``solve``, ``marginals``, ``uncertainty``; ``lines`` and
            ``solve_person``: the scene's lines and the person-alone solve before the
            fused one, where the focal length is estimated on a video); kept out of the JSON
            so that the same input gives byte-identical output.
        refine_parts: the refinement's uncertainty figures with their covariances
            (:func:`mirrorgraph.graph.uncertainty.robust_normal_cov`); the JSON holds
            their standard deviations (``uncertainty.robust``).
        joints_std: ``(T, J)`` each joint's own uncertainty, the RMS length of its 3D
            error ``sqrt(trace(joints_cov))`` (the unit of :attr:`joints3d`): the graph's
            joints from the graph's information with the mirror's and the metric
            scale's uncertainty, the completed ones from their two rays
            (:mod:`mirrorgraph.graph.joints_uncertainty`); NaN where
            :attr:`joints3d` is; ``None`` without refinement or marginals.
        joints_cov: ``(T, J, 3, 3)`` the covariances behind :attr:`joints_std`.
        joints_std_shape: ``(T, J)`` :attr:`joints_std` without the metric scale's
            share (one factor on every length, ``relative std x |X|``): the body's shape
            and its place at the calibration's scale.
        scale_rel_std: that share: the metric scale's relative std (the subject's height
            as given, ``height_sigma``, and the stature's own spread), one draw for the
            whole run: ``joints_std^2 = joints_std_shape^2 + (scale_rel_std |X|)^2``;
            ``None`` with :attr:`joints_std` ``None``, 0 without a subject height.
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
    joints_std: np.ndarray | None = None
    joints_cov: np.ndarray | None = None
    joints_std_shape: np.ndarray | None = None
    scale_rel_std: float | None = None

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
        lines = None
        if intrinsics is None and focal_estimated(opts):     # the scene's lines, a witness
            if opts.graph.focal.lines:
                step("the scene's straight lines")
            clock = time.perf_counter()
            lines = lines_witness(video_of(keypoints, opts.video),
                                  getattr(obs.keypoints, "people", None),
                                  obs.intrinsics.image_size, opts.graph.focal, seed=opts.seed)
            run.timings["lines"] = time.perf_counter() - clock
        try:
            refine_run(run, opts, iteration_progress, estimate_focal=intrinsics is None,
                       focal_rel_sigma=None if focal_estimated(opts) else
                       opts.graph.focal.guess_rel_sigma, lines=lines)
        except DegenerateGeometryError as exc:    # the graph's refusal names the input
            source = str(run.paired.source)
            if str(exc).startswith(source):
                raise
            raise DegenerateGeometryError(f"{source}: {exc}") from None
    elif opts.subject_height is not None:
        run.calibration.warnings.append(
            "subject_height needs the refinement (it scales the body); without it the "
            "distance stays unknown")
    judge_run(run, obs, init, opts)                                         # result
    return run


def judge_run(run: CalibrationRun, obs: Observations, init: Initial,
              opts: CalibrateOptions) -> None:
    """Every warning about the run's calibration (:func:`.judge.judge_mirror`): its rays'
    angle, the initialisation's residuals, the motion, the reflection check; and about its
    joints where their rays meet at small angles (:func:`.judge.low_parallax_warning`)."""
    calib = run.calibration
    rays = (median_ray_angle_deg(run.joints3d, run.valid3d, calib.normal,
                                 calib.distance if calib.distance is not None else 1.0)
            if opts.refine else float("nan"))
    est = init.estimate
    judge_mirror(calib, est.residuals[est.inliers],
                 motion_px(obs.paired, obs.joints, opts.min_confidence), init.check, rays)
    warning = low_parallax_warning(rays, run.scale_rel_std)
    if warning:
        calib.warnings.append(warning)


@dataclass
class Prepared:
    """A single camera's input before the pairing (:func:`prepare`).

    Attributes:
        keypoints: the input as read (raw pixels); data: the same, undistorted.
        joints: ``(k,)`` the joints the run uses.
        intrinsics: the camera's (given, or the field-of-view guess).
        fps, fps_source: the frame rate of the 3D motion and where it came from.
        pairing: the pairing's options (threshold, confidence, seed).
        warnings: what reading them found worth saying.
    """

    keypoints: RawDetections | PairedKeypoints
    data: RawDetections | PairedKeypoints
    joints: np.ndarray
    intrinsics: Intrinsics
    fps: float
    fps_source: str
    pairing: PairingOptions
    warnings: list[str]


@dataclass
class Observations(Prepared):
    """A single mirror's observations, ready for the initialisation (:func:`observe`): the
    :class:`Prepared` input, paired.

    Attributes (besides :class:`Prepared`'s):
        paired: person and reflection paired, the reflection's labels in the person's.
        seconds: the pairing's wall time.
        body_lr_fixes: (frame, left/right pair, view) entries whose labels the detector
            swapped, swapped back (:mod:`mirrorgraph.initial.body_left_right`).
    """

    paired: PairedKeypoints
    seconds: float
    body_lr_fixes: int = 0

    @classmethod
    def of(cls, prepared: Prepared, paired: PairedKeypoints, seconds: float,
           body_lr_fixes: int = 0, **changes) -> "Observations":
        """``prepared`` once paired; ``changes``: fields of ``prepared`` replaced."""
        base = {f.name: getattr(prepared, f.name) for f in fields(Prepared)}
        return cls(**{**base, **changes}, paired=paired, seconds=seconds,
                   body_lr_fixes=body_lr_fixes)


def prepare(keypoints: RawDetections | PairedKeypoints | str | os.PathLike,
            intrinsics: Intrinsics | None, opts: CalibrateOptions,
            step: Callable[[str], None] = lambda _name: None) -> Prepared:
    """Read the keypoints, resolve the joints, frame rate and intrinsics, and undistort:
    what the pairing of one person (:func:`observe`) and of every person
    (:func:`mirrorgraph.pipelines.people.calibrate_people`) start from."""
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
    return Prepared(keypoints, data, joints, intr, fps, fps_source, pair_opts, warnings)


def observe(keypoints: RawDetections | PairedKeypoints | str | os.PathLike,
            intrinsics: Intrinsics | None, opts: CalibrateOptions,
            step: Callable[[str], None] = lambda _name: None) -> Observations:
    """Read the keypoints, resolve the joints, frame rate and intrinsics, undistort
    (:func:`prepare`), pair person and reflection (:mod:`mirrorgraph.initial.pairing`),
    decide their left/right labels over the clip (``opts.left_right``,
    :mod:`mirrorgraph.initial.clip_left_right`) and undo the detector's confusions of
    single pairs (:mod:`mirrorgraph.initial.body_left_right`): the observations of the
    rig of one camera and one mirror."""
    p = prepare(keypoints, intrinsics, opts, step)
    step("pairing person and reflection")
    clock = time.perf_counter()
    if isinstance(p.data, PairedKeypoints):
        paired = fix_left_right(p.data, p.joints, p.pairing)
    else:
        paired = pair_detections(p.data, p.joints, p.pairing)
    if opts.left_right == "clip":
        paired, _ = clip_left_right(paired, p.intrinsics.K, p.joints, p.pairing)
    paired, body_swaps = undo_body_swaps(paired, opts.min_confidence)
    return Observations.of(p, paired, time.perf_counter() - clock, body_swaps)


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
               "keypoint_offset": opts.graph.keypoint_offset,
               "height_sigma": opts.graph.height_sigma,
               "read_notes": obs.keypoints.read_notes.as_dict(),
               "body_lr_fixes": obs.body_lr_fixes},
        warnings=obs.warnings)
    calib.refinement = {"initial_epipolar_median_px": float(np.median(est.residuals[est.inliers]))}
    calib.input["reflection_check"] = init.check.to_dict()
    return CalibrationRun(calibration=calib, paired=paired, inliers=inliers, joints=joints,
                          candidates=init.candidates, fps=obs.fps, fps_source=obs.fps_source,
                          timings={"pairing": obs.seconds, "initialisation": init.seconds})


def refine_run(run: CalibrationRun, opts: CalibrateOptions,
               iteration_progress: Callable[[int, float], None] | None = None,
               estimate_focal: bool = False, focal_rel_sigma: float | None = None,
               lines: LinesFocal | None = None) -> None:
    """Solve, complete and scale ``run`` in place (the graph of :func:`.solve.refine_mirror`
    from its pairs; ``estimate_focal``: the intrinsics a guess, estimated). ``lines``: the
    scene's witness of the focal length (:mod:`.lines`): where it has an estimate the graph
    is solved a second time with it joined to the guess's prior, and both cues are
    recorded apart (``intrinsics.estimated.focal_sources``). The graph's acceleration
    priors are taken at the run's frame rate (``run.fps``,
    :meth:`~mirrorgraph.graph.options.PriorOptions.at_frame_rate`): here, once, for the
    solves, the sensitivity's and the completion's smoothing."""
    ropts = opts.graph.at_frame_rate(run.fps)
    calib = run.calibration
    pairs = run.candidates if run.candidates is not None else run.inliers
    guess = calib.intrinsics
    start_K, start_rel, near = guess.K, focal_rel_sigma, None
    res = refine_mirror(run.paired, start_K, calib.normal, pairs,
                        joints=run.joints, options=ropts, progress=iteration_progress,
                        estimate_focal=estimate_focal, focal_rel_sigma=start_rel)
    sources = None
    if estimate_focal and lines is not None:
        person = dict(res.focal)
        fused = None
        if lines.usable:
            f0 = float(guess.K[0, 0])
            rel0 = ropts.focal.prior_rel_sigma if focal_rel_sigma is None else focal_rel_sigma
            f, std = fuse_gaussians((f0, rel0 * f0), (lines.focal_px, lines.std_px))
            start_K = np.array(guess.K, dtype=float)
            start_K[0, 0] = start_K[1, 1] = f
            start_rel, near = std / f, (f, std)
            run.timings["solve_person"] = float(res.timings.get("solve", 0.0))
            res = refine_mirror(run.paired, start_K, calib.normal, pairs,
                                joints=run.joints, options=searched_near(ropts, f, std, start_K),
                                progress=iteration_progress, estimate_focal=True,
                                focal_rel_sigma=start_rel)
            fused = res.focal
        sources = focal_sources(person, lines, fused)
    if estimate_focal:
        calib.intrinsics = estimated_intrinsics(guess, res.intrinsics, res.focal,
                                                opts.fov_deg, calib.warnings,
                                                user_guess=focal_rel_sigma is not None)
    if sources is not None:
        calib.intrinsics.estimated["focal_sources"] = sources
        if sources["fused"]["with_lines"]:
            calib.intrinsics.source = calib.intrinsics.source.replace(
                "from the person and the reflection",
                "from the person and the reflection with the scene's straight lines")
        warning = disagreement_warning(sources)
        if warning:
            calib.warnings.append(warning)
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
            o = o if near is None else searched_near(o, near[0], near[1], start_K)
            return refine_mirror(run.paired, start_K, calib.initial_normal, pairs,
                                 joints=run.joints, options=o, estimate_focal=estimate_focal,
                                 focal_rel_sigma=start_rel)
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
    cov = res.joints_cov
    noise = (res.priors.get("reprojection") or {}).get("a_posteriori_sigma_px")
    noise = float(noise) if noise is not None and np.isfinite(noise) else ropts.pixel_sigma
    if cov is not None:
        cov = _with_own_rays(run, calib, res, cov, noise, opts.min_confidence)
    if opts.complete_joints:
        clock = time.perf_counter()
        done = complete_mirror_joints(run.paired, calib.intrinsics.K, calib.normal,
                                      float(res.distance), res.joints3d, res.valid,
                                      joints=run.joints, min_confidence=opts.min_confidence,
                                      threshold_px=opts.threshold_px,
                                      pixel_sigma=noise,
                                      plane_cov=res.plane_cov,
                                      body_gauge=res.scale == "subject_height",
                                      smoothness=_completion_smoothness(run, res, ropts),
                                      head=(list(run.paired.skeleton.joints),
                                            height_from_bone_lengths(res.bone_lengths,
                                                                     run.paired.skeleton),
                                            cov))
        run.joints3d, run.valid3d, run.completed = done.joints3d, done.valid, done.completed
        if cov is not None and done.cov is not None:
            cov = np.where(done.completed[..., None, None], done.cov, cov)
        calib.refinement["completion"] = done.to_dict()
        run.timings["completion"] = time.perf_counter() - clock
    if cov is not None:
        cov = np.where(run.valid3d[..., None, None], cov, np.nan)
        run.joints_std_shape = position_std(cov)
        run.scale_rel_std = float(res.scale_rel_std)
        cov = with_scale(cov, np.nan_to_num(run.joints3d), res.scale_rel_std)
        run.joints_cov, run.joints_std = cov, position_std(cov)


def _completion_smoothness(run: CalibrationRun, res, ropts) -> tuple[float, int] | None:
    """``(sigma, max_gap)`` of the completed joints' smoothing: the joints pass's
    (``joints_smoothness_sigma`` of the body's height its bone lengths make,
    :func:`mirrorgraph.anthropometry.height_from_bone_lengths`; ``ropts`` at the run's
    frame rate, so per frame^2 of the video, and ``max_gap`` in frames)."""
    if ropts.joints_smoothness_sigma is None:
        return None
    h = height_from_bone_lengths(res.bone_lengths, run.paired.skeleton)
    if not np.isfinite(h):
        return None
    return float(ropts.joints_smoothness_sigma * h), int(ropts.smoothness_max_gap)


def _with_own_rays(run: CalibrationRun, calib: Calibration, res, cov: np.ndarray,
                   noise: float, min_confidence: float) -> np.ndarray:
    """The graph's joints' covariances widened where their own two observations disagree
    with them (:func:`mirrorgraph.graph.joints_uncertainty.with_disagreement`)."""
    P = run.paired
    seen = (res.valid & (P.real[..., 2] >= min_confidence) & (P.mirror[..., 2] >= min_confidence)
            & np.isfinite(P.real[..., :2]).all(-1) & np.isfinite(P.mirror[..., :2]).all(-1))
    if not seen.any():
        return cov
    t, j = np.nonzero(seen)
    K = calib.intrinsics.K
    u, um = P.real[t, j, :2], P.mirror[t, j, :2]
    Xr = triangulate_mirror(K, calib.normal, float(res.distance), u, um)
    Cr = triangulated_covariance(mirror_plane_projections(K, calib.normal, float(res.distance)),
                                 None, Xr, [u, um], [np.ones(len(t), bool)] * 2, noise)
    out = np.array(cov, dtype=float, copy=True)
    out[t, j], _ = with_disagreement(cov[t, j], res.joints3d[t, j], Xr, Cr)
    return out


#: The refinement gets every pair within this many RANSAC thresholds of the initial
#: mirror, not only the RANSAC inliers: an inlier set chosen against the initial
#: estimate truncates the noise about *that* estimate and pulls the refinement back
#: to it (measured on the paper's protocol, 12 seeds: RMS error / Cramer-Rao bound
#: 1.41 with the inliers, 1.10 with every pair). The gate only keeps gross outliers
#: (tens of pixels off their epipolar line) out of the first solve; the graph's
#: robust kernel and its own rejection (:mod:`mirrorgraph.graph.outliers`) do the rest.
REFINE_GATE_FACTOR = 3.0
