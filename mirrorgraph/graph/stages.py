"""The stages of the one solve driver (:func:`mirrorgraph.graph.solve.solve`), one function each.

:func:`solve_rows` runs them in order on a working state handed from stage to stage;
what varies between rigs (the full-graph stages, the first rejection, the warm start,
the focal search, the joints pass) is the :class:`~.stage_config.SolveConfig`
(:func:`~.stage_config.single_mirror_config`, :func:`~.stage_config.rig_config`).

Stages (each recorded in :attr:`~.solve_state.SolveState.stages`):

1. **Triangulation** of every joint seen in two views or more
   (:func:`mirrorgraph.geometry.triangulate`), dropping observations behind their camera,
   joints behind a mirror and rays meeting under ``options.min_parallax_deg``;
2. **Warm start** (``config.warm_start``): robust reprojection alone on
   ``options.warm_start_frames`` frames, then triangulation again;
2b. **Focal search** (``config.focal_search``): the focal length that makes the body most
   rigid (:func:`~.focal_search.focal_search`);
3. **Gauge**: with a subject height, bone lengths scaled to Winter's for that height;
4. **Stages** of :attr:`~.stage_config.SolveConfig.stages`: the full graph with the
   stage's robust kernel, then the observations beyond its threshold dropped;
5. **Joints pass** (``config.joints_pass``): the joints with every global held, the
   smoothness and every bone (:func:`~.bones.debiased_bone_lengths`);
6. **Marginals and noise**: the reduced information's inverse
   (:func:`~.optimizer.reduced_covariance`, :mod:`.marginals`) scaled by the noise the
   data show (:mod:`.noise`).

Each stage in full: ``docs/internals.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import gtsam
import numpy as np

from ..errors import DegenerateGeometryError
from ..keypoints import MIN_PAIRS
from .bones import (bone_curvature_bias, bone_table, debiased_bone_lengths, gauge_scale,
                    integrated_bone_lengths, median_bone_lengths)
from .builder import build_problem, with_motion_priors, with_torso
from .priors import torso_lengths, torso_table
from .focal_search import focal_search, focal_searchable
from .marginals import covariances
from .noise import residual_noise
from .optimizer import LMResult
from .options import RefineOptions
from .outliers import (bone_outliers, check_held, clean_views, observation_outliers,
                       one_view_outliers)
from .problem import (GraphProblem, extract_camera_poses, extract_intrinsics, extract_planes,
                      extract_points, snap_virtual_poses, without_observations)
from .rig import (Rig, parallax_deg, seen_twice, spread_rows, triangulate_rig, view_residuals,
                  with_intrinsics, with_views)
from .scores import joint_scores
from .solve_graph import Progress, information_at, optimize, undetermined
from .solve_state import SolveState
from .stage_config import SolveConfig, Stage
from .uncertainty import robust_intrinsics_std

__all__ = ["solve_rows", "joints_pass", "Counter", "stage_record", "THIN_BONE_FRAMES",
           "JOINTS_PASS_ITERATIONS", "LOW_PARALLAX_ITERATIONS"]


# --------------------------------------------------------------------------- bookkeeping
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
    """One entry of :attr:`~.solve_state.SolveState.stages`."""
    return {"name": name, "iterations": res.iterations, "initial_error": res.initial_error,
            "final_error": res.final_error, "converged": res.converged, "rejected": rejected,
            "failed_steps": res.rejected_steps, "guarded": res.guarded,
            "undetermined": len(res.indeterminate), **extra}


# --------------------------------------------------------------------------- the driver
@dataclass
class _Run:
    """The driver's working state, handed from stage to stage (:func:`solve_rows`).

    Attributes:
        rig: the rig (its ``K`` replaced where a focal length is estimated).
        opts, config, height, counter: the arguments of :func:`solve_rows`.
        poses: ``(4, 4)`` camera-to-world pose per camera; planes: ``(n, d)`` per mirror.
        masks: per view the ``(T, J)`` observations kept; offered: per view the count
            of observations the rig came with (for :func:`~.outliers.check_held`).
        timings: seconds per part; t_start: :func:`time.perf_counter` at the start.
        points: ``(T, J, 3)`` joints (world frame; graph units once on the gauge);
            used: ``(T, J)`` the joints the next graph estimates.
        rejected: observations dropped so far; found: outliers the first rejection
            found (for the ``"auto"`` kernel).
        stages: the stages' records (:func:`stage_record`).
        problem, values, res, z_keys: the last full-graph stage's graph, solution,
            solve and reduced keys.
        lengths, body_height, length_sum: what the next full-graph stage starts from
            (bone name -> length, the body priors' length scale, the gauge's sum).
        iterations: iterations so far; n_undetermined: joints dropped as undetermined.
    """

    rig: Rig
    opts: RefineOptions
    config: SolveConfig
    height: float | None
    counter: Counter
    poses: list[np.ndarray]
    planes: list[tuple[np.ndarray, float]]
    masks: list[np.ndarray]
    offered: list[int]
    timings: dict[str, float]
    t_start: float
    points: np.ndarray | None = None
    used: np.ndarray | None = None
    rejected: int = 0
    found: int = 0
    stages: list[dict] = field(default_factory=list)
    problem: GraphProblem | None = None
    values: gtsam.Values | None = None
    res: LMResult | None = None
    z_keys: list[tuple[int, int]] = field(default_factory=list)
    lengths: dict[str, float] | None = None
    body_height: float | None = None
    length_sum: float | None = None
    iterations: int = 0
    n_undetermined: int = 0

    def clean(self, masks: list[np.ndarray]) -> None:
        """The joints triangulated from ``masks`` with the current rig and the views
        cleaned (:func:`~.outliers.clean_views`)."""
        self.points, self.masks, self.rejected, self.found = clean_views(
            self.rig, masks, self.poses, self.planes, self.opts, self.config,
            self.opts.min_parallax_deg)

    def view_masks(self) -> list[np.ndarray]:
        """Per view the ``(T, J)`` observations the rig came with."""
        return [np.asarray(v.mask, bool) for v in self.rig.views]


def solve_rows(rig: Rig, opts: RefineOptions, config: SolveConfig, height: float | None,
               counter: Counter) -> SolveState:
    """The driver's stages (the module docstring's 1 to 6) on every frame row of ``rig``.

    Args:
        rig: cameras, mirrors, views and observations; its poses, planes and ``K`` are
            the initial values.
        opts: weights, kernels, thresholds; config: what varies between rigs
            (:mod:`.stage_config`).
        height: the subject's height, m (the gauge), or ``None``.
        counter: counts the iterations for the user's progress callback.

    Returns:
        The solved rig, joints, covariances and bookkeeping (graph units: metres with a
        subject height).

    Raises:
        DegenerateGeometryError: under :data:`~mirrorgraph.keypoints.MIN_PAIRS` joints
            left in two views, or an estimated camera or a mirror left with (almost) no
            keypoints (:func:`~.outliers.check_held`).
    """
    timings = {"triangulate": 0.0, "build": 0.0, "solve": 0.0, "marginals": 0.0}
    t_start = time.perf_counter()
    if height is not None:
        opts = replace(opts, subject_height=float(height))
    masks = [np.asarray(v.mask, bool) for v in rig.views]
    run = _Run(rig=rig, opts=opts, config=config, height=height, counter=counter,
               poses=[np.asarray(c.pose, float).copy() for c in rig.cameras],
               planes=[(np.asarray(m.normal, float), float(m.distance)) for m in rig.mirrors],
               masks=masks, offered=[int(np.count_nonzero(m)) for m in masks],
               timings=timings, t_start=t_start)
    _triangulate(run)                                          # 1.
    _warm_start(run)                                           # 2.
    _search_focal(run)                                         # 2b.
    _start_on_gauge(run)                                       # 3.
    _full_graph_stages(run)                                    # 4.
    final_error, final_used, state_points, intrinsics = _solution(run)
    final_masks, tri, tri_ok = _retriangulate(run, final_used)
    lengths = _joints_pass_lengths(run, tri, tri_ok)
    torso = _joints_pass_torso(run, state_points, final_used)
    calibration_points = state_points
    state_points, joints_priors, observed = _joints_pass_stage(run, lengths, torso,
                                                               state_points)         # 5.
    unc = _marginals_and_noise(run, final_masks, tri, tri_ok)                        # 6.
    timings["total"] = time.perf_counter() - t_start
    problem, factor = run.problem, unc["factor"]
    if observed is not None:
        # the output joints' graph: the calibration's with the observations the joints
        # pass kept (their covariance, the residuals reported)
        problem = replace(problem, reprojection=observed.reprojection, rig=observed.rig)
    info = dict(problem.prior_info)
    if joints_priors is not None:
        info["joints_pass"] = joints_priors
    if problem.distance_gauge is not None:
        info["distance_gauge"] = {"sigma": 1e-6, "weight": 1e12, "unit": "d", "factors": 1,
                                  "distance": problem.distance_gauge}
    return SolveState(poses=run.poses, planes=run.planes, points=state_points,
                      used=final_used, bone_lengths=lengths, torso_lengths=torso,
                      calibration_points=(calibration_points if observed is not None
                                          else None),
                      scale=problem.scale,
                      camera_cov=[C * factor for C in unc["cam_cov"]],
                      plane_cov=[C * factor for C in unc["plane_cov"]],
                      plane_basis=unc["basis"], noise_px=unc["noise_px"],
                      variance_factor=factor, view_masks=final_masks,
                      rejected=run.rejected, undetermined=run.n_undetermined,
                      prior_info=info, reprojection_factors=int(problem.reprojection.size()),
                      iterations=run.iterations, final_error=final_error, stages=run.stages,
                      timings=timings, body_height=problem.body_height,
                      information=run.res.reduced_information, z_keys=run.z_keys,
                      z_values=unc["zv"], problem=problem, scores=unc["scores"],
                      intrinsics=intrinsics,
                      intrinsics_cov=[C * factor for C in unc["intr_cov"]],
                      intrinsics_std=unc["intr_std"])


def _triangulate(run: _Run) -> None:
    """Stage 1: triangulate, cheirality, parallax, the first rejection."""
    t = time.perf_counter()
    run.clean(run.masks)
    run.timings["triangulate"] += time.perf_counter() - t


def _warm_start(run: _Run) -> None:
    """Stage 2: reprojection only on spread frames, the first mirror's distance held
    (only where every camera pose is held); then every joint cleaned again with the
    warm rig (the original masks: the first rejection is judged anew against the
    better mirror)."""
    rig, opts = run.rig, run.opts
    if not (run.config.warm_start and opts.warm_start_iterations > 0 and run.planes
            and not any(c.estimate_pose for c in rig.cameras)):
        return
    t = time.perf_counter()
    rows = spread_rows(rig.num_frames, opts.warm_start_frames)
    used = seen_twice(run.masks) & rows[:, None]
    used &= (parallax_deg(rig, run.points, run.masks, run.poses, run.planes)
             >= opts.warm_start_min_parallax_deg)
    if np.count_nonzero(used) >= MIN_PAIRS:
        warm = build_problem(with_views(rig, run.masks), run.points, used, run.planes, opts,
                             priors=False, hold_intrinsics=True)
        run.timings["build"] += time.perf_counter() - t
        t = time.perf_counter()
        res, _ = optimize(warm, warm.reprojection, opts, distance_gauge=run.planes[0][1],
                          max_iterations=opts.warm_start_iterations, progress=run.counter)
        run.planes = extract_planes(warm, res.values)
        run.poses = extract_camera_poses(warm, res.values)
        run.clean(run.view_masks())
        run.stages.append(stage_record("warm start (reprojection only, %d frames)"
                                       % np.count_nonzero(used.any(1)), res, run.rejected))
    run.timings["solve"] += time.perf_counter() - t


def _search_focal(run: _Run) -> None:
    """Stage 2b: the focal length's initial search (one camera held, its mirrors;
    :func:`~.focal_search.focal_search`), then every joint cleaned again with it."""
    if not (run.config.focal_search and focal_searchable(run.rig)):
        return
    t = time.perf_counter()
    run.rig, run.planes, record = focal_search(run.rig, run.masks, run.poses, run.planes,
                                               run.opts, run.config, run.height)
    run.clean(run.view_masks())
    run.stages.append(record)
    run.timings["solve"] += time.perf_counter() - t


def _start_on_gauge(run: _Run) -> None:
    """Stage 3: the joints left in two views checked, and with a subject height the
    joints, planes and camera positions scaled onto the gauge
    (:func:`~.bones.gauge_scale`)."""
    check_held(run.rig, run.masks, run.offered)
    run.used = seen_twice(run.masks) & np.isfinite(run.points).all(-1)
    if np.count_nonzero(run.used) < MIN_PAIRS:
        raise DegenerateGeometryError(
            f"only {np.count_nonzero(run.used)} joints are seen in two views after the "
            f"outliers and the joints without depth were removed (need {MIN_PAIRS})")
    if run.height is not None:
        s = gauge_scale(run.rig, run.points, run.used, float(run.height))
        run.points = run.points * s
        run.planes = [(n, d * s) for n, d in run.planes]
        for p in run.poses:
            p[:3, 3] *= s


def _full_graph_stages(run: _Run) -> None:
    """Stage 4: :attr:`~.stage_config.SolveConfig.stages` in order, each built from the
    previous one's solution; a stage ``only_if_rejected`` runs when the previous one
    dropped something (and ``options.resolve_after_rejection`` or the previous one
    stopped before converging), or where a focal length is estimated."""
    run.body_height = None if run.height is None else float(run.height)
    run.iterations = sum(s["iterations"] for s in run.stages)
    dropped_last = True
    focal = any(c.intrinsics_dim for c in run.rig.cameras)
    for stage in run.config.stages:
        again = run.opts.resolve_after_rejection or (run.res is not None
                                                     and not run.res.converged)
        if stage.only_if_rejected and not (dropped_last and again) and not focal:
            continue
        dropped_last = _full_graph_stage(run, stage) > 0


def _full_graph_stage(run: _Run, stage: Stage) -> int:
    """One full-graph stage: build, solve, read back, reject; the count dropped."""
    opts = run.opts
    kernel = stage.kernel
    if kernel == "auto":
        kernel = ("geman_mcclure" if run.found > opts.auto_kernel_fraction * max(run.used.sum(), 1)
                  else None)
    if np.count_nonzero(run.used) < MIN_PAIRS:
        raise DegenerateGeometryError(
            f"only {int(np.count_nonzero(run.used))} joints left in two views after outlier "
            f"rejection (need {MIN_PAIRS})")
    t = time.perf_counter()
    stage_opts = replace(opts, final_kernel_scale_px=stage.kernel_scale_px)
    srig = with_views(run.rig, run.masks, run.poses, run.planes)
    problem = build_problem(srig, run.points, run.used, run.planes, stage_opts,
                            body_height=run.body_height, bone_lengths=run.lengths,
                            length_sum=run.length_sum, final_kernel=kernel)
    if run.height is not None:
        problem.body_height = float(run.height)
    snap_virtual_poses(problem, problem.values)
    run.timings["build"] += time.perf_counter() - t
    t = time.perf_counter()
    # the cap only saves time where the globals converge in a few steps; an estimated
    # focal length moves the whole reconstruction and needs the full count
    cap = (stage.cap_if_outliers
           if (run.res is None and run.found and not problem.calibration_keys) else None)
    res, run.z_keys = optimize(problem, problem.full(), stage_opts,
                               distance_gauge=problem.distance_gauge, max_iterations=cap,
                               progress=run.counter)
    run.iterations += res.iterations
    run.problem, run.values, run.res = problem, res.values, res
    _read_back(run)
    dropped = _reject(run, stage)
    run.rejected += dropped
    run.stages.append(stage_record(stage.name, res, dropped, kernel=kernel))
    run.timings["solve"] += time.perf_counter() - t
    return dropped


def _read_back(run: _Run) -> None:
    """The stage's solution as the next stage's start: joints, planes, poses, the
    estimated ``K`` (every later triangulation and residual with it), bone lengths,
    the body height and the gauge's sum."""
    problem, values = run.problem, run.values
    run.points = extract_points(problem, values)
    run.planes = extract_planes(problem, values)
    run.poses = extract_camera_poses(problem, values)
    if problem.calibration_keys:
        run.rig = with_intrinsics(run.rig, extract_intrinsics(problem, values))
    run.lengths = problem.bone_lengths()
    run.body_height = problem.body_height
    if problem.lengths is not None and run.height is None:
        run.length_sum = problem.prior_info["length_sum_gauge"]["sum"]


