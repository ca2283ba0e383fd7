"""Build the factor graph of a rig: variables, initial values and every factor.

Variables (keys from :mod:`gtsam.symbol_shorthand`):

* ``X(t * J + j)``: :class:`gtsam.Point3`, joint ``j`` in frame row ``t`` (world
  frame), only for the pairs marked used;
* ``P(m)``: :class:`gtsam.OrientedPlane3`, mirror ``m``;
* ``V(v)``: :class:`gtsam.Pose3`, the virtual camera of view ``v`` (mirror views);
* ``C(c)``: :class:`gtsam.Pose3`, the pose (camera-to-world) of camera ``c`` where
  it is estimated (:attr:`Camera.estimate_pose`); a fixed camera has no variable,
  unless its intrinsics are estimated: then ``C(c)`` is a *held* variable (the
  factor that takes the calibration as a variable needs a pose key; the solver
  never moves it, :mod:`.reduction`);
* ``K(c)``, ``Q(c)``: :class:`gtsam.Cal3_S2`, the calibration ``K`` of camera ``c``
  and the mirrored one ``K D = (-fx, fy, s, cx, cy)`` of its mirror views, where its
  intrinsics are estimated (:attr:`Camera.estimate_focal`): two variables, one
  unknown ``f`` (and ``cx, cy``), kept equal by the solver (:mod:`.reduction`);
* the bone lengths are not variables of the linear systems: the bone factors are
  range factors holding them, set between linearisations (:mod:`.lengths`);
  the length-only priors and the gauge act on the vector :data:`LENGTH_KEY` of
  that small problem. Where a camera's intrinsics are estimated the lengths are
  strongly coupled to its focal length (which only the bones' constancy
  determines) and the vector ``L(0)`` is a variable of the graph instead
  (:attr:`GraphProblem.length_key`): one factor per frame on its joints and ``L``
  (:meth:`~mirrorgraph.factors.BoneLengthFactor.add_frames`), the length-only priors
  and the gauge in the graph too.

Factors are kept in separate graphs so that the solver can use subsets:
``reprojection`` (every view), ``links`` (one :class:`MirrorLinkFactor` per mirror
view), ``priors`` (the per-frame body priors other than the bones: hip,
smoothness), ``bones`` (one range factor per frame and bone, at the held
lengths), ``length_priors`` (symmetry, anthropometry) and ``gauge`` (the
bone-length sum) of the length problem; without bone lengths a distance prior on
the plane, applied by :mod:`.reduction`. :meth:`GraphProblem.full` is the graph
of the joints and globals. The solver (:mod:`.optimizer`) does not put the links
in the least-squares system: it enforces them exactly (:mod:`.reduction`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import gtsam
import numpy as np
from gtsam.symbol_shorthand import C as C_, K as K_, L as L_, P as P_, Q as Q_, V as V_, X as X_

from ..anthropometry import expected_bone_lengths, femur_ratios, height_fractions
from ..factors import (AnthropometricRatioFactor, BoneLengthFactor, HeightPriorFactor, HipColinearityFactor, MirrorLinkFactor,
                       ReprojectionFactors, SmoothnessFactor, SymmetryFactor, calibration,
                       mirrored_calibration, plane_from_gtsam, plane_to_gtsam, reflected_pose,
                       robust_pixel_noise)
from ..geometry import triangulation_covariance
from .options import RefineOptions
from .rig import Rig, view_projections

__all__ = ["GraphProblem", "LENGTH_KEY", "build_problem", "with_motion_priors", "point_keys", "bone_table", "body_height_from_points",
           "debiased_bone_lengths", "extract_points", "extract_planes", "extract_camera_poses",
           "extract_intrinsics", "camera_matrix",
           "snap_virtual_poses", "cheirality_guard", "points_array"]

_X_BASE = X_(0)

#: Key of the bone-length vector in the length problem (:mod:`.lengths`): the
#: length-only priors and the gauge are factors on it; it is not a variable of the
#: graph of the joints.
LENGTH_KEY = L_(0)


def point_keys(flat_index: np.ndarray) -> list[int]:
    """Keys ``X(i)`` of flat point indices ``i = t * J + j`` (vectorised)."""
    return (np.uint64(_X_BASE) + np.asarray(flat_index, dtype=np.uint64)).tolist()


def bone_table(rig: Rig) -> tuple[list[str], np.ndarray]:
    """Bones whose two joints are both estimated: names and ``(B, 2)`` joint indices."""
    sk = rig.skeleton
    keep = set(np.asarray(rig.joints, dtype=int).tolist())
    names, pairs = [], []
    for name, (a, b) in zip(sk.bone_names, sk.bone_index):
        if int(a) in keep and int(b) in keep:
            names.append(name)
            pairs.append((int(a), int(b)))
    return names, np.array(pairs, dtype=int).reshape(-1, 2)


def body_height_from_points(rig: Rig, points: np.ndarray, used: np.ndarray) -> float:
    """Subject height in the points' length unit, from median bone lengths (Winter's fractions).

    Args:
        points: ``(T, J, 3)``; used: ``(T, J)`` bool.

    Returns:
        The median over bones of ``median_t |X_a - X_b| / fraction``; NaN if no bone is seen.
    """
    names, pairs = bone_table(rig)
    fr = height_fractions(rig.skeleton)
    est = []
    for name, (a, b) in zip(names, pairs):
        ok = used[:, a] & used[:, b]
        if ok.any():
            est.append(np.median(np.linalg.norm(points[ok, a] - points[ok, b], axis=1)) / fr[name])
    return float(np.median(est)) if est else float("nan")


@dataclass
class GraphProblem:
    """A built graph with its bookkeeping.

    Attributes:
        rig: the rig.
        used: ``(T, J)`` bool, the estimated points.
        flat_index: ``(N,)`` ``t * J + j`` of the used points, ascending (key order).
        plane_keys: ``P(m)`` per mirror.
        virtual_keys: view index -> ``V(v)`` for the mirror views.
        camera_keys: camera index -> ``C(c)`` for the cameras whose pose is estimated.
        calibration_keys: camera index -> ``(K(c), Q(c))`` for the cameras whose
            intrinsics are estimated (``Q(c)``: ``None`` without a mirror view).
        held_pose_keys: camera index -> ``C(c)`` for the fixed cameras whose
            intrinsics are estimated (a pose variable the solver holds).
        length_key: :data:`LENGTH_KEY` where the bone lengths are a variable of the
            graph (a camera's intrinsics are estimated), else ``None`` (held lengths).
        lengths: ``(B,)`` the held bone lengths (graph units), ``None`` without bone
            factors; bone_names: their bones.
        bone_rows: ``(N, 3)`` int, one row per bone factor: the positions of its two
            joints in the key-ordered points (:func:`points_array`) and its bone.
        bone_sigma: the bone factors' standard deviation (graph units).
        reprojection: reprojection factors of every view.
        links: the mirror-link factors (virtual pose = reflected camera).
        priors: per-frame body-prior factors other than the bones (hip, smoothness).
        bones: the bone factors at :attr:`lengths` (:meth:`set_lengths`).
        length_priors: factors on the bone lengths only (symmetry, anthropometry), on
            :data:`LENGTH_KEY`.
        gauge: the bone-length-sum prior (empty without bone lengths), on :data:`LENGTH_KEY`.
        distance_gauge: ``d`` held by a distance prior when there is no length sum
            to hold, else ``None``.
        scale: ``"subject_height"`` (metres) or ``"unit_distance"`` (the result is
            rescaled to ``d = 1``).
        values: initial values of every variable.
        body_height: subject height in graph units (sets the prior sigmas).
        median_depth: median depth ``Z`` of the initial points (graph units).
        prior_info: prior name -> ``{"sigma", "weight", "unit", "factors"}``.
    """

    rig: Rig
    used: np.ndarray
    flat_index: np.ndarray
    plane_keys: list[int]
    virtual_keys: dict[int, int]
    camera_keys: dict[int, int]
    lengths: np.ndarray | None
    bone_names: list[str]
    bone_rows: np.ndarray
    bone_sigma: float
    reprojection: gtsam.NonlinearFactorGraph
    links: gtsam.NonlinearFactorGraph
    priors: gtsam.NonlinearFactorGraph
    bones: gtsam.NonlinearFactorGraph
    length_priors: gtsam.NonlinearFactorGraph
    gauge: gtsam.NonlinearFactorGraph
    distance_gauge: float | None
    values: gtsam.Values
    body_height: float
    median_depth: float
    scale: str
    prior_info: dict[str, dict] = field(default_factory=dict)
    calibration_keys: dict[int, tuple[int, int | None]] = field(default_factory=dict)
    held_pose_keys: dict[int, int] = field(default_factory=dict)
    length_key: int | None = None

    def full(self, links: bool = False) -> gtsam.NonlinearFactorGraph:
        """The graph of the joints and globals: reprojection, body priors and the bone
        factors at the held lengths (and the soft links if asked, for GTSAM's own
        optimisers); with the lengths a variable (:attr:`length_key`) the bone factors
        on them, the length-only priors and the gauge."""
        g = gtsam.NonlinearFactorGraph(self.reprojection)
        g.push_back(self.priors)
        g.push_back(self.bones)
        if self.length_key is not None:
            g.push_back(self.length_priors)
            g.push_back(self.gauge)
        if links:
            g.push_back(self.links)
        return g

    def set_lengths(self, lengths: np.ndarray) -> None:
        """Hold the bones at ``lengths`` (``(B,)``, :attr:`bone_names` order): the bone
        factors are made again with them (with the lengths a variable, their value in
        :attr:`values` is set instead)."""
        self.lengths = np.asarray(lengths, dtype=float).copy()
        if self.length_key is not None:
            self.values.update(self.length_key, self.lengths)
            return
        self.bones = _bone_graph(self.bone_rows, self.flat_index, self.lengths, self.bone_sigma)

    def bone_lengths(self) -> dict[str, float]:
        """Bone name -> held length (empty without bone factors)."""
        if self.lengths is None:
            return {}
        return {b: float(x) for b, x in zip(self.bone_names, self.lengths)}

    @property
    def global_keys(self) -> list[int]:
        """Keys shared by all frames: virtual poses, camera poses (held ones too),
        calibrations, planes."""
        calib = [k for pair in self.calibration_keys.values() for k in pair if k is not None]
        return (list(self.virtual_keys.values()) + list(self.camera_keys.values())
                + list(self.held_pose_keys.values()) + calib + list(self.plane_keys))

    def intrinsics(self, index: int, values: gtsam.Values) -> np.ndarray:
        """``(3, 3)`` camera matrix of camera ``index``: its variable, or the fixed ``K``."""
        keys = self.calibration_keys.get(index)
        if keys is not None:
            return camera_matrix(values.atCal3_S2(keys[0]))
        return np.asarray(self.rig.cameras[index].K, dtype=float)

    def camera_pose(self, index: int, values: gtsam.Values) -> gtsam.Pose3:
        """Pose (camera-to-world) of camera ``index``: its variable, or the fixed pose."""
        key = self.camera_keys.get(index)
        if key is not None:
            return values.atPose3(key)
        return self.rig.cameras[index].gtsam_pose

    def point_ordering(self) -> gtsam.Ordering:
        """Elimination ordering of the points: frame-major (row ``t``, then joint).

        The smoothness factors make the graph a band along time; eliminating
        frame after frame is the natural banded ordering. Measured on 1000
        frames x 12 joints it eliminates as fast as COLAMD (0.30 s vs 0.32 s)
        and costs nothing to compute (COLAMD: ~0.1 s per graph).
        """
        o = gtsam.Ordering()
        for k in point_keys(self.flat_index):
            o.push_back(k)
        return o


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
    keys[flat] = np.uint64(_X_BASE) + flat.astype(np.uint64)
    keys = keys.reshape(T, J)
    if body_height is None:
        body_height = body_height_from_points(rig, points, used)
    h = float(body_height)

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

    repro = gtsam.NonlinearFactorGraph()
    links = gtsam.NonlinearFactorGraph()
    virtual_keys: dict[int, int] = {}
    if priors:
        noise = robust_pixel_noise(options.pixel_sigma, final_kernel,
                                   options.final_kernel_scale_px)
    else:
        noise = robust_pixel_noise(options.pixel_sigma, options.robust_kernel,
                                   options.kernel_scale_px)
    for vi, view in enumerate(rig.views):
        ci = rig.camera_index(view.camera)
        cam = rig.cameras[ci]
        ck = camera_keys.get(ci)
        fac = ReprojectionFactors(cam.K, noise, cam.gtsam_pose)
        mask = used & np.asarray(view.mask, dtype=bool)
        idx = np.flatnonzero(mask.ravel())
        uv = np.asarray(view.pixels, dtype=float).reshape(-1, 2)[idx]
        calib = calibration_keys.get(ci)
        if view.mirror is None:
            if calib is not None:
                pose_key = ck if ck is not None else held_pose_keys[ci]
                fac.add_calibrated(repro, uv, pose_key, calib[0], keys.ravel()[idx])
            elif ck is None:
                fac.add_direct(repro, uv, keys.ravel()[idx])
            else:
                fac.add_posed(repro, uv, ck, keys.ravel()[idx])
            continue
        m = rig.mirror_index(view.mirror)
        vk = V_(vi)
        virtual_keys[vi] = vk
        n, d = planes[m]
        values.insert(vk, reflected_pose(n, d, cam.gtsam_pose))
        if calib is not None:
            fac.add_calibrated(repro, uv, vk, calib[1], keys.ravel()[idx])
        else:
            fac.add_mirror(repro, uv, vk, keys.ravel()[idx])
        link = MirrorLinkFactor(options.link_sigma_rotation, options.link_sigma_translation,
                                camera_pose=cam.gtsam_pose)
        links.push_back(link.make(plane_keys[m], vk, ck))

    prior_graph = gtsam.NonlinearFactorGraph()
    length_priors = gtsam.NonlinearFactorGraph()
    info: dict[str, dict] = {}
    names, pairs = bone_table(rig)
    if bones is not None:
        sel = [i for i, b in enumerate(names) if b in set(bones)]
        names, pairs = [names[i] for i in sel], pairs[sel]
    need_lengths = priors and (options.use_bone_length or options.subject_height is not None)
    bone = _BoneSet.empty(h * options.bone_sigma)
    # an estimated focal length is decided by the bones, and a bone's curvature bias
    # biases it: the bone rule of the focal options (FocalOptions.bone_bias_limit)
    bias_limit = options.focal.bone_bias_limit if calibration_keys else options.bone_bias_limit
    if need_lengths and len(names):
        both = used[:, pairs[:, 0]] & used[:, pairs[:, 1]]                     # (T, B)
        keep = both
        if bias_limit is not None:
            bias = bone_curvature_bias(rig, points, used, planes, pairs,
                                       _median_lengths(points, pairs, both), options.pixel_sigma)
            keep = both & ~(bias > bias_limit * h * options.bone_sigma)
        bone = _BoneSet.make(keep, points, names, pairs, flat, J, h * options.bone_sigma,
                             bone_lengths)
        if bone.lengths is not None:
            _record(info, "bone_length", bone.sigma, "length", len(bone.rows))
            info["bone_length"].update(
                frames=int(np.count_nonzero(keep.any(1))), bias_limit=bias_limit,
                left_out=float(1.0 - keep.sum() / max(int(both.sum()), 1)))
    if bone.lengths is not None:
        _add_symmetry(rig, length_priors, bone.names, h * options.symmetry_sigma, options, info)
        if not calibration_keys or options.focal.anthropometry:
            _add_anthropometry(rig, length_priors, bone.names, options, info)
    for c, (kk, _) in calibration_keys.items():
        _add_focal_prior(rig.cameras[c], kk, prior_graph, info)
    if priors and options.use_hip:
        _add_hip(rig, prior_graph, used, keys, h, options, info)
    if priors and options.use_smoothness:
        _add_smoothness(rig, prior_graph, values, used, keys, points, h * options.smoothness_sigma,
                        options.smoothness_max_gap, info)

    gauge = gtsam.NonlinearFactorGraph()
    distance_gauge = None
    scale = "unit_distance"
    # where the lengths are a variable of the graph (an estimated focal length) the
    # gauge weighs each bone by its frames (gauge_weights)
    weights = (gauge_weights(bone.rows, len(bone.names))
               if calibration_keys and bone.lengths is not None else None)
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
    length_key = None
    if calibration_keys and bone.lengths is not None:
        # the lengths start on the gauge (its residual, of weight 1e12, would otherwise
        # dwarf every other term of the first error, and with it the solver's tolerances)
        length_key = LENGTH_KEY
        bone.lengths = np.asarray(bone.lengths, dtype=float) * (
            info["length_sum_gauge"]["sum"] / float(weights @ np.asarray(bone.lengths, float)))
        values.insert(LENGTH_KEY, bone.lengths)
    return GraphProblem(rig=rig, used=used, flat_index=flat, plane_keys=plane_keys,
                        virtual_keys=virtual_keys, camera_keys=camera_keys,
                        lengths=bone.lengths, bone_names=bone.names, bone_rows=bone.rows,
                        bone_sigma=bone.sigma, reprojection=repro, links=links,
                        priors=prior_graph,
                        bones=_bone_graph(bone.rows, flat, bone.lengths, bone.sigma,
                                          J=J, length_key=length_key),
                        length_priors=length_priors,
                        gauge=gauge,
                        distance_gauge=distance_gauge,
                        values=values, body_height=h,
                        median_depth=float(np.median(pts[:, 2])) if len(pts) else 1.0,
                        scale=scale, prior_info=info, calibration_keys=calibration_keys,
                        held_pose_keys=held_pose_keys, length_key=length_key)


def with_motion_priors(problem: GraphProblem, values: gtsam.Values, lengths: dict[str, float],
                       options: RefineOptions) -> GraphProblem:
    """The graph of the joints pass: ``problem``'s variables and reprojection factors, other
    body priors.

    Every bone of ``lengths`` in every frame where both its joints are estimated (no
    curvature rule: the globals are held, a bone of known length holds the depth of
    joints whose rays meet at a small angle), the hip prior, and the smoothness of
    ``options.smoothness_sigma``; no length-only factor and no gauge (the globals
    and the lengths are held). The reprojection factors are shared, not rebuilt.

    Args:
        problem: a built graph; values: its solution (the new graph starts there).
        lengths: bone name -> length (graph units), held.
        options: the priors' switches and sigmas (``use_smoothness`` and
            ``smoothness_sigma`` as the joints pass wants them).

    Returns:
        A :class:`GraphProblem` with new ``priors``, ``bones``, ``values`` and
        ``prior_info``.
    """
    rig, used = problem.rig, problem.used
    T, J = used.shape
    keys = np.zeros(T * J, dtype=np.uint64)
    keys[problem.flat_index] = np.uint64(_X_BASE) + problem.flat_index.astype(np.uint64)
    keys = keys.reshape(T, J)
    points = extract_points(problem, values)
    start = gtsam.Values(values)
    if problem.length_key is not None:            # the lengths are held here
        start.erase(problem.length_key)
    graph, info = gtsam.NonlinearFactorGraph(), {}
    names, pairs = bone_table(rig)
    sel = [i for i, b in enumerate(names) if b in lengths]
    names, pairs = [names[i] for i in sel], pairs[sel]
    h = problem.body_height
    bone = _BoneSet.empty(h * options.bone_sigma)
    if options.use_bone_length and len(names):
        both = used[:, pairs[:, 0]] & used[:, pairs[:, 1]]
        bone = _BoneSet.make(both, points, names, pairs, problem.flat_index, J,
                             h * options.bone_sigma, lengths)
        if bone.lengths is not None:
            _record(info, "bone_length", bone.sigma, "length", len(bone.rows))
    if options.use_hip:
        _add_hip(rig, graph, used, keys, h, options, info)
    if options.use_smoothness:
        _add_smoothness(rig, graph, start, used, keys, points, h * options.smoothness_sigma,
                        options.smoothness_max_gap, info)
    distance_gauge = float(extract_planes(problem, values)[0][1]) if problem.plane_keys else None
    return replace(problem, priors=graph, lengths=bone.lengths, bone_names=bone.names,
                   bone_rows=bone.rows, bone_sigma=bone.sigma,
                   bones=_bone_graph(bone.rows, problem.flat_index, bone.lengths, bone.sigma),
                   length_priors=gtsam.NonlinearFactorGraph(),
                   gauge=gtsam.NonlinearFactorGraph(), values=start, prior_info=info,
                   distance_gauge=distance_gauge, length_key=None)


def _record(info: dict, name: str, sigma: float, unit: str, count: int) -> None:
    if count:
        info[name] = {"sigma": float(sigma), "weight": 1.0 / float(sigma) ** 2, "unit": unit,
                      "factors": int(count)}


def bone_curvature_bias(rig: Rig, points: np.ndarray, used: np.ndarray,
                        planes: list[tuple[np.ndarray, float]], pairs: np.ndarray,
                        lengths: np.ndarray, pixel_sigma: float) -> np.ndarray:
    """``(T, B)`` bound on the second-order bias of each bone's length measured from noisy joints.

    A bone's length ``|X_a - X_b|`` is a curved function of its joints: noise across
    the bone lengthens it on average by ``tr(P S) / (2 L)`` (the expectation of
    ``|x + e|`` to second order in ``e``), ``S = Sigma_a + Sigma_b`` the two joints'
    triangulation covariances (:func:`~mirrorgraph.geometry.triangulation_covariance`),
    ``P = I - u u^T`` the projection across the bone's direction ``u``, ``L`` its
    length. Where the joints' rays meet at a small angle their depth error is
    centimetres and a bone across the line of sight (a standing person's thigh seen
    from the front) is measured decimetres long on average: a bone-length factor
    there is a biased measurement, and the joint optimum of the mirror and the
    per-frame depths with it is biased too, however many frames there are (Neyman
    and Scott's incidental parameters).

    The bound ``tr(S) / (2 L)`` is returned, which does not depend on the bone's
    measured direction: a rule that kept a bone where its *measured* direction runs
    along the line of sight would keep exactly the frames whose depth noise made it
    long (a selection bias of the same sign).

    Args:
        points: ``(T, J, 3)`` joints (world frame); used: ``(T, J)`` bool.
        planes: ``(n, d)`` per mirror; pairs: ``(B, 2)`` joint indices of the bones.
        lengths: ``(B,)`` each bone's length (the points' unit).
        pixel_sigma: pixel noise, px.

    Returns:
        The bound in the points' length unit; NaN where a joint is not used.
    """
    masks = [np.asarray(v.mask, bool) & used for v in rig.views]
    cov = triangulation_covariance(view_projections(rig, None, planes), points, masks,
                                   pixel_sigma)                                  # (T, J, 3, 3)
    var = np.trace(cov, axis1=-2, axis2=-1)                                     # (T, J)
    total = var[:, pairs[:, 0]] + var[:, pairs[:, 1]]
    return total / (2.0 * np.maximum(np.asarray(lengths, dtype=float), 1e-12))


def debiased_bone_lengths(rig: Rig, points: np.ndarray, used: np.ndarray,
                          planes: list[tuple[np.ndarray, float]], pairs: np.ndarray,
                          pixel_sigma: float, outlier_k: float = 10.0,
                          min_frames: int = 10) -> np.ndarray:
    """``(B,)`` bone lengths from noisy triangulated joints, free of the curvature bias.

    ``E |d|^2 = L^2 + tr(S)`` for a bone ``d = X_a - X_b`` measured with zero-mean noise
    of covariance ``S = Sigma_a + Sigma_b``, whatever the bone's direction (the
    corrected-score idea of measurement-error models: Stefanski 1989, Nakamura 1990).
    So ``L^2`` is estimated by the mean over frames of ``|d|^2 - tr(S)``
    (:func:`~mirrorgraph.geometry.triangulation_covariance`), where the median of
    ``|d|`` would be decimetres long for joints whose rays meet at a small angle
    (:func:`bone_curvature_bias`). Values beyond ``outlier_k`` robust standard
    deviations (1.4826 MAD) of their median are left out first (a mean, unlike a
    trimmed one, stays unbiased on the skewed distribution of ``|d|^2``; a cut at 5
    MAD took that skewed tail off a forearm at low parallax, 4 % short, at 10 MAD
    the lengths of three low-parallax scenes are 0.07 % short on average, 1.4 % at
    most).

    Args:
        points: ``(T, J, 3)`` joints triangulated from the views (not pulled by priors);
            used: ``(T, J)`` bool.
        planes: ``(n, d)`` per mirror; pairs: ``(B, 2)`` joint indices.
        pixel_sigma: pixel noise, px.
        outlier_k: the outlier cut, robust standard deviations.
        min_frames: frames a bone needs.

    Returns:
        The lengths in the points' unit; NaN for a bone seen in under ``min_frames``
        frames or whose corrected square is not positive.
    """
    masks = [np.asarray(v.mask, bool) & used for v in rig.views]
    cov = triangulation_covariance(view_projections(rig, None, planes), points, masks,
                                   pixel_sigma)
    var = np.trace(cov, axis1=-2, axis2=-1)                                     # (T, J)
    pts = np.asarray(points, dtype=float)
    sq = np.sum((pts[:, pairs[:, 0]] - pts[:, pairs[:, 1]]) ** 2, axis=-1)      # (T, B)
    corrected = sq - var[:, pairs[:, 0]] - var[:, pairs[:, 1]]
    out = np.full(len(pairs), np.nan)
    for b in range(len(pairs)):
        v = corrected[:, b][np.isfinite(corrected[:, b])]
        if len(v) < min_frames:
            continue
        med = np.median(v)
        mad = 1.4826 * np.median(np.abs(v - med))
        m = float(np.mean(v[np.abs(v - med) <= outlier_k * mad])) if mad > 0 else float(med)
        if m > 0:
            out[b] = np.sqrt(m)
    return out


def gauge_weights(rows: np.ndarray, num_bones: int) -> np.ndarray:
    """``(B,)`` weight of each bone length in the gauge where the lengths are a variable
    of the graph: its frames (rows of ``rows[:, 2]``), scaled to a mean of 1.

    The gauge holds a sum of lengths, and every other length-valued term (a bone's
    constancy, the smoothness) costs less in a smaller scene (:mod:`mirrorgraph.factors.
    gauge`): a plain sum lets a bone that few frames measure carry it, stretched (its
    joints moved along their lines of sight, cheap in a few frames) while the rest of
    the body and the scene shrink. Without the anthropometric ratios, which tie every
    length to the others (:attr:`~.options.FocalOptions.anthropometry` leaves them out
    where a focal length is estimated), nothing else stops it: a hip width measured in
    one frame of 960 was stretched to 12 times the shoulder width, the scene shrank 3.5
    times, the stature measured on the distorted body put the mirror 30 % short
    (issue #17). Weighted by its frames (the information of its mean length, as in
    :func:`~.lengths.update_lengths`), a bone moves the gauge in proportion to what
    holds it: the shrink a stretch buys is the same per frame whichever bone it is.
    """
    n = np.bincount(np.asarray(rows, dtype=np.int64)[:, 2], minlength=num_bones)
    n = n[:num_bones].astype(float)
    return n * (num_bones / n.sum()) if n.sum() > 0 else np.ones(num_bones)


def _median_lengths(points: np.ndarray, pairs: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``(B,)`` median over the frames of ``mask`` (``(T, B)``) of each bone's length
    (NaN for a bone never in ``mask``)."""
    d = np.linalg.norm(np.asarray(points, float)[:, pairs[:, 0]]
                       - np.asarray(points, float)[:, pairs[:, 1]], axis=-1)
    with np.errstate(invalid="ignore"):
        return np.array([np.median(d[mask[:, b], b]) if mask[:, b].any() else np.nan
                         for b in range(len(pairs))])


