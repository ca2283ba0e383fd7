"""The same person in every camera: following one person over time, and matching
detections across cameras by epipolar consistency.

Neither a camera without mirrors nor one with mirrors can tell its subject from
a bystander frame by frame: the most confident detection may be anyone, and in
front of a mirror everyone pairs with their own reflection. So:

* **Over time, in one camera** (the rig's first, the reference): the
  candidates are linked into tracks frame to frame (Hungarian assignment on the
  mean joint distance, :func:`track_people`) and the subject is the track seen
  in the most frames (:func:`subject_track`; with mirrors the candidates are
  the people that pair with a reflection, so the one that pairs longest), and
  between tracks seen nearly as long the one that moves most (:func:`track_motion`).
* **Across cameras** (:func:`match_candidates`), for every other camera:

  1. its candidates are linked into tracks (:func:`track_labelled`: a detector's
     left/right swap of a turning person continues the track, and each detection's
     labels are read against the track's);
  2. each long enough track is tested against the reference camera's person, its
     detections in the labels continuity gives them and with one answer per track
     (and stretch of the reference person's track) for how those relate to the
     reference person's (:func:`_labelled_geometry`):
     an essential matrix by MAGSAC++, refined robustly
     (:func:`mirrorgraph.initial.relative.refine_relative_pose`); the track whose
     joints fit it best (largest fraction under :data:`TRACK_INLIER_PX`, or 2 %
     of the reference person's size where larger: :func:`inlier_threshold_px`,
     weighted by the square root of its size) gives the geometry. Pooling every
     candidate pair instead fails: with two people half the pairs are wrong,
     and the person's small extent in the image leaves the minimal samples'
     essential matrices degrees off (bas-relief ambiguity), so the wrong pairs
     win;
  3. with that track's geometry every frame's candidates, as labelled, are scored
     by their
     median Sampson distance (Hartley and Zisserman, *Multiple View Geometry*,
     2nd ed., sec. 11.4.3) to the reference person, and the best under
     :data:`MATCH_THRESHOLD_PX` (scaled as the inlier threshold) is kept (track
     switches are repaired here),
     except on tracks that fit in too few of their frames
     (:data:`MIN_TRACK_AGREEMENT`): those are other people, never kept, not even
     where the subject is missing and they are a frame's only candidate.

  When no whole track fits with :data:`MIN_TRACK_INLIERS` inliers, step 2 is
  repeated on the tracks' pieces between the left/right swaps the tracker read
  (:func:`tracklets`): where the subject walks into another person, the detector
  swaps and scatters their joints and the tracker links those frames into the
  subject's track, which then fits no geometry as a whole; the piece before it does
  (Pose2Sim's Demo_MultiPerson, cam03, every 3rd frame: 92 % against 45 % for the
  whole track and 46 % for the person standing still). A piece is one track's
  stretch, so still one person a frame; only the geometry comes from it, and step 3
  follows as above.

  When no track has :data:`MIN_CORRESPONDENCES` joints seen with the reference
  person, or the best one (nor any piece) fits with fewer than :data:`MIN_TRACK_INLIERS`
  inliers, a :class:`~mirrorgraph.errors.DegenerateGeometryError` says so.
  That test is one-sided: the joints of two upright people of about the same
  height lie on about the same (nearly horizontal) epipolar lines of level
  cameras, and a wrong person's own best essential matrix can fit up to ~90 %
  of the joints (the subject's ~95 %, synthetic rigs with 4 px noise). The
  choice among the people a camera sees is reliable; a camera that does not
  see the subject at all can pass.
"""

from __future__ import annotations

import warnings

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from ..errors import DegenerateGeometryError
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from ..skeletons import Skeleton
from ..geometry import skew
from ..initial.relative import normalised_coordinates, refine_relative_pose, sampson_px

__all__ = ["match_candidates", "match_people", "track_people", "track_labelled",
           "continuity_labels", "subject_track", "track_motion", "tracklets",
           "MATCH_THRESHOLD_PX"]

#: Median Sampson distance (px) above which no candidate of a frame is accepted.
MATCH_THRESHOLD_PX = 12.0

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
#: 10-15 px): at 8 px the subject's track fitted 47 % in cam02 and the camera was
#: refused, at 12 px 71 % (the other person's tracks 32 %); 1.5 % of the size (~10 px)
#: calibrates every camera. Synthetic rigs (4 px noise, people 500-650 px): 8-9.5 px,
#: where a camera seeing only another person's walk is still refused (at 2 %, 10-12
#: px, it was not).
TRACK_INLIER_OF_SIZE = 0.015

