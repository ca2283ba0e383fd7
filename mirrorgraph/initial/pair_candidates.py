"""The candidate pairs of the pairing (:mod:`mirrorgraph.initial.pairing`) and their geometry.

Every unordered pair of detections of a frame is a candidate (:func:`candidates`, step 1 of
the pairing); it is scored by the median epipolar distance over the joints both show
(:func:`median_distance`), and where it fits, the detection closer to the epipole is the
reflection (:func:`b_is_reflection_of`, step 4). :class:`PairingOptions` are the options of
every step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import geometry as geo
from ..errors import DegenerateGeometryError, InputError
from ..keypoints import DEFAULT_MIN_CONFIDENCE, RawDetections
from .estimators import DEFAULT_THRESHOLD_PX, estimate_epipole

__all__ = ["Candidates", "FAR_EPIPOLE_PX", "PairingOptions", "b_is_reflection_of", "candidates",
           "epipole_either_labelling", "masked", "median_distance", "spread_subset"]


@dataclass(frozen=True)
class PairingOptions:
    """Options of :func:`pair_detections`.

    Attributes:
        min_confidence: joints below this detector confidence are ignored.
        threshold_px: inlier threshold on the epipolar distance, pixels.
        max_people: detections considered per frame (most confident first).
        ransac_frames: frames sampled (evenly spread) to find the epipole.
        min_joints: joints a candidate pair needs in common to be scored.
        seed: RANSAC seed.
    """

    min_confidence: float = DEFAULT_MIN_CONFIDENCE
    threshold_px: float = DEFAULT_THRESHOLD_PX
    max_people: int = 6
    ransac_frames: int = 400
    min_joints: int = 4
    seed: int = 0


@dataclass
class Candidates:
    """The candidate pairs of a camera's frames, ``M`` of them (:func:`candidates`)."""

    frame: np.ndarray      # (M,) frame index
    a: np.ndarray          # (M, J, 3) first detection
    b: np.ndarray          # (M, J, 3) second detection, labels flipped
    ia: np.ndarray         # (M,) index of the first detection in its frame's list
    ib: np.ndarray         # (M,) index of the second


def masked(people: np.ndarray, min_conf: float) -> np.ndarray:
    p = np.array(people, dtype=float, copy=True)
    low = ~(p[..., 2] >= min_conf) | ~np.isfinite(p[..., :2]).all(-1)
    p[low] = (np.nan, np.nan, 0.0)
    return p


def candidates(raw: RawDetections, opts: PairingOptions) -> Candidates:
    """Every unordered pair of detections of every frame (at most ``max_people`` a frame,
    the most confident), the second one's labels flipped; frame by frame, in
    ``np.triu_indices`` order within a frame. Vectorised over the frames holding the
    same number of people (a long video has tens of thousands of frames)."""
    flip = raw.skeleton.flip
    J = raw.skeleton.num_joints
    counts = np.array([len(p) for p in raw.people], dtype=int)
    frames_with = np.flatnonzero(counts >= 2)
    if frames_with.size == 0:
        raise InputError("no frame holds two people (a person and their reflection): "
                         "the reflection is missing in every frame", source=raw.source)
    people = masked(np.concatenate([np.asarray(raw.people[t], dtype=float).reshape(-1, J, 3)
                                     for t in frames_with]), opts.min_confidence)
    start = np.concatenate([[0], np.cumsum(counts[frames_with])[:-1]])  # first row a frame
    frame, ia, ib, rank = [], [], [], []
    for c in np.unique(counts[frames_with]):
        sel = counts[frames_with] == c
        f, base = frames_with[sel], start[sel]                          # (F,)
        if c <= opts.max_people:
            index = np.broadcast_to(np.arange(c), (len(f), c))          # (F, c)
        else:                                  # the most confident max_people, in order
            conf = people[base[:, None] + np.arange(c), :, 2].mean(-1)  # (F, c)
            index = np.sort(np.argsort(-conf, axis=1, kind="stable")[:, :opts.max_people],
                            axis=1)
        i, k = np.triu_indices(index.shape[1], 1)
        frame.append(np.repeat(f, len(i)))
        ia.append(index[:, i].ravel())
        ib.append(index[:, k].ravel())
        rank.append(np.tile(np.arange(len(i)), len(f)))
        start_rows = np.repeat(base, len(i))
        ia[-1] = np.stack([ia[-1], start_rows + ia[-1]])                # (2, P): index, row
        ib[-1] = np.stack([ib[-1], start_rows + ib[-1]])
    frame, rank = np.concatenate(frame), np.concatenate(rank)
    ia, ib = np.concatenate(ia, axis=1), np.concatenate(ib, axis=1)
    order = np.lexsort((rank, frame))
    ia, ib = ia[:, order], ib[:, order]
    return Candidates(frame[order], people[ia[1]], people[ib[1]][:, flip], ia[0], ib[0])


