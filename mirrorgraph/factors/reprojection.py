"""Robust reprojection factors of the direct and the mirror view (the paper's ``L_repro``).

MirrorCalib (Liao, Zheng and Mitchell, sec. "Refining 2D joint locations",
eq. ``L_repro``) penalises ``rho(|Pi(Theta, X) - u| + |Pi(Theta', X) - u'|)`` with
``rho`` the Geman-McClure function. Here every observation is its own factor,
``rho(|Pi(Theta, X) - u| / sigma)`` for the direct view and the same for the
mirror view, so that a gross error in one view does not discard the other.

Both are GTSAM's built-in C++ factors (a Python factor per observation would
cost ~10x more per linearisation):

* direct view: :class:`gtsam.TriangulationFactorCal3_S2` with the fixed camera
  ``PinholeCameraCal3_S2(C, K)`` (``C`` camera-to-world), a factor on the point only;
* direct view of a camera whose pose is estimated:
  :class:`gtsam.GenericProjectionFactorCal3_S2` between its pose variable and the point;
* mirror view: :class:`gtsam.GenericProjectionFactorCal3_S2` between the pose
  variable ``V`` of the virtual camera and the point, with the mirrored
  calibration ``K D = Cal3_S2(-fx, fy, s, cx, cy)`` (:func:`mirrored_calibration`).
  With ``V = (H R_c D, S(t_c))`` (:func:`mirrorgraph.factors.mirror_link.reflected_pose`)
  it projects ``X`` to ``pi(K S(X))``: the virtual camera frame is ``D`` times the
  reflected (left-handed) frame, and the ``D`` is absorbed by negating ``fx``;
* a camera whose intrinsics are estimated (:attr:`mirrorgraph.graph.rig.Camera.estimate_focal`):
  :class:`gtsam.GeneralSFMFactor2Cal3_S2` between a pose, the point and a
  :class:`gtsam.Cal3_S2` variable, in both views (:meth:`ReprojectionFactors.add_calibrated`):
  the real camera's calibration ``K`` for the direct view (its pose variable, or a
  held one), the mirrored calibration ``K D`` for the mirror views. The two
  calibration variables are one unknown ``f`` (and ``cx, cy``): the solver moves
  them together (:mod:`mirrorgraph.graph.reduction`).

Frames and units: points are in the world frame (the real camera frame of
:mod:`mirrorgraph.geometry`), in the length unit of the scene; pixels are
undistorted, origin top-left. The whitened residual is ``(Pi(X) - u) / sigma``
with ``sigma`` in pixels; the robust kernel acts on its norm (GTSAM's block
reweighting), i.e. on the pixel distance, with scale ``kernel_scale_px / sigma``.
"""

from __future__ import annotations

import gtsam
import numpy as np

from ..geometry import project, reflect_points

__all__ = ["ReprojectionFactors", "robust_pixel_noise", "mirrored_calibration",
           "calibration", "direct_residuals", "mirror_residuals", "KERNELS",
           "kernel_weights"]

#: Robust kernels by option name: GTSAM m-estimator constructors taking the scale.
KERNELS = {
    "geman_mcclure": gtsam.noiseModel.mEstimator.GemanMcClure.Create,
    "huber": gtsam.noiseModel.mEstimator.Huber.Create,
    "cauchy": gtsam.noiseModel.mEstimator.Cauchy.Create,
    "tukey": gtsam.noiseModel.mEstimator.Tukey.Create,
}


