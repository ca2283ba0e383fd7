"""The detector's left/right confusions of the person, in either view or both, undone by the
motion's continuity.

A detector that mistakes which way a person faces labels their left limbs "right" in that
frame, in the direct view and, as it sees the reflection the same way, in the mirror too.
Such a pair is epipolar-consistent (both views image the same physical joint), so neither
the pairing (:mod:`.left_right` fixes the reflection *against* the person) nor the robust
kernels can see it: it triangulates the person's right wrist where the left one should be,
and a smoothness prior then drags the neighbouring frames towards it. A confusion in one
view alone is the pairing's to undo, by the epipole, but where the person's left/right
pairs lie along the epipolar lines (a person seen from the side of the mirror) both
labellings fit it alike and the pairing keeps the detector's: a pair of the two different
joints that still reprojects within the noise, its depth off.

:func:`undo_body_swaps` decides, for each left/right pair of joints (shoulders, wrists,
knees, eyes, ...) on its own, which frames the detector swapped in which view, with a
four-state hidden Markov chain over time decoded by the Viterbi algorithm (Rabiner 1989,
sec. III-B): the state is whether the direct view's labels are swapped and whether the
reflection's are, the emission of a transition between two consecutive frames is the
motion of the labelled keypoints in each view under that view's state pair, a robust
(truncated) squared distance in units of that keypoint's typical frame-to-frame motion,
and a swap event (a change of state, one view's or both's) and each swapped view of a frame
cost a constant, so that the labels as given are the default and a swap needs evidence.
Frames further apart than ``max_gap`` are unrelated (snapshots, cuts): the chain restarts
there.

Frames: ``paired.real`` and ``paired.mirror`` in pixels, the reflection's labels already in
the person's (:class:`~mirrorgraph.keypoints.PairedKeypoints`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..keypoints import PairedKeypoints

__all__ = ["BodySwapOptions", "BodySwapFilter", "min_sum_messages", "undo_body_swaps",
           "swap_states"]


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


def _points(real: np.ndarray, mirror: np.ndarray, min_confidence: float, left: np.ndarray,
            right: np.ndarray) -> np.ndarray:
    """``(..., P, 4, 2)``: per pair the real left, real right, mirror left, mirror right
    keypoints of ``(..., J, 3)`` views, NaN where unseen."""
    out = []
    for view in (real, mirror):
        v = np.array(view[..., :2], dtype=float)
        low = ~(view[..., 2] > min_confidence) | ~np.isfinite(v).all(-1)
        v[low] = np.nan
        out += [v[..., left, :], v[..., right, :]]
    return np.stack(out, axis=-2)


def _motion_scale(pts: np.ndarray, step: np.ndarray, floor: float) -> np.ndarray:
    """``(P, 4)`` each keypoint's typical motion between consecutive frames (px): the
    median of its displacements over frames one apart, at least ``floor``."""
    d = np.linalg.norm(pts[1:] - pts[:-1], axis=-1)[step[1:] == 1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)                 # all-NaN columns
        med = np.nanmedian(d, axis=0) if len(d) else np.full(pts.shape[1:3], np.nan)
    return np.where(np.isfinite(med), np.maximum(med, floor), floor)


#: The chain's states: whether the direct view's (bit 0) and the reflection's (bit 1)
#: labels of a pair are swapped.
_REAL_SWAPPED = np.array([0, 1, 0, 1])
_MIRROR_SWAPPED = np.array([0, 0, 1, 1])
_STATES = len(_REAL_SWAPPED)


def _transitions(pts: np.ndarray, last: np.ndarray, gap: np.ndarray, fresh: np.ndarray,
                 scale: np.ndarray, opts: BodySwapOptions) -> np.ndarray:
    """``(..., P, 4, 4)`` the chain's min-plus transition matrices ``M[prev, cur]`` over
    the states of :data:`_REAL_SWAPPED`, :data:`_MIRROR_SWAPPED`: the keypoints' motion
    from ``last`` to ``pts`` (both ``(..., P, 4, 2)``, NaN unseen) in each view under the
    labelling the two states give it relative to each other, over ``gap`` frames, plus a
    switch's cost (one detector event, whatever views it changes) and each swapped view's;
    where ``fresh`` (a chain's start) any state follows any; where a pair is unseen the
    state carries on (``0`` on the diagonal, ``inf`` off it)."""
    s = (scale * np.maximum(gap, 1)[..., None])[..., None]
    cap = opts.truncation ** 2
    with np.errstate(invalid="ignore"):
        same = np.minimum(np.sum(((pts - last) / s) ** 2, axis=-1), cap)
        cross = np.minimum(np.sum(((pts[..., [1, 0, 3, 2], :] - last) / s) ** 2, axis=-1), cap)
    views = []
    for k, bits in ((slice(0, 2), _REAL_SWAPPED), (slice(2, 4), _MIRROR_SWAPPED)):
        kept = (bits[:, None] == bits[None, :])                      # (prev, cur)
        a, b = np.nansum(same[..., k], axis=-1), np.nansum(cross[..., k], axis=-1)
        views.append(np.where(kept, a[..., None, None], b[..., None, None]))
    M = views[0] + views[1] + opts.switch_cost * (1.0 - np.eye(_STATES))
    M = (np.where(fresh[..., None, None], 0.0, M)
         + opts.swapped_cost * (_REAL_SWAPPED + _MIRROR_SWAPPED))
    seen = np.isfinite(pts).all(-1).any(-1)
    hold = np.where(np.eye(_STATES, dtype=bool), 0.0, np.inf)
    return np.where(seen[..., None, None], M, hold)


def _minplus(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The min-plus product of stacks of square matrices (``A`` may have one row)."""
    out = A[..., :, 0:1] + B[..., 0:1, :]
    for k in range(1, B.shape[-2]):
        np.minimum(out, A[..., :, k:k + 1] + B[..., k:k + 1, :], out=out)
    return out


#: Frames a block of :func:`min_sum_messages` (the blocks' products are formed side by side).
MESSAGE_BLOCK = 64


def min_sum_messages(M: np.ndarray, block: int = MESSAGE_BLOCK) -> np.ndarray:
    """``(T, ..., S)`` the Viterbi recursion's forward messages ``v_t = v_{t-1} M[t]``
    (min-plus, ``v_{-1} = 0``) of ``(T, ..., S, S)`` matrices: the product of each block
    of ``block`` frames, every block at once; the blocks' entering messages one block
    after the other; then every block's frames at once. ``O(T)`` work in ``2 block``
    vectorised steps (a scan of prefix products, Hillis and Steele 1986, does
    ``log2 T`` times the work)."""
    T, S = len(M), M.shape[-1]
    nb = -(-T // block)
    pad = nb * block - T
    if pad:                                                  # identity matrices at the end
        eye = np.where(np.eye(S, dtype=bool), 0.0, np.inf)
        M = np.concatenate([M, np.broadcast_to(eye, (pad,) + M.shape[1:])])
    Mb = M.reshape((nb, block) + M.shape[1:])
    total = Mb[:, 0].copy()
    for k in range(1, block):
        total = _minplus(total, Mb[:, k])
    entering = np.zeros((nb,) + M.shape[1:-1])
    for i in range(1, nb):
        entering[i] = _minplus(entering[i - 1][..., None, :], total[i - 1])[..., 0, :]
    out = np.empty((nb, block) + M.shape[1:-1])
    v = entering
    for k in range(block):
        v = _minplus(v[..., None, :], Mb[:, k])[..., 0, :]
        out[:, k] = v
    return out.reshape((nb * block,) + M.shape[1:-1])[:T]


class _Chain:
    """The chains' forward state for a stream: per pair the cost of each state so far,
    the last keypoints seen and their frame (the Viterbi recursion, one frame a step)."""

    def __init__(self, P: int, opts: BodySwapOptions) -> None:
        self.opts = opts
        self.cost = np.zeros((P, _STATES))
        self.last = np.full((P, 4, 2), np.nan)
        self.last_frame = np.full(P, -(10 ** 12), dtype=np.int64)
        self.started = np.zeros(P, bool)

    def step(self, pts: np.ndarray, frame: int, scale: np.ndarray) -> np.ndarray:
        """Take one frame's ``(P, 4, 2)`` keypoints (NaN unseen) at ``frame`` with the
        keypoints' typical motions ``(P, 4)``. Returns ``(P, 2)`` whether the pair is
        seen in the direct view and in the reflection."""
        obs = np.isfinite(pts).all(-1).any(-1)
        gap = frame - self.last_frame
        fresh = obs & (~self.started | (gap > self.opts.max_gap))
        M = _transitions(pts, self.last, gap, fresh, scale, self.opts)
        self.cost = _minplus(self.cost[:, None, :], M)[:, 0]
        self.last = np.where(np.isfinite(pts), pts, self.last)
        self.last_frame = np.where(obs, frame, self.last_frame)
        self.started |= obs
        return np.isfinite(pts).all(-1).reshape(len(pts), 2, 2).any(-1)


def _carried(pts: np.ndarray) -> np.ndarray:
    """``(T, ...)`` each keypoint's last finite value before frame ``t`` (NaN: none)."""
    T = len(pts)
    ok = np.isfinite(pts).all(-1)                                       # (T, P, 4)
    idx = np.where(ok, np.arange(T)[:, None, None], -1)
    idx = np.maximum.accumulate(idx, axis=0)
    prev = np.concatenate([np.full((1,) + idx.shape[1:], -1), idx[:-1]])   # strictly before
    out = np.take_along_axis(pts, np.maximum(prev, 0)[..., None], axis=0)
    return np.where((prev >= 0)[..., None], out, np.nan)


def swap_states(paired: PairedKeypoints, min_confidence: float = 0.0,
                options: BodySwapOptions | None = None) -> np.ndarray:
    """``(T, P, 2)`` bool: the frames where the detector swapped pair ``p``'s labels in
    the direct view (``[..., 0]``) and in the reflection (``[..., 1]``) (the most likely
    path of the module docstring's chain: each frame's state the smaller of the forward
    and backward min-plus messages' sums, :func:`min_sum_messages`); pairs in the order of
    ``np.flatnonzero(flip > arange)`` (the left joint of each pair)."""
    opts = options or BodySwapOptions()
    left, right = _pairs(np.asarray(paired.skeleton.flip))
    T, P = len(paired), len(left)
    if T == 0 or P == 0:
        return np.zeros((T, P, 2), bool)
    frames = np.asarray(paired.frame_ids, dtype=np.int64)
    if len(frames) != T:                 # frame numbers that are not the rows': no chain
        return np.zeros((T, P, 2), bool)
    pts = _points(paired.real, paired.mirror, min_confidence, left, right)   # (T, P, 4, 2)
    step = np.diff(frames, prepend=frames[0] - 1)
    scale = _motion_scale(pts, step, opts.min_scale_px)             # (P, 4)
    seen = np.isfinite(pts).all(-1).any(-1)                         # (T, P)
    last_obs = np.maximum.accumulate(np.where(seen, np.arange(T)[:, None], -1), axis=0)
    before = np.concatenate([np.full((1, P), -1), last_obs[:-1]])   # last seen before t
    gap = np.where(before >= 0, frames[:, None] - frames[np.maximum(before, 0)], 10 ** 12)
    fresh = seen & ((before < 0) | (gap > opts.max_gap))
    M = _transitions(pts, _carried(pts), gap, fresh, scale, opts)   # (T, P, 4, 4)
    forward = min_sum_messages(M)                                          # (T, P, cur)
    backward = np.zeros((T, P, _STATES))
    if T > 1:                                       # M[t+1] ... M[T-1], transposed
        backward[:-1] = min_sum_messages(np.swapaxes(M[1:][::-1], -1, -2))[::-1]
    state = np.argmin(forward + backward, axis=-1)
    in_view = np.isfinite(pts).all(-1).reshape(T, P, 2, 2).any(-1)  # (T, P, view)
    return np.stack([_REAL_SWAPPED[state], _MIRROR_SWAPPED[state]], -1).astype(bool) & in_view


#: The stream's typical motions are taken anew every this many frames.
SCALE_EVERY = 30


class BodySwapFilter:
    """The chain of :func:`swap_states` run forward, one frame at a time, for a stream
    (the live run): each frame's decision is the state the frames so far make likelier
    (the forward recursion's, without the later frames' say).

    Args:
        skeleton: the keypoint layout (its flip map gives the pairs).
        min_confidence: keypoints below it are unseen.
        options: :class:`BodySwapOptions`.
        history: frames of displacements each keypoint's typical motion is the median of.
    """

    def __init__(self, skeleton, min_confidence: float = 0.0,
                 options: BodySwapOptions | None = None, history: int = 300) -> None:
        self.opts = options or BodySwapOptions()
        self.left, self.right = _pairs(np.asarray(skeleton.flip))
        self.min_confidence = float(min_confidence)
        self._chain = _Chain(len(self.left), self.opts)
        self._moves = np.full((int(history), len(self.left), 4), np.nan)
        self._n = 0
        self._prev: tuple[int, np.ndarray] | None = None
        self._scale: np.ndarray | None = None

    def update(self, real: np.ndarray, mirror: np.ndarray, frame_id: int
               ) -> tuple[np.ndarray, np.ndarray]:
        """One frame's paired ``(J, 3)`` keypoints (the reflection's labels in the
        person's) with the pairs the chain finds swapped exchanged in the views they are
        swapped in."""
        pts = _points(np.asarray(real), np.asarray(mirror), self.min_confidence, self.left,
                      self.right)                                                # (P, 4, 2)
        if self._prev is not None and frame_id - self._prev[0] == 1:
            self._moves[self._n % len(self._moves)] = np.linalg.norm(pts - self._prev[1], axis=-1)
            self._n += 1
        self._prev = (int(frame_id), pts)
        if self._scale is None or self._n % SCALE_EVERY == 0:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)             # all-NaN columns
                med = (np.nanmedian(self._moves[:min(self._n, len(self._moves))], axis=0)
                       if self._n else np.full(pts.shape[:2], np.nan))
            self._scale = np.where(np.isfinite(med), np.maximum(med, self.opts.min_scale_px),
                                   self.opts.min_scale_px)
        seen = self._chain.step(pts, int(frame_id), self._scale)
        state = np.argmin(self._chain.cost, axis=1)
        swapped = seen & np.stack([_REAL_SWAPPED[state], _MIRROR_SWAPPED[state]], -1).astype(bool)
        if not swapped.any():
            return real, mirror
        out = []
        for i, view in enumerate((real, mirror)):
            v = np.array(view, copy=True)
            p = np.flatnonzero(swapped[:, i])
            v[self.left[p]], v[self.right[p]] = view[self.right[p]], view[self.left[p]]
            out.append(v)
        return out[0], out[1]


def undo_body_swaps(paired: PairedKeypoints, min_confidence: float = 0.0,
                    options: BodySwapOptions | None = None) -> tuple[PairedKeypoints, int]:
    """Swap back the left/right labels the detector confused, in either view or both.

    Args:
        paired: person and reflection, paired (the reflection's labels in the person's).
        min_confidence: keypoints below it are unseen.
        options: :class:`BodySwapOptions`.

    Returns:
        The keypoints with the swapped pairs' labels exchanged in the views they are
        swapped in, and how many (frame, pair, view) entries were swapped back.
    """
    swapped = swap_states(paired, min_confidence, options)
    n = int(np.count_nonzero(swapped))
    if n == 0:
        return paired, 0
    left, right = _pairs(np.asarray(paired.skeleton.flip))
    views = []
    for i, view in enumerate((paired.real, paired.mirror)):
        v = np.array(view, copy=True)
        t, p = np.nonzero(swapped[..., i])
        v[t, left[p]], v[t, right[p]] = view[t, right[p]], view[t, left[p]]
        views.append(v)
    return replace(paired, real=views[0], mirror=views[1]), n