@dataclass
class _BoneSet:
    """The bone factors of a graph: which (frame, bone) pairs, their held lengths."""

    names: list[str]
    rows: np.ndarray            # (N, 3): key-order positions of the two joints, bone index
    lengths: np.ndarray | None
    sigma: float

    @classmethod
    def empty(cls, sigma: float) -> "_BoneSet":
        return cls([], np.zeros((0, 3), dtype=np.int64), None, float(sigma))

    @classmethod
    def make(cls, keep: np.ndarray, points: np.ndarray, names: list[str], pairs: np.ndarray,
             flat: np.ndarray, J: int, sigma: float, init: dict[str, float] | None
             ) -> "_BoneSet":
        """The bones of ``keep`` (``(T, B)``), their lengths from ``init`` or else the
        median over the kept frames; ``flat``: the used points' ``t * J + j`` (key order)."""
        present = np.flatnonzero(keep.any(0))
        if len(present) == 0:
            return cls.empty(sigma)
        names = [names[b] for b in present]
        pairs, keep = pairs[present], keep[:, present]
        medians = _median_lengths(points, pairs, keep)
        lengths = np.array([float(init[n]) if init is not None and n in init else medians[b]
                            for b, n in enumerate(names)])
        pos = np.full(keep.shape[0] * J, -1, dtype=np.int64)
        pos[flat] = np.arange(len(flat))
        t, b = np.nonzero(keep)
        rows = np.stack([pos[t * J + pairs[b, 0]], pos[t * J + pairs[b, 1]], b], axis=1)
        return cls(names, rows, lengths, float(sigma))


