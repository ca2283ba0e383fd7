"""The graph's front ends: a rig built from a front end's observations, solved by the one
driver, its solution read back with its uncertainty.

One driver solves every rig (:func:`mirrorgraph.graph.solve.solve`); what differs is
what goes in and what comes out, and the configuration that says what varies
(:mod:`mirrorgraph.graph.stage_config`).

**One mirror** (MirrorCalib's setting: the rig of one camera, the world frame, held, and
one mirror): :func:`refine_mirror` validates the pairs, builds that rig
(:func:`~mirrorgraph.graph.rig.single_mirror_rig`) with the initial distance (1, or
metres from the median bone lengths when the subject's height is known), and solves it
with :func:`~mirrorgraph.graph.stage_config.single_mirror_config`: the first rejection
at once (the RANSAC mirror is good to a pixel), a warm start on the reprojection alone,
the full graph with the kernel the rejection calls for, a second solve if that exposed
more outliers, the joints pass, the marginals. The plane's 3x3 tangent covariance
becomes the unit normal's (:mod:`mirrorgraph.graph.result`); with a subject height
everything is rescaled so that the stature measured on the joints equals the height
(:mod:`.scale`).

**A rig** (:func:`build_rig`, :func:`solve_rig`): every camera but the first has a
:class:`gtsam.Pose3` variable, every mirror an :class:`gtsam.OrientedPlane3` (each
mirror view's virtual camera tied to its camera and plane exactly,
:mod:`mirrorgraph.graph.reduction`); the world frame is the first camera's, the scale
the subject's height. :func:`~mirrorgraph.graph.stage_config.rig_config` says what
differs from a single mirror: a chained pairwise initialisation can be degrees off, so
no rejection before the first solve, a kernel
:data:`~mirrorgraph.graph.stage_config.INITIAL_REJECTION_FACTOR` times wider first, then
the final kernel, then least squares on the inliers; the rejection per observation.
Videos longer than ``options.max_graph_frames`` frames are calibrated on that many
frames spread over the video (the joints of the other frames are triangulated with the
result).

Both read the reprojection's record the same way (:func:`reprojection_record`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from ..errors import DegenerateGeometryError, InputError
from ..graph.bones import body_height_from_points
from ..graph.options import FocalOptions, RefineOptions
from ..graph.outliers import feasible
from ..graph.result import RefinementResult, normal_cov_from_tangent, rotation_std_from_normal_cov
from ..graph.rig import (Camera, Mirror, Rig, View, single_mirror_rig, spread_rows, triangulate_rig,
                         view_residuals, with_intrinsics)
from ..graph.sensitivity import rig_sensitivity_report, sensitivity_report
from ..graph.solve import solve
from ..graph.solve_graph import Progress
from ..graph.solve_state import SolveState
from ..graph.stage_config import INITIAL_REJECTION_FACTOR, rig_config, single_mirror_config
from .. import geometry as geo
from ..graph.joints_uncertainty import graph_joints_covariance, view_projections
from ..graph.uncertainty import robust_blocks, robust_normal_cov
from ..keypoints import MIN_PAIRS, PairedKeypoints
from ..stature import keypoint_offset_fraction, measurement_rel_std, with_height_sigma
from .scale import scale_by_stature

if TYPE_CHECKING:         # a single mirror's run needs neither (they import SciPy and OpenCV)
    from ..initial.rig import InitialRig
    from ..rigs.observations import RigObservations

__all__ = ["refine_mirror", "RefineOptions", "RefinementResult", "rotation_std_from_normal_cov",
           "MIN_PAIRS", "RigSolution", "build_rig", "triangulate_rig_views", "solve_rig",
           "INITIAL_REJECTION_FACTOR", "reprojection_record", "solve_config"]



def reprojection_record(state: SolveState, opts: RefineOptions, **kernel) -> dict:
    """The ``priors`` record of a solve, one mirror's or a rig's: the reprojection term
    (its sigma and weight, the noise the data show and the factor that scaled the
    covariances, the outlier threshold and parallax, the joints dropped as
    undetermined, the factor count, and ``kernel``'s entries: the kernels as the front
    end describes them) and every prior the graph held (``state.prior_info``)."""
    rep = {"sigma": opts.pixel_sigma, "weight": 1.0 / opts.pixel_sigma ** 2, "unit": "px",
           "a_posteriori_sigma_px": state.noise_px,
           "covariance_scaled_by": state.variance_factor, **kernel,
           "outlier_threshold_px": opts.outlier_threshold,
           "min_parallax_deg": opts.min_parallax_deg,
           "undetermined_dropped": state.undetermined, "factors": state.reprojection_factors}
    return {"reprojection": rep, **state.prior_info}


# --------------------------------------------------------------------------- entry point
def refine_mirror(paired: PairedKeypoints, K: np.ndarray, normal0: np.ndarray,
                  inliers: np.ndarray, *, joints: np.ndarray | None = None,
                  options: RefineOptions | None = None,
                  progress: Progress | None = None,
                  estimate_focal: bool = False,
                  focal_rel_sigma: float | None = None) -> RefinementResult:
    """Jointly refine the mirror plane and every 3D joint in one GTSAM factor graph.

    Args:
        paired: person and reflection keypoints (undistorted pixels, mirror labels flipped).
        K: ``(3, 3)`` camera intrinsics.
        normal0: ``(3,)`` initial mirror normal (camera frame, away from the camera).
        inliers: ``(T, J)`` bool, the pairs the initialisation kept.
        joints: ``(k,)`` joint indices to use; default ``skeleton.calibration_joints``.
        options: weights, kernel, gauge, solver settings.
        progress: ``progress(iteration, error)`` after every accepted step (iterations
            count over all stages; within a stage the error never rises).
        estimate_focal: ``K`` is a guess (square pixels, no skew): the focal length and
            the principal point are variables of the graph, each with a prior about the
            guess (:func:`guessed_camera`, :class:`~.options.FocalOptions`); the focal
            length starts from a search. The estimate is kept where the data do not
            determine it too, with its large std (``RefinementResult.focal``).
        focal_rel_sigma: the focal length's prior about the guess, relative
            (default ``options.focal.prior_rel_sigma``; a user's field-of-view guess:
            ``options.focal.guess_rel_sigma``).

    Returns:
        :class:`RefinementResult`.

    Raises:
        InputError: shapes that do not match.
        DegenerateGeometryError: fewer than :data:`MIN_PAIRS` usable pairs.
    """
    t_start = time.perf_counter()
    opts = options or RefineOptions()
    rig = prepare(paired, K, normal0, inliers, joints, opts, estimate_focal=estimate_focal,
                  focal_rel_sigma=focal_rel_sigma)
    state = solve(rig, opts, single_mirror_config(opts), height=opts.subject_height,
                  progress=progress)
    guess = rig.cameras[0]
    rig = with_intrinsics(rig, state.intrinsics)
    res = finish(rig, state, opts, t_start)
    if estimate_focal:
        res.focal = focal_record(state, guess, options=opts)
    res = with_joints_cov(res, state, opts, single_mirror_config(opts).joints_pass, rig)
    if res.scale == "subject_height":
        offset = keypoint_offset_fraction(opts.keypoint_offset, opts.subject_height)
        res = scale_by_stature(res, paired, res.intrinsics, float(opts.subject_height),
                               opts.scale_from, offset, opts.height_sigma)
        # the scale's relative std: the height's prior and the measurement's own, the
        # stature's or the limbs' (mirrorgraph.stature.measurement_rel_std), as the
        # distance's std holds it
        res = replace(res, scale_rel_std=float(np.hypot(
            opts.height_sigma, measurement_rel_std(res.stature, opts.scale_from, offset))))
    return res


def with_joints_cov(res: RefinementResult, state: SolveState, opts: RefineOptions,
                    joints_pass: bool, rig: Rig | None = None) -> RefinementResult:
    """``res`` with each joint's covariance (:func:`~mirrorgraph.graph.joints_uncertainty.
    graph_joints_covariance`, the globals at the headline's ratio to their marginal std)
    and the plane's tangent covariance, in ``res``'s unit; unchanged without marginals."""
    if not (opts.marginals and opts.joints_uncertainty):
        return res
    t = time.perf_counter()
    inflation = float(res.uncertainty_parts.get("ratio_to_marginal", 1.0))
    if not np.isfinite(inflation) or inflation <= 0:
        inflation = 1.0
    unit = res.distance / float(state.planes[0][1])
    cov = graph_joints_covariance(state, opts, joints_pass=joints_pass, inflation=inflation,
                                  rig=rig)
    plane = np.array(state.plane_cov[0], float) * inflation ** 2
    if state.plane_spread:
        plane = plane + state.plane_spread[0]
    plane[2, :] *= unit
    plane[:, 2] *= unit
    timings = dict(res.timings, joints_uncertainty=time.perf_counter() - t)
    return replace(res, joints_cov=cov * unit ** 2, plane_cov=plane, timings=timings)


def focal_record(state: SolveState, guess: Camera, index: int = 0,
                 options: RefineOptions | None = None) -> dict:
    """The ``focal`` record of :class:`RefinementResult` for camera ``index`` of a solve
    whose focal length was estimated (``guess``: the camera as given to the solve);
    ``poorly_determined`` where its relative std exceeds
    ``options.focal.undetermined_rel_std``."""
    options = options or RefineOptions()
    K = np.asarray(state.intrinsics[index], dtype=float)
    f = float(K[0, 0])
    search = [s.get("focal_px") for s in state.stages if "focal_px" in s]
    rec = {"estimated": True, "determined": guess.name not in state.focal_undetermined,
           "focal_px": f,
           "guess_px": float(guess.focal_prior[0]) if guess.focal_prior else float(guess.K[0, 0]),
           "search_px": float(search[0]) if search else None,
           "principal_point": [float(K[0, 2]), float(K[1, 2])],
           "principal_point_estimated": bool(guess.estimate_principal_point)}
    if not rec["determined"]:
        rec["undetermined"] = dict(state.focal_undetermined[guess.name])
    cov = np.asarray(state.intrinsics_cov[index], dtype=float)
    marginal = np.sqrt(np.maximum(np.diag(cov), 0.0)) if cov.size else np.full(1, np.nan)
    robust = (np.asarray(state.intrinsics_std[index], dtype=float)
              if index < len(state.intrinsics_std) and len(state.intrinsics_std[index])
              else marginal)
    std = np.fmax(marginal, robust)
    rec.update(std_px=float(std[0]), marginal_std_px=float(marginal[0]),
               robust_std_px=float(robust[0]), rel_std=float(std[0] / f),
               poorly_determined=bool(std[0] / f > options.focal.undetermined_rel_std))
    if guess.estimate_principal_point and len(std) == 3:
        rec["principal_point_std_px"] = [float(std[1]), float(std[2])]
        if guess.principal_point_prior is not None:
            rec["principal_point_prior_px"] = [float(v) for v in guess.principal_point_prior]
    if guess.focal_prior is not None:
        rec["focal_prior_std_px"] = float(guess.focal_prior[1])
    if index < len(state.intrinsics_data_std) and len(state.intrinsics_data_std[index]):
        rec["data_std_px"] = float(np.asarray(state.intrinsics_data_std[index], float)[0])
    if guess.name in state.focal_bias:
        rec["bias"] = dict(state.focal_bias[guess.name])
    return rec


def focal_rel_std(state: SolveState, index: int = 0) -> float:
    """The headline relative std of camera ``index``'s estimated focal length (the larger
    of its marginal and robust figures, as :func:`focal_record`), 0 where it is held."""
    if index >= len(state.intrinsics_cov) or not np.size(state.intrinsics_cov[index]):
        return 0.0
    f = float(np.asarray(state.intrinsics[index], float)[0, 0])
    marginal = float(np.sqrt(max(np.asarray(state.intrinsics_cov[index], float)[0, 0], 0.0)))
    robust = (float(np.asarray(state.intrinsics_std[index], float)[0])
              if index < len(state.intrinsics_std) and len(state.intrinsics_std[index])
              else marginal)
    std = max(marginal, robust)
    return std / f if np.isfinite(std) and f > 0 else 0.0


# --------------------------------------------------------------------------- steps
def prepare(paired: PairedKeypoints, K: np.ndarray, normal0: np.ndarray, inliers: np.ndarray,
            joints: np.ndarray | None, opts: RefineOptions, *,
            estimate_focal: bool = False, focal_rel_sigma: float | None = None) -> Rig:
    """Validate the inputs, select the pairs and set the initial scale.

    Returns:
        The rig of one camera and one mirror: the used pairs (seen in both views,
        inliers, selected joints) as its views' masks, the initial plane with the
        distance 1, or, with a subject height, the distance in metres implied by the
        median bone lengths of pairs triangulated on frames spread over the video.
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
        masks = [v.mask & sample for v in rig.views]
        poses = [c.pose for c in rig.cameras]
        pts, ok = triangulate_rig(rig, masks, poses, [(n0, 1.0)])
        ok &= np.all(feasible(rig, pts, masks, poses, [(n0, 1.0)]), axis=0)   # cheirality
        h = body_height_from_points(rig, pts, ok)
        if np.isfinite(h) and h > 0:
            d0 = float(opts.subject_height) / h
    cam = rig.cameras[0]
    if estimate_focal:      # K is the guess: the start, and the centre of the priors
        cam = guessed_camera(cam, K, opts.focal, focal_rel_sigma)
    return replace(rig, cameras=(cam,), mirrors=(replace(rig.mirrors[0], distance=d0),))


def guessed_camera(camera: Camera, K: np.ndarray, focal: FocalOptions,
                   focal_rel_sigma: float | None = None) -> Camera:
    """A camera whose intrinsics are a guess ``K`` (square pixels, the principal point at
    the image centre): its focal length and principal point variables of the graph, each
    with a prior about the guess (:class:`~.options.FocalOptions`: the focal length at
    ``focal_rel_sigma`` of it, default ``focal.prior_rel_sigma``; the principal point at
    ``focal.principal_point_rel_sigma`` of the image's larger side ``2 max(cx, cy)``, or
    loose with ``focal.principal_point``), so that no reported figure assumes the guess."""
    K = np.asarray(K, dtype=float)
    f0 = float(K[0, 0])
    rel = focal.prior_rel_sigma if focal_rel_sigma is None else float(focal_rel_sigma)
    cx, cy = float(K[0, 2]), float(K[1, 2])
    pp = (None if focal.principal_point
          else (cx, cy, focal.principal_point_rel_sigma * 2.0 * max(cx, cy)))
    return replace(camera, estimate_focal=True, estimate_principal_point=True,
                   focal_prior=(f0, rel * f0), principal_point_prior=pp)


def finish(rig: Rig, state: SolveState, opts: RefineOptions, t_start: float
           ) -> RefinementResult:
    """The result record of one mirror: normal covariance, residuals, priors, timings."""
    n, d = state.planes[0]
    # unit-distance results are reported with d = 1 (a pure change of length unit)
    unit = 1.0 / d if state.scale == "unit_distance" else 1.0
    used = state.used
    res = view_residuals(rig, state.points, used, [(n, d)])
    rms = [float(np.sqrt(np.nanmean(r[used] ** 2))) if used.any() else float("nan") for r in res]
    cov = state.plane_cov[0]
    t_unc = time.perf_counter()
    parts: dict = {}
    sensitivity: dict = {}
    marginal_cov, marginal_std = np.full((3, 3), np.nan), float("nan")
    if opts.marginals and np.all(np.isfinite(cov)):
        basis = state.plane_basis[0]
        marginal_cov = normal_cov_from_tangent(basis, cov[:2, :2])
        marginal_std = rotation_std_from_normal_cov(marginal_cov)
        normal_cov, inflation = marginal_cov, 1.0
        if state.scores is not None:
            normal_cov, parts = robust_normal_cov(state.scores, basis, marginal_cov)
            inflation = parts["ratio_to_marginal"]
            sensitivity = sensitivity_report(state.scores, basis, parts, marginal_std,
                                             rig.skeleton, rig.frame_ids)
        # the marginal, widened as the rotation was, and what the intrinsics' headline
        # spread adds (a focal length the data hardly determine: the distance with it)
        spread = state.plane_spread[0][2, 2] if state.plane_spread else 0.0
        distance_var = max(cov[2, 2], 0.0) * inflation ** 2 + spread
        # with the distance held as the gauge the graph shows no coupling: a person of
        # known size imaged at a fixed size lies at a depth proportional to f
        distance_var = max(distance_var, (d * focal_rel_std(state)) ** 2)
        distance_std = float(np.sqrt(distance_var))
        if state.scale == "subject_height":       # the gauge's honest uncertainty, a pure scale
            distance_std = with_height_sigma(distance_std, d, opts.height_sigma)
        else:
            distance_std = 0.0                    # d = 1 by definition
        rot_std = rotation_std_from_normal_cov(normal_cov)
    else:
        normal_cov, distance_std, rot_std = np.full((3, 3), np.nan), float("nan"), float("nan")
    t_unc = time.perf_counter() - t_unc
    priors = reprojection_record(state, opts, kernel=opts.robust_kernel,
                                 kernel_scale_px=opts.kernel_scale_px,
                                 final_kernel=opts.final_kernel,
                                 final_kernel_scale_px=opts.final_kernel_scale_px)
    timings = {"build": state.timings.get("build", 0.0),
               "solve": state.timings.get("solve", 0.0) + state.timings.get("triangulate", 0.0),
               "marginals": state.timings.get("marginals", 0.0),
               "uncertainty": state.timings.get("uncertainty", 0.0) + t_unc}
    timings["total"] = time.perf_counter() - t_start
    return RefinementResult(
        normal=np.asarray(n, dtype=float), distance=float(d * unit), scale=state.scale,
        joints3d=state.points * unit, valid=used.copy(), inliers=used.copy(),
        bone_lengths={b: v * unit for b, v in state.bone_lengths.items()},
        normal_cov=normal_cov, rotation_std_deg=rot_std, distance_std=distance_std,
        marginal_normal_cov=marginal_cov, marginal_rotation_std_deg=marginal_std,
        uncertainty_parts=parts, sensitivity=sensitivity,
        intrinsics=np.asarray(rig.cameras[0].K, dtype=float),
        rms_direct_px=rms[0], rms_mirror_px=rms[1], iterations=state.iterations,
        final_error=float(state.final_error), priors=priors, timings=timings,
        stages=state.stages)


# --------------------------------------------------------------------------- rigs
@dataclass
class RigSolution:
    """The refined rig (graph units = metres with a subject height, else heights).

    Attributes:
        poses: ``(4, 4)`` camera-to-world pose per camera.
        planes: ``(n, d)`` per mirror of the rig, world frame.
        mirror_names: names of ``planes``.
        camera_cov: per camera ``(6, 6)`` covariance of its pose in GTSAM's tangent
            ``(rotation rad, translation in the camera frame)``; zeros for the first
            camera (the fixed world frame); NaN when not computed. The headline
            figure: the data's error structure included (:func:`robust_blocks`).
        plane_cov: per mirror ``(3, 3)`` tangent covariance ``(v1, v2, d)``, the same.
        marginal_camera_cov, marginal_plane_cov: the graph's marginals (iid noise).
        robust_parts: camera or mirror name -> which figure the headline is and its
            ratio to the marginal std.
        sensitivity: camera or mirror name -> what it rests on
            (:func:`~mirrorgraph.graph.sensitivity.rig_sensitivity_report`).
        plane_basis: per mirror the ``(3, 2)`` tangent basis of the normal.
        points: ``(T, J, 3)`` joints; used: ``(T, J)``.
        view_names, view_rms_px: reprojection RMS per view, pixels.
        view_counts: observations used per view.
        view_observed: observations each view offered the graph (seen, on the graph's
            frames), before any rejection.
        view_joint_tally: ``(V, J, 3)`` the same per view and joint: the sum of the squared
            residuals (px^2), the observations used, those offered (the figures of one
            person of several side by side: their joints' columns summed); ``None``: not
            computed.
        bone_lengths: bone -> length.
        rejected: observations dropped as outliers, all views.
        iterations: Levenberg-Marquardt solves.
        priors: prior name -> description (as the single-mirror result).
        timings: seconds per stage.
        intrinsics: ``(3, 3)`` per camera: the estimate where its focal length was
            estimated, else the given one.
        focal: camera name -> its focal length's record
            (:func:`mirrorgraph.pipelines.solve.focal_record`) for the cameras whose focal
            length was estimated.
        joints_cov: ``(T, J, 3, 3)`` each joint's covariance
            (:func:`~mirrorgraph.graph.joints_uncertainty.graph_joints_covariance`; the
            completed joints' from their rays, :func:`~mirrorgraph.completion.complete_rig_joints`),
            NaN where unknown; ``None``: not computed.
        noise_px: the a posteriori pixel noise.
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
    marginal_camera_cov: list[np.ndarray] = field(default_factory=list)
    marginal_plane_cov: list[np.ndarray] = field(default_factory=list)
    robust_parts: dict = field(default_factory=dict)
    intrinsics: list[np.ndarray] = field(default_factory=list)
    focal: dict[str, dict] = field(default_factory=dict)
    sensitivity: dict = field(default_factory=dict)
    joints_cov: np.ndarray | None = None
    noise_px: float = float("nan")
    view_joint_tally: np.ndarray | None = None

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
        d_unit = np.diag([1.0, 1.0, f])
        return replace(self, poses=poses, planes=[(np.asarray(n), float(d) * f) for n, d in self.planes],
                       camera_cov=[unit @ C @ unit for C in self.camera_cov],
                       plane_cov=[d_unit @ C @ d_unit for C in self.plane_cov],
                       marginal_camera_cov=[unit @ C @ unit for C in self.marginal_camera_cov],
                       marginal_plane_cov=[d_unit @ C @ d_unit for C in self.marginal_plane_cov],
                       points=self.points * f,
                       joints_cov=None if self.joints_cov is None else self.joints_cov * f * f,
                       bone_lengths={b: v * f for b, v in self.bone_lengths.items()})


def build_rig(obs: "RigObservations", init: "InitialRig",
              joints: tuple[np.ndarray, np.ndarray] | None = None,
              estimate_focal: bool = True, focal: FocalOptions | None = None) -> Rig:
    """The graph's :class:`~mirrorgraph.graph.rig.Rig`: cameras (all but the first
    estimated), the mirrors that were placed, one direct view per camera and one
    view per camera and mirror. ``joints`` = ``(direct, mirror)`` joint indices that
    the direct views and the views through mirrors use
    (:func:`~mirrorgraph.joint_sets.resolve_joints`; default: the calibration joints).
    With ``estimate_focal`` a camera given without intrinsics (``intrinsics.approximate``)
    has its focal length estimated (:attr:`~mirrorgraph.graph.rig.Camera.estimate_focal`),
    from its initial one (:attr:`InitialRig.K`), with the weak prior of ``focal``
    (:class:`~mirrorgraph.graph.options.FocalOptions`) about the field-of-view guess."""
    from ..initial.rig import joint_masks, observed

    dmask, mmask = joint_masks(obs.skeleton, joints)
    focal = focal or FocalOptions()
    cams = []
    for i, (c, p) in enumerate(zip(obs.cameras, init.poses)):
        K = init.K[i] if init.K else c.intrinsics.K
        cam = Camera(c.name, np.asarray(K, float), np.asarray(p, float), estimate_pose=i > 0)
        if c.intrinsics.approximate:
            # no intrinsics: the focal length and principal point are variables with
            # priors about the guess (the guess's own spread without estimate_focal)
            cam = replace(guessed_camera(cam, c.intrinsics.K, focal,
                                         None if estimate_focal else focal.guess_rel_sigma),
                          K=np.asarray(K, float))
        cams.append(cam)
    cams = tuple(cams)
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


def triangulate_rig_views(rig: Rig, poses: list[np.ndarray],
                          planes: list[tuple[np.ndarray, float]],
                          rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(T, J, 3)`` joints (world frame) and ``(T, J)`` mask, triangulated from every
    view that observes them (:attr:`View.mask`), estimated joints only."""
    masks = [np.asarray(v.mask, bool) for v in rig.views]
    if rows is not None:
        masks = [m & rows[:, None] for m in masks]
    return triangulate_rig(rig, masks, poses, planes)


def solve_config(rig: Rig, options: RefineOptions):
    """The driver's configuration for ``rig``: what varies decides it.

    With one camera every pose is held and each mirror comes from its own reflective
    RANSAC in that camera (good to a pixel): the RANSAC-initialised configuration of a
    single mirror (:func:`~mirrorgraph.graph.stage_config.single_mirror_config`: the first
    rejection at once, a warm start, the joints pass). With several cameras the poses
    come from chained pairwise estimates that can be degrees off:
    :func:`~mirrorgraph.graph.stage_config.rig_config` (a kernel five times wider first,
    the rejection per observation). A one-camera rig takes the single mirror's (on wide
    one-camera, one-mirror scenes the rig's is the less accurate; with the single
    mirror's, ``calibrate_rig`` matches ``calibrate``: ``bench/RESULTS_one_camera_rig.md``;
    on one-camera, two-mirror rigs the two agree to noise).
    """
    one_camera = len(rig.cameras) == 1
    return single_mirror_config(options) if one_camera else rig_config(options)


def solve_rig(rig: Rig, options: RefineOptions, height: float,
              progress=None) -> RigSolution:
    """Solve ``rig`` (initial poses and planes inside) with the one driver.

    The configuration follows what varies (:func:`solve_config`): a rig of one camera is
    solved as a single mirror is (the same numbers as :func:`refine_mirror` on the same
    pairs: ``bench/bench_one_camera_rig.py``), a chained rig with :func:`rig_config`.

    Args:
        rig: cameras (initial poses), mirrors (initial planes), views.
        options: weights and solver settings (``subject_height`` is ignored: the
            gauge is ``height``).
        height: the subject's height in the output unit.
        progress: ``progress(iteration, error)`` per accepted step.

    Raises:
        DegenerateGeometryError: too few joints seen twice, or a camera or mirror
            left without keypoints.
    """
    state = solve(rig, options, solve_config(rig, options), height=float(height),
                  progress=progress)
    problem = state.problem
    rows = spread_rows(rig.num_frames, options.max_graph_frames)     # the graph's frames
    res_views = view_residuals(problem.rig, state.points[rows], problem.used,
                               state.planes, state.poses)
    rms = [float(np.sqrt(np.nanmean(r[np.isfinite(r)] ** 2))) if np.isfinite(r).any()
           else float("nan") for r in res_views]
    counts = [int(np.count_nonzero(np.isfinite(r))) for r in res_views]
    offered = [int(np.count_nonzero(np.asarray(v.mask, bool)[rows])) for v in rig.views]
    tally = np.stack([np.stack([np.nansum(r ** 2, axis=0), np.isfinite(r).sum(0),
                                np.asarray(v.mask, bool)[rows].sum(0)], axis=-1)
                      for r, v in zip(res_views, rig.views)]) if rig.views else None
    priors = reprojection_record(state, options, kernel=" then ".join(
        str(s.get("kernel")) for s in state.stages if "kernel" in s))
    camera_cov, plane_cov = list(state.camera_cov), list(state.plane_cov)
    robust_parts: dict = {}
    sensitivity: dict = {}
    if state.scores is not None and state.scores.z_keys:
        # the headline figures follow the data's error structure (graph.uncertainty)
        order = ([("camera", i) for i in problem.camera_keys]
                 + [("mirror", m) for m in range(len(problem.plane_keys))])
        marg = [camera_cov[i] if kind == "camera" else plane_cov[i] for kind, i in order]
        blocks, parts = robust_blocks(state.scores, marg)
        for (kind, i), B, part in zip(order, blocks, parts):
            if kind == "camera":
                camera_cov[i] = B
                robust_parts[rig.cameras[i].name] = part
            else:
                plane_cov[i] = B
                robust_parts[rig.mirrors[i].name] = part
        # what each camera and mirror rests on: joint pairs and segments left out
        named = [(rig.cameras[i].name, "camera", None) if kind == "camera"
                 else (rig.mirrors[i].name, "mirror", state.plane_basis[i])
                 for kind, i in order]
        sensitivity = rig_sensitivity_report(state.scores, named, marg, rig.skeleton,
                                             rig.frame_ids)
    # what the intrinsics' headline spread adds to positions and distances (a camera whose
    # focal length the data hardly determine: the lengths with it)
    for i, extra in enumerate(state.camera_spread):
        camera_cov[i] = np.array(camera_cov[i], float)
        camera_cov[i][3:, 3:] += extra[3:, 3:]
    for i, extra in enumerate(state.plane_spread):
        plane_cov[i] = np.array(plane_cov[i], float)
        plane_cov[i][2, 2] += extra[2, 2]
    focal = {c.name: focal_record(state, c, i, options) for i, c in enumerate(rig.cameras)
             if c.estimate_focal}
    joints_cov = None
    if options.marginals:
        ratios = [float(p.get("ratio_to_marginal", 1.0)) for p in robust_parts.values()]
        ratios = [r for r in ratios if np.isfinite(r) and r > 0]
        joints_cov = graph_joints_covariance(state, options,
                                             joints_pass=solve_config(rig, options).joints_pass,
                                             inflation=max(ratios, default=1.0),
                                             rig=with_intrinsics(rig, state.intrinsics))
        # the frames outside the graph (a long video's spread subset): their rays
        outside = state.used & ~np.isfinite(joints_cov).all((-2, -1))
        if outside.any():
            views = view_projections(with_intrinsics(rig, state.intrinsics), state.poses,
                                     state.planes)
            joints_cov[outside] = geo.triangulation_covariance(
                views, state.points[outside],
                [np.asarray(v.mask, bool)[outside] for v in rig.views],
                state.noise_px if np.isfinite(state.noise_px) else options.pixel_sigma)
    return RigSolution(joints_cov=joints_cov, noise_px=float(state.noise_px),poses=state.poses, planes=state.planes,
                       intrinsics=list(state.intrinsics), focal=focal,
                       mirror_names=[m.name for m in rig.mirrors],
                       camera_cov=camera_cov, plane_cov=plane_cov,
                       marginal_camera_cov=list(state.camera_cov),
                       marginal_plane_cov=list(state.plane_cov), robust_parts=robust_parts,
                       sensitivity=sensitivity,
                       plane_basis=state.plane_basis, points=state.points, used=state.used,
                       view_names=[v.name for v in rig.views], view_rms_px=rms,
                       view_counts=counts, view_observed=offered, view_joint_tally=tally,
                       bone_lengths=state.bone_lengths, rejected=state.rejected,
                       iterations=state.iterations, priors=priors, timings=state.timings)


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
