"""The noise model: the a posteriori pixel sigma that the solved rig's residuals show.

Every used joint is triangulated again from its kept views with the solved rig (the
maximum-likelihood point of the reprojection alone, free of the body priors that pull
the graph's joints off it), and ``sigma^2 = RSS / (2 observations - 3 joints - globals)``
(:func:`residual_noise`; for one mirror this is the pairs' Sampson distances to first
order; the residual of a maximum-likelihood estimate, Hartley and Zisserman,
*Multiple View Geometry*, 2nd ed., ch. 5). The marginal covariances are scaled by
``(sigma / pixel_sigma)^2`` (:mod:`.marginals`). Pixels throughout.
"""

from __future__ import annotations

import numpy as np

from .result import residual_noise_px
from .rig import Rig, triangulate_rig, view_residuals, with_views

__all__ = ["reprojection_noise_px", "residual_noise", "NOISE_BLOCK_FRAMES"]


def reprojection_noise_px(rig: Rig, masks: list[np.ndarray], poses, planes,
                          global_unknowns: int) -> float:
    """A posteriori pixel sigma of a whole video: :func:`residual_noise` of every joint of
    ``masks`` triangulated from its views with the solved rig, in blocks of
    :data:`NOISE_BLOCK_FRAMES` frames, so that a long video's temporaries stay small."""
    rss, n_obs, n_points = 0.0, 0, 0
    for a in range(0, rig.num_frames, NOISE_BLOCK_FRAMES):
        rows = slice(a, a + NOISE_BLOCK_FRAMES)
        block = rig.subset(rows)
        bm = [np.asarray(m, bool)[rows] for m in masks]
        X, ok = triangulate_rig(block, bm, poses, planes)
        parts = _residual_sums(block, bm, X, ok, poses, planes)
        rss, n_obs, n_points = rss + parts[0], n_obs + parts[1], n_points + parts[2]
    return residual_noise_px(rss, 2 * n_obs, 3 * n_points + global_unknowns)


def residual_noise(rig: Rig, masks: list[np.ndarray], points: np.ndarray, ok: np.ndarray,
                   poses, planes, global_unknowns: int) -> float:
    """A posteriori pixel sigma from the joints ``points`` ``(T, J, 3)`` (``ok``: ``(T, J)``)
    triangulated from the views of ``masks`` with the solved rig (the maximum-likelihood
    points of the reprojection alone): ``sqrt(RSS / dof)`` with
    ``dof = 2 observations - 3 joints - global_unknowns``
    (:func:`~.result.residual_noise_px`)."""
    rss, n_obs, n_points = _residual_sums(rig, masks, points, ok, poses, planes)
    return residual_noise_px(rss, 2 * n_obs, 3 * n_points + global_unknowns)


def _residual_sums(rig: Rig, masks, points, ok, poses, planes) -> tuple[float, int, int]:
    """Sum of squared residuals, observations and joints of triangulated ``points``."""
    res = view_residuals(with_views(rig, [np.asarray(m, bool) & ok for m in masks]), points,
                         ok, planes, poses)
    r = np.concatenate([v[np.isfinite(v)] for v in res])
    return float(np.sum(r ** 2)), len(r), int(np.count_nonzero(ok))


#: Frames a block of :func:`reprojection_noise_px` holds.
NOISE_BLOCK_FRAMES = 2000