def _bone_graph(rows: np.ndarray, flat: np.ndarray, lengths: np.ndarray | None,
                sigma: float, J: int | None = None, length_key: int | None = None
                ) -> gtsam.NonlinearFactorGraph:
    """The range factors of the bone ``rows`` (``(N, 3)``: key-order positions of the two
    joints among the used points ``flat`` (``t * J + j``), bone index) at ``lengths``;
    with ``length_key`` one factor per frame on its joints and the length vector
    (``J`` joints a frame)."""
    graph = gtsam.NonlinearFactorGraph()
    if lengths is None or len(rows) == 0:
        return graph
    keys = np.uint64(_X_BASE) + np.asarray(flat, dtype=np.uint64)
    factor = BoneLengthFactor(sigma)
    if length_key is not None:
        frames = np.asarray(flat, dtype=np.int64)[rows[:, 0]] // int(J)
        factor.add_frames(graph, keys[rows[:, 0]], keys[rows[:, 1]], rows[:, 2], frames,
                          length_key, len(lengths))
        return graph
    factor.add(graph, keys[rows[:, 0]], keys[rows[:, 1]],
               np.asarray(lengths, dtype=float)[rows[:, 2]])
    return graph


def _add_symmetry(rig, graph, bone_names, sigma, options, info):
    if not options.use_symmetry:
        return
    factor = SymmetryFactor(sigma)
    index = {b: i for i, b in enumerate(bone_names)}
    count = 0
    for left, right in rig.skeleton.symmetric_bones:
        if left in index and right in index:
            graph.push_back(factor.make(LENGTH_KEY, index[left], index[right]))
            count += 1
    _record(info, "symmetry", sigma, "length", count)


