"""The stages of the one solve driver (:func:`mirrorgraph.graph.solve.solve`), and what varies.

A :class:`SolveConfig` says what differs between rigs: the full-graph
:class:`Stage` s (kernel, scale, rejection after each), whether outliers are
rejected before the first solve, the warm start, the joints pass, chunking.
:func:`single_mirror_config` and :func:`rig_config` are the two in use.

Stages (each recorded in :attr:`SolveState.stages`):

1. **Triangulation** of every joint seen in two views or more with the initial rig
   (:func:`mirrorgraph.geometry.triangulate`, DLT then Gauss-Newton). An observation
   behind its (real or virtual) camera, or a joint behind a mirror it is seen in, is
   dropped (cheirality); a joint whose rays all meet at under
   ``options.min_parallax_deg`` (the angle of the rays' *lines*: rays pointing opposite
   ways, the usual mirror case, count too) is dropped; with
   ``config.first_rejection``, observations whose residual exceeds the outlier
   threshold and joints whose bones are all implausible are dropped too.
2. **Warm start** (``config.warm_start``, rigs whose camera poses are all held):
   Levenberg-Marquardt on the robust reprojection terms alone, on
   ``options.warm_start_frames`` frames spread over the video, the first mirror's
   distance held; then every joint is triangulated again with the warm rig and step
   1 repeated. Its joints must meet at ``options.warm_start_min_parallax_deg`` at
   least: without a body prior nothing else holds their depth.
2b. **Focal search** (``config.focal_search``, one held camera whose focal length is
   estimated, :attr:`~.rig.Camera.estimate_focal`): the focal length that makes the body
   most rigid among log-spaced candidates, each with its normals from the epipoles
   (:func:`focal_search`); then every joint triangulated again with it. The stages
   that follow estimate it with the rest (the bone lengths then a variable of the
   linear system, :mod:`.builder`), the last one always runs (its bones chosen at the
   estimated focal length), and an undamped step that overshoots is halved before the
   damping grows (:attr:`~.optimizer.LMParams.backtrack`).
3. **Gauge.** With a subject height everything is scaled so that the per-bone median
   lengths sum to Winter's lengths for that height (the gauge's value).
4. **Stages** of :attr:`SolveConfig.stages`: the full graph (every joint, every
   estimated pose and plane, the bone lengths, the body priors) with the stage's
   robust kernel, then the observations beyond the stage's threshold (and behind
   their camera) are dropped, with the joints left in fewer than two views and the
   joints GTSAM found undetermined, before the next stage (built from this one's
   solution). ``"auto"`` is least squares when the first rejection found under
   ``options.auto_kernel_fraction`` outliers, else Geman-McClure. A bone enters a
   frame's factor only where its length is measured without bias
   (``options.bone_bias_limit``, :func:`~.builder.bone_curvature_bias`).
5. **Joints pass** (``config.joints_pass``): the joints once more with every pose,
   plane and bone length held, the smoothness of ``options.joints_smoothness_sigma``
   and every bone in every frame; the bones the calibration left out entirely get
   the length their triangulations give without the curvature bias
   (:func:`~.builder.debiased_bone_lengths`).
6. **Marginals and noise.** The reduced information of the last undamped solve is the
   Schur complement of every joint on (poses, bone lengths, planes) that GTSAM's
   elimination leaves; its inverse (:func:`~.optimizer.reduced_covariance`) gives each
   estimated camera's ``6 x 6`` and each plane's ``3 x 3`` covariance, scaled by the noise the data show: every used joint
   triangulated again from its kept views with the solved rig (the maximum-likelihood
   point of the reprojection alone, free of the body priors that pull the graph's
   joints off it), ``sigma^2 = RSS / (2 observations - 3 joints)`` (for one mirror
   this is the pairs' Sampson distances to first order). An estimated camera's
   intrinsics get their ``(d, d)`` covariance the same way (the bone lengths among the
   eliminated globals), and a headline std that is the larger of it and the
   time-robust figure (:func:`~.uncertainty.frame_scores`,
   :func:`~.uncertainty.robust_intrinsics_std`).

"""