def _reject(run: _Run, stage: Stage) -> int:
    """After a stage: the joints GTSAM found undetermined, and with ``stage.reject_px``
    the observations beyond it (and behind their camera) and with
    ``stage.bone_outliers`` the joints whose bones are all implausible, dropped; the
    joints left in under two views leave ``run.used``. Returns the count dropped."""
    rig, opts, points = run.rig, run.opts, run.points
    lost = undetermined(run.problem, run.res)
    run.n_undetermined += int(np.count_nonzero(lost))
    used = run.problem.used & ~lost
    dropped = 0
    if stage.reject_px is not None:
        run.masks, dropped = observation_outliers(rig, points, used, run.masks, run.poses,
                                                  run.planes, stage.reject_px)
        if stage.bone_outliers and opts.bone_outlier_k > 0:
            _, pairs = bone_table(rig)
            bad = bone_outliers(points, used, pairs, k=opts.bone_outlier_k)
            dropped += int(np.count_nonzero(bad))
            run.masks = [m & ~bad for m in run.masks]
        check_held(rig, run.masks, run.offered)
    dropped += int(np.count_nonzero(lost))
    used &= seen_twice(run.masks)
    run.used = used
    return dropped


def _solution(run: _Run) -> tuple[float, np.ndarray, np.ndarray, list[np.ndarray]]:
    """The last stage's error, its ``(T, J)`` used joints, its ``(T, J, 3)`` joints and
    every camera's ``(3, 3)`` ``K``; where every solve of the last stage was damped (it
    met a nearly singular point) the reduced information at its solution, for the
    covariances."""
    problem, values, res = run.problem, run.values, run.res
    final_error = float(res.final_error)
    if res.reduced_information is None and run.opts.marginals:
        res.reduced_information, res.reduced_gradient = information_at(problem, values,
                                                                       run.opts)
    final_used = problem.used.copy()
    state_points = extract_points(problem, values)
    intrinsics = extract_intrinsics(problem, values)
    if problem.calibration_keys:
        problem.rig = with_intrinsics(problem.rig, intrinsics)
    return final_error, final_used, state_points, intrinsics


