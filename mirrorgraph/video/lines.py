"""Line segments of a static camera's scene: the background of sampled frames, OpenCV's LSD.

The camera of a mirror calibration is fixed, so the room's edges stand still while the
people move: the per-pixel median of frames sampled over the video
(:func:`background`) keeps the room and drops whoever moves through it. Where a
person stays (a pixel inside a person's box in more than ``occupied`` of the frames:
:func:`person_mask`, from the keypoints) the median still shows them, so segments
there are dropped. OpenCV's line segment detector (von Gioi et al., "LSD: a fast line
segment detector with a false detection control", PAMI 2010) finds the segments
(:func:`scene_segments`); :mod:`mirrorgraph.initial.vanishing` turns them into a focal
length.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .reader import probe, quiet_stderr

__all__ = ["SceneSegments", "background", "person_mask", "scene_segments", "image_segments",
           "SEEK_GAP"]

#: Frames further apart than this are reached by seeking, nearer ones by decoding
#: through (a seek decodes from the previous key frame anyway).
SEEK_GAP = 60


@dataclass
class SceneSegments:
    """Line segments of a video's static scene.

    Attributes:
        segments: ``(N, 4)`` ``x1, y1, x2, y2`` px (the video's pixels).
        image_size: ``(width, height)`` px.
        frames: frames the background was taken over.
        masked_fraction: fraction of the image masked as a person's.
    """

    segments: np.ndarray
    image_size: tuple[int, int]
    frames: int
    masked_fraction: float


def background(path: str | os.PathLike, frames: int = 31) -> tuple[np.ndarray, int]:
    """The per-pixel median grey image of ``frames`` frames spread evenly over the video
    (seeking to each), and how many were read.

    Returns:
        ``(H, W)`` uint8 and the count (0 with an empty image where none could be read).
    """
    info = probe(path)
    n = max(info.frame_count, 1)
    wanted = np.unique(np.linspace(0, n - 1, max(1, min(frames, n))).round().astype(int))
    with quiet_stderr():                    # probe has checked that it opens
        cap = cv2.VideoCapture(str(Path(path)))
    grey = []
    at = 0                                  # the next frame the decoder gives
    try:
        for t in wanted:
            if t - at > SEEK_GAP:           # far ahead: seek; near: decode through
                cap.set(cv2.CAP_PROP_POS_FRAMES, int(t))
                at = int(t)
            ok = True
            while ok and at < t:
                ok = cap.grab()
                at += 1
            ok, bgr = cap.read() if ok else (False, None)
            at += 1
            if ok:
                grey.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
    finally:
        cap.release()
    if not grey:
        return np.zeros((info.height, info.width), np.uint8), 0
    return np.median(np.stack(grey), axis=0).astype(np.uint8), len(grey)


def person_mask(people: list[np.ndarray], size: tuple[int, int], *, occupied: float = 0.3,
                margin: float = 0.15, min_confidence: float = 0.1) -> np.ndarray:
    """``(H, W)`` bool: pixels inside a person's box (their keypoints' box widened by
    ``margin`` of its size) in more than ``occupied`` of the frames.

    Args:
        people: per frame ``(P, J, 3)`` keypoints ``x, y, confidence`` px.
        size: ``(width, height)`` px.
    """
    W, H = int(size[0]), int(size[1])
    count = np.zeros((H + 1, W + 1), np.float64)
    frames = 0
    for p in people:
        p = np.asarray(p, dtype=float)
        frames += 1
        for person in p.reshape(-1, *p.shape[-2:]) if p.size else []:
            ok = (person[:, 2] > min_confidence) & np.isfinite(person[:, :2]).all(1)
            if np.count_nonzero(ok) < 2:
                continue
            lo, hi = person[ok, :2].min(0), person[ok, :2].max(0)
            pad = margin * (hi - lo)
            x0, y0 = np.clip(np.floor(lo - pad), 0, [W, H]).astype(int)
            x1, y1 = np.clip(np.ceil(hi + pad), 0, [W, H]).astype(int)
            count[y0, x0] += 1                      # 2D difference array of the box
            count[y0, x1] -= 1
            count[y1, x0] -= 1
            count[y1, x1] += 1
    if frames == 0:
        return np.zeros((H, W), bool)
    occ = count.cumsum(0).cumsum(1)[:H, :W] / frames
    return occ > occupied


def scene_segments(path: str | os.PathLike, people: list[np.ndarray] | None = None, *,
                   frames: int = 31, min_length: float = 0.02) -> SceneSegments:
    """Line segments of the video's static scene (see the module docstring).

    Args:
        path: the video.
        people: per frame ``(P, J, 3)`` keypoints of every detection (``None``: no mask).
        frames: frames of the median background.
        min_length: shortest segment kept, fraction of the image's larger side.

    Returns:
        :class:`SceneSegments`; segments touching the person mask are dropped.
    """
    img, read = background(path, frames)
    H, W = img.shape
    if read == 0:
        return SceneSegments(np.zeros((0, 4)), (W, H), 0, 0.0)
    mask = person_mask(people, (W, H)) if people else None
    seg = image_segments(img, mask, min_length=min_length)
    return SceneSegments(seg, (W, H), read, 0.0 if mask is None else float(mask.mean()))


def image_segments(image: np.ndarray, mask: np.ndarray | None = None, *,
                   min_length: float = 0.02) -> np.ndarray:
    """``(N, 4)`` line segments ``x1, y1, x2, y2`` px of one image (OpenCV's LSD).

    Args:
        image: ``(H, W)`` grey or ``(H, W, 3)`` RGB uint8.
        mask: ``(H, W)`` bool: segments with an endpoint or the midpoint inside are
            dropped (``None``: none).
        min_length: shortest segment kept, fraction of the image's larger side.
    """
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    H, W = img.shape
    found = cv2.createLineSegmentDetector().detect(np.ascontiguousarray(img, np.uint8))[0]
    seg = np.zeros((0, 4)) if found is None else found.reshape(-1, 4).astype(float)
    seg = seg[np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]) >= min_length * max(W, H)]
    if mask is not None and mask.any() and len(seg):
        hit = np.zeros(len(seg), bool)
        for p in (seg[:, :2], seg[:, 2:], 0.5 * (seg[:, :2] + seg[:, 2:])):
            x = np.clip(p[:, 0].astype(int), 0, W - 1)
            y = np.clip(p[:, 1].astype(int), 0, H - 1)
            hit |= mask[y, x]
        seg = seg[~hit]
    return seg
