"""``calibrate_rig``: a rig file in, every camera and mirror calibrated out.

The run of a rig, step for step as :mod:`.mirror`'s for one mirror: read and sort every
camera's keypoints (observations, :mod:`mirrorgraph.rigs.observations`), pairwise
initialisation chained along a spanning tree (:mod:`mirrorgraph.initial.rig`), one
factor graph over all joints, cameras and mirrors (solve, :func:`.solve.solve_rig`), the
joints the graph did not use triangulated with its rig (completion,
:func:`mirrorgraph.completion.complete_rig_joints`), the scale (the graph holds the limb
bones at Winter's fractions of the subject's height, then the whole rig is rescaled so
that the stature measured on the solved joints equals that height,
:func:`mirrorgraph.stature.stature_rescale`), and the result with its uncertainties
(:mod:`mirrorgraph.result.rig`) judged by :func:`.judge.judge_rig`. With every person
(``people="all"``) the solve is followed by :func:`.rig_people.solve_everyone`: every
person associated with the solved rig, all of them in the one graph, solved again.
"""

from __future__ import annotations

import os
from dataclasses import replace
from typing import Callable

import numpy as np

from ..graph.joints_uncertainty import position_std, with_scale
from ..graph.options import REFERENCE_FPS, RefineOptions
from .options import CalibrateOptions
from .judge import judge_rig
from ..stature import keypoint_offset_fraction, measurement_rel_std, with_height_sigma
from .scale import distance_rel_parts, normal_scale_rel_std, scale_rig_by_stature
from ..keypoints import PairedKeypoints
from ..completion import complete_rig_joints
from ..joint_sets import resolve_joints
from ..rigs.config import RigConfig, load_rig_config
from ..initial.rig import initialise_rig
from ..intrinsics import estimated_intrinsics
from ..rigs.observations import load_observations
from ..rigs.tracking import rig_segments
from ..rigs.failure import (MIN_FIT_SHARE, candidate_people, failure_cause, fit_shares,
                            scan_offsets)
from ..errors import DegenerateGeometryError, FailedCameraError
from ..initial.rig import observed
from ..result.rig import RigCalibration, RigCamera, RigMirror
from .solve import build_rig, camera_std, plane_std, solve_rig

__all__ = ["calibrate_rig", "DEFAULT_PEOPLE"]

#: Who a rig calibrates from where :attr:`CalibrateOptions.people` is ``None``: the person
#: seen longest. Every person is 5-14x closer on synthetic rigs of 2-5 people, within
#: 1.08x of a bundle adjustment that knows the identities, but on Pose2Sim's
#: Demo_MultiPerson (BlazePose) two of three cameras land further from Qualisys
#: (``bench/RESULTS_rig_people.md``): not as good everywhere, so not the default.
DEFAULT_PEOPLE = "one"

#: A phrase of the observations' warning that a camera sees several people (the one-person
#: path's), left out where every person is used.
SUBJECT_NOTE = "; calibrating from the one seen longest"

#: The deprecated keywords :func:`calibrate_rig` accepts beside :class:`CalibrateOptions`,
#: and the fields they set (a :class:`RefineOptions` as ``options``: ``refine_options``).
LEGACY_KEYWORDS = {"subject_height": "subject_height", "skeleton": "skeleton", "joints": "joints",
                   "seed": "seed", "video": "detection", "estimate_focal": "estimate_focal",
                   "fov_deg": "fov_deg"}


def _legacy_options(options, legacy: dict) -> CalibrateOptions:
    """:class:`CalibrateOptions` from the deprecated keywords, with a
    :class:`DeprecationWarning` (a :class:`RefineOptions` as ``options``, ``subject_height``,
    ``skeleton``, ``joints``, ``seed``, ``video``, ``estimate_focal``, ``fov_deg``: a
    ``fov_deg`` holds the focal length near it, as ``estimate_focal=False`` does)."""
    unknown = sorted(set(legacy) - set(LEGACY_KEYWORDS))
    if unknown:
        raise TypeError(f"calibrate_rig() got unexpected keyword argument(s) {', '.join(unknown)}")
    import warnings as _w
    if legacy or isinstance(options, RefineOptions):
        _w.warn("calibrate_rig's keywords are CalibrateOptions fields: pass "
                "options=CalibrateOptions(...) (a RefineOptions goes in its refine_options)",
                DeprecationWarning, stacklevel=3)
    opts = CalibrateOptions(refine_options=options) if isinstance(options, RefineOptions) \
        else (options or CalibrateOptions())
    fields = {LEGACY_KEYWORDS[k]: v for k, v in legacy.items() if v is not None}
    if fields.get("fov_deg") is not None:
        fields["estimate_focal"] = False
    return replace(opts, **fields)


