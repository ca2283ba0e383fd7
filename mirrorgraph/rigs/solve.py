"""Refine a whole rig in one factor graph: all joints, all camera poses, all mirror planes.

The graph is :mod:`mirrorgraph.graph`'s, with the rig's cameras (every camera
but the first has a :class:`gtsam.Pose3` variable), its mirrors (one
:class:`gtsam.OrientedPlane3` each; every mirror view's virtual camera is tied
to its camera and plane exactly, :mod:`mirrorgraph.graph.reduction`), robust
reprojection in every view, the body priors and the subject-height gauge. The
world frame is the first camera's (its pose fixed: 6 of the 7 gauge freedoms),
the scale is the subject's height (the seventh).

Stages:

1. triangulate every joint seen twice with the initial rig (observations behind
   their camera dropped);
2. scale everything so that the median bone lengths sum to Winter's lengths
   for the subject's height (the gauge's value);
3. three solves (:func:`mirrorgraph.graph.refine.full_solve`, Python-driven
   Levenberg-Marquardt), each from the previous solution: Geman-McClure with a
   kernel :data:`INITIAL_REJECTION_FACTOR` times the final one, then drop the
   observations beyond that many outlier thresholds and the joints whose bones
   are all implausible; Geman-McClure at ``options.final_kernel_scale_px``, then
   drop the observations beyond ``options.outlier_threshold``; least squares on
   what is left. Rejection is per *observation*: a wrong keypoint in one camera
   does not cost the other views;
4. marginals: the reduced information of the last undamped solve is the Schur
   complement of every joint on (camera poses, bone lengths, planes); GTSAM's
   :class:`gtsam.Marginals` of it gives each camera's 6x6 and each plane's 3x3
   covariance.

Videos longer than ``options.max_graph_frames`` frames are calibrated on that
many frames spread over the video (the joints of the other frames are
triangulated with the result).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import gtsam
import numpy as np

from ..errors import DegenerateGeometryError
from ..graph.builder import (GraphProblem, build_problem, bone_table, extract_camera_poses,
                             extract_planes, extract_points, snap_virtual_poses, view_residuals)
from ..graph.optimizer import reduced_marginals
from ..graph.options import RefineOptions
from ..graph.outliers import bone_outliers
from ..graph.refine import MIN_PAIRS, _gauge_scale, full_solve, spread_rows, undetermined
from ..graph.result import (normal_cov_from_tangent, residual_noise_px,
                            rotation_std_from_normal_cov)
from ..graph.rig import Camera, Mirror, Rig, View
from .initial import InitialRig, joint_masks, observed
from .observations import RigObservations
from .triangulation import camera_projection, mirror_projection, triangulate_views

__all__ = ["RigSolution", "build_rig", "triangulate_rig_views", "solve_rig",
           "INITIAL_REJECTION_FACTOR"]

#: The first solve's robust kernel is this many times wider than the final one, and
#: only observations beyond this many outlier thresholds are dropped after it. The
#: chained pairwise initialisation can be degrees and decimetres off (residuals of
#: 50-150 px on a 120-frame four-camera rig), which that solve removes; a kernel
#: or a rejection at the final scale would then discard good keypoints.
INITIAL_REJECTION_FACTOR = 5.0


@dataclass
class RigSolution:
    """The refined rig (graph units = metres with a subject height, else heights).

    Attributes:
        poses: ``(4, 4)`` camera-to-world pose per camera.
        planes: ``(n, d)`` per mirror of the rig, world frame.
        mirror_names: names of ``planes``.
        camera_cov: per camera ``(6, 6)`` covariance of its pose in GTSAM's tangent
            ``(rotation rad, translation in the camera frame)``; zeros for the first
            camera (the fixed world frame); NaN when not computed.
        plane_cov: per mirror ``(3, 3)`` tangent covariance ``(v1, v2, d)``.
        plane_basis: per mirror the ``(3, 2)`` tangent basis of the normal.
        points: ``(T, J, 3)`` joints; used: ``(T, J)``.
        view_names, view_rms_px: reprojection RMS per view, pixels.
        view_counts: observations used per view.
        view_observed: observations each view offered the graph (seen, on the graph's
            frames), before any rejection.
        bone_lengths: bone -> length.
        rejected: observations dropped as outliers, all views.
        iterations: Levenberg-Marquardt solves.
        priors: prior name -> description (as the single-mirror result).
        timings: seconds per stage.
    """

    poses: list[np.ndarray]
    planes: list[tuple[np.ndarray, float]]
    mirror_names: list[str]
    camera_cov: list[np.ndarray]
    plane_cov: list[np.ndarray]
    plane_basis: list[np.ndarray]
    points: np.ndarray
    used: np.ndarray
    view_names: list[str]
    view_rms_px: list[float]
    view_counts: list[int]
    view_observed: list[int]
    bone_lengths: dict[str, float]
    rejected: int
    iterations: int
    priors: dict
    timings: dict

    def scaled(self, factor: float) -> "RigSolution":
        """The same solution with every length multiplied by ``factor`` (> 0).

        Reprojections, the body priors (ratios, and lengths relative to the
        body) and the marginals' rotations do not change with the scale, so this
        is the solution the graph would have reached under a gauge ``factor``
        times larger: camera centres, plane distances, joints, bone lengths and
        the length parts of the covariances scale, nothing else.
        """
        f = float(factor)
        poses = []
        for P in self.poses:
            Q = np.array(P, dtype=float)
            Q[:3, 3] *= f
            poses.append(Q)
        unit = np.diag([1.0, 1.0, 1.0, f, f, f])
        camera_cov = [unit @ C @ unit for C in self.camera_cov]
        d_unit = np.diag([1.0, 1.0, f])
        plane_cov = [d_unit @ C @ d_unit for C in self.plane_cov]
        return replace(self, poses=poses, planes=[(np.asarray(n), float(d) * f) for n, d in self.planes],
                       camera_cov=camera_cov, plane_cov=plane_cov, points=self.points * f,
                       bone_lengths={b: v * f for b, v in self.bone_lengths.items()})


def build_rig(obs: RigObservations, init: InitialRig,
              joints: tuple[np.ndarray, np.ndarray] | None = None) -> Rig:
    """The graph's :class:`~mirrorgraph.graph.rig.Rig`: cameras (all but the first
    estimated), the mirrors that were placed, one direct view per camera and one
    view per camera and mirror. ``joints`` = ``(direct, mirror)`` joint indices that
    the direct views and the views through mirrors use
    (:func:`~mirrorgraph.rigs.config.resolve_joints`; default: the calibration joints)."""
    dmask, mmask = joint_masks(obs.skeleton, joints)
    cams = tuple(Camera(c.name, c.intrinsics.K, np.asarray(p, float), estimate_pose=i > 0)
                 for i, (c, p) in enumerate(zip(obs.cameras, init.poses)))
    mirrors = tuple(Mirror(m, *init.planes[m]) for m in obs.mirrors if m in init.planes)
    placed = {m.name for m in mirrors}
    views = []
    for c in obs.cameras:
        views.append(View(c.name, c.name, None, c.real[..., :2].copy(),
                          observed(c.real, dmask)))
        for m, refl in c.reflections.items():
            if m in placed:
                views.append(View(f"{c.name}/{m}", c.name, m, refl[..., :2].copy(),
                                  observed(refl, mmask)))
    return Rig(cameras=cams, mirrors=mirrors, views=tuple(views), skeleton=obs.skeleton,
               frame_ids=np.asarray(obs.frame_ids, dtype=np.int64),
               joints=np.flatnonzero(dmask | mmask))


def _projections(rig: Rig, poses: list[np.ndarray], planes: list[tuple[np.ndarray, float]]
                 ) -> list[np.ndarray]:
    out = []
    for v in rig.views:
        ci = rig.camera_index(v.camera)
        K = rig.cameras[ci].K
        if v.mirror is None:
            out.append(camera_projection(K, poses[ci]))
        else:
            out.append(mirror_projection(K, poses[ci], *planes[rig.mirror_index(v.mirror)]))
    return out


def triangulate_rig_views(rig: Rig, poses: list[np.ndarray],
                          planes: list[tuple[np.ndarray, float]],
                          rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(T, J, 3)`` joints (world frame) and ``(T, J)`` mask, triangulated from every
    view that observes them (:attr:`View.mask`), estimated joints only."""
    jmask = np.zeros(rig.skeleton.num_joints, dtype=bool)
    jmask[rig.joints] = True
    masks = [np.asarray(v.mask, bool) & jmask[None, :] for v in rig.views]
    if rows is not None:
        masks = [m & rows[:, None] for m in masks]
    return triangulate_views(_projections(rig, poses, planes),
                             [v.pixels for v in rig.views], masks)


