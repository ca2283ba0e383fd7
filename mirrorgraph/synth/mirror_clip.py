"""A synthetic mirror video composited from real frames: a person and their reflection.

For testing the video path without a recorded mirror video: each frame of a
source video (e.g. one of the Pose2Sim demo videos) is placed on a canvas as the
"person", and beside it the same frame flipped left to right, scaled down and
dimmed as the "reflection" (a mirror image, smaller because farther, darker
because a mirror reflects less than all the light). :class:`MirrorComposite` holds
the two placements, so that a point of the person maps exactly onto its
reflection (:meth:`MirrorComposite.to_reflection`): what a detector finds in the
reflection can be checked against what it finds on the person.

This is an image-space composite, not a rendering of a mirror's geometry: both
copies come from one camera, so it tests detection and tracking, not a
calibration.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["MirrorComposite"]


@dataclass(frozen=True)
class MirrorComposite:
    """Where the person and the reflection go on the canvas.

    Attributes:
        canvas: ``(width, height)`` px of the output.
        person_scale: source px -> canvas px of the person copy.
        person_origin: ``(2,)`` canvas px of the source's top-left corner.
        mirror_scale: source px -> canvas px of the reflection (smaller).
        mirror_origin: ``(2,)`` canvas px of the flipped copy's top-left corner.
        gain: intensity factor of the reflection (< 1: dimmer).
        background: canvas grey level.
    """

    canvas: tuple[int, int] = (1920, 1080)
    person_scale: float = 0.5
    person_origin: tuple[float, float] = (60.0, 60.0)
    mirror_scale: float = 0.4
    mirror_origin: tuple[float, float] = (1200.0, 140.0)
    gain: float = 0.6
    background: int = 40

    def compose(self, frame: np.ndarray) -> np.ndarray:
        """``(H, W, 3)`` uint8 canvas from one ``(h, w, 3)`` uint8 source frame."""
        W, H = self.canvas
        out = np.full((H, W, 3), self.background, np.uint8)
        for scale, origin, flip, gain in ((self.person_scale, self.person_origin, False, 1.0),
                                          (self.mirror_scale, self.mirror_origin, True, self.gain)):
            img = frame[:, ::-1] if flip else frame
            h, w = img.shape[:2]
            sw, sh = round(w * scale), round(h * scale)
            small = cv2.resize(np.ascontiguousarray(img), (sw, sh), interpolation=cv2.INTER_AREA)
            if gain != 1.0:
                small = np.clip(small.astype(np.float32) * gain, 0, 255).astype(np.uint8)
            x0, y0 = round(origin[0]), round(origin[1])
            x1, y1 = min(W, x0 + sw), min(H, y0 + sh)
            out[y0:y1, x0:x1] = small[:y1 - y0, :x1 - x0]
        return out

    def to_person(self, xy: np.ndarray) -> np.ndarray:
        """Source px ``(..., 2)`` -> canvas px of the person copy."""
        return np.asarray(xy, float) * self.person_scale + np.asarray(self.person_origin)

    def to_reflection(self, xy_canvas: np.ndarray, source_width: int) -> np.ndarray:
        """Canvas px of the person copy ``(..., 2)`` -> canvas px of the same point in
        the reflection (the flipped, scaled copy)."""
        src = (np.asarray(xy_canvas, float) - np.asarray(self.person_origin)) / self.person_scale
        flipped = np.stack([source_width - 1 - src[..., 0], src[..., 1]], axis=-1)
        return flipped * self.mirror_scale + np.asarray(self.mirror_origin)



def mirror_homography(K: np.ndarray, normal: np.ndarray, distance: float,
                      depth: float) -> np.ndarray:
    """``(3, 3)`` image of the reflection of the fronto-parallel plane ``z = depth``.

    A mirror ``n . X = d`` (camera frame, ``n`` pointing away from the camera) maps
    a point ``X`` to ``S(X) = (I - 2 n n^T) X + 2 d n``; on the plane ``z = depth``,
    ``X = depth * K^-1 x / (K^-1 x)_z``, so the reflection is seen at
    ``H x`` with ``H = K ((I - 2 n n^T) + (2 d / depth) n e_z^T) K^-1``. For every
    pixel ``x`` (not only those of the plane) ``H x = x + c e`` with ``e = K n``:
    each pixel and its image lie on a line through the epipole, the reflective
    epipolar geometry of the mirror holds exactly. A person treated so is a flat
    cut-out at ``depth``: the epipole (the mirror's normal) is exact, the depths of
    the reflection are those of the cut-out.
    """
    K = np.asarray(K, float)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    A = np.eye(3) - 2.0 * np.outer(n, n) + (2.0 * distance / depth) * np.outer(n, [0, 0, 1.0])
    return K @ A @ np.linalg.inv(K)


@dataclass(frozen=True)
class PlanarMirrorClip:
    """A mirror video from a one-camera video: the frame, widened, with the reflection of
    the scene as a flat cut-out (:func:`mirror_homography`) in the part of the widened
    frame right of ``split`` (the mirror's edge), dimmed by ``gain``.

    Attributes:
        K: ``(3, 3)`` camera matrix of the source frames (px), also the clip's.
        normal: ``(3,)`` mirror normal, camera frame.
        distance: mirror distance (the unit of ``depth``).
        depth: depth of the cut-out plane (the person's distance).
        width: the clip's width, px (height: the source's).
        split: first column of the mirror region.
        gain: intensity factor of the reflection.
    """

    K: np.ndarray
    normal: np.ndarray
    distance: float
    depth: float
    width: int
    split: int
    gain: float = 0.7

    @property
    def H(self) -> np.ndarray:
        """``(3, 3)`` source pixel -> reflection pixel."""
        return mirror_homography(self.K, self.normal, self.distance, self.depth)

    @property
    def epipole(self) -> np.ndarray:
        """``(2,)`` the epipole ``K n``, px."""
        e = np.asarray(self.K, float) @ np.asarray(self.normal, float)
        return e[:2] / e[2]

    def compose(self, frame: np.ndarray) -> np.ndarray:
        """``(h, width, 3)`` uint8 clip frame from an ``(h, w, 3)`` uint8 source frame."""
        h, w = frame.shape[:2]
        out = np.zeros((h, self.width, 3), np.uint8)
        out[:, :min(w, self.split)] = frame[:, :min(w, self.split)]
        warped = cv2.warpPerspective(frame, self.H, (self.width, h), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT)
        mirror = np.clip(warped[:, self.split:].astype(np.float32) * self.gain, 0, 255)
        out[:, self.split:] = mirror.astype(np.uint8)
        return out