from __future__ import annotations

import time
from dataclasses import replace

import gtsam
import numpy as np

from ..errors import DegenerateGeometryError
from ..keypoints import MIN_PAIRS
from .builder import (GraphProblem, bone_table, build_problem, debiased_bone_lengths,
                      extract_camera_poses, extract_intrinsics, extract_planes, extract_points,
                      gauge_scale, snap_virtual_poses, with_motion_priors)
from .focal_search import focal_search, focal_searchable
from .marginals import covariances
from .noise import residual_noise
from .optimizer import LMResult
from .options import RefineOptions
from .outliers import bone_outliers, check_held, clean_views, observation_outliers
from .rig import (Rig, parallax_deg, seen_twice, spread_rows, triangulate_rig, with_intrinsics,
                  with_views)
from .solve_graph import Progress, information_at, optimize, undetermined
from .solve_state import SolveState
from .stage_config import SolveConfig
from .uncertainty import joint_scores, robust_intrinsics_std

__all__ = ["solve_rows", "joints_pass", "Counter", "stage_record", "THIN_BONE_FRAMES",
           "JOINTS_PASS_ITERATIONS"]



# --------------------------------------------------------------------------- pieces


class Counter:
    """Counts iterations over stages and chunks and forwards them to the user's callback.

    Each solve reports only accepted steps, so its errors never rise; a new stage or
    chunk is another objective and may start higher (the CLI's
    :class:`mirrorgraph.progress.SolveProgress` shows it as a new pass)."""

    def __init__(self, progress: Progress | None) -> None:
        self.progress, self.count = progress, 0

    def __call__(self, iteration: int, error: float) -> None:
        self.count += 1
        if self.progress is not None:
            self.progress(self.count, error)


def stage_record(name: str, res: LMResult, rejected: int, **extra) -> dict:
    """One entry of :attr:`SolveState.stages`."""
    return {"name": name, "iterations": res.iterations, "initial_error": res.initial_error,
            "final_error": res.final_error, "converged": res.converged, "rejected": rejected,
            "failed_steps": res.rejected_steps, "guarded": res.guarded,
            "undetermined": len(res.indeterminate), **extra}