#: An estimated camera or a mirror needs at least this many keypoints left in its
#: views after outlier rejection (a pose has 6 unknowns, a plane 3).
MIN_HELD_OBSERVATIONS = 30


def _check_held(rig: Rig, masks: list[np.ndarray], offered: list[int]) -> None:
    """Raise when an estimated camera or a mirror has (almost) no keypoints left.

    Args:
        rig: the graph's rig; masks: per view, the observations kept; offered: per
            view, the observations it had before any rejection.

    Raises:
        DegenerateGeometryError: naming the camera or mirror, with the counts.
    """
    kept = np.array([int(np.count_nonzero(m)) for m in masks])
    had = np.asarray(offered)
    groups = [(f"camera {c.name}", [i for i, v in enumerate(rig.views) if v.camera == c.name])
              for c in rig.cameras if c.estimate_pose]
    groups += [(f"mirror {m.name}", [i for i, v in enumerate(rig.views) if v.mirror == m.name])
               for m in rig.mirrors]
    for what, idx in groups:
        if kept[idx].sum() < MIN_HELD_OBSERVATIONS:
            raise DegenerateGeometryError(
                f"{what}: {kept[idx].sum()} of its {had[idx].sum()} keypoints fit the rest of "
                f"the rig (need {MIN_HELD_OBSERVATIONS}): is it the same person as in the "
                "other cameras? the right intrinsics, frame offset, mirror?")


