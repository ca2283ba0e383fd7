"""Every person a rig sees, associated across its cameras with the rig's current geometry.

The one-person path (:mod:`.observations`) follows one person, the reference camera's
subject, and matches it across cameras before any camera is placed. Once the rig is
calibrated from that person, the epipolar geometry of every camera pair is known, and
every other person can be associated (:func:`associate_people`):

1. **Tracks per camera**: each camera's candidates are linked over time
   (:func:`~.tracking.track_labelled`), the tracks cut wherever the rig's frames jump by
   more than :data:`~.tracking.TRACK_MAX_GAP` frames or the people jump from frame to
   frame (:func:`~.tracking.segments`: snapshots share no track, no continuity is
   assumed where the frame numbers or the people say otherwise).
2. **Clusters per frame**: every pair of detections of one frame in two cameras is scored
   by the median Sampson distance (px) of their joints under the current rig (Hartley and
   Zisserman, *Multiple View Geometry*, 2nd ed., sec. 11.4.3), relative to a threshold
   that grows with the person's size in the image (:data:`ASSOCIATION_OF_SIZE`, at least
   :data:`ASSOCIATION_PX`); the pairs are merged cheapest first into clusters of at most
   one detection a camera, a merge allowed only where every pair of the two clusters fits
   (complete linkage): a person standing on another's epipolar line in one camera pair is
   told apart by the other cameras.
3. **People over time**: tracks whose detections share clusters are one person; two
   groups merge only where they are not two clusters of one frame (beyond
   :data:`CONFLICT_SHARE` of their common frames): a track that jumps from one person to
   another (an occlusion in one camera) joins one of them and its frames with the other
   are taken by the clusters' geometry, not by the track. Each frame's cluster goes to
   the person most of its tracks belong to.
4. **Left/right**: a detection whose labels fit the others of its cluster better swapped
   (:attr:`mirrorgraph.skeletons.Skeleton.flip`) is left out of that frame, as the
   one-person path leaves out frames whose labels disagree with the reference person's.
5. **Slots**: the people are packed into the fewest slots of the layout of several people
   (:func:`mirrorgraph.skeletons.people_skeleton`): the person holding most of the
   one-person path's subject first (slot 0), then the others longest first, each in the
   first slot free on all of its frames; where the frames jump (snapshots), no track
   follows a person from one stretch of frames to the next, and the people are put in
   slots by their bone lengths (:func:`~.identities.people_by_body`), the slot holding
   most detections first.

:class:`PeopleAssociation` holds the result and builds the observations of the one graph
(:meth:`PeopleAssociation.observations`); :meth:`PeopleAssociation.changed` compares two
rounds (the loop of :func:`mirrorgraph.pipelines.rig_people.solve_everyone`).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, replace

import numpy as np

from ..keypoints import DEFAULT_MIN_CONFIDENCE
from ..skeletons import Skeleton, people_skeleton
from .observations import CameraObservations, RigObservations
from .identities import people_by_body
from .tracking import rig_segments, track_labelled

__all__ = ["ASSOCIATION_OF_SIZE", "ASSOCIATION_PX", "CONFLICT_SHARE", "PeopleAssociation",
           "associate_people", "candidate_index", "pair_costs"]

#: Least association threshold, px: two detections whose joints' median Sampson distance
#: under the rig is below the threshold may be one person.
ASSOCIATION_PX = 12.0

#: The threshold grows with the people's size in the image (the larger side of the box of
#: their confident joints, the mean of the two detections'): a detector's error does
#: (:data:`~.epipolar.TRACK_INLIER_OF_SIZE`); about twice the one-person inlier threshold,
#: since a rig calibrated from one person is less exact away from that person.
ASSOCIATION_OF_SIZE = 0.025

#: Two groups of tracks are two people where they are different clusters of the same
#: frame in more than this share of the frames both are in (and in more than one frame).
CONFLICT_SHARE = 0.05

#: A detection's labels are swapped against its cluster's where the swapped labels' cost
#: is under this share of the labels' own with most of the cluster (a person seen from the
#: side fits nearly as well either way: noise alone must not drop them).
SWAP_MARGIN = 0.5

#: Joints two detections must share for their cost.
MIN_SHARED_JOINTS = 4


@dataclass
class PeopleAssociation:
    """Every person across the cameras (:func:`associate_people`).

    Attributes:
        count: ``P``, the slots of the layout of several people (slot 0: the person of the
            one-person path).
        index: per camera ``(T, P)`` int: the candidate (``camera.people[t]`` row) of each
            slot in each frame, -1 where none.
        people_found: people (groups of tracks) found before their packing into slots.
        lr_dropped: detections left out because their left/right labels disagree with
            the rest of their cluster.
        switched: track detections taken by another person than their track's (a track
            that jumps between people, decided by the geometry).
    """

    count: int
    index: list[np.ndarray]
    people_found: int = 0
    lr_dropped: int = 0
    switched: int = 0

    def views(self) -> np.ndarray:
        """``(P, T)`` int: cameras seeing each slot in each frame."""
        return sum((ix >= 0).astype(int) for ix in self.index).T

    def frames(self) -> np.ndarray:
        """``(P,)`` frames where each slot is seen by two cameras or more."""
        return np.count_nonzero(self.views() >= 2, axis=1)

    def changed(self, other: "PeopleAssociation | None") -> float:
        """The share of (camera, frame, slot) entries held by either association that the
        other does not hold the same (1 where the slot counts differ or ``other`` is
        ``None``)."""
        if other is None or other.count != self.count:
            return 1.0
        held = differ = 0
        for a, b in zip(self.index, other.index):
            some = (a >= 0) | (b >= 0)
            held += int(np.count_nonzero(some))
            differ += int(np.count_nonzero(some & (a != b)))
        return differ / held if held else 0.0

    def observations(self, obs: RigObservations) -> RigObservations:
        """``obs`` in the layout of several people (:func:`~mirrorgraph.skeletons.people_skeleton`):
        each camera's ``real`` ``(T, P J, 3)`` with slot ``p``'s detection in joints
        ``p J .. p J + J - 1``; the reflections the subject's, in slot 0 on the frames
        where slot 0 holds the subject's detection, the rest NaN (the others'
        reflections are not associated)."""
        sk = obs.skeleton
        J, P = sk.num_joints, self.count
        cams = []
        for cam, ix in zip(obs.cameras, self.index):
            T = len(ix)
            real = np.full((T, P, J, 3), np.nan)
            real[..., 2] = 0.0
            t, p = np.nonzero(ix >= 0)
            if len(t):
                real[t, p] = np.stack([cam.people[a][b] for a, b in zip(t, ix[t, p])])
            refl = {}
            # the subject's reflections where slot 0 holds the subject's detection
            mine = (np.ones(T, bool) if cam.people is None
                    else (candidate_index(cam) == ix[:, 0]) & (ix[:, 0] >= 0))
            for m, r in cam.reflections.items():
                full = np.full((T, P, J, 3), np.nan)
                full[..., 2] = 0.0
                full[mine, 0] = r[mine]
                refl[m] = full.reshape(T, P * J, 3)
            cams.append(replace(cam, real=real.reshape(T, P * J, 3), reflections=refl))
        return replace(obs, skeleton=people_skeleton(sk, P), cameras=cams,
                       warnings=list(obs.warnings))


def candidate_index(cam: CameraObservations) -> np.ndarray:
    """``(T,)`` int: the row of ``cam.people[t]`` that ``cam.real[t]`` is (-1: none)."""
    out = np.full(len(cam.real), -1)
    for t, (p, r) in enumerate(zip(cam.people, cam.real)):
        if len(p) and r[:, 2].any():
            same = np.all((p == r[None]) | (np.isnan(p) & np.isnan(r[None])), axis=(1, 2))
            if same.any():
                out[t] = int(np.argmax(same))
    return out


def _fundamental(Ka, pose_a, Kb, pose_b) -> np.ndarray:
    """``(3, 3)`` F with ``x_b^T F x_a = 0`` (pixels) for camera-to-world poses."""
    Ra, Ca = pose_a[:3, :3], pose_a[:3, 3]
    Rb, Cb = pose_b[:3, :3], pose_b[:3, 3]
    R = Rb.T @ Ra
    t = Rb.T @ (Ca - Cb)
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return np.linalg.inv(Kb).T @ tx @ R @ np.linalg.inv(Ka)


def pair_costs(A: np.ndarray, B: np.ndarray, F: np.ndarray, min_confidence: float
               ) -> np.ndarray:
    """``(M,)`` median absolute Sampson distance (px) of detections ``A`` ``(M, J, 3)`` and
    ``B`` ``(M, J, 3)`` (same labels) under ``F``; ``inf`` where they share fewer than
    :data:`MIN_SHARED_JOINTS` confident joints."""
    ok = ((A[..., 2] >= min_confidence) & (B[..., 2] >= min_confidence)
          & np.isfinite(A[..., :2]).all(-1) & np.isfinite(B[..., :2]).all(-1))
    xa = np.concatenate([np.nan_to_num(A[..., :2]), np.ones(A.shape[:2] + (1,))], -1)
    xb = np.concatenate([np.nan_to_num(B[..., :2]), np.ones(B.shape[:2] + (1,))], -1)
    Fx = xa @ F.T                                           # (M, J, 3) lines in b
    Ftx = xb @ F                                            # lines in a
    e = np.sum(xb * Fx, -1)
    den = np.sqrt(Fx[..., 0] ** 2 + Fx[..., 1] ** 2 + Ftx[..., 0] ** 2 + Ftx[..., 1] ** 2)
    d = np.where(ok, np.abs(e) / np.maximum(den, 1e-12), np.nan)
    out = np.full(len(A), np.inf)
    enough = np.count_nonzero(ok, axis=1) >= MIN_SHARED_JOINTS
    if enough.any():
        out[enough] = np.nanmedian(d[enough], axis=1)
    return out


def _sizes(X: np.ndarray, joints: np.ndarray, min_confidence: float) -> np.ndarray:
    """``(N,)`` the larger side of the box of each detection's confident ``joints`` (px)."""
    xy = np.where(X[:, joints, 2:3] >= min_confidence, X[:, joints, :2], np.nan)
    with np.errstate(invalid="ignore"):
        lo, hi = np.nanmin(np.where(np.isfinite(xy), xy, np.inf), 1), \
            np.nanmax(np.where(np.isfinite(xy), xy, -np.inf), 1)
    side = np.max(hi - lo, axis=1)
    return np.where(np.isfinite(side), side, 0.0)