def calibrate_rig(config: RigConfig | str | os.PathLike,
                  options: CalibrateOptions | None = None, *,
                  progress: Callable[[str], None] | None = None,
                  iteration_progress: Callable[[int, float], None] | None = None,
                  frame_progress: Callable[[str, int, int], None] | None = None,
                  keep_failed: bool = False, **legacy) -> RigCalibration:
    """Calibrate every camera and mirror of a rig from the people in its videos.

    Args:
        config: a :class:`~.config.RigConfig` or the path of a rig TOML file.
        options: :class:`~mirrorgraph.pipelines.options.CalibrateOptions`, the same object
            :func:`mirrorgraph.calibrate` takes. A rig reads ``subject_height`` (else the
            file's; without any, lengths are in units of the subject's height),
            ``skeleton`` (for cameras whose table names none), ``joints`` (else the file's),
            ``seed``, ``detection`` (cameras whose ``keypoints`` name a video),
            ``estimate_focal`` and ``fov_deg`` (every camera listed without intrinsics:
            its focal length estimated from an initial one, :func:`mirrorgraph.initial.rig.initial_focals`,
            in the one graph; or with ``estimate_focal=False`` held near ``fov_deg``, its
            spread in every std), ``refine_options`` and ``people`` (``"all"``: every
            person in view associated across the cameras and solved in the one graph,
            :mod:`.rig_people`; default :data:`DEFAULT_PEOPLE`).
        progress: called with a short description of each step (as
            :func:`mirrorgraph.calibrate`'s ``progress``).
        iteration_progress: ``(iteration, error)`` of the graph solve, after every
            iteration (as :func:`mirrorgraph.calibrate`'s).
        frame_progress: ``(camera, done, total)`` per frame of a video being detected.
        keep_failed: return a rig with a failed camera (one that fits under half of its
            keypoints, :data:`~mirrorgraph.rigs.failure.MIN_FIT_SHARE`) marked
            ``status = "failed"`` with its ``reason``, instead of raising.
        legacy (Any): the deprecated keywords (``subject_height=``, ``seed=``, ...,
            ``options=RefineOptions(...)``): accepted with a :class:`DeprecationWarning`.

    Returns:
        :class:`~.result.RigCalibration` (world frame = the first camera); with every
        person, ``people_joints3d`` holds each one's joints and ``joints3d`` person 0's
        (the person seen longest, whose stature gives the scale).

    Raises:
        InputError: a malformed rig file, input or option, naming the file and field.
        DegenerateGeometryError: a camera that cannot be placed, a mirror that
            cannot be found, too few joints.
        FailedCameraError: (a :class:`DegenerateGeometryError`) without ``keep_failed``,
            a camera that fits under half of its keypoints, with its likeliest cause
            (:func:`mirrorgraph.rigs.failure.failure_cause`); its ``calibration`` holds
            the rig with that camera marked.
    """
    cfg = config if isinstance(config, RigConfig) else load_rig_config(config)
    run = _legacy_options(options, legacy).checked(default_height=cfg.subject_height)
    opts = run.graph
    height = run.subject_height
    estimate_focal = run.estimate_focal
    scale = "subject_height" if height is not None else "unit_height"
    H = float(height) if height is not None else 1.0
    offset = keypoint_offset_fraction(opts.keypoint_offset, height)   # of the height
    say = progress or (lambda s: None)
    seed, joints = run.seed, run.joints

    obs = load_observations(cfg, skeleton=run.skeleton,                   # observations
                            progress=lambda name: say(f"reading camera {name}"),
                            video=run.detection, frame_progress=frame_progress,
                            estimate_focal=estimate_focal, fov_deg=run.fov_deg,
                            time_offsets=run.time_offsets, offset_window=run.offset_window,
                            seed=seed)
    warnings = list(obs.warnings)
    # the acceleration priors (stated at REFERENCE_FPS) at the rig clock's frame interval
    opts = opts.at_frame_rate(obs.fps or REFERENCE_FPS)
    used_joints = resolve_joints(obs.skeleton, joints if joints is not None else cfg.joints,
                                 source=cfg.source)
    say("initialising: camera pairs, mirrors, spanning tree")               # initialisation
    try:
        init = initialise_rig(obs, H, seed=seed, joints=used_joints,
                              estimate_focal=estimate_focal)
    except DegenerateGeometryError as exc:
        if type(exc) is not DegenerateGeometryError or len(obs.cameras) < 2:
            raise
        say("a camera cannot be placed: looking for time offsets")
        hints = _offset_hints(cfg, obs, used_joints[0], opts.outlier_threshold, seed)
        if not hints:
            raise
        raise DegenerateGeometryError(f"{exc}; likeliest cause: " + "; ".join(hints)) from None
    rig = build_rig(obs, init, used_joints, estimate_focal=estimate_focal, focal=opts.focal)
    say("refining the rig in one factor graph")                             # solve
    # every person: where some camera sees several (one person alone is the one-person run)
    every = (run.people or DEFAULT_PEOPLE) == "all" and len(obs.cameras) > 1 and any(
        c.people is not None and any(len(p) > 1 for p in c.people) for c in obs.cameras)
    # every person's graph gives the uncertainties: the first solve needs none
    sol = solve_rig(rig, replace(opts, marginals=False) if every else opts, H,
                    progress=iteration_progress)
    everyone, solved = None, obs
    if every:                                       # every person, in the one graph
        from .rig_people import solve_everyone
        everyone = solve_everyone(obs, init, sol, used_joints, opts, H,
                                  estimate_focal=estimate_focal, progress=say,
                                  iteration_progress=iteration_progress)
        if everyone is None:                        # no one seen twice: the subject alone
            sol = solve_rig(rig, opts, H, progress=iteration_progress)
        else:
            solved, sol = everyone.observations, everyone.solution
            warnings = [w for w in warnings if SUBJECT_NOTE not in w]
    sol = complete_rig_joints(solved, sol, opts.outlier_threshold)         # completion
    if everyone is not None:                                                 # scale
        from .rig_people import scale_everyone
        sol, scale_source, stature = scale_everyone(sol, obs.skeleton, everyone.count, H,
                                                    opts.scale_from, offset)
    else:                   # snapshots: each stretch its own subject, one body's stature
        stretch = rig_segments(solved.frame_ids, [c.people or [] for c in solved.cameras],
                               obs.skeleton.calibration_joints)
        count = max((len(p) for c in solved.cameras for p in (c.people or [])), default=1)
        sol, scale_source, stature = scale_rig_by_stature(sol, obs.skeleton, H,
                                                          opts.scale_from, stretch, count,
                                                          offset)
    if opts.scale_from == "stature" and stature is None:
        warnings.append(f"scale: {scale_source}")

    cameras, mirrors = _records(solved, init, sol, run, warnings, stature)  # result
    failed = _judge_cameras(cfg, obs, cameras, sol, used_joints[0], opts.outlier_threshold,
                            seed, say)
    warnings += [f"camera {c.name} failed: {c.reason}" for c in cameras if c.failed]
    warnings += judge_rig(cameras, mirrors, sol.robust_parts, sol.view_names, sol.view_counts,
                          sol.view_observed, init.mirror_spread_deg, failed=failed)
    initialisation = {
        "edges": [{"cameras": [a, b], "inliers": e.inliers, "correspondences": e.correspondences,
                   "median_sampson_px": e.residual_px} for (a, b), e in init.edges.items()],
        "spanning_tree": [list(e) for e in init.tree],
        "mirror_sightings": [{"camera": c, "mirror": m, "inliers": s.inliers}
                             for (c, m), s in init.sightings.items()],
        "mirror_spread_deg": init.mirror_spread_deg,
    }
    refinement = {"joints": {"direct": [obs.skeleton.joints[j] for j in used_joints[0]],
                             "through_mirrors": [obs.skeleton.joints[j] for j in used_joints[1]]},
                  "iterations": sol.iterations, "rejected_observations": sol.rejected,
                  "priors": sol.priors,
                  "views": {v: {"rms_px": r, "observations": k, "offered": n}
                            for v, r, k, n in zip(sol.view_names, sol.view_rms_px,
                                                  sol.view_counts, sol.view_observed)}}
    refinement["stature"] = stature.to_dict() if stature is not None else None
    joints_std = None
    if sol.joints_cov is not None:
        # the metric scale's share: the height's prior and the legs' disagreement
        rel = (float(np.hypot(opts.height_sigma,
                              measurement_rel_std(stature, opts.scale_from, offset)))
               if height is not None else 0.0)
        cov = with_scale(sol.joints_cov, np.nan_to_num(sol.points), rel)
        cov[~np.asarray(sol.used, bool)] = np.nan
        joints_std = position_std(cov)
    joints3d, valid, bones, people = sol.points, sol.used, sol.bone_lengths, None
    if everyone is not None:                    # the subject (slot 0) as the one person
        from .rig_people import people_record, split_solution
        refinement["people"] = people_record(everyone)
        people = (split_solution(sol.points, everyone.count),
                  split_solution(sol.used, everyone.count),
                  split_solution(joints_std, everyone.count))
        joints3d, valid = people[0][0], people[1][0]
        joints_std = None if people[2] is None else people[2][0]
        bones = {b[:-2]: v for b, v in sol.bone_lengths.items() if b.endswith("@0")}
    else:
        refinement["people"] = {"mode": run.people or DEFAULT_PEOPLE, "count": 1}
    result = RigCalibration(joints_std=joints_std,cameras=cameras, mirrors=mirrors, scale=scale, subject_height=height,
                          scale_source=scale_source,
                          skeleton=obs.skeleton.name, frame_ids=np.asarray(obs.frame_ids),
                          joints3d=joints3d, valid=valid, bone_lengths=bones,
                          people_joints3d=None if people is None else people[0],
                          people_valid=None if people is None else people[1],
                          people_std=None if people is None else people[2],
                          initialisation=initialisation, refinement=refinement,
                          sensitivity=sol.sensitivity,
                          warnings=warnings, source=str(cfg.source))
    if failed and not keep_failed:
        raise FailedCameraError("; ".join(f"camera {c.name} failed: {c.reason}"
                                          for c in result.failed_cameras),
                                calibration=result, cameras=tuple(failed))
    return result


