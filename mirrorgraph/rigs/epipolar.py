"""A track's epipolar geometry with the reference camera's person, and how well it fits.

The consistency test of :func:`mirrorgraph.rigs.matching.match_candidates` (step 2 of its
module docstring): an essential matrix by MAGSAC++ refined robustly
(:func:`track_geometry`), with the track's detections in the labelling continuity gives
them (:func:`labelled_geometry`, one answer a group of frames: :func:`group_bits`); the
candidates' median Sampson distance under it (:func:`row_medians`); the inlier threshold
scaled with the person's size (:func:`inlier_threshold_px`).
"""

from __future__ import annotations

import cv2
import numpy as np

from ..geometry import skew
from ..initial.relative import refine_relative_pose, sampson_px

__all__ = ["TRACK_INLIER_OF_SIZE", "TRACK_INLIER_PX", "group_bits", "inlier_threshold_px",
           "labelled_geometry", "row_medians", "track_geometry"]

#: A track's joint pairs within this Sampson distance (px) of its epipolar geometry
#: are inliers (MAGSAC's threshold too), at least; for a person larger in the image
#: than :data:`TRACK_INLIER_PX` / :data:`TRACK_INLIER_OF_SIZE` px, that fraction of
#: their size (:func:`inlier_threshold_px`).
TRACK_INLIER_PX = 8.0

#: A detector's keypoint error grows with the person's size in the image (which is why
#: OKS and PCK normalise by it): the inlier threshold is at least this fraction of the
#: reference person's size (the median over the frames of the larger side of the box
#: of their joints). BlazePose on Pose2Sim's Demo_MultiPerson (the subject 600-700 px
#: tall in 1080 x 1920 video; the Qualisys cameras reproject its joints at a median
#: 10-15 px): at 8 px the subject's track fits 47 % in cam02 and the camera is
#: refused, at 12 px 71 % (the other person's tracks 32 %); 1.5 % of the size (~10 px)
#: calibrates every camera. Synthetic rigs (4 px noise, people 500-650 px): 8-9.5 px,
#: where a camera seeing only another person's walk is still refused (at 2 %, 10-12
#: px, it is not).
TRACK_INLIER_OF_SIZE = 0.015


def inlier_threshold_px(person: np.ndarray, joints: np.ndarray, min_confidence: float) -> float:
    """The inlier threshold (px) of
    :func:`~mirrorgraph.rigs.matching.match_candidates` for a reference person
    ``(T, J, 3)``: :data:`TRACK_INLIER_PX`, or :data:`TRACK_INLIER_OF_SIZE` of the
    person's size if larger (the median over frames of the larger side of the box of
    their confident ``joints``)."""
    xy = np.where(person[:, joints, 2:3] >= min_confidence, person[:, joints, :2], np.nan)
    ok = np.count_nonzero(np.isfinite(xy).all(-1), axis=1) >= 2
    if not ok.any():
        return TRACK_INLIER_PX
    side = np.nanmax(np.nanmax(xy[ok], axis=1) - np.nanmin(xy[ok], axis=1), axis=1)
    return float(max(TRACK_INLIER_PX, TRACK_INLIER_OF_SIZE * np.median(side)))


def track_geometry(xa: np.ndarray, xb: np.ndarray, f: float, seed: int,
                    inlier_px: float = TRACK_INLIER_PX) -> tuple[np.ndarray | None, float]:
    """Essential matrix of one track's correspondences with the reference person and
    the fraction of them within ``inlier_px`` of it (``None, 0`` if none)."""
    cv2.setRNGSeed(int(seed))
    E, _ = cv2.findEssentialMat(xa, xb, np.eye(3), method=cv2.USAC_MAGSAC, prob=0.9999,
                                threshold=inlier_px / f, maxIters=5000)
    if E is None or E.shape[0] < 3:
        return None, 0.0
    _, R, t, _ = cv2.recoverPose(E[:3], xa, xb, np.eye(3))
    R, t = refine_relative_pose(xa, xb, R, np.asarray(t, float).ravel(), f, 4.0)
    E = skew(t) @ R
    return E, float(np.mean(np.abs(sampson_px(E, xa, xb, f)) < inlier_px))