def _with_masks(rig: Rig, masks: list[np.ndarray]) -> Rig:
    return replace(rig, views=tuple(replace(v, mask=m) for v, m in zip(rig.views, masks)))


def _with_poses(rig: Rig, poses: list[np.ndarray], planes) -> Rig:
    cams = tuple(replace(c, pose=np.asarray(p, float)) for c, p in zip(rig.cameras, poses))
    mirrors = tuple(replace(m, normal=np.asarray(n, float), distance=float(d))
                    for m, (n, d) in zip(rig.mirrors, planes))
    return replace(rig, cameras=cams, mirrors=mirrors)


def _depth_ok(rig: Rig, points: np.ndarray, used: np.ndarray, poses, planes) -> list[np.ndarray]:
    """Per view: the observed point lies in front of the (real or virtual) camera."""
    out = []
    for v, P in zip(rig.views, _projections(rig, poses, planes)):
        with np.errstate(invalid="ignore"):
            w = np.einsum("ij,tkj->tki", P[2:3, :3], np.nan_to_num(points))[..., 0] + P[2, 3]
        out.append(~(used & (w <= 0)))
    return out


def _reject(rig: Rig, points, used, poses, planes, threshold: float
            ) -> tuple[list[np.ndarray], int]:
    """View masks without the observations beyond ``threshold`` px or behind their camera."""
    res = view_residuals(rig, points, used, planes, poses)
    depth = _depth_ok(rig, points, used, poses, planes)
    masks, dropped = [], 0
    for v, r, ok in zip(rig.views, res, depth):
        bad = used & ((np.nan_to_num(r, nan=0.0) > threshold) | ~ok) & np.asarray(v.mask, bool)
        dropped += int(np.count_nonzero(bad))
        masks.append(np.asarray(v.mask, bool) & ~bad)
    return masks, dropped


