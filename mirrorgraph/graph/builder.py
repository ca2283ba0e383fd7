"""Build the factor graph of a rig: variables, initial values and every factor.

:func:`build_problem` makes a :class:`~.problem.GraphProblem` (its variables and
factor graphs are described in :mod:`.problem`) from a rig, initial joints and
planes: the joints', planes', virtual and real cameras' and intrinsics' variables,
the reprojection factors of every view (:class:`~mirrorgraph.factors.ReprojectionFactors`,
its robust kernel), the mirror links, the bone factors of the bones whose length is
measured without bias (:func:`~.bones.bone_curvature_bias`), the body priors
(:mod:`.priors`) and the gauge: a sum of bone lengths (a subject height's Winter
lengths, or the initial ones) or, without bone lengths, the first mirror's distance.
:func:`with_motion_priors` makes the graph of the joints pass from a solved one.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import gtsam
import numpy as np
from gtsam.symbol_shorthand import C as C_
from gtsam.symbol_shorthand import K as K_
from gtsam.symbol_shorthand import P as P_
from gtsam.symbol_shorthand import Q as Q_
from gtsam.symbol_shorthand import V as V_

from ..anthropometry import expected_bone_lengths
from ..factors import (HeightPriorFactor, MirrorLinkFactor, ReprojectionFactors, calibration,
                       mirrored_calibration, plane_to_gtsam, reflected_pose, robust_pixel_noise)
from .bones import body_height_from_points, bone_curvature_bias, bone_table, median_bone_lengths
from .options import RefineOptions
from .priors import (BoneSet, add_anthropometry, add_focal_prior, add_hip, add_smoothness,
                     add_symmetry, add_torso, gauge_weights, other_side_lengths,
                     record_prior)
from .problem import LENGTH_KEY, X_BASE, GraphProblem, bone_graph, extract_planes, extract_points
from .rig import Rig

__all__ = ["build_problem", "with_motion_priors"]


# --------------------------------------------------------------------------- build
def build_problem(rig: Rig, points: np.ndarray, used: np.ndarray,
                  planes: list[tuple[np.ndarray, float]], options: RefineOptions,
                  *, body_height: float | None = None,
                  bone_lengths: dict[str, float] | None = None,
                  priors: bool = True, length_sum: float | None = None,
                  final_kernel: str | None = None,
                  bones: list[str] | None = None,
                  hold_intrinsics: bool = False) -> GraphProblem:
    """Variables, initial values and factors.

    Args:
        rig: cameras, mirrors, views and observations.
        points: ``(T, J, 3)`` initial joints (world frame; read where ``used``).
        used: ``(T, J)`` bool, the points to estimate (each must be seen in two views).
        planes: initial ``(n, d)`` of each mirror.
        options: weights and switches.
        body_height: subject height in graph units; default: from ``points``.
        bone_lengths: initial bone lengths; default: per-bone medians of ``points``.
        priors: build the body priors and the gauge (``False``: reprojection and
            links only, for the warm start; the distance is then held by the solver).
        length_sum: the gauge's sum of bone lengths without a subject height
            (default: the sum of the initial lengths).
        final_kernel: the kernel of the reprojection factors when ``priors``
            (resolved: not ``"auto"``).
        bones: only these bones (default: every bone of the skeleton between
            estimated joints).
        hold_intrinsics: every camera's ``K`` held, whatever
            :attr:`~.rig.Camera.estimate_focal` says (a reprojection-only graph of one
            camera and its mirrors does not determine the focal length).
    """
    T, J = used.shape
    used = np.asarray(used, dtype=bool) & (rig.observation_count() >= 2)
    flat = np.flatnonzero(used.ravel())
    keys = np.zeros(T * J, dtype=np.uint64)
    keys[flat] = np.uint64(X_BASE) + flat.astype(np.uint64)
    keys = keys.reshape(T, J)
    if body_height is None:
        body_height = body_height_from_points(rig, points, used)
    h = float(body_height)
    var = _variables(rig, points, planes, flat, keys, hold_intrinsics)
    repro, links, virtual_keys = _reprojection_factors(rig, used, planes, options, var,
                                                       priors=priors, final_kernel=final_kernel)
    info: dict[str, dict] = {}
    calibrated = bool(var.calibration_keys)
    bone = _bone_set(rig, points, used, planes, flat, h, options, info, priors=priors,
                     bones=bones, bone_lengths=bone_lengths, calibrated=calibrated)
    prior_graph, length_priors = _prior_factors(rig, points, used, var, h, options, info, bone,
                                                priors=priors)
    gauge, distance_gauge, scale, weights = _gauge(rig, planes, options, info, bone,
                                                   priors=priors, length_sum=length_sum,
                                                   calibrated=calibrated)
    length_key = None
    if calibrated and bone.lengths is not None:
        # the lengths start on the gauge (its residual, of weight 1e12, would otherwise
        # dwarf every other term of the first error, and with it the solver's tolerances)
        length_key = LENGTH_KEY
        bone.lengths = np.asarray(bone.lengths, dtype=float) * (
            info["length_sum_gauge"]["sum"] / float(weights @ np.asarray(bone.lengths, float)))
        var.values.insert(LENGTH_KEY, bone.lengths)
    return GraphProblem(rig=rig, used=used, flat_index=flat, plane_keys=var.plane_keys,
                        virtual_keys=virtual_keys, camera_keys=var.camera_keys,
                        lengths=bone.lengths, bone_names=bone.names, bone_rows=bone.rows,
                        bone_sigma=bone.sigma, reprojection=repro, links=links,
                        priors=prior_graph,
                        bones=bone_graph(bone.rows, flat, bone.lengths, bone.sigma,
                                         J=J, length_key=length_key),
                        length_priors=length_priors,
                        gauge=gauge,
                        distance_gauge=distance_gauge,
                        values=var.values, body_height=h,
                        median_depth=float(np.median(var.pts[:, 2])) if len(var.pts) else 1.0,
                        scale=scale, prior_info=info, calibration_keys=var.calibration_keys,
                        held_pose_keys=var.held_pose_keys, length_key=length_key)


@dataclass
class _Variables:
    """The variables of a graph being built: their keys and initial values.

    Attributes:
        values: initial values (joints, planes, estimated and held camera poses,
            calibrations; the virtual poses are added with their factors).
        keys: ``(T, J)`` uint64, ``X(t * J + j)`` of the used joints (0 elsewhere).
        pts: ``(N, 3)`` the used joints' initial values, key order.
        plane_keys, camera_keys, calibration_keys, held_pose_keys: as
            :class:`~.problem.GraphProblem`'s.
    """

    values: gtsam.Values
    keys: np.ndarray
    pts: np.ndarray
    plane_keys: list[int]
    camera_keys: dict[int, int]
    calibration_keys: dict[int, tuple[int, int | None]]
    held_pose_keys: dict[int, int]


def _variables(rig: Rig, points: np.ndarray, planes: list[tuple[np.ndarray, float]],
               flat: np.ndarray, keys: np.ndarray, hold_intrinsics: bool) -> _Variables:
    """Keys and initial values of the joints (``flat``: the used ``t * J + j``), the
    planes, the estimated camera poses and, where a camera's intrinsics are estimated
    (and not ``hold_intrinsics``), its calibration ``K(c)``, the mirrored one ``Q(c)``
    where it sees a mirror, and its held pose ``C(c)`` where the pose is fixed."""
    values = gtsam.Values()
    pts = np.asarray(points, dtype=float).reshape(-1, 3)[flat]
    for k, x in zip(keys.ravel()[flat].tolist(), pts):
        values.insertPoint3(k, x)
    plane_keys = [P_(m) for m in range(len(rig.mirrors))]
    for k, (n, d) in zip(plane_keys, planes):
        values.insert(k, plane_to_gtsam(n, d))
    camera_keys = {c: C_(c) for c, cam in enumerate(rig.cameras) if cam.estimate_pose}
    for c, k in camera_keys.items():
        values.insert(k, rig.cameras[c].gtsam_pose)
    free = [c for c, cam in enumerate(rig.cameras)
            if cam.intrinsics_dim > 0 and not hold_intrinsics]
    has_mirror = {rig.camera_index(v.camera) for v in rig.views if v.mirror is not None}
    calibration_keys: dict[int, tuple[int, int | None]] = {}
    held_pose_keys: dict[int, int] = {}
    for c in free:
        K = np.asarray(rig.cameras[c].K, dtype=float)
        calibration_keys[c] = (K_(c), Q_(c) if c in has_mirror else None)
        values.insert(K_(c), calibration(K))
        if c in has_mirror:
            values.insert(Q_(c), mirrored_calibration(K))
        if c not in camera_keys:
            held_pose_keys[c] = C_(c)
            values.insert(C_(c), rig.cameras[c].gtsam_pose)
    return _Variables(values=values, keys=keys, pts=pts, plane_keys=plane_keys,
                      camera_keys=camera_keys, calibration_keys=calibration_keys,
                      held_pose_keys=held_pose_keys)


def _reprojection_factors(rig: Rig, used: np.ndarray, planes: list[tuple[np.ndarray, float]],
                          options: RefineOptions, var: _Variables, *, priors: bool,
                          final_kernel: str | None
                          ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.NonlinearFactorGraph,
                                     dict[int, int]]:
    """The reprojection factors of every view (the final kernel with ``priors``, else
    the warm start's), a virtual pose ``V(v)`` per mirror view (its initial value the
    camera reflected across the plane, added to ``var.values``) and its mirror link.
    Returns the reprojection graph, the links and view index -> ``V(v)``."""
    keys = var.keys
    repro = gtsam.NonlinearFactorGraph()
    links = gtsam.NonlinearFactorGraph()
    virtual_keys: dict[int, int] = {}
    kernel, scale = ((final_kernel, options.final_kernel_scale_px) if priors
                     else (options.robust_kernel, options.kernel_scale_px))
    noise = robust_pixel_noise(options.pixel_sigma, kernel, scale)
    J = used.shape[1]
    for vi, view in enumerate(rig.views):
        ci = rig.camera_index(view.camera)
        cam = rig.cameras[ci]
        ck = var.camera_keys.get(ci)
        mask = used & np.asarray(view.mask, dtype=bool)
        calib = var.calibration_keys.get(ci)
        if view.mirror is None:
            # one factory per weight of the view's joint columns (View.weight)
            w = np.ones(J) if view.weight is None else np.asarray(view.weight, float)
            for wv in np.unique(w):
                fac = ReprojectionFactors(cam.K, noise if wv == 1.0 else robust_pixel_noise(
                    options.pixel_sigma / np.sqrt(wv), kernel, scale), cam.gtsam_pose)
                idx = np.flatnonzero((mask & (w == wv)[None, :]).ravel())
                uv = np.asarray(view.pixels, dtype=float).reshape(-1, 2)[idx]
                if calib is not None:
                    pose_key = ck if ck is not None else var.held_pose_keys[ci]
                    fac.add_calibrated(repro, uv, pose_key, calib[0], keys.ravel()[idx])
                elif ck is None:
                    fac.add_direct(repro, uv, keys.ravel()[idx])
                else:
                    fac.add_posed(repro, uv, ck, keys.ravel()[idx])
            continue
        fac = ReprojectionFactors(cam.K, noise, cam.gtsam_pose)
        idx = np.flatnonzero(mask.ravel())
        uv = np.asarray(view.pixels, dtype=float).reshape(-1, 2)[idx]
        m = rig.mirror_index(view.mirror)
        vk = V_(vi)
        virtual_keys[vi] = vk
        n, d = planes[m]
        var.values.insert(vk, reflected_pose(n, d, cam.gtsam_pose))
        if calib is not None:
            fac.add_calibrated(repro, uv, vk, calib[1], keys.ravel()[idx])
        else:
            fac.add_mirror(repro, uv, vk, keys.ravel()[idx])
        link = MirrorLinkFactor(options.link_sigma_rotation, options.link_sigma_translation,
                                camera_pose=cam.gtsam_pose)
        links.push_back(link.make(var.plane_keys[m], vk, ck))
    return repro, links, virtual_keys


def _bone_set(rig: Rig, points: np.ndarray, used: np.ndarray,
              planes: list[tuple[np.ndarray, float]], flat: np.ndarray, h: float,
              options: RefineOptions, info: dict, *, priors: bool, bones: list[str] | None,
              bone_lengths: dict[str, float] | None, calibrated: bool) -> BoneSet:
    """The (frame, bone) pairs of the bone factors: every bone of ``bones`` (default:
    all between estimated joints) in the frames where both its joints are used and its
    curvature bias (:func:`~.bones.bone_curvature_bias`) is under the bone rule's limit
    (``options.bone_bias_limit``, or ``options.focal.bone_bias_limit`` where a focal
    length is estimated: ``calibrated``), at ``bone_lengths`` or their medians."""
    J = used.shape[1]
    names, pairs = bone_table(rig)
    if bones is not None:
        sel = [i for i, b in enumerate(names) if b in set(bones)]
        names, pairs = [names[i] for i in sel], pairs[sel]
    need_lengths = priors and (options.use_bone_length or options.subject_height is not None)
    bone = BoneSet.empty(h * options.bone_sigma)
    # an estimated focal length is decided by the bones, and a bone's curvature bias
    # biases it: the bone rule of the focal options (FocalOptions.bone_bias_limit)
    bias_limit = options.focal.bone_bias_limit if calibrated else options.bone_bias_limit
    if need_lengths and len(names):
        both = used[:, pairs[:, 0]] & used[:, pairs[:, 1]]                     # (T, B)
        keep = both
        if bias_limit is not None:
            bias = bone_curvature_bias(rig, points, used, planes, pairs,
                                       median_bone_lengths(points, pairs, both),
                                       options.pixel_sigma)
            keep = both & ~(bias > bias_limit * h * options.bone_sigma)
        bone = BoneSet.make(keep, points, names, pairs, flat, J, h * options.bone_sigma,
                            bone_lengths)
        if bone.lengths is not None:
            record_prior(info, "bone_length", bone.sigma, "length", len(bone.rows))
            info["bone_length"].update(
                frames=int(np.count_nonzero(keep.any(1))), bias_limit=bias_limit,
                left_out=float(1.0 - keep.sum() / max(int(both.sum()), 1)))
    return bone


def _prior_factors(rig: Rig, points: np.ndarray, used: np.ndarray, var: _Variables, h: float,
                   options: RefineOptions, info: dict, bone: BoneSet, *, priors: bool
                   ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.NonlinearFactorGraph]:
    """The per-frame priors (the intrinsics' priors, hip, smoothness) and the length-only
    priors (symmetry; anthropometry unless a focal length is estimated without
    ``options.focal.anthropometry``) of :mod:`.priors`: two graphs."""
    prior_graph = gtsam.NonlinearFactorGraph()
    length_priors = gtsam.NonlinearFactorGraph()
    if bone.lengths is not None:
        add_symmetry(rig, length_priors, bone.names, h * options.symmetry_sigma, options, info)
        if not var.calibration_keys or options.focal.anthropometry:
            add_anthropometry(rig, length_priors, bone.names, options, info)
    for c, (kk, _) in var.calibration_keys.items():
        add_focal_prior(rig.cameras[c], kk, prior_graph, info)
    if priors and options.use_hip:
        add_hip(rig, prior_graph, used, var.keys, h, options, info)
    if priors and options.use_smoothness:
        add_smoothness(rig, prior_graph, var.values, used, var.keys, points,
                       h * options.smoothness_sigma, options.smoothness_max_gap, info)
    return prior_graph, length_priors


def _gauge(rig: Rig, planes: list[tuple[np.ndarray, float]], options: RefineOptions,
           info: dict, bone: BoneSet, *, priors: bool, length_sum: float | None,
           calibrated: bool):
    """The gauge: a prior on the sum of the bone lengths (Winter's for the subject's
    height, the lengths this graph starts from where they are a variable, else
    ``length_sum`` or the initial sum), each bone weighted by its frames where the
    lengths are a variable (``calibrated``, :func:`~.priors.gauge_weights`); without
    bone lengths the first mirror's distance.

    Returns:
        The gauge graph, the distance held (``None`` with a length sum), the scale
        (``"subject_height"`` or ``"unit_distance"``) and the bones' weights (``None``
        unless ``calibrated``).
    """
    gauge = gtsam.NonlinearFactorGraph()
    distance_gauge = None
    scale = "unit_distance"
    # where the lengths are a variable of the graph (an estimated focal length) the
    # gauge weighs each bone by its frames (gauge_weights)
    weights = (gauge_weights(bone.rows, len(bone.names))
               if calibrated and bone.lengths is not None else None)
    if priors and bone.lengths is not None:
        if options.subject_height is not None:
            expected = expected_bone_lengths(rig.skeleton, float(options.subject_height))
            reference = np.array([expected[b] for b in bone.names])
            scale = "subject_height"
        elif weights is not None:       # the scale of the lengths this graph starts from
            reference = np.asarray(bone.lengths, dtype=float)
        else:
            reference = None
        if weights is not None:
            total = float(weights @ reference)
        elif reference is not None:
            total = sum(float(x) for x in reference)
        else:
            total = float(length_sum if length_sum is not None else np.sum(bone.lengths))
        hp = HeightPriorFactor(total, weights=weights)
        gauge.push_back(hp.make(LENGTH_KEY))
        info["length_sum_gauge"] = {"sigma": hp.sigma, "weight": 1.0 / hp.sigma ** 2,
                                    "unit": "length (sum of bone lengths)", "factors": 1,
                                    "sum": total}
        if weights is not None:
            info["length_sum_gauge"]["bone_weights"] = {
                b: float(w) for b, w in zip(bone.names, weights)}
            info["length_sum_gauge"]["unit"] = ("length (sum of bone lengths, each weighted "
                                                "by its frames)")
        if scale == "subject_height":
            info["length_sum_gauge"].update(
                height_m=float(options.subject_height),
                relative_sigma_reported=float(options.height_sigma))
    elif planes:
        # no bone length to hold: the first mirror's distance is the gauge (metres when
        # the caller set it from the subject's height, see ``solve``)
        distance_gauge = float(planes[0][1])
        if priors and options.subject_height is not None:
            scale = "subject_height"
    return gauge, distance_gauge, scale, weights


def with_torso(problem: GraphProblem, torso: dict[str, float], options: RefineOptions
               ) -> GraphProblem:
    """``problem`` (a joints pass's graph, :func:`with_motion_priors`) with the torso's
    distances ``torso`` (``"a-b"`` joint names -> length, graph units) held with
    ``options.torso_sigma`` (:func:`~.priors.add_torso`) beside its priors, which are
    shared, not rebuilt; ``problem`` itself unchanged."""
    if not torso or options.torso_sigma is None or not options.use_bone_length:
        return problem
    T, J = problem.used.shape
    keys = np.zeros(T * J, dtype=np.uint64)
    keys[problem.flat_index] = np.uint64(X_BASE) + problem.flat_index.astype(np.uint64)
    graph = gtsam.NonlinearFactorGraph()
    graph.push_back(problem.priors)
    info = {k: dict(v) for k, v in problem.prior_info.items()}
    add_torso(problem.rig, graph, problem.used, keys.reshape(T, J), torso,
              problem.body_height * options.torso_sigma, info)
    return replace(problem, priors=graph, prior_info=info)


def with_motion_priors(problem: GraphProblem, values: gtsam.Values, lengths: dict[str, float],
                       options: RefineOptions, torso: dict[str, float] | None = None
                       ) -> GraphProblem:
    """The graph of the joints pass: ``problem``'s variables and reprojection factors, other
    body priors.

    Every bone of ``lengths`` (a bone it lacks at its left/right partner's length,
    :func:`~.priors.other_side_lengths`) in every frame where both its joints are estimated (no
    curvature rule: the globals are held, a bone of known length holds the depth of
    joints whose rays meet at a small angle), the torso's distances no bone holds
    (``options.torso_sigma``, :func:`~.priors.add_torso`: a shoulder is tied to the
    hips), the hip prior, and the smoothness of ``options.smoothness_sigma``; no
    length-only factor and no gauge (the globals and the lengths are held). The
    reprojection factors are shared, not rebuilt.

    Args:
        problem: a built graph; values: its solution (the new graph starts there).
        lengths: bone name -> length (graph units), held.
        options: the priors' switches and sigmas (``use_smoothness`` and
            ``smoothness_sigma`` as the joints pass wants them).
        torso: the torso's distances (``"a-b"`` joint names -> length, graph units,
            :func:`~.priors.torso_lengths`), held; ``None``: no torso term.

    Returns:
        A :class:`~.problem.GraphProblem` with new ``priors``, ``bones``, ``values`` and
        ``prior_info``.
    """
    rig, used = problem.rig, problem.used
    T, J = used.shape
    keys = np.zeros(T * J, dtype=np.uint64)
    keys[problem.flat_index] = np.uint64(X_BASE) + problem.flat_index.astype(np.uint64)
    keys = keys.reshape(T, J)
    points = extract_points(problem, values)
    start = gtsam.Values(values)
    if problem.length_key is not None:            # the lengths are held here
        start.erase(problem.length_key)
    graph, info = gtsam.NonlinearFactorGraph(), {}
    lengths, other_side = other_side_lengths(rig.skeleton, lengths)
    names, pairs = bone_table(rig)
    sel = [i for i, b in enumerate(names) if b in lengths]
    names, pairs = [names[i] for i in sel], pairs[sel]
    h = problem.body_height
    bone = BoneSet.empty(h * options.bone_sigma)
    if options.use_bone_length and len(names):
        both = used[:, pairs[:, 0]] & used[:, pairs[:, 1]]
        bone = BoneSet.make(both, points, names, pairs, problem.flat_index, J,
                            h * options.bone_sigma, lengths)
        if bone.lengths is not None:
            record_prior(info, "bone_length", bone.sigma, "length", len(bone.rows))
            if other_side and "bone_length" in info:
                info["bone_length"]["from_other_side"] = [b for b in other_side
                                                          if b in bone.names]
    if options.use_bone_length and options.torso_sigma is not None and torso:
        add_torso(rig, graph, used, keys, torso, h * options.torso_sigma, info)
    if options.use_hip:
        add_hip(rig, graph, used, keys, h, options, info)
    if options.use_smoothness:
        add_smoothness(rig, graph, start, used, keys, points, h * options.smoothness_sigma,
                       options.smoothness_max_gap, info)
    distance_gauge = float(extract_planes(problem, values)[0][1]) if problem.plane_keys else None
    return replace(problem, priors=graph, lengths=bone.lengths, bone_names=bone.names,
                   bone_rows=bone.rows, bone_sigma=bone.sigma,
                   bones=bone_graph(bone.rows, problem.flat_index, bone.lengths, bone.sigma),
                   length_priors=gtsam.NonlinearFactorGraph(),
                   gauge=gtsam.NonlinearFactorGraph(), values=start, prior_info=info,
                   distance_gauge=distance_gauge, length_key=None)



