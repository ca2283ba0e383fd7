"""Every person before one mirror paired with their own reflection, and followed over time.

Where several people stand before a mirror (a gym, a dance studio) each of them pairs
with their own reflection; :func:`~.pairing.pair_detections` keeps one pair a frame,
:func:`pair_people` keeps them all (image pixels throughout):

1. **The mirror's epipole** from every candidate pair (:func:`~.pairing.pair_candidates`);
   of a few RANSAC runs the epipole that pairs the most detections is kept.
2. **Each person with their own reflection, per frame**: a bipartite assignment of
   persons to reflections minimising the summed epipolar distances
   (:func:`scipy.optimize.linear_sum_assignment`), or scored over time
   (``pair_over_time``: :func:`track_detections`, :func:`pair_track_scores`,
   :func:`partners_only`).
3. **Tracks**: pairs linked frame to frame to tracks last seen at most ``max_gap``
   frames before, by an assignment on the joints' displacement relative to the
   track's size.
4. **Fragments**: a track that continues another is merged (:func:`merge_fragments`);
   tracks of fewer than ``min_frames`` frames are left out.

The people come out side by side in one :class:`~mirrorgraph.keypoints.PairedKeypoints`
of the layout :func:`~mirrorgraph.skeletons.people_skeleton` (person ``p``'s joint ``j``
is column ``p * J + j``), ordered by their first frame, so that the one graph holds each
person's own joints and bone lengths (:func:`split_people` takes them apart again).
Accuracy: ``bench/RESULTS_multiperson.md``; each step in full: ``docs/internals.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..errors import DegenerateGeometryError
from ..keypoints import PairedKeypoints, RawDetections
from ..skeletons import Skeleton, people_skeleton
from .pair_candidates import PairingOptions, masked
from .pairing import PairCandidates, pair_candidates

__all__ = ["PeopleOptions", "PeoplePairing", "assign_pairs", "merge_fragments", "pair_people",
           "pair_track_scores", "partners_only", "split_people", "track_detections", "track_pairs"]


@dataclass(frozen=True)
class PeopleOptions:
    """Options of :func:`pair_people` beyond the pairing's own.

    Attributes:
        max_detections: detections considered per frame (most confident first): at
            least twice the people before the mirror.
        ransac_candidates: candidate pairs the epipole's RANSAC samples its lines from
            (frames evenly spread until about this many).
        max_gap: frames a track may go unseen and still continue (frame numbers).
        gate: largest displacement, relative to the person's size in the image, of a
            pair continuing a track.
        gate_frame: largest relative displacement a frame (a track unseen for ``g``
            frames continues within ``min(gate, gate_frame (1 + g))``): people who
            come near each other are not taken for one another.
        merge_gap, merge_gate: a track that starts at most ``merge_gap`` frames after
            another ended, within ``merge_gate`` of it, continues it
            (:func:`merge_fragments`).
        min_frames: fewest frames a track needs to be kept.
        pair_over_time: each candidate pair scored over time (:func:`pair_track_scores`:
            every detection tracked on its own, the median over the frames two tracks
            share) instead of in its frame alone.
        min_common_frames: fewest frames two tracks share for their score over time.
        epipole_attempts: RANSAC runs for the epipole (seeds ``seed + 7919 k``); the one
            whose assignment (step 2) pairs the most detections is kept.
    """

    max_detections: int = 24
    ransac_candidates: int = 8000
    max_gap: int = 60
    gate: float = 0.35
    gate_frame: float = 0.04
    merge_gap: int = 150
    merge_gate: float = 0.6
    min_frames: int = 10
    pair_over_time: bool = True
    min_common_frames: int = 5
    epipole_attempts: int = 4


@dataclass
class PeoplePairing:
    """Every person with their reflection, tracked (:func:`pair_people`).

    Attributes:
        paired: person and reflection of every kept track side by side, layout
            :func:`~mirrorgraph.skeletons.people_skeleton` of ``base`` (``(T, P J, 3)``).
        base: one person's layout.
        detections: ``(T, P, 2)`` int, the person's and the reflection's detection
            index in ``raw.people[t]`` of each kept track (-1: not seen).
        epipole: ``(3,)`` homogeneous epipole, pixels.
        pairs_per_frame: ``(T,)`` pairs found per frame (before tracking).
        tracks_found: tracks before leaving out the short ones.
        pairs_left_out: pairs of the tracks left out.
    """

    paired: PairedKeypoints
    base: Skeleton
    detections: np.ndarray
    epipole: np.ndarray
    pairs_per_frame: np.ndarray
    tracks_found: int
    pairs_left_out: int
    notes: list[str] = field(default_factory=list)

    @property
    def num_people(self) -> int:
        """``P``, the people kept."""
        return int(self.detections.shape[1])


def pair_track_scores(cands: PairCandidates, tracks: np.ndarray, min_frames: int
                      ) -> np.ndarray:
    """``(M,)`` each candidate's score over time: the median, over every frame where the
    two detections' tracks are both seen, of that pair of tracks' epipolar distance (its
    own frame's where the two tracks share fewer than ``min_frames`` frames).

    Args:
        cands: :func:`~.pairing.pair_candidates` with one epipole.
        tracks: ``(M, 2)`` the track of each candidate's two detections
            (:func:`track_detections`).
        min_frames: fewest frames in common for the median to replace the frame's score.
    """
    score = np.asarray(cands.score[0], dtype=float)
    lo, hi = tracks.min(1), tracks.max(1)
    key = lo.astype(np.int64) * (int(hi.max(initial=0)) + 1) + hi
    groups, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    order = np.lexsort((score, inverse))                 # by group, then score
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    s = score[order]
    lower = s[starts + (counts - 1) // 2]
    upper = s[starts + counts // 2]
    median = 0.5 * (lower + upper) if np.isfinite(s).all() else np.where(
        np.isfinite(lower) & np.isfinite(upper), 0.5 * (lower + upper), np.inf)
    return np.where(counts[inverse] >= min_frames, median[inverse], score)


def assign_pairs(cands: PairCandidates, threshold_px: float,
                 scores: np.ndarray | None = None, frame_limit: float = 3.0
                 ) -> list[np.ndarray]:
    """Per frame, the candidate of each person's pair (step 2 of the module docstring).

    Args:
        cands: :func:`~.pairing.pair_candidates` with one epipole.
        threshold_px: the largest median epipolar distance of a pair.
        scores: ``(M,)`` the candidates' scores (default: their own frame's,
            ``cands.score``; :func:`pair_track_scores`: over time); a candidate's own
            frame's score must then stay under ``frame_limit`` thresholds.
        frame_limit: see ``scores``.

    Returns:
        ``T`` int arrays of candidate indices into ``cands``, one per pair kept.
    """
    T = cands.num_frames
    out = [np.zeros(0, dtype=int) for _ in range(T)]
    own = np.asarray(cands.score[0], dtype=float)
    if scores is None:
        scores = own
        ok = cands.valid[0] & (own < threshold_px)
    else:
        ok = (scores < threshold_px) & (own < frame_limit * threshold_px)
    ok = np.flatnonzero(ok)
    if len(ok) == 0:
        return out
    person, refl = cands.roles(0)
    order = ok[np.argsort(cands.frame[ok], kind="stable")]
    frames = cands.frame[order]
    starts = np.flatnonzero(np.r_[True, frames[1:] != frames[:-1]])
    for s, e in zip(starts, np.r_[starts[1:], len(order)]):
        c = order[s:e]
        p, r, score = person[c], refl[c], scores[c]
        n = int(max(p.max(), r.max())) + 1
        big = 1e6 * (1.0 + float(score.max()))
        cost = np.full((n, n), big)
        cost[p, r] = score
        index = np.full((n, n), -1)
        index[p, r] = c
        rows, cols = linear_sum_assignment(cost)
        keep = cost[rows, cols] < big
        chosen = index[rows[keep], cols[keep]]
        # a detection the person of one pair and the reflection of another: the better
        # pair stays (the assignment treats the two roles as different nodes)
        chosen = chosen[np.argsort(scores[chosen], kind="stable")]
        used: set[int] = set()
        final = []
        for k in chosen:
            a, b = int(person[k]), int(refl[k])
            if a in used or b in used:
                continue
            used.update((a, b))
            final.append(k)
        out[int(frames[s])] = np.array(sorted(final), dtype=int)
    return out


def track_detections(raw: RawDetections, joints: np.ndarray, min_confidence: float,
                     max_gap: int, gate: float, gate_frame: float,
                     flip: np.ndarray | None = None) -> list[np.ndarray]:
    """Every detection followed over time on its own (person or reflection alike), as
    :func:`track_pairs` follows pairs: ``T`` int arrays, the track of each detection of
    ``raw.people[t]``."""
    J = raw.skeleton.num_joints
    dets = [masked(np.asarray(p, dtype=float).reshape(-1, J, 3), min_confidence)[:, joints]
            for p in raw.people]
    return track_pairs(raw.frame_ids, dets, dets, max_gap, gate, gate_frame, flip)


def partners_only(cands: PairCandidates, tracks: np.ndarray, chosen: list[np.ndarray]
                  ) -> list[np.ndarray]:
    """The chosen pairs but those that pair neither detection with its partner.

    A detection's track pairs, over the frames, mostly with one other track (in either
    role): the person's with their reflection's. Where a person's reflection is hidden and another person is
    hidden, the person and the other's reflection may fit the epipole for a while; such a
    pair joins two tracks each of which pairs mostly with another: it is left out.

    Args:
        cands: :func:`~.pairing.pair_candidates` with one epipole.
        tracks: ``(M, 2)`` the tracks of each candidate's detections.
        chosen: :func:`assign_pairs`.
    """
    c = np.concatenate(chosen) if chosen else np.zeros(0, dtype=int)
    if len(c) == 0:
        return chosen
    person, refl = cands.roles(0)
    own_a = np.where(person[c] == cands.ia[c], tracks[c, 0], tracks[c, 1])     # person's
    own_b = np.where(person[c] == cands.ia[c], tracks[c, 1], tracks[c, 0])     # reflection's
    n = int(max(own_a.max(), own_b.max())) + 1
    count = np.zeros((n, n), dtype=np.int64)
    np.add.at(count, (own_a, own_b), 1)
    partner = (count + count.T).argmax(1)            # in either role
    keep = (partner[own_a] == own_b) | (partner[own_b] == own_a)
    kept = set(c[keep].tolist())
    return [np.array([k for k in ch if k in kept], dtype=int) for ch in chosen]


def _pair_keypoints(cands: PairCandidates, c: np.ndarray, flip: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(n, J, 3)`` person and reflection (labels of the real joints) of candidates ``c``,
    as :func:`~.pairing.choose_pairs` lays them out."""
    a, b_own = cands.a[c], cands.b[c][:, flip]
    b_is_mirror = cands.b_is_reflection[0, c][:, None, None]
    mirror_own = np.where(b_is_mirror, b_own, a)
    mirror = np.where(cands.swapped[0, c, None, None], mirror_own, mirror_own[:, flip])
    return np.where(b_is_mirror, a, b_own), mirror