def _add_anthropometry(rig, graph, bone_names, options, info):
    if not options.use_anthropometry:
        return
    index = {b: i for i, b in enumerate(bone_names)}
    femurs = [index[b] for b in ("left_femur", "right_femur") if b in index]
    if not femurs:
        return
    ratios = femur_ratios(rig.skeleton)
    factor = AnthropometricRatioFactor(options.anthropometry_sigma)
    count = 0
    for name, i in index.items():
        if name.endswith("femur"):
            continue
        graph.push_back(factor.make(LENGTH_KEY, i, femurs, ratios[name]))
        count += 1
    _record(info, "anthropometry", options.anthropometry_sigma, "ratio (Winter 2009)", count)


#: Standard deviation of the principal point's prior where it is estimated without a
#: :attr:`~.rig.Camera.principal_point_prior`, fraction of the image width (``2 cx`` of
#: the initial ``K``): the loose prior of ``--principal-point free``.
PRINCIPAL_POINT_PRIOR = 0.05


#: Where a principal point has a prior of the population of cameras
#: (:attr:`~.rig.Camera.principal_point_prior`), the graph's factor holds it at this
#: fraction of that prior's sigma: the estimate keeps the centre, and the uncertainty
#: takes the population's spread (:func:`intrinsics_prior_sigmas`,
#: :func:`~.uncertainty.intrinsics_prior_spread`: a "consider" parameter). The people
#: pull it, but wrongly: on the independent generator's scenes estimating it from them
#: turned the mirror by 6.8 and 1.2 deg (0.008 and 0.016 with the true intrinsics), on a
#: 20 px offset the data moved it 42 px the other way (tests/graph/
#: test_focal_principal_point.py).
PRINCIPAL_POINT_HOLD = 1e-3


