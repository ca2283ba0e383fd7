"""The mirror link as an exact constraint: reduced coordinates for the global variables.

The virtual camera pose ``V`` of a mirror view is a function of the plane
(:mod:`mirrorgraph.factors.mirror_link`): ``V = reflect(C, plane)``. The graph's
reprojection factors see ``V``; the quantity estimated is the plane. Linearising
the link residual ``e(plane, V) = 0`` with the factor's analytic Jacobians,

    e + J_V dV + J_P dP = 0   =>   dV = -J_V^-1 (e + J_P dP)   (e = 0 after projection),

so the reduced coordinates are ``z = planes`` and

    delta_globals = T z,   T = [[M], [I]]  for  (V..., P...),  M = -J_V^-1 J_P.

(The bone lengths are not variables of the linear system: :mod:`.lengths`.)

In a rig whose camera poses are estimated too, ``z`` also holds the camera
poses and a virtual pose follows its camera as well: ``dV = -J_V^-1 (J_P dP + J_C dC)``.

Estimated intrinsics (:attr:`~.rig.Camera.estimate_focal`): a camera's calibration
is two :class:`gtsam.Cal3_S2` variables of the graph, ``K = (f, f, 0, cx, cy)`` for
its direct view and ``K D = (-f, f, 0, cx, cy)`` for its mirror views
(:mod:`mirrorgraph.factors.reprojection`), whose tangents are additive
``(dfx, dfy, ds, dcx, dcy)``. One reduced coordinate ``df`` (and ``dcx, dcy`` with
the principal point free) moves both:

    dK = (df, df, 0, dcx, dcy),    d(K D) = (-df, df, 0, dcx, dcy),

which keeps the pixels square, the skew zero and the two variables one camera.
A fixed camera whose intrinsics are estimated has a held pose variable (the
calibrated factor needs a pose key): zero rows of ``T``. The bone lengths are then
a variable of the graph too (:attr:`~.problem.GraphProblem.length_key`), the last
block of ``z`` (identity rows).

After every retraction the virtual poses are reset to the exact reflection of
their camera across the updated plane (``project``), which keeps ``e = 0``, and
each mirrored calibration to ``K D`` of its camera's ``K``.
This is the constrained Gauss-Newton step of the problem where ``V`` is
parametrised by the plane: the plane's marginal covariance from the reduced
information is exact, and no near-infinite weight enters a Cholesky factor.
"""

from __future__ import annotations

import gtsam
import numpy as np

from ..factors import DistancePriorFactor, MirrorLinkFactor, plane_from_gtsam
from .problem import GraphProblem, snap_virtual_poses
from .optimizer import GlobalReduction

__all__ = ["mirror_reduction", "intrinsics_basis", "CALIBRATION_DIM"]

#: Tangent dimension of a :class:`gtsam.Cal3_S2` ``(fx, fy, s, cx, cy)``.
CALIBRATION_DIM = 5


def intrinsics_basis(dim: int, mirrored: bool) -> np.ndarray:
    """``(5, dim)`` map from the reduced intrinsics ``(df[, dcx, dcy])`` to a
    :class:`gtsam.Cal3_S2` tangent ``(dfx, dfy, ds, dcx, dcy)``.

    Args:
        dim: 1 (the focal length) or 3 (and the principal point).
        mirrored: the mirrored calibration ``K D`` (``fx = -f``) of a mirror view.
    """
    M = np.zeros((CALIBRATION_DIM, dim))
    M[0, 0] = -1.0 if mirrored else 1.0
    M[1, 0] = 1.0
    if dim == 3:
        M[3, 1] = M[4, 2] = 1.0
    return M


