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

__all__ = ["refine_with_bones", "triangulate_two_rays", "HUBER_K"]

#: Huber's threshold in standard deviations (95 % efficiency under Gaussian noise).
HUBER_K = 1.345


def _huber_weight(r: np.ndarray) -> np.ndarray:
    """IRLS weights of Huber's loss for normalised residual norms ``r``."""
    return np.minimum(1.0, HUBER_K / np.maximum(np.abs(r), 1e-12))


def _projection(K: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels ``(k, 2)`` of points ``Y`` ``(k, 3)`` and their Jacobians ``(k, 2, 3)``."""
    q = Y @ K.T
    p = q[:, :2] / q[:, 2:3]
    J = (K[None, :2, :] - p[:, :, None] * K[None, 2:3, :]) / q[:, 2, None, None]
    return p, J


def triangulate_two_rays(K: np.ndarray, normal: np.ndarray, distance: float, u: np.ndarray,
                         um: np.ndarray) -> np.ndarray:
    """Joints from their direct and mirrored pixels: the midpoint of the two rays.

    The direct ray leaves the camera centre along ``K^-1 [u, 1]``, the mirrored one the
    virtual camera's centre ``2 d n`` along ``H K^-1 [u', 1]`` (``H = I - 2 n n^T``);
    the point is the midpoint of their common perpendicular (Hartley and Zisserman,
    *Multiple View Geometry*, 2nd ed., sec. 12.1), closed form, vectorised. It is the
    starting point of :func:`refine_with_bones`, whose Gauss-Newton steps take it to the
    reprojection optimum.

    Args:
        K: ``(3, 3)`` camera matrix, px; normal, distance: the plane ``n . X = d``.
        u, um: ``(k, 2)`` undistorted pixels in the camera and in the mirror.

    Returns:
        ``(k, 3)`` points, camera frame, the unit of ``d``; NaN where the rays are
        parallel.
    """
    n = np.asarray(normal, float)
    Kinv = np.linalg.inv(K)
    H = np.eye(3) - 2.0 * np.outer(n, n)
    r1 = u @ Kinv[:, :2].T + Kinv[:, 2]                                   # (k, 3)
    HK = H @ Kinv
    r2 = um @ HK[:, :2].T + HK[:, 2]
    c2 = 2.0 * float(distance) * n
    a, b, c = (r1 * r1).sum(1), (r1 * r2).sum(1), (r2 * r2).sum(1)
    e, f = r1 @ c2, r2 @ c2
    den = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (e * c - b * f) / den                   # along the direct ray
        t = (b * e - a * f) / den                   # along the mirrored one
        X = 0.5 * (s[:, None] * r1 + c2 + t[:, None] * r2)
    X[~(np.abs(den) > 1e-12 * a * c)] = np.nan
    return X


def _bone_index(k: int, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flat indices into a ``(3k, 3k)`` matrix of the four ``3 x 3`` blocks ``(a, a)``,
    ``(b, b)``, ``(a, b)``, ``(b, a)`` of every bone, and their signs."""
    i3 = np.arange(3)
    rows = lambda p: 3 * p[:, None, None] + i3[None, :, None]      # noqa: E731
    cols = lambda q: 3 * q[:, None, None] + i3[None, None, :]      # noqa: E731
    idx = np.stack([rows(a) * 3 * k + cols(a), rows(b) * 3 * k + cols(b),
                    rows(a) * 3 * k + cols(b), rows(b) * 3 * k + cols(a)])   # (4, B, 3, 3)
    sign = np.array([1.0, 1.0, -1.0, -1.0])[:, None, None, None]
    return idx, sign


_INDICES: dict = {}