def intrinsics_prior(camera, population: bool = False) -> tuple[gtsam.Cal3_S2, np.ndarray] | None:
    """The prior of an estimated camera's intrinsics: its mean and ``(5,)`` sigmas on the
    :class:`gtsam.Cal3_S2` coordinates ``(fx, fy, s, cx, cy)`` (px), or ``None`` without
    one. ``fx`` and ``fy`` move together (one unknown ``f``): each at ``sigma sqrt(2)`` is
    ``sigma`` on ``f`` (:func:`intrinsics_prior_sigmas`). A principal point with a
    population prior is held in the graph (:data:`PRINCIPAL_POINT_HOLD`); ``population``:
    that prior's own sigma (the uncertainty's)."""
    if camera.focal_prior is None and not camera.estimate_principal_point:
        return None
    K = np.asarray(camera.K, dtype=float)
    f0, sigma = camera.focal_prior if camera.focal_prior is not None else (K[0, 0], 1e9)
    cx, cy = float(K[0, 2]), float(K[1, 2])
    sp = 1e9
    if camera.estimate_principal_point:
        if camera.principal_point_prior is not None:
            cx, cy, sp = (float(v) for v in camera.principal_point_prior)
            sp = sp if population else sp * PRINCIPAL_POINT_HOLD
        else:
            sp = PRINCIPAL_POINT_PRIOR * 2.0 * cx
    sigmas = np.array([sigma * np.sqrt(2.0), sigma * np.sqrt(2.0), 1e9, sp, sp])
    return gtsam.Cal3_S2(f0, f0, 0.0, cx, cy), sigmas