def _tracks(people: list[np.ndarray], frame_ids: np.ndarray, joints: np.ndarray,
            min_confidence: float, flip: np.ndarray, first_id: int) -> np.ndarray:
    """``(N,)`` global track ids of a camera's detections (in frame order), the tracks cut
    where the frames jump by more than :data:`~.tracking.TRACK_MAX_GAP` or the people
    jump from frame to frame (:func:`~.tracking.segments`)."""
    ids, _ = track_labelled(people, joints, min_confidence, flip, frame_ids)
    flat = np.concatenate(ids + [np.zeros(0, int)]).astype(int)
    return flat + first_id


class _Groups:
    """Groups of tracks with, per group, the cluster it holds in each frame."""

    def __init__(self, tracks: np.ndarray):
        self.parent = {int(k): int(k) for k in tracks}
        self.clusters: dict[int, dict[int, set[int]]] = {int(k): {} for k in tracks}

    def find(self, k: int) -> int:
        while self.parent[k] != k:
            self.parent[k] = self.parent[self.parent[k]]
            k = self.parent[k]
        return k

    def add(self, track: int, frame: int, cluster: int) -> None:
        self.clusters[track].setdefault(frame, set()).add(cluster)

    def merge(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra == rb:
            return
        ca, cb = self.clusters[ra], self.clusters[rb]
        both = ca.keys() & cb.keys()
        conflicts = sum(1 for f in both if ca[f] != cb[f] and not (ca[f] & cb[f]))
        if conflicts > max(1.0, CONFLICT_SHARE * len(both)):
            return
        if len(ca) < len(cb):
            ra, rb, ca, cb = rb, ra, cb, ca
        for f, s in cb.items():
            ca.setdefault(f, set()).update(s)
        self.parent[rb] = ra
        del self.clusters[rb]


def associate_people(obs: RigObservations, Ks: list[np.ndarray], poses: list[np.ndarray], *,
                     min_confidence: float = DEFAULT_MIN_CONFIDENCE) -> PeopleAssociation:
    """Associate every person across the cameras with the rig's current geometry (the
    module docstring).

    Args:
        obs: the one-person path's observations (each camera's ``people``, the candidates
            per frame, and ``real``, the subject); cameras without candidates (already
            paired input) contribute the subject only.
        Ks: ``(3, 3)`` per camera, the intrinsics of the undistorted pixels (an estimated
            focal length's).
        poses: ``(4, 4)`` camera-to-world per camera.
        min_confidence: joints below it are ignored.

    Returns:
        :class:`PeopleAssociation`.
    """
    sk: Skeleton = obs.skeleton
    joints = np.asarray(sk.calibration_joints, int)
    flip = np.asarray(sk.flip)
    T, C = len(obs.frame_ids), len(obs.cameras)
    frame_ids = np.asarray(obs.frame_ids)
    # every detection: camera, frame, row in the frame's candidates, keypoints, track
    cam_of, frame_of, row_of, X, track_of = [], [], [], [], []
    next_id = 0
    for c, cam in enumerate(obs.cameras):
        people = cam.people if cam.people is not None else [
            r[None] if r[:, 2].any() else np.zeros((0,) + r.shape) for r in cam.real]
        n = [len(p) for p in people]
        cam_of.append(np.full(sum(n), c))
        frame_of.append(np.repeat(np.arange(T), n))
        row_of.append(np.concatenate([np.arange(k) for k in n] + [np.zeros(0, int)]))
        X.append(np.concatenate([np.asarray(p, float) for p in people if len(p)]
                                + [np.zeros((0, sk.num_joints, 3))]))
        tr = _tracks(people, frame_ids, joints, min_confidence, flip, next_id)
        next_id = int(tr.max()) + 1 if len(tr) else next_id
        track_of.append(tr)
    cam_of, frame_of, row_of, track_of = (np.concatenate(a).astype(int)
                                          for a in (cam_of, frame_of, row_of, track_of))
    X = np.concatenate(X)
    size = _sizes(X, joints, min_confidence)
    # pairs of detections of one frame in two cameras, their cost relative to the threshold
    order = np.lexsort((cam_of, frame_of))
    starts = np.searchsorted(frame_of[order], np.arange(T + 1))
    ia, ib = [], []
    for t in range(T):
        rows = order[starts[t]:starts[t + 1]]
        if len(rows) < 2:
            continue
        a, b = np.triu_indices(len(rows), 1)
        keep = cam_of[rows[a]] != cam_of[rows[b]]
        ia.append(rows[a[keep]])
        ib.append(rows[b[keep]])
    ia = np.concatenate(ia + [np.zeros(0, int)]).astype(int)
    ib = np.concatenate(ib + [np.zeros(0, int)]).astype(int)
    ratio = np.full(len(ia), np.inf)
    flipped = np.full(len(ia), np.inf)
    thr = np.maximum(ASSOCIATION_PX, ASSOCIATION_OF_SIZE * 0.5 * (size[ia] + size[ib]))
    for a in range(C):
        for b in range(C):
            sel = (cam_of[ia] == a) & (cam_of[ib] == b)
            if not sel.any():
                continue
            F = _fundamental(np.asarray(Ks[a], float), np.asarray(poses[a], float),
                             np.asarray(Ks[b], float), np.asarray(poses[b], float))
            ratio[sel] = pair_costs(X[ia[sel]], X[ib[sel]], F, min_confidence) / thr[sel]
            flipped[sel] = pair_costs(X[ia[sel]], X[ib[sel]][:, flip], F,
                                      min_confidence) / thr[sel]
    clusters = _cluster(len(X), cam_of, frame_of, ia, ib, ratio)
    lr_dropped = _drop_swapped(clusters, ia, ib, ratio, flipped)
    # people over time: tracks co-clustered, groups that are not two clusters of a frame
    groups = _Groups(np.unique(track_of))
    weight: dict[tuple[int, int], int] = defaultdict(int)
    for k, members in enumerate(clusters):
        if len(members) < 2:
            continue
        ts = sorted({int(track_of[m]) for m in members})
        f = int(frame_of[members[0]])
        for tr in ts:
            groups.add(tr, f, k)
        for i, a in enumerate(ts):
            for b in ts[i + 1:]:
                weight[(a, b)] += 1
    for (a, b), _ in sorted(weight.items(), key=lambda kv: (-kv[1], kv[0])):
        groups.merge(a, b)
    # each frame's cluster to the person most of its detections' tracks belong to
    person_frames: dict[int, dict[int, list[int]]] = defaultdict(dict)
    switched = 0
    for k, members in enumerate(clusters):
        if len(members) < 2:
            continue
        votes = defaultdict(int)
        for m in members:
            votes[groups.find(int(track_of[m]))] += 1
        g = max(votes, key=lambda v: (votes[v], -v))
        switched += len(members) - votes[g]
        f = int(frame_of[members[0]])
        held = person_frames[g].get(f)
        if held is None or len(members) > len(held):
            person_frames[g][f] = list(members)
    slots = _slots(person_frames, cam_of, frame_of, row_of, obs)
    stretch = rig_segments(frame_ids, [c.people if c.people is not None else [] for c in
                                        obs.cameras], joints, min_confidence)
    if len(slots) > 1 and len(stretch) and stretch[-1] > 0:    # frames far apart: by body
        slots = people_by_body(person_frames, X, cam_of, stretch, Ks, poses, sk, min_confidence)
    P = max(len(slots), 1)
    index = [np.full((T, P), -1) for _ in range(C)]
    for p, people in enumerate(slots):
        for g in people:
            for f, members in person_frames[g].items():
                for m in members:
                    index[cam_of[m]][f, p] = row_of[m]
    return PeopleAssociation(count=P, index=index, people_found=len(person_frames),
                             lr_dropped=lr_dropped, switched=switched)


def _cluster(N: int, cam_of: np.ndarray, frame_of: np.ndarray, ia: np.ndarray,
             ib: np.ndarray, ratio: np.ndarray) -> list[list[int]]:
    """Each frame's detections merged cheapest pair first into clusters of one detection a
    camera at most, every pair of a cluster under its threshold (``ratio < 1``, complete
    linkage; a pair without a cost, too few joints in common, does not forbid). Returns
    every cluster of two or more detections (lists of detection ids)."""
    out: list[list[int]] = []
    if not len(ia):
        return out
    by_frame = np.argsort(frame_of[ia], kind="stable")
    ia, ib, r = ia[by_frame], ib[by_frame], ratio[by_frame]
    bounds = np.flatnonzero(np.diff(frame_of[ia])) + 1
    for seg in np.split(np.arange(len(ia)), bounds):
        cost = {}
        for a, b, v in zip(ia[seg].tolist(), ib[seg].tolist(), r[seg].tolist()):
            cost[(a, b)] = cost[(b, a)] = v
        member: dict[int, list[int]] = {}
        for j in seg[np.argsort(r[seg], kind="stable")]:
            if not r[j] < 1.0:
                break
            a, b = int(ia[j]), int(ib[j])
            ca, cb = member.get(a, [a]), member.get(b, [b])
            if ca is cb or {int(cam_of[x]) for x in ca} & {int(cam_of[x]) for x in cb}:
                continue
            cross = [cost.get((x, y), np.inf) for x in ca for y in cb]
            if any(np.isfinite(v) and v >= 1.0 for v in cross):
                continue
            merged = ca + cb
            for x in merged:
                member[x] = merged
        seen = set()
        for lst in member.values():
            if id(lst) not in seen:
                seen.add(id(lst))
                out.append(sorted(lst))
    return out


def _drop_swapped(clusters: list[list[int]], ia: np.ndarray, ib: np.ndarray,
                  ratio: np.ndarray, flipped: np.ndarray) -> int:
    """Leave out, in place, each cluster's detection whose labels fit the others clearly
    better swapped (:data:`SWAP_MARGIN`, most of its pairs); a cluster of two that fits better swapped is emptied.
    Returns the detections left out."""
    pair = {}
    for a, b, r, f in zip(ia, ib, ratio, flipped):
        pair[(int(a), int(b))] = pair[(int(b), int(a))] = (float(r), float(f))
    dropped = 0
    for members in clusters:
        if len(members) < 2:
            continue
        worse = []
        for m in members:
            rs = [pair.get((m, o)) for o in members if o != m]
            rs = [x for x in rs if x is not None and np.isfinite(x[0])]
            if rs and sum(f < SWAP_MARGIN * r for r, f in rs) > len(rs) / 2:
                worse.append(m)
        if not worse:
            continue
        if len(members) - len(worse) < 2 or len(members) == 2:
            dropped += len(members)
            members.clear()
        else:
            dropped += len(worse)
            members[:] = [m for m in members if m not in worse]
    return dropped


def _slots(person_frames: dict[int, dict[int, list[int]]], cam_of: np.ndarray,
           frame_of: np.ndarray, row_of: np.ndarray, obs: RigObservations) -> list[list[int]]:
    """The people packed into slots (module docstring, step 5): per slot its people."""
    if not person_frames:
        return []
    subject = [candidate_index(c) if c.people is not None else
               np.where(c.real[:, :, 2].any(1), 0, -1) for c in obs.cameras]

    def subject_share(g: int) -> int:
        return sum(1 for members in person_frames[g].values() for m in members
                   if subject[cam_of[m]][frame_of[m]] == row_of[m])

    people = sorted(person_frames, key=lambda g: (-subject_share(g),
                                                  -sum(map(len, person_frames[g].values())), g))
    first, rest = people[0], people[1:]
    rest.sort(key=lambda g: (-sum(map(len, person_frames[g].values())), g))
    slots: list[list[int]] = [[first]]
    busy: list[set[int]] = [set(person_frames[first])]
    for g in rest:
        frames = set(person_frames[g])
        for s, b in enumerate(busy):
            if s and not (b & frames):
                slots[s].append(g)
                b |= frames
                break
        else:
            slots.append([g])
            busy.append(frames)
    return slots
