"""A synthetic scene drawn as a video: the person and their reflection as simple bodies.

Each frame draws the true image of the joints (:attr:`SyntheticScene.real_image`,
:attr:`SyntheticScene.mirror_image`: the camera's own projection, distortion included) as
a body a pose detector takes for a person: a head, a neck, a torso and limbs as rounded
strokes of a fixed thickness in metres (so a farther body is thinner), painted far to
near, the reflection dimmer (a mirror reflects less than all the light) and behind the
person where they overlap. A head shows its face (the eyes) only where it turns to the
camera, else hair: the reflection of a person facing the camera is seen from behind (a
face drawn there makes BlazePose label the reflection as a person facing the camera, left
and right crossed, in most frames: ``bench/RESULTS_synth_clip.md``).
:func:`reflection_visibility` measures how much of the reflection a clip shows. The scene's
detector noise and outliers are not drawn: the detector that reads the video makes its own. What it is for: trying ``calibrate clip.mp4``,
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

__all__ = ["render_frame", "write_scene_video", "reflection_visibility", "hidden_reflection_note",
           "VIDEO_JOINTS", "VISIBLE_FRACTION"]

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
_HAIR = (30, 40, 60)
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
        # the face where it turns to the camera: an eye nearer than the ears' middle
        # is seen, the back of the head is hair (a reflection of a person facing the
        # camera shows their back, and a pose detector labels it so)
        ears = [index[n] for n in ("left_ear", "right_ear") if n in index]
        back = float(np.mean(z[ears])) if ears else depth
        eyes = [index[n] for n in ("left_eye", "right_eye")
                if n in index and np.isfinite(p[index[n]]).all() and z[index[n]] < back]
        parts.append((depth, "head", (head, f * _HEAD_M / depth, _SKIN if eyes else _HAIR)))
        if eyes:
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
            centre, size, colour = arg
            cv2.ellipse(img, pt(centre), (max(2, int(0.42 * size)), max(2, int(0.5 * size))),
                        0, 0, 360, col(colour), -1, cv2.LINE_AA)


#: A reflection counts as visible in a frame where at least this fraction of its drawn
#: area lies in the image and not behind the person.
VISIBLE_FRACTION = 0.5


def _joint_index(scene) -> dict:
    sk = scene.skeleton
    return {n: sk.index(n) for n in (*VIDEO_JOINTS, "left_eye", "right_eye", "left_ear",
                                     "right_ear") if sk.has(n)}


def reflection_visibility(scene, frames: int | None = None, *, scale: float = 0.125
                          ) -> np.ndarray:
    """``(T,)`` fraction of the reflection's drawn area that the clip shows, per frame of
    the first ``frames`` (default all): inside the image and not behind the person.

    Both bodies are drawn as :func:`render_frame` draws them, as masks at ``scale``
    times the image size on a canvas three images wide and high (the image in its
    middle), so that the part of the reflection outside the image is counted too.
    A reflection drawn nowhere (behind the camera) has visibility 0.
    """
    from .. import geometry as geo

    W, H = scene.image_size
    count = len(scene.frame_ids) if frames is None else min(int(frames), len(scene.frame_ids))
    index = _joint_index(scene)
    f = float(scene.K[0, 0]) * scale
    w, h = int(round(W * scale)), int(round(H * scale))
    offset = np.array([w, h], float)
    out = np.zeros(count)
    for t in range(count):
        X = scene.joints3d[t]
        S = geo.reflect_points(X, scene.normal, scene.distance)
        masks = []
        for p, z in ((scene.mirror_image[t], S[:, 2]), (scene.real_image[t], X[:, 2])):
            img = np.zeros((3 * h, 3 * w), np.uint8)     # every colour's first channel > 0
            _body(img, p * scale + offset, z, f, index, 1.0)
            masks.append(img > 0)
        mirror, person = masks
        area = mirror.sum()
        if area == 0:
            continue
        shown = mirror[h:2 * h, w:2 * w] & ~person[h:2 * h, w:2 * w]
        out[t] = shown.sum() / area
    return out


def hidden_reflection_note(scene, frames: int | None = None) -> str | None:
    """What the clip of the first ``frames`` frames cannot show, in one line, where its
    reflection is visible (:data:`VISIBLE_FRACTION`, :func:`reflection_visibility`) in
    fewer than half of them; else ``None``."""
    seen = reflection_visibility(scene, frames) >= VISIBLE_FRACTION
    if 2 * seen.sum() >= len(seen):
        return None
    return (f"the reflection is behind the person or outside the image in "
            f"{len(seen) - int(seen.sum())} of the {len(seen)} frames drawn")


def render_frame(scene, t: int, *, reflection_gain: float = 0.7) -> np.ndarray:
    """Frame ``t`` of ``scene`` (:class:`~mirrorgraph.synth.scene.SyntheticScene`) as an
    ``(H, W, 3)`` uint8 BGR image: the reflection, then the person over it."""
    from .. import geometry as geo

    W, H = scene.image_size
    img = np.empty((H, W, 3), np.uint8)
    img[:] = _BACKGROUND
    index = _joint_index(scene)
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