# --------------------------------------------------------------------------- the stages
def solve_rows(rig: Rig, opts: RefineOptions, config: SolveConfig, height: float | None,
                counter: Counter) -> SolveState:
    timings = {"triangulate": 0.0, "build": 0.0, "solve": 0.0, "marginals": 0.0}
    t_start = time.perf_counter()
    stages: list[dict] = []
    if height is not None:
        opts = replace(opts, subject_height=float(height))
    poses = [np.asarray(c.pose, float).copy() for c in rig.cameras]
    planes = [(np.asarray(m.normal, float), float(m.distance)) for m in rig.mirrors]
    masks = [np.asarray(v.mask, bool) for v in rig.views]
    offered = [int(np.count_nonzero(m)) for m in masks]

    # 1. triangulate, cheirality, parallax, first rejection
    t = time.perf_counter()
    points, masks, rejected, found = clean_views(rig, masks, poses, planes, opts, config,
                                            opts.min_parallax_deg)
    timings["triangulate"] += time.perf_counter() - t

    # 2. warm start on spread frames, reprojection only, the first distance held
    if (config.warm_start and opts.warm_start_iterations > 0 and planes
            and not any(c.estimate_pose for c in rig.cameras)):
        t = time.perf_counter()
        rows = spread_rows(rig.num_frames, opts.warm_start_frames)
        used = seen_twice(masks) & rows[:, None]
        used &= parallax_deg(rig, points, masks, poses, planes) >= opts.warm_start_min_parallax_deg
        if np.count_nonzero(used) >= MIN_PAIRS:
            warm = build_problem(with_views(rig, masks), points, used, planes, opts, priors=False,
                                 hold_intrinsics=True)
            timings["build"] += time.perf_counter() - t
            t = time.perf_counter()
            res, _ = optimize(warm, warm.reprojection, opts,
                              distance_gauge=planes[0][1],
                              max_iterations=opts.warm_start_iterations, progress=counter)
            planes = extract_planes(warm, res.values)
            poses = extract_camera_poses(warm, res.values)
            # every joint again with the warm rig (the original masks: the first
            # rejection is judged anew against the better mirror)
            points, masks, rejected, found = clean_views(
                rig, [np.asarray(v.mask, bool) for v in rig.views], poses, planes, opts,
                config, opts.min_parallax_deg)
            stages.append(stage_record("warm start (reprojection only, %d frames)"
                                       % np.count_nonzero(used.any(1)), res, rejected))
        timings["solve"] += time.perf_counter() - t
    # 2b. the focal length's initial search (one camera held, its mirrors)
    if config.focal_search and focal_searchable(rig):
        t = time.perf_counter()
        rig, planes, record = focal_search(rig, masks, poses, planes, opts, config, height)
        points, masks, rejected, found = clean_views(
            rig, [np.asarray(v.mask, bool) for v in rig.views], poses, planes, opts, config,
            opts.min_parallax_deg)
        stages.append(record)
        timings["solve"] += time.perf_counter() - t
    check_held(rig, masks, offered)
    used = seen_twice(masks) & np.isfinite(points).all(-1)
    if np.count_nonzero(used) < MIN_PAIRS:
        raise DegenerateGeometryError(
            f"only {np.count_nonzero(used)} joints are seen in two views after the outliers "
            f"and the joints without depth were removed (need {MIN_PAIRS})")

    # 3. start on the gauge
    if height is not None:
        s = gauge_scale(rig, points, used, float(height))
        points = points * s
        planes = [(n, d * s) for n, d in planes]
        for p in poses:
            p[:3, 3] *= s

    # 4. the stages
    problem, values, res, z_keys = None, None, None, []
    lengths, body_height, length_sum = None, (None if height is None else float(height)), None
    dropped_last, n_undetermined, iterations = True, 0, sum(s["iterations"] for s in stages)
    focal = any(c.intrinsics_dim for c in rig.cameras)
    for stage in config.stages:
        if stage.only_if_rejected and not dropped_last and not focal:
            continue
        kernel = stage.kernel
        if kernel == "auto":
            kernel = ("geman_mcclure" if found > opts.auto_kernel_fraction * max(used.sum(), 1)
                      else None)
        if np.count_nonzero(used) < MIN_PAIRS:
            raise DegenerateGeometryError(
                f"only {int(np.count_nonzero(used))} joints left in two views after outlier "
                f"rejection (need {MIN_PAIRS})")
        t = time.perf_counter()
        stage_opts = replace(opts, final_kernel_scale_px=stage.kernel_scale_px)
        srig = with_views(rig, masks, poses, planes)
        problem = build_problem(srig, points, used, planes, stage_opts,
                                body_height=body_height, bone_lengths=lengths,
                                length_sum=length_sum, final_kernel=kernel)
        if height is not None:
            problem.body_height = float(height)
        snap_virtual_poses(problem, problem.values)
        timings["build"] += time.perf_counter() - t
        t = time.perf_counter()
        # the cap only saves time where the globals converge in a few steps; an estimated
        # focal length moves the whole reconstruction and needs the full count
        cap = (stage.cap_if_outliers if (res is None and found and not problem.calibration_keys)
               else None)
        res, z_keys = optimize(problem, problem.full(), stage_opts,
                               distance_gauge=problem.distance_gauge, max_iterations=cap,
                               progress=counter)
        iterations += res.iterations
        values = res.values
        points = extract_points(problem, values)
        planes = extract_planes(problem, values)
        poses = extract_camera_poses(problem, values)
        if problem.calibration_keys:      # every later triangulation and residual with the new K
            rig = with_intrinsics(rig, extract_intrinsics(problem, values))
        lengths = problem.bone_lengths()
        body_height = problem.body_height
        if problem.lengths is not None and height is None:
            length_sum = problem.prior_info["length_sum_gauge"]["sum"]
        lost = undetermined(problem, res)
        n_undetermined += int(np.count_nonzero(lost))
        used = problem.used & ~lost
        dropped = 0
        if stage.reject_px is not None:
            masks, dropped = observation_outliers(rig, points, used, masks, poses, planes, stage.reject_px)
            if stage.bone_outliers and opts.bone_outlier_k > 0:
                _, pairs = bone_table(rig)
                bad = bone_outliers(points, used, pairs, k=opts.bone_outlier_k)
                dropped += int(np.count_nonzero(bad))
                masks = [m & ~bad for m in masks]
            check_held(rig, masks, offered)
        dropped += int(np.count_nonzero(lost))
        used &= seen_twice(masks)
        rejected += dropped
        dropped_last = dropped > 0
        stages.append(stage_record(stage.name, res, dropped, kernel=kernel))
        timings["solve"] += time.perf_counter() - t
    final_error = float(res.final_error)
    if res.reduced_information is None and opts.marginals:
        # every solve of the last stage was damped (it met a nearly singular point):
        # the information at its solution, for the covariances
        res.reduced_information, res.reduced_gradient = information_at(problem, values, opts)
    final_used = problem.used.copy()
    state_points = extract_points(problem, values)
    intrinsics = extract_intrinsics(problem, values)
    if problem.calibration_keys:
        problem.rig = with_intrinsics(problem.rig, intrinsics)

    # every kept joint triangulated with the solved rig: the maximum-likelihood points of
    # the reprojection alone (free of the priors' pull), for the noise and the lengths
    t = time.perf_counter()
    final_masks = [np.asarray(v.mask, bool) & final_used for v in problem.rig.views]
    tri, tri_ok = triangulate_rig(problem.rig, final_masks, poses, planes)
    timings["triangulate"] += time.perf_counter() - t

    # the bones the calibration left out, or measured in too few frames to hold every
    # frame of the joints pass to: their length measured without the curvature bias
    lengths = problem.bone_lengths()
    names, pairs = bone_table(problem.rig)
    frames = (dict(zip(problem.bone_names, np.bincount(problem.bone_rows[:, 2].astype(np.int64),
                                                       minlength=len(problem.bone_names))))
              if problem.lengths is not None else {})
    other = [i for i, b in enumerate(names)
             if b not in lengths or frames.get(b, 0) < THIN_BONE_FRAMES]
    if other and opts.use_bone_length:
        est = debiased_bone_lengths(problem.rig, tri, tri_ok, planes, pairs[other],
                                    opts.pixel_sigma)
        lengths.update({names[i]: float(v) for i, v in zip(other, est) if np.isfinite(v)})

    # 5. joints pass: the joints with everything else held, tighter smoothness, every bone
    joints_priors = None
    if config.joints_pass:
        t = time.perf_counter()
        jp = joints_pass(problem, values, lengths, opts)
        if jp is not None:
            state_points = extract_points(jp[0], jp[1].values)
            joints_priors = {k: v for k, v in jp[0].prior_info.items()
                             if k in ("bone_length", "hip", "smoothness")}
            stages.append(stage_record("joints pass (globals held, smoothness %g h)"
                                       % opts.joints_smoothness_sigma, jp[1], 0))
            iterations += jp[1].iterations
        timings["solve"] += time.perf_counter() - t

    # 6. marginals, scaled by the noise the data show
    t = time.perf_counter()
    noise_px = residual_noise(problem.rig, final_masks, tri, tri_ok, poses, planes,
                              6 * len(problem.camera_keys) + 3 * len(planes)
                              + sum(problem.rig.cameras[c].intrinsics_dim
                                    for c in problem.calibration_keys))
    factor = (noise_px / opts.pixel_sigma) ** 2 if np.isfinite(noise_px) else 1.0
    cam_cov, plane_cov, basis, zv, intr_cov = covariances(problem, values,
                                                          res.reduced_information, z_keys,
                                                          opts.marginals)
    timings["marginals"] = time.perf_counter() - t
    t = time.perf_counter()
    scores = (joint_scores(problem, values, bias_pixel_sigma=noise_px
                           if np.isfinite(noise_px) else opts.pixel_sigma)
              if opts.marginals else None)
    intr_std = []
    if scores is not None and problem.calibration_keys:
        robust = robust_intrinsics_std(scores, {
            int(problem.calibration_keys[c][0]): intr_cov[c] * factor
            for c in problem.calibration_keys})
        intr_std = [robust[int(problem.calibration_keys[c][0])][0]
                    if c in problem.calibration_keys else np.zeros(0)
                    for c in range(len(problem.rig.cameras))]
    timings["uncertainty"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t_start
    info = dict(problem.prior_info)
    if joints_priors is not None:
        info["joints_pass"] = joints_priors
    if problem.distance_gauge is not None:
        info["distance_gauge"] = {"sigma": 1e-6, "weight": 1e12, "unit": "d", "factors": 1,
                                  "distance": problem.distance_gauge}
    return SolveState(poses=poses, planes=planes, points=state_points, used=final_used,
                      bone_lengths=lengths, scale=problem.scale,
                      camera_cov=[C * factor for C in cam_cov],
                      plane_cov=[C * factor for C in plane_cov], plane_basis=basis,
                      noise_px=noise_px, variance_factor=factor, view_masks=final_masks,
                      rejected=rejected, undetermined=n_undetermined, prior_info=info,
                      reprojection_factors=int(problem.reprojection.size()),
                      iterations=iterations, final_error=final_error, stages=stages,
                      timings=timings, body_height=problem.body_height,
                      information=res.reduced_information, z_keys=z_keys, z_values=zv,
                      problem=problem, scores=scores, intrinsics=intrinsics,
                      intrinsics_cov=[C * factor for C in intr_cov], intrinsics_std=intr_std)


#: A bone the calibration graph measured in fewer frames than this (its bone rule kept
#: it there in a few frames only) gets, for the joints pass, the length its
#: triangulations give in every frame without the curvature bias
#: (:func:`~.builder.debiased_bone_lengths`, whose own minimum this is): a length from
#: one frame held in every frame puts its error in all of them (a hip width measured
#: in one frame of 960 was 30 % long, issue #17).
THIN_BONE_FRAMES = 10


#: Gauss-Newton steps of the joints pass (:func:`joints_pass`): the points start at the
#: calibration's solution and the smoothness is linear in them, so one step lands
#: within ~1 mm of the converged joints (error 15156.7 vs 15155.9 converged on a
#: 1000-frame protocol scene).
JOINTS_PASS_ITERATIONS = 1


def joints_pass(problem: GraphProblem, values: gtsam.Values, lengths: dict[str, float],
                opts: RefineOptions) -> tuple[GraphProblem, LMResult] | None:
    """The 3D joints solved again with every global held, from the calibration's solution.

    The calibration's variables and reprojection factors with other body priors
    (:func:`~.builder.with_motion_priors`): the smoothness of
    ``opts.joints_smoothness_sigma`` (tight: it halves the joints' error, where the
    calibration wants none, see :class:`RefineOptions`), and every bone of ``lengths``
    in every frame, the frames that ``opts.bone_bias_limit`` left out of the
    calibration included (the mirror held, a bone's known length is what fixes the
    depth of joints whose rays meet at a small angle).

    Args:
        problem, values: the calibration's graph and its solution.
        lengths: bone name -> length (graph units), held.

    Returns:
        The joints' graph and its solve; ``None`` without ``joints_smoothness_sigma``.
    """
    sigma = opts.joints_smoothness_sigma
    if sigma is None:
        return None
    jopts = replace(opts, use_smoothness=True, smoothness_sigma=sigma)
    jp = with_motion_priors(problem, values, lengths, jopts)
    res, _ = optimize(jp, jp.full(), jopts, distance_gauge=jp.distance_gauge,
                      max_iterations=JOINTS_PASS_ITERATIONS,
                      hold_globals=True)
    return jp, res


