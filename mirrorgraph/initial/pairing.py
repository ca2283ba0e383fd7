"""Pairing of the person and their reflection, frame by frame.

A detector gives, per frame, an unordered list of people: the person, their reflection,
sometimes one of them, sometimes bystanders. This module decides which two detections are
the person and the reflection, which is the reflection, and flips the reflection's
labels (:attr:`~mirrorgraph.skeletons.Skeleton.flip`). It relies on one fact of mirror
geometry, independent of the intrinsics: every joint, its reflection and the epipole
``e`` are collinear (:mod:`mirrorgraph.geometry`). Coordinates are image pixels.

1. **Candidates**: every unordered pair of a frame's detections (at most ``max_people``).
2. **Epipole**: reflective RANSAC
   (:func:`mirrorgraph.initial.estimators.estimate_epipole`) over the candidates' lines.
3. **Choice per frame**: both labelings of each candidate's reflection scored by the
   median epipolar distance; the best under the threshold kept.
4. **Which is the reflection**: for a mirror the camera faces (``n_z > 0``) the
   reflection lies between the joint and the epipole.

:func:`pair_detections` (one mirror) and :func:`pair_reflections` (several) do all four
steps; they are :func:`pair_candidates` followed by :func:`choose_pairs`, split so that a
caller that follows one person over time (:mod:`mirrorgraph.rigs.observations`) decides
who the person is per frame (:func:`paired_people`). With several mirrors the set of
epipoles that best explains the frames is kept (:func:`_consistent_mirrors`).

Modules: :mod:`.pair_candidates` (steps 1 and 4, :class:`~.pair_candidates.PairingOptions`),
:mod:`.left_right` (the detector's left/right confusions), :mod:`.pair_scores` (every
frame's score against a mirror found). Details: ``docs/internals.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence
from itertools import combinations

import numpy as np

from ..errors import DegenerateGeometryError
from ..keypoints import PairedKeypoints, RawDetections
from .left_right import is_swap
from .pair_candidates import (Candidates, PairingOptions, b_is_reflection_of, candidates,
                              epipole_either_labelling, masked, median_distance, spread_subset)

__all__ = ["MirrorPairing", "PairCandidates", "choose_pairs", "pair_candidates",
           "pair_detections", "pair_frame_with_epipole", "pair_reflections", "paired_people"]

@dataclass
class MirrorPairing:
    """Person and reflections in several mirrors, per frame (:func:`pair_reflections`).

    Attributes:
        real: ``(T, J, 3)`` the person (x px, y px, confidence; NaN / 0 where unknown).
        reflections: one ``(T, J, 3)`` per mirror, labels flipped to the real joints
            they image, in the order of :attr:`epipoles`.
        epipoles: ``(3,)`` homogeneous epipole of each mirror (pixels).
        lr_fixes: frames (summed over mirrors) whose reflection's labels were
            found swapped by the detector.
    """

    real: np.ndarray
    reflections: list[np.ndarray]
    epipoles: list[np.ndarray]
    lr_fixes: int = 0



@dataclass
class PairCandidates:
    """Every candidate (person, reflection) pair of a camera, scored against each mirror
    (:func:`pair_candidates`).

    A candidate is an unordered pair of detections of one frame; ``K`` mirrors,
    ``M`` candidates, ``T`` frames, ``J`` joints.

    Attributes:
        frame: ``(M,)`` frame index (into ``raw.people``).
        ia, ib: ``(M,)`` the two detections' indices in their frame's list.
        a: ``(M, J, 3)`` detection ``ia`` (x px, y px, confidence; joints below the
            confidence threshold NaN / 0).
        b: ``(M, J, 3)`` detection ``ib``, labels flipped (as if it were the reflection).
        epipoles: ``K`` homogeneous epipoles ``(3,)``, pixels.
        score: ``(K, M)`` median epipolar distance (px) of the better labelling of
            the reflection (inf: too few joints in common).
        swapped: ``(K, M)`` the better labelling is the detector's own (it
            confused the reflection's left and right).
        valid: ``(K, M)`` the pair fits the mirror: ``score`` under the threshold.
        b_is_reflection: ``(K, M)`` in a valid pair, ``ib`` (not ``ia``) is the
            reflection (:func:`b_is_reflection_of`); False where not valid.
        num_frames: ``T``.
    """

    frame: np.ndarray
    ia: np.ndarray
    ib: np.ndarray
    a: np.ndarray
    b: np.ndarray
    epipoles: list[np.ndarray]
    score: np.ndarray
    swapped: np.ndarray
    valid: np.ndarray
    b_is_reflection: np.ndarray
    num_frames: int

    def roles(self, mirror: int) -> tuple[np.ndarray, np.ndarray]:
        """``(M,)`` detection index of the person and of the reflection of each
        candidate under a mirror (meaningful where :attr:`valid`)."""
        refl_b = self.b_is_reflection[mirror]
        return np.where(refl_b, self.ia, self.ib), np.where(refl_b, self.ib, self.ia)


#: Epipoles searched beyond the number of mirrors, for :func:`_consistent_mirrors`.
EXTRA_EPIPOLES = 2


@dataclass
class _Epipole:
    e: np.ndarray          # (3,) homogeneous, pixels
    score: np.ndarray      # (M,) median epipolar distance of the better labelling
    swapped: np.ndarray    # (M,) the better labelling is the detector's own
    valid: np.ndarray      # (M,) score under the threshold
    b_refl: np.ndarray     # (M,) in a valid pair, b is the reflection


def _score_epipole(e: np.ndarray, cand: Candidates, joints: np.ndarray, flip: np.ndarray,
                   opts: PairingOptions) -> _Epipole:
    """Every candidate scored against one epipole (step 3 and 4 of the module docstring)."""
    flipped = median_distance(e, cand.a, cand.b, joints, opts.min_joints)
    swapped_score = median_distance(e, cand.a, cand.b[:, flip], joints, opts.min_joints)
    swapped = is_swap(flipped, swapped_score, opts.threshold_px)
    score = np.where(swapped, swapped_score, flipped)
    ok = score < opts.threshold_px
    b_refl = np.zeros(len(ok), dtype=bool)
    b_label = np.where(swapped[ok, None, None], cand.b[ok][:, flip], cand.b[ok])
    b_refl[ok] = b_is_reflection_of(e, cand.a[ok][:, joints], b_label[:, joints])
    return _Epipole(e, score, swapped, ok, b_refl)


def _find_epipoles(cand: Candidates, num_mirrors: int, joints: np.ndarray, flip: np.ndarray,
                   opts: PairingOptions, source: str) -> list[_Epipole]:
    """Sequential RANSAC: the epipole explaining most candidates, then the next among
    those it does not explain, ... ``num_mirrors`` of them (errors naming ``source``),
    then up to :data:`EXTRA_EPIPOLES` more where they can be found."""
    remaining = np.ones(len(cand.frame), dtype=bool)
    found = []
    for m in range(num_mirrors + (EXTRA_EPIPOLES if num_mirrors > 1 else 0)):
        needed = m < num_mirrors
        pool = np.flatnonzero(remaining)
        if not needed and len(pool) == 0:
            break
        sub = pool[spread_subset(cand.frame[pool], opts.ransac_frames)]
        try:
            e = epipole_either_labelling(cand.a[sub], cand.b[sub], joints, flip, opts,
                                         opts.seed + m)
        except DegenerateGeometryError as exc:
            if not needed:
                break
            what = ("cannot pair person and reflection" if num_mirrors == 1
                    else f"cannot find mirror {m + 1} of {num_mirrors}")
            raise DegenerateGeometryError(f"{source}: {what}: {exc}") from None
        ep = _score_epipole(e, cand, joints, flip, opts)
        if not ep.valid.any():
            if not needed:
                break
            raise DegenerateGeometryError(
                f"{source}: no frame has a pair of detections consistent with "
                + ("one mirror" if num_mirrors == 1 else f"mirror {m + 1} of {num_mirrors}"))
        remaining &= ~ep.valid
        found.append(ep)
    return found


def _consistency(cand: Candidates, epipoles: list[_Epipole]) -> int:
    """How well a set of epipoles explains the frames as people and their reflections:
    summed over frames, the largest number of mirrors in which one detection is the
    person (the one farther from the epipole) of a valid pair while it is the
    reflection of none."""
    T = int(cand.frame.max()) + 1
    P = 1 + max(int(cand.ia.max()), int(cand.ib.max()))
    person = np.zeros((T, P), dtype=int)
    reflection = np.zeros((T, P), dtype=bool)
    for ep in epipoles:
        ok = ep.valid
        p = np.where(ep.b_refl, cand.ia, cand.ib)[ok]
        r = np.where(ep.b_refl, cand.ib, cand.ia)[ok]
        mark = np.zeros((T, P), dtype=bool)
        mark[cand.frame[ok], p] = True
        person += mark
        reflection[cand.frame[ok], r] = True
    return int(np.where(reflection, 0, person).max(1).sum())


def _consistent_mirrors(cand: Candidates, found: list[_Epipole], num_mirrors: int
                        ) -> list[_Epipole]:
    """The ``num_mirrors`` epipoles among those found that are most consistent
    (:func:`_consistency`); the first ones found unless another set is strictly better.

    Why: RANSAC keeps the epipole explaining most candidate pairs, and two
    mirrors meeting at a vertical edge offer a false one. The lines joining
    two reflections (of one person in both mirrors, or of two people of about
    the same size) are all nearly horizontal, and a far epipole on the horizon
    explains them; with a bystander their pairs outnumber each true mirror's.
    Under such an epipole the real people pair with nothing, so a set holding it
    explains fewer frames as a person with a reflection in each mirror.
    """
    if len(found) <= num_mirrors:
        return found
    best, best_score = list(range(num_mirrors)), _consistency(cand, found[:num_mirrors])
    for subset in combinations(range(len(found)), num_mirrors):
        score = _consistency(cand, [found[i] for i in subset])
        if score > best_score:
            best, best_score = list(subset), score
    return [found[i] for i in best]


def pair_candidates(raw: RawDetections, num_mirrors: int, joints: np.ndarray | None = None,
                    options: PairingOptions | None = None) -> PairCandidates:
    """Find the mirrors' epipoles and score every candidate pair of every frame against them.

    Steps 1, 2 and the scoring of step 3 of the module docstring, once per
    mirror: the epipole of the mirror explaining most candidate pairs is found by
    RANSAC, the pairs it explains are set aside, and the next mirror's epipole
    is searched among the rest (two reflections of the person, or a reflection
    and a double reflection, are not related by a reflection: their lines meet
    in no common point). With several mirrors :data:`EXTRA_EPIPOLES` more are
    searched and the set that best explains the frames as people with their
    reflections is kept (:func:`_consistent_mirrors`). Every candidate is then
    scored against every epipole; nothing is chosen yet: with several people in
    front of a mirror each of them pairs with their own reflection, and the
    choice among those needs more than one frame (:func:`choose_pairs` with
    ``person``).

    Args:
        raw: detections per frame (undistorted pixels).
        num_mirrors: mirrors the camera sees (>= 1).
        joints: joints judging the pairs (default: the calibration joints).
        options: :class:`PairingOptions`.

    Raises:
        InputError: no frame holds two people.
        DegenerateGeometryError: a mirror's epipole cannot be found, or no pair fits it.
    """
    opts = options or PairingOptions()
    sk = raw.skeleton
    joints = sk.calibration_joints if joints is None else np.asarray(joints, dtype=int)
    cand = candidates(raw, opts)
    found = _find_epipoles(cand, num_mirrors, joints, sk.flip, opts, str(raw.source))
    chosen = _consistent_mirrors(cand, found, num_mirrors)
    return _scored_candidates(cand, chosen, len(raw.people))


def _scored_candidates(cand: Candidates, epipoles: list, num_frames: int) -> PairCandidates:
    """The candidate pairs with their scores against each of ``epipoles`` (the records
    :func:`_score_epipole` returns), as :func:`choose_pairs` takes them."""
    return PairCandidates(frame=cand.frame, ia=cand.ia, ib=cand.ib, a=cand.a, b=cand.b,
                          epipoles=[ep.e for ep in epipoles],
                          score=np.array([ep.score for ep in epipoles]),
                          swapped=np.array([ep.swapped for ep in epipoles]),
                          valid=np.array([ep.valid for ep in epipoles]),
                          b_is_reflection=np.array([ep.b_refl for ep in epipoles]),
                          num_frames=num_frames)


def pair_with_epipoles(raw: RawDetections, epipoles: Sequence[np.ndarray],
                       joints: np.ndarray | None = None, options: PairingOptions | None = None
                       ) -> MirrorPairing:
    """Pair person and reflection(s) against epipoles already known (step 3 and 4 of the
    module docstring, no RANSAC): what a live run does frame by frame once its mirror
    is estimated (:mod:`mirrorgraph.pipelines.live`).

    Args:
        raw: detections (undistorted pixels); frames holding fewer than two people stay
            unpaired.
        epipoles: ``(3,)`` homogeneous epipole of each mirror, pixels.
        joints: joints judging the pairs (default: the calibration joints).
        options: :class:`PairingOptions`.

    Returns:
        :class:`MirrorPairing` over the frames of ``raw`` (unpaired frames: NaN / 0).
    """
    opts = options or PairingOptions()
    sk = raw.skeleton
    joints = sk.calibration_joints if joints is None else np.asarray(joints, dtype=int)
    T, J = len(raw.people), sk.num_joints
    if not any(len(p) >= 2 for p in raw.people):
        empty = np.full((T, J, 3), np.nan)
        empty[..., 2] = 0.0
        return MirrorPairing(real=empty, reflections=[empty.copy() for _ in epipoles],
                             epipoles=[np.asarray(e, float) for e in epipoles])
    cand = candidates(raw, opts)
    found = [_score_epipole(np.asarray(e, float).reshape(3), cand, joints, sk.flip, opts)
             for e in epipoles]
    return choose_pairs(_scored_candidates(cand, found, T), sk.flip)


def pair_frame_with_epipole(people: np.ndarray, epipole: np.ndarray, skeleton,
                            joints: np.ndarray | None = None,
                            options: PairingOptions | None = None
                            ) -> tuple[np.ndarray, np.ndarray]:
    """One frame paired against one known epipole: :func:`pair_with_epipoles` for a
    single frame and mirror, the same result, without the batch's bookkeeping where the
    frame holds two detections (its one candidate scored and chosen directly).

    Args:
        people: ``(P, J, 3)`` the frame's detections (undistorted pixels, confidence).
        epipole: ``(3,)`` homogeneous epipole, pixels.
        skeleton: the detections' :class:`~mirrorgraph.skeletons.Skeleton`.
        joints: joints judging the pair (default: the calibration joints).
        options: :class:`PairingOptions`.

    Returns:
        ``(real, mirror)``: ``(J, 3)`` the person and the reflection (its labels those of
        the real joints it images); NaN / 0 where no pair under the threshold.
    """
    opts = options or PairingOptions()
    people = np.asarray(people, dtype=float)
    if len(people) != 2:
        raw = RawDetections(skeleton, np.array([0]), [people])
        pairing = pair_with_epipoles(raw, [epipole], joints, opts)
        return pairing.real[0], pairing.reflections[0][0]
    flip = skeleton.flip
    joints = skeleton.calibration_joints if joints is None else np.asarray(joints, dtype=int)
    e = np.asarray(epipole, float).reshape(3)
    a, b_own = masked(people, opts.min_confidence)
    b = b_own[flip]
    # the one candidate's two labellings scored together (:func:`_score_epipole`)
    flipped, swapped_score = median_distance(e, np.stack([a, a]), np.stack([b, b[flip]]),
                                             joints, opts.min_joints)
    swapped = bool(is_swap(flipped, swapped_score, opts.threshold_px))
    score = swapped_score if swapped else flipped
    real = np.full((len(flip), 3), np.nan)
    real[:, 2] = 0.0
    if not score < opts.threshold_px:
        return real, real.copy()
    b_label = b[flip] if swapped else b
    b_refl = bool(b_is_reflection_of(e, a[None, joints], b_label[None, joints])[0])
    # one candidate: no detection is shared by two chosen pairs, the vote decides
    b_own = b[flip]
    mirror_own, person = (b_own, a) if b_refl else (a, b_own)
    return person.copy(), (mirror_own if swapped else mirror_own[flip]).copy()


def paired_people(cands: PairCandidates) -> list[np.ndarray]:
    """The detections of each frame that may be the person: those that are the person
    (the one farther from the epipole) of a valid pair of some mirror and the
    reflection of none.

    Returns:
        ``T`` sorted int arrays: detection indices into ``raw.people[t]``.
    """
    T = cands.num_frames
    P = 1 + max(int(cands.ia.max(initial=0)), int(cands.ib.max(initial=0)))
    is_person = np.zeros((T, P), dtype=bool)
    is_reflection = np.zeros((T, P), dtype=bool)
    for k in range(len(cands.epipoles)):
        ok = cands.valid[k]
        person, refl = cands.roles(k)
        is_person[cands.frame[ok], person[ok]] = True
        is_reflection[cands.frame[ok], refl[ok]] = True
    keep = is_person & ~is_reflection
    return [np.flatnonzero(row) for row in keep]


def choose_pairs(cands: PairCandidates, flip: np.ndarray, person: np.ndarray | None = None
                 ) -> MirrorPairing:
    """Keep per frame and mirror the best valid candidate: the person and their reflections.

    Without ``person``, the method of :func:`pair_reflections`: the candidate with
    the smallest score; the person is the detection that the chosen pairs of a
    frame share, or, in a frame with one pair only, the one farther from the
    epipole. With ``person`` (the subject chosen over several frames, e.g. by
    tracking) only the pairs holding that detection compete, and it is the person.

    Args:
        cands: :func:`pair_candidates`.
        flip: ``(J,)`` the skeleton's left/right flip map.
        person: ``(T,)`` int, the person's detection index per frame (-1: none, the
            frame is left unpaired); ``None``: decided per frame as above.

    Returns:
        :class:`MirrorPairing` (reflections in the order of ``cands.epipoles``).
    """
    T, J = cands.num_frames, cands.a.shape[1]
    choices = []
    for k in range(len(cands.epipoles)):
        allowed = cands.valid[k]
        if person is not None:
            p = np.asarray(person)[cands.frame]
            allowed = allowed & (p >= 0) & ((cands.ia == p) | (cands.ib == p))
        best = np.full(T, -1)
        idx = np.flatnonzero(allowed)
        order = idx[np.lexsort((cands.score[k][idx], cands.frame[idx]))]
        first = np.ones(len(order), bool)
        first[1:] = cands.frame[order][1:] != cands.frame[order][:-1]
        best[cands.frame[order[first]]] = order[first]
        choices.append(best)

    if person is None:      # the person: the detection the chosen pairs of a frame share
        P = 1 + max(int(cands.ia.max()), int(cands.ib.max()))
        count = np.zeros((T, P), dtype=int)
        for best in choices:
            has = best >= 0
            np.add.at(count, (np.flatnonzero(has), cands.ia[best[has]]), 1)
            np.add.at(count, (np.flatnonzero(has), cands.ib[best[has]]), 1)
        shared = np.where(count.max(1) >= 2, count.argmax(1), -1)
    else:
        shared = np.asarray(person)

    real = np.full((T, J, 3), np.nan)
    real[..., 2] = 0.0
    reflections, fixes = [], 0
    for k, best in enumerate(choices):
        swapped = cands.swapped[k]
        mirror = np.full((T, J, 3), np.nan)       # not a copy of ``real``: filled below
        mirror[..., 2] = 0.0
        rows = np.flatnonzero(best >= 0)
        c = best[rows]
        a, b_own = cands.a[c], cands.b[c][:, flip]
        s = shared[rows]
        in_pair = (cands.ia[c] == s) | (cands.ib[c] == s)
        b_is_mirror = np.where((s >= 0) & in_pair, cands.ia[c] == s, cands.b_is_reflection[k, c])
        keep = b_is_mirror[:, None, None]
        mirror_own = np.where(keep, b_own, a)
        mirror[rows] = np.where(swapped[c, None, None], mirror_own, mirror_own[:, flip])
        person_rows = np.where(keep, a, b_own)
        fill = rows[~(real[rows, :, 2] > 0).any(1)]
        real[fill] = person_rows[np.isin(rows, fill)]
        reflections.append(mirror)
        fixes += int(np.count_nonzero(swapped[c]))
    return MirrorPairing(real=real, reflections=reflections, epipoles=list(cands.epipoles),
                         lr_fixes=fixes)


def pair_reflections(raw: RawDetections, num_mirrors: int, joints: np.ndarray | None = None,
                     options: PairingOptions | None = None) -> MirrorPairing:
    """Sort out, per frame, the person and their reflections in ``num_mirrors`` mirrors.

    The method of the module docstring, once per mirror (:func:`pair_candidates`),
    then per frame and mirror the best candidate under the threshold is kept
    (:func:`choose_pairs`). The person is the detection that the chosen pairs of
    a frame share; in a frame with one pair only (always, with one mirror), the
    reflection is the detection closer to the epipole. The person keeps the
    detector's labels; the reflection is relabelled by the flip map, or kept as
    it is where the detector confused its left and right (a confusion cannot be
    told apart from one on the person, and the reflection, seen from behind, is
    where detectors make it).

    Each frame is decided on its own: where several people stand in front of
    the mirror, each with their reflection, the frame's best pair may be any of
    them. A camera that must follow one person over time chooses the person
    first (:func:`paired_people`, tracks) and passes it to :func:`choose_pairs`
    (:mod:`mirrorgraph.rigs.observations` does).

    Args:
        raw: detections per frame (undistorted pixels).
        num_mirrors: mirrors the camera sees (>= 1).
        joints: joints judging the pairs (default: the calibration joints).
        options: :class:`PairingOptions`.

    Raises:
        InputError: no frame holds two people.
        DegenerateGeometryError: a mirror's epipole cannot be found.
    """
    cands = pair_candidates(raw, num_mirrors, joints, options)
    return choose_pairs(cands, raw.skeleton.flip)


def pair_detections(raw: RawDetections, joints: np.ndarray | None = None,
                    options: PairingOptions | None = None) -> PairedKeypoints:
    """Pair person and reflection in every frame (see the module docstring).

    Args:
        raw: detections per frame, pixel coordinates (undistorted if the camera
            has distortion).
        joints: ``(k,)`` joint indices used to judge pairs (default: the
            skeleton's calibration joints).
        options: :class:`PairingOptions`.

    Returns:
        :class:`PairedKeypoints` over all frames of ``raw``; unpaired frames have
        confidence 0 and NaN coordinates.

    Raises:
        InputError: no frame holds two people.
        DegenerateGeometryError: the candidates do not determine an epipole.
    """
    pairing = pair_reflections(raw, 1, joints, options)
    return PairedKeypoints(skeleton=raw.skeleton, frame_ids=np.asarray(raw.frame_ids),
                           real=pairing.real, mirror=pairing.reflections[0], source=raw.source,
                           format=raw.format, image_size=raw.image_size, fps=raw.fps,
                           lr_fixes=pairing.lr_fixes, frames_read=len(raw.people))
