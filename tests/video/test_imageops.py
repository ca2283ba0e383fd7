"""The detection path's numbers, pinned independently of OpenCV's version (#28).

OpenCV 5.1 reimplemented ``warpAffine``: a few pixels of each BlazePose crop moved by
one grey level, and a hand's landmark by 112 px a few frames later. The crops and the
detector's letterbox are now numpy (:mod:`mirrorgraph.video.imageops`); these tests
check them against independent references (scipy's spline sampling; an exact area
average by replication), then pin each stage of the path on a fixed frame of the
Pose2Sim demo: the decoded frame, the two input tensors, the detection and the
landmarks. A new release of OpenCV (decoding), LiteRT (the networks) or of this code
that moves any of them fails the stage that moved, not an end-to-end tolerance.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from scipy import ndimage

from mirrorgraph.video.blazepose import (DETECTOR_SIZE, LANDMARK_SIZE, crop_matrix,
                                         detector_input, landmark_input, letterbox)
from mirrorgraph.video.imageops import area_resize, area_weights, warp_crop


def _pattern(h: int, w: int) -> np.ndarray:
    """A fixed ``(h, w, 3)`` uint8 image with structure at every scale (no RNG)."""
    y, x = np.mgrid[0:h, 0:w].astype(float)
    c = np.arange(3)[None, None, :]
    v = 127.5 + 60 * np.sin(x[..., None] / (7.0 + c)) * np.cos(y[..., None] / 11.0) \
        + 60 * np.sin((x[..., None] + 2 * y[..., None]) / 97.0 + c)
    return np.clip(np.round(v), 0, 255).astype(np.uint8)


# ------------------------------------------------------------------ against references
def test_area_weights_rows_sum_to_one_and_cover_the_input():
    for n_in, n_out in ((1080, 126), (53, 20), (20, 53), (7, 7), (1, 5)):
        W = area_weights(n_in, n_out)
        np.testing.assert_allclose(W.sum(1), 1.0, atol=1e-12)
        # every input pixel contributes its full length: columns sum to n_out / n_in
        np.testing.assert_allclose(W.sum(0), n_out / n_in, atol=1e-12)


@pytest.mark.parametrize("size", [(53, 37, 20, 14), (40, 30, 160, 90), (192, 108, 56, 63)])
def test_area_resize_is_the_exact_area_average(size):
    """Replicate each input pixel ``n_out`` times along each axis: every output pixel
    then covers exactly ``n_in`` replicated pixels, whose plain mean is the exact area
    average (an independent construction of the same integral)."""
    w, h, nw, nh = size
    img = _pattern(h, w)
    ref = np.repeat(np.repeat(img.astype(float), nh, axis=0), nw, axis=1)
    ref = ref.reshape(nh, h, nw, w, 3).mean(axis=(1, 3))
    out = area_resize(img, nw, nh)
    assert out.dtype == np.float32 and out.shape == (nh, nw, 3)
    np.testing.assert_allclose(out, ref, atol=2e-3)


def test_warp_crop_is_bilinear_with_a_zero_border():
    """scipy's order-1 spline with ``grid-constant`` is bilinear interpolation with zero
    outside the image: the same sampling, computed another way."""
    img = _pattern(300, 400)
    for roi in ([200.0, 150.0, 180.0, 0.3], [380.0, 20.0, 260.0, -2.0], [10.0, 290.0, 90.0, 1.1]):
        M = crop_matrix(np.array(roi), 64)
        out = warp_crop(img, M, 64)
        u, v = np.meshgrid(np.arange(64.0), np.arange(64.0))
        x = M[0, 0] * u + M[0, 1] * v + M[0, 2]
        y = M[1, 0] * u + M[1, 1] * v + M[1, 2]
        ref = np.stack([ndimage.map_coordinates(img[..., c].astype(float), [y, x], order=1,
                                                mode="grid-constant", cval=0.0)
                        for c in range(3)], axis=-1)
        np.testing.assert_allclose(out, ref, atol=2e-3)
    # pixel centres at integer coordinates: the identity map returns the image itself
    M = np.array([[1.0, 0, 5], [0, 1.0, 7]])
    np.testing.assert_array_equal(warp_crop(img, M, 32), img[7:39, 5:37].astype(np.float32))


def test_input_tensors_from_their_definitions():
    img = _pattern(270, 480)
    x, scale, offset = detector_input(img)
    assert x.shape == (1, DETECTOR_SIZE, DETECTOR_SIZE, 3) and x.dtype == np.float32
    assert scale == pytest.approx(224 / 480) and offset.tolist() == [0.0, 49.0]
    inner = x[0, 49:49 + 126] * 127.5 + 127.5
    np.testing.assert_allclose(inner, area_resize(img, 224, 126), atol=2e-3)
    assert np.all(x[0, :49] == -1.0) and np.all(x[0, 49 + 126:] == -1.0)   # zero padding
    np.testing.assert_array_equal(letterbox(img, DETECTOR_SIZE)[0][49:175],
                                  area_resize(img, 224, 126))
    roi = np.array([240.0, 130.0, 200.0, 0.4])
    y, M = landmark_input(img, roi, gain=False)
    np.testing.assert_array_equal(M, crop_matrix(roi, LANDMARK_SIZE))
    np.testing.assert_allclose(y[0] * 255.0, warp_crop(img, M, LANDMARK_SIZE), atol=1e-3)


# ------------------------------------------------------- the path, stage by stage, pinned
#: Frame 40 of Demo_SinglePerson/videos/cam01.mp4 (pose2sim 0.10.49), RGB, as decoded by
#: OpenCV 5.0.0.93 and 5.1.0.95 alike; the detection and the landmarks from it, with
#: ai-edge-litert 2.3.0 (the same with either OpenCV since #28).
FRAME_SHA256 = "cd06575c88aea9777ca860f6f55f64f492b125ca6a953f4b590f1638a8e4de66"
DETECTOR_TENSOR_SUM = -76694.1875
LANDMARK_TENSOR_SUM = 81220.0463  # at ROI, as rounded here
ROI = [429.041, 795.44, 1181.343, 0.839]
LANDMARKS = [
    [714.38, 599.99], [727.17, 586.85], [728.62, 587.96], [730.03, 588.64], [720.64, 577.52],
    [717.46, 572.56], [713.81, 567.22], [719.13, 578.3], [695.56, 550.87], [702.68, 609.81],
    [693.39, 599.48], [661.29, 662.96], [572.8, 538.29], [647.24, 795.77], [440.18, 486.58],
    [640.28, 910.35], [522.72, 403.72], [640.71, 941.01], [543.47, 391.45], [641.53, 941.56],
    [559.96, 392.56], [640.41, 932.7], [554.83, 400.65], [483.05, 823.44], [403.02, 775.56],
    [473.33, 1000.02], [272.78, 921.42], [407.12, 1100.43], [132.26, 1061.21],
    [383.65, 1105.18], [117.26, 1070.96], [433.16, 1176.28], [115.41, 1146.81]]


@pytest.fixture(scope="module")
def demo_frame(demo):
    from mirrorgraph.video.reader import frames
    [(_, frame)] = list(frames(demo / "Demo_SinglePerson" / "videos" / "cam01.mp4",
                               start=40, end=41))
    return frame


def test_decoded_frame_is_pinned(demo_frame):
    import cv2
    assert demo_frame.shape == (1920, 1080, 3) and demo_frame.dtype == np.uint8
    assert hashlib.sha256(demo_frame.tobytes()).hexdigest() == FRAME_SHA256, (
        f"OpenCV {cv2.__version__} decodes the demo frame to other pixels (mean "
        f"{demo_frame.mean():.4f}, was 111.1797): its FFmpeg or colour conversion changed")


def test_input_tensors_on_the_demo_frame_are_pinned(demo_frame):
    x, _, _ = detector_input(demo_frame)
    assert float(x.sum(dtype=np.float64)) == pytest.approx(DETECTOR_TENSOR_SUM, abs=0.05)
    y, _ = landmark_input(demo_frame, np.array(ROI))
    assert float(y.sum(dtype=np.float64)) == pytest.approx(LANDMARK_TENSOR_SUM, abs=0.05)


def test_detection_and_landmarks_on_the_demo_frame_are_pinned(demo_frame, models):
    dets = models.detect(demo_frame)
    assert len(dets) == 1 and dets[0].score > 0.9
    np.testing.assert_allclose(dets[0].roi, ROI, atol=0.05)
    pose = models.landmarks(demo_frame, np.array(ROI))
    assert pose.score > 0.99
    np.testing.assert_allclose(pose.xy, LANDMARKS, atol=0.05)
