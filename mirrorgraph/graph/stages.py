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
from typing import Callable

import gtsam
import numpy as np

from ..anthropometry import expected_bone_lengths
from ..errors import DegenerateGeometryError
from ..keypoints import MIN_PAIRS
from .builder import (GraphProblem, bone_table, build_problem, cheirality_guard,
                      debiased_bone_lengths, extract_camera_poses, extract_intrinsics,
                      extract_planes, extract_points, point_keys, snap_virtual_poses,
                      with_motion_priors)
from .rig import (Rig, parallax_deg, seen_twice, spread_rows, triangulate_rig, view_residuals,
                  with_intrinsics, with_views)
from .lengths import update_lengths
from .optimizer import LevenbergMarquardt, LMParams, LMResult, reduced_covariance
from .options import RefineOptions
from .outliers import bone_outliers, observation_outliers
from .reduction import mirror_reduction
from .result import residual_noise_px
from .uncertainty import joint_scores, robust_intrinsics_std
from .stage_config import SolveConfig
from .solve_state import SolveState

__all__ = ["MIN_PAIRS", "lm_params", "solve_rows", "Counter"]


Progress = Callable[[int, float], None]


# --------------------------------------------------------------------------- pieces
#: Halvings of an undamped step that overshoots where intrinsics are estimated
#: (:attr:`~.optimizer.LMParams.backtrack`).
FOCAL_BACKTRACK = 4


def lm_params(opts: RefineOptions, problem: GraphProblem,
              max_iterations: int | None = None) -> LMParams:
    """:class:`LMParams` from the options; the points' damping scale is the typical
    information of a point seen in two views, ``2 (f / Z)^2 / sigma^2`` (graph units)."""
    K = problem.rig.cameras[0].K
    depth = problem.median_depth
    scale = 2.0 * (K[0, 0] / max(depth, 1e-9)) ** 2 / opts.pixel_sigma ** 2
    return LMParams(max_iterations=opts.max_iterations if max_iterations is None
                    else max_iterations, relative_tolerance=opts.relative_tolerance,
                    global_step_tolerance=opts.global_step_tolerance, local_scale=scale,
                    backtrack=FOCAL_BACKTRACK if problem.calibration_keys else 0)


def optimize(problem: GraphProblem, graph: gtsam.NonlinearFactorGraph, opts: RefineOptions,
             *, distance_gauge: float | None, max_iterations=None,
             hold_globals: bool = False, progress: Progress | None = None,
             values: gtsam.Values | None = None) -> tuple[LMResult, list[tuple[int, int]]]:
    """Levenberg-Marquardt on ``graph`` from ``values`` (default: the problem's initial
    values) with the links exact, the cheirality guard on. Where the problem has bone
    factors and the globals move, the bone lengths are set to their optimum after
    every accepted step (:func:`~.lengths.update_lengths`; ``problem`` holds the last
    ones, and ``graph`` must be its :meth:`~.builder.GraphProblem.full` graph)."""
    red = mirror_reduction(problem, distance_gauge=distance_gauge)
    refresh = None
    if problem.lengths is not None and not hold_globals and problem.length_key is None:
        current = [graph]

        def refresh(v: gtsam.Values) -> gtsam.NonlinearFactorGraph:
            # the bone factors are made again only when a length moved by more than
            # the tolerance of the globals' steps, in its own standard deviations
            L, std = update_lengths(problem, v)
            if np.any(np.abs(L - problem.lengths) > opts.global_step_tolerance * std):
                problem.set_lengths(L)
                current[0] = problem.full()
            return current[0]
    lm = LevenbergMarquardt(graph, red, lm_params(opts, problem, max_iterations),
                            ordering=problem.point_ordering(), hold_globals=hold_globals,
                            guard=cheirality_guard(problem), refresh=refresh)
    res = lm.optimize(problem.values if values is None else values, progress)
    if problem.length_key is not None:       # the lengths are a variable: read them back
        problem.lengths = np.asarray(res.values.atVector(problem.length_key), dtype=float)
    return res, red.z_keys


