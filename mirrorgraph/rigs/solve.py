"""Refine a whole rig in one factor graph: all joints, all camera poses, all mirror planes.

The rig front end of the one solve driver (:func:`mirrorgraph.graph.solve.solve`):
the rig's cameras (every camera but the first has a :class:`gtsam.Pose3`
variable), its mirrors (one :class:`gtsam.OrientedPlane3` each; every mirror
view's virtual camera is tied to its camera and plane exactly,
:mod:`mirrorgraph.graph.reduction`), robust reprojection in every view, the body
priors and the subject-height gauge. The world frame is the first camera's (its
pose fixed: 6 of the 7 gauge freedoms), the scale is the subject's height (the
seventh). The configuration (:func:`~mirrorgraph.graph.stage_config.rig_config`) says
what differs from a single mirror: a chained pairwise initialisation can be
degrees off, so no rejection before the first solve, a kernel
:data:`~mirrorgraph.graph.stage_config.INITIAL_REJECTION_FACTOR` times wider first,
then the final kernel, then least squares on the inliers; the rejection per
observation (a wrong keypoint in one camera does not cost the other views).

Videos longer than ``options.max_graph_frames`` frames are calibrated on that
many frames spread over the video (the joints of the other frames are
triangulated with the result).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..graph.rig import Camera, Mirror, Rig, View, spread_rows, triangulate_rig, view_residuals
from ..graph.refine import focal_record, guessed_camera
from ..graph.options import FocalOptions, RefineOptions
from ..graph.result import normal_cov_from_tangent, rotation_std_from_normal_cov
from ..graph.sensitivity import rig_sensitivity_report
from ..graph.uncertainty import robust_blocks
from ..graph.solve import solve
from ..graph.stage_config import INITIAL_REJECTION_FACTOR, rig_config
from .initial import InitialRig, joint_masks, observed
from .observations import RigObservations

__all__ = ["RigSolution", "build_rig", "triangulate_rig_views", "solve_rig",
           "INITIAL_REJECTION_FACTOR"]

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
        bone_lengths: bone -> length.
        rejected: observations dropped as outliers, all views.
        iterations: Levenberg-Marquardt solves.
        priors: prior name -> description (as the single-mirror result).
        timings: seconds per stage.
        intrinsics: ``(3, 3)`` per camera: the estimate where its focal length was
            estimated, else the given one.
        focal: camera name -> its focal length's record
            (:func:`mirrorgraph.graph.refine.focal_record`) for the cameras whose focal
            length was estimated.
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
                       bone_lengths={b: v * f for b, v in self.bone_lengths.items()})


def build_rig(obs: RigObservations, init: InitialRig,
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


def solve_rig(rig: Rig, options: RefineOptions, height: float,
              progress=None) -> RigSolution:
    """Solve ``rig`` (initial poses and planes inside) with the one driver.

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
    state = solve(rig, options, rig_config(options), height=float(height), progress=progress)
    problem = state.problem
    rows = spread_rows(rig.num_frames, options.max_graph_frames)     # the graph's frames
    res_views = view_residuals(problem.rig, state.points[rows], problem.used,
                               state.planes, state.poses)
    rms = [float(np.sqrt(np.nanmean(r[np.isfinite(r)] ** 2))) if np.isfinite(r).any()
           else float("nan") for r in res_views]
    counts = [int(np.count_nonzero(np.isfinite(r))) for r in res_views]
    offered = [int(np.count_nonzero(np.asarray(v.mask, bool)[rows])) for v in rig.views]
    priors = {"reprojection": {"sigma": options.pixel_sigma, "unit": "px",
                               "a_posteriori_sigma_px": state.noise_px,
                               "covariance_scaled_by": state.variance_factor,
                               "kernel": " then ".join(str(s.get("kernel"))
                                                       for s in state.stages if "kernel" in s),
                               "outlier_threshold_px": options.outlier_threshold,
                               "min_parallax_deg": options.min_parallax_deg,
                               "undetermined_dropped": state.undetermined,
                               "factors": state.reprojection_factors}}
    priors.update(state.prior_info)
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
    return RigSolution(poses=state.poses, planes=state.planes,
                       intrinsics=list(state.intrinsics), focal=focal,
                       mirror_names=[m.name for m in rig.mirrors],
                       camera_cov=camera_cov, plane_cov=plane_cov,
                       marginal_camera_cov=list(state.camera_cov),
                       marginal_plane_cov=list(state.plane_cov), robust_parts=robust_parts,
                       sensitivity=sensitivity,
                       plane_basis=state.plane_basis, points=state.points, used=state.used,
                       view_names=[v.name for v in rig.views], view_rms_px=rms,
                       view_counts=counts, view_observed=offered,
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
