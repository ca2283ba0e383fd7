"""Refine a mirror calibration in one factor graph: the single-mirror front end.

MirrorCalib's setting is the rig of one camera (the world frame, held) and one
mirror: :func:`refine_mirror` validates the pairs, builds that rig
(:func:`~.rig.single_mirror_rig`) with the initial distance (1, or metres from the
median bone lengths when the subject's height is known), and hands it to the one
solve driver of every rig (:func:`mirrorgraph.graph.solve.solve`) with
:func:`~mirrorgraph.graph.stages.single_mirror_config`: the first rejection at
once (the RANSAC mirror is good to a pixel), a warm start on the reprojection
alone, the full graph with the kernel the rejection calls for, a second solve if
that exposed more outliers, the joints pass, the marginals. The plane's 3x3
tangent covariance becomes the unit normal's (:mod:`.result`); with a subject
height everything is rescaled so that the stature measured on the joints equals
the height (:mod:`.stature_scale`).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ..errors import DegenerateGeometryError, InputError
from ..keypoints import PairedKeypoints
from .bones import body_height_from_points
from .rig import (Camera, Rig, single_mirror_rig, spread_rows, triangulate_rig, view_residuals,
                  with_intrinsics)
from .options import FocalOptions, RefineOptions
from .outliers import feasible
from .result import RefinementResult, normal_cov_from_tangent, rotation_std_from_normal_cov
from .sensitivity import sensitivity_report
from .solve import solve
from ..keypoints import MIN_PAIRS
from ..stature import LIMB_CHOSEN, with_height_sigma
from .solve_graph import Progress
from .solve_state import SolveState
from .stage_config import single_mirror_config
from .stature_scale import scale_by_stature
from .uncertainty import robust_normal_cov

__all__ = ["refine_mirror", "RefineOptions", "RefinementResult", "rotation_std_from_normal_cov",
           "MIN_PAIRS"]


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
    if res.scale == "subject_height":
        res = (scale_by_stature(res, paired, res.intrinsics, float(opts.subject_height))
               if opts.scale_from == "stature" else replace(res, scale_source=LIMB_CHOSEN))
    return res


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
    priors = {"reprojection": {"sigma": opts.pixel_sigma, "weight": 1.0 / opts.pixel_sigma ** 2,
                               "a_posteriori_sigma_px": state.noise_px,
                               "covariance_scaled_by": state.variance_factor,
                               "unit": "px", "kernel": opts.robust_kernel,
                               "kernel_scale_px": opts.kernel_scale_px,
                               "final_kernel": opts.final_kernel,
                               "final_kernel_scale_px": opts.final_kernel_scale_px,
                               "outlier_threshold_px": opts.outlier_threshold,
                               "min_parallax_deg": opts.min_parallax_deg,
                               "undetermined_dropped": state.undetermined,
                               "factors": state.reprojection_factors}}
    priors.update(state.prior_info)
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
