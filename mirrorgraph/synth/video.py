"""A synthetic scene drawn as a video: the person and their reflection as simple bodies.

Each frame draws the true image of the joints (:attr:`SyntheticScene.real_image`,
:attr:`SyntheticScene.mirror_image`: the camera's own projection, distortion included) as
a body a pose detector takes for a person: a head, a neck, a torso and limbs as rounded
strokes of a fixed thickness in metres (so a farther body is thinner), painted far to
near, the reflection dimmer (a mirror reflects less than all the light) and behind the
person where they overlap. The scene's detector noise and outliers are not drawn: the
detector that reads the video makes its own. What it is for: trying ``calibrate clip.mp4``,
``live clip.mp4``, ``--video`` and ``--render`` on a scene with a known answer
(``tests/synth/test_video.py``: BlazePose finds both bodies in every frame of seed 1).
A body drawn across much of the frame or cut by its edge is not a person to BlazePose
(``make_scene(seed=2)``: none found).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["render_frame", "write_scene_video", "VIDEO_JOINTS"]

#: The joints the drawing needs (every layout mirrorgraph reads has them).
VIDEO_JOINTS = ("nose", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
                "left_wrist", "right_wrist", "left_hip", "right_hip", "left_knee",
                "right_knee", "left_ankle", "right_ankle")

#: Strokes: two joints and the limb's diameter, metres.
_LIMBS = (("left_shoulder", "left_elbow", 0.10), ("left_elbow", "left_wrist", 0.08),
          ("right_shoulder", "right_elbow", 0.10), ("right_elbow", "right_wrist", 0.08),
          ("left_hip", "left_knee", 0.16), ("left_knee", "left_ankle", 0.12),
          ("right_hip", "right_knee", 0.16), ("right_knee", "right_ankle", 0.12))
_HEAD_M, _NECK_M, _CHEST_M, _EYE_M = 0.22, 0.10, 0.24, 0.02   # heights, widths: metres
_SKIN, _SHIRT, _TROUSERS, _EYE = (150, 180, 220), (180, 90, 40), (60, 50, 40), (40, 30, 30)
_BACKGROUND = (90, 100, 110)


def _body(img: np.ndarray, p: np.ndarray, z: np.ndarray, f: float, index: dict,
          gain: float) -> None:
    """Draw one body: ``p`` ``(J, 2)`` px, ``z`` ``(J,)`` depths (m), ``f`` the focal
    length (px); joints not finite are left out."""
    import cv2

    def col(c):
        return tuple(float(v) * gain for v in c)

    def pt(x):
        return tuple(int(v) for v in np.round(x))

    def width(m, depth):
        return max(2, int(round(f * m / depth)))

    head_ids = [index[n] for n in ("nose", "left_eye", "right_eye", "left_ear", "right_ear")
                if n in index and np.isfinite(p[index[n]]).all()]
    parts = []
    for a, b, m in _LIMBS:
        i, j = index[a], index[b]
        if np.isfinite(p[[i, j]]).all() and z[i] > 0 and z[j] > 0:
            colour = _TROUSERS if "hip" in a or "knee" in a else (
                _SHIRT if "shoulder" in a else _SKIN)
            parts.append((0.5 * (z[i] + z[j]), "stroke", (p[i], p[j], width(m, 0.5 * (z[i] + z[j])),
                                                          colour)))
    torso = [index[n] for n in ("left_shoulder", "right_shoulder", "right_hip", "left_hip")]
    if np.isfinite(p[torso]).all() and (z[torso] > 0).all():
        depth = float(np.mean(z[torso]))
        parts.append((depth, "torso", p[torso]))
        # the chest's depth: a body seen edge-on is no thinner than this
        parts.append((depth - 1e-3, "stroke", (p[torso[:2]].mean(0), p[torso[2:]].mean(0),
                                               width(_CHEST_M, depth), _SHIRT)))
    if head_ids and (z[head_ids] > 0).all():
        head, depth = p[head_ids].mean(0), float(np.mean(z[head_ids]))
        shoulders = p[torso[:2]].mean(0)
        if np.isfinite(shoulders).all():
            parts.append((depth + 1e-3, "stroke", (shoulders, head, width(_NECK_M, depth), _SKIN)))
        parts.append((depth, "head", (head, f * _HEAD_M / depth)))
        eyes = [index[n] for n in ("left_eye", "right_eye") if n in index]
        if eyes and np.isfinite(p[eyes]).all():
            parts.append((depth - 1e-3, "eyes", (p[eyes], width(_EYE_M, depth))))
    for _, kind, arg in sorted(parts, key=lambda t: -t[0]):      # far to near
        if kind == "stroke":
            a, b, w, colour = arg
            cv2.line(img, pt(a), pt(b), col(colour), w, cv2.LINE_AA)
        elif kind == "eyes":
            points, w = arg
            for e in points:
                cv2.circle(img, pt(e), max(1, w // 2), col(_EYE), -1, cv2.LINE_AA)
        elif kind == "torso":
            cv2.fillConvexPoly(img, np.round(arg).astype(np.int32), col(_SHIRT), cv2.LINE_AA)
        else:
            centre, size = arg
            cv2.ellipse(img, pt(centre), (max(2, int(0.42 * size)), max(2, int(0.5 * size))),
                        0, 0, 360, col(_SKIN), -1, cv2.LINE_AA)


def render_frame(scene, t: int, *, reflection_gain: float = 0.7) -> np.ndarray:
    """Frame ``t`` of ``scene`` (:class:`~mirrorgraph.synth.scene.SyntheticScene`) as an
    ``(H, W, 3)`` uint8 BGR image: the reflection, then the person over it."""
    from .. import geometry as geo

    W, H = scene.image_size
    img = np.empty((H, W, 3), np.uint8)
    img[:] = _BACKGROUND
    sk = scene.skeleton
    index = {n: sk.index(n) for n in (*VIDEO_JOINTS, "left_eye", "right_eye", "left_ear",
                                      "right_ear") if sk.has(n)}
    X = scene.joints3d[t]
    S = geo.reflect_points(X, scene.normal, scene.distance)
    f = float(scene.K[0, 0])
    _body(img, scene.mirror_image[t], S[:, 2], f, index, reflection_gain)
    _body(img, scene.real_image[t], X[:, 2], f, index, 1.0)
    return img


def write_scene_video(scene, path: str | os.PathLike, frames: int | None = None,
                      progress=None) -> tuple[Path, str | None]:
    """Write the scene's first ``frames`` frames (default all) as a video at its frame
    rate and image size (:func:`mirrorgraph.io.video_out.open_video_writer`: ``.mp4``
    or ``.webm``).

    Returns:
        ``(path, note)``: ``note`` where browsers will not play the codec, else ``None``.

    Raises:
        InputError: the skeleton lacks a joint of :data:`VIDEO_JOINTS`; no codec opens.
    """
    from ..io.video_out import open_video_writer

    missing = [n for n in VIDEO_JOINTS if not scene.skeleton.has(n)]
    if missing:
        raise InputError(f"the video draws {', '.join(missing)}, which "
                         f"{scene.skeleton.name} lacks", field="skeleton")
    path = Path(path)
    count = len(scene.frame_ids) if frames is None else min(int(frames), len(scene.frame_ids))
    tmp = path.with_name(f".{path.stem}.part{path.suffix}")
    writer, _, note = open_video_writer(tmp, scene.fps, scene.image_size)
    try:
        for t in range(count):
            writer.write(render_frame(scene, t))
            if progress is not None:
                progress()
        writer.release()
        os.replace(tmp, path)
    finally:
        writer.release()
        if tmp.exists():
            tmp.unlink()
    return path, None if note is None else note.replace(tmp.name, path.name)
