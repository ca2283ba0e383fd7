"""Linear triangulation of joints seen by any number of real and virtual cameras.

A view is a ``(3, 4)`` projection matrix from the world frame to pixels. For a
real camera with pose ``(R_c, c_c)`` (camera-to-world) it is
``K [R_c^T | -R_c^T c_c]``; for the same camera looking through a mirror
``n . X = d`` it is that matrix times the reflection ``S = [[H, 2 d n], [0, 1]]``,
``H = I - 2 n n^T``: the camera sees ``X`` where it would see ``S(X)``.

The direct linear transform (Hartley and Zisserman, *Multiple View Geometry*,
2nd ed., sec. 12.2) stacks two rows per view, ``u P_3 - P_1`` and
``v P_3 - P_2``, each scaled to unit norm, and takes the right singular vector of
the smallest singular value; all points are solved in one batched SVD.
"""

from __future__ import annotations

import numpy as np

from ..geometry import householder

__all__ = ["camera_projection", "mirror_projection", "triangulate_views"]


def camera_projection(K: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``(3, 4)`` world-to-pixel matrix of a camera with ``(4, 4)`` camera-to-world ``pose``."""
    pose = np.asarray(pose, dtype=float)
    R, c = pose[:3, :3], pose[:3, 3]
    return np.asarray(K, dtype=float) @ np.hstack([R.T, (-R.T @ c)[:, None]])


def mirror_projection(K: np.ndarray, pose: np.ndarray, normal: np.ndarray, distance: float
                      ) -> np.ndarray:
    """``(3, 4)``: the camera of ``pose`` looking through the mirror ``n . X = d`` (world frame)."""
    n = np.asarray(normal, dtype=float).reshape(3)
    S = np.eye(4)
    S[:3, :3] = householder(n)
    S[:3, 3] = 2.0 * float(distance) * n
    return camera_projection(K, pose) @ S


def triangulate_views(projections: list[np.ndarray], pixels: list[np.ndarray],
                      masks: list[np.ndarray], min_views: int = 2
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate every point seen in at least ``min_views`` views.

    Args:
        projections: ``V`` matrices ``(3, 4)``.
        pixels: ``V`` arrays ``(..., 2)`` (same leading shape ``S``), undistorted pixels.
        masks: ``V`` bool arrays of shape ``S``: the view observes the point.
        min_views: fewest views a point needs.

    Returns:
        ``(S + (3,))`` world points (NaN where not triangulated) and the ``S`` bool
        mask of the triangulated ones.
    """
    shape = np.asarray(masks[0]).shape
    uv = np.stack([np.asarray(p, dtype=float).reshape(-1, 2) for p in pixels])     # (V, N, 2)
    m = np.stack([np.asarray(k, dtype=bool).reshape(-1) for k in masks])          # (V, N)
    m &= np.isfinite(uv).all(-1)
    ok = m.sum(0) >= min_views
    out = np.full((m.shape[1], 3), np.nan)
    if ok.any():
        P = np.stack([np.asarray(p, dtype=float) for p in projections])           # (V, 3, 4)
        u = np.nan_to_num(uv[:, ok])                                              # (V, M, 2)
        rows_x = u[..., 0:1] * P[:, None, 2] - P[:, None, 0]                      # (V, M, 4)
        rows_y = u[..., 1:2] * P[:, None, 2] - P[:, None, 1]
        A = np.concatenate([rows_x, rows_y], axis=0)                              # (2V, M, 4)
        A = A / np.maximum(np.linalg.norm(A, axis=-1, keepdims=True), 1e-300)
        w = np.concatenate([m[:, ok], m[:, ok]], axis=0)[..., None]
        A = np.where(w, A, 0.0).transpose(1, 0, 2)                                # (M, 2V, 4)
        _, _, Vt = np.linalg.svd(A)
        Xh = Vt[:, -1]
        with np.errstate(divide="ignore", invalid="ignore"):
            X = Xh[:, :3] / Xh[:, 3:4]
        good = np.isfinite(X).all(1) & (np.abs(Xh[:, 3]) > 1e-12)
        idx = np.flatnonzero(ok)
        out[idx[good]] = X[good]
        ok[idx[~good]] = False
    return out.reshape(shape + (3,)), ok.reshape(shape)
