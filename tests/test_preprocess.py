"""Tests of what happens to the keypoints and the camera before any geometry
(mirrorgraph.preprocess): the size check, undistortion, the frame rate."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.intrinsics import Intrinsics
from mirrorgraph.preprocess import (DEFAULT_FPS, check_image_size, resolve_fps,
                                    undistort_keypoints)
from mirrorgraph.synth import make_scene


@pytest.fixture(scope="module")
def scene():
    return make_scene(frames=30, seed=3)


def test_the_frame_rate_comes_from_the_user_then_the_input_then_the_default(scene):
    warnings: list[str] = []
    assert resolve_fps(scene.detections, warnings, fps=50.0) == (50.0, "option")
    assert any("50" in w and "30" in w for w in warnings)          # input's 30 named
    warnings.clear()
    assert resolve_fps(scene.detections, warnings) == (30.0, "input")
    assert resolve_fps(replace(scene.detections, fps=None), warnings) == (DEFAULT_FPS, "default")
    assert resolve_fps(scene.detections, warnings, fps=30.1) == (30.1, "option")
    assert not warnings                                             # within the tolerance
    with pytest.raises(InputError, match="field 'fps'"):
        resolve_fps(scene.detections, warnings, fps=float("nan"))


def test_keypoints_in_other_pixels_than_the_intrinsics_are_refused(scene):
    warnings: list[str] = []
    check_image_size(scene.detections, scene.intrinsics, warnings)   # the right size: quiet
    w, h = scene.image_size
    small = replace(scene.intrinsics, image_size=(w // 4, h // 4), source="cam.json")
    with pytest.raises(InputError) as info:
        check_image_size(scene.detections, small, warnings)
    assert info.value.field == "image_size" and "cam.json" in str(info.value)


def test_undistortion_inverts_the_lens(scene):
    K = scene.K
    dist = np.array([-0.12, 0.03, 0.001, -0.0005, 0.0])
    w, h = scene.image_size
    rng = np.random.default_rng(0)
    pts = rng.uniform([0.1 * w, 0.1 * h], [0.9 * w, 0.9 * h], (2 * 17, 2))  # pinhole pixels
    rays = np.linalg.solve(K, np.c_[pts, np.ones(len(pts))].T).T
    seen, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, dist)    # through the lens
    people = [np.concatenate([seen.reshape(2, 17, 2), np.ones((2, 17, 1))], axis=-1)]
    data = replace(scene.detections, people=people)
    lens = Intrinsics(K=K, dist=dist, image_size=scene.image_size)
    out = undistort_keypoints(data, lens)
    assert np.abs(out.people[0][..., :2].reshape(-1, 2) - pts).max() < 0.05
    assert np.abs(seen.reshape(-1, 2) - pts).max() > 5.0                    # the lens mattered
    assert undistort_keypoints(data, replace(lens, dist=None)) is data      # no lens: as is