def intrinsics_prior_sigmas(camera) -> np.ndarray:
    """``(d,)`` the prior's standard deviations on the camera's reduced intrinsics
    (:mod:`.reduction`: ``f`` or ``f, cx, cy``, px; ``inf`` where it has none)."""
    d = camera.intrinsics_dim
    prior = intrinsics_prior(camera, population=True)
    if prior is None:
        return np.full(d, np.inf)
    s = prior[1]
    return np.array([s[0] / np.sqrt(2.0), s[3], s[4]])[:d]


def _add_focal_prior(camera, key, graph, info):
    """The prior of :func:`intrinsics_prior` on ``K(c)``: the weak one of
    :attr:`~.rig.Camera.focal_prior` on the focal length, and where the principal point
    is estimated its :attr:`~.rig.Camera.principal_point_prior`."""
    prior = intrinsics_prior(camera)
    if prior is None:
        return
    mean, sigmas = prior
    population = intrinsics_prior(camera, population=True)[1]
    graph.push_back(gtsam.PriorFactorCal3_S2(key, mean,
                                             gtsam.noiseModel.Diagonal.Sigmas(sigmas)))
    sigma = float(sigmas[0] / np.sqrt(2.0))
    info[f"focal_prior_{camera.name}"] = {"sigma": sigma, "weight": 1.0 / sigma ** 2,
                                          "unit": "px", "factors": 1,
                                          "focal_px": float(mean.fx())}
    if camera.estimate_principal_point:
        info[f"principal_point_prior_{camera.name}"] = {
            "sigma": float(population[3]), "weight": 1.0 / float(population[3]) ** 2,
            "unit": "px", "factors": 1, "principal_point_px": [float(mean.px()), float(mean.py())],
            "held": bool(sigmas[3] < population[3])}


