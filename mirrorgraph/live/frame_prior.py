"""One frame's joints refined with the body's bone lengths: the live run's per-frame prior.

The per-frame path of :class:`~mirrorgraph.live.calibrator.LiveCalibrator` triangulates
each joint from its two rays alone (the camera and its reflection). The offline graph
holds every bone at one length over the video (:mod:`mirrorgraph.factors.bone_length`);
the live run has those lengths from its latest window's solve, and refines each frame's
joints with them at a fixed cost: a few Gauss-Newton steps on

    sum_j rho(|pi(K X_j) - u_j|^2 / s^2) + rho(|pi(K S(X_j)) - u'_j|^2 / s^2)
      + sum_b (|X_a - X_b| - L_b)^2 / s_L^2

over the frame's joints ``X`` (``S`` the reflection in the mirror plane, ``s`` the
reprojection noise, ``s_L`` the bones' spread, ``rho`` Huber's loss at 1.345 standard
deviations on the pixels: Huber, *Robust Statistics*, 1981; Hartley and Zisserman,
*Multiple View Geometry*, 2nd ed., sec. A6.8). The bones are Gaussian, as the offline
graph's factor: a joint the detector misplaced along its epipolar line (which the
reprojection threshold cannot see) is held by its bones. The normal equations are one dense ``3k x 3k`` system
(``k`` <= 33 joints), built from per-joint ``2 x 3`` projection Jacobians and per-bone
``1 x 3`` length Jacobians, vectorised; the joints' covariance is its inverse (the
Laplace approximation, at the final weights).
"""

from __future__ import annotations

import numpy as np

__all__ = ["refine_with_bones", "HUBER_K"]

#: Huber's threshold in standard deviations (95 % efficiency under Gaussian noise).
HUBER_K = 1.345


def _huber_weight(r: np.ndarray) -> np.ndarray:
    """IRLS weights of Huber's loss for normalised residual norms ``r``."""
    a = np.abs(r)
    return np.where(a <= HUBER_K, 1.0, HUBER_K / np.maximum(a, 1e-12))


def _projection(K: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels ``(k, 2)`` of points ``Y`` ``(k, 3)`` and their Jacobians ``(k, 2, 3)``."""
    q = Y @ K.T
    p = q[:, :2] / q[:, 2:3]
    J = (K[None, :2, :] - p[:, :, None] * K[None, 2:3, :]) / q[:, 2, None, None]
    return p, J


def refine_with_bones(K: np.ndarray, normal: np.ndarray, distance: float, X: np.ndarray,
                      u: np.ndarray, um: np.ndarray, joints: np.ndarray, bones: np.ndarray,
                      lengths: np.ndarray, sigma_px: float, sigma_len: float,
                      iterations: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Refine one frame's triangulated joints with the bones' lengths.

    Args:
        K: ``(3, 3)`` camera matrix, px.
        normal, distance: the mirror plane ``n . X = d`` (camera frame, unit ``n``).
        X: ``(k, 3)`` the joints triangulated from their two rays (camera frame).
        u, um: ``(k, 2)`` their pixels in the camera and in the mirror (the reflection's
            keypoints in the person's labels), undistorted.
        joints: ``(k,)`` the skeleton's indices of the ``k`` joints.
        bones: ``(B, 2)`` skeleton joint indices of each bone's two ends.
        lengths: ``(B,)`` the bones' lengths (the unit of ``X``); NaN: not used.
        sigma_px: the reprojection noise, px.
        sigma_len: the bones' spread about their lengths (the unit of ``X``).
        iterations: Gauss-Newton steps.

    Returns:
        ``(X, cov)``: the refined ``(k, 3)`` joints and each one's ``(k, 3, 3)``
        covariance (a bone's two ends are correlated; the blocks are the marginals).
    """
    X = np.array(X, dtype=float)
    k = len(X)
    n = np.asarray(normal, float)
    H = np.eye(3) - 2.0 * np.outer(n, n)
    local = np.full(int(max(np.max(joints), np.max(bones, initial=0))) + 1, -1)
    local[np.asarray(joints)] = np.arange(k)
    a, b = local[bones[:, 0]], local[bones[:, 1]]
    use = (a >= 0) & (b >= 0) & np.isfinite(lengths)
    a, b, L = a[use], b[use], np.asarray(lengths, float)[use]
    ar = np.arange(k)
    A = np.zeros((k, 3, k, 3))
    for _ in range(max(int(iterations), 1)):
        p1, J1 = _projection(K, X)
        p2, J2 = _projection(K, X @ H.T + 2.0 * distance * n)
        J2 = J2 @ H
        r1, r2 = (p1 - u) / sigma_px, (p2 - um) / sigma_px
        w1 = _huber_weight(np.linalg.norm(r1, axis=1))[:, None, None]
        w2 = _huber_weight(np.linalg.norm(r2, axis=1))[:, None, None]
        J1, J2 = J1 / sigma_px, J2 / sigma_px
        A[:] = 0.0
        A[ar, :, ar, :] = (w1 * np.einsum("kri,krj->kij", J1, J1)
                           + w2 * np.einsum("kri,krj->kij", J2, J2))
        g = (w1[:, :, 0] * np.einsum("kri,kr->ki", J1, r1)
             + w2[:, :, 0] * np.einsum("kri,kr->ki", J2, r2))
        if len(L):
            diff = X[a] - X[b]
            length = np.linalg.norm(diff, axis=1)
            e = diff / np.maximum(length, 1e-12)[:, None] / sigma_len    # d r / d X_a
            rb = (length - L) / sigma_len
            outer = e[:, :, None] * e[:, None, :]
            np.add.at(A, (a, slice(None), a, slice(None)), outer)
            np.add.at(A, (b, slice(None), b, slice(None)), outer)
            np.add.at(A, (a, slice(None), b, slice(None)), -outer)
            np.add.at(A, (b, slice(None), a, slice(None)), -outer)
            np.add.at(g, a, e * rb[:, None])
            np.add.at(g, b, -e * rb[:, None])
        M = A.reshape(3 * k, 3 * k)
        try:
            step = np.linalg.solve(M, -g.reshape(-1))
        except np.linalg.LinAlgError:
            break
        X = X + step.reshape(k, 3)
    cov = np.linalg.inv(A.reshape(3 * k, 3 * k)).reshape(k, 3, k, 3)[ar, :, ar, :]
    return X, cov
