"""The mirror link: the virtual camera is the reflection of the real one across the plane.

The mirror view is an ordinary GTSAM camera (:mod:`mirrorgraph.factors.reprojection`): a
:class:`gtsam.Pose3` variable ``V`` (camera-to-world, world = real camera frame) with the
mirrored calibration ``Cal3_S2(-fx, fy, s, cx, cy)``, whose pose is the reflection of the
real camera pose ``C = (R_c, t_c)`` across the mirror plane ``n . X = d``:

    R_v = H R_c D,    c_v = S(t_c) = H t_c + 2 d n,    H = I - 2 n n^T,  D = diag(-1, 1, 1).

For the real camera at the origin this is the virtual camera of
:func:`mirrorgraph.geometry.virtual_camera_from_mirror`. One :class:`MirrorLinkFactor` per
mirror view ties ``V`` to the plane variable (and to the real camera pose where that is a
variable), so that the mirror view's reprojection factors are GTSAM's built-in projection
factors while the plane stays the estimated quantity. The refinement enforces the link
exactly (:mod:`mirrorgraph.graph.reduction` substitutes ``dV = -J_V^-1 J_P dP`` with this
factor's Jacobians); :meth:`MirrorLinkFactor.make` builds the soft factor.

The plane is a :class:`gtsam.OrientedPlane3`, ``n . X + d_gtsam = 0``, so
``d_gtsam = -d`` (:func:`plane_to_gtsam`, :func:`plane_from_gtsam`); tangent
``(v1, v2, v3)``: ``n <- n.retract((v1, v2))``, ``d <- d - v3``.

Residual (6,): ``e = [Log(R_p^T R_v), R_p^T (c_v - c_p)]``, ``(R_p, c_p)`` the reflection
predicted from ``C`` and the plane; zero exactly when ``V`` is the reflection of ``C``.
Jacobians are analytic in GTSAM's tangent spaces (``Pose3``: ``R <- R Exp(w)``,
``t <- t + R v``); their derivation is in ``docs/internals.md``.

Reference: MirrorCalib (Liao, Zheng and Mitchell), sec. "Reflective essential matrix
decomposition" for ``D``; Sola, Deray and Atchuthan, "A micro Lie theory for state
estimation in robotics" (2018), eqs. 143-146 for ``Jr^-1``, ``Jl^-1``.
"""

from __future__ import annotations

import gtsam
import numpy as np

from ..geometry import D_FLIP, householder, skew

__all__ = ["MirrorLinkFactor", "plane_to_gtsam", "plane_from_gtsam", "reflected_pose",
           "so3_log", "so3_right_jacobian_inverse", "so3_left_jacobian_inverse"]


# --------------------------------------------------------------------------- plane helpers
def plane_to_gtsam(normal: np.ndarray, distance: float) -> gtsam.OrientedPlane3:
    """Our plane ``n . X = d`` (unit ``n``, ``d > 0``) as GTSAM's ``n . X + d_gtsam = 0``."""
    n = np.asarray(normal, dtype=float).reshape(3)
    return gtsam.OrientedPlane3(gtsam.Unit3(n / np.linalg.norm(n)), -float(distance))


def plane_from_gtsam(plane: gtsam.OrientedPlane3) -> tuple[np.ndarray, float]:
    """``(n (3,), d)`` of ``n . X = d`` from a :class:`gtsam.OrientedPlane3`."""
    coeffs = plane.planeCoefficients()
    return np.asarray(coeffs[:3], dtype=float), -float(coeffs[3])


def reflected_pose(normal: np.ndarray, distance: float,
                   camera_pose: gtsam.Pose3 | None = None) -> gtsam.Pose3:
    """Pose (camera-to-world) of the virtual camera: the camera reflected across the plane.

    Args:
        normal: ``(3,)`` unit mirror normal, world (= real camera) frame.
        distance: ``d`` of ``n . X = d``, length unit of the scene.
        camera_pose: real camera pose (camera-to-world); identity if ``None``.

    Returns:
        ``Pose3(H R_c D, H t_c + 2 d n)``: with the mirrored calibration of
        :func:`mirrorgraph.factors.reprojection.mirrored_calibration` it projects
        ``X`` where the real camera images the reflection ``S(X)``.
    """
    n = np.asarray(normal, dtype=float).reshape(3)
    Rc, tc = _pose_parts(camera_pose)
    H = householder(n)
    return gtsam.Pose3(gtsam.Rot3(H @ Rc @ D_FLIP), H @ tc + 2.0 * float(distance) * n)


def _pose_parts(pose: gtsam.Pose3 | None) -> tuple[np.ndarray, np.ndarray]:
    if pose is None:
        return np.eye(3), np.zeros(3)
    return np.asarray(pose.rotation().matrix()), np.asarray(pose.translation(), dtype=float)