def _retriangulate(run: _Run, final_used: np.ndarray
                   ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Every kept joint triangulated with the solved rig: the maximum-likelihood points
    of the reprojection alone (free of the priors' pull), for the noise and the
    lengths. Returns the final view masks, ``(T, J, 3)`` joints and ``(T, J)`` mask."""
    problem = run.problem
    t = time.perf_counter()
    final_masks = [np.asarray(v.mask, bool) & final_used for v in problem.rig.views]
    tri, tri_ok = triangulate_rig(problem.rig, final_masks, run.poses, run.planes)
    run.timings["triangulate"] += time.perf_counter() - t
    return final_masks, tri, tri_ok


def _joints_pass_lengths(run: _Run, tri: np.ndarray, tri_ok: np.ndarray) -> dict[str, float]:
    """Bone name -> length for the joints pass (and the result): the calibration's, and
    for the bones it left out, or measured in under :data:`THIN_BONE_FRAMES` frames,
    their length measured without the curvature bias (``opts.joints_bone_lengths``:
    :func:`~.bones.debiased_bone_lengths`, or :func:`~.bones.integrated_bone_lengths`
    with a left and a right bone among them one length)."""
    problem, opts = run.problem, run.opts
    lengths = problem.bone_lengths()
    names, pairs = bone_table(problem.rig)
    frames = (dict(zip(problem.bone_names, np.bincount(problem.bone_rows[:, 2].astype(np.int64),
                                                       minlength=len(problem.bone_names))))
              if problem.lengths is not None else {})
    other = [i for i, b in enumerate(names)
             if b not in lengths or frames.get(b, 0) < THIN_BONE_FRAMES]
    if other and opts.use_bone_length:
        row = {names[i]: k for k, i in enumerate(other)}
        partners = np.full(len(other), -1)
        for left, right in problem.rig.skeleton.symmetric_bones:
            if left in row and right in row:
                partners[row[left]], partners[row[right]] = row[right], row[left]
        if opts.joints_bone_lengths == "integrated":
            est = integrated_bone_lengths(problem.rig, tri, tri_ok, run.planes, pairs[other],
                                          opts.pixel_sigma, partners=partners)
        else:
            est = debiased_bone_lengths(problem.rig, tri, tri_ok, run.planes, pairs[other],
                                        opts.pixel_sigma)
        lengths.update({names[i]: float(v) for i, v in zip(other, est) if np.isfinite(v)})
    return lengths


def _joints_pass_torso(run: _Run, points: np.ndarray, used: np.ndarray
                       ) -> dict[str, float] | None:
    """The torso's distances the joints pass holds (``opts.torso_sigma``), read on the
    calibration's joints ``points`` ``(T, J, 3)`` (``used`` ``(T, J)``) where their
    depth is fixed: in each distance's frames whose curvature bias
    (:func:`~.bones.bone_curvature_bias`, its bound ``tr S / 2L``) is under the
    calibration's bone rule (``opts.bone_bias_limit`` bone sigmas: the frames where the
    calibration would measure it as a bone), each the median over them
    (:func:`~.priors.torso_lengths`). ``None`` where a distance has fewer than
    :data:`THIN_BONE_FRAMES` such frames (rays that meet at a few degrees over most of
    the clip): :func:`joints_pass` then reads them on its own joints; ``{}`` without a
    torso term. (A rule twice as loose, ``opts.bone_bias_limit`` torso sigmas, reads
    them so on more wide scenes, and on one of them, iid 1 of
    ``bench/bench_joints.py``, gives a PA-MPJPE of 21.3 mm against 19.4 mm.)"""
    problem, opts = run.problem, run.opts
    if opts.torso_sigma is None or not opts.use_bone_length:
        return {}
    names, pairs = torso_table(problem.rig)
    if not len(pairs):
        return {}
    both = used[:, pairs[:, 0]] & used[:, pairs[:, 1]]                          # (T, P)
    keep = both
    if opts.bone_bias_limit is not None:
        bias = bone_curvature_bias(problem.rig, points, used, run.planes, pairs,
                                   median_bone_lengths(points, pairs, both), opts.pixel_sigma)
        keep = both & ~(bias > opts.bone_bias_limit * problem.body_height * opts.bone_sigma)
    if (np.count_nonzero(keep, axis=0) < THIN_BONE_FRAMES).any():
        return None
    return torso_lengths(problem.rig, points, used, keep)


def _joints_pass_stage(run: _Run, lengths: dict[str, float], torso: dict[str, float] | None,
                       points: np.ndarray
                       ) -> tuple[np.ndarray, dict | None, GraphProblem | None]:
    """Stage 5 (``config.joints_pass``): the joints with everything else held
    (:func:`joints_pass`, the torso's distances ``torso``). Returns the joints
    (``points`` without a pass), the pass's body priors for the record and its graph
    (``None`` without one)."""
    joints_priors, observed = None, None
    if run.config.joints_pass:
        t = time.perf_counter()
        jp = joints_pass(run.problem, run.values, lengths, run.opts, torso=torso)
        if jp is not None:
            points = extract_points(jp[0], jp[1].values)
            observed = jp[0]
            joints_priors = {k: v for k, v in jp[0].prior_info.items()
                             if k in ("bone_length", "torso", "hip", "smoothness")}
            joints_priors["observations_left_out"] = int(
                sum(np.count_nonzero(np.asarray(a.mask, bool) & ~np.asarray(b.mask, bool))
                    for a, b in zip(run.problem.rig.views, jp[0].rig.views)))
            run.stages.append(stage_record("joints pass (globals held, smoothness %g h)"
                                           % run.opts.joints_smoothness_sigma, jp[1], 0))
            run.iterations += jp[1].iterations
        run.timings["solve"] += time.perf_counter() - t
    return points, joints_priors, observed


def _marginals_and_noise(run: _Run, final_masks: list[np.ndarray], tri: np.ndarray,
                         tri_ok: np.ndarray) -> dict:
    """Stage 6: the a posteriori noise (:func:`~.noise.residual_noise`), the marginal
    covariances (:func:`~.marginals.covariances`, unscaled) and the variance factor
    ``(noise / pixel_sigma)^2`` that scales them, the joints' scores and the estimated
    intrinsics' robust stds (:func:`~.uncertainty.robust_intrinsics_std`). Returns
    them by name (``noise_px``, ``factor``, ``cam_cov``, ``plane_cov``, ``basis``,
    ``zv``, ``intr_cov``, ``scores``, ``intr_std``)."""
    problem, values, opts = run.problem, run.values, run.opts
    t = time.perf_counter()
    noise_px = residual_noise(problem.rig, final_masks, tri, tri_ok, run.poses, run.planes,
                              6 * len(problem.camera_keys) + 3 * len(run.planes)
                              + sum(problem.rig.cameras[c].intrinsics_dim
                                    for c in problem.calibration_keys))
    factor = (noise_px / opts.pixel_sigma) ** 2 if np.isfinite(noise_px) else 1.0
    cam_cov, plane_cov, basis, zv, intr_cov = covariances(problem, values,
                                                          run.res.reduced_information,
                                                          run.z_keys, opts.marginals)
    run.timings["marginals"] = time.perf_counter() - t
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
    run.timings["uncertainty"] = time.perf_counter() - t
    return {"noise_px": noise_px, "factor": factor, "cam_cov": cam_cov, "plane_cov": plane_cov,
            "basis": basis, "zv": zv, "intr_cov": intr_cov, "scores": scores,
            "intr_std": intr_std}


#: A bone the calibration graph measured in fewer frames than this (its bone rule kept
#: it there in a few frames only) gets, for the joints pass, the length its
#: triangulations give in every frame without the curvature bias
#: (:func:`~.bones.debiased_bone_lengths`, whose own minimum this is): a length from
#: one frame held in every frame puts its error in all of them (a hip width measured
#: in one frame of 960 comes out 30 % long: ``tests/graph/test_focal.py``,
#: ``test_a_bone_measured_in_one_frame_does_not_carry_the_gauge``).
THIN_BONE_FRAMES = 10


#: Gauss-Newton steps of the joints pass (:func:`joints_pass`): the points start at the
#: calibration's solution and the smoothness is linear in them, so one step lands
#: within ~1 mm of the converged joints (error 15156.7 vs 15155.9 converged on a
#: 1000-frame protocol scene). With the torso held a second step would lower the
#: PA-MPJPE a little more (1000-frame wide scenes, realistic detector: by 0-1.3 mm, 2 %
#: at most), at the cost of one more elimination of every joint (+0.2 s per 1000
#: frames, +25 % CPU on a 16,000-frame video).
JOINTS_PASS_ITERATIONS = 1

#: Gauss-Newton steps of the joints pass with the torso held where the torso's distances
#: are read on the pass's own joints (:func:`joints_pass` with ``torso=None``: rays that
#: meet at a few degrees over most of the video, where the torso moves the joints far
#: from the calibration's solution and one step stops short of it).
LOW_PARALLAX_ITERATIONS = 2


def joints_pass(problem: GraphProblem, values: gtsam.Values, lengths: dict[str, float],
                opts: RefineOptions, sensitivity: bool = False,
                torso: dict[str, float] | None = None, iterations: int | None = None
                ) -> tuple[GraphProblem, LMResult] | None:
    """The 3D joints solved again with every global held, from the calibration's solution.

    The calibration's variables and reprojection factors with other body priors
    (:func:`~.builder.with_motion_priors`): the smoothness of
    ``opts.joints_smoothness_sigma`` (tight: it halves the joints' error, where the
    calibration wants none, see :class:`~.options.RefineOptions`; per frame^2 of the
    video: ``opts`` as the pipeline took them at its frame rate,
    :meth:`~.options.PriorOptions.at_frame_rate`), and every bone of ``lengths``
    in every frame, the frames that ``opts.bone_bias_limit`` left out of the
    calibration included (the mirror held, a bone's known length is what fixes the
    depth of joints whose rays meet at a small angle); a bone ``lengths`` lacks at its
    left/right partner's length (:func:`~.priors.other_side_lengths`), and with
    ``opts.torso_sigma`` the torso nearly rigid (:mod:`mirrorgraph.factors.torso`):
    its distances no bone holds at ``torso``, or where ``torso`` is ``None`` at their
    medians on the pass solved first without them (:func:`~.priors.torso_lengths`:
    joints the bones and the smoothness hold), the pass then solved again from there.

    Then the observations whose residual exceeds ``opts.outlier_threshold`` (the
    calibration's own rule) at that solution are left out, at most one view of a
    joint (:func:`~.outliers.one_view_outliers`), and the pass is solved again from it
    without them. A keypoint displaced along its epipolar line (a knee detected up or
    down the leg that points at the epipole) fits both views in the calibration's
    graph, its joint slid in depth; held by every bone and the smoothness, the joint
    leaves that ray and the residual shows it.

    Args:
        problem, values: the calibration's graph and its solution.
        lengths: bone name -> length (graph units), held.
        torso: the torso's distances (``"a-b"`` joint names -> length, graph units), held
            with ``opts.torso_sigma``; ``None``: read on the pass's own joints.
        sensitivity: also return the joints' change per unit of the held mirror's
            reduced coordinates (:attr:`~.optimizer.LMResult.sensitivity`, ``(N, 3, nz)``
            in ``problem.flat_index`` order): the joints of the pass at a mirror moved
            by ``z`` are, to first order, the result plus ``sensitivity @ z``.
        iterations: Gauss-Newton steps of each of the pass's solves (the one after the
            torso is read on the pass's own joints takes :data:`LOW_PARALLAX_ITERATIONS`);
            ``None``: :data:`JOINTS_PASS_ITERATIONS` (from the calibration's solution).
            A graph that starts elsewhere (the live run's windows,
            :mod:`mirrorgraph.live.window_graph`, from the per-frame joints) takes more.

    Returns:
        The joints' graph (without the observations left out: its views' masks and its
        reprojection factors) and its solve; ``None`` without ``joints_smoothness_sigma``.
    """
    sigma = opts.joints_smoothness_sigma
    if sigma is None:
        return None
    steps = JOINTS_PASS_ITERATIONS if iterations is None else int(iterations)
    jopts = replace(opts, use_smoothness=True, smoothness_sigma=sigma)
    if opts.torso_sigma is None or not opts.use_bone_length:
        torso = {}
    if torso is None:
        # the torso's distances read on the joints the bones and the smoothness hold,
        # then the pass again from there with the torso held nearly rigid
        jp = with_motion_priors(problem, values, lengths, jopts)
        res, _ = optimize(jp, jp.full(), jopts, distance_gauge=jp.distance_gauge,
                          max_iterations=steps, hold_globals=True)
        torso = torso_lengths(jp.rig, extract_points(jp, res.values), jp.used)
        jp = with_torso(jp, torso, jopts)
        res, _ = optimize(jp, jp.full(), jopts, distance_gauge=jp.distance_gauge,
                          max_iterations=LOW_PARALLAX_ITERATIONS, hold_globals=True,
                          values=res.values, sensitivity=sensitivity)
    else:
        jp = with_motion_priors(problem, values, lengths, jopts, torso=torso)
        res, _ = optimize(jp, jp.full(), jopts, distance_gauge=jp.distance_gauge,
                          max_iterations=steps, hold_globals=True,
                          sensitivity=sensitivity)
    if opts.outlier_threshold > 0:
        # what the body now exposes: a keypoint displaced along its epipolar line fits
        # both views in the calibration's graph (the joint slides in depth), and
        # leaves its ray once every bone and the smoothness hold the joint
        residuals = view_residuals(jp.rig, extract_points(jp, res.values), jp.used,
                                   extract_planes(jp, res.values),
                                   extract_camera_poses(jp, res.values))
        drop = one_view_outliers(residuals, opts.outlier_threshold)
        if any(d.any() for d in drop):
            jp = without_observations(jp, drop)
            res, _ = optimize(jp, jp.full(), jopts, distance_gauge=jp.distance_gauge,
                              max_iterations=steps, hold_globals=True,
                              values=res.values, sensitivity=sensitivity)
    return jp, res


