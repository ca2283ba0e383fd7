"""Following people over time in one camera: tracks, their left/right labels, the subject.

The candidates of a camera are linked into tracks frame to frame (Hungarian assignment
on the mean joint distance, :func:`track_people`; a detector's left/right swap of a
turning person continues the track, :func:`track_labelled`, and :func:`continuity_labels`
reads one person's swaps); the subject is the track seen in the most frames, and
between tracks seen nearly as long the one that moves most (:func:`subject_track`,
:func:`track_motion`). :func:`tracklets` cuts tracks where the tracker read a swap.
:mod:`mirrorgraph.rigs.matching` matches the tracks across cameras.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["JUMP_OF_SIZE", "NEAR_LONGEST", "TRACK_AGE_PX", "TRACK_GATE_PX", "TRACK_MAX_GAP",
           "continuity_labels", "jumping", "rig_segments", "segments", "subject_track", "track_labelled", "track_motion",
           "track_people", "tracklets"]

#: Tracks: a detection farther than this (mean joint distance, px) from every
#: track's last position starts a new track.
TRACK_GATE_PX = 150.0

#: Tracks: each frame a track has gone unseen adds this many px to a detection's
#: distance from it: a person seen in the last frame is preferred to a track that
#: went missing (brief false detections otherwise leave tracks that can take over a
#: moving person's identity, as on Pose2Sim's Demo_MultiPerson).
TRACK_AGE_PX = 20.0

#: Tracks unseen for more frames than this end; where two consecutive frames of a
#: recording are farther apart than this, nothing continues from one to the other
#: (:func:`segments`: snapshots).
TRACK_MAX_GAP = 30


#: People who move more than this share of their size a frame (to the nearest detection of
#: the frame before, the median over a frame's detections), in most frames, are not
#: filmed but snapshots numbered frame after frame (:func:`jumping`): a person walking
#: at 30 frames/s moves ~0.02 of their size a frame on synthetic rigs, people placed and
#: turned anew ~0.23, and 0.1 a frame is three body sizes a second.
JUMP_OF_SIZE = 0.1

#: Pairs of consecutive frames :func:`jumping` compares at most (evenly spread).
JUMP_PAIRS = 400


def jumping(candidates: list[np.ndarray], joints: np.ndarray, min_confidence: float,
            frame_ids: np.ndarray | None = None) -> bool:
    """Whether the people jump from frame to frame (snapshots, whatever their numbers): in
    more than half of the pairs of consecutive frames that both hold someone (at most
    :data:`JUMP_PAIRS` of them, evenly spread), the median over the later frame's
    detections of their distance (mean over the ``joints`` seen in both, px, as the
    tracks measure it) to the nearest detection of the earlier frame, over their size (the
    larger side of the box of their confident joints) and the frames between the two
    (``frame_ids``; default 1), exceeds :data:`JUMP_OF_SIZE`.

    Args:
        candidates: ``T`` arrays ``(P_t, J, 3)`` (x px, y px, confidence).
        joints: the joints compared; min_confidence: joints below it are not.
        frame_ids: ``(T,)`` the frames' numbers.
    """
    T = len(candidates)
    if T < 2:
        return False
    joints = np.asarray(joints, int)
    pairs = np.unique(np.linspace(0, T - 2, min(T - 1, JUMP_PAIRS)).round().astype(int))
    rows = np.unique(np.concatenate([pairs, pairs + 1]))
    P = max((len(candidates[t]) for t in rows), default=0)
    if P == 0:
        return False
    xy = np.full((len(rows), P, len(joints), 2), np.nan)
    for i, t in enumerate(rows):
        p = candidates[t]
        if len(p):
            q = np.asarray(p, float).reshape(len(p), -1, 3)[:, joints]
            xy[i, :len(q)] = np.where(q[..., 2:3] >= min_confidence, q[..., :2], np.nan)
    step = (np.diff(np.asarray(frame_ids, float)[:T]) if frame_ids is not None
            else np.ones(T - 1))
    later, earlier = xy[np.searchsorted(rows, pairs + 1)], xy[np.searchsorted(rows, pairs)]
    with warnings.catch_warnings():                   # empty rows: nobody there
        warnings.simplefilter("ignore", RuntimeWarning)
        size = np.nanmax(np.nanmax(later, 2) - np.nanmin(later, 2), -1)          # (n, P)
        d = np.nanmean(np.linalg.norm(later[:, :, None] - earlier[:, None], axis=-1),
                       axis=-1)                                                   # (n, P, P)
        nearest = np.nanmin(d, axis=2) / np.where(size > 0, size, np.nan)
        rate = np.nanmedian(nearest, axis=1) / np.maximum(step[pairs], 1.0)       # (n,)
    judged = np.isfinite(rate)
    return bool(judged.any() and np.count_nonzero(rate[judged] > JUMP_OF_SIZE)
                > 0.5 * np.count_nonzero(judged))


def segments(frame_ids: np.ndarray | None, T: int | None = None,
             candidates: list[np.ndarray] | None = None, joints: np.ndarray | None = None,
             min_confidence: float = 0.3) -> np.ndarray:
    """``(T,)`` int: the continuous stretch of each frame, ``0 ..``, a new one wherever the
    frame numbers ``frame_ids`` ``(T,)`` jump by more than :data:`TRACK_MAX_GAP`
    (snapshots far apart in time), and one a frame where the people of ``candidates``
    (``T`` arrays ``(P_t, J, 3)``, their ``joints``) jump from frame to frame
    (:func:`jumping`: snapshots numbered frame after frame). ``None``: one stretch of
    ``T`` frames."""
    if frame_ids is None:
        out = np.zeros(int(T if T is not None else len(candidates or [])), dtype=int)
    else:
        ids = np.asarray(frame_ids, dtype=np.int64).ravel()
        out = np.zeros(len(ids), dtype=int)
        out[1:] = np.cumsum(np.diff(ids) > TRACK_MAX_GAP)
    if (candidates is not None and joints is not None and len(out) > 1 and out[-1] < len(out) - 1
            and jumping(candidates, joints, min_confidence, frame_ids)):
        out = np.arange(len(out))
    return out


def rig_segments(frame_ids: np.ndarray, cameras: list[list[np.ndarray]], joints: np.ndarray,
                 min_confidence: float = 0.3) -> np.ndarray:
    """``(T,)`` :func:`segments` of a rig's frames: cut where ``frame_ids`` jump, one a
    frame where the people jump in most of the ``cameras`` (each ``T`` arrays
    ``(P_t, J, 3)``) that see anyone."""
    out = segments(frame_ids)
    seen = [c for c in cameras if any(len(p) for p in c)]
    if len(out) > 1 and out[-1] < len(out) - 1 and seen and sum(
            jumping(c, joints, min_confidence, frame_ids) for c in seen) > 0.5 * len(seen):
        out = np.arange(len(out))
    return out


def track_people(candidates: list[np.ndarray], joints: np.ndarray, min_confidence: float,
                 flip: np.ndarray | None = None, frame_ids: np.ndarray | None = None
                 ) -> list[np.ndarray]:
    """Link detections into tracks frame to frame: :func:`track_labelled`'s track ids."""
    return track_labelled(candidates, joints, min_confidence, flip, frame_ids)[0]