def _view_distance(a: np.ndarray, b: np.ndarray, flip: np.ndarray | None = None
                   ) -> np.ndarray:
    """``(..., )`` median over the joints both show of the pixel distance (inf: none); with
    ``flip`` (the joints' left/right map) the smaller of that and the same with ``b``'s
    left and right swapped: a detector's left/right confusion is no other person."""
    if flip is not None:
        return np.minimum(_view_distance(a, b), _view_distance(a, b[..., flip, :]))
    d = np.linalg.norm(a[..., :2] - b[..., :2], axis=-1)
    d = np.where(np.isfinite(d), d, np.nan)
    seen = np.isfinite(d).any(-1)
    out = np.full(d.shape[:-1], np.inf)
    if seen.any():
        out[seen] = np.nanmedian(d[seen], axis=-1)
    return out


def _size(real: np.ndarray) -> float:
    """A person's size in the image: the diagonal of their joints' box, px."""
    xy = real[..., :2][np.isfinite(real[..., :2]).all(-1)]
    if len(xy) < 2:
        return float("nan")
    return float(np.linalg.norm(xy.max(0) - xy.min(0)))


def track_pairs(frame_ids: np.ndarray, real: list[np.ndarray], mirror: list[np.ndarray],
                max_gap: int, gate: float, gate_frame: float,
                flip: np.ndarray | None = None) -> list[np.ndarray]:
    """Link each frame's pairs into tracks (step 3 of the module docstring).

    Args:
        frame_ids: ``(T,)`` frame numbers.
        real, mirror: ``T`` arrays ``(n_t, J, 3)``: the pairs' person and reflection.
        max_gap: frames a track may go unseen.
        gate: largest relative displacement of a pair continuing a track.
        gate_frame: largest relative displacement a frame: a track unseen for ``g``
            frames continues within ``min(gate, gate_frame (1 + g))``.
        flip: the joints' left/right map: displacements are taken the better way round
            (:func:`_view_distance`).

    Returns:
        ``T`` int arrays ``(n_t,)``: the track of each pair.
    """
    last_real: list[np.ndarray] = []
    last_mirror: list[np.ndarray] = []
    last_frame: list[int] = []
    size: list[float] = []
    out = []
    for t, fid in enumerate(np.asarray(frame_ids, dtype=np.int64)):
        R, M = real[t], mirror[t]
        ids = np.full(len(R), -1, dtype=int)
        live = [k for k in range(len(last_frame)) if fid - last_frame[k] <= max_gap]
        if live and len(R):
            LR = np.stack([last_real[k] for k in live])
            LM = np.stack([last_mirror[k] for k in live])
            s = np.array([size[k] for k in live])
            cost = np.maximum(_view_distance(LR[:, None], R[None], flip),
                              _view_distance(LM[:, None], M[None], flip)) / s[:, None]
            cost = np.where(np.isfinite(cost), cost, 1e9)
            rows, cols = linear_sum_assignment(cost)
            gap = fid - np.array([last_frame[k] for k in live])
            allowed = np.minimum(gate, gate_frame * (1.0 + gap))       # (live,)
            for i, j in zip(rows, cols):
                if cost[i, j] < allowed[i]:
                    ids[j] = live[i]
        for j in range(len(R)):
            if ids[j] < 0:
                ids[j] = len(last_frame)
                last_real.append(R[j].copy())
                last_mirror.append(M[j].copy())
                last_frame.append(int(fid))
                size.append(_size(R[j]))
                continue
            k = ids[j]
            # a joint not seen now keeps its last position
            seen_r = np.isfinite(R[j][:, :2]).all(-1)
            seen_m = np.isfinite(M[j][:, :2]).all(-1)
            last_real[k][seen_r] = R[j][seen_r]
            last_mirror[k][seen_m] = M[j][seen_m]
            last_frame[k] = int(fid)
            new = _size(R[j])
            if np.isfinite(new):
                size[k] = new if not np.isfinite(size[k]) else 0.8 * size[k] + 0.2 * new
        out.append(ids)
    return out