def _direct_points(obs, direct: np.ndarray) -> list[list[np.ndarray]]:
    """Per camera the ``(T, J, 2)`` sequences that may be its person (observed ``direct``
    joints, NaN elsewhere): the person kept; where none was kept, its candidates
    (:func:`~mirrorgraph.rigs.failure.candidate_people`)."""
    joints = np.zeros(obs.skeleton.num_joints, bool)
    joints[np.asarray(direct, int)] = True
    out = []
    for cam in obs.cameras:
        seqs = [np.asarray(cam.real, float)]
        if not observed(seqs[0], joints).any() and cam.people is not None:
            seqs = candidate_people(cam.people, *seqs[0].shape[:2], np.asarray(direct, int))
        points = []
        for real in seqs:
            p = real[..., :2].copy()
            p[~observed(real, joints)] = np.nan
            points.append(p)
        out.append(points)
    return out


def _frame_step(obs) -> int:
    """The frames between two rows of the rig's clock (a video read every n-th frame)."""
    ids = np.asarray(obs.frame_ids)
    return max(int(np.median(np.diff(ids))), 1) if len(ids) > 1 else 1


def _offset_hints(cfg, obs, direct: np.ndarray, threshold_px: float, seed: int) -> list[str]:
    """``"camera <name>: a time offset ..."`` for every camera whose frames fit the others
    far better shifted (:func:`~mirrorgraph.rigs.failure.scan_offsets`)."""
    seqs = _direct_points(obs, direct)
    points = [s[0] for s in seqs]
    Ks = [np.asarray(c.intrinsics.K, float) for c in obs.cameras]
    step = _frame_step(obs)
    out = []
    for i, c in enumerate(obs.cameras):
        others = [j for j in range(len(points)) if j != i]
        found = []
        for mine in seqs[i]:
            scan = scan_offsets(points[:i] + [mine] + points[i + 1:], Ks, i, others,
                                threshold_px, seed=seed)
            cause = failure_cause(scan, cfg.cameras[i].frame_offset, step)
            if cause.startswith("a time offset"):
                found.append((scan.at(scan.best), cause))
        if found:
            out.append(f"camera {c.name}: {max(found)[1]}")
    return out


