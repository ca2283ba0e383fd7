"""One skeleton per person: non-maximum suppression of poses by keypoint similarity and box.

A detector run on the whole frame and on overlapping tiles, and a tracker that
follows every person by their own landmarks, can put two or three skeletons on
one person (from two views of them, from a crop turned the wrong way, from two
tracks that converged). :func:`pose_nms` keeps one: of poses that are one person
by their keypoints or their boxes, the first in the order given.

Keypoint similarity is COCO's object keypoint similarity (OKS; read in the COCO
keypoint evaluation's definition, https://cocodataset.org/#keypoints-eval, and in
MMPose's ``mmpose/evaluation/functional/nms.py`` ``oks_iou`` / ``oks_nms``, which
use it between two detections, the area their mean)::

    OKS(a, b) = mean_i exp(-d_i^2 / (2 s^2 k_i^2))    over the keypoints seen in both

with ``d_i`` the distance of keypoint ``i`` between the two poses (px), ``s^2``
the object's area (here the mean of the two poses' keypoint-box areas, px^2) and
``k_i = 2 sigma_i`` the keypoint's spread in COCO's human annotations
(:data:`BLAZEPOSE_SIGMAS`). 1 is the same pose; for two poses of one person
from two crops it is typically above 0.8, for two people side by side below 0.1.
A detector may label one person with left and right swapped in one of two crops
(a person seen from behind): with ``flip`` the similarity is the larger of the
poses' as labelled and with one of them mirrored.

OKS compares labels; a landmark model run on a crop turned by about 90 deg
returns a skeleton on the person with its labels scrambled (OKS 0.0-0.5 with the
person's own skeleton, measured on a composited mirror clip). Such a skeleton lies
on the person's body: :func:`on_body_matrix` counts the share of one pose's
keypoints that lie on another's body (its bones, torso and keypoints, within a
tenth of the smaller one's size), whatever their labels; a pose nearly all on a kept one's body
is that person too.
"""

from __future__ import annotations

import numpy as np

from ..skeletons import BLAZEPOSE

__all__ = ["COCO_SIGMAS", "BLAZEPOSE_SIGMAS", "BLAZEPOSE_BODY", "pose_boxes", "box_areas",
           "box_iou_matrix", "oks_matrix", "on_body_matrix", "pose_nms"]

#: COCO's per-keypoint sigmas (nose, eyes, ears, shoulders, elbows, wrists, hips, knees,
#: ankles), the COCO keypoint evaluation's values.
COCO_SIGMAS = {"nose": 0.026, "eye": 0.025, "ear": 0.035, "shoulder": 0.079, "elbow": 0.072,
               "wrist": 0.062, "hip": 0.107, "knee": 0.087, "ankle": 0.089}

#: ``(33,)`` sigmas of :data:`~mirrorgraph.skeletons.BLAZEPOSE`: COCO's where the
#: keypoint is COCO's; the inner and outer eye corners the eye's, the mouth the nose's,
#: the hand's points (pinky, index, thumb) the wrist's, heel and toe the ankle's.
BLAZEPOSE_SIGMAS = np.array([
    COCO_SIGMAS["nose"] if n in ("nose", "left_mouth", "right_mouth") else
    COCO_SIGMAS["eye"] if "eye" in n else
    COCO_SIGMAS["wrist"] if n.split("_")[-1] in ("pinky", "index", "thumb", "wrist") else
    COCO_SIGMAS["ankle"] if n.split("_")[-1] in ("heel", "toe", "ankle") else
    COCO_SIGMAS[n.split("_")[-1]] for n in BLAZEPOSE.joints])


def _segments(names: tuple[tuple[str, str], ...]) -> np.ndarray:
    return np.array([[BLAZEPOSE.index(a), BLAZEPOSE.index(b)] for a, b in names])


#: ``(S, 2)`` joint index pairs of the body's segments of
#: :data:`~mirrorgraph.skeletons.BLAZEPOSE`: its bones, the torso's sides and
#: diagonals, neck-to-nose lines, hands and feet (every keypoint also counts as a point).
BLAZEPOSE_BODY = _segments(tuple(BLAZEPOSE.bones.values()) + tuple(
    (f"{s}_{a}", f"{t}_{b}") for s, t, a, b in (
        ("left", "left", "shoulder", "hip"), ("right", "right", "shoulder", "hip"),
        ("left", "right", "shoulder", "hip"), ("right", "left", "shoulder", "hip"),
        ("left", "left", "wrist", "index"), ("right", "right", "wrist", "index"),
        ("left", "left", "wrist", "pinky"), ("right", "right", "wrist", "pinky"),
        ("left", "left", "ankle", "heel"), ("right", "right", "ankle", "heel"),
        ("left", "left", "heel", "big_toe"), ("right", "right", "heel", "big_toe"),
        ("left", "left", "ankle", "big_toe"), ("right", "right", "ankle", "big_toe"))) + (
        ("nose", "left_shoulder"), ("nose", "right_shoulder")))


