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

After every retraction the virtual poses are reset to the exact reflection of
their camera across the updated plane (``project``), which keeps ``e = 0``.
This is the constrained Gauss-Newton step of the problem where ``V`` is
parametrised by the plane: the plane's marginal covariance from the reduced
information is exact, and no near-infinite weight enters a Cholesky factor.
"""

from __future__ import annotations

import gtsam
import numpy as np

from ..factors import DistancePriorFactor, MirrorLinkFactor, plane_from_gtsam
from .builder import GraphProblem, snap_virtual_poses
from .optimizer import GlobalReduction

__all__ = ["mirror_reduction"]


def mirror_reduction(problem: GraphProblem, *, distance_gauge: float | None) -> GlobalReduction:
    """Reduced coordinates for a problem's globals.

    ``z`` holds, in this order, the estimated camera poses (6 each) and the planes
    (3 each). A virtual pose follows its plane and, when its camera is estimated,
    its camera: ``dV = -J_V^-1 (J_P dP + J_C dC)``.

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
    graph_cams = [(c, k) for c, k in ckeys if k in in_graph]
    extra_cams = [(c, k) for c, k in ckeys if k not in in_graph]
    graph_keys = [(k, 6) for _, k in vkeys] + [(k, 6) for _, k in graph_cams]
    extra_keys = [(k, 6) for _, k in extra_cams] + [(k, 3) for k in pkeys]
    z_keys = [(k, 6) for _, k in ckeys] + [(k, 3) for k in pkeys]
    nv, nc, npl = len(vkeys), len(ckeys), len(pkeys)
    # columns of z and rows of delta_globals = graph_keys + extra_keys
    zcol_cam = {c: 6 * i for i, (c, _) in enumerate(ckeys)}
    zcol_plane = 6 * nc
    row_cam = {}
    for i, (c, _) in enumerate(graph_cams):
        row_cam[c] = 6 * nv + 6 * i
    row_extra = 6 * nv + 6 * len(graph_cams)
    for i, (c, _) in enumerate(extra_cams):
        row_cam[c] = row_extra + 6 * i
    row_plane = row_extra + 6 * len(extra_cams)
    views = [(vi, vk, rig.mirror_index(rig.views[vi].mirror),
              rig.camera_index(rig.views[vi].camera)) for vi, vk in vkeys]

    def basis(values: gtsam.Values) -> np.ndarray:
        T = np.zeros((row_plane + 3 * npl, 6 * nc + 3 * npl))
        for i, (_, vk, m, c) in enumerate(views):
            plane = values.atOrientedPlane3(pkeys[m])
            n, d = plane_from_gtsam(plane)
            V = values.atPose3(vk)
            cam = problem.camera_pose(c, values)
            _, Jc, Jp, Jv = MirrorLinkFactor.evaluate(
                cam.rotation().matrix(), np.asarray(cam.translation()), n, d,
                np.asarray(plane.normal().basis()), V.rotation().matrix(),
                np.asarray(V.translation()))
            Jv_inv = np.linalg.inv(Jv)
            T[6 * i:6 * i + 6, zcol_plane + 3 * m:zcol_plane + 3 * m + 3] = -Jv_inv @ Jp
            if c in zcol_cam:
                T[6 * i:6 * i + 6, zcol_cam[c]:zcol_cam[c] + 6] = -Jv_inv @ Jc
        for c, col in zcol_cam.items():
            T[row_cam[c]:row_cam[c] + 6, col:col + 6] = np.eye(6)
        T[row_plane:, zcol_plane:] = np.eye(3 * npl)
        return T

    extra = gtsam.NonlinearFactorGraph()
    if distance_gauge is not None:
        extra.push_back(DistancePriorFactor(distance_gauge).make(pkeys[0]))
    return GlobalReduction(graph_keys=graph_keys, extra_keys=extra_keys, z_keys=z_keys,
                           basis=basis, extra_graph=extra,
                           project=lambda v: snap_virtual_poses(problem, v))
