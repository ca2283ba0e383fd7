"""The detector's left/right confusions of the person, in both views at once, undone by the
motion's continuity.

A detector that mistakes which way a person faces labels their left limbs "right" in that
frame, in the direct view and, as it sees the reflection the same way, in the mirror too.
Such a pair is epipolar-consistent (both views image the same physical joint), so neither
the pairing (:mod:`.left_right` fixes the reflection *against* the person) nor the robust
kernels can see it: it triangulates the person's right wrist where the left one should be,
and a smoothness prior then drags the neighbouring frames towards it.

:func:`undo_body_swaps` decides, for each left/right pair of joints (shoulders, wrists,
knees, eyes, ...) on its own, which frames the detector swapped, with a two-state hidden
Markov chain over time decoded by the Viterbi algorithm (Rabiner 1989, sec. III-B): the
state is "labels as given" or "labels swapped", the emission of a transition between
two consecutive frames is the motion of the labelled keypoints in both views under the
state pair, a robust (truncated) squared distance in units of that joint's typical
frame-to-frame motion, and a swap event and a swapped frame each cost a constant, so that
the labels as given are the default and a swap needs evidence. Frames further apart than
``max_gap`` are unrelated (snapshots, cuts): the chain restarts there.

Frames: ``paired.real`` and ``paired.mirror`` in pixels, the reflection's labels already in
the person's (:class:`~mirrorgraph.keypoints.PairedKeypoints`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..keypoints import PairedKeypoints

__all__ = ["BodySwapOptions", "undo_body_swaps", "swap_states"]


@dataclass(frozen=True)
class BodySwapOptions:
    """The chain's costs (negative log-probabilities) and limits.

    Attributes:
        switch_cost: a change of state between two consecutive frames (a detector's
            swap starting or ending): ``-log`` of its prior probability per frame
            (``4.6``: 1 %).
        swapped_cost: each frame in the swapped state (the detector labels most
            frames as they are).
        truncation: a keypoint's motion counts up to this many of its typical motions
            (squared): a single outlier among the keypoints weighs no more than this.
        max_gap: frames further apart are unrelated; the chain restarts.
        min_scale_px: floor of a joint's typical motion (the detector's noise).
    """

    switch_cost: float = 4.6
    swapped_cost: float = 1.0
    truncation: float = 4.0
    max_gap: int = 5
    min_scale_px: float = 2.0


def _pairs(flip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(P,)`` left and ``(P,)`` right joint indices of the skeleton's left/right pairs."""
    left = np.flatnonzero(flip > np.arange(len(flip)))
    return left, flip[left]


def _points(paired: PairedKeypoints, min_confidence: float, left: np.ndarray,
            right: np.ndarray) -> np.ndarray:
    """``(T, P, 4, 2)``: per pair the real left, real right, mirror left, mirror right
    keypoints, NaN where unseen."""
    out = []
    for view in (paired.real, paired.mirror):
        v = np.array(view[..., :2], dtype=float)
        low = ~(view[..., 2] > min_confidence) | ~np.isfinite(v).all(-1)
        v[low] = np.nan
        out += [v[:, left], v[:, right]]
    return np.stack(out, axis=2)


def _motion_scale(pts: np.ndarray, step: np.ndarray, floor: float) -> np.ndarray:
    """``(P, 4)`` each keypoint's typical motion between consecutive frames (px): the
    median of its displacements over frames one apart, at least ``floor``."""
    d = np.linalg.norm(pts[1:] - pts[:-1], axis=-1)[step[1:] == 1]
    with np.errstate(all="ignore"):
        med = np.nanmedian(d, axis=0) if len(d) else np.full(pts.shape[1:3], np.nan)
    return np.where(np.isfinite(med), np.maximum(med, floor), floor)