def track_labelled(candidates: list[np.ndarray], joints: np.ndarray, min_confidence: float,
                   flip: np.ndarray | None = None, frame_ids: np.ndarray | None = None
                   ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Link detections into tracks frame to frame, each detection's left/right labels
    read against its track's.

    A detector may swap a person's left and right labels from one frame to the next
    (BlazePose on a subject turning on the spot: on Pose2Sim's Demo_SinglePerson the
    mean joint distance between consecutive frames jumps from ~7 px to ~230 px where
    it does, and was read as a new person). With ``flip`` the detections are assigned
    to tracks as labelled, each taking the labelling closer to its track, and those
    that assignment leaves without a track are assigned again, with their labels
    swapped, among the tracks left; a track carries on in its own labelling.

    Args:
        candidates: ``T`` arrays ``(P_t, J, 3)`` (x px, y px, confidence).
        joints: joints compared.
        min_confidence: joints below it are not compared.
        flip: ``(J,)`` left/right permutation of the labels
            (:attr:`mirrorgraph.skeletons.Skeleton.flip`); ``None``: labels as given.
        frame_ids: ``(T,)`` the candidates' frame numbers: every track ends where they
            jump by more than :data:`TRACK_MAX_GAP`, and at every frame where the people
            jump from frame to frame (:func:`segments`; snapshots share no track).
            ``None``: consecutive frames, continuity assumed.

    Returns:
        ``T`` int arrays ``(P_t,)``: the track id of each detection, and ``T`` bool
        arrays ``(P_t,)``: the detection's labels are swapped relative to its track's
        (the labelling of the track's first detection, carried on by continuity;
        always ``False`` without ``flip``).
    """
    last: dict[int, np.ndarray] = {}
    seen_at: dict[int, int] = {}
    ids, swaps, next_id = [], [], 0
    stretch = (segments(np.asarray(frame_ids)[:len(candidates)], len(candidates), candidates,
                        joints, min_confidence) if frame_ids is not None
               else segments(None, len(candidates)))
    for t, people in enumerate(candidates):
        p = np.asarray(people, dtype=float)
        lab = np.full(len(p), -1)
        swapped = np.zeros(len(p), dtype=int)
        if t and stretch[t] != stretch[t - 1]:
            last.clear()                                # the frames jump: every track ends
            seen_at.clear()
        for k in [k for k, s in seen_at.items() if t - s > TRACK_MAX_GAP]:
            del last[k], seen_at[k]                     # a track unseen for long has ended
        if len(p):
            xy = np.where((p[:, joints, 2:3] >= min_confidence), p[:, joints, :2], np.nan)
            if flip is not None:
                pf = p[:, flip]
                xy = np.stack([xy, np.where((pf[:, joints, 2:3] >= min_confidence),
                                            pf[:, joints, :2], np.nan)])      # (2, P, j, 2)
            else:
                xy = xy[None]                                                 # (1, P, j, 2)
            keys = list(last)
            if keys:
                prev = np.stack([last[k] for k in keys])                       # (K, j, 2)
                with warnings.catch_warnings():          # all-NaN rows: no joint in common
                    warnings.simplefilter("ignore", RuntimeWarning)
                    dist = np.nanmean(np.linalg.norm(xy[:, :, None] - prev[None, None],
                                                     axis=-1), -1)             # (L, P, K)
                dist = np.where(np.isfinite(dist), dist, 1e9)
                # a track seen in the last frame is preferred to one that went missing
                age = np.array([t - 1 - seen_at[k] for k in keys], dtype=float)
                free = np.ones(len(keys), dtype=bool)
                # as labelled first; only what that leaves is linked with swapped labels
                # (swapped labels for all would let a duplicate or a passer-by take over
                # a moving person's track: Demo_MultiPerson, every 2nd frame)
                for how in range(len(dist)):
                    rows, cols = np.flatnonzero(lab < 0), np.flatnonzero(free)
                    if not len(rows) or not len(cols):
                        break
                    d = dist[how][np.ix_(rows, cols)]
                    r, c = linear_sum_assignment(d + TRACK_AGE_PX * age[cols][None, :])
                    for i, k in zip(rows[r], cols[c]):
                        if dist[how, i, k] < TRACK_GATE_PX:
                            # the track as labelled, its labels as they fit it best
                            lab[i], free[k] = keys[k], False
                            swapped[i] = how or (len(dist) > 1 and dist[1, i, k] < dist[0, i, k])
            for i in np.flatnonzero(lab < 0):
                lab[i] = next_id
                next_id += 1
            for i, k in enumerate(lab):
                mine = xy[swapped[i], i]                 # in the track's own labelling
                seen = np.isfinite(mine).all(-1)
                prev_xy = last.get(int(k), np.full(mine.shape, np.nan))
                last[int(k)] = np.where(seen[:, None], mine, prev_xy)
                seen_at[int(k)] = t
        ids.append(lab)
        swaps.append(swapped.astype(bool))
    return ids, swaps


def continuity_labels(person: np.ndarray, joints: np.ndarray, min_confidence: float,
                      flip: np.ndarray, frame_ids: np.ndarray | None = None) -> np.ndarray:
    """Where one person's left/right labels are swapped, read by continuity.

    The person's detections (one a frame) are tracked with :func:`track_labelled`;
    within each stretch the tracker follows, the frames whose labels disagree with
    the stretch's labelling are swapped, the stretch's labelling being the one most
    of its frames carry as detected (a detector is right more often than not).

    Args:
        person: ``(T, J, 3)`` x px, y px, confidence (frames without the person:
            confidence 0).
        joints: joints compared; min_confidence: joints below it are not compared.
        flip: ``(J,)`` left/right permutation of the labels.
        frame_ids: ``(T,)`` frame numbers: no stretch crosses a jump of more than
            :data:`TRACK_MAX_GAP` (:func:`track_labelled`); ``None``: consecutive.

    Returns:
        ``(T,)`` bool: swap the frame's labels (``person[t, flip]``) to follow the
        stretch's labelling.
    """
    T, J = person.shape[:2]
    present = (np.asarray(person[..., 2]) >= min_confidence).any(axis=1)
    people = [person[t][None] if present[t] else np.zeros((0, J, 3)) for t in range(T)]
    ids, swaps = track_labelled(people, joints, min_confidence, flip, frame_ids)
    track = np.array([i[0] if len(i) else -1 for i in ids])
    swap = np.array([bool(s[0]) if len(s) else False for s in swaps])
    out = np.zeros(T, dtype=bool)
    for k in np.unique(track[track >= 0]):
        mine = track == k
        out[mine] = swap[mine] if swap[mine].mean() <= 0.5 else ~swap[mine]
    return out


#: Tracks seen in at least this share of the longest track's frames compete on motion
#: in :func:`subject_track`.
NEAR_LONGEST = 0.9


def subject_track(tracks: list[np.ndarray], motion: dict[int, float] | None = None,
                  confidence: list[np.ndarray] | None = None) -> tuple[int, dict[int, int]]:
    """The track to calibrate from: seen in (nearly) the most frames, moving the most.

    A person who hardly moves sweeps a small volume, and the rig's geometry comes from
    the joints' spread: between tracks seen in at least :data:`NEAR_LONGEST` of the
    longest one's frames, the one whose joints move most is chosen (on Pose2Sim's
    Demo_MultiPerson, two people in all 100 frames, the one standing nearly still
    gave cameras 3.7-5.7 deg off, the other 0.7-2.6 deg: ``bench/RESULTS_real.md``).

    Args:
        tracks: ``T`` int arrays ``(P_t,)``, :func:`track_people`'s output.
        motion: track id -> how much it moves (:func:`track_motion`); default: the
            frame count alone decides.
        confidence: ``T`` arrays ``(P_t,)``, e.g. each detection's summed joint
            confidence: breaks the remaining ties by the track's total (default: the
            track that started first).

    Returns:
        the track id (-1 when there is no detection at all), and the number of
        frames of every track.
    """
    ids = np.concatenate([np.asarray(t, dtype=int).ravel() for t in tracks] + [np.zeros(0, int)])
    if len(ids) == 0:
        return -1, {}
    found, where, counts = np.unique(ids, return_inverse=True, return_counts=True)
    total = np.zeros(len(found))
    if confidence is not None:
        conf = np.concatenate([np.asarray(c, float).ravel() for c in confidence] + [np.zeros(0)])
        np.add.at(total, where, np.nan_to_num(conf))
    frames = counts.astype(float)
    if motion is not None:                  # near-longest tracks are equal on frames
        near = counts >= NEAR_LONGEST * counts.max()
        frames = np.where(near, counts.max(), counts)
        moves = np.array([motion.get(int(k), 0.0) for k in found])
        order = (-np.arange(len(found)), total, np.where(near, moves, 0.0), frames)
    else:
        order = (-np.arange(len(found)), total, frames)
    best = np.lexsort(order)[-1]            # a track is once a frame
    return int(found[best]), dict(zip(found.tolist(), counts.tolist()))


def track_motion(tracks: list[np.ndarray], people: list[np.ndarray], joints: np.ndarray,
                 min_confidence: float) -> dict[int, float]:
    """How much each track moves: the median over ``joints`` of the spread (RMS distance
    from its mean, pixels) of the joint's image positions over the track's frames.

    Args:
        tracks: ``T`` int arrays ``(P_t,)`` of track ids.
        people: ``T`` arrays ``(P_t, J, 3)`` (x, y, confidence) of the detections.
        joints: the joints to measure.
        min_confidence: joints below it are not counted.

    Returns:
        track id -> spread in pixels (0 for a track with too few frames to tell).
    """
    rows = [(int(k), p[i, joints]) for ids, p in zip(tracks, people)
            for i, k in enumerate(np.asarray(ids, dtype=int).ravel())]
    out: dict[int, float] = {}
    for k in {r[0] for r in rows}:
        X = np.array([r[1] for r in rows if r[0] == k], dtype=float)       # (n, j, 3)
        xy = np.where((X[..., 2:3] >= min_confidence), X[..., :2], np.nan)
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            spread = np.sqrt(np.nanmean(np.sum((xy - np.nanmean(xy, axis=0)) ** 2, -1), axis=0))
        spread = spread[np.isfinite(spread)]
        out[k] = float(np.median(spread)) if len(spread) and len(X) >= 2 else 0.0
    return out


def tracklets(track: np.ndarray, swapped: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Tracks cut into pieces where the tracker read a left/right swap.

    A swap the tracker reads (:func:`track_labelled`) is its least certain link: where
    a person walks into another, a detector swaps their labels and places their joints
    on both people at once (Pose2Sim's Demo_MultiPerson, cam03, every 3rd frame: the
    subject's track reads a swap at frame 42 as they reach the person standing still;
    the 14 frames before it fit an epipolar geometry with the first camera's person to
    92 % of their joints, the 7 after it 53 %, the whole track's best geometry 45 %).
    Each piece is one person for as long as it lasts, so it has a geometry of its own;
    a piece is never two people in one frame, since a track is not.

    Args:
        track: ``(M,)`` track ids; swapped: ``(M,)`` bool, the detection's labels swapped
            relative to its track's (:func:`track_labelled`); frame: ``(M,)`` frame
            indices.

    Returns:
        ``(M,)`` int piece ids (``0 ..``), a new one at each track's first detection and
        at each change of ``swapped`` along it.
    """
    track, swapped, frame = (np.asarray(a).ravel() for a in (track, swapped, frame))
    order = np.lexsort((frame, track))
    new = np.ones(len(order), bool)
    new[1:] = (track[order][1:] != track[order][:-1]) | (swapped[order][1:] != swapped[order][:-1])
    out = np.empty(len(order), int)
    out[order] = np.cumsum(new) - 1
    return out