#: The best track must have at least this fraction of inliers to be the person.
MIN_TRACK_INLIERS = 0.5

#: Joint pairs (with the reference person) a track needs for its geometry.
MIN_CORRESPONDENCES = 30

#: A track whose candidates fit the chosen geometry (median Sampson distance under
#: :data:`MATCH_THRESHOLD_PX`) in fewer than this fraction of its frames is another
#: person: never chosen, not even where it is a frame's only candidate. (Synthetic
#: rigs, 4 px noise, 5 % outliers: the subject's track fits in 96-99 % of its
#: frames, a bystander's in 0-7 %; a track switch leaves each part about half.)
MIN_TRACK_AGREEMENT = 0.25

#: Tracks: a detection farther than this (mean joint distance, px) from every
#: track's last position starts a new track.
TRACK_GATE_PX = 150.0

#: Tracks: each frame a track has gone unseen adds this many px to a detection's
#: distance from it (a person seen in the last frame is preferred to a track that
#: went missing: on Pose2Sim's Demo_MultiPerson, brief false detections left tracks
#: that took over the moving person's identity).
TRACK_AGE_PX = 20.0

#: Tracks unseen for more frames than this end.
TRACK_MAX_GAP = 30


def track_people(candidates: list[np.ndarray], joints: np.ndarray, min_confidence: float,
                 flip: np.ndarray | None = None) -> list[np.ndarray]:
    """Link detections into tracks frame to frame: :func:`track_labelled`'s track ids."""
    return track_labelled(candidates, joints, min_confidence, flip)[0]


