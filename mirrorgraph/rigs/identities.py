"""Who is who across snapshots: the people of frames far apart told apart by their bones.

Frames far apart in time (snapshots, :func:`~.tracking.segments`) share no track, so the
people of one stretch of frames are not followed into the next. The graph of every
person (:mod:`mirrorgraph.pipelines.rig_people`) gives each slot of the layout of several
people one set of bone lengths, constant over its frames: slots that hold different
people in different stretches hold them to one set of lengths, and that biases the rig
(``bench/RESULTS_rig_people.md``). A body's proportions tell people apart where their
place and motion cannot (staff of an operating room, ~75 s between snapshots):

1. **Each person's bones** (:func:`body_lengths`): their joints triangulated with the
   current rig (:func:`mirrorgraph.geometry.triangulate`), the median length of every
   bone between two calibration joints over their frames.
2. **Slots** (:func:`slots_by_body`): a clustering of those lengths with one person of a
   stretch per slot at most (the k-means of Lloyd, *IEEE Trans. Inf. Theory* 28, 1982,
   its assignment step one optimal assignment per stretch, Kuhn's Hungarian method):
   the slots start from the stretch showing the most people, each person's distance to
   a slot the median over the bones both have of the absolute difference of the log
   lengths (a ratio, robust to a bone measured wrong), each slot's lengths the median of
   its people's, until no person changes slot. Two people of like proportions may
   swap slots: their bones then differ little, which is what the slots are for.

Lengths in the rig's unit; ``(B,)`` arrays over the skeleton's calibration bones, NaN
where not measured.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..geometry import camera_projection, triangulate
from ..skeletons import Skeleton

__all__ = ["MAX_ITERATIONS", "MIN_BONES", "body_lengths", "calibration_bones", "people_by_body",
           "slots_by_body"]

#: Rounds of :func:`slots_by_body` at most.
MAX_ITERATIONS = 30

#: Bones two people must both have measured for their distance; fewer: any slot fits.
MIN_BONES = 3


def calibration_bones(skeleton: Skeleton) -> np.ndarray:
    """``(B, 2)`` joint indices of the skeleton's bones between two calibration joints."""
    keep = set(np.asarray(skeleton.calibration_joints, int).tolist())
    bones = np.asarray(skeleton.bone_index, int)
    return bones[[int(a) in keep and int(b) in keep for a, b in bones]].reshape(-1, 2)


def body_lengths(pixels: list[np.ndarray], Ks: list[np.ndarray], poses: list[np.ndarray],
                 bones: np.ndarray, min_confidence: float) -> np.ndarray:
    """``(B,)`` one person's bone lengths: their joints triangulated with the rig, each
    bone's median length over the frames where both its joints are.

    Args:
        pixels: per camera ``(F, J, 3)`` the person's detections in their ``F`` frames
            (undistorted px, confidence; NaN / 0 where the camera does not hold them).
        Ks: ``(3, 3)`` per camera; poses: ``(4, 4)`` camera-to-world per camera.
        bones: ``(B, 2)`` joint indices; min_confidence: joints below it are not used.
    """
    P = [camera_projection(K, T) for K, T in zip(Ks, poses)]
    seen = [(p[..., 2] >= min_confidence) & np.isfinite(p[..., :2]).all(-1) for p in pixels]
    X, ok = triangulate(P, [p[..., :2] for p in pixels], seen)                # (F, J, 3)
    d = np.linalg.norm(X[:, bones[:, 0]] - X[:, bones[:, 1]], axis=-1)           # (F, B)
    both = ok[:, bones[:, 0]] & ok[:, bones[:, 1]]
    d = np.where(both, d, np.nan)
    out = np.full(len(bones), np.nan)
    have = both.any(0)
    out[have] = np.nanmedian(d[:, have], axis=0)
    return out


