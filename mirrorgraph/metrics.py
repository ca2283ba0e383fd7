"""Error metrics against ground truth, as MirrorCalib defines them.

* rotation error: the angle of ``R_est^T R_true`` (axis-angle), degrees;
* translation error: ``|mu t_est - t_true|`` with ``mu = |t_true| / |t_est|``
  (the estimate scaled to the true norm), in the unit of ``t_true``;
* PA-MPJPE: mean per-joint position error after Procrustes alignment
  (rotation, translation and scale) of each frame, in the unit of the truth.

For a mirror, the virtual camera's rotation error is twice the angle between
the estimated and the true normal (``R_est^T R_true = H_est H_true``, a
rotation by twice the angle between the two planes).
"""

from __future__ import annotations

import numpy as np


def rotation_error_deg(R_est: np.ndarray, R_true: np.ndarray) -> float:
    """Angle of ``R_est^T R_true`` in degrees (both ``(3, 3)`` rotations)."""
    c = (np.trace(np.asarray(R_est).T @ np.asarray(R_true)) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def mirror_rotation_error_deg(n_est: np.ndarray, n_true: np.ndarray) -> float:
    """Rotation error (deg) of the virtual camera implied by two mirror normals.

    Equal to ``rotation_error_deg(D H_est, D H_true)``, i.e. twice the angle
    between the normals.
    """
    from .geometry import virtual_camera_from_mirror

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


def pa_mpjpe(pred: np.ndarray, truth: np.ndarray, valid: np.ndarray | None = None) -> float:
    """Procrustes-aligned mean per-joint position error.

    Args:
        pred, truth: ``(T, J, 3)`` joints.
        valid: ``(T, J)`` bool; frames with fewer than 3 valid joints are skipped.

    Returns:
        Mean error over valid joints after a per-frame similarity alignment
        (Umeyama 1991), in the unit of ``truth``.
    """
    pred, truth = np.asarray(pred, float), np.asarray(truth, float)
    ok = np.isfinite(pred).all(-1) & np.isfinite(truth).all(-1)
    if valid is not None:
        ok &= valid
    frames = ok.sum(1) >= 3
    if not frames.any():
        return float("nan")
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
    err = np.linalg.norm(aligned - Q0, axis=-1)
    return float(err[w[..., 0] > 0].mean())