def merge_fragments(frame_ids: np.ndarray, real: list[np.ndarray], mirror: list[np.ndarray],
                    track: list[np.ndarray], max_gap: int, gate: float,
                    flip: np.ndarray | None = None) -> list[np.ndarray]:
    """Join tracks of one person (step 4 of the module docstring).

    A person hidden longer than the tracker's gap, or moving further meanwhile, starts a
    new track; so may a pair whose joints the detector misplaced, and the two tracks then
    take the person's pair in turns. Two tracks that share no frame join where the later
    one's first pair lies within ``gate`` of the earlier one's last pair before it, at most
    ``max_gap`` frames back (the larger of the two views' median joint displacement,
    relative to the person's size); the closest first, each track's start joined once,
    and never two tracks that would then share a frame: two tracks seen in one frame are
    two people.

    Returns:
        ``track`` with the joined tracks renumbered (the earlier one's number).
    """
    fid = np.asarray(frame_ids, dtype=np.int64)
    n = 1 + max((int(ids.max()) for ids in track if len(ids)), default=-1)
    if n < 2:
        return track
    rows: list[list[int]] = [[] for _ in range(n)]
    where: list[list[int]] = [[] for _ in range(n)]
    for t, ids in enumerate(track):
        for j, k in enumerate(ids):
            rows[k].append(t)
            where[k].append(j)
    rows_a = [np.asarray(r, dtype=np.int64) for r in rows]
    cand = []
    for b in range(n):
        if not len(rows_a[b]):
            continue
        t0 = int(rows_a[b][0])
        rb, mb = real[t0][where[b][0]], mirror[t0][where[b][0]]
        for a in range(n):
            if a == b or not len(rows_a[a]):
                continue
            i = int(np.searchsorted(rows_a[a], t0)) - 1
            if i < 0 or fid[t0] - fid[rows_a[a][i]] > max_gap:
                continue
            if np.intersect1d(rows_a[a], rows_a[b], assume_unique=True).size:
                continue
            ta = int(rows_a[a][i])
            ra, ma = real[ta][where[a][i]], mirror[ta][where[a][i]]
            cost = max(float(_view_distance(ra, rb, flip)),
                       float(_view_distance(ma, mb, flip))) / _size(ra)
            if np.isfinite(cost) and cost < gate:
                cand.append((cost, a, b))
    root = np.arange(n)

    def find(k: int) -> int:
        while root[k] != k:
            k = int(root[k])
        return k

    frames = {k: set(rows[k]) for k in range(n)}
    started: set[int] = set()
    for _cost, a, b in sorted(cand):
        ra_, rb_ = find(a), find(b)
        if b in started or ra_ == rb_ or frames[ra_] & frames[rb_]:
            continue
        started.add(b)
        keep, gone = (ra_, rb_) if rows_a[ra_][0] <= rows_a[rb_][0] else (rb_, ra_)
        root[gone] = keep
        frames[keep] |= frames.pop(gone)
    final = np.array([find(k) for k in range(n)])
    return [final[ids] if len(ids) else ids for ids in track]


