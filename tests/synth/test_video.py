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


def _facing_camera(points3d: np.ndarray, sk) -> np.ndarray:
    """``(T,)`` the nose nearer the camera than the ears' middle."""
    ears = 0.5 * (points3d[:, sk.index("left_ear"), 2] + points3d[:, sk.index("right_ear"), 2])
    return points3d[:, sk.index("nose"), 2] < ears


def test_a_face_is_drawn_only_where_it_turns_to_the_camera():
    """The person of the README's scene faces the camera, so their reflection shows the
    back of the head: the eyes are drawn on the person, and at the reflection's eyes the
    frame holds the dimmed hair, not an eye (a face there makes a pose detector label the
    reflection as a person facing the camera, left and right the other way round)."""
    from mirrorgraph import geometry as geo
    from mirrorgraph.synth.video import _EYE, _HAIR

    scene = make_scene(frames=1000, seed=8, geometry="gym", outlier_rate=0.1, lr_swap_rate=0.05,
                       subject_height=1.75)          # the README's scene
    sk = scene.skeleton
    X = scene.joints3d[:6]
    S = geo.reflect_points(X.reshape(-1, 3), scene.normal, scene.distance).reshape(X.shape)
    assert _facing_camera(X, sk).all() and not _facing_camera(S, sk).any()
    eyes = [sk.index("left_eye"), sk.index("right_eye")]
    for t in range(6):
        img = render_frame(scene, t).astype(float)
        for e in eyes:
            x, y = np.round(scene.real_image[t, e]).astype(int)
            assert np.abs(img[y, x] - _EYE).max() < 12, (t, img[y, x])
            x, y = np.round(scene.mirror_image[t, e]).astype(int)
            assert np.abs(img[y, x] - 0.7 * np.array(_HAIR)).max() < 12, (t, img[y, x])


def test_reflection_visibility_sees_where_the_reflection_is_drawn():
    """The visible share of the reflection: ~1 where it is drawn apart from the person,
    ~0 where it lies on the person's own pixels (thinner, farther) or outside the image."""
    import dataclasses

    from mirrorgraph.synth.video import VISIBLE_FRACTION, hidden_reflection_note, \
        reflection_visibility

    scene = make_scene(frames=5, seed=1)
    W, _ = scene.image_size
    centre = scene.real_image[:, :, 0].mean(1, keepdims=True)
    apart = scene.real_image.copy()
    apart[..., 0] += np.where(centre < W / 2, 0.5 * W, -0.5 * W)    # the other half
    for image, low, high in ((apart, 0.95, 1.0), (scene.real_image, 0.0, 0.1),
                             (scene.real_image + [3.0 * W, 0.0], 0.0, 0.0)):
        v = reflection_visibility(dataclasses.replace(scene, mirror_image=image))
        assert v.shape == (5,) and (v >= low).all() and (v <= high).all(), v
    assert hidden_reflection_note(dataclasses.replace(scene, mirror_image=apart)) is None
    note = hidden_reflection_note(dataclasses.replace(scene, mirror_image=scene.real_image))
    assert note and "5 of the 5 frames" in note
    assert VISIBLE_FRACTION == 0.5


def test_synth_warns_of_a_clip_whose_reflection_is_hidden(tmp_path, capsys):
    """`synth` names the seed and why where its clip hides the reflection (the README's
    geometry, seed 0: behind the person), and says nothing of a clip that shows it."""
    from mirrorgraph.cli import main
    from mirrorgraph.synth.video import reflection_visibility

    for seed, hidden in ((0, True), (8, False)):
        scene = make_scene(frames=1000, seed=seed, geometry="gym", outlier_rate=0.1,
                           lr_swap_rate=0.05, subject_height=1.75)     # the README's
        seen = (reflection_visibility(scene, 30) >= 0.5).mean()
        assert (seen < 0.5) == hidden, (seed, seen)
        assert main(["synth", "--out", str(tmp_path / str(seed)), "--frames", "1000", "--seed",
                     str(seed), "--outliers", "0.1", "--lr-swaps", "0.05", "--subject-height",
                     "1.75", "--formats", "mmpose", "--video-frames", "30"]) == 0
        err = capsys.readouterr().err
        lines = [ln for ln in err.splitlines() if "clip.mp4 of seed" in ln]
        if hidden:
            assert len(lines) == 1 and f"seed {seed}:" in lines[0] and "behind the person" \
                in lines[0], err
        else:
            assert not lines, err