def _marginals(problem: GraphProblem, values: gtsam.Values, info: np.ndarray | None,
               z_keys) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    rig = problem.rig
    nan6, nan3 = np.full((6, 6), np.nan), np.full((3, 3), np.nan)
    basis = [np.asarray(values.atOrientedPlane3(k).normal().basis()) for k in problem.plane_keys]
    if info is None:
        return ([np.zeros((6, 6)) if i == 0 else nan6 for i in range(len(rig.cameras))],
                [nan3] * len(problem.plane_keys), basis)
    zv = gtsam.Values()
    for k, _ in z_keys:
        if k in problem.plane_keys:
            zv.insert(k, values.atOrientedPlane3(k))
        elif k == problem.length_key:
            zv.insert(k, values.atVector(k))
        else:
            zv.insert(k, values.atPose3(k))
    marg = reduced_marginals(info, z_keys, zv)
    cams = []
    for i in range(len(rig.cameras)):
        k = problem.camera_keys.get(i)
        cams.append(np.zeros((6, 6)) if k is None else np.asarray(marg.marginalCovariance(k)))
    planes = [np.asarray(marg.marginalCovariance(k)) for k in problem.plane_keys]
    return cams, planes, basis


def solve_rig(rig: Rig, options: RefineOptions, height: float,
              progress=None) -> RigSolution:
    """Run the stages of the module docstring on ``rig`` (initial poses and planes inside).

    Args:
        rig: cameras (initial poses), mirrors (initial planes), views.
        options: weights and solver settings (``subject_height`` is ignored: the
            gauge is ``height``).
        height: the subject's height in the output unit.
        progress: ``progress(iteration, error)`` per accepted step.

    Raises:
        DegenerateGeometryError: too few joints seen twice.
    """
    timings = {"triangulate": 0.0, "build": 0.0, "solve": 0.0, "marginals": 0.0}
    opts = replace(options, subject_height=float(height))
    t0 = time.perf_counter()
    T = rig.num_frames
    rows = spread_rows(T, opts.max_graph_frames)
    poses = [np.asarray(c.pose, float) for c in rig.cameras]
    planes = [(np.asarray(m.normal, float), float(m.distance)) for m in rig.mirrors]
    sub = rig.subset(rows)
    observed_counts = [int(np.count_nonzero(v.mask)) for v in sub.views]

    # 1. triangulate; only observations behind their (real or virtual) camera go
    points, used = triangulate_rig_views(sub, poses, planes)
    masks, rejected = _reject(sub, points, used, poses, planes, np.inf)
    _check_held(sub, masks, observed_counts)
    sub = _with_masks(sub, masks)
    points, used = triangulate_rig_views(sub, poses, planes)
    if np.count_nonzero(used) < MIN_PAIRS:
        raise DegenerateGeometryError(
            f"only {np.count_nonzero(used)} joints are seen in two views (need {MIN_PAIRS})")
    # 2. start on the gauge
    s = _gauge_scale(sub, points, used, float(height))
    points = points * s
    planes = [(n, d * s) for n, d in planes]
    for p in poses:
        p[:3, 3] *= s
    sub = _with_poses(sub, poses, planes)
    timings["triangulate"] += time.perf_counter() - t0

    # 3. robust solves with a shrinking kernel, then least squares on the inliers
    wide = INITIAL_REJECTION_FACTOR * opts.outlier_threshold
    stages = [("geman_mcclure", INITIAL_REJECTION_FACTOR * opts.final_kernel_scale_px, wide),
              ("geman_mcclure", opts.final_kernel_scale_px, opts.outlier_threshold),
              (None, opts.final_kernel_scale_px, opts.outlier_threshold)]
    problem, values, res, z_keys, iterations, lengths = None, None, None, None, 0, None
    for i, (kernel, kernel_scale, threshold) in enumerate(stages):
        t = time.perf_counter()
        stage_opts = replace(opts, final_kernel_scale_px=kernel_scale)
        problem = build_problem(sub, points, used, planes, stage_opts, body_height=float(height),
                                bone_lengths=lengths, final_kernel=kernel)
        if problem.used.sum() < MIN_PAIRS:
            raise DegenerateGeometryError(
                f"only {int(problem.used.sum())} joints left in two views after outlier "
                f"rejection (need {MIN_PAIRS})")
        snap_virtual_poses(problem, problem.values)
        timings["build"] += time.perf_counter() - t
        t = time.perf_counter()
        res, z_keys = full_solve(problem, problem.values, stage_opts, progress)
        iterations += res.iterations
        values = res.values
        points = extract_points(problem, values)
        planes = extract_planes(problem, values)
        poses = extract_camera_poses(problem, values)
        lengths = problem.bone_lengths(values)
        used = problem.used & ~undetermined(problem, res)
        if i < len(stages) - 1:
            masks, dropped = _reject(problem.rig, points, used, poses, planes, threshold)
            _check_held(problem.rig, masks, observed_counts)
            rejected += dropped
            if i == 0 and opts.bone_outlier_k > 0:
                _, pairs = bone_table(problem.rig)
                bad = bone_outliers(points, used, pairs, k=opts.bone_outlier_k)
                rejected += int(np.count_nonzero(bad))
                used &= ~bad
            sub = _with_poses(_with_masks(problem.rig, masks), poses, planes)
        timings["solve"] += time.perf_counter() - t
    t = time.perf_counter()
    cam_cov, plane_cov, basis = (_marginals(problem, values, res.reduced_information, z_keys)
                                 if opts.marginals else
                                 ([np.full((6, 6), np.nan)] * len(poses),
                                  [np.full((3, 3), np.nan)] * len(planes), []))
    timings["marginals"] = time.perf_counter() - t
    res_views = view_residuals(problem.rig, points, problem.used, planes, poses)
    # the noise the data show (the marginals assume pixel_sigma): the final least-squares
    # residuals over their degrees of freedom (3 a joint, 6 a camera, 3 a plane)
    finite = np.concatenate([r[np.isfinite(r)] for r in res_views])
    unknowns = (3 * int(np.count_nonzero(problem.used)) + 6 * len(problem.camera_keys)
                + 3 * len(planes))
    noise_px = residual_noise_px(float(np.sum(finite ** 2)), 2 * len(finite), unknowns)
    factor = (noise_px / opts.pixel_sigma) ** 2 if np.isfinite(noise_px) else 1.0
    cam_cov = [C * factor for C in cam_cov]
    plane_cov = [C * factor for C in plane_cov]

    # every frame: triangulate with the final rig (the graph's joints where it has them)
    all_points, all_used = triangulate_rig_views(rig, poses, planes)
    all_points[np.flatnonzero(rows)] = np.where(problem.used[..., None], points,
                                                all_points[rows])
    all_used[np.flatnonzero(rows)] |= problem.used
    rms = [float(np.sqrt(np.nanmean(r[np.isfinite(r)] ** 2))) if np.isfinite(r).any()
           else float("nan") for r in res_views]
    counts = [int(np.count_nonzero(np.isfinite(r))) for r in res_views]
    priors = {"reprojection": {"sigma": opts.pixel_sigma, "unit": "px",
                               "a_posteriori_sigma_px": noise_px,
                               "covariance_scaled_by": factor,
                               "kernel": "geman_mcclure then none",
                               "outlier_threshold_px": opts.outlier_threshold,
                               "factors": int(problem.reprojection.size())}}
    priors.update(problem.prior_info)
    timings["total"] = time.perf_counter() - t0
    return RigSolution(poses=poses, planes=planes, mirror_names=[m.name for m in rig.mirrors],
                       camera_cov=cam_cov, plane_cov=plane_cov, plane_basis=basis,
                       points=all_points, used=all_used, view_names=[v.name for v in rig.views],
                       view_rms_px=rms, view_counts=counts,
                       view_observed=observed_counts, bone_lengths=lengths or {},
                       rejected=rejected, iterations=iterations, priors=priors, timings=timings)


def camera_std(cov: np.ndarray, pose: np.ndarray) -> tuple[float, float]:
    """RMS rotation error (deg) and position error (length unit) of a camera from its
    ``(6, 6)`` tangent covariance (rotation, then translation in the camera frame)."""
    rot = float(np.degrees(np.sqrt(max(np.trace(cov[:3, :3]), 0.0))))
    R = np.asarray(pose, float)[:3, :3]
    pos = float(np.sqrt(max(np.trace(R @ cov[3:, 3:] @ R.T), 0.0)))
    return rot, pos


def plane_std(cov: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Normal covariance ``(3, 3)``, virtual-camera rotation RMS (deg), distance std."""
    ncov = normal_cov_from_tangent(basis, cov[:2, :2])
    return ncov, rotation_std_from_normal_cov(ncov), float(np.sqrt(max(cov[2, 2], 0.0)))
