"""Error metrics against ground truth, as MirrorCalib defines them.

* rotation error: the angle of ``R_est^T R_true`` (axis-angle), degrees;
* translation error: ``|mu t_est - t_true|`` with ``mu = |t_true| / |t_est|``
  (the estimate scaled to the true norm), in the unit of ``t_true``;
* PA-MPJPE: mean per-joint position error after Procrustes alignment
  (rotation, translation and scale) of each frame, in the unit of the truth.

For a mirror, the virtual camera's rotation error is twice the angle between
the estimated and the true normal (``R_est^T R_true = H_est H_true``, a
rotation by twice the angle between the two planes).

What the best estimator could reach: :func:`cramer_rao_mirror`, the Cramer-Rao
bound of the mirror normal from joints seen in both views under iid pixel noise.
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import (householder, project_with_jacobian, similarity_align, tangent_basis,
                       virtual_camera_from_mirror)


def rotation_error_deg(R_est: np.ndarray, R_true: np.ndarray) -> float:
    """Angle of ``R_est^T R_true`` in degrees (both ``(3, 3)`` rotations), SciPy's
    :meth:`~scipy.spatial.transform.Rotation.magnitude`: exact to the last digits at any
    angle, where ``arccos((trace - 1) / 2)`` reads 0 below ~1e-6 deg."""
    from scipy.spatial.transform import Rotation    # at first use: not on every start-up

    R = np.asarray(R_est, dtype=float).T @ np.asarray(R_true, dtype=float)
    return float(np.degrees(Rotation.from_matrix(R).magnitude()))


def mirror_rotation_error_deg(n_est: np.ndarray, n_true: np.ndarray) -> float:
    """Rotation error (deg) of the virtual camera implied by two mirror normals.

    Equal to ``rotation_error_deg(D H_est, D H_true)``, i.e. twice the angle
    between the normals.
    """
    return rotation_error_deg(virtual_camera_from_mirror(n_est, 1.0)[0],
                              virtual_camera_from_mirror(n_true, 1.0)[0])


def normal_angle_deg(n_est: np.ndarray, n_true: np.ndarray) -> float:
    """Angle between two normals (any length), degrees: ``atan2(|a x b|, a . b)``,
    exact at small angles, where the ``arccos`` of the cosine reads 0 below ~1e-6 deg."""
    a, b = np.asarray(n_est, dtype=float), np.asarray(n_true, dtype=float)
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b))))


def translation_error(t_est: np.ndarray, t_true: np.ndarray) -> float:
    """MirrorCalib's translation error: ``|mu t_est - t_true|``, ``mu = |t_true|/|t_est|``."""
    t_est, t_true = np.asarray(t_est, float), np.asarray(t_true, float)
    return float(np.linalg.norm(t_est * (np.linalg.norm(t_true) / np.linalg.norm(t_est)) - t_true))


def pa_joint_errors(pred: np.ndarray, truth: np.ndarray,
                    valid: np.ndarray | None = None) -> np.ndarray:
    """Each joint's error after its frame's similarity alignment
    (:func:`~mirrorgraph.geometry.similarity_align`, Umeyama 1991).

    Args:
        pred, truth: ``(T, J, 3)`` joints.
        valid: ``(T, J)`` bool; the alignment of a frame uses its valid finite joints.

    Returns:
        ``(T, J)`` errors in the unit of ``truth``; NaN off the valid finite joints and in
        frames of fewer than 3 of them.
    """
    pred, truth = np.asarray(pred, float), np.asarray(truth, float)
    ok = np.isfinite(pred).all(-1) & np.isfinite(truth).all(-1)
    if valid is not None:
        ok &= valid
    out = np.full(ok.shape, np.nan)
    frames = ok.sum(1) >= 3
    if not frames.any():
        return out
    w = ok[frames].astype(float)
    R, s, t = similarity_align(pred[frames], truth[frames], w)
    aligned = s[:, None, None] * np.einsum("fij,fnj->fni", R, pred[frames]) + t[:, None, :]
    out[frames] = np.where(w > 0, np.linalg.norm(aligned - truth[frames], axis=-1), np.nan)
    return out