def kernel_weights(kernel: str | None, residual: np.ndarray, scale: float) -> np.ndarray:
    """The weight :data:`KERNELS`' m-estimator gives each residual (its square root
    multiplies a factor's whitened Jacobian and error when GTSAM linearises it).

    Args:
        kernel: a name of :data:`KERNELS`, or ``None``/``"none"`` (weights 1).
        residual: ``(...)`` residual norms; scale: the kernel's scale, the same unit.

    Returns:
        ``(...)`` weights in ``[0, 1]``: Geman-McClure ``c^4 / (c^2 + e^2)^2``, Huber
        ``min(1, c / |e|)``, Cauchy ``c^2 / (c^2 + e^2)``, Tukey ``(1 - (e / c)^2)^2``
        within ``c`` (0 beyond).
    """
    e2 = np.asarray(residual, float) ** 2
    c2 = float(scale) ** 2
    if kernel is None or kernel == "none":
        return np.ones_like(e2)
    if kernel == "geman_mcclure":
        return (c2 / (c2 + e2)) ** 2
    if kernel == "huber":
        return np.minimum(1.0, np.sqrt(c2 / np.maximum(e2, 1e-300)))
    if kernel == "cauchy":
        return c2 / (c2 + e2)
    if kernel == "tukey":
        return np.where(e2 <= c2, (1.0 - e2 / c2) ** 2, 0.0)
    raise ValueError(f"unknown robust kernel {kernel!r}; known: {', '.join(KERNELS)}, none")


def robust_pixel_noise(sigma_px: float, kernel: str | None = "geman_mcclure",
                       kernel_scale_px: float = 10.0) -> gtsam.noiseModel.Base:
    """Isotropic 2-D pixel noise, optionally wrapped in a robust kernel.

    Args:
        sigma_px: standard deviation of a keypoint coordinate, pixels (weight of
            the reprojection terms: the paper's ``lambda_repro`` is ``1 / sigma^2``).
        kernel: ``"geman_mcclure"`` (the paper), ``"huber"``, ``"cauchy"``,
            ``"tukey"`` or ``None``/``"none"`` for plain least squares.
        kernel_scale_px: the kernel's scale ``c`` in pixels of residual norm
            (Geman-McClure: ``rho(e) = c^2 e^2 / (2 (c^2 + e^2))``, weight 1/4 at ``e = c``).
    """
    base = gtsam.noiseModel.Isotropic.Sigma(2, float(sigma_px))
    if kernel is None or kernel == "none":
        return base
    if kernel not in KERNELS:
        raise ValueError(f"unknown robust kernel {kernel!r}; known: {', '.join(KERNELS)}, none")
    return gtsam.noiseModel.Robust.Create(KERNELS[kernel](float(kernel_scale_px) / sigma_px),
                                          base)


def calibration(K: np.ndarray) -> gtsam.Cal3_S2:
    """:class:`gtsam.Cal3_S2` of a ``(3, 3)`` camera matrix (fx, fy, skew, cx, cy)."""
    K = np.asarray(K, dtype=float)
    return gtsam.Cal3_S2(K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2])


def mirrored_calibration(K: np.ndarray) -> gtsam.Cal3_S2:
    """``K D`` as a :class:`gtsam.Cal3_S2`: ``(-fx, fy, skew, cx, cy)``, for the mirror view."""
    K = np.asarray(K, dtype=float)
    return gtsam.Cal3_S2(-K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2])


