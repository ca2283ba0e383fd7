"""Outlier rejection between solves: reprojection residuals and bone-length consistency.

Two complementary tests, both on the current estimate:

* :func:`observation_outliers` -- an observation whose reprojection residual
  exceeds a threshold, or whose joint lies behind its camera (:func:`feasible`).
  It cannot see a keypoint displaced *along its epipolar line*: the point simply
  moves in depth and both views fit.
* :func:`bone_outliers` -- those depth errors break the body instead: the
  bones at the joint come out too long or too short. A bone is inconsistent
  in a frame when its length is more than ``k`` robust standard deviations
  (1.4826 MAD over the frames, at least ``min_rel`` of the median) from its
  median; a joint is rejected in that frame when *all* its measured bones are
  inconsistent, keeping, for each inconsistent bone, only the end with more
  inconsistent bones (a displaced elbow spoils the humerus and the ulna; the
  wrist, whose only bone is the ulna, is then spared).

Shapes: ``(T, J, 3)`` points in the world frame, ``(T, J)`` masks.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from typing import TYPE_CHECKING

from ..errors import DegenerateGeometryError
from .options import RefineOptions
from .stage_config import SolveConfig

if TYPE_CHECKING:
    from .rig import Rig

# the rig's geometry (and GTSAM with it) is imported where it is used: the live run's
# per-frame path takes :func:`one_view_outliers` alone, without GTSAM

__all__ = ["feasible", "observation_outliers", "one_view_outliers", "bone_outliers",
           "clean_views", "check_held", "MIN_HELD_OBSERVATIONS"]


def feasible(rig: Rig, points: np.ndarray, masks: list[np.ndarray], poses, planes
             ) -> list[np.ndarray]:
    """Per view ``(T, J)`` bool: the observed joint is in front of the view's (real or
    virtual) camera and, through a mirror, in front of that mirror (cheirality);
    ``True`` where the view does not observe it."""
    from .rig import view_projections

    out = []
    X = np.nan_to_num(points)
    for v, P, m in zip(rig.views, view_projections(rig, poses, planes), masks):
        with np.errstate(invalid="ignore"):
            ok = X @ P[2, :3] + P[2, 3] > 0          # the depth: K's third row is e3
            if v.mirror is not None:
                n, d = planes[rig.mirror_index(v.mirror)]
                ok &= X @ np.asarray(n, float) < d
        out.append(~np.asarray(m, bool) | (ok & np.isfinite(points).all(-1)))
    return out


def observation_outliers(rig: Rig, points: np.ndarray, used: np.ndarray,
                         masks: list[np.ndarray], poses, planes, threshold: float
                         ) -> tuple[list[np.ndarray], int]:
    """View masks without the observations of ``used`` joints whose reprojection residual
    exceeds ``threshold`` px or that lie behind their camera (per observation: a wrong
    keypoint in one view does not cost the others).

    Args:
        rig: views and cameras; points: ``(T, J, 3)``; used: ``(T, J)``;
        masks: per view ``(T, J)`` observations; poses, planes: the rig's geometry.

    Returns:
        The new masks and how many observations were dropped.
    """
    from .rig import view_residuals

    probe = [np.asarray(m, bool) & used for m in masks]
    res = view_residuals(replace(rig, views=tuple(replace(v, mask=m) for v, m
                                                  in zip(rig.views, probe))),
                         points, used, planes, poses)
    ok = feasible(rig, points, probe, poses, planes)
    out, dropped = [], 0
    for m, p, r, good in zip(masks, probe, res, ok):
        bad = p & ((np.nan_to_num(r, nan=0.0) > threshold) | ~good)
        dropped += int(np.count_nonzero(bad))
        out.append(np.asarray(m, bool) & ~bad)
    return out, dropped


def one_view_outliers(residuals: list[np.ndarray], threshold: float) -> list[np.ndarray]:
    """Per view ``(T, J)`` bool: observations whose reprojection residual exceeds
    ``threshold`` px, at most one view of each joint (the worst), so that every joint
    keeps an observation.

    Args:
        residuals: per view ``(T, J)`` residual norms, px, NaN where the view does not
            observe the joint (:func:`~.rig.view_residuals`).
        threshold: px.
    """
    r = np.stack([np.nan_to_num(np.asarray(v, float), nan=-np.inf) for v in residuals])
    worst = np.argmax(r, axis=0)                                  # (T, J)
    over = r.max(0) > threshold
    return [over & (worst == i) for i in range(len(residuals))]


def bone_outliers(points: np.ndarray, used: np.ndarray, bones: np.ndarray, *, k: float = 5.0,
                  min_rel: float = 0.03) -> np.ndarray:
    """``(T, J)`` bool: joints whose every bone in that frame has an implausible length.

    Args:
        points: ``(T, J, 3)`` current 3D joints.
        used: ``(T, J)`` bool, the estimated joints.
        bones: ``(B, 2)`` joint indices of the bones.
        k: threshold in robust standard deviations.
        min_rel: floor of the robust standard deviation, relative to the median length.
    """
    T, J = used.shape
    bones = np.asarray(bones, dtype=int).reshape(-1, 2)
    if len(bones) == 0:
        return np.zeros((T, J), dtype=bool)
    a, b = bones[:, 0], bones[:, 1]
    seen = used[:, a] & used[:, b]                                           # (T, B)
    length = np.where(seen, np.linalg.norm(np.nan_to_num(points[:, a] - points[:, b]), axis=-1),
                      np.nan)
    with warnings.catch_warnings():       # a bone no frame holds: NaN, and no bone flagged
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(np.where(seen, length, np.nan), axis=0)         # (B,)
        mad = np.nanmedian(np.abs(length - med), axis=0) * 1.4826
    scale = np.maximum(np.nan_to_num(mad), min_rel * np.nan_to_num(med))
    bad = seen & (np.abs(length - med) > k * np.maximum(scale, 1e-12))     # (T, B)

    n_bad = np.zeros((T, J), dtype=int)
    n_seen = np.zeros((T, J), dtype=int)
    for col, end in ((a, 0), (b, 1)):
        np.add.at(n_bad, (slice(None), col), bad.astype(int))
        np.add.at(n_seen, (slice(None), col), seen.astype(int))
    cand = (n_bad > 0) & (n_bad == n_seen)
    # of the two ends of an inconsistent bone keep the one with more inconsistent bones
    spare = np.zeros((T, J), dtype=bool)
    for i in range(len(bones)):
        both = bad[:, i] & cand[:, a[i]] & cand[:, b[i]]
        na, nb = n_bad[:, a[i]], n_bad[:, b[i]]
        spare[both & (na > nb), b[i]] = True
        spare[both & (nb > na), a[i]] = True
    return cand & ~spare & used


def clean_views(rig: Rig, masks: list[np.ndarray], poses, planes, opts: RefineOptions,
           config: SolveConfig, min_parallax: float):
    """Triangulate; drop observations behind their camera, joints without parallax and,
    with ``config.first_rejection``, outliers. Returns points, masks, the count dropped
    and the count of outliers found (for the ``"auto"`` kernel)."""
    from .bones import bone_table
    from .rig import parallax_deg, seen_twice, triangulate_rig

    offered = masks
    points, ok = triangulate_rig(rig, masks, poses, planes)
    masks, behind = observation_outliers(rig, points, seen_twice(masks), masks, poses, planes, np.inf)
    if behind:           # again, only the joints that lost an observation
        changed = np.any([a & ~b for a, b in zip(offered, masks)], axis=0)
        again, again_ok = triangulate_rig(rig, [m & changed for m in masks], poses, planes)
        points = np.where(changed[..., None], again, points)
        ok = np.where(changed, again_ok, ok)
    flat = ok & (parallax_deg(rig, points, masks, poses, planes) < min_parallax)
    masks = [m & ~flat for m in masks]
    found = 0
    if config.first_rejection:
        used = seen_twice(masks) & ok
        masks, found = observation_outliers(rig, points, used, masks, poses, planes, opts.outlier_threshold)
        if opts.bone_outlier_k > 0:
            _, pairs = bone_table(rig)
            bad = bone_outliers(points, used & seen_twice(masks), pairs, k=opts.bone_outlier_k)
            found += int(np.count_nonzero(bad))
            masks = [m & ~bad for m in masks]
    return points, masks, behind + int(np.count_nonzero(flat)) + found, found


#: An estimated camera or a mirror needs at least this many keypoints left in its
#: views after outlier rejection (a pose has 6 unknowns, a plane 3).
MIN_HELD_OBSERVATIONS = 30


def check_held(rig: Rig, masks: list[np.ndarray], offered: list[int]) -> None:
    """Raise when an estimated camera or a mirror has (almost) no keypoints left.

    Raises:
        DegenerateGeometryError: naming the camera or mirror, with the counts; for a
            camera whose focal length is estimated, that its start (the initial focal
            length and placement) may be what is too far off, not the user's input.
    """
    kept = np.array([int(np.count_nonzero(m)) for m in masks])
    had = np.asarray(offered)
    groups = [(c, f"camera {c.name}", [i for i, v in enumerate(rig.views)
                                        if v.camera == c.name])
              for c in rig.cameras if c.estimate_pose or c.estimate_focal]
    groups += [(None, f"mirror {m.name}", [i for i, v in enumerate(rig.views)
                                           if v.mirror == m.name])
               for m in rig.mirrors]
    for cam, what, idx in groups:
        if kept[idx].sum() < MIN_HELD_OBSERVATIONS:
            head = (f"{what}: {kept[idx].sum()} of its {had[idx].sum()} keypoints fit the "
                    f"rest of the rig (need {MIN_HELD_OBSERVATIONS})")
            if cam is not None and cam.estimate_focal:
                raise DegenerateGeometryError(
                    f"{head} at its initial focal length {cam.K[0, 0]:.0f} px and placement, "
                    "which the graph starts its estimate from: the start is too far off for "
                    "these views (give this camera's intrinsics), or it sees another person "
                    "or needs a frame offset")
            if len(rig.cameras) == 1:
                raise DegenerateGeometryError(
                    f"{head}: too few of the person's keypoints agree with one reflection "
                    "(a short clip, or a second person taken for the reflection?)")
            raise DegenerateGeometryError(
                f"{head}: is it the same person as in the other cameras? the right "
                "intrinsics, frame offset, mirror?")