def pa_mpjpe(pred: np.ndarray, truth: np.ndarray, valid: np.ndarray | None = None) -> float:
    """Procrustes-aligned mean per-joint position error.

    Args:
        pred, truth: ``(T, J, 3)`` joints.
        valid: ``(T, J)`` bool; frames with fewer than 3 valid joints are skipped.

    Returns:
        Mean error over valid joints after a per-frame similarity alignment
        (Umeyama 1991; :func:`pa_joint_errors`), in the unit of ``truth``.
    """
    err = pa_joint_errors(pred, truth, valid)
    ok = np.isfinite(err)
    return float(err[ok].mean()) if ok.any() else float("nan")


def cramer_rao_mirror(K: np.ndarray, n: np.ndarray, d: float, X: np.ndarray, sigma: float,
                      rng: np.random.Generator | None = None) -> dict:
    """Cramer-Rao bound of the mirror normal from joints seen in both views.

    Every joint ``X_i`` (unknown, 3 parameters) is seen at ``pi(K X_i)`` and in the
    mirror ``n . X = d`` at ``pi(K S(X_i))``, with iid Gaussian noise ``sigma`` per
    pixel coordinate; the Fisher information of the normal's two tangent coordinates
    with every joint eliminated (the Schur complement of the ``3 x 3`` joint blocks,
    Hartley and Zisserman, *Multiple View Geometry*, 2nd ed., sec. 5.2 and A6.3)
    inverts to the bound on any unbiased estimator's covariance. The distance ``d``
    is the gauge (images fix ``n``, not ``d``). Reprojection only: a body prior adds
    information, a detector's bias is not in it.

    Args:
        K: ``(3, 3)`` intrinsics.
        n: ``(3,)`` unit normal (real camera frame, away from the camera); d: distance.
        X: ``(N, 3)`` joints (real camera frame, the unit of ``d``).
        sigma: pixel noise, px.
        rng: for the median form (default: seed 0).

    Returns:
        ``rot_rms_deg`` (``2 sqrt(tr Sigma_n)``: the RMS rotation error of the virtual
        camera, degrees), ``rot_median_deg`` (median of ``2 |delta|`` for
        ``delta ~ N(0, Sigma_n)``), ``trans_rms_mm`` (``2 d sqrt(tr Sigma_n)`` in
        thousandths of ``d``'s unit: mm for metres) and ``normal_cov`` (``2 x 2``,
        rad^2, in :func:`~mirrorgraph.geometry.tangent_basis` of ``n``).
    """
    K = np.asarray(K, float)
    X = np.asarray(X, float).reshape(-1, 3)
    n = np.asarray(n, float)
    B = tangent_basis(n)
    H = householder(n)
    S = X @ H.T + 2.0 * d * n                              # reflected points
    J1 = project_with_jacobian(K, X)[1]                    # (N, 2, 3) d u / d X
    J2 = project_with_jacobian(K, S)[1]                    # d u' / d S
    Jx = np.concatenate([J1, J2 @ H], 1)                   # (N, 4, 3)
    s = X @ n - d                                          # (N,)
    # d S / d n = -2 (s I + n X^T), along the tangent basis
    dS_dn = -2.0 * (s[:, None, None] * np.eye(3)[None] + n[None, :, None] * X[:, None, :])
    Jn2 = J2 @ dS_dn @ B                                   # (N, 2, 2)
    Jn = np.concatenate([np.zeros_like(Jn2), Jn2], 1)      # (N, 4, 2)
    A = np.einsum("nki,nkj->nij", Jx, Jx)                  # (N, 3, 3)
    C = np.einsum("nki,nkj->nij", Jx, Jn)                  # (N, 3, 2)
    Dn = np.einsum("nki,nkj->nij", Jn, Jn).sum(0)          # (2, 2)
    schur = Dn - np.einsum("nji,njk->ik", C, np.linalg.solve(A, C))
    cov = np.linalg.inv(schur) * sigma ** 2
    tr = float(np.trace(cov))
    rng = rng or np.random.default_rng(0)
    delta = rng.multivariate_normal(np.zeros(2), cov, 20000)
    med = float(np.degrees(2.0 * np.median(np.linalg.norm(delta, axis=1))))
    return dict(rot_rms_deg=float(np.degrees(2.0 * math.sqrt(tr))), rot_median_deg=med,
                trans_rms_mm=float(2.0 * d * math.sqrt(tr) * 1000.0), normal_cov=cov.tolist())