def _add_hip(rig, graph, used, keys, h, options, info):
    sk = rig.skeleton
    if sk.mid_hip is None:
        return
    joints = set(np.asarray(rig.joints, dtype=int).tolist())
    m, lh, rh = sk.index(sk.mid_hip), sk.index("left_hip"), sk.index("right_hip")
    if not {m, lh, rh} <= joints:
        return
    scale = h * height_fractions(sk).get("left_pelvis", 0.0955)
    factor = HipColinearityFactor(scale, options.hip_sigma)
    frames = np.flatnonzero(used[:, m] & used[:, lh] & used[:, rh])
    for t in frames:
        graph.push_back(factor.make(int(keys[t, m]), int(keys[t, lh]), int(keys[t, rh])))
    _record(info, "hip", options.hip_sigma, "sine", len(frames))


def _add_smoothness(rig, graph, values, used, keys, points, sigma, max_gap, info):
    factor = SmoothnessFactor(sigma, max_gap)
    fid = np.asarray(rig.frame_ids, dtype=np.int64)
    triples = []
    for j in np.asarray(rig.joints, dtype=int):
        rows = np.flatnonzero(used[:, j])
        tri = rows[factor.triples(fid[rows])]
        if len(tri):
            triples.append(np.stack([tri, np.full_like(tri, j)], axis=-1))      # (M, 3, 2)
    count = 0
    if triples:
        tri = np.concatenate(triples)
        k = keys[tri[..., 0], tri[..., 1]]                                      # (M, 3)
        X = np.asarray(points, dtype=float)[tri[..., 0], tri[..., 1]]           # (M, 3, 3)
        factor.add_many(graph, k, fid[tri[..., 0]], X, values)
        count = len(tri)
    _record(info, "smoothness", sigma, "length / frame^2", count)


# --------------------------------------------------------------------------- read back
def extract_points(problem: GraphProblem, values: gtsam.Values) -> np.ndarray:
    """``(T, J, 3)`` points from ``values``, NaN where not estimated."""
    T, J = problem.used.shape
    out = np.full((T * J, 3), np.nan)
    out[problem.flat_index] = points_array(problem, values)
    return out.reshape(T, J, 3)


def points_array(problem: GraphProblem, values: gtsam.Values) -> np.ndarray:
    """``(N, 3)`` the used points of ``values`` in key order (``problem.flat_index`` order)."""
    pts = np.asarray(gtsam.utilities.extractPoint3(values), dtype=float).reshape(-1, 3)
    if len(pts) != len(problem.flat_index):       # other 3-vectors among the values
        pts = np.array([values.atPoint3(k) for k in point_keys(problem.flat_index)],
                       dtype=float).reshape(-1, 3)
    return pts