def pose_boxes(xy: np.ndarray, visibility: np.ndarray, min_visibility: float = 0.5
               ) -> np.ndarray:
    """``(N, 4)`` ``x1, y1, x2, y2`` px of each pose's keypoints seen above
    ``min_visibility`` (all of them where fewer than 4 are).

    Args:
        xy: ``(N, J, 2)`` keypoints, px (finite).
        visibility: ``(N, J)`` in ``[0, 1]``.
    """
    xy = np.asarray(xy, float)
    seen = np.asarray(visibility) >= min_visibility
    seen |= (seen.sum(axis=1) < 4)[:, None]
    lo = np.where(seen[..., None], xy, np.inf).min(axis=1)
    hi = np.where(seen[..., None], xy, -np.inf).max(axis=1)
    return np.concatenate([lo, hi], axis=1).reshape(-1, 4)


def box_areas(boxes: np.ndarray) -> np.ndarray:
    """``(N,)`` areas px^2 of ``(N, 4)`` ``x1, y1, x2, y2`` boxes (0 for empty ones)."""
    b = np.asarray(boxes, float)
    return np.prod(np.clip(b[:, 2:] - b[:, :2], 0, None), axis=1)


def box_iou_matrix(boxes: np.ndarray) -> np.ndarray:
    """``(N, N)`` intersection over union of every pair of ``(N, 4)`` boxes."""
    b = np.asarray(boxes, float)
    lo = np.maximum(b[:, None, :2], b[None, :, :2])
    hi = np.minimum(b[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=2)
    area = box_areas(b)
    union = area[:, None] + area[None, :] - inter
    return np.where(union > 0, inter / np.maximum(union, 1e-12), 0.0)


def oks_matrix(xy: np.ndarray, visibility: np.ndarray, boxes: np.ndarray | None = None, *,
               sigmas: np.ndarray | None = None, min_visibility: float = 0.5,
               flip: np.ndarray | None = None) -> np.ndarray:
    """``(N, N)`` object keypoint similarity of every pair of poses (module docstring).

    Args:
        xy: ``(N, J, 2)`` keypoints, px (finite).
        visibility: ``(N, J)``: a keypoint counts where both poses see it at
            ``min_visibility`` or more (every keypoint where fewer than 4 do).
        boxes: ``(N, 4)`` the poses' boxes for their areas (default :func:`pose_boxes`).
        sigmas: ``(J,)`` (default :data:`BLAZEPOSE_SIGMAS` for 33 keypoints, else
            0.07 each, about COCO's mean).
        flip: ``(J,)`` left/right permutation: the larger of the similarity as labelled
            and with the second pose's labels swapped.
    """
    xy = np.asarray(xy, float)
    vis = np.asarray(visibility, float)
    N, J = xy.shape[:2]
    if sigmas is None:
        sigmas = BLAZEPOSE_SIGMAS if J == len(BLAZEPOSE_SIGMAS) else np.full(J, 0.07)
    if boxes is None:
        boxes = pose_boxes(xy, vis, min_visibility)
    area = box_areas(boxes)
    scale2 = np.maximum((area[:, None] + area[None, :]) / 2.0, 1.0)       # s^2, (N, N)
    denom = 2.0 * scale2[..., None] * (2.0 * np.asarray(sigmas, float)) ** 2   # (N, N, J)
    seen = vis >= min_visibility

    def similarity(other_xy: np.ndarray, other_seen: np.ndarray) -> np.ndarray:
        d2 = np.sum((xy[:, None] - other_xy[None]) ** 2, axis=-1)          # (N, N, J)
        both = seen[:, None] & other_seen[None]
        both |= (both.sum(axis=-1) < 4)[..., None]
        return np.sum(np.exp(-d2 / denom) * both, axis=-1) / both.sum(axis=-1)

    out = similarity(xy, seen)
    if flip is not None:
        out = np.maximum(out, similarity(xy[:, flip], seen[:, flip]))
    return out


def on_body_matrix(xy: np.ndarray, visibility: np.ndarray, segments: np.ndarray, *,
                   tolerance: float = 0.1, min_visibility: float = 0.5,
                   boxes: np.ndarray | None = None) -> np.ndarray:
    """``(N, N)``: entry ``[i, j]`` the share of pose ``i``'s keypoints (those it sees at
    ``min_visibility``, all where fewer than 4) within ``tolerance`` times the smaller
    of the two poses' box diagonals of pose ``j``'s body: its segments ``segments``
    between keypoints it sees, and those keypoints. Labels play no part. (The
    smaller size: a person beside a larger one is not on the larger one's body for
    being within a tenth of the larger one's size of it.)

    Args:
        xy: ``(N, J, 2)`` keypoints, px (finite); visibility ``(N, J)``.
        segments: ``(S, 2)`` joint index pairs (e.g. :data:`BLAZEPOSE_BODY`).
    """
    xy = np.asarray(xy, float)
    seen = np.asarray(visibility) >= min_visibility
    seen |= (seen.sum(axis=1) < 4)[:, None]
    N, J = seen.shape
    seg = np.asarray(segments, int).reshape(-1, 2)
    seg = np.concatenate([seg, np.repeat(np.arange(J)[:, None], 2, axis=1)])   # + points
    a, b = xy[:, seg[:, 0]], xy[:, seg[:, 1]]                     # (N, S, 2) each
    usable = seen[:, seg[:, 0]] & seen[:, seg[:, 1]]             # (N, S)
    ab = b - a
    len2 = np.maximum(np.sum(ab ** 2, axis=-1), 1e-12)            # (N, S)
    # point k of pose i against segment s of pose j: (N_i, J, N_j, S)
    ap = xy[:, :, None, None, :] - a[None, None]
    t = np.clip(np.sum(ap * ab[None, None], axis=-1) / len2[None, None], 0.0, 1.0)
    d = np.linalg.norm(ap - t[..., None] * ab[None, None], axis=-1)
    d = np.where(usable[None, None], d, np.inf).min(axis=-1)      # (N_i, J, N_j)
    if boxes is None:
        boxes = pose_boxes(xy, visibility, min_visibility)
    diag = np.hypot(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1])
    tol = tolerance * np.minimum(diag[:, None], diag[None, :])    # (N_i, N_j)
    near = (d <= tol[:, None, :]) & seen[:, :, None]
    return near.sum(axis=1) / seen.sum(axis=1)[:, None]