def _judge_cameras(cfg, obs, cameras: list[RigCamera], sol, direct: np.ndarray,
                   threshold_px: float, seed: int, say) -> list[str]:
    """Every camera's share of its keypoints kept by the final solve (``fit_share``); a
    camera under :data:`~mirrorgraph.rigs.failure.MIN_FIT_SHARE` marked failed with its
    likeliest cause (a time offset, other people, too few keypoints,
    :func:`~mirrorgraph.rigs.failure.failure_cause`). Returns the failed cameras' names."""
    shares = fit_shares([c.name for c in cameras], sol.view_names, sol.view_counts,
                        sol.view_observed)
    for c in cameras:
        kept, offered = shares[c.name]
        c.fit_share = kept / offered if offered else float("nan")
    bad = [i for i, c in enumerate(cameras) if c.fit_share < MIN_FIT_SHARE]
    if not bad:
        return []
    points = [s[0] for s in _direct_points(obs, direct)]
    Ks = [np.asarray(c.intrinsics.K, float) for c in cameras]
    for i in bad:
        c = cameras[i]
        say(f"camera {c.name} fits {100 * c.fit_share:.0f} % of its keypoints: "
            "looking for the cause (time shifts against the other cameras)")
        others = [j for j in range(len(cameras)) if j not in bad] or \
            [j for j in range(len(cameras)) if j != i]
        scan = (scan_offsets(points, Ks, i, others, threshold_px, seed=seed) if others
                else None)
        cause = (failure_cause(scan, cfg.cameras[i].frame_offset, _frame_step(obs)) if others
                 else "no other camera to compare it with")
        kept, offered = shares[c.name]
        c.status = "failed"
        c.reason = (f"only {100 * c.fit_share:.0f} % of its keypoints fit the rig ({kept} of "
                    f"{offered}, half needed); likeliest cause: {cause}")
    return [cameras[i].name for i in bad]