def pair_people(raw: RawDetections, joints: np.ndarray | None = None,
                options: PairingOptions | None = None,
                people: PeopleOptions | None = None) -> PeoplePairing:
    """Pair every person with their reflection and follow them (the module docstring).

    Args:
        raw: detections per frame (undistorted pixels).
        joints: ``(k,)`` joints judging the pairs and the tracks (default: the calibration
            joints).
        options: the pairing's options (threshold, confidence, joints in common).
        people: :class:`PeopleOptions`.

    Returns:
        :class:`PeoplePairing`.

    Raises:
        InputError: no frame holds two detections.
        DegenerateGeometryError: no epipole, or no track long enough.
    """
    opts = options or PairingOptions()
    pops = people or PeopleOptions()
    sk = raw.skeleton
    joints = sk.calibration_joints if joints is None else np.asarray(joints, dtype=int)
    counts = np.array([len(p) for p in raw.people], dtype=int)
    most = int(min(max(counts.max(initial=0), 2), pops.max_detections))
    per_frame = max(most * (most - 1) // 2, 1)
    frames_with = int(np.count_nonzero(counts >= 2))
    ransac_frames = int(np.clip(pops.ransac_candidates // per_frame, 20,
                                max(frames_with, 20)))
    opts = replace(opts, max_people=max(opts.max_people, most),
                   ransac_frames=min(opts.ransac_frames, ransac_frames))
    # the lines joining two people standing side by side meet near the horizon too: of a
    # few RANSAC runs, the epipole under which most candidates pair (every person's own
    # pair does under the mirror's)
    # the joints' left/right map among themselves (a joint without its partner: itself)
    where = {int(j): i for i, j in enumerate(joints)}
    sub_flip = np.array([where.get(int(sk.flip[j]), i) for i, j in enumerate(joints)])
    det_track = track_detections(raw, joints, opts.min_confidence, pops.max_gap, pops.gate,
                                 pops.gate_frame, sub_flip)
    cands, chosen, best = None, None, (-1, -1)
    for k in range(pops.epipole_attempts):
        found = pair_candidates(raw, 1, joints, replace(opts, seed=opts.seed + 7919 * k))
        pairs = assign_pairs(found, opts.threshold_px)
        score = (sum(len(c) for c in pairs), int(found.valid[0].sum()))
        if score > best:
            cands, chosen, best = found, pairs, score
    if pops.pair_over_time:
        tracks = np.stack([[det_track[f][i] for f, i in zip(cands.frame, cands.ia)],
                           [det_track[f][i] for f, i in zip(cands.frame, cands.ib)]], axis=1)
        chosen = assign_pairs(cands, opts.threshold_px,
                              pair_track_scores(cands, tracks, pops.min_common_frames))
        chosen = partners_only(cands, tracks, chosen)
    flip = sk.flip
    T, J = len(raw.people), sk.num_joints
    real, mirror = [], []
    for c in chosen:
        if len(c):
            r, m = _pair_keypoints(cands, c, flip)
        else:
            r = m = np.zeros((0, J, 3))
        real.append(r)
        mirror.append(m)
    # tracks follow the judging joints only (faces and feet are the least stable)
    track = track_pairs(raw.frame_ids, [r[:, joints] for r in real],
                        [m[:, joints] for m in mirror], pops.max_gap, pops.gate, pops.gate_frame,
                        sub_flip)
    track = merge_fragments(raw.frame_ids, [r[:, joints] for r in real],
                            [m[:, joints] for m in mirror], track, pops.merge_gap,
                            pops.merge_gate, sub_flip)
    n_tracks = 1 + max((int(ids.max()) for ids in track if len(ids)), default=-1)
    frames_of = np.zeros(n_tracks, dtype=int)
    first = np.full(n_tracks, np.iinfo(np.int64).max)
    for t, ids in enumerate(track):
        np.add.at(frames_of, ids, 1)
        first[ids] = np.minimum(first[ids], t)
    kept = np.flatnonzero(frames_of >= pops.min_frames)
    if len(kept) == 0:
        raise DegenerateGeometryError(
            f"{raw.source}: no person is paired with their reflection in {pops.min_frames} "
            f"frames or more ({n_tracks} tracks, the longest {int(frames_of.max(initial=0))} "
            "frames)")
    kept = kept[np.argsort(first[kept], kind="stable")]
    slot = np.full(n_tracks, -1)
    slot[kept] = np.arange(len(kept))
    P = len(kept)
    R = np.full((T, P, J, 3), np.nan)
    R[..., 2] = 0.0
    M = R.copy()
    det = np.full((T, P, 2), -1, dtype=int)
    person_idx, refl_idx = cands.roles(0)
    lr_fixes = 0
    for t, (ids, c) in enumerate(zip(track, chosen)):
        if not len(ids):
            continue
        s = slot[ids]
        k = s >= 0
        R[t, s[k]] = real[t][k]
        M[t, s[k]] = mirror[t][k]
        det[t, s[k], 0] = person_idx[c[k]]
        det[t, s[k], 1] = refl_idx[c[k]]
        lr_fixes += int(np.count_nonzero(cands.swapped[0, c[k]]))
    left_out = int(frames_of[frames_of < pops.min_frames].sum())
    psk = people_skeleton(sk, P)
    paired = PairedKeypoints(skeleton=psk, frame_ids=np.asarray(raw.frame_ids),
                             real=R.reshape(T, P * J, 3), mirror=M.reshape(T, P * J, 3),
                             source=raw.source, format=raw.format, image_size=raw.image_size,
                             fps=raw.fps, lr_fixes=lr_fixes, frames_read=T)
    notes = []
    if left_out:
        notes.append(f"{n_tracks - P} short tracks ({left_out} pairs) under "
                     f"{pops.min_frames} frames left out")
    return PeoplePairing(paired=paired, base=sk, detections=det, epipole=cands.epipoles[0],
                         pairs_per_frame=np.array([len(c) for c in chosen]),
                         tracks_found=n_tracks, pairs_left_out=left_out, notes=notes)


def split_people(values: np.ndarray, count: int) -> np.ndarray:
    """``(T, P J, ...)`` arrays of the layout of several people to ``(P, T, J, ...)``."""
    v = np.asarray(values)
    T, PJ = v.shape[:2]
    return np.moveaxis(v.reshape(T, count, PJ // count, *v.shape[2:]), 1, 0)
