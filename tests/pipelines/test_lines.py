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
from tests.video.test_lines import _rotation, render_room

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


def _calibrate(d, video, lines=True):
    opts = mg.CalibrateOptions(image_size=SIZE, video=video, fps=30,
                               refine_options=mg.RefineOptions(focal=FocalOptions(lines=lines)))
    return mg.calibrate(d / "keypoints_mmpose.json", None, opts).calibration


def test_lines_join_the_person_in_the_graph(scene, tmp_path):
    """The room drawn with the scene's camera: the lines within 1.5 % and 3 std of the
    truth, the fused estimate within 2 % and tighter than the person's alone, every cue
    in ``focal_sources`` and the summary, no disagreement warning."""
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


def test_lines_of_another_camera_are_flagged(scene, tmp_path):
    """A room drawn with a 40 % longer focal length: person and lines disagree, and a
    warning says so."""
    d, K = scene
    K2 = K.copy()
    K2[0, 0] = K2[1, 1] = 1.4 * K[0, 0]
    calib = _calibrate(d, _room_video(tmp_path / "other.mp4", K2))
    src = calib.intrinsics.estimated["focal_sources"]
    assert abs(src["agreement_sigma"]) > 2
    assert any("disagree" in w for w in calib.warnings)


def test_without_lines_the_person_alone_and_the_reason(scene, tmp_path):
    """Switched off, or keypoints without a video: the person's estimate, and why the
    lines are missing."""
    d, K = scene
    calib = _calibrate(d, _room_video(tmp_path / "room.mp4", K), lines=False)
    src = calib.intrinsics.estimated["focal_sources"]
    assert "switched off" in src["lines"]["reason"] and not src["fused"]["with_lines"]
    assert src["fused"]["f"] == pytest.approx(src["person"]["f"])
    calib = _calibrate(d, None)
    assert "no video" in calib.intrinsics.estimated["focal_sources"]["lines"]["reason"]
    assert main(["calibrate", str(d / "keypoints_mmpose.json"), "--image-size", "1920x1080",
                 "--no-lines", "--out", str(tmp_path / "c.json"), "--quiet"]) == 0
    out = json.loads((tmp_path / "c.json").read_text())
    assert "switched off" in out["intrinsics"]["estimated"]["focal_sources"]["lines"]["reason"]
