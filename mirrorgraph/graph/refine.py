"""Refine a mirror calibration in one factor graph: the public entry point.

Pipeline of :func:`refine_mirror` (:func:`solve_single`):

1. **Warm start.** Pairs on frames spread over the video
   (``options.warm_start_frames``) are triangulated with the initial mirror
   (``d = 1``, or metres from the median bone lengths when the subject's height
   is known) and a few Levenberg-Marquardt iterations run on their robust
   (Geman-McClure) reprojection terms alone: the points are independent given
   the mirror, so these iterations are cheap.
2. **First rejection.** Every pair is triangulated with the warm mirror; pairs
   whose reprojection residual exceeds ``options.outlier_threshold`` in either
   view, or whose bones are all implausible (a keypoint displaced along its
   epipolar line fits both views at a wrong depth), are dropped (:mod:`.outliers`).
3. **The graph** (:mod:`.builder`): every remaining joint of every frame, the
   mirror plane, the virtual camera, the bone lengths; reprojection in both
   views, the mirror link, the body priors and the gauge. Solved by
   :class:`~.optimizer.LevenbergMarquardt` driven from Python, the link enforced
   exactly through reduced coordinates (:mod:`.reduction`).
4. **Second rejection and final solve**: pairs the body priors expose (same
   tests on the solution) are dropped, the graph rebuilt from the current
   estimate and solved again.
5. **Marginals.** The reduced information of the final undamped solve is the
   Schur complement of every point on (bone lengths, plane); GTSAM's
   :class:`gtsam.Marginals` of that reduced Gaussian gives the plane's 3x3
   tangent covariance, mapped to the unit normal with the tangent basis
   (:mod:`.result`).
6. **Metric scale** (with a subject height): everything is rescaled so that the
   stature measured on the joints equals the height (:mod:`.stature_scale`).

Videos longer than ``options.max_graph_frames`` are solved by :mod:`.chunked`
(a spread subset first, then frame chunks sharing the mirror).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable

import gtsam
import numpy as np

from ..anthropometry import expected_bone_lengths
from ..errors import DegenerateGeometryError, InputError
from ..geometry import epipolar_distances, epipole_from_normal, triangulate_mirror
from ..keypoints import PairedKeypoints
from .builder import (GraphProblem, body_height_from_points, bone_table, build_problem,
                      cheirality_guard, point_keys,
                      extract_planes, extract_points, smoothness_graph, snap_virtual_poses,
                      view_residuals)
from .optimizer import LevenbergMarquardt, LMParams, LMResult, reduced_marginals
from .options import RefineOptions
from .outliers import bone_outliers, reprojection_outliers
from .reduction import mirror_reduction
from .result import (RefinementResult, normal_cov_from_tangent, residual_noise_px,
                     rotation_std_from_normal_cov)
from .rig import Rig, single_mirror_rig

__all__ = ["refine_mirror", "RefineOptions", "RefinementResult", "rotation_std_from_normal_cov",
           "MIN_PAIRS"]

#: Fewest usable pairs for a refinement.
MIN_PAIRS = 12

Progress = Callable[[int, float], None]


# --------------------------------------------------------------------------- entry point
def refine_mirror(paired: PairedKeypoints, K: np.ndarray, normal0: np.ndarray,
                  inliers: np.ndarray, *, joints: np.ndarray | None = None,
                  options: RefineOptions | None = None,
                  progress: Progress | None = None) -> RefinementResult:
    """Jointly refine the mirror plane and every 3D joint in one GTSAM factor graph.

    Args:
        paired: person and reflection keypoints (undistorted pixels, mirror labels flipped).
        K: ``(3, 3)`` camera intrinsics.
        normal0: ``(3,)`` initial mirror normal (camera frame, away from the camera).
        inliers: ``(T, J)`` bool, the pairs the initialisation kept.
        joints: ``(k,)`` joint indices to use; default ``skeleton.calibration_joints``.
        options: weights, kernel, gauge, solver settings.
        progress: ``progress(iteration, error)`` after every iteration (iterations
            count over all stages).

    Returns:
        :class:`RefinementResult`.

    Raises:
        InputError: shapes that do not match.
        DegenerateGeometryError: fewer than :data:`MIN_PAIRS` usable pairs.
    """
    t_start = time.perf_counter()
    opts = options or RefineOptions()
    rig, used, d0 = prepare(paired, K, normal0, inliers, joints, opts)
    if rig.num_frames > opts.max_graph_frames:
        from .chunked import solve_chunked
        state = solve_chunked(rig, used, d0, opts, progress)
    else:
        state = solve_single(rig, used, d0, opts, progress)
    res = finish(rig, state, opts, t_start)
    if res.scale == "subject_height":
        from .stature_scale import LIMB_CHOSEN, scale_by_stature
        res = (scale_by_stature(res, paired, K, float(opts.subject_height))
               if opts.scale_from == "stature" else replace(res, scale_source=LIMB_CHOSEN))
    return res


# --------------------------------------------------------------------------- steps
def prepare(paired: PairedKeypoints, K: np.ndarray, normal0: np.ndarray, inliers: np.ndarray,
            joints: np.ndarray | None, opts: RefineOptions) -> tuple[Rig, np.ndarray, float]:
    """Validate the inputs, select the pairs and set the initial scale.

    Returns:
        The rig (initial plane inside), the used pairs ``(T, J)`` (seen in both
        views, inliers, selected joints) and the initial distance: 1, or, with a
        subject height, the distance in metres implied by the median bone lengths
        of pairs triangulated on frames spread over the video.
    """
    sk = paired.skeleton
    T, J = paired.real.shape[:2]
    K = np.asarray(K, dtype=float)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        raise InputError(f"K must be a finite 3x3 matrix, got shape {K.shape}", field="K")
    inl = np.asarray(inliers, dtype=bool)
    if inl.shape != (T, J):
        raise InputError(f"inliers must be ({T}, {J}), got {inl.shape}", field="inliers")
    n0 = np.asarray(normal0, dtype=float).reshape(3)
    if not np.all(np.isfinite(n0)) or np.linalg.norm(n0) < 1e-12:
        raise InputError("normal0 must be a finite non-zero vector", field="normal0")
    n0 = n0 / np.linalg.norm(n0)
    joints = np.asarray(sk.calibration_joints if joints is None else joints, dtype=int)
    jmask = np.zeros(J, dtype=bool)
    jmask[joints] = True
    used = paired.valid() & inl & jmask[None, :]
    if np.count_nonzero(used) < MIN_PAIRS:
        raise DegenerateGeometryError(
            f"only {np.count_nonzero(used)} usable joint pairs for the refinement "
            f"(need {MIN_PAIRS})")
    real, mirror = paired.real[..., :2], paired.mirror[..., :2]
    rig = single_mirror_rig(sk, paired.frame_ids, K, real, mirror, used, n0, 1.0, joints)
    d0 = 1.0
    if opts.subject_height is not None:
        sample = used & spread_rows(T, opts.warm_start_frames)[:, None]
        pts = triangulate_rig(rig, sample, [(n0, 1.0)])
        sample &= in_front(pts, n0, 1.0)
        h = body_height_from_points(rig, pts, sample)
        if np.isfinite(h) and h > 0:
            d0 = float(opts.subject_height) / h
    return rig, used, d0


def in_front(points: np.ndarray, normal: np.ndarray, distance: float) -> np.ndarray:
    """``(T, J)`` bool: finite points in front of the camera and of the mirror (cheirality)."""
    with np.errstate(invalid="ignore"):
        return (np.isfinite(points).all(-1) & (points[..., 2] > 0)
                & (points @ np.asarray(normal, dtype=float) < distance))


@dataclass
class SolveState:
    """What a solve hands to :func:`finish` (plain arrays, whatever the solver).

    Attributes:
        normal, distance: the first mirror, graph units.
        points: ``(T, J, 3)`` joints (graph units, NaN where not estimated); used: ``(T, J)``.
        bone_lengths: bone name -> length (graph units).
        scale: ``"subject_height"`` or ``"unit_distance"``.
        information: reduced information over ``z_keys`` at the solution (or ``None``).
        z_keys: ``(key, dim)`` layout of ``information``; the plane key is ``plane_key``.
        z_values: a :class:`gtsam.Values` holding the ``z`` variables (for the marginals).
        plane_key: key of the first plane.
        prior_info: prior name -> description (see :class:`RefinementResult`).
        reprojection_factors: number of reprojection factors in the final graph(s).
        iterations, final_error, stages, timings: bookkeeping.
        body_height: subject height in graph units (the body priors' length scale).
    """

    normal: np.ndarray
    distance: float
    points: np.ndarray
    used: np.ndarray
    bone_lengths: dict[str, float]
    scale: str
    information: np.ndarray | None
    z_keys: list[tuple[int, int]]
    z_values: gtsam.Values
    plane_key: int
    prior_info: dict[str, dict]
    reprojection_factors: int
    iterations: int
    final_error: float
    stages: list[dict]
    timings: dict[str, float]
    body_height: float = float("nan")


def state_from_problem(problem: GraphProblem, values: gtsam.Values, res: LMResult,
                       z_keys: list[tuple[int, int]], stages: list[dict],
                       timings: dict[str, float]) -> SolveState:
    """A :class:`SolveState` from a solved single graph."""
    n, d = extract_planes(problem, values)[0]
    zv = gtsam.Values()
    for k, _ in z_keys:
        if k in problem.plane_keys:
            zv.insert(k, values.atOrientedPlane3(k))
        else:
            zv.insert(k, values.atVector(k))
    info = dict(problem.prior_info)
    if problem.distance_gauge is not None:
        info["distance_gauge"] = {"sigma": 1e-6, "weight": 1e12, "unit": "d", "factors": 1,
                                  "distance": problem.distance_gauge}
    return SolveState(normal=n, distance=d, points=extract_points(problem, values),
                      used=problem.used.copy(), bone_lengths=problem.bone_lengths(values),
                      scale=problem.scale, information=res.reduced_information, z_keys=z_keys,
                      z_values=zv, plane_key=problem.plane_keys[0], prior_info=info,
                      reprojection_factors=int(problem.reprojection.size()),
                      iterations=sum(s["iterations"] for s in stages),
                      final_error=float(res.final_error), stages=stages, timings=timings,
                      body_height=problem.body_height)


def lm_params(opts: RefineOptions, problem: GraphProblem,
              max_iterations: int | None = None) -> LMParams:
    """:class:`LMParams` from the options; the points' damping scale is the typical
    information of a point seen in two views, ``2 (f / Z)^2 / sigma^2`` (graph units)."""
    K = problem.rig.cameras[0].K
    depth = problem.median_depth
    scale = 2.0 * (K[0, 0] / max(depth, 1e-9)) ** 2 / opts.pixel_sigma ** 2
    return LMParams(max_iterations=opts.max_iterations if max_iterations is None
                    else max_iterations, relative_tolerance=opts.relative_tolerance,
                    global_step_tolerance=opts.global_step_tolerance, local_scale=scale)


def warm_start(problem: GraphProblem, values: gtsam.Values, opts: RefineOptions,
               progress: Progress | None = None) -> LMResult:
    """Levenberg-Marquardt on the reprojection terms alone, the distance held at its value."""
    _, d = extract_planes(problem, values)[0]
    red = mirror_reduction(problem, with_lengths=False, distance_gauge=d)
    lm = LevenbergMarquardt(problem.reprojection, red,
                            lm_params(opts, problem, opts.warm_start_iterations),
                            ordering=problem.point_ordering(), guard=cheirality_guard(problem))
    return lm.optimize(values, progress)


def full_solve(problem: GraphProblem, values: gtsam.Values, opts: RefineOptions,
               progress: Progress | None = None, max_iterations: int | None = None
               ) -> tuple[LMResult, list[tuple[int, int]]]:
    """Levenberg-Marquardt on the whole graph; returns the result and the reduced keys."""
    red = mirror_reduction(problem, with_lengths=True, distance_gauge=problem.distance_gauge)
    lm = LevenbergMarquardt(problem.full(), red, lm_params(opts, problem, max_iterations),
                            ordering=problem.point_ordering(), guard=cheirality_guard(problem))
    return lm.optimize(values, progress), red.z_keys


def solve_single(rig: Rig, used: np.ndarray, d0: float, opts: RefineOptions,
                 progress: Progress | None = None) -> SolveState:
    """Warm start, first rejection, full solve, second rejection and final solve."""
    timings = {"build": 0.0, "solve": 0.0}
    stages: list[dict] = []
    counter = _Counter(progress)
    n0 = rig.mirrors[0].normal
    planes = [(n0, d0)]

    # 1. warm start: reprojection only, robust kernel, on frames spread over the video
    sub = used & spread_rows(rig.num_frames, opts.warm_start_frames)[:, None]
    t = time.perf_counter()
    points = triangulate_rig(rig, sub, planes)
    sub &= in_front(points, n0, d0)
    # without the body priors nothing but the two rays holds a point's depth
    sub &= ~low_parallax(rig, points, sub, planes, opts.warm_start_min_parallax_deg)
    timings["solve"] += time.perf_counter() - t
    if opts.warm_start_iterations > 0 and np.count_nonzero(sub) >= MIN_PAIRS:
        t = time.perf_counter()
        warm = build_problem(rig, points, sub, planes, opts, priors=False)
        timings["build"] += time.perf_counter() - t
        t = time.perf_counter()
        res = warm_start(warm, warm.values, opts, counter)
        planes = extract_planes(warm, res.values)
        stages.append(_stage("warm start (reprojection only, %d frames)"
                             % np.count_nonzero(sub.any(1)), res, np.zeros_like(used)))
        timings["solve"] += time.perf_counter() - t

    # 2. every pair triangulated with the warm mirror; first rejection
    t = time.perf_counter()
    points = triangulate_rig(rig, used, planes)
    used = used & in_front(points, *planes[0])
    keep = used & ~first_outliers(rig, points, used, planes, opts)
    if stages:
        stages[-1]["rejected"] = int(np.count_nonzero(used & ~keep))
    timings["solve"] += time.perf_counter() - t

    # 3. the full graph; if the solve exposes more outliers, once more without them
    found = np.count_nonzero(used & ~keep)
    kernel = opts.final_kernel
    if kernel == "auto":
        kernel = "geman_mcclure" if found > opts.auto_kernel_fraction * used.sum() else None
    problem, values, res = None, None, None
    for name in ("full graph", "final (outliers removed)"):
        if np.count_nonzero(keep) < MIN_PAIRS:
            raise DegenerateGeometryError("too few pairs left after outlier rejection")
        t = time.perf_counter()
        problem = _build_full(rig, problem, values, points, keep, planes, opts, kernel)
        timings["build"] += time.perf_counter() - t
        t = time.perf_counter()
        cap = opts.outlier_pass_iterations if (res is None and found) else None
        res, z_keys = full_solve(problem, problem.values, opts, counter, cap)
        values = res.values
        keep = reject_outliers(problem, values, opts) & ~undetermined(problem, res)
        rejected = problem.used & ~keep
        stages.append(_stage(name, res, rejected))
        stages[-1]["kernel"] = kernel
        timings["solve"] += time.perf_counter() - t
        if not rejected.any():
            break
    state = state_from_problem(problem, values, res, z_keys, stages, timings)
    smooth_joints(problem, values, opts, state)
    return state


#: Gauss-Newton steps of the joints pass (:func:`smooth_joints`).
JOINTS_PASS_ITERATIONS = 1


def joints_pass(problem: GraphProblem, values: gtsam.Values, opts: RefineOptions
                ) -> LMResult | None:
    """The 3D joints solved again with the mirror and the bone lengths held and the
    smoothness of ``opts.joints_smoothness_sigma``, from ``values``.

    Returns:
        The solve (``None``: skipped, without smoothness or when that sigma is not
        tighter than the calibration's).
    """
    sigma = opts.joints_smoothness_sigma
    if not opts.use_smoothness or sigma is None or sigma >= opts.smoothness_sigma:
        return None
    # the calibration's smoothness stays; factors of sigma_x are added so that the two
    # together weigh as one of ``sigma``: 1 / sigma^2 = 1 / sigma_c^2 + 1 / sigma_x^2
    sigma_x = 1.0 / np.sqrt(1.0 / sigma ** 2 - 1.0 / opts.smoothness_sigma ** 2)
    graph = problem.full()
    graph.push_back(smoothness_graph(problem, values, problem.body_height * sigma_x,
                                     opts.smoothness_max_gap))
    red = mirror_reduction(problem, with_lengths=True, distance_gauge=problem.distance_gauge)
    # the smoothness is linear in the points and the points start at the calibration's
    # solution: one Gauss-Newton step lands within ~1 mm of the converged joints (error
    # 15156.7 vs 15155.9 converged on a 1000-frame protocol scene)
    lm = LevenbergMarquardt(graph, red, lm_params(opts, problem, JOINTS_PASS_ITERATIONS),
                            ordering=problem.point_ordering(), hold_globals=True,
                            guard=cheirality_guard(problem))
    return lm.optimize(values)


def smooth_joints(problem: GraphProblem, values: gtsam.Values, opts: RefineOptions,
                  state: "SolveState") -> None:
    """The joints pass (:func:`joints_pass`) on ``state``, in place.

    ``state.final_error`` stays the calibration graph's error.
    """
    t = time.perf_counter()
    res = joints_pass(problem, values, opts)
    if res is None:
        return
    sigma = opts.joints_smoothness_sigma
    state.points = extract_points(problem, res.values)
    state.stages.append(_stage("joints pass (mirror held, smoothness %g h)" % sigma, res,
                               np.zeros_like(problem.used)))
    state.iterations += res.iterations
    state.timings["solve"] += time.perf_counter() - t


def spread_rows(T: int, count: int) -> np.ndarray:
    """``(T,)`` bool: ``count`` frame rows spread evenly over ``T`` (all if ``T <= count``)."""
    mask = np.zeros(T, dtype=bool)
    if count <= 0 or T <= count:
        mask[:] = count > 0 or T == 0
        return mask
    mask[np.unique(np.linspace(0, T - 1, count).round().astype(int))] = True
    return mask


def triangulate_rig(rig: Rig, used: np.ndarray, planes: list[tuple[np.ndarray, float]]
                    ) -> np.ndarray:
    """``(T, J, 3)`` points triangulated from the direct and the mirror view (NaN elsewhere).

    MirrorCalib's rig: the first camera (at the world origin) and the first mirror.
    """
    direct = next(v for v in rig.views if v.mirror is None)
    mirror = next(v for v in rig.views if v.mirror is not None)
    n, d = planes[rig.mirror_index(mirror.mirror)]
    K = rig.camera(direct.camera).K
    out = np.full(used.shape + (3,), np.nan)
    out[used] = triangulate_mirror(K, n, d, np.asarray(direct.pixels)[used],
                                   np.asarray(mirror.pixels)[used])
    return out


def undetermined(problem: GraphProblem, res: LMResult) -> np.ndarray:
    """``(T, J)`` bool: the points GTSAM found (nearly) undetermined during ``res``
    (:attr:`~.optimizer.LMResult.indeterminate`); they are dropped with their pairs."""
    T, J = problem.used.shape
    out = np.zeros(T * J, dtype=bool)
    flat = np.array(sorted(res.indeterminate), dtype=np.uint64) - np.uint64(point_keys([0])[0])
    flat = flat[flat < T * J].astype(np.int64)
    out[flat] = True
    return out.reshape(T, J) & problem.used


def low_parallax(rig: Rig, points: np.ndarray, used: np.ndarray,
                 planes: list[tuple[np.ndarray, float]], min_deg: float) -> np.ndarray:
    """``(T, J)`` bool: used pairs whose two rays meet at under ``min_deg`` degrees.

    The angle is between the *lines* of the two rays (from the camera and from its
    virtual camera), so rays pointing the same way and rays pointing opposite ways
    (a joint straight between the camera and the mirror: the usual case, since the
    virtual camera stands behind the mirror) both count as low parallax. A point's
    depth standard deviation grows as ``1 / sin(angle)``.
    """
    direct = next(v for v in rig.views if v.mirror is None)
    mirror = next(v for v in rig.views if v.mirror is not None)
    n, d = planes[rig.mirror_index(mirror.mirror)]
    c = np.asarray(rig.camera(direct.camera).pose, float)[:3, 3]
    cv = c - 2.0 * (np.asarray(n) @ c - d) * np.asarray(n)          # the virtual centre
    X = np.where(used[..., None], np.nan_to_num(points), 1.0)
    a, b = X - c, X - cv
    cos = np.einsum("...i,...i", a, b) / np.maximum(
        np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1), 1e-300)
    return used & (np.abs(cos) > np.cos(np.radians(min_deg)))


def first_outliers(rig: Rig, points: np.ndarray, used: np.ndarray,
                   planes: list[tuple[np.ndarray, float]], opts: RefineOptions) -> np.ndarray:
    """``(T, J)`` bool: pairs failing the reprojection or the bone test, or seen from
    (nearly) one direction by both views (numpy, no graph)."""
    bad = np.zeros_like(used)
    for r in view_residuals(rig, points, used, planes):
        bad |= r > opts.outlier_threshold
    bad |= low_parallax(rig, points, used, planes, opts.min_parallax_deg)
    if opts.bone_outlier_k > 0:
        _, pairs = bone_table(rig)
        bad |= bone_outliers(points, used, pairs, k=opts.bone_outlier_k)
    return bad & used


def _build_full(rig: Rig, previous: GraphProblem | None, values: gtsam.Values | None,
                points: np.ndarray, keep: np.ndarray, planes: list[tuple[np.ndarray, float]],
                opts: RefineOptions, kernel: str | None) -> GraphProblem:
    """The full graph on the pairs ``keep``: from the triangulated ``points`` and the warm
    ``planes`` the first time, from the previous solution afterwards."""
    if previous is None:
        lengths, body_height, length_sum = None, None, None
        if opts.subject_height is not None:
            # start exactly on the height gauge: the per-bone medians sum to Winter's
            s = _gauge_scale(rig, points, keep, float(opts.subject_height))
            points = points * s
            planes = [(n, d * s) for n, d in planes]
    else:
        points = extract_points(previous, values)
        planes = extract_planes(previous, values)
        lengths = previous.bone_lengths(values)
        body_height = previous.body_height
        length_sum = None
        if previous.length_key is not None and opts.subject_height is None:
            length_sum = previous.prior_info["length_sum_gauge"]["sum"]
    problem = build_problem(_with_mask(rig, keep), points, keep, planes, opts,
                            body_height=body_height, bone_lengths=lengths,
                            length_sum=length_sum, final_kernel=kernel)
    if opts.subject_height is not None:
        problem.body_height = float(opts.subject_height)
    snap_virtual_poses(problem, problem.values)
    return problem


def _gauge_scale(rig: Rig, points: np.ndarray, used: np.ndarray, height: float) -> float:
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


def reject_outliers(problem: GraphProblem, values: gtsam.Values, opts: RefineOptions
                    ) -> np.ndarray:
    """``(T, J)`` bool: the used pairs that pass both outlier tests (:mod:`.outliers`)."""
    bad = reprojection_outliers(problem, values, opts.outlier_threshold)
    if opts.bone_outlier_k > 0:
        _, pairs = bone_table(problem.rig)
        bad |= bone_outliers(extract_points(problem, values), problem.used, pairs,
                             k=opts.bone_outlier_k)
    return problem.used & ~bad


def plane_covariance(state: SolveState) -> np.ndarray:
    """``(3, 3)`` covariance of the first plane in its tangent space ``(v1, v2, v3)``:
    :class:`gtsam.Marginals` of the reduced Gaussian (points eliminated, virtual
    cameras substituted through the link) at the last linearisation point."""
    marg = reduced_marginals(state.information, state.z_keys, state.z_values)
    return np.asarray(marg.marginalCovariance(state.plane_key))


def finish(rig: Rig, state: SolveState, opts: RefineOptions, t_start: float
           ) -> RefinementResult:
    """Marginals, residuals and the result record."""
    n, d = state.normal, state.distance
    # unit-distance results are reported with d = 1 (a pure change of length unit)
    unit = 1.0 / d if state.scale == "unit_distance" else 1.0
    used = state.used
    res = view_residuals(rig, state.points, used, [(n, d)])
    rms = [float(np.sqrt(np.nanmean(r[used] ** 2))) if used.any() else float("nan") for r in res]
    # the noise the data show: the marginals assume pixel_sigma and are rescaled to it.
    # Measured by the pairs' Sampson distances to the refined mirror (one constraint a
    # pair, free of the body priors, which hold the joints and so inflate the
    # reprojection residuals: by 1.5x with the joints pass)
    view_d, view_m = rig.views[0], rig.views[1]
    e = epipole_from_normal(rig.cameras[0].K, n)
    dist = epipolar_distances(e, view_d.pixels[used], view_m.pixels[used])
    dist = dist[np.isfinite(dist)]
    noise_px = residual_noise_px(float(np.sum(dist ** 2)), len(dist), 2)
    variance_factor = (noise_px / opts.pixel_sigma) ** 2 if np.isfinite(noise_px) else 1.0
    t = time.perf_counter()
    if opts.marginals and state.information is not None:
        cov = plane_covariance(state) * variance_factor
        basis = np.asarray(state.z_values.atOrientedPlane3(state.plane_key).normal().basis())
        normal_cov = normal_cov_from_tangent(basis, cov[:2, :2])
        distance_std = float(np.sqrt(max(cov[2, 2], 0.0)))
        if state.scale == "subject_height":       # the gauge's honest uncertainty, a pure scale
            distance_std = float(np.hypot(distance_std, opts.height_sigma * d))
        else:
            distance_std = 0.0                    # d = 1 by definition
        rot_std = rotation_std_from_normal_cov(normal_cov)
    else:
        normal_cov, distance_std, rot_std = np.full((3, 3), np.nan), float("nan"), float("nan")
    t_marg = time.perf_counter() - t

    priors = {"reprojection": {"sigma": opts.pixel_sigma, "weight": 1.0 / opts.pixel_sigma ** 2,
                               "a_posteriori_sigma_px": noise_px,
                               "covariance_scaled_by": variance_factor,
                               "unit": "px", "kernel": opts.robust_kernel,
                               "kernel_scale_px": opts.kernel_scale_px,
                               "final_kernel": opts.final_kernel,
                               "final_kernel_scale_px": opts.final_kernel_scale_px,
                               "outlier_threshold_px": opts.outlier_threshold,
                               "factors": state.reprojection_factors}}
    priors.update(state.prior_info)
    timings = dict(state.timings)
    timings["marginals"] = t_marg
    timings["total"] = time.perf_counter() - t_start
    return RefinementResult(
        normal=np.asarray(n, dtype=float), distance=float(d * unit), scale=state.scale,
        joints3d=state.points * unit, valid=used.copy(), inliers=used.copy(),
        bone_lengths={b: v * unit for b, v in state.bone_lengths.items()},
        normal_cov=normal_cov, rotation_std_deg=rot_std, distance_std=distance_std,
        rms_direct_px=rms[0], rms_mirror_px=rms[1], iterations=state.iterations,
        final_error=float(state.final_error), priors=priors, timings=timings,
        stages=state.stages)


# --------------------------------------------------------------------------- helpers
class _Counter:
    """Counts iterations over stages and forwards them to the user's callback."""

    def __init__(self, progress: Progress | None) -> None:
        self.progress, self.count = progress, 0

    def __call__(self, iteration: int, error: float) -> None:
        self.count += 1
        if self.progress is not None:
            self.progress(self.count, error)


def _stage(name: str, res: LMResult, rejected: np.ndarray) -> dict:
    return {"name": name, "iterations": res.iterations, "initial_error": res.initial_error,
            "final_error": res.final_error, "converged": res.converged,
            "rejected": int(np.count_nonzero(rejected)), "failed_steps": res.rejected_steps,
            "guarded": res.guarded, "indeterminate": len(res.indeterminate)}


def _with_mask(rig: Rig, mask: np.ndarray) -> Rig:
    from dataclasses import replace
    views = tuple(replace(v, mask=np.asarray(v.mask, dtype=bool) & mask) for v in rig.views)
    return replace(rig, views=views)