def information_at(problem: GraphProblem, values: gtsam.Values, opts: RefineOptions
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The reduced information and gradient of ``problem``'s full graph at ``values``
    (:meth:`~.optimizer.LevenbergMarquardt.reduced_system`)."""
    red = mirror_reduction(problem, distance_gauge=problem.distance_gauge)
    lm = LevenbergMarquardt(problem.full(), red, lm_params(opts, problem),
                            ordering=problem.point_ordering())
    return lm.reduced_system(values)


def undetermined(problem: GraphProblem, res: LMResult) -> np.ndarray:
    """``(T, J)`` bool: the points GTSAM found (nearly) undetermined during ``res``
    (:attr:`~.optimizer.LMResult.indeterminate`); they are dropped with their pairs."""
    T, J = problem.used.shape
    out = np.zeros(T * J, dtype=bool)
    flat = np.array(sorted(res.indeterminate), dtype=np.uint64) - np.uint64(point_keys([0])[0])
    flat = flat[flat < T * J].astype(np.int64)
    out[flat] = True
    return out.reshape(T, J) & problem.used


def gauge_scale(rig: Rig, points: np.ndarray, used: np.ndarray, height: float) -> float:
    """Factor that makes the per-bone median lengths sum to Winter's lengths for ``height``."""
    names, pairs = bone_table(rig)
    expected = expected_bone_lengths(rig.skeleton, height)
    total, want = 0.0, 0.0
    for name, (a, b) in zip(names, pairs):
        ok = used[:, a] & used[:, b]
        if ok.any():
            total += float(np.median(np.linalg.norm(points[ok, a] - points[ok, b], axis=1)))
            want += expected[name]
    return want / total if total > 0 else 1.0


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


# --------------------------------------------------------------------------- focal search
def focal_searchable(rig: Rig) -> bool:
    """A rig whose focal length the search (:func:`focal_search`) can start: one held camera
    whose focal length is estimated, seen through its mirrors."""
    return (len(rig.cameras) == 1 and rig.cameras[0].estimate_focal
            and not rig.cameras[0].estimate_pose and len(rig.mirrors) > 0)


def focal_candidates(K: np.ndarray, opts: RefineOptions) -> np.ndarray:
    """``(S,)`` candidate focal lengths, px: log-spaced over the horizontal fields of view of
    ``opts.focal.search_fov_deg`` for an image ``2 cx`` wide."""
    lo, hi = opts.focal.search_fov_deg
    width = 2.0 * float(K[0, 2])
    fov = np.radians(np.geomspace(float(hi), float(lo), int(opts.focal.search_steps)))
    return 0.5 * width / np.tan(0.5 * fov)


def focal_search(rig: Rig, masks: list[np.ndarray], poses: list[np.ndarray],
                 planes: list[tuple[np.ndarray, float]], opts: RefineOptions,
                 config: SolveConfig, height: float | None
                 ) -> tuple[Rig, list[tuple[np.ndarray, float]], dict]:
    """The focal length that makes the body most rigid, among candidates: the start of
    the graph's own estimate.

    For a camera at the origin the epipole ``e ~ K n`` of each mirror is what the
    images fix; a candidate focal length ``f`` gives the normal ``n ~ K_f^-1 e`` (the
    distance is a gauge). Each candidate's graph (every joint of
    ``opts.focal.search_frames`` frames spread over the video, every bone in every
    frame: one set of factors for all, so that their errors compare; the focal length
    held) is solved for a few iterations, and the errors are the profile of the
    objective over ``f`` (among the candidates that keep nearly all the observations, so
    that the errors compare); a parabola in ``log f`` through the best and its neighbours
    gives the start. With every bone the profile's minimum is biased where the bones
    are measured with a curvature bias; the graph's estimate that follows keeps
    the bones of ``opts.focal.bone_bias_limit``.

    Args:
        rig: one camera (held) with ``estimate_focal``, its mirrors, views; its ``K`` is
            the initial guess (the principal point stays).
        masks: per view the observations to use; poses, planes: the current rig.
        opts, config: the solve's options and configuration.
        height: the subject's height (the gauge), or ``None``.

    Returns:
        The rig with the chosen ``K``, the planes turned to it, and the stage's record
        (``{"name", "candidates_px", "errors", "focal_px", ...}``).
    """
    K0 = np.asarray(rig.cameras[0].K, dtype=float)
    epipoles = [K0 @ np.asarray(n, float) for n, _ in planes]
    rows = spread_rows(rig.num_frames, opts.focal.search_frames)
    sub = rig.subset(rows)
    sub_masks = [np.asarray(m, bool)[rows] for m in masks]
    sopts = replace(opts, bone_bias_limit=None, focal=replace(opts.focal, bone_bias_limit=None),
                    use_bone_length=True)

    def profile(f: float) -> tuple[float, int]:
        K = K0.copy()
        K[0, 0] = K[1, 1] = f
        frig = with_intrinsics(sub, [K])
        fplanes = [(_normal_from_epipole(K, e, n), d) for e, (n, d) in zip(epipoles, planes)]
        pts, fm, _, _ = clean_views(frig, sub_masks, poses, fplanes, sopts, config,
                                    opts.warm_start_min_parallax_deg)
        used = seen_twice(fm) & np.isfinite(pts).all(-1)
        kept = int(sum(np.count_nonzero(np.asarray(m, bool) & used) for m in fm))
        if np.count_nonzero(used) < MIN_PAIRS:
            return np.inf, kept
        fposes = [np.asarray(p, float).copy() for p in poses]
        if height is not None:
            scale = gauge_scale(frig, pts, used, float(height))
            pts, fplanes = pts * scale, [(n, d * scale) for n, d in fplanes]
            for p in fposes:
                p[:3, 3] *= scale
        problem = build_problem(with_views(frig, fm, fposes, fplanes), pts, used, fplanes,
                                sopts, body_height=height, hold_intrinsics=True,
                                final_kernel=None)
        snap_virtual_poses(problem, problem.values)
        try:
            res, _ = optimize(problem, problem.full(), sopts,
                              distance_gauge=problem.distance_gauge,
                              max_iterations=FOCAL_SEARCH_ITERATIONS)
        except DegenerateGeometryError:
            return np.inf, kept
        return float(res.final_error), kept

    fs = focal_candidates(K0, opts)
    runs = [profile(f) for f in fs]
    # the errors compare only on the same data: a candidate whose cleaning rejected more
    # than FOCAL_SEARCH_MIN_KEPT of the observations the best-kept one has is out (a
    # wrong focal length that rejects two thirds of the pairs must not win by the error
    # it no longer counts)
    kept = np.array([k for _, k in runs], dtype=float)
    errors = np.array([e for e, _ in runs])
    errors[kept < FOCAL_SEARCH_MIN_KEPT * kept.max()] = np.inf
    best = int(np.argmin(errors))
    f = float(fs[best])
    if 0 < best < len(fs) - 1 and np.all(np.isfinite(errors[best - 1:best + 2])):
        x = np.log(fs[best - 1:best + 2])
        a, b, _ = np.polyfit(x, errors[best - 1:best + 2], 2)
        if a > 0:
            f = float(np.exp(np.clip(-b / (2 * a), x[0], x[2])))
    K = K0.copy()
    K[0, 0] = K[1, 1] = f
    new_planes = [(_normal_from_epipole(K, e, n), d) for e, (n, d) in zip(epipoles, planes)]
    record = {"name": "focal search (%d candidates, %d frames, focal held)"
              % (len(fs), int(np.count_nonzero(rows))),
              "iterations": 0, "initial_error": float("nan"),
              "final_error": float(errors[best]), "converged": True, "rejected": 0,
              "failed_steps": 0, "guarded": 0, "undetermined": 0,
              "candidates_px": [float(x) for x in fs],
              "errors": [float(x) for x in errors], "kept": [int(k) for k in kept],
              "focal_px": f,
              "initial_focal_px": float(K0[0, 0])}
    return with_intrinsics(rig, [K]), new_planes, record


#: Iterations of each candidate's solve in :func:`focal_search`.
FOCAL_SEARCH_ITERATIONS = 3

#: A candidate of :func:`focal_search` whose cleaning kept fewer than this fraction of the
#: observations the best-kept candidate kept is not compared.
FOCAL_SEARCH_MIN_KEPT = 0.9


def _normal_from_epipole(K: np.ndarray, e: np.ndarray, like: np.ndarray) -> np.ndarray:
    """Unit ``K^-1 e`` (3,), the sign of ``like`` (the normal it replaces)."""
    n = np.linalg.solve(K, np.asarray(e, float))
    n /= np.linalg.norm(n)
    return n if n @ np.asarray(like, float) >= 0 else -n


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
    _check_held(rig, masks, offered)
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
            _check_held(rig, masks, offered)
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


def floor_focal(state: SolveState, undetermined: set[int] = frozenset()) -> None:
    """Variance floors of the estimated focal lengths, in every robust figure.

    Two estimates of one focal length from the same data, the initial search's (every
    bone in every frame) and the graph's (the bones whose curvature bias is small),
    differ by what the bones' choice does to it; where that exceeds the graph's std the
    std is no measure of the error (rays meeting at 16 deg: the search 2699 px, the
    graph 1365 px at a std of 4 %, the truth 2186 px), and the difference squared is
    the floor of its variance. A camera in ``undetermined`` gets its prior's variance, and
    so does a principal point held at the centre
    (:data:`~.builder.PRINCIPAL_POINT_HOLD`: its uncertainty is the population's).
    Sets the scores' :attr:`~.uncertainty.JointScores.prior_floor` and recomputes the
    cameras' robust intrinsics stds with it.
    """
    sc, problem = state.scores, state.problem
    if sc is None or problem is None or sc.prior_spread is None:
        return
    search = [s.get("focal_px") for s in state.stages if s.get("focal_px") is not None]
    floor = (np.zeros(sc.scores.shape[1]) if sc.prior_floor is None
             else np.asarray(sc.prior_floor, float).copy())
    off = 0
    keys = {int(pair[0]): c for c, pair in problem.calibration_keys.items()}
    for key, dim in sc.z_keys:
        c = keys.get(int(key))
        if c is not None:
            if dim == 3 and problem.rig.cameras[c].principal_point_prior is not None:
                floor[off + 1:off + 3] = np.inf       # held at the centre: the prior's spread
            f = float(np.asarray(state.intrinsics[c])[0, 0])
            if c in undetermined:
                floor[off] = np.inf                        # the prior's (capped there)
            elif search and len(problem.calibration_keys) == 1:
                floor[off] = max(floor[off], (float(search[-1]) - f) ** 2)
        off += dim
    sc.prior_floor = floor
    marginal = {int(problem.calibration_keys[c][0]): state.intrinsics_cov[c]
                for c in problem.calibration_keys}
    robust = robust_intrinsics_std(sc, marginal)
    state.intrinsics_std = [robust[int(problem.calibration_keys[c][0])][0]
                            if c in problem.calibration_keys else np.zeros(0)
                            for c in range(len(state.intrinsics))]


def clean_views(rig: Rig, masks: list[np.ndarray], poses, planes, opts: RefineOptions,
           config: SolveConfig, min_parallax: float):
    """Triangulate; drop observations behind their camera, joints without parallax and,
    with ``config.first_rejection``, outliers. Returns points, masks, the count dropped
    and the count of outliers found (for the ``"auto"`` kernel)."""
    offered = masks
    points, ok = triangulate_rig(rig, masks, poses, planes)
    masks, behind = observation_outliers(rig, points, seen_twice(masks), masks, poses, planes, np.inf)
    if behind:           # again, only the joints that lost an observation
        changed = np.any([a & ~b for a, b in zip(offered, masks)], axis=0)
        again, again_ok = triangulate_rig(rig, [m & changed for m in masks], poses, planes)
        points = np.where(changed[..., None], again, points)
        ok = np.where(changed, again_ok, ok)
    flat = ok & (parallax_deg(rig, points, masks, poses, planes) < min_parallax)
    masks = [m & ~flat for m in masks]
    found = 0
    if config.first_rejection:
        used = seen_twice(masks) & ok
        masks, found = observation_outliers(rig, points, used, masks, poses, planes, opts.outlier_threshold)
        if opts.bone_outlier_k > 0:
            _, pairs = bone_table(rig)
            bad = bone_outliers(points, used & seen_twice(masks), pairs, k=opts.bone_outlier_k)
            found += int(np.count_nonzero(bad))
            masks = [m & ~bad for m in masks]
    return points, masks, behind + int(np.count_nonzero(flat)) + found, found


#: An estimated camera or a mirror needs at least this many keypoints left in its
#: views after outlier rejection (a pose has 6 unknowns, a plane 3).
MIN_HELD_OBSERVATIONS = 30


def _check_held(rig: Rig, masks: list[np.ndarray], offered: list[int]) -> None:
    """Raise when an estimated camera or a mirror has (almost) no keypoints left.

    Raises:
        DegenerateGeometryError: naming the camera or mirror, with the counts; for a
            camera whose focal length is estimated, that its start (the initial focal
            length and placement) may be what is too far off, not the user's input.
    """
    kept = np.array([int(np.count_nonzero(m)) for m in masks])
    had = np.asarray(offered)
    groups = [(c, f"camera {c.name}", [i for i, v in enumerate(rig.views)
                                        if v.camera == c.name])
              for c in rig.cameras if c.estimate_pose or c.estimate_focal]
    groups += [(None, f"mirror {m.name}", [i for i, v in enumerate(rig.views)
                                           if v.mirror == m.name])
               for m in rig.mirrors]
    for cam, what, idx in groups:
        if kept[idx].sum() < MIN_HELD_OBSERVATIONS:
            head = (f"{what}: {kept[idx].sum()} of its {had[idx].sum()} keypoints fit the "
                    f"rest of the rig (need {MIN_HELD_OBSERVATIONS})")
            if cam is not None and cam.estimate_focal:
                raise DegenerateGeometryError(
                    f"{head} at its initial focal length {cam.K[0, 0]:.0f} px and placement, "
                    "which the graph starts its estimate from: the start is too far off for "
                    "these views (give this camera's intrinsics), or it sees another person "
                    "or needs a frame offset")
            raise DegenerateGeometryError(
                f"{head}: is it the same person as in the other cameras? the right "
                "intrinsics, frame offset, mirror?")


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


def reprojection_noise_px(rig: Rig, masks: list[np.ndarray], poses, planes,
                          global_unknowns: int) -> float:
    """A posteriori pixel sigma of a whole video: :func:`residual_noise` of every joint of
    ``masks`` triangulated from its views with the solved rig, in blocks of
    :data:`NOISE_BLOCK_FRAMES` frames, so that a long video's temporaries stay small."""
    rss, n_obs, n_points = 0.0, 0, 0
    for a in range(0, rig.num_frames, NOISE_BLOCK_FRAMES):
        rows = slice(a, a + NOISE_BLOCK_FRAMES)
        block = rig.subset(rows)
        bm = [np.asarray(m, bool)[rows] for m in masks]
        X, ok = triangulate_rig(block, bm, poses, planes)
        parts = _residual_sums(block, bm, X, ok, poses, planes)
        rss, n_obs, n_points = rss + parts[0], n_obs + parts[1], n_points + parts[2]
    return residual_noise_px(rss, 2 * n_obs, 3 * n_points + global_unknowns)


def residual_noise(rig: Rig, masks: list[np.ndarray], points: np.ndarray, ok: np.ndarray,
                   poses, planes, global_unknowns: int) -> float:
    """A posteriori pixel sigma from the joints ``points`` ``(T, J, 3)`` (``ok``: ``(T, J)``)
    triangulated from the views of ``masks`` with the solved rig (the maximum-likelihood
    points of the reprojection alone): ``sqrt(RSS / dof)`` with
    ``dof = 2 observations - 3 joints - global_unknowns``
    (:func:`~.result.residual_noise_px`)."""
    rss, n_obs, n_points = _residual_sums(rig, masks, points, ok, poses, planes)
    return residual_noise_px(rss, 2 * n_obs, 3 * n_points + global_unknowns)


def _residual_sums(rig: Rig, masks, points, ok, poses, planes) -> tuple[float, int, int]:
    """Sum of squared residuals, observations and joints of triangulated ``points``."""
    res = view_residuals(with_views(rig, [np.asarray(m, bool) & ok for m in masks]), points,
                         ok, planes, poses)
    r = np.concatenate([v[np.isfinite(v)] for v in res])
    return float(np.sum(r ** 2)), len(r), int(np.count_nonzero(ok))


#: Frames a block of :func:`reprojection_noise_px` holds.
NOISE_BLOCK_FRAMES = 2000


def covariances(problem: GraphProblem, values: gtsam.Values, info: np.ndarray | None,
                z_keys, compute: bool = True):
    """Per camera ``(6, 6)`` and per plane ``(3, 3)`` tangent covariance from the reduced
    information (:func:`~.optimizer.reduced_covariance`), the planes' normal bases, the
    reduced variables' values and per camera the ``(d, d)`` covariance of its estimated
    intrinsics (``(0, 0)`` where held). Held cameras get zeros; NaN where not computed."""
    rig = problem.rig
    nan6, nan3 = np.full((6, 6), np.nan), np.full((3, 3), np.nan)
    basis = [np.asarray(values.atOrientedPlane3(k).normal().basis()) for k in problem.plane_keys]
    zv = gtsam.Values()
    for k, _ in z_keys:
        if k in problem.plane_keys:
            zv.insert(k, values.atOrientedPlane3(k))
        elif gtsam.Symbol(k).chr() == ord("k"):
            zv.insert(k, values.atCal3_S2(k))
        elif k == problem.length_key:
            zv.insert(k, values.atVector(k))
        else:
            zv.insert(k, values.atPose3(k))
    dims = [rig.cameras[i].intrinsics_dim if i in problem.calibration_keys else 0
            for i in range(len(rig.cameras))]
    if info is None or not compute:
        return ([np.zeros((6, 6)) if i not in problem.camera_keys else nan6
                 for i in range(len(rig.cameras))],
                [nan3] * len(problem.plane_keys), basis, zv,
                [np.full((d, d), np.nan) for d in dims])
    cov = reduced_covariance(info, z_keys)
    cams = [np.zeros((6, 6)) if problem.camera_keys.get(i) is None
            else cov[int(problem.camera_keys[i])] for i in range(len(rig.cameras))]
    planes = [cov[int(k)] for k in problem.plane_keys]
    intr = [cov[int(problem.calibration_keys[i][0])] if d else np.zeros((0, 0))
            for i, d in enumerate(dims)]
    return cams, planes, basis, zv, intr