def cheirality_guard(problem: GraphProblem):
    """A guard for :class:`~.optimizer.LevenbergMarquardt`: every point stays in front
    of each camera that sees it, real or virtual, and in front of each mirror it is
    seen in.

    A point pushed behind a camera is where a projection factor's residual turns
    constant with a zero Jacobian (GTSAM's cheirality handling): the point loses
    that view's rows, its block turns singular and the next step is indeterminate.
    The guard puts such a point back at its previous value (a projection of the step
    onto the feasible set); the step is then judged on its error as usual.

    A step that moves a camera or a mirror past a point (the point, restored, is still
    behind it) cannot be repaired this way: the guard then says the step is infeasible
    (``None``) and the optimiser rejects it unevaluated (GTSAM's factors whose
    calibration is a variable give such a point a zero residual, and print a line
    per factor: on a scene of the independent generator with the focal length
    estimated a step turned the mirror's virtual camera past 10 683 joints).

    Returns:
        ``guard(previous, candidate, delta=None) -> int | None`` (points restored in
        ``candidate``, ``None``: the step is infeasible; ``delta`` the step that made
        it, for the points' new values).
    """
    rig = problem.rig
    T, J = problem.used.shape
    pos = np.full(T * J, -1, dtype=np.int64)
    pos[problem.flat_index] = np.arange(len(problem.flat_index))
    checks = []
    for vi, view in enumerate(rig.views):
        mask = (problem.used & np.asarray(view.mask, dtype=bool)).reshape(-1)
        idx = pos[np.flatnonzero(mask)]
        if len(idx) == 0:
            continue
        ci = rig.camera_index(view.camera)
        plane_key = (problem.plane_keys[rig.mirror_index(view.mirror)]
                     if view.mirror is not None else None)
        checks.append((idx, ci, problem.virtual_keys.get(vi), plane_key))
    keys = np.asarray(point_keys(problem.flat_index), dtype=np.uint64)

    def infeasible(values: gtsam.Values, X: np.ndarray) -> np.ndarray:
        bad = np.zeros(len(X), dtype=bool)
        for idx, ci, vkey, pkey in checks:
            pose = (values.atPose3(vkey) if vkey is not None
                    else problem.camera_pose(ci, values))
            R, c = np.asarray(pose.rotation().matrix()), np.asarray(pose.translation())
            with np.errstate(invalid="ignore"):
                bad[idx] |= ~(((X[idx] - c) @ R[:, 2]) > 0.0)
                if pkey is not None:
                    n, d = plane_from_gtsam(values.atOrientedPlane3(pkey))
                    bad[idx] |= ~(X[idx] @ n < d)
        return bad

    key_list = keys.tolist()
    cache: dict[str, object] = {"values": None, "X": None, "bad": None}

    def guard(previous: gtsam.Values, candidate: gtsam.Values,
              delta: gtsam.VectorValues | None = None) -> int:
        # the points of ``previous`` (cached: it is the last candidate when that was
        # accepted) and of ``candidate`` (a point's retraction is an addition, so
        # ``X + delta``: no per-key reads of 10^4 points)
        if cache["values"] is previous:
            Xp, bad_p = cache["X"], cache["bad"]
        else:
            Xp = points_array(problem, previous)
            bad_p = infeasible(previous, Xp)
        if delta is not None:
            Xc = Xp + np.asarray(delta.vector(key_list), dtype=float).reshape(-1, 3)
        else:
            Xc = points_array(problem, candidate)
        bad_c = infeasible(candidate, Xc)
        back = np.flatnonzero(bad_c & ~bad_p)
        if len(back):
            # restored, a point must be feasible for the candidate's cameras and
            # mirrors too: where the step moved a camera or mirror past it, no point
            # value of the step's makes it so, and the step is infeasible
            Xr = Xc.copy()
            Xr[back] = Xp[back]
            if np.any(infeasible(candidate, Xr)[back]):
                return None
        for i in back:                 # Values.update takes no Point3 from Python
            candidate.erase(int(keys[i]))
            candidate.insertPoint3(int(keys[i]), Xp[i])
        Xc[back], bad_c[back] = Xp[back], bad_p[back]
        cache.update(values=candidate, X=Xc, bad=bad_c)
        return int(len(back))

    return guard


def snap_virtual_poses(problem: GraphProblem, values: gtsam.Values) -> None:
    """Set every virtual camera pose in ``values`` to the reflection of its camera
    across its plane (in place): the hard form of the mirror link. Where a camera's
    intrinsics are estimated its mirrored calibration is set to ``K D`` of its ``K``
    too (and ``K`` to square pixels without skew)."""
    for c, (kk, qk) in problem.calibration_keys.items():
        K = camera_matrix(values.atCal3_S2(kk))
        f = 0.5 * (K[0, 0] + K[1, 1])
        K[0, 0] = K[1, 1] = f
        K[0, 1] = 0.0
        values.update(kk, calibration(K))
        if qk is not None:
            values.update(qk, mirrored_calibration(K))
    rig = problem.rig
    for vi, key in problem.virtual_keys.items():
        view = rig.views[vi]
        n, d = plane_from_gtsam(values.atOrientedPlane3(problem.plane_keys[
            rig.mirror_index(view.mirror)]))
        pose = problem.camera_pose(rig.camera_index(view.camera), values)
        values.update(key, reflected_pose(n, d, pose))


def extract_camera_poses(problem: GraphProblem, values: gtsam.Values) -> list[np.ndarray]:
    """``(4, 4)`` camera-to-world pose of every camera (estimated or fixed), rig order."""
    return [np.asarray(problem.camera_pose(c, values).matrix(), dtype=float)
            for c in range(len(problem.rig.cameras))]


def camera_matrix(cal: gtsam.Cal3_S2) -> np.ndarray:
    """``(3, 3)`` camera matrix of a :class:`gtsam.Cal3_S2`."""
    return np.asarray(cal.K(), dtype=float)


def extract_intrinsics(problem: GraphProblem, values: gtsam.Values) -> list[np.ndarray]:
    """``(3, 3)`` camera matrix of every camera (estimated or fixed), rig order."""
    return [problem.intrinsics(c, values) for c in range(len(problem.rig.cameras))]


def extract_planes(problem: GraphProblem, values: gtsam.Values) -> list[tuple[np.ndarray, float]]:
    """``(n, d)`` of every mirror from ``values``."""
    return [plane_from_gtsam(values.atOrientedPlane3(k)) for k in problem.plane_keys]


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