def pose_nms(xy: np.ndarray, visibility: np.ndarray, *, oks_threshold: float = 0.5,
             iou_threshold: float = 0.7, on_body: float | None = 0.85,
             segments: np.ndarray | None = None, sigmas: np.ndarray | None = None,
             min_visibility: float = 0.5, flip: np.ndarray | None = None) -> np.ndarray:
    """Indices of the poses kept, in the given order: each pose is dropped where a pose
    before it and kept is the same person, by keypoints (OKS above ``oks_threshold``,
    :func:`oks_matrix`), by box (IoU of their keypoint boxes above ``iou_threshold``)
    or, with ``on_body``, by lying on its body (more than that share of its keypoints,
    :func:`on_body_matrix` with ``segments``, default :data:`BLAZEPOSE_BODY` for 33
    keypoints).

    The order is the caller's preference (e.g. the oldest track first, then new
    detections by score), as greedy NMS keeps the best-scoring box.

    Args:
        xy: ``(N, J, 2)`` keypoints, px; visibility ``(N, J)``.

    Returns:
        ``(K,)`` int indices into the ``N`` poses, ascending.
    """
    xy = np.asarray(xy, float)
    if len(xy) < 2:
        return np.arange(len(xy))
    boxes = pose_boxes(xy, visibility, min_visibility)
    same = (oks_matrix(xy, visibility, boxes, sigmas=sigmas, min_visibility=min_visibility,
                       flip=flip) > oks_threshold) | (box_iou_matrix(boxes) > iou_threshold)
    if on_body is not None:
        if segments is None and xy.shape[1] == BLAZEPOSE.num_joints:
            segments = BLAZEPOSE_BODY
        if segments is not None:
            same |= on_body_matrix(xy, visibility, segments, min_visibility=min_visibility,
                                   boxes=boxes) > on_body
    keep: list[int] = []
    for i in range(len(xy)):
        if not any(same[i, k] for k in keep):
            keep.append(i)
    return np.array(keep, dtype=np.int64)
