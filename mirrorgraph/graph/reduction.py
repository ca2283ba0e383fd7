"""The mirror link as an exact constraint: reduced coordinates for the global variables.

The virtual camera pose ``V`` of a mirror view is a function of the plane
(:mod:`mirrorgraph.factors.mirror_link`): ``V = reflect(C, plane)``. The graph's
reprojection factors see ``V``; the quantity estimated is the plane. Linearising
the link residual ``e(plane, V) = 0`` with the factor's analytic Jacobians,

    e + J_V dV + J_P dP = 0   =>   dV = -J_V^-1 (e + J_P dP)   (e = 0 after projection),

so the reduced coordinates are ``z = (bone-length vector, planes)`` and

    delta_globals = T z,   T = [[0, M], [I, 0], [0, I]]  for  (V..., L..., P...),  M = -J_V^-1 J_P.

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


def mirror_reduction(problem: GraphProblem, *, with_lengths: bool,
                     distance_gauge: float | None) -> GlobalReduction:
    """Reduced coordinates for a problem's globals.

    Args:
        problem: the built problem (its views, mirrors and keys).
        with_lengths: the bone-length variables are in the graph being solved
            (not in the reprojection-only warm start).
        distance_gauge: if not ``None``, a prior ``d = distance_gauge`` on the first
            plane (the unit-distance gauge, or holding ``d`` during the warm start).
    """
    rig = problem.rig
    vkeys = list(problem.virtual_keys.items())                  # (view index, key)
    lkeys = ([(problem.length_key, len(problem.bone_names))]
             if with_lengths and problem.length_key is not None else [])
    pkeys = list(problem.plane_keys)
    graph_keys = [(k, 6) for _, k in vkeys] + lkeys
    extra_keys = [(k, 3) for k in pkeys]
    z_keys = lkeys + [(k, 3) for k in pkeys]
    nv, nl, npl = len(vkeys), sum(d for _, d in lkeys), len(pkeys)
    plane_of_view = [rig.mirror_index(rig.views[vi].mirror) for vi, _ in vkeys]
    cams = [rig.camera(rig.views[vi].camera).gtsam_pose for vi, _ in vkeys]

    def basis(values: gtsam.Values) -> np.ndarray:
        T = np.zeros((6 * nv + nl + 3 * npl, nl + 3 * npl))
        for i, ((_, vk), m, cam) in enumerate(zip(vkeys, plane_of_view, cams)):
            plane = values.atOrientedPlane3(pkeys[m])
            n, d = plane_from_gtsam(plane)
            V = values.atPose3(vk)
            _, _, Jp, Jv = MirrorLinkFactor.evaluate(
                cam.rotation().matrix(), np.asarray(cam.translation()), n, d,
                np.asarray(plane.normal().basis()), V.rotation().matrix(),
                np.asarray(V.translation()))
            T[6 * i:6 * i + 6, nl + 3 * m:nl + 3 * m + 3] = -np.linalg.solve(Jv, Jp)
        T[6 * nv:6 * nv + nl, :nl] = np.eye(nl)
        T[6 * nv + nl:, nl:] = np.eye(3 * npl)
        return T

    extra = gtsam.NonlinearFactorGraph()
    if distance_gauge is not None:
        extra.push_back(DistancePriorFactor(distance_gauge).make(pkeys[0]))
    return GlobalReduction(graph_keys=graph_keys, extra_keys=extra_keys, z_keys=z_keys,
                           basis=basis, extra_graph=extra,
                           project=lambda v: snap_virtual_poses(problem, v))
