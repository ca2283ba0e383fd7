"""Marginal covariances of the solved globals and the variance floors of estimated focal lengths.

The reduced information of the last undamped solve is the Schur complement of every
joint on the globals (camera poses, planes, intrinsics, bone lengths) that GTSAM's
elimination leaves; its inverse (:func:`~.optimizer.reduced_covariance`) gives each
estimated camera's ``6 x 6`` and each plane's ``3 x 3`` tangent covariance and each
estimated camera's ``(d, d)`` intrinsics covariance (:func:`covariances`), which the
driver scales by the noise the data show (:mod:`.noise`). :func:`floor_focal` puts a
floor under the focal lengths' robust standard deviations (:mod:`.uncertainty`), and
:func:`intrinsics_spread` carries what that floor adds into every camera's and plane's
covariance (a distance, a position), which the marginals alone do not hold.
"""

from __future__ import annotations

import gtsam
import numpy as np

from .optimizer import reduced_covariance, reduced_covariance_matrix
from .problem import GraphProblem
from .solve_state import SolveState
from .uncertainty import robust_intrinsics_std

__all__ = ["covariances", "floor_focal", "intrinsics_spread"]


def covariances(problem: GraphProblem, values: gtsam.Values, info: np.ndarray | None,
                z_keys, compute: bool = True):
    """Per camera ``(6, 6)`` and per plane ``(3, 3)`` tangent covariance from the reduced
    information (:func:`~.optimizer.reduced_covariance`), the planes' normal bases, the
    reduced variables' values and per camera the ``(d, d)`` covariance of its estimated
    intrinsics (``(0, 0)`` where held). Held cameras get zeros; NaN where not computed."""
    rig = problem.rig
    nan6, nan3 = np.full((6, 6), np.nan), np.full((3, 3), np.nan)
    basis = [np.asarray(values.atOrientedPlane3(k).normal().basis()) for k in problem.plane_keys]
    zv = gtsam.Values()
    for k, _ in z_keys:
        if k in problem.plane_keys:
            zv.insert(k, values.atOrientedPlane3(k))
        elif gtsam.Symbol(k).chr() == ord("k"):
            zv.insert(k, values.atCal3_S2(k))
        elif k == problem.length_key:
            zv.insert(k, values.atVector(k))
        else:
            zv.insert(k, values.atPose3(k))
    dims = [rig.cameras[i].intrinsics_dim if i in problem.calibration_keys else 0
            for i in range(len(rig.cameras))]
    if info is None or not compute:
        return ([np.zeros((6, 6)) if i not in problem.camera_keys else nan6
                 for i in range(len(rig.cameras))],
                [nan3] * len(problem.plane_keys), basis, zv,
                [np.full((d, d), np.nan) for d in dims])
    cov = reduced_covariance(info, z_keys)
    cams = [np.zeros((6, 6)) if problem.camera_keys.get(i) is None
            else cov[int(problem.camera_keys[i])] for i in range(len(rig.cameras))]
    planes = [cov[int(k)] for k in problem.plane_keys]
    intr = [cov[int(problem.calibration_keys[i][0])] if d else np.zeros((0, 0))
            for i, d in enumerate(dims)]
    return cams, planes, basis, zv, intr


