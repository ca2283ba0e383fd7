"""The built factor graph of a rig (:class:`GraphProblem`): variables, factors, values read back.

Variables (keys from :mod:`gtsam.symbol_shorthand`; world = the first camera's frame):

* ``X(t * J + j)``: :class:`gtsam.Point3`, joint ``j`` in frame row ``t``;
* ``P(m)``: :class:`gtsam.OrientedPlane3`, mirror ``m``;
* ``V(v)``: :class:`gtsam.Pose3`, the virtual camera of mirror view ``v``;
* ``C(c)``: :class:`gtsam.Pose3`, camera ``c``'s pose (camera-to-world) where it is
  estimated, or held where only its intrinsics are;
* ``K(c)``, ``Q(c)``: :class:`gtsam.Cal3_S2`, camera ``c``'s calibration and the mirrored
  one ``(-fx, fy, s, cx, cy)``, where its intrinsics are estimated (kept equal,
  :mod:`.reduction`);
* the bone lengths: held by range factors and set between linearisations
  (:mod:`.lengths`, the vector :data:`LENGTH_KEY`), or the variable ``L(0)`` where a
  focal length is estimated (:attr:`GraphProblem.length_key`).

Factors are kept in separate graphs so that the solver uses subsets: ``reprojection``,
``links`` (one :class:`MirrorLinkFactor` per mirror view, enforced exactly by
:mod:`.reduction`), ``priors`` (hip, smoothness), ``bones``, ``length_priors`` and
``gauge``; :meth:`GraphProblem.full` is the graph of the joints and globals.

Here too: the keys (:func:`point_keys`, :data:`LENGTH_KEY`), the values read back as
arrays (:func:`extract_points`, :func:`extract_planes`, :func:`extract_camera_poses`,
:func:`extract_intrinsics`), the virtual poses snapped onto their mirrors
(:func:`snap_virtual_poses`) and the solver's cheirality guard (:func:`cheirality_guard`).
The graph is built by :mod:`.builder`; the variables in full: ``docs/internals.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L as L_
from gtsam.symbol_shorthand import X as X_

from ..factors import (BoneLengthFactor, calibration, mirrored_calibration, plane_from_gtsam,
                       reflected_pose)
from .rig import Rig

__all__ = ["GraphProblem", "LENGTH_KEY", "X_BASE", "point_keys", "bone_graph", "camera_matrix",
           "extract_points", "points_array", "extract_camera_poses", "extract_intrinsics",
           "extract_planes", "snap_virtual_poses", "cheirality_guard", "without_observations"]

#: Key ``X(0)``: joint ``j`` of frame row ``t`` is ``X(t * J + j)``.
X_BASE = X_(0)

#: Key of the bone-length vector in the length problem (:mod:`.lengths`): the
#: length-only priors and the gauge are factors on it; it is not a variable of the
#: graph of the joints.
LENGTH_KEY = L_(0)


def point_keys(flat_index: np.ndarray) -> list[int]:
    """Keys ``X(i)`` of flat point indices ``i = t * J + j`` (vectorised)."""
    return (np.uint64(X_BASE) + np.asarray(flat_index, dtype=np.uint64)).tolist()


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
        self.bones = bone_graph(self.bone_rows, self.flat_index, self.lengths, self.bone_sigma)

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


def bone_graph(rows: np.ndarray, flat: np.ndarray, lengths: np.ndarray | None,
               sigma: float, J: int | None = None, length_key: int | None = None
               ) -> gtsam.NonlinearFactorGraph:
    """The range factors of the bone ``rows`` (``(N, 3)``: key-order positions of the two
    joints among the used points ``flat`` (``t * J + j``), bone index) at ``lengths``;
    with ``length_key`` one factor per frame on its joints and the length vector
    (``J`` joints a frame)."""
    graph = gtsam.NonlinearFactorGraph()
    if lengths is None or len(rows) == 0:
        return graph
    keys = np.uint64(X_BASE) + np.asarray(flat, dtype=np.uint64)
    factor = BoneLengthFactor(sigma)
    if length_key is not None:
        frames = np.asarray(flat, dtype=np.int64)[rows[:, 0]] // int(J)
        factor.add_frames(graph, keys[rows[:, 0]], keys[rows[:, 1]], rows[:, 2], frames,
                          length_key, len(lengths))
        return graph
    factor.add(graph, keys[rows[:, 0]], keys[rows[:, 1]],
               np.asarray(lengths, dtype=float)[rows[:, 2]])
    return graph


def camera_matrix(cal: gtsam.Cal3_S2) -> np.ndarray:
    """``(3, 3)`` camera matrix of a :class:`gtsam.Cal3_S2`."""
    return np.asarray(cal.K(), dtype=float)


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


def extract_camera_poses(problem: GraphProblem, values: gtsam.Values) -> list[np.ndarray]:
    """``(4, 4)`` camera-to-world pose of every camera (estimated or fixed), rig order."""
    return [np.asarray(problem.camera_pose(c, values).matrix(), dtype=float)
            for c in range(len(problem.rig.cameras))]


def extract_intrinsics(problem: GraphProblem, values: gtsam.Values) -> list[np.ndarray]:
    """``(3, 3)`` camera matrix of every camera (estimated or fixed), rig order."""
    return [problem.intrinsics(c, values) for c in range(len(problem.rig.cameras))]


def extract_planes(problem: GraphProblem, values: gtsam.Values) -> list[tuple[np.ndarray, float]]:
    """``(n, d)`` of every mirror from ``values``."""
    return [plane_from_gtsam(values.atOrientedPlane3(k)) for k in problem.plane_keys]


def without_observations(problem: GraphProblem, drop: list[np.ndarray]) -> GraphProblem:
    """``problem`` without the reprojection factors of the observations ``drop`` (per
    view ``(T, J)`` bool), its views' masks without them; the factors kept are shared.

    The reprojection graph holds one factor per observation, view by view, each view's
    in the row-major order of ``used & view.mask`` (:mod:`.builder`)."""
    keep = []
    for view, d in zip(problem.rig.views, drop):
        mask = problem.used & np.asarray(view.mask, dtype=bool)
        keep.append(~np.asarray(d, dtype=bool)[mask])
    keep = np.concatenate(keep) if keep else np.zeros(0, dtype=bool)
    if keep.size != problem.reprojection.size():
        raise ValueError(f"{problem.reprojection.size()} reprojection factors for "
                         f"{keep.size} observations")
    graph = gtsam.NonlinearFactorGraph()
    for i in np.flatnonzero(keep).tolist():
        graph.push_back(problem.reprojection.at(i))
    views = tuple(replace(v, mask=np.asarray(v.mask, dtype=bool) & ~np.asarray(d, dtype=bool))
                  for v, d in zip(problem.rig.views, drop))
    return replace(problem, reprojection=graph, rig=replace(problem.rig, views=views))


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