def _indices(k: int, a: np.ndarray, b: np.ndarray) -> tuple:
    """The flat indices of one frame's normal equations: the bones' blocks and signs
    (:func:`_bone_index`), the gradient's entries of each bone's two ends and the
    ``(k, 3, 3)`` diagonal blocks; kept per joint and bone layout (a stream repeats a
    few)."""
    key = (k, a.tobytes(), b.tobytes())
    if key not in _INDICES:
        if len(_INDICES) > 256:
            _INDICES.clear()
        bidx, bsign = _bone_index(k, a, b)
        ga = (3 * a[:, None] + np.arange(3)).ravel()
        gb = (3 * b[:, None] + np.arange(3)).ravel()
        ar = np.arange(k)
        diag = (3 * ar[:, None, None] + np.arange(3)[None, :, None]) * 3 * k \
            + 3 * ar[:, None, None] + np.arange(3)[None, None, :]               # (k, 3, 3)
        _INDICES[key] = (bidx.ravel(), bsign, ga, gb, diag)
    return _INDICES[key]


def refine_with_bones(K: np.ndarray, normal: np.ndarray, distance: float, X: np.ndarray,
                      u: np.ndarray, um: np.ndarray, joints: np.ndarray, bones: np.ndarray,
                      lengths: np.ndarray, sigma_px: float, sigma_len: float,
                      iterations: int = 3, *, gate_px: float | None = None,
                      full: bool = False):
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
        gate_px: after the steps, a view whose residual exceeds this (px) is left out
            of a joint held by bones (a keypoint displaced along its epipolar line,
            which the two rays follow in depth and the bones do not) and one more step
            is taken; ``None``: every view kept.
        full: also return the information matrix and the views kept.

    Returns:
        ``(X, cov)``: the refined ``(k, 3)`` joints and each one's ``(k, 3, 3)``
        covariance (a bone's two ends are correlated; the blocks are the marginals);
        with ``full`` also ``(3k, 3k)`` the information matrix and ``(k, 2)`` bool the
        views kept.
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
    held = np.zeros(k, bool)
    held[a] = held[b] = True
    bidx, bsign, ga, gb, diag = _indices(k, a, b)
    ar = np.arange(k)
    keep = np.ones((k, 2), bool)
    steps = max(int(iterations), 1)
    M = np.zeros(9 * k * k)
    done = 0
    uu = np.concatenate([u, um])                  # both views' pixels, stacked: (2k, 2)
    c2 = 2.0 * distance * n
    while True:
        p, Jv = _projection(K, np.concatenate([X, X @ H.T + c2]))           # (2k, ...)
        Jv[k:] = Jv[k:] @ H
        r = (p - uu) / sigma_px
        rn = np.sqrt((r * r).sum(1))
        w = _huber_weight(rn) * keep.T.ravel()
        Jv = Jv / sigma_px
        JJ = w[:, None, None] * np.einsum("kri,krj->kij", Jv, Jv)
        Jr = w[:, None] * np.einsum("kri,kr->ki", Jv, r)
        M[:] = 0.0
        M[diag] = JJ[:k] + JJ[k:]
        g = Jr[:k] + Jr[k:]
        if len(L):
            diff = X[a] - X[b]
            length = np.sqrt((diff * diff).sum(1))
            e = diff / np.maximum(length, 1e-12)[:, None] / sigma_len    # d r / d X_a
            rb = (length - L) / sigma_len
            outer = e[:, :, None] * e[:, None, :]
            M += np.bincount(bidx, (bsign * outer[None]).ravel(), minlength=M.size)
            er = (e * rb[:, None]).ravel()
            g += (np.bincount(ga, er, minlength=3 * k)
                  - np.bincount(gb, er, minlength=3 * k)).reshape(k, 3)
        A = M.reshape(3 * k, 3 * k)
        if done >= steps:
            if gate_px is None or not held.any():
                break
            px = sigma_px * rn.reshape(2, k).T
            drop = keep & (px > gate_px) & held[:, None]
            drop[drop.all(1)] = False            # a joint keeps one view at least
            if not drop.any():
                break
            keep &= ~drop
            gate_px, steps = None, steps + 1     # one more step without them, then stop
        try:
            step = np.linalg.solve(A, -g.reshape(-1))
        except np.linalg.LinAlgError:
            break
        X = X + step.reshape(k, 3)
        done += 1
    try:
        inv = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        inv = np.full_like(A, np.nan)
    cov = inv.reshape(k, 3, k, 3)[ar, :, ar, :]
    if full:
        return X, cov, A.copy(), keep
    return X, cov