def mirror_reduction(problem: GraphProblem, *, distance_gauge: float | None) -> GlobalReduction:
    """Reduced coordinates for a problem's globals.

    ``z`` holds, in this order, the estimated camera poses (6 each), the planes
    (3 each) and the estimated intrinsics (1 or 3 per camera:
    :attr:`~.rig.Camera.intrinsics_dim`; the block's key is the camera's ``K(c)``).
    A virtual pose follows its plane and, when its camera is estimated, its camera:
    ``dV = -J_V^-1 (J_P dP + J_C dC)``.

    Args:
        problem: the built problem (its views, mirrors and keys).
        distance_gauge: if not ``None``, a prior ``d = distance_gauge`` on the first
            plane (the unit-distance gauge, or holding ``d`` during the warm start).
    """
    rig = problem.rig
    vkeys = list(problem.virtual_keys.items())                  # (view index, key)
    in_graph = set(problem.reprojection.keyVector())
    ckeys = list(problem.camera_keys.items())                   # (camera index, key)
    pkeys = list(problem.plane_keys)
    calib = list(problem.calibration_keys.items())              # (camera, (K, Q))
    idim = {c: rig.cameras[c].intrinsics_dim for c, _ in calib}
    held = [(k, 6) for k in problem.held_pose_keys.values()]
    calib_keys = [(k, 5) for _, pair in calib for k in pair if k is not None]
    # rows of delta_globals: the keys in the graph first (eliminated last), then the rest
    candidates = ([(k, 6) for _, k in vkeys] + [(k, 6) for _, k in ckeys] + held
                  + calib_keys)
    graph_keys = [(k, d) for k, d in candidates if k in in_graph]
    extra_keys = [(k, d) for k, d in candidates if k not in in_graph] + [(k, 3) for k in pkeys]
    z_keys = ([(k, 6) for _, k in ckeys] + [(k, 3) for k in pkeys]
              + [(pair[0], idim[c]) for c, pair in calib])
    if problem.length_key is not None:          # the bone lengths, a variable of the graph
        nb = len(problem.lengths)
        graph_keys.append((problem.length_key, nb))
        z_keys.append((problem.length_key, nb))
    row = _offsets(graph_keys + extra_keys)
    col = _offsets(z_keys)
    n_rows = sum(d for _, d in graph_keys + extra_keys)
    n_cols = sum(d for _, d in z_keys)
    views = [(vk, rig.mirror_index(rig.views[vi].mirror),
              rig.camera_index(rig.views[vi].camera)) for vi, vk in vkeys]
    # the constant blocks: camera poses, planes, intrinsics
    T0 = np.zeros((n_rows, n_cols))
    for _, k in ckeys:
        T0[row[k]:row[k] + 6, col[k]:col[k] + 6] = np.eye(6)
    for k in pkeys:
        T0[row[k]:row[k] + 3, col[k]:col[k] + 3] = np.eye(3)
    if problem.length_key is not None:
        k = problem.length_key
        T0[row[k]:row[k] + nb, col[k]:col[k] + nb] = np.eye(nb)
    for c, (kk, qk) in calib:
        d = idim[c]
        T0[row[kk]:row[kk] + 5, col[kk]:col[kk] + d] = intrinsics_basis(d, False)
        if qk is not None:
            T0[row[qk]:row[qk] + 5, col[kk]:col[kk] + d] = intrinsics_basis(d, True)
    camera_col = {c: col[k] for c, k in ckeys}

    def basis(values: gtsam.Values) -> np.ndarray:
        T = T0.copy()
        for vk, m, c in views:
            plane = values.atOrientedPlane3(pkeys[m])
            n, d = plane_from_gtsam(plane)
            V = values.atPose3(vk)
            cam = problem.camera_pose(c, values)
            _, Jc, Jp, Jv = MirrorLinkFactor.evaluate(
                cam.rotation().matrix(), np.asarray(cam.translation()), n, d,
                np.asarray(plane.normal().basis()), V.rotation().matrix(),
                np.asarray(V.translation()))
            Jv_inv = np.linalg.inv(Jv)
            r, p = row[vk], col[pkeys[m]]
            T[r:r + 6, p:p + 3] = -Jv_inv @ Jp
            if c in camera_col:
                T[r:r + 6, camera_col[c]:camera_col[c] + 6] = -Jv_inv @ Jc
        return T

    extra = gtsam.NonlinearFactorGraph()
    if distance_gauge is not None:
        extra.push_back(DistancePriorFactor(distance_gauge).make(pkeys[0]))
    return GlobalReduction(graph_keys=graph_keys, extra_keys=extra_keys, z_keys=z_keys,
                           basis=basis, extra_graph=extra,
                           project=lambda v: snap_virtual_poses(problem, v))


def _offsets(keys: list[tuple[int, int]]) -> dict[int, int]:
    out, off = {}, 0
    for k, d in keys:
        out[int(k)] = off
        off += d
    return out