def nanmedian_rows(x: np.ndarray) -> np.ndarray:
    """``(M,)`` the median of each row of ``x`` ``(M, N)`` over its non-NaN entries (NaN
    where a row has none): :func:`numpy.nanmedian` along ``axis=1``, equal to it, by one
    sort. NumPy takes rows shorter than 600 through masked arrays, ~0.7 ms a call for
    the two candidates of a frame against ~0.05 ms here (the live run scores every frame).
    """
    x = np.asarray(x, dtype=float)
    if x.shape[1] == 0:
        return np.full(len(x), np.nan)
    s = np.sort(x, axis=1)                              # NaN sorts last
    k = np.count_nonzero(~np.isnan(x), axis=1)
    r = np.arange(len(x))
    lo, hi = s[r, np.maximum(k - 1, 0) // 2], s[r, np.minimum(k // 2, x.shape[1] - 1)]
    return np.where(k > 0, 0.5 * (lo + hi), np.nan)


def median_distance(e: np.ndarray, a: np.ndarray, b: np.ndarray, joints: np.ndarray,
                     min_joints: int) -> np.ndarray:
    """``(M,)`` median epipolar distance over shared joints (inf if too few)."""
    d = geo.epipolar_distances(e, a[:, joints, :2], b[:, joints, :2])
    d[~np.isfinite(d)] = np.nan
    enough = np.count_nonzero(np.isfinite(d), axis=1) >= min_joints
    out = np.full(len(a), np.inf)
    if enough.any():
        out[enough] = nanmedian_rows(d[enough])
    return out


#: The epipole found on both labellings of the reflection replaces the one found on the
#: labels as given only where its truncated cost over the candidates (either labelling's
#: median distance, squared, at most the threshold's square) is under this fraction of
#: the other's: where the detector crossed a view's labels in a whole clip, an epipole
#: beside the true one fits the crossed pairs loosely and the true one fits them at the
#: noise once relabelled; where it crossed none both epipoles fit alike (and among
#: several people the pairs of the other labelling add chance fits).
EITHER_LABELLING_GAIN = 0.8


def epipole_either_labelling(a: np.ndarray, b: np.ndarray, joints: np.ndarray,
                             flip: np.ndarray, opts: PairingOptions, seed: int) -> np.ndarray:
    """``(3,)`` the mirror's homogeneous epipole (pixels) from candidates ``a``, ``b``
    (``(M, J, 3)``, ``b`` in ``a``'s labels) whichever way a detector labels left and
    right, in any share of them (a body seen from behind labelled as facing the camera in
    a whole clip).

    The reflective RANSAC (:func:`~.estimators.estimate_epipole`) on the pairs as
    labelled; and on every joint of ``joints`` as labelled with, for the joints with a
    left/right counterpart, ``b``'s counterpart too (of a left/right joint's two pairs one
    images the same physical joint), then again on each candidate under the labelling of
    ``b`` that fits that epipole better (median epipolar distance). The second is kept
    where its truncated cost is under :data:`EITHER_LABELLING_GAIN` times the first's.

    Raises:
        DegenerateGeometryError: the pairs do not determine an epipole.
    """
    def paired(e: np.ndarray) -> tuple[float, np.ndarray]:
        keep = median_distance(e, a, b, joints, opts.min_joints)
        swap = median_distance(e, a, b[:, flip], joints, opts.min_joints)
        cost = np.minimum(np.minimum(keep, swap), opts.threshold_px) ** 2
        return float(np.sum(cost[np.isfinite(cost)])), swap < keep

    try:
        e_as, _, _, _ = estimate_epipole(a[:, joints, :2].reshape(-1, 2),
                                         b[:, joints, :2].reshape(-1, 2),
                                         threshold_px=opts.threshold_px, seed=seed)
        count_as = paired(e_as)[0]
    except DegenerateGeometryError:
        e_as, count_as = None, np.inf
    sided = joints[flip[joints] != joints]
    u = np.concatenate([a[:, joints, :2].reshape(-1, 2), a[:, sided, :2].reshape(-1, 2)])
    um = np.concatenate([b[:, joints, :2].reshape(-1, 2),
                         b[:, flip[sided], :2].reshape(-1, 2)])
    try:
        e, _, _, _ = estimate_epipole(u, um, threshold_px=opts.threshold_px, seed=seed)
        better = np.where(paired(e)[1][:, None, None], b[:, flip], b)
        e, _, _, _ = estimate_epipole(a[:, joints, :2].reshape(-1, 2),
                                      better[:, joints, :2].reshape(-1, 2),
                                      threshold_px=opts.threshold_px, seed=seed)
    except DegenerateGeometryError:
        if e_as is None:
            raise
        return e_as
    if e_as is None or paired(e)[0] < EITHER_LABELLING_GAIN * count_as:
        return e
    return e_as


def spread_subset(frames: np.ndarray, count: int) -> np.ndarray:
    """Bool mask over candidates keeping those of ``count`` evenly spread frames."""
    unique = np.unique(frames)
    if len(unique) <= count:
        return np.ones(len(frames), bool)
    keep = unique[np.linspace(0, len(unique) - 1, count).round().astype(int)]
    return np.isin(frames, keep)


#: Beyond this distance from the joints (pixels) the epipole is treated as at
#: infinity and the reflection is told apart by its smaller size instead.
FAR_EPIPOLE_PX = 1e5


def b_is_reflection_of(e: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(M,)`` bool: detection ``b`` (not ``a``) is the reflection.

    Votes over joints for the detection closer to the epipole. The distances
    are compared in homogeneous form ``|x e_z - e| = |e_z| |u - e_pix|`` so the
    unknown sign of ``e`` cancels. When the epipole is (nearly) at infinity the
    reflection, farther from the camera, is the smaller detection.
    """
    ah = geo.to_homogeneous(a[..., :2])
    bh = geo.to_homogeneous(b[..., :2])
    da = np.linalg.norm(ah * e[2] - e, axis=-1)
    db = np.linalg.norm(bh * e[2] - e, axis=-1)
    votes = np.where(np.isfinite(da) & np.isfinite(db), np.sign(da - db), 0.0)
    by_epipole = votes.sum(axis=1) >= 0
    far = nanmedian_rows(np.where(np.isfinite(da), da, np.nan)) > FAR_EPIPOLE_PX * abs(e[2])
    if not np.any(far):
        return by_epipole
    size_a = np.nansum(np.nanstd(a[..., :2], axis=1), axis=-1)
    size_b = np.nansum(np.nanstd(b[..., :2], axis=1), axis=-1)
    return np.where(far, size_b <= size_a, by_epipole)
