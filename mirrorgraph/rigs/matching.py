"""The same person in every camera: following one person over time, and matching
detections across cameras by epipolar consistency.

Neither a camera without mirrors nor one with mirrors can tell its subject from a
bystander frame by frame. So:

* **Over time, in the reference camera** (the rig's first): the candidates are linked
  into tracks (:func:`~.tracking.track_people`) and the subject is the track seen in the
  most frames (:func:`~.tracking.subject_track`), between tracks seen nearly as long the
  one that moves most (:func:`~.tracking.track_motion`).
* **Across cameras** (:func:`match_candidates`), for every other camera:

  1. its candidates are linked into tracks (:func:`~.tracking.track_labelled`, left/right
     swaps read against the track's labels);
  2. each long enough track is tested against the reference person
     (:func:`~.epipolar.labelled_geometry`: an essential matrix by MAGSAC++, refined by
     :func:`mirrorgraph.initial.relative.refine_relative_pose`); the track whose joints fit
     it best (inliers under :func:`~.epipolar.inlier_threshold_px`) gives the geometry;
     where no whole track fits with :data:`MIN_TRACK_INLIERS`, the tracks' pieces between
     left/right swaps are tried (:func:`~.tracking.tracklets`); where the frames jump
     (snapshots far apart in time, :func:`~.tracking.segments`: no track crosses a jump)
     and neither fits, one candidate a frame (:func:`consensus_geometry`);
  3. every frame's candidates are scored by their median Sampson distance (Hartley and
     Zisserman, *Multiple View Geometry*, 2nd ed., sec. 11.4.3) to the reference person;
     the best under :data:`MATCH_THRESHOLD_PX` is kept, except on tracks that fit in too
     few of their frames (:data:`MIN_TRACK_AGREEMENT`).

  Without :data:`MIN_CORRESPONDENCES` shared joints or :data:`MIN_TRACK_INLIERS`
  inliers a :class:`~mirrorgraph.errors.DegenerateGeometryError` says so. The test is
  one-sided: a camera that does not see the subject at all can pass
  (``docs/internals.md``).

Modules: :mod:`.tracking` (the tracks, their labels, the subject), :mod:`.epipolar` (a
track's geometry with the reference person and how well candidates fit it), this one
(the choice per frame, :func:`match_candidates`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DegenerateGeometryError
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from ..skeletons import Skeleton
from ..initial.relative import normalised_coordinates
from .epipolar import (TRACK_INLIER_PX, group_bits, inlier_threshold_px, labelled_geometry,
                       row_medians, track_geometry)
from .tracking import continuity_labels, segments, track_labelled, tracklets

__all__ = ["match_candidates", "match_people", "consensus_geometry", "MATCH_THRESHOLD_PX",
           "CONSENSUS_FRAMES", "CONSENSUS_DRAWS"]

#: Median Sampson distance (px) above which no candidate of a frame is accepted.
MATCH_THRESHOLD_PX = 12.0

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

#: Frames of one hypothesis of :func:`consensus_geometry` (one candidate each, ~13 joint
#: pairs a frame on a BODY_25 limb set: three frames span depth enough for an essential
#: matrix).
CONSENSUS_FRAMES = 3

#: Hypotheses of :func:`consensus_geometry` at most (drawn until one all of whose
#: candidates are the person is drawn with probability :data:`CONSENSUS_CONFIDENCE`).
CONSENSUS_DRAWS = 3000

#: The probability of :func:`consensus_geometry`'s stopping rule.
CONSENSUS_CONFIDENCE = 0.999

#: Hypotheses of :func:`consensus_geometry` solved and scored as one batch.
CONSENSUS_BATCH = 100


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
                     seed: int = 0, frame_ids: np.ndarray | None = None
                     ) -> tuple[np.ndarray, int]:
    """Choose, per frame, which candidate detection is the reference camera's person.

    Steps 1-3 of the module docstring: the tracks and their geometry read a
    detector's left/right swaps (a turning person's, in one camera and not in
    another: :func:`~.epipolar.labelled_geometry`); per frame the candidates are scored as
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
        frame_ids: ``(T,)`` the frames' numbers: no track crosses a jump of more than
            :data:`~.tracking.TRACK_MAX_GAP` frames nor a frame where the people jump
            (:func:`~.tracking.segments`: snapshots), and where there are jumps the
            geometry may come from one candidate a frame (:func:`consensus_geometry`).
            ``None``: consecutive frames, continuity assumed.

    Returns:
        ``(T,)`` int: the index of the chosen candidate per frame (-1: none; where
        no candidate fits and a frame has several, none is guessed; a frame's only
        candidate is kept unless its track is another person's), and the number of
        frames where the choice differs from the most confident candidate.

    Raises:
        DegenerateGeometryError: no track can be matched: too few joints seen in
            both cameras to estimate the epipolar geometry, or no track's joints
            fit one (fewer than :data:`MIN_TRACK_INLIERS` of them within
            :func:`~.epipolar.inlier_threshold_px`).
    """
    joints = skeleton.calibration_joints
    flip = np.asarray(skeleton.flip)
    chosen, rows, A, C = _candidate_rows(ref_person, candidates, joints)
    best_conf = chosen.copy()
    if rows is None:
        return chosen, 0
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
    track, own, ref_stretch, rel = _relative_labels(ref_person, candidates, rows[:, 0], joints,
                                                    min_confidence, flip, frame_ids)
    inlier_px = inlier_threshold_px(ref_person, joints, min_confidence)
    match_px = MATCH_THRESHOLD_PX * inlier_px / TRACK_INLIER_PX
    fits = _Fits(xa_all, xb_all, seen, rel, ref_stretch, f, seed, inlier_px)
    T, J = ref_person.shape[:2]
    ref_rows = [ref_person[t][None] if (ref_person[t, :, 2] >= min_confidence).any()
                else np.zeros((0, J, 3)) for t in range(T)]
    jumps = frame_ids is not None and T > 1 and any(
        segments(frame_ids, T, c, joints, min_confidence)[-1] > 0 for c in (candidates, ref_rows))
    best_E, group = _person_geometry(fits, track, own, rows[:, 0],
                                     match_px if jumps else None)
    # frame by frame as labelled, and a detection whose labels disagree with the
    # reference person's (by its track's answer) is not kept, not even as a frame's
    # only candidate: relabelled, such frames put Demo_SinglePerson's cameras 0.1-0.8
    # deg further from Qualisys (a detector that swaps a person seen from behind places
    # the joints wrong, not only their names); kept as they are, they pair the wrong
    # sides
    disagree = rel ^ group_bits(best_E, xa_all, xb_all, seen, rel, group, f, inlier_px)[group]
    score = row_medians(best_E, xa_all, xb_all[0], seen[0], f)
    _choose_per_frame(chosen, rows, score, _other_people(track, score, match_px), disagree,
                      candidates, match_px)
    changed = int(np.count_nonzero((chosen >= 0) & (chosen != best_conf)))
    return chosen, changed


# ------------------------------------------------------------------ match_candidates' steps
def _candidate_rows(ref_person: np.ndarray, candidates: list[np.ndarray], joints: np.ndarray):
    """Every candidate of every frame beside the reference person: ``(chosen, rows, A, C)``,
    ``chosen`` ``(T,)`` the most confident candidate per frame (-1: none), ``rows``
    ``(M, 2)`` (frame, index), ``A`` ``(M, k, 3)`` the reference person's ``joints`` and
    ``C`` ``(M, J, 3)`` the candidates (``None`` but ``chosen`` without a candidate)."""
    T, J = ref_person.shape[:2]
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
    if not rows:
        return chosen, None, None, None
    return chosen, np.asarray(rows), np.concatenate(refs)[:, joints], np.concatenate(cands)


def _relative_labels(ref_person: np.ndarray, candidates: list[np.ndarray], frame: np.ndarray,
                     joints: np.ndarray, min_confidence: float, flip: np.ndarray,
                     frame_ids: np.ndarray | None = None):
    """The candidates' tracks and labels against the reference person's:
    ``(track, own, ref_stretch, rel)``, each ``(M,)`` over the candidates (in frame order,
    ``frame`` their frames): the track id, the labels swapped relative to the track's, the
    reference person's track in the frame, and the labels swapped relative to the
    reference person's up to one answer a (track, reference stretch); no track crosses a
    jump of ``frame_ids`` (:func:`~.tracking.track_labelled`)."""
    T, J = ref_person.shape[:2]
    ids, own = track_labelled(candidates, joints, min_confidence, flip, frame_ids)
    track, own = np.concatenate(ids), np.concatenate(own)
    ref_swap = continuity_labels(ref_person, joints, min_confidence, flip, frame_ids)
    ref_ids, _ = track_labelled([ref_person[t][None] if (ref_person[t, :, 2] >= min_confidence).any()
                                 else np.zeros((0, J, 3)) for t in range(T)],
                                joints, min_confidence, flip, frame_ids)
    ref_track = np.array([i[0] if len(i) else -1 for i in ref_ids])
    rel = own ^ ref_swap[frame]               # up to one answer a (track, reference stretch)
    return track, own, ref_track[frame], rel


def _groups(unit: np.ndarray, ref_stretch: np.ndarray) -> np.ndarray:
    """``(M,)`` int ids of the (unit, reference stretch) groups: one labelling answer each."""
    _, group = np.unique(np.stack([unit, ref_stretch], 1), axis=0, return_inverse=True)
    return group.ravel()


@dataclass
class _Fits:
    """The correspondences with the reference person every unit's geometry is fitted to:
    ``xa`` ``(M, k, 2)``, ``xb`` ``(2, M, k, 2)``, ``seen`` ``(2, M, k)``, ``rel`` ``(M,)``
    (:func:`~.epipolar.labelled_geometry`), ``ref_stretch`` ``(M,)`` the reference
    person's track, the focal length ``f``, OpenCV's ``seed`` and ``inlier_px``."""

    xa: np.ndarray
    xb: np.ndarray
    seen: np.ndarray
    rel: np.ndarray
    ref_stretch: np.ndarray
    f: float
    seed: int
    inlier_px: float

    def geometries(self, unit: np.ndarray) -> dict[int, tuple[np.ndarray, float, float]]:
        """unit id -> (E, fraction of inliers, fit) of every unit (track or piece) with
        enough correspondences."""
        grp = _groups(unit, self.ref_stretch)
        out = {}
        for k in np.unique(unit):
            mine = unit == k
            n = np.count_nonzero(self.seen[0][mine])
            if n < MIN_CORRESPONDENCES:
                continue
            _, g = np.unique(grp[mine], return_inverse=True)
            E, frac, _ = labelled_geometry(self.xa[mine], self.xb[:, mine], self.seen[:, mine],
                                           self.rel[mine], g.ravel(), self.f, self.seed,
                                           self.inlier_px)
            if E is not None:
                out[int(k)] = (E, frac, frac * np.sqrt(n))
        return out


def _best_of(fits: dict) -> tuple[np.ndarray | None, float]:
    if not fits:
        return None, 0.0
    E, frac, _ = max(fits.values(), key=lambda v: v[2])     # first of equal fits
    return E, frac


def _person_geometry(fits: _Fits, track: np.ndarray, own: np.ndarray, frame: np.ndarray,
                     consensus_px: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The epipolar geometry of the best fitting track, or of the best piece of a track
    (:func:`~.tracking.tracklets`) where no whole track fits, or with ``consensus_px``
    (frames far apart) of one candidate a frame (:func:`consensus_geometry`, candidates
    within ``consensus_px``) where neither does, and the candidates' groups under it
    (step 2 of the module docstring): ``(E, group)``.

    Raises:
        DegenerateGeometryError: neither a track nor a piece fits.
    """
    group = _groups(track, fits.ref_stretch)
    tried = sum(np.count_nonzero(fits.seen[0][track == k]) >= MIN_CORRESPONDENCES
                for k in np.unique(track))
    best_E, best_frac = _best_of(fits.geometries(track))
    whole_frac = best_frac
    if tried and best_frac < MIN_TRACK_INLIERS:
        # no whole track fits: its pieces between the tracker's left/right swaps do
        # (see tracklets)
        piece = tracklets(track, own, frame)
        E, frac = _best_of(fits.geometries(piece))
        if E is not None and frac >= MIN_TRACK_INLIERS:
            best_E, best_frac = E, frac
            group = _groups(piece, fits.ref_stretch)
    consensus = ""
    if consensus_px is not None and (best_E is None or best_frac < MIN_TRACK_INLIERS):
        E, share = consensus_geometry(fits.xa, fits.xb[0], fits.seen[0], frame, fits.f,
                                      consensus_px, fits.inlier_px, fits.seed)
        if E is not None and share >= MIN_TRACK_INLIERS:
            return E, group
        consensus = (f"; nor one candidate a frame ({100 * share:.0f} % of the frames within "
                     f"{consensus_px:.0f} px of the best geometry of any {CONSENSUS_FRAMES})")
    if best_E is None or best_frac < MIN_TRACK_INLIERS:
        raise DegenerateGeometryError(
            f"none of its {tried} tracked people is consistent with the reference camera's "
            f"person (best: {100 * whole_frac:.0f} % of the joints within "
            f"{fits.inlier_px:.0f} px of an epipolar geometry, left/right labels read by "
            f"continuity, {100 * MIN_TRACK_INLIERS:.0f} % needed; no piece of a track "
            f"between its left/right swaps either{consensus})" if tried else
            f"no tracked person shares {MIN_CORRESPONDENCES} joints with the reference "
            f"camera's person{consensus}")
    return best_E, group


def consensus_geometry(xa: np.ndarray, xb: np.ndarray, seen: np.ndarray, frame: np.ndarray,
                       f: float, match_px: float, inlier_px: float, seed: int = 0
                       ) -> tuple[np.ndarray | None, float]:
    """The epipolar geometry of the reference person and one candidate a frame, without
    tracks: frames far apart in time (snapshots) share no track, and a frame's people
    are not the last frame's.

    A RANSAC over the frames' candidates: a hypothesis draws :data:`CONSENSUS_FRAMES`
    frames and one candidate in each, and fits an essential matrix to their joints (the
    linear eight-point solution projected onto the essential matrices, Hartley and
    Zisserman, *Multiple View Geometry*, 2nd ed., sec. 11.1 and 9.6, hypotheses solved
    as one batch); it scores the frames one of whose candidates lies within ``match_px``
    of it (median Sampson distance, sec. 11.4.3), ties broken by the summed medians;
    hypotheses are drawn until one of correct candidates only was drawn with probability
    :data:`CONSENSUS_CONFIDENCE` (the share of frames matched over the mean candidates a
    frame, to the power :data:`CONSENSUS_FRAMES`), at most :data:`CONSENSUS_DRAWS`. The
    best is refined twice on every frame's best candidate within ``match_px``
    (:func:`~.epipolar.track_geometry`: MAGSAC++ and the robust Sampson refinement).

    Args:
        xa: ``(M, k, 2)`` the reference person's joints beside each candidate,
            normalised coordinates; xb: ``(M, k, 2)`` the candidates', as labelled.
        seen: ``(M, k)`` joints seen in both; frame: ``(M,)`` each candidate's frame.
        f: focal length (px) for the units; match_px: a candidate's median Sampson
            distance within which it is the person; inlier_px: the joints' inlier
            threshold (px); seed: of the draws and OpenCV's.

    Returns:
        the essential matrix (``None`` where fewer than :data:`CONSENSUS_FRAMES` frames
        have a candidate), and the share of the frames with a candidate one of whose
        candidates lies within ``match_px`` of it.
    """
    M = len(frame)
    enough = np.count_nonzero(seen, axis=1) >= 5
    frames = np.unique(frame[enough])
    if len(frames) < CONSENSUS_FRAMES:
        return None, 0.0
    rows = [np.flatnonzero(enough & (frame == t)) for t in frames]
    per = np.array([len(r) for r in rows], float)
    _, where = np.unique(frame, return_inverse=True)
    where = where.ravel()
    by_frame = np.argsort(where, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(where[by_frame]) != 0])

    def score(E: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Frames matched and summed medians per hypothesis ``(H,)``, medians ``(H, M)``."""
        d = _batch_medians(E.reshape(-1, 3, 3), xa, xb, seen, f)
        best = np.minimum.reduceat(d[:, by_frame], starts, axis=1)           # (H, T)
        hit = best <= match_px
        return hit.sum(1), np.where(hit, best, 0.0).sum(1), d

    rng = np.random.default_rng(seed)
    top, best_E = (-1, 0.0), None
    needed, drawn = CONSENSUS_DRAWS, 0
    while drawn < needed:
        H = min(CONSENSUS_BATCH, needed - drawn)
        drawn += H
        picks = np.stack([[rng.choice(rows[i]) for i in rng.choice(len(rows), CONSENSUS_FRAMES,
                                                                  replace=False)]
                          for _ in range(H)])                                 # (H, n)
        use = seen[picks].reshape(H, -1)                                      # (H, n k)
        a = np.where(use[..., None], xa[picks].reshape(H, -1, 2), 0.0)
        b = np.where(use[..., None], xb[picks].reshape(H, -1, 2), 0.0)
        E = _eight_point(a, b, use)
        hits, total, _ = score(E)
        i = int(np.lexsort((-total, hits))[-1])
        if (hits[i], -total[i]) > top:
            top, best_E = (int(hits[i]), -float(total[i])), E[i]
            p = min(top[0] / len(frames) / per.mean(), 1.0) ** CONSENSUS_FRAMES
            needed = (drawn if p >= 1 else CONSENSUS_DRAWS if p <= 0 else
                      min(CONSENSUS_DRAWS, int(np.ceil(np.log(1 - CONSENSUS_CONFIDENCE)
                                                       / np.log(1 - p)))))
    if best_E is None:
        return None, 0.0
    E = best_E
    for _ in range(2):                     # refined on every frame's best candidate
        d = score(E)[2][0]
        order = np.lexsort((d, where))
        first = np.ones(M, bool)
        first[1:] = where[order][1:] != where[order][:-1]
        chosen = order[first & (d[order] <= match_px)]
        use = np.zeros_like(seen)
        use[chosen] = seen[chosen]
        if np.count_nonzero(use) < MIN_CORRESPONDENCES:
            break
        E_new, _ = track_geometry(xa[use], xb[use], f, seed, inlier_px)
        if E_new is None:
            break
        (h_new, s_new, _), (h_old, s_old, _) = score(E_new), score(E)
        if (h_new[0], -s_new[0]) < (h_old[0], -s_old[0]):
            break
        E = E_new
    return E, float(score(E)[0][0]) / len(frames)


def _eight_point(xa: np.ndarray, xb: np.ndarray, use: np.ndarray) -> np.ndarray:
    """``(H, 3, 3)`` essential matrices, ``x_b^T E x_a = 0``, of ``H`` sets of normalised
    correspondences ``xa``, ``xb`` ``(H, n, 2)`` (rows where ``use`` ``(H, n)`` is false
    ignored): the linear eight-point solution, its two nonzero singular values made equal
    (Hartley and Zisserman, *Multiple View Geometry*, 2nd ed., sec. 11.1, result 9.17)."""
    ha = np.concatenate([xa, np.ones(xa.shape[:2] + (1,))], -1)
    hb = np.concatenate([xb, np.ones(xb.shape[:2] + (1,))], -1)
    A = (hb[..., :, None] * ha[..., None, :]).reshape(xa.shape[:2] + (9,))
    A = A * use[..., None]
    F = np.linalg.svd(A)[2][:, -1].reshape(-1, 3, 3)
    U, _, Vt = np.linalg.svd(F)
    return U @ np.diag([1.0, 1.0, 0.0]) @ Vt


def _batch_medians(E: np.ndarray, xa: np.ndarray, xb: np.ndarray, seen: np.ndarray, f: float
                   ) -> np.ndarray:
    """``(H, M)`` :func:`~.epipolar.row_medians` under each of ``H`` essential matrices
    ``E`` ``(H, 3, 3)``: each candidate's median absolute Sampson distance (px), ``inf``
    where fewer than 4 joints are ``seen``."""
    ha = np.concatenate([np.nan_to_num(xa), np.ones(xa.shape[:2] + (1,))], -1)   # (M, k, 3)
    hb = np.concatenate([np.nan_to_num(xb), np.ones(xb.shape[:2] + (1,))], -1)
    Ex = np.einsum("hij,mkj->hmki", E, ha)                                    # lines in b
    Etx = np.einsum("hji,mkj->hmki", E, hb)                                   # lines in a
    e = np.sum(hb[None] * Ex, -1)
    den = Ex[..., 0] ** 2 + Ex[..., 1] ** 2 + Etx[..., 0] ** 2 + Etx[..., 1] ** 2
    d = np.where(seen[None], f * np.abs(e) / np.sqrt(np.maximum(den, 1e-300)), np.nan)
    out = np.full(d.shape[:2], np.inf)
    enough = np.count_nonzero(seen, axis=1) >= 4
    if enough.any():
        out[:, enough] = np.nanmedian(d[:, enough], axis=2)
    return out


def _choose_per_frame(chosen: np.ndarray, rows: np.ndarray, score: np.ndarray,
                      other: np.ndarray, disagree: np.ndarray, candidates: list[np.ndarray],
                      match_px: float) -> None:
    """Per frame the best candidate under ``match_px`` (step 3 of the module docstring), in
    ``chosen`` in place: never one of ``other`` people's, and where none fits a frame's only
    candidate unless its labels ``disagree`` with the reference person's."""
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
