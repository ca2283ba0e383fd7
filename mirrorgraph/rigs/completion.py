"""The joints the graph did not estimate, triangulated with the calibrated rig.

The calibration uses a chosen set of joints per view (by default every keypoint
in the direct views but only the limbs through mirrors, :mod:`.config`). A rig
whose only second view of the face or the feet is a mirror (one camera and its
mirrors) then has no 3D face or feet from the graph, although every view saw
them. Once the cameras and mirrors are known those joints are a linear
triangulation away: every view that observes them, real or through a mirror
(:func:`mirrorgraph.geometry.triangulate`), one round of rejecting observations farther than the
outlier threshold from the first solution, then the final triangulation. They
complete the output's 3D joints and give the stature estimate its eyes
(:mod:`mirrorgraph.stature`); they take no part in the calibration.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .initial import observed
from .observations import RigObservations
from .solve import RigSolution
from ..geometry import camera_projection, mirror_projection, triangulate

__all__ = ["complete_joints"]


def _views(obs: RigObservations, sol: RigSolution
           ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Projection matrices ``(3, 4)`` and keypoints ``(T, J, 3)`` of every real and
    mirror view of the solved rig."""
    planes = dict(zip(sol.mirror_names, sol.planes))
    projections, keypoints = [], []
    for cam, pose in zip(obs.cameras, sol.poses):
        K = cam.intrinsics.K
        projections.append(camera_projection(K, pose))
        keypoints.append(cam.real)
        for m, refl in cam.reflections.items():
            if m in planes:
                projections.append(mirror_projection(K, pose, *planes[m]))
                keypoints.append(refl)
    return projections, keypoints


def _residuals(P: np.ndarray, X: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel distance ``(N,)`` of ``uv`` ``(N, 2)`` to the projection of ``X`` ``(N, 3)``,
    and whether ``X`` is in front of the view."""
    h = np.nan_to_num(X) @ P[:, :3].T + P[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = np.linalg.norm(h[:, :2] / h[:, 2:3] - uv, axis=-1)
    return dist, h[:, 2] > 0


def complete_joints(obs: RigObservations, sol: RigSolution, threshold_px: float
                    ) -> RigSolution:
    """Fill the joints the solution lacks by triangulating them with its rig.

    Args:
        obs: the rig's sorted observations (frames = ``sol``'s frames).
        sol: the solved rig; ``sol.points`` ``(T, J, 3)`` world frame, ``sol.used``
            ``(T, J)``.
        threshold_px: observations farther than this from the first triangulation
            (pixels) are dropped before the second.

    Returns:
        ``sol`` with ``points`` and ``used`` filled where the graph had no joint and
        two views or more (after rejection) observe it; the graph's joints unchanged.
    """
    missing = ~np.asarray(sol.used, bool)                                  # (T, J)
    if not missing.any():
        return sol
    projections, keypoints = _views(obs, sol)
    masks = [observed(k) & missing for k in keypoints]
    pixels = [k[..., :2] for k in keypoints]
    X, ok = triangulate(projections, pixels, masks)
    if not ok.any():
        return sol
    kept = []
    for P, uv, m in zip(projections, pixels, masks):
        dist, ahead = _residuals(P, X[ok], uv[ok])
        keep = m.copy()
        keep[ok] &= (dist <= threshold_px) & ahead
        kept.append(keep)
    X, ok = triangulate(projections, pixels, kept)
    points = np.array(sol.points, dtype=float, copy=True)
    used = np.array(sol.used, dtype=bool, copy=True)
    points[ok] = X[ok]
    used |= ok
    return replace(sol, points=points, used=used)
