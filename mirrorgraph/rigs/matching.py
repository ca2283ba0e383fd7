"""The same person in every camera: matching detections across cameras by epipolar consistency.

A camera that sees no mirror cannot tell its subject from a bystander by the
mirror geometry; taking the most confident detection may pick different people
in different cameras. For such a camera:

1. its detections are linked into tracks frame to frame (Hungarian assignment on
   the mean joint distance, :func:`track_people`);
2. each long enough track is tested against the reference camera's person: an
   essential matrix by MAGSAC++, refined robustly
   (:func:`mirrorgraph.rigs.relative.refine_relative_pose`); the track whose
   joints fit it best (largest fraction under the threshold) is the subject.
   Pooling every candidate pair instead fails: with two people half the pairs
   are wrong, and the person's small extent in the image leaves the minimal
   samples' essential matrices degrees off (bas-relief ambiguity), so the
   wrong pairs win;
3. with that track's geometry every frame's candidates are scored by their
   median Sampson distance (Hartley and Zisserman, *Multiple View Geometry*, 2nd
   ed., sec. 11.4.3) to the reference person, and the best under
   :data:`MATCH_THRESHOLD_PX` is kept (track switches are repaired here). The reference is the first camera; with mirrors its
person is the detection that pairs with a reflection, which a bystander without
one cannot be.
"""

from __future__ import annotations

import warnings

import cv2
import numpy as np

from ..skeletons import Skeleton
from .relative import _normalised, _skew, refine_relative_pose, sampson_px

__all__ = ["match_people", "track_people", "MATCH_THRESHOLD_PX"]

#: Median Sampson distance (px) above which no candidate of a frame is accepted.
MATCH_THRESHOLD_PX = 12.0

#: Tracks: a detection farther than this (mean joint distance, px) from every
#: track's last position starts a new track.
TRACK_GATE_PX = 150.0


def track_people(candidates: list[np.ndarray], joints: np.ndarray, min_confidence: float
                 ) -> list[np.ndarray]:
    """Link detections into tracks frame to frame.

    Args:
        candidates: ``T`` arrays ``(P_t, J, 3)``.
        joints: joints compared.

    Returns:
        ``T`` int arrays ``(P_t,)``: the track id of each detection.
    """
    from scipy.optimize import linear_sum_assignment

    last: dict[int, np.ndarray] = {}
    ids, next_id = [], 0
    for people in candidates:
        p = np.asarray(people, dtype=float)
        lab = np.full(len(p), -1)
        if len(p):
            xy = np.where((p[:, joints, 2:3] >= min_confidence), p[:, joints, :2], np.nan)
            keys = list(last)
            if keys:
                prev = np.stack([last[k] for k in keys])                       # (K, j, 2)
                with warnings.catch_warnings():          # all-NaN rows: no joint in common
                    warnings.simplefilter("ignore", RuntimeWarning)
                    dist = np.nanmean(np.linalg.norm(xy[:, None] - prev[None], axis=-1), -1)
                dist = np.where(np.isfinite(dist), dist, 1e9)
                r, c = linear_sum_assignment(dist)
                for i, k in zip(r, c):
                    if dist[i, k] < TRACK_GATE_PX:
                        lab[i] = keys[k]
            for i in np.flatnonzero(lab < 0):
                lab[i] = next_id
                next_id += 1
            for i, k in enumerate(lab):
                seen = np.isfinite(xy[i]).all(-1)
                prev_xy = last.get(int(k), np.full(xy[i].shape, np.nan))
                last[int(k)] = np.where(seen[:, None], xy[i], prev_xy)
        ids.append(lab)
    return ids


