"""``calibrate`` without intrinsics with the scene's lines as a second witness: the
synthetic scene's keypoints with a video of a room drawn with the same camera
(``CalibrateOptions.video``), ``focal_sources`` against the truth; a room drawn with
another camera gives the disagreement warning; ``--no-lines`` and keypoints without a
video say why the lines are missing."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.cli import main
from mirrorgraph.graph.options import FocalOptions
from mirrorgraph.initial.vanishing import LinesFocal
from mirrorgraph.pipelines.lines import disagreement_warning, focal_sources, fuse_gaussians
from mirrorgraph.synth.room import render_room, rotation_ypr as _rotation

SIZE = (1920, 1080)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("lines") / "scene"
    assert main(["synth", "--out", str(d), "--frames", "300", "--seed", "3", "--focal", "1100",
                 "--quiet"]) == 0
    K = np.asarray(json.loads((d / "camera.json").read_text())["K"], float)
    return d, K


def _room_video(path, K, frames: int = 6):
    img = render_room(K, _rotation(30.0, 12.0, 2.0), SIZE)
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30, SIZE)
    for _ in range(frames):
        out.write(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
    out.release()
    return path


def _calibrate(d, video, lines=True, **refine):
    opts = mg.CalibrateOptions(image_size=SIZE, video=video, fps=30,
                               refine_options=mg.RefineOptions(focal=FocalOptions(lines=lines),
                                                               **refine))
    return mg.calibrate(d / "keypoints_mmpose.json", None, opts).calibration


def test_lines_join_the_person_in_the_graph(scene, tmp_path):
    """The room drawn with the scene's camera: the lines within 1.5 % and 3 std of the
    truth, the fused estimate within 2 % and tighter than the person's alone, every cue
    in ``focal_sources`` and the summary, no disagreement warning (the person's estimate
    on this scene, 1289 px against 1100, carries its bias in its std:
    :func:`mirrorgraph.graph.solve.focal_bias`)."""
    d, K = scene
    f = K[0, 0]
    calib = _calibrate(d, _room_video(tmp_path / "room.mp4", K))
    src = calib.intrinsics.estimated["focal_sources"]
    assert abs(src["lines"]["f"] - f) / f < 0.015
    assert abs(src["lines"]["f"] - f) < 3 * src["lines"]["std"]
    assert src["fused"]["with_lines"]
    assert abs(src["fused"]["f"] - f) / f < 0.02
    assert src["fused"]["std"] < src["person"]["std"]
    assert calib.intrinsics.K[0, 0] == pytest.approx(src["fused"]["f"])
    assert "lines" in calib.summary() and "fused" in calib.summary()
    assert not any("disagree" in w for w in calib.warnings)
    back = mg.read_calibration(json.loads(json.dumps(calib.to_dict())))
    assert back.intrinsics.estimated["focal_sources"] == json.loads(json.dumps(src))


def test_the_persons_focal_std_covers_its_error(scene, tmp_path):
    """Under the default options the focal length from the person and the reflection lies
    within 3 of its stds of the truth: 1289 px against 1100, whose bias the bootstrap on
    the calibration's own joints measures (+133 px of one replicate; on the joints
    pass's, whose torso is held nearly rigid, +16 px: a std of 61 px, 3.1 std off)."""
    d, K = scene
    calib = _calibrate(d, _room_video(tmp_path / "room.mp4", K))
    person = calib.intrinsics.estimated["focal_sources"]["person"]
    assert abs(person["f"] - K[0, 0]) < 3 * person["std"]


def test_lines_of_another_camera_are_flagged(scene, tmp_path):
    """A room drawn with a 40 % shorter focal length (a wide lens the person's estimate,
    itself high on this scene, lies far from): person and lines disagree by more than 2
    combined std, and a warning says so."""
    d, K = scene
    K2 = K.copy()
    K2[0, 0] = K2[1, 1] = 0.6 * K[0, 0]
    calib = _calibrate(d, _room_video(tmp_path / "other.mp4", K2))
    src = calib.intrinsics.estimated["focal_sources"]
    assert abs(src["lines"]["f"] - K2[0, 0]) / K2[0, 0] < 0.015
    assert abs(src["agreement_sigma"]) > 2
    assert any("disagree" in w for w in calib.warnings)


def test_fusion_and_the_warning_rule():
    """Two Gaussians make one (inverse-variance weights); the warning past 2 combined std
    only, naming both estimates."""
    f, s = fuse_gaussians((1000.0, 300.0), (1200.0, 40.0))
    w1, w2 = 1 / 300.0 ** 2, 1 / 40.0 ** 2
    assert f == pytest.approx((w1 * 1000 + w2 * 1200) / (w1 + w2))
    assert s == pytest.approx((w1 + w2) ** -0.5)
    lines = LinesFocal(1200.0, 40.0, 100, n_vps=3, n_axes=3)
    near = focal_sources({"focal_px": 1100.0, "std_px": 60.0}, lines, None)
    assert near["agreement_sigma"] == pytest.approx(-100 / np.hypot(60, 40))
    assert disagreement_warning(near) is None
    far = focal_sources({"focal_px": 900.0, "std_px": 60.0}, lines,
                        {"focal_px": 1150.0, "std_px": 30.0})
    text = disagreement_warning(far)
    assert text and "900" in text and "1200" in text and far["fused"]["with_lines"]


def test_without_lines_the_person_alone_and_the_reason(scene, tmp_path):
    """Switched off, or keypoints without a video: the person's estimate, and why the
    lines are missing."""
    d, K = scene
    calib = _calibrate(d, None)
    src = calib.intrinsics.estimated["focal_sources"]
    assert not src["fused"]["with_lines"] and "agreement_sigma" not in src
    assert src["fused"]["f"] == pytest.approx(src["person"]["f"])
    assert "no video" in calib.intrinsics.estimated["focal_sources"]["lines"]["reason"]
    video = _room_video(tmp_path / "room.mp4", K)
    assert main(["calibrate", str(d / "keypoints_mmpose.json"), "--image-size", "1920x1080",
                 "--video", str(video), "--no-lines", "--out", str(tmp_path / "c.json"),
                 "--quiet"]) == 0
    out = json.loads((tmp_path / "c.json").read_text())
    assert "switched off" in out["intrinsics"]["estimated"]["focal_sources"]["lines"]["reason"]