# --------------------------------------------------------------------------- SO(3) helpers
def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector ``(3,)`` (radians) of a ``(3, 3)`` rotation matrix."""
    return np.asarray(gtsam.Rot3.Logmap(gtsam.Rot3(np.asarray(R, dtype=float))), dtype=float)


def so3_right_jacobian_inverse(theta: np.ndarray) -> np.ndarray:
    """``Jr^-1(theta)`` (3, 3): ``Log(Exp(theta) Exp(d)) = theta + Jr^-1(theta) d + O(d^2)``
    (GTSAM's :meth:`gtsam.SO3.LogmapDerivative`)."""
    return np.asarray(gtsam.SO3.LogmapDerivative(np.asarray(theta, dtype=float).reshape(3)))


def so3_left_jacobian_inverse(theta: np.ndarray) -> np.ndarray:
    """``Jl^-1(theta)`` (3, 3): ``Log(Exp(d) Exp(theta)) = theta + Jl^-1(theta) d + O(d^2)``
    (``Jl(theta) = Jr(-theta)``)."""
    return np.asarray(gtsam.SO3.LogmapDerivative(-np.asarray(theta, dtype=float).reshape(3)))


# --------------------------------------------------------------------------- the factor
class MirrorLinkFactor:
    """Soft equality "virtual pose = reflection of the real camera pose across the plane".

    Keys: the plane (:class:`gtsam.OrientedPlane3`), the virtual camera pose
    (:class:`gtsam.Pose3`) and, optionally, the real camera pose (:class:`gtsam.Pose3`;
    when it is not a variable, ``camera_pose`` is the fixed value).

    Args:
        sigma_rotation: standard deviation of the rotation residual, radians.
        sigma_translation: standard deviation of the centre residual, length
            unit of the scene (of ``d``). Both are tiny: the link acts as a
            constraint while keeping the system well conditioned (a reprojection
            factor brings an information of ``(f / sigma_px)^2 ~ 1e5`` per rad^2;
            ``1e-6`` gives ``1e12``).
        camera_pose: the fixed real camera pose (camera-to-world) used when no
            camera key is given; identity if ``None``.

    Residual: ``(6,)`` ``[Log(R_p^T R_v) (rad), R_p^T (c_v - c_p) (length)]``, see the
    module docstring for the Jacobians.
    """

    def __init__(self, sigma_rotation: float = 1e-6, sigma_translation: float = 1e-6,
                 camera_pose: gtsam.Pose3 | None = None) -> None:
        self.sigmas = np.array([sigma_rotation] * 3 + [sigma_translation] * 3, dtype=float)
        self.camera_pose = camera_pose if camera_pose is not None else gtsam.Pose3()

    # ----------------------------------------------------------------- numpy core
    @staticmethod
    def evaluate(Rc: np.ndarray, tc: np.ndarray, n: np.ndarray, d: float, basis: np.ndarray,
                 Rv: np.ndarray, cv: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Residual and Jacobians.

        Args:
            Rc, tc: real camera rotation (3, 3) and centre (3,), world frame.
            n, d: unit plane normal (3,) and distance of ``n . X = d``.
            basis: ``(3, 2)`` tangent basis of ``n`` (:meth:`gtsam.Unit3.basis`).
            Rv, cv: virtual camera rotation (3, 3) and centre (3,).

        Returns:
            ``e`` (6,), ``J_camera`` (6, 6), ``J_plane`` (6, 3), ``J_virtual`` (6, 6),
            each Jacobian with respect to the GTSAM tangent space of that variable.
        """
        n = np.asarray(n, dtype=float).reshape(3)
        H = householder(n)
        Rp = H @ Rc @ D_FLIP
        cp = H @ tc + 2.0 * d * n
        e_rot = so3_log(Rp.T @ Rv)
        e_tr = Rp.T @ (cv - cp)
        Jr_inv = so3_right_jacobian_inverse(e_rot)
        Jl_inv = so3_left_jacobian_inverse(e_rot)
        E_tr = skew(e_tr)

        J_virtual = np.zeros((6, 6))
        J_virtual[:3, :3] = Jr_inv
        J_virtual[3:, 3:] = Rp.T @ Rv

        # camera: phi = -D a, dc_p = H R_c b
        J_camera = np.zeros((6, 6))
        J_camera[:3, :3] = Jl_inv @ D_FLIP
        J_camera[3:, :3] = -E_tr @ D_FLIP
        J_camera[3:, 3:] = -Rp.T @ H @ Rc

        # plane: phi = 2 D R_c^T [n]x B v12, dc_p = -2 (n t_c^T + (n.t_c - d) I) B v12 - 2 n v3
        dphi = 2.0 * D_FLIP @ Rc.T @ skew(n) @ basis                        # (3, 2)
        dcp = -2.0 * (np.outer(n, tc) + (n @ tc - d) * np.eye(3)) @ basis   # (3, 2)
        J_plane = np.zeros((6, 3))
        J_plane[:3, :2] = -Jl_inv @ dphi
        J_plane[3:, :2] = E_tr @ dphi - Rp.T @ dcp
        J_plane[3:, 2] = Rp.T @ (2.0 * n)
        e = np.concatenate([e_rot, e_tr])
        return e, J_camera, J_plane, J_virtual

    # ----------------------------------------------------------------- GTSAM factor
    def make(self, plane_key: int, virtual_key: int, camera_key: int | None = None
             ) -> gtsam.CustomFactor:
        """The :class:`gtsam.CustomFactor` on ``(plane, virtual[, camera])``."""
        fixed = self.camera_pose
        keys = [plane_key, virtual_key] + ([camera_key] if camera_key is not None else [])
        evaluate = self.evaluate

        def error(this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
            plane = values.atOrientedPlane3(plane_key)
            n, d = plane_from_gtsam(plane)
            basis = np.asarray(plane.normal().basis())
            V = values.atPose3(virtual_key)
            C = values.atPose3(camera_key) if camera_key is not None else fixed
            e, Jc, Jp, Jv = evaluate(C.rotation().matrix(), np.asarray(C.translation()),
                                     n, d, basis, V.rotation().matrix(),
                                     np.asarray(V.translation()))
            if H is not None:
                H[0] = Jp
                H[1] = Jv
                if camera_key is not None:
                    H[2] = Jc
            return e

        return gtsam.CustomFactor(gtsam.noiseModel.Diagonal.Sigmas(self.sigmas), keys, error)