def track_labelled(candidates: list[np.ndarray], joints: np.ndarray, min_confidence: float,
                   flip: np.ndarray | None = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
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

    Returns:
        ``T`` int arrays ``(P_t,)``: the track id of each detection, and ``T`` bool
        arrays ``(P_t,)``: the detection's labels are swapped relative to its track's
        (the labelling of the track's first detection, carried on by continuity;
        always ``False`` without ``flip``).
    """
    last: dict[int, np.ndarray] = {}
    seen_at: dict[int, int] = {}
    ids, swaps, next_id = [], [], 0
    for t, people in enumerate(candidates):
        p = np.asarray(people, dtype=float)
        lab = np.full(len(p), -1)
        swapped = np.zeros(len(p), dtype=int)
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
                      flip: np.ndarray) -> np.ndarray:
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

    Returns:
        ``(T,)`` bool: swap the frame's labels (``person[t, flip]``) to follow the
        stretch's labelling.
    """
    T, J = person.shape[:2]
    present = (np.asarray(person[..., 2]) >= min_confidence).any(axis=1)
    people = [person[t][None] if present[t] else np.zeros((0, J, 3)) for t in range(T)]
    ids, swaps = track_labelled(people, joints, min_confidence, flip)
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


def inlier_threshold_px(person: np.ndarray, joints: np.ndarray, min_confidence: float) -> float:
    """The inlier threshold (px) of :func:`match_candidates` for a reference person
    ``(T, J, 3)``: :data:`TRACK_INLIER_PX`, or :data:`TRACK_INLIER_OF_SIZE` of the
    person's size if larger (the median over frames of the larger side of the box of
    their confident ``joints``)."""
    xy = np.where(person[:, joints, 2:3] >= min_confidence, person[:, joints, :2], np.nan)
    ok = np.count_nonzero(np.isfinite(xy).all(-1), axis=1) >= 2
    if not ok.any():
        return TRACK_INLIER_PX
    side = np.nanmax(np.nanmax(xy[ok], axis=1) - np.nanmin(xy[ok], axis=1), axis=1)
    return float(max(TRACK_INLIER_PX, TRACK_INLIER_OF_SIZE * np.median(side)))


def _track_geometry(xa: np.ndarray, xb: np.ndarray, f: float, seed: int,
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


def _row_medians(E: np.ndarray, xa: np.ndarray, xb: np.ndarray, seen: np.ndarray, f: float
                 ) -> np.ndarray:
    """``(M,)`` median absolute Sampson distance (px) of each candidate's joints ``(M, k, 2)``
    (normalised) under ``E``; ``inf`` where fewer than 4 joints are ``seen`` ``(M, k)``."""
    d = np.full(seen.shape, np.nan)
    d[seen] = np.abs(sampson_px(E, xa[seen], xb[seen], f))
    out = np.full(len(seen), np.inf)
    enough = np.count_nonzero(seen, axis=1) >= 4
    out[enough] = np.nanmedian(d[enough], axis=1)
    return out


def _group_bits(E: np.ndarray, xa: np.ndarray, xb: np.ndarray, seen: np.ndarray,
                rel: np.ndarray, group: np.ndarray, f: float,
                inlier_px: float = TRACK_INLIER_PX) -> np.ndarray:
    """Per group, whether its detections fit ``E`` better with their relative labelling
    ``rel`` inverted: the labelling under which more of the group's joints lie within
    :data:`TRACK_INLIER_PX` (one decision a group, never frame by frame).

    Args:
        E: essential matrix; xa ``(M, k, 2)``, xb ``(2, M, k, 2)`` (as labelled, swapped),
            seen ``(2, M, k)``: as :func:`_labelled_geometry`.
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


def _labelled_geometry(xa: np.ndarray, xb: np.ndarray, seen: np.ndarray, rel: np.ndarray,
                       group: np.ndarray, f: float, seed: int,
                       inlier_px: float = TRACK_INLIER_PX
                       ) -> tuple[np.ndarray | None, float, np.ndarray]:
    """One track's epipolar geometry with the reference person, its detections taken in
    the labelling continuity gives them.

    A detector swaps a turning person's left and right labels in one camera and not
    in another, frame by frame; a swapped frame's limbs are outliers to the true
    geometry. Tracking reads every swap against the track's own labelling (and the
    reference person's against theirs, :func:`track_labelled`), which leaves one
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
        E0, frac0 = _track_geometry(xa[use], xb[lab, rows][use], f, seed, inlier_px)
        if E0 is None:
            continue
        bits = _group_bits(E0, xa, xb, seen, rel, group, f, inlier_px)
        E, frac = E0, frac0
        if np.any(bits != start):               # another answer for some group: again
            lab = (rel ^ bits[group]).astype(int)
            use = seen[lab, rows]
            E, frac = _track_geometry(xa[use], xb[lab, rows][use], f, seed, inlier_px)
        if E is not None and frac > best[1]:
            best = (E, frac, bits)
    return best


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


def _other_people(track: np.ndarray, score: np.ndarray, match_px: float = MATCH_THRESHOLD_PX
                  ) -> np.ndarray:
    """``(M,)`` bool: the candidate is on a track that fits the reference person's
    geometry (median Sampson distance under ``match_px``) in fewer than
    :data:`MIN_TRACK_AGREEMENT` of its frames, i.e. another person."""
    ids, where = np.unique(track, return_inverse=True)
    fits = np.bincount(where, weights=score <= match_px, minlength=len(ids))
    agreement = fits / np.bincount(where, minlength=len(ids))
    return agreement[where] < MIN_TRACK_AGREEMENT


def match_candidates(ref_person: np.ndarray, K_ref: np.ndarray, candidates: list[np.ndarray],
                     K: np.ndarray, skeleton: Skeleton, *, min_confidence: float = DEFAULT_MIN_CONFIDENCE,
                     seed: int = 0) -> tuple[np.ndarray, int]:
    """Choose, per frame, which candidate detection is the reference camera's person.

    Steps 1-3 of the module docstring: the tracks and their geometry read a
    detector's left/right swaps (a turning person's, in one camera and not in
    another: :func:`_labelled_geometry`); per frame the candidates are scored as
    labelled, so that a frame whose labels disagree with the reference person's is
    not kept.

    Args:
        ref_person: ``(T, J, 3)`` the person in the reference camera (undistorted px),
            on this camera's frames.
        K_ref, K: ``(3, 3)`` intrinsics of the reference and of this camera.
        candidates: ``T`` arrays ``(P_t, J, 3)``: this camera's candidates per frame
            (every detection, or, with mirrors, those that pair with a reflection).
        skeleton: the layout (its calibration joints are compared, its ``flip``
            swaps the labels).
        min_confidence: joints below it are ignored.
        seed: OpenCV's RANSAC seed.

    Returns:
        ``(T,)`` int: the index of the chosen candidate per frame (-1: none; where
        no candidate fits and a frame has several, none is guessed; a frame's only
        candidate is kept unless its track is another person's), and the number of
        frames where the choice differs from the most confident candidate.

    Raises:
        DegenerateGeometryError: no track can be matched: too few joints seen in
            both cameras to estimate the epipolar geometry, or no track's joints
            fit one (fewer than :data:`MIN_TRACK_INLIERS` of them within
            :func:`inlier_threshold_px`).
    """
    T, J = ref_person.shape[:2]
    joints = skeleton.calibration_joints
    flip = np.asarray(skeleton.flip)
    chosen = np.full(T, -1)
    rows, cands, refs = [], [], []
    for t, people in enumerate(candidates):
        p = np.asarray(people, dtype=float).reshape(-1, J, 3)
        if len(p) == 0:
            continue
        chosen[t] = int(np.argmax(np.nan_to_num(p[:, joints, 2]).sum(1)))
        rows += [(t, i) for i in range(len(p))]
        cands.append(p)
        refs.append(np.repeat(ref_person[t][None], len(p), axis=0))
    best_conf = chosen.copy()
    if not rows:
        return chosen, 0
    rows = np.asarray(rows)
    A = np.concatenate(refs)[:, joints]                               # (M, k, 3)
    C = np.concatenate(cands)
    B = np.stack([C[:, joints], C[:, flip][:, joints]])               # (2, M, k, 3)
    ok_a = (A[..., 2] >= min_confidence) & np.isfinite(A[..., :2]).all(-1)
    seen = ok_a[None] & (B[..., 2] >= min_confidence) & np.isfinite(B[..., :2]).all(-1)
    if np.count_nonzero(seen[0]) < MIN_CORRESPONDENCES:
        raise DegenerateGeometryError(
            f"too few joints ({np.count_nonzero(seen[0])}) seen at once with the reference "
            "camera's person to tell which detection is that person")
    f = 0.5 * (K_ref[0, 0] + K[0, 0])
    xa_all = np.full(A.shape[:-1] + (2,), np.nan)
    xb_all = np.full(B.shape[:-1] + (2,), np.nan)
    xa_all[ok_a] = normalised_coordinates(np.asarray(K_ref, float), A[..., :2][ok_a])
    for lab in range(2):
        xb_all[lab][seen[lab]] = normalised_coordinates(np.asarray(K, float),
                                                        B[lab][..., :2][seen[lab]])
    ids, own = track_labelled(candidates, joints, min_confidence, flip)
    track, own = np.concatenate(ids), np.concatenate(own)
    ref_swap = continuity_labels(ref_person, joints, min_confidence, flip)
    ref_ids, _ = track_labelled([ref_person[t][None] if (ref_person[t, :, 2] >= min_confidence).any()
                                 else np.zeros((0, J, 3)) for t in range(T)],
                                joints, min_confidence, flip)
    ref_track = np.array([i[0] if len(i) else -1 for i in ref_ids])
    rel = own ^ ref_swap[rows[:, 0]]          # up to one answer a (track, reference stretch)
    _, group = np.unique(np.stack([track, ref_track[rows[:, 0]]], 1), axis=0,
                         return_inverse=True)
    group = group.ravel()
    inlier_px = inlier_threshold_px(ref_person, joints, min_confidence)
    match_px = MATCH_THRESHOLD_PX * inlier_px / TRACK_INLIER_PX
    def geometry_of(unit: np.ndarray) -> dict[int, tuple[np.ndarray, float, float]]:
        """unit id -> (E, fraction of inliers, fit) of every unit (track or piece) with
        enough correspondences."""
        _, grp = np.unique(np.stack([unit, ref_track[rows[:, 0]]], 1), axis=0,
                           return_inverse=True)
        out = {}
        for k in np.unique(unit):
            mine = unit == k
            n = np.count_nonzero(seen[0][mine])
            if n < MIN_CORRESPONDENCES:
                continue
            _, g = np.unique(grp.ravel()[mine], return_inverse=True)
            E, frac, _ = _labelled_geometry(xa_all[mine], xb_all[:, mine], seen[:, mine],
                                            rel[mine], g.ravel(), f, seed, inlier_px)
            if E is not None:
                out[int(k)] = (E, frac, frac * np.sqrt(n))
        return out

    def best_of(fits: dict) -> tuple[np.ndarray | None, float]:
        if not fits:
            return None, 0.0
        E, frac, _ = max(fits.values(), key=lambda v: v[2])     # first of equal fits
        return E, frac

    tried = sum(np.count_nonzero(seen[0][track == k]) >= MIN_CORRESPONDENCES
                for k in np.unique(track))
    best_E, best_frac = best_of(geometry_of(track))
    whole_frac = best_frac
    if tried and best_frac < MIN_TRACK_INLIERS:
        # no whole track fits: its pieces between the tracker's left/right swaps do
        # (see tracklets)
        piece = tracklets(track, own, rows[:, 0])
        E, frac = best_of(geometry_of(piece))
        if E is not None and frac >= MIN_TRACK_INLIERS:
            best_E, best_frac = E, frac
            _, group = np.unique(np.stack([piece, ref_track[rows[:, 0]]], 1), axis=0,
                                 return_inverse=True)
            group = group.ravel()
    if best_E is None or best_frac < MIN_TRACK_INLIERS:
        raise DegenerateGeometryError(
            f"none of its {tried} tracked people is consistent with the reference camera's "
            f"person (best: {100 * whole_frac:.0f} % of the joints within "
            f"{inlier_px:.0f} px of an epipolar geometry, left/right labels read by "
            f"continuity, {100 * MIN_TRACK_INLIERS:.0f} % needed; no piece of a track "
            "between its left/right swaps either)" if tried else
            f"no tracked person shares {MIN_CORRESPONDENCES} joints with the reference "
            "camera's person")
    # frame by frame as labelled, and a detection whose labels disagree with the
    # reference person's (by its track's answer) is not kept, not even as a frame's
    # only candidate: relabelled, such frames put Demo_SinglePerson's cameras 0.1-0.8
    # deg further from Qualisys (a detector that swaps a person seen from behind places
    # the joints wrong, not only their names); kept as they are, they pair the wrong
    # sides
    disagree = rel ^ _group_bits(best_E, xa_all, xb_all, seen, rel, group, f, inlier_px)[group]
    score = _row_medians(best_E, xa_all, xb_all[0], seen[0], f)
    other = _other_people(track, score, match_px)
    chosen[np.unique(rows[other, 0])] = -1          # re-decided below, without them
    keep = np.flatnonzero(~other)
    order = keep[np.lexsort((score[keep], rows[keep, 0]))]
    first = np.ones(len(order), bool)
    first[1:] = rows[order][1:, 0] != rows[order][:-1, 0]
    for k in order[first]:                   # per frame the best candidate (a handful)
        t, i = rows[k]
        if not np.isfinite(score[k]) or score[k] > match_px:
            if len(candidates[t]) == 1 and not disagree[k]:   # a frame's only candidate
                chosen[t] = i                   # is kept, but nobody is guessed among several
            else:
                chosen[t] = -1
            continue
        chosen[t] = i
    changed = int(np.count_nonzero((chosen >= 0) & (chosen != best_conf)))
    return chosen, changed


def match_people(ref_person: np.ndarray, K_ref: np.ndarray, candidates: list[np.ndarray],
                 K: np.ndarray, skeleton: Skeleton, *, min_confidence: float = DEFAULT_MIN_CONFIDENCE,
                 seed: int = 0) -> tuple[np.ndarray, int]:
    """Choose, per frame, the candidate detection that is the reference camera's person.

    :func:`match_candidates`, returning the detections themselves.

    Returns:
        ``(T, J, 3)`` the chosen person (NaN / confidence 0 where none fits), and the
        number of frames where the choice differs from the most confident detection.

    Raises:
        DegenerateGeometryError: no track can be matched (:func:`match_candidates`).
    """
    T, J = ref_person.shape[:2]
    chosen, changed = match_candidates(ref_person, K_ref, candidates, K, skeleton,
                                       min_confidence=min_confidence, seed=seed)
    out = np.full((T, J, 3), np.nan)
    out[..., 2] = 0.0
    for t in np.flatnonzero(chosen >= 0):
        out[t] = np.asarray(candidates[t], dtype=float).reshape(-1, J, 3)[chosen[t]]
    return out, changed