def _distances(logs: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """``(G, S)`` the median over common bones of ``|log l_g - log c_s|`` (0 with fewer
    than :data:`MIN_BONES` in common)."""
    diff = np.abs(logs[:, None] - centres[None])                             # (G, S, B)
    common = np.isfinite(diff)
    out = np.zeros(diff.shape[:2])
    enough = common.sum(-1) >= MIN_BONES
    if enough.any():
        out[enough] = np.nanmedian(diff[enough], axis=-1)
    return out


def slots_by_body(lengths: np.ndarray, stretch: np.ndarray, count: int) -> np.ndarray:
    """``(G,)`` the slot (``0 .. count - 1``) of each of ``G`` people, by their bones
    (module docstring, step 2), no two people of a stretch in one slot.

    Args:
        lengths: ``(G, B)`` each person's bone lengths (:func:`body_lengths`; NaN where
            not measured).
        stretch: ``(G,)`` each person's stretch of frames (people of one stretch are
            different people); at most ``count`` people a stretch.
        count: the slots.
    """
    lengths = np.asarray(lengths, float)
    stretch = np.asarray(stretch)
    G = len(lengths)
    logs = np.log(np.where(lengths > 0, lengths, np.nan))
    _, where, sizes = np.unique(stretch, return_inverse=True, return_counts=True)
    where = where.ravel()
    if sizes.max() > count:
        raise ValueError(f"a stretch holds {sizes.max()} people, more than {count} slots")
    # the slots start from the stretch showing the most people, the most bones among those
    measured = np.isfinite(logs).sum(1)
    score = [(sizes[s], measured[where == s].sum()) for s in range(len(sizes))]
    seed = max(range(len(sizes)), key=lambda s: score[s])
    centres = np.full((count, logs.shape[1]), np.nan)
    start = np.flatnonzero(where == seed)
    centres[:len(start)] = logs[start]
    groups = [np.flatnonzero(where == s) for s in range(len(sizes))]
    slot = np.full(G, -1)
    for _ in range(MAX_ITERATIONS):
        new = np.full(G, -1)
        cost = _distances(logs, np.where(np.isfinite(centres), centres, np.nan))
        cost[:, ~np.isfinite(centres).any(1)] = 0.0           # an empty slot takes anyone
        for rows in groups:
            r, c = linear_sum_assignment(cost[rows])
            new[rows[r]] = c
        if np.array_equal(new, slot):
            break
        slot = new
        for s in range(count):
            mine = logs[slot == s]
            if len(mine) and np.isfinite(mine).any():
                with warnings.catch_warnings():            # a bone no one of the slot has
                    warnings.simplefilter("ignore", RuntimeWarning)
                    centres[s] = np.nanmedian(mine, axis=0)
    return slot


def people_by_body(person_frames: dict[int, dict[int, list[int]]], X: np.ndarray,
                   cam_of: np.ndarray, stretch: np.ndarray, Ks: list[np.ndarray],
                   poses: list[np.ndarray], skeleton: Skeleton, min_confidence: float
                   ) -> list[list[int]]:
    """The people of :func:`mirrorgraph.rigs.people.associate_people` put in slots by
    their bones (:func:`body_lengths`, :func:`slots_by_body`): per slot its people, the
    slot holding most detections first.

    Args:
        person_frames: person -> frame -> the detection ids of their cluster there.
        X: ``(N, J, 3)`` every detection (undistorted px, confidence); cam_of: ``(N,)``
            each one's camera.
        stretch: ``(T,)`` each frame's stretch (:func:`~.tracking.segments`).
        Ks, poses: the current rig (``(3, 3)``, camera-to-world ``(4, 4)``, per camera).
        skeleton: the layout of one person; min_confidence: joints below it unused.
    """
    bones = calibration_bones(skeleton)
    people = sorted(person_frames)
    C, J = len(Ks), skeleton.num_joints
    lengths, where = [], []
    for g in people:
        frames = sorted(person_frames[g])
        pix = np.full((C, len(frames), J, 3), np.nan)
        pix[..., 2] = 0.0
        for i, f in enumerate(frames):
            for m in person_frames[g][f]:
                pix[cam_of[m], i] = X[m]
        lengths.append(body_lengths(list(pix), Ks, poses, bones, min_confidence))
        where.append(int(stretch[frames[0]]))
    _, counts = np.unique(where, return_counts=True)
    slot = slots_by_body(np.array(lengths).reshape(len(people), len(bones)), np.array(where),
                         int(counts.max()))
    held = [sum(len(m) for g, s in zip(people, slot) if s == k
                for m in person_frames[g].values()) for k in range(int(counts.max()))]
    order = sorted(range(len(held)), key=lambda k: (-held[k], k))
    return [[g for g, s in zip(people, slot) if s == k] for k in order if held[k]]