def floor_focal(state: SolveState, undetermined: set[int] = frozenset(), *,
                disagreement: bool = True, model_var: dict[int, float] | None = None) -> None:
    """Variance floors of the estimated focal lengths, in every robust figure.

    Two estimates of one focal length from the same data, the initial search's (every
    bone in every frame of its ``T_s`` frames) and the graph's (the bones whose curvature
    bias is small), differ by what the bones' choice does to it; where that exceeds the
    graph's std the std is no measure of the error (rays meeting at 16 deg: the search
    2699 px, the graph 1365 px at a std of 4 %, the truth 2186 px), and the difference
    squared is the floor of its variance (``disagreement``; off: the data's own
    figures). The driver takes that floor only where the two are further apart than
    ``FocalOptions.fallback_rel_std`` (:func:`~.solve.judge_focal`): a smaller
    difference is mostly the search's sampling noise (its fewer frames), and a bias
    both share is in neither (:func:`~.solve.focal_bias` measures it). A camera in ``undetermined`` gets its
    prior's variance, and so does a principal point held at the centre
    (:data:`~.priors.PRINCIPAL_POINT_HOLD`: its uncertainty is the population's).
    ``model_var`` (camera index -> px^2) is a variance the data's own figures do not hold
    (the estimator's bias, :func:`~.solve.focal_bias`): the floor is at least the data's
    variance plus it. Sets the scores' :attr:`~.scores.JointScores.prior_floor` and recomputes the
    cameras' robust intrinsics stds with it.
    """
    sc, problem = state.scores, state.problem
    if sc is None or problem is None or sc.prior_spread is None:
        return
    search = [s for s in state.stages if s.get("focal_px") is not None] if disagreement else []
    if not state.intrinsics_data_std:             # the data's own, before any floor
        state.intrinsics_data_std = [np.asarray(x, float).copy() for x in state.intrinsics_std]
    floor = (np.zeros(sc.scores.shape[1]) if sc.prior_floor is None
             else np.asarray(sc.prior_floor, float).copy())
    cap = np.zeros(sc.scores.shape[1])
    off = 0
    keys = {int(pair[0]): c for c, pair in problem.calibration_keys.items()}
    for key, dim in sc.z_keys:
        c = keys.get(int(key))
        if c is not None:
            cam, K = problem.rig.cameras[c], np.asarray(state.intrinsics[c], float)
            if cam.focal_prior is not None:         # the estimate's distance from the guess
                cap[off] = cam.focal_prior[1] ** 2 + (K[0, 0] - cam.focal_prior[0]) ** 2
            if dim == 3 and cam.principal_point_prior is not None:
                cx0, cy0, sd = cam.principal_point_prior
                cap[off + 1:off + 3] = sd ** 2 + (K[:2, 2] - (cx0, cy0)) ** 2
            if dim == 3 and problem.rig.cameras[c].principal_point_prior is not None:
                floor[off + 1:off + 3] = np.inf       # held at the centre: the prior's spread
            f = float(np.asarray(state.intrinsics[c])[0, 0])
            if c in undetermined:
                floor[off] = np.inf                        # the prior's (capped there)
            else:
                if search and len(problem.calibration_keys) == 1:
                    floor[off] = max(floor[off], (float(search[-1]["focal_px"]) - f) ** 2)
                if model_var and model_var.get(c, 0.0) > 0 and c < len(state.intrinsics_data_std):
                    own = np.asarray(state.intrinsics_data_std[c], float)
                    data_var = float(own[0]) ** 2 if own.size else 0.0
                    floor[off] = max(floor[off], data_var + float(model_var[c]))
        off += dim
    sc.prior_floor = floor
    sc.prior_cap = cap
    marginal = {int(problem.calibration_keys[c][0]): state.intrinsics_cov[c]
                for c in problem.calibration_keys}
    robust = robust_intrinsics_std(sc, marginal)
    state.intrinsics_std = [robust[int(problem.calibration_keys[c][0])][0]
                            if c in problem.calibration_keys else np.zeros(0)
                            for c in range(len(state.intrinsics))]


def intrinsics_spread(state: SolveState) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """What the estimated intrinsics' headline variance adds to every camera and plane.

    The marginals hold each estimated intrinsic at its marginal variance ``C_kk``; its
    headline figure (:func:`floor_focal`: the disagreement with the search, or the
    prior's spread where the data do not determine it) can be far larger, and every
    quantity correlated with it inherits the difference. With ``C`` the joint covariance
    of the reduced coordinates (:func:`~.optimizer.reduced_covariance_matrix`, scaled by
    the noise), ``D = diag(max(s^2 - diag C_kk, 0))`` the variance the headline stds
    ``s`` add, and ``b`` a camera's or a plane's block, the covariance ``b`` gains is
    ``C_bk C_kk^-1 D C_kk^-1 C_kb`` (the regression of ``b`` on the intrinsics: Gaussian
    propagation of the extra spread, Bishop 2006, sec. 2.3.3). A focal length 20 % uncertain
    makes a mirror's distance about 20 % uncertain too (depth scales with it for a
    fixed image of a person of known height).

    Returns:
        per camera a ``(6, 6)`` and per plane a ``(3, 3)`` covariance to add (tangent
        coordinates; zeros where nothing is estimated or nothing is added).
    """
    problem = state.problem
    rig = problem.rig if problem is not None else None
    cams = [np.zeros((6, 6)) for _ in (rig.cameras if rig is not None else ())]
    planes = [np.zeros((3, 3)) for _ in state.planes]
    if (problem is None or state.information is None or not problem.calibration_keys
            or not state.intrinsics_std):
        return cams, planes
    C = reduced_covariance_matrix(state.information) * state.variance_factor
    if not np.all(np.isfinite(C)):
        return cams, planes
    where, off = {}, 0
    for key, dim in state.z_keys:
        where[int(key)] = (off, dim)
        off += dim
    k_idx, extra = [], []
    for c, pair in problem.calibration_keys.items():
        o, dim = where[int(pair[0])]
        std = np.asarray(state.intrinsics_std[c], float)[:dim]
        if std.size != dim:
            continue
        var = np.diag(C)[o:o + dim]
        add = np.where(np.isfinite(std), np.maximum(std ** 2 - var, 0.0), 0.0)
        k_idx += range(o, o + dim)
        extra += list(add)
    if not k_idx or not np.any(np.asarray(extra) > 0):
        return cams, planes
    k = np.asarray(k_idx)
    Ckk = C[np.ix_(k, k)]
    gain = np.linalg.lstsq(Ckk, C[k, :], rcond=None)[0].T          # (n, |k|): C_bk C_kk^-1
    add = (gain * np.asarray(extra)) @ gain.T
    for i, key in problem.camera_keys.items():
        o, dim = where[int(key)]
        cams[i] = add[o:o + dim, o:o + dim]
    for m, key in enumerate(problem.plane_keys):
        o, dim = where[int(key)]
        planes[m] = add[o:o + dim, o:o + dim]
    return cams, planes