def direct_residuals(K: np.ndarray, X: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """``(..., 2)`` pixel residuals ``pi(K X) - u`` of the direct view (camera at the origin)."""
    return project(K, X) - np.asarray(uv, dtype=float)


def mirror_residuals(K: np.ndarray, normal: np.ndarray, distance: float, X: np.ndarray,
                     uv: np.ndarray) -> np.ndarray:
    """``(..., 2)`` pixel residuals ``pi(K S(X)) - u'`` of the mirror view (camera at the origin)."""
    return project(K, reflect_points(X, normal, distance)) - np.asarray(uv, dtype=float)


class ReprojectionFactors:
    """Factory of the built-in reprojection factors of one view.

    Args:
        K: ``(3, 3)`` intrinsics of the real camera.
        noise: pixel noise model (:func:`robust_pixel_noise`), shared by all factors.
        camera_pose: fixed real camera pose (camera-to-world, :class:`gtsam.Pose3`);
            identity if ``None``.

    The factors' Jacobians are GTSAM's analytic ones; ``tests/factors/test_factors.py``
    checks them against central differences of ``pi(K X)`` and ``pi(K S(X))``.
    """

    def __init__(self, K: np.ndarray, noise: gtsam.noiseModel.Base,
                 camera_pose: gtsam.Pose3 | None = None) -> None:
        self.K = np.asarray(K, dtype=float)
        self.noise = noise
        self.camera = gtsam.PinholeCameraCal3_S2(
            camera_pose if camera_pose is not None else gtsam.Pose3(), calibration(K))
        self.K_mirror = mirrored_calibration(K)

    def direct(self, uv: np.ndarray, point_key: int) -> gtsam.TriangulationFactorCal3_S2:
        """Factor ``rho(|pi(K X) - u| / sigma)`` on one point; ``uv`` (2,) pixels."""
        return gtsam.TriangulationFactorCal3_S2(self.camera, uv, self.noise, point_key)

    def add_posed(self, graph: gtsam.NonlinearFactorGraph, uv: np.ndarray, pose_key: int,
                  point_keys: np.ndarray) -> None:
        """Add one direct-view factor per row of ``uv`` (N, 2) for a camera whose pose
        (camera-to-world) is the variable ``pose_key``."""
        Kc, noise = calibration(self.K), self.noise
        make = gtsam.GenericProjectionFactorCal3_S2
        for u, k in zip(np.asarray(uv, dtype=float), np.asarray(point_keys).tolist()):
            graph.push_back(make(u, noise, pose_key, k, Kc))

    def mirror(self, uv: np.ndarray, virtual_key: int, point_key: int
               ) -> gtsam.GenericProjectionFactorCal3_S2:
        """Factor ``rho(|pi(K S(X)) - u'| / sigma)`` through the virtual camera pose ``V``."""
        return gtsam.GenericProjectionFactorCal3_S2(uv, self.noise, virtual_key, point_key,
                                                     self.K_mirror)

    def add_direct(self, graph: gtsam.NonlinearFactorGraph, uv: np.ndarray,
                   point_keys: np.ndarray) -> None:
        """Add one direct-view factor per row of ``uv`` (N, 2) with ``point_keys`` (N,)."""
        cam, noise = self.camera, self.noise
        make = gtsam.TriangulationFactorCal3_S2
        for u, k in zip(np.asarray(uv, dtype=float), np.asarray(point_keys).tolist()):
            graph.push_back(make(cam, u, noise, k))

    def add_calibrated(self, graph: gtsam.NonlinearFactorGraph, uv: np.ndarray, pose_key: int,
                       calibration_key: int, point_keys: np.ndarray) -> None:
        """Add one factor per row of ``uv`` (N, 2) whose calibration is a variable.

        ``rho(|pi(K_c, P, X) - u| / sigma)`` with the pose ``P`` (camera-to-world: the
        real camera's, or the virtual camera ``V`` of a mirror view), the point ``X``
        and the calibration ``K_c`` (:class:`gtsam.Cal3_S2`: the camera's ``K``, or
        ``K D`` for a mirror view) all variables: GTSAM's
        :class:`gtsam.GeneralSFMFactor2Cal3_S2`.
        """
        noise = self.noise
        make = gtsam.GeneralSFMFactor2Cal3_S2
        for u, k in zip(np.asarray(uv, dtype=float), np.asarray(point_keys).tolist()):
            graph.push_back(make(u, noise, pose_key, k, calibration_key))

    def add_mirror(self, graph: gtsam.NonlinearFactorGraph, uv: np.ndarray, virtual_key: int,
                   point_keys: np.ndarray) -> None:
        """Add one mirror-view factor per row of ``uv`` (N, 2) with ``point_keys`` (N,)."""
        Km, noise = self.K_mirror, self.noise
        make = gtsam.GenericProjectionFactorCal3_S2
        for u, k in zip(np.asarray(uv, dtype=float), np.asarray(point_keys).tolist()):
            graph.push_back(make(u, noise, virtual_key, k, Km))