def swap_states(paired: PairedKeypoints, min_confidence: float = 0.0,
                options: BodySwapOptions | None = None) -> np.ndarray:
    """``(T, P)`` bool: the frames where the detector swapped pair ``p``'s labels in both
    views (the Viterbi path of the module docstring's chain); pairs in the order of
    ``np.flatnonzero(flip > arange)`` (the left joint of each pair)."""
    opts = options or BodySwapOptions()
    left, right = _pairs(np.asarray(paired.skeleton.flip))
    T, P = len(paired), len(left)
    if T == 0 or P == 0:
        return np.zeros((T, P), bool)
    pts = _points(paired, min_confidence, left, right)              # (T, P, 4, 2)
    frames = np.asarray(paired.frame_ids, dtype=np.int64)
    step = np.diff(frames, prepend=frames[0] - 1)
    scale = _motion_scale(pts, step, opts.min_scale_px)             # (P, 4)
    crossed = pts[:, :, [1, 0, 3, 2]]                               # labels swapped
    seen = np.isfinite(pts).all(-1).any(-1)                         # (T, P)
    cap = opts.truncation ** 2
    unary = np.array([0.0, opts.swapped_cost])
    cost = np.zeros((P, 2))
    back = np.zeros((T, P, 2), dtype=np.int8)
    last = np.full((P, 4, 2), np.nan)
    last_frame = np.full(P, -(10 ** 12), dtype=np.int64)
    started = np.zeros(P, bool)
    ar = np.arange(P)
    for t in range(T):
        obs = seen[t]
        gap = frames[t] - last_frame
        fresh = obs & (~started | (gap > opts.max_gap))
        s = (scale * np.maximum(gap, 1)[:, None])[..., None]
        with np.errstate(invalid="ignore"):
            same = np.minimum(np.sum(((pts[t] - last) / s) ** 2, axis=-1), cap)
            cross = np.minimum(np.sum(((crossed[t] - last) / s) ** 2, axis=-1), cap)
        same = np.nansum(same, axis=-1)                             # (P,)
        cross = np.nansum(cross, axis=-1)
        # trans[p, prev, cur]: the motion under (prev, cur) plus the switch's cost
        trans = np.stack([np.stack([same, cross + opts.switch_cost], -1),
                          np.stack([cross + opts.switch_cost, same], -1)], 1)
        total = cost[:, :, None] + trans                            # (P, prev, cur)
        best_prev = np.argmin(total, axis=1)                        # (P, cur)
        chained = total[ar[:, None], best_prev, np.arange(2)[None, :]]
        restart = cost.min(1)[:, None] + np.zeros((1, 2))
        restart_prev = np.repeat(np.argmin(cost, 1)[:, None], 2, 1)
        new_cost = np.where(fresh[:, None], restart, chained) + unary
        new_back = np.where(fresh[:, None], restart_prev, best_prev)
        # frames where the pair is unseen carry the state on unchanged
        cost = np.where(obs[:, None], new_cost, cost)
        back[t] = np.where(obs[:, None], new_back, np.arange(2)[None, :])
        last = np.where(obs[:, None, None], np.where(np.isfinite(pts[t]), pts[t], last), last)
        last_frame = np.where(obs, frames[t], last_frame)
        started |= obs
    state = np.zeros((T, P), dtype=np.int8)
    cur = np.argmin(cost, axis=1).astype(np.int8)
    for t in range(T - 1, -1, -1):
        state[t] = cur
        cur = back[t, ar, cur]
    return state.astype(bool) & seen


def undo_body_swaps(paired: PairedKeypoints, min_confidence: float = 0.0,
                    options: BodySwapOptions | None = None) -> tuple[PairedKeypoints, int]:
    """Swap back the left/right labels the detector confused in both views.

    Args:
        paired: person and reflection, paired (the reflection's labels in the person's).
        min_confidence: keypoints below it are unseen.
        options: :class:`BodySwapOptions`.

    Returns:
        The keypoints with the swapped pairs' labels exchanged in both views, and how
        many (frame, pair) entries were swapped back.
    """
    swapped = swap_states(paired, min_confidence, options)
    n = int(np.count_nonzero(swapped))
    if n == 0:
        return paired, 0
    left, right = _pairs(np.asarray(paired.skeleton.flip))
    views = []
    for view in (paired.real, paired.mirror):
        v = np.array(view, copy=True)
        t, p = np.nonzero(swapped)
        v[t, left[p]], v[t, right[p]] = view[t, right[p]], view[t, left[p]]
        views.append(v)
    return replace(paired, real=views[0], mirror=views[1]), n
