"""mirrorgraph.synth.video: the scene drawn as a video, read back and detected."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from mirrorgraph.synth import make_scene
from mirrorgraph.synth.video import render_frame, write_scene_video
from tests.helpers import need_module


@pytest.fixture(scope="module")
def scene():
    return make_scene(frames=12, seed=1)


def test_the_clip_is_the_scenes_frames_at_its_rate_and_size(scene, tmp_path):
    path, _ = write_scene_video(scene, tmp_path / "clip.mp4", frames=10)
    cap = cv2.VideoCapture(str(path))
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(scene.fps)
    frames = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        frames.append(img)
    cap.release()
    assert len(frames) == 10 and frames[0].shape == (scene.image_size[1], scene.image_size[0], 3)
    assert not list(tmp_path.glob(".*part*"))


def test_the_bodies_are_drawn_where_the_joints_are(scene):
    """The person's torso and the reflection's are painted at the middle of their
    hips and shoulders; a corner far from both is background."""
    sk = scene.skeleton
    torso = [sk.index(n) for n in ("left_shoulder", "right_shoulder", "left_hip", "right_hip")]
    for t in (0, 6, 11):
        img = render_frame(scene, t).astype(float)
        background = img[2, 2]
        for points in (scene.real_image[t], scene.mirror_image[t]):
            x, y = np.round(points[torso].mean(0)).astype(int)
            assert np.abs(img[y, x] - background).sum() > 60, (t, x, y)


def test_blazepose_finds_the_person_and_the_reflection(scene, tmp_path):
    """The drawn bodies are people to a pose detector: BlazePose finds two in every frame,
    their shoulders and hips within 25 px of the true joints (the drawing's own
    proportions against the detector's idea of a joint)."""
    need_module("ai_edge_litert", "LiteRT runs BlazePose (the dev and video extras install it)")
    from mirrorgraph.errors import MissingExtraError
    from mirrorgraph.video.detect import VideoOptions, detect_video

    path, _ = write_scene_video(scene, tmp_path / "clip.mp4", frames=8)
    try:
        det = detect_video(path, VideoOptions(cache=False))
    except MissingExtraError as exc:
        pytest.skip(f"BlazePose's model files are missing ({exc})")
    raw = det.to_raw()
    names = ("left_shoulder", "right_shoulder", "left_hip", "right_hip")
    found = [raw.skeleton.index(n) for n in names]
    truth = [scene.skeleton.index(n) for n in names]
    assert len(raw.people) == 8
    for t, people in enumerate(raw.people):
        assert len(people) == 2, t
        for points in (scene.real_image[t], scene.mirror_image[t]):
            centre = points[truth].mean(0)
            best = min(people, key=lambda p: np.linalg.norm(p[found, :2].mean(0) - centre))
            assert np.linalg.norm(best[found, :2].mean(0) - centre) < 25, t
