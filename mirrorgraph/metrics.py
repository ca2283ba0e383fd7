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

from .geometry import householder, tangent_basis, virtual_camera_from_mirror


def rotation_error_deg(R_est: np.ndarray, R_true: np.ndarray) -> float:
    """Angle of ``R_est^T R_true`` in degrees (both ``(3, 3)`` rotations)."""
    c = (np.trace(np.asarray(R_est).T @ np.asarray(R_true)) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def mirror_rotation_error_deg(n_est: np.ndarray, n_true: np.ndarray) -> float:
    """Rotation error (deg) of the virtual camera implied by two mirror normals.

    Equal to ``rotation_error_deg(D H_est, D H_true)``, i.e. twice the angle
    between the normals.
    """
    return rotation_error_deg(virtual_camera_from_mirror(n_est, 1.0)[0],
                              virtual_camera_from_mirror(n_true, 1.0)[0])


def normal_angle_deg(n_est: np.ndarray, n_true: np.ndarray) -> float:
    """Angle between two unit normals, degrees."""
    c = float(np.dot(n_est, n_true) / (np.linalg.norm(n_est) * np.linalg.norm(n_true)))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def translation_error(t_est: np.ndarray, t_true: np.ndarray) -> float:
    """MirrorCalib's translation error: ``|mu t_est - t_true|``, ``mu = |t_true|/|t_est|``."""
    t_est, t_true = np.asarray(t_est, float), np.asarray(t_true, float)
    return float(np.linalg.norm(t_est * (np.linalg.norm(t_true) / np.linalg.norm(t_est)) - t_true))


def pa_joint_errors(pred: np.ndarray, truth: np.ndarray,
                    valid: np.ndarray | None = None) -> np.ndarray:
    """Each joint's error after its frame's similarity alignment (Umeyama 1991).

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
    w = ok[frames].astype(float)[..., None]                    # (F, J, 1)
    P = np.where(w > 0, pred[frames], 0.0)
    Q = np.where(w > 0, truth[frames], 0.0)
    count = w.sum(1, keepdims=True)
    P0 = (P - (w * P).sum(1, keepdims=True) / count) * w
    Q0 = (Q - (w * Q).sum(1, keepdims=True) / count) * w
    U, S, Vt = np.linalg.svd(np.einsum("fji,fjk->fik", P0, Q0))
    sign = np.sign(np.linalg.det(U @ Vt))
    sign[sign == 0] = 1.0
    diag = np.stack([np.ones_like(sign), np.ones_like(sign), sign], axis=1)   # (F, 3)
    R = U @ (diag[:, :, None] * Vt)
    scale = (S * diag).sum(1) / (P0 ** 2).sum((1, 2))
    aligned = scale[:, None, None] * P0 @ R
    out[frames] = np.where(w[..., 0] > 0, np.linalg.norm(aligned - Q0, axis=-1), np.nan)
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


def _projection_jacobian(K: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``(N, 2, 3)`` Jacobian of ``pi(K Y)`` with respect to the camera-frame points ``Y``."""
    z = Y[:, 2]
    J = np.zeros((len(Y), 2, 3))
    J[:, 0, 0] = J[:, 1, 1] = 1.0 / z
    J[:, 0, 2] = -Y[:, 0] / z ** 2
    J[:, 1, 2] = -Y[:, 1] / z ** 2
    return K[None, :2, :2] @ J


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
    J1 = _projection_jacobian(K, X)                        # (N, 2, 3) d u / d X
    J2 = _projection_jacobian(K, S)                        # d u' / d S
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
