"""The refinement's result and the uncertainty it implies for the virtual camera.

Normal covariance to rotation uncertainty. The virtual camera's rotation is
``R_v = H R_c D`` (camera-to-world, :mod:`mirrorgraph.factors.mirror_link`), and
its extrinsic rotation ``D H`` (:func:`mirrorgraph.geometry.virtual_camera_from_mirror`)
is the same up to transpose. A small tilt of the unit normal, ``n <- n + dn`` with
``dn`` perpendicular to ``n``, changes ``H`` by ``dH = -2 (dn n^T + n dn^T)`` and
``H dH = 2 [dn x n]x``: the virtual camera turns about the axis ``n x dn`` by the
angle ``|phi| = 2 |n x dn| = 2 |dn|``. A mirror tilted by ``theta`` turns the
virtual camera by ``2 theta``.

If ``dn`` has covariance ``Sigma_n`` (3x3, rank 2, in the tangent plane), the
rotation error angle ``|phi|`` has mean square ``E|phi|^2 = 4 tr(Sigma_n)``. The
*rotation standard deviation* reported is its root mean square,
``2 sqrt(tr Sigma_n)`` in degrees, the figure to compare with the angle of
``R_est^T R_true`` over repeated experiments (for an isotropic ``Sigma_n`` the
angle is Rayleigh-distributed: median = 0.83 x RMS).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["RefinementResult", "rotation_std_from_normal_cov", "normal_cov_from_tangent",
           "residual_noise_px"]


def rotation_std_from_normal_cov(normal_cov: np.ndarray) -> float:
    """RMS rotation error of the virtual camera, degrees, from the normal's ``(3, 3)`` covariance.

    ``2 sqrt(trace(normal_cov))`` radians, in degrees (see the module docstring).
    """
    tr = float(np.trace(np.asarray(normal_cov, dtype=float)))
    return float(np.degrees(2.0 * np.sqrt(max(tr, 0.0))))


def residual_noise_px(sum_sq_px: float, coordinates: int, unknowns: int) -> float:
    """A posteriori standard deviation of one keypoint coordinate, pixels.

    ``sqrt(RSS / (m - u))`` for ``m`` measured coordinates and ``u`` estimated
    parameters: the residuals of a maximum-likelihood fit are smaller than the noise
    by ``sqrt(1 - u / m)`` (Hartley and Zisserman, *Multiple View Geometry*, 2nd ed.,
    result 5.2). The marginals assume ``RefineOptions.pixel_sigma``; multiplied by
    ``(this / pixel_sigma)^2`` they follow the noise actually in the data, as
    OpenCV's ``calibrateCamera`` scales its parameter deviations. The body priors
    (bone lengths, symmetry, smoothness) are not counted as measurements, so with
    them this slightly overstates the noise (a cautious direction).

    Args:
        sum_sq_px: sum of the squared reprojection residuals (both coordinates), px^2.
        coordinates: ``m``, twice the number of observations.
        unknowns: ``u``: 3 per estimated point, plus the camera and plane parameters.

    Returns:
        The standard deviation, px; NaN when ``m <= u``.
    """
    dof = int(coordinates) - int(unknowns)
    return float(np.sqrt(sum_sq_px / dof)) if dof > 0 else float("nan")


def normal_cov_from_tangent(basis: np.ndarray, tangent_cov: np.ndarray) -> np.ndarray:
    """``B Sigma B^T`` (3, 3): the unit normal's covariance from its ``(2, 2)`` tangent one.

    Args:
        basis: ``(3, 2)`` orthonormal tangent basis at the normal (:meth:`gtsam.Unit3.basis`).
        tangent_cov: ``(2, 2)`` covariance of the tangent coordinates (radians^2).
    """
    B = np.asarray(basis, dtype=float)
    return B @ np.asarray(tangent_cov, dtype=float) @ B.T


@dataclass
class RefinementResult:
    """The refined mirror, joints and body, and how certain they are.

    Attributes:
        normal: ``(3,)`` unit mirror normal, real camera frame, away from the camera.
        distance: mirror distance ``d``: metres with ``subject_height``, else 1.0.
        scale: ``"subject_height"`` or ``"unit_distance"`` (which gauge fixed the scale).
        joints3d: ``(T, J, 3)`` joints, real camera frame, unit of ``distance``;
            NaN where not estimated.
        valid: ``(T, J)`` bool, where ``joints3d`` is estimated.
        inliers: ``(T, J)`` bool, pairs used by the final solve (input inliers minus
            the ones rejected by the reprojection and bone tests); here equal to ``valid``.
        bone_lengths: bone name -> length (unit of ``distance``).
        normal_cov: ``(3, 3)`` covariance of the unit normal (camera frame, rad^2): the
            cluster-robust one that sees errors correlated over time and per joint
            (:mod:`.uncertainty`), never below the marginal one,
            rank 2; NaN if marginals were not computed.
        rotation_std_deg: RMS virtual-camera rotation error implied by ``normal_cov``
            (:func:`rotation_std_from_normal_cov`).
        distance_std: standard deviation of ``distance`` (0 for the unit-distance gauge
            up to the gauge prior's tiny sigma).
        rms_direct_px, rms_mirror_px: RMS reprojection residual norm of the final
            inliers in the direct and the mirror view, px.
        iterations: Levenberg-Marquardt linear solves, all stages together (the
            progress callback counts the accepted ones).
        final_error: the final graph error (0.5 sum of squared whitened, robustified residuals).
        priors: prior name -> ``{"sigma", "weight", "unit", "factors", ...}`` (weight
            ``1 / sigma^2``); ``"reprojection"`` holds the pixel sigma and kernel.
        timings: seconds: ``build``, ``solve``, ``marginals``, ``total``.
        stages: per solve stage: name, iterations, initial/final error, rejected
            pairs, kernel (and, for long videos, each chunk pass's global step).
        scale_source: with a subject height, how it became a length: the stature
            measured on the joints (:mod:`mirrorgraph.stature`) or, failing that,
            the limb bones' Winter proportions; empty without a height.
        stature: the stature estimate's record (:meth:`StatureEstimate.to_dict`),
            after scaling (its height is the subject's), or ``None``.
        marginal_normal_cov, marginal_rotation_std_deg: the graph's marginals (the
            iid figure), scaled by the a posteriori noise.
        uncertainty_parts: what the robust figure is made of: the rotation std seen by
            the time series alone and by the joint clusters alone, the time
            series' bandwidth (frames), the ratio to the marginal one.
        sensitivity: what the calibration rests on (:mod:`.sensitivity`): the mirror's
            move when a joint pair or a segment is left out, each segment's
            information, the std predicted for other numbers of frames.
        intrinsics: ``(3, 3)`` the camera matrix of the solution: the estimate where the
            focal length was estimated, else the one given.
        focal: where the focal length was estimated, its record: ``estimated`` (it is
            the solution's; ``False``: the data did not determine it and the guess was
            kept), ``focal_px``, ``std_px`` (the larger of the marginal and the
            time-robust figure), ``marginal_std_px``, ``robust_std_px``,
            ``robust_figure``, ``rel_std``, ``guess_px``, ``search_px`` (the initial
            search's), ``principal_point`` (and ``principal_point_std_px`` where it was
            estimated), ``undetermined`` (the figures found, where the guess was kept);
            empty where the intrinsics were given.
        joints_cov: ``(T, J, 3, 3)`` each joint's covariance (unit of ``distance``
            squared; :mod:`.joints_uncertainty`), the metric scale's share left out
            (``scale_rel_std``); NaN where not estimated; ``None``: not computed.
        plane_cov: ``(3, 3)`` the plane's covariance in GTSAM's tangent of
            :class:`gtsam.OrientedPlane3` (two normal directions, the distance), the
            headline's, scaled as ``distance``: what a joint triangulated with the
            plane inherits; ``None``: not computed.
        scale_rel_std: the metric scale's relative std (the subject's height and
            the stature measured on the joints; 0 without a subject height).
    """

    normal: np.ndarray
    distance: float
    scale: str
    joints3d: np.ndarray
    valid: np.ndarray
    inliers: np.ndarray
    bone_lengths: dict[str, float]
    normal_cov: np.ndarray
    rotation_std_deg: float
    distance_std: float
    rms_direct_px: float
    rms_mirror_px: float
    iterations: int
    final_error: float
    priors: dict[str, dict]
    timings: dict[str, float]
    stages: list[dict] = field(default_factory=list)
    scale_source: str = ""
    stature: dict | None = None
    marginal_normal_cov: np.ndarray | None = None
    marginal_rotation_std_deg: float = float("nan")
    uncertainty_parts: dict = field(default_factory=dict)
    sensitivity: dict = field(default_factory=dict)
    intrinsics: np.ndarray | None = None
    focal: dict = field(default_factory=dict)
    joints_cov: np.ndarray | None = None
    plane_cov: np.ndarray | None = None
    scale_rel_std: float = 0.0