def _clock(clock) -> dict:
    """A camera's time offset as :class:`RigCamera` fields."""
    if clock is None:
        return {}
    frames, std = clock.reference_frames
    secs, secs_std = clock.seconds
    return dict(time_offset_frames=float(frames), time_offset_std=float(std),
                time_offset_source=clock.source, time_offset_s=float(secs),
                time_offset_s_std=float(secs_std),
                fps=float(clock.fps) if clock.fps else float("nan"),
                clock_rate=float(clock.rate), clock_rate_std=float(clock.rate_std))


def _one_mirror_distance_std(obs, sol, name: str, n, d: float, normal_cov, data_std: float,
                             stature, run: CalibrateOptions) -> float | None:
    """A one-camera rig's mirror distance std with the scale from the stature: the single
    mirror's (:func:`~.scale.distance_rel_parts`, the normal's share through the stature,
    :func:`~.scale.normal_scale_rel_std`, from the camera's person and reflection); ``None``
    (the graph's std with the scale's share) for several cameras, the limbs' scale or no
    stature."""
    opts, height = run.graph, run.subject_height
    if (len(obs.cameras) != 1 or stature is None or height is None
            or opts.scale_from != "stature" or not np.isfinite(data_std)):
        return None
    cam = obs.cameras[0]
    if name not in cam.reflections:
        return None
    paired = PairedKeypoints(skeleton=obs.skeleton, frame_ids=obs.frame_ids, real=cam.real,
                             mirror=cam.reflections[name], source=cam.source)
    offset = keypoint_offset_fraction(opts.keypoint_offset, height)
    normal_rel = normal_scale_rel_std(paired, np.asarray(sol.intrinsics[0], float), n, d,
                                      np.asarray(sol.used, bool), normal_cov, offset)
    focal = sol.focal.get(cam.name) or {}
    parts = distance_rel_parts(normal_rel, stature, opts.height_sigma,
                               float(focal.get("rel_std", 0.0)) if focal else 0.0)
    return parts["total"] * float(d)