def row_medians(E: np.ndarray, xa: np.ndarray, xb: np.ndarray, seen: np.ndarray, f: float
                 ) -> np.ndarray:
    """``(M,)`` median absolute Sampson distance (px) of each candidate's joints ``(M, k, 2)``
    (normalised) under ``E``; ``inf`` where fewer than 4 joints are ``seen`` ``(M, k)``."""
    d = np.full(seen.shape, np.nan)
    d[seen] = np.abs(sampson_px(E, xa[seen], xb[seen], f))
    out = np.full(len(seen), np.inf)
    enough = np.count_nonzero(seen, axis=1) >= 4
    out[enough] = np.nanmedian(d[enough], axis=1)
    return out


def group_bits(E: np.ndarray, xa: np.ndarray, xb: np.ndarray, seen: np.ndarray,
                rel: np.ndarray, group: np.ndarray, f: float,
                inlier_px: float = TRACK_INLIER_PX) -> np.ndarray:
    """Per group, whether its detections fit ``E`` better with their relative labelling
    ``rel`` inverted: the labelling under which more of the group's joints lie within
    :data:`TRACK_INLIER_PX` (one decision a group, never frame by frame).

    Args:
        E: essential matrix; xa ``(M, k, 2)``, xb ``(2, M, k, 2)`` (as labelled, swapped),
            seen ``(2, M, k)``: as :func:`labelled_geometry`.
        rel: ``(M,)`` bool, group: ``(M,)`` int ids ``0 .. G-1``.

    Returns:
        ``(G,)`` bool.
    """
    counts = np.zeros((2, group.max() + 1 if len(group) else 0))
    for b in (0, 1):
        lab = (rel ^ bool(b)).astype(int)
        rows = np.arange(len(rel))
        ok = seen[lab, rows]
        d = np.full(ok.shape, np.inf)
        d[ok] = np.abs(sampson_px(E, xa[ok], xb[lab, rows][ok], f))
        np.add.at(counts[b], group, np.count_nonzero(d < inlier_px, axis=1))
    return counts[1] > counts[0]


def labelled_geometry(xa: np.ndarray, xb: np.ndarray, seen: np.ndarray, rel: np.ndarray,
                       group: np.ndarray, f: float, seed: int,
                       inlier_px: float = TRACK_INLIER_PX
                       ) -> tuple[np.ndarray | None, float, np.ndarray]:
    """One track's epipolar geometry with the reference person, its detections taken in
    the labelling continuity gives them.

    A detector swaps a turning person's left and right labels in one camera and not
    in another, frame by frame; a swapped frame's limbs are outliers to the true
    geometry. Tracking reads every swap against the track's own labelling (and the
    reference person's against theirs,
    :func:`~mirrorgraph.rigs.tracking.track_labelled`), which leaves one
    unknown a group of frames (a track against one stretch of the reference person's
    track): whether the two labellings agree. Both answers are tried, the geometry
    estimated on each and every group's answer decided by the geometry; the one with
    more inliers is kept. Frame by frame choices are not made: they let a wrong
    geometry (a camera mirrored through the subject's plane of symmetry, which fits
    a person's symmetric joints) pick the labelling that suits it in every frame.

    Args:
        xa: ``(M, k, 2)`` the reference person's joints, normalised coordinates.
        xb: ``(2, M, k, 2)`` the track's detections as labelled and with the labels
            swapped, normalised.
        seen: ``(2, M, k)`` joints seen in both cameras, per labelling.
        rel: ``(M,)`` bool: the detection's labels swapped relative to the reference
            person's, up to its group's answer.
        group: ``(M,)`` int ids ``0 .. G-1`` of the groups.
        f: focal length (px) for the units; seed: OpenCV's RANSAC seed;
        inlier_px: the inlier threshold (px).

    Returns:
        the essential matrix (``None``: none found), the fraction of the chosen
        correspondences within ``inlier_px`` of it, and ``(G,)`` bool: the
        group's answer (invert ``rel``).
    """
    rows = np.arange(len(rel))
    best: tuple[np.ndarray | None, float, np.ndarray] = (None, 0.0, np.zeros(0, bool))
    for start in (False, True):
        lab = (rel ^ start).astype(int)
        use = seen[lab, rows]
        E0, frac0 = track_geometry(xa[use], xb[lab, rows][use], f, seed, inlier_px)
        if E0 is None:
            continue
        bits = group_bits(E0, xa, xb, seen, rel, group, f, inlier_px)
        E, frac = E0, frac0
        if np.any(bits != start):               # another answer for some group: again
            lab = (rel ^ bits[group]).astype(int)
            use = seen[lab, rows]
            E, frac = track_geometry(xa[use], xb[lab, rows][use], f, seed, inlier_px)
        if E is not None and frac > best[1]:
            best = (E, frac, bits)
    return best
