"""The geometry of the drawing: reflected points, a mirror's drawn extent, clipped lines."""

from __future__ import annotations

import numpy as np

from .scene import ViewMirror

__all__ = ["clip_lines", "mirror_quad", "reflect"]


def reflect(X: np.ndarray, normal: np.ndarray, distance: float) -> np.ndarray:
    """``(..., 3)`` points reflected across ``n . X = d``: ``X - 2 (n . X - d) n``."""
    n = np.asarray(normal, float)
    return X - 2.0 * ((X @ n) - distance)[..., None] * n


def mirror_quad(mirror: ViewMirror, points: np.ndarray | None) -> np.ndarray:
    """``(4, 3)`` corners of the drawn part of a mirror (see :mod:`mirrorgraph.viewer.recording`).

    ``points`` ``(N, 3)`` joints: the reflections of them seen from each camera of
    :attr:`ViewMirror.seen_from` cross the plane where the mirror must be.
    """
    n, d = np.asarray(mirror.normal, float), float(mirror.distance)
    a = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    centre_default = d * n
    hits = []
    if points is not None and len(points):
        R = reflect(points, n, d)
        for c in mirror.seen_from or [np.zeros(3)]:
            ray = R - c
            denom = ray @ n
            s = (d - c @ n) / np.where(np.abs(denom) > 1e-12, denom, np.nan)
            p = c + s[:, None] * ray
            hits.append(p[np.isfinite(p).all(-1) & (s > 0) & (s < 1)])
    hits = np.concatenate(hits) if hits else np.zeros((0, 3))
    if len(hits) >= 3:
        u, v = (hits - d * n) @ a, (hits - d * n) @ b
        lo_u, hi_u, lo_v, hi_v = u.min(), u.max(), v.min(), v.max()
        pad_u, pad_v = 0.1 * (hi_u - lo_u) + 1e-6, 0.1 * (hi_v - lo_v) + 1e-6
        lo_u, hi_u, lo_v, hi_v = lo_u - pad_u, hi_u + pad_u, lo_v - pad_v, hi_v + pad_v
        origin = d * n
    else:
        lo_u, hi_u, lo_v, hi_v = -1.0, 1.0, -1.0, 1.0
        origin = centre_default
    return np.array([origin + u * a + v * b for u, v in ((lo_u, lo_v), (hi_u, lo_v),
                                                          (hi_u, hi_v), (lo_u, hi_v))])


def clip_lines(lines: np.ndarray, width: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Segments of homogeneous image lines ``(N, 3)`` inside ``[0, W] x [0, H]``.

    Returns ``(N, 2, 2)`` end points and ``(N,)`` bool: the line crosses the image.
    """
    L = np.asarray(lines, float)
    a, b, c = L[:, 0], L[:, 1], L[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        cand = np.stack([
            np.stack([np.zeros_like(a), -c / b], -1),                  # x = 0
            np.stack([np.full_like(a, width), -(c + a * width) / b], -1),   # x = W
            np.stack([-c / a, np.zeros_like(a)], -1),                  # y = 0
            np.stack([-(c + b * height) / a, np.full_like(a, height)], -1),  # y = H
        ], axis=1)                                                     # (N, 4, 2)
    eps = 1e-6 * max(width, height)
    inside = (np.isfinite(cand).all(-1) & (cand[..., 0] >= -eps) & (cand[..., 0] <= width + eps)
              & (cand[..., 1] >= -eps) & (cand[..., 1] <= height + eps))
    # the two inside candidates farthest apart
    big = np.where(inside[..., None], cand, np.nan)
    first = np.nanargmin(np.where(inside, cand[..., 0] + 1e-3 * cand[..., 1], np.inf), axis=1)
    last = np.nanargmax(np.where(inside, cand[..., 0] + 1e-3 * cand[..., 1], -np.inf), axis=1)
    rows = np.arange(len(L))
    seg = np.stack([big[rows, first], big[rows, last]], axis=1)
    ok = inside.sum(1) >= 2
    return seg, ok & np.isfinite(seg).all((-1, -2))