def match_people(ref_person: np.ndarray, K_ref: np.ndarray, candidates: list[np.ndarray],
                 K: np.ndarray, skeleton: Skeleton, *, min_confidence: float = 0.3,
                 seed: int = 0) -> tuple[np.ndarray, int]:
    """Choose, per frame, the candidate detection that is the reference camera's person.

    Args:
        ref_person: ``(T, J, 3)`` the person in the reference camera (undistorted px).
        K_ref, K: ``(3, 3)`` intrinsics of the reference and of this camera.
        candidates: ``T`` arrays ``(P_t, J, 3)``: this camera's detections per frame.
        skeleton: the layout (its calibration joints are compared).
        min_confidence: joints below it are ignored.
        seed: OpenCV's RANSAC seed.

    Returns:
        ``(T, J, 3)`` the chosen person (NaN / confidence 0 where none fits), and the
        number of frames where the choice differs from the most confident detection.
        Frames are returned as the most confident detection when the epipolar
        geometry cannot be estimated (too few frames with a person in both).
    """
    T, J = ref_person.shape[:2]
    joints = skeleton.calibration_joints
    out = np.full((T, J, 3), np.nan)
    out[..., 2] = 0.0
    best_conf = np.full(T, -1)
    rows, cands, refs = [], [], []
    for t, people in enumerate(candidates):
        p = np.asarray(people, dtype=float).reshape(-1, J, 3)
        if len(p) == 0:
            continue
        best_conf[t] = int(np.argmax(np.nan_to_num(p[:, joints, 2]).sum(1)))
        out[t] = p[best_conf[t]]
        for i in range(len(p)):
            rows.append((t, i))
            cands.append(p[i])
            refs.append(ref_person[t])
    if not rows:
        return out, 0
    rows = np.asarray(rows)
    A = np.asarray(refs)[:, joints]                                   # (M, k, 3)
    B = np.asarray(cands)[:, joints]
    seen = (A[..., 2] >= min_confidence) & (B[..., 2] >= min_confidence) \
        & np.isfinite(A[..., :2]).all(-1) & np.isfinite(B[..., :2]).all(-1)
    if np.count_nonzero(seen) < 30:
        return out, 0
    f = 0.5 * (K_ref[0, 0] + K[0, 0])
    xa_all = np.full(A.shape[:-1] + (2,), np.nan)
    xb_all = np.full(B.shape[:-1] + (2,), np.nan)
    xa_all[seen] = _normalised(np.asarray(K_ref, float), A[..., :2][seen])
    xb_all[seen] = _normalised(np.asarray(K, float), B[..., :2][seen])
    track = np.concatenate(track_people(candidates, joints, min_confidence))
    best_E, best_fit = None, -1.0
    for k in np.unique(track):
        sel = (track == k)[:, None] & seen
        if np.count_nonzero(sel) < 30:
            continue
        xa, xb = xa_all[sel], xb_all[sel]
        cv2.setRNGSeed(int(seed))
        E, _ = cv2.findEssentialMat(xa, xb, np.eye(3), method=cv2.USAC_MAGSAC, prob=0.9999,
                                    threshold=8.0 / f, maxIters=5000)
        if E is None or E.shape[0] < 3:
            continue
        _, R, t, _ = cv2.recoverPose(E[:3], xa, xb, np.eye(3))
        R, t = refine_relative_pose(xa, xb, R, np.asarray(t, float).ravel(), f, 4.0)
        E = _skew(t) @ R
        fit = float(np.mean(np.abs(sampson_px(E, xa, xb, f)) < 8.0)) * np.sqrt(len(xa))
        if fit > best_fit:
            best_E, best_fit = E, fit
    if best_E is None:
        return out, 0
    d = np.full(seen.shape, np.nan)
    d[seen] = np.abs(sampson_px(best_E, xa_all[seen], xb_all[seen], f))
    enough = np.count_nonzero(seen, axis=1) >= 4
    score = np.full(len(rows), np.inf)
    score[enough] = np.nanmedian(d[enough], axis=1)
    changed = 0
    order = np.lexsort((score, rows[:, 0]))
    first = np.ones(len(order), bool)
    first[1:] = rows[order][1:, 0] != rows[order][:-1, 0]
    for k in order[first]:
        t, i = rows[k]
        if not np.isfinite(score[k]) or score[k] > MATCH_THRESHOLD_PX:
            if len(candidates[t]) > 1:          # nobody fits: do not guess among several
                out[t] = np.nan
                out[t, :, 2] = 0.0
            continue
        if i != best_conf[t]:
            changed += 1
        out[t] = np.asarray(candidates[t], float).reshape(-1, J, 3)[i]
    return out, changed