def _records(obs, init, sol, run: CalibrateOptions, warnings: list[str], sol_stature=None
             ) -> tuple[list[RigCamera], list[RigMirror]]:
    """The result's cameras and mirrors from the solution: poses, intrinsics (an estimated
    focal length's record and warnings), stds (with the scale's own uncertainty), residuals.
    """
    height, opts = run.subject_height, run.graph
    # with a subject height the metric scale rests on the subject's proportions where the
    # stature is not measured (or on the limbs'), the detector and the height itself: a
    # pure scale uncertainty of ``height_sigma`` (relative) added to every length's std,
    # as the single-mirror refinement does; without one the unit is the height itself
    rel = opts.height_sigma if height is not None else 0.0
    if height is not None:                  # the measurement's own: the stature's or the limbs'
        rel = float(np.hypot(rel, measurement_rel_std(
            sol_stature, opts.scale_from, keypoint_offset_fraction(opts.keypoint_offset, height))))
    rms = dict(zip(sol.view_names, sol.view_rms_px))
    counts = dict(zip(sol.view_names, sol.view_counts))
    cameras = []
    marg_cams = sol.marginal_camera_cov or sol.camera_cov
    for i, (c, pose, cov, mcov) in enumerate(zip(obs.cameras, sol.poses, sol.camera_cov,
                                                 marg_cams)):
        rot, pos = camera_std(cov, pose)
        pos = with_height_sigma(pos, np.linalg.norm(np.asarray(pose)[:3, 3]), rel)
        intr = c.intrinsics
        if c.name in sol.focal:
            sol.focal[c.name]["initial"] = init.focals.get(c.name)
            intr = estimated_intrinsics(c.intrinsics, sol.intrinsics[i], sol.focal[c.name],
                                        run.fov_deg, warnings, camera=c.name,
                                        user_guess=not run.estimate_focal)
        cameras.append(RigCamera(name=c.name, intrinsics=intr, pose=np.asarray(pose),
                                 rotation_std_deg=rot, position_std=pos,
                                 marginal_rotation_std_deg=camera_std(mcov, pose)[0],
                                 reprojection_rms_px=rms.get(c.name, float("nan")),
                                 observations=counts.get(c.name, 0), lr_fixes=c.lr_fixes,
                                 matched_frames=c.matched, **_clock(c.clock)))
    mirrors = []
    for i, name in enumerate(sol.mirror_names):
        n, d = sol.planes[i]
        mrot = float("nan")
        if sol.plane_basis:
            ncov, rot, dstd = plane_std(sol.plane_cov[i], sol.plane_basis[i])
            one = _one_mirror_distance_std(obs, sol, name, n, d, ncov, dstd, sol_stature, run)
            dstd = with_height_sigma(dstd, d, rel) if one is None else one
            mrot = plane_std((sol.marginal_plane_cov or sol.plane_cov)[i], sol.plane_basis[i])[1]
        else:
            ncov, rot, dstd = np.full((3, 3), np.nan), float("nan"), float("nan")
        seen_by = [c.name for c in obs.cameras if name in c.reflections]
        mirrors.append(RigMirror(name=name, normal=np.asarray(n), distance=float(d),
                                 normal_cov=ncov, rotation_std_deg=rot, distance_std=dstd,
                                 marginal_rotation_std_deg=mrot,
                                 seen_by=seen_by,
                                 views_rms_px={c: rms.get(f"{c}/{name}", float("nan"))
                                               for c in seen_by}))
    return cameras, mirrors
