"""The Python API end to end on synthetic scenes with known mirrors."""

import json

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.metrics import rotation_error_deg, translation_error
from mirrorgraph.synth import make_scene


@pytest.fixture(scope="module")
def paper_scene():
    """MirrorCalib's protocol: 1000 frames, 1920x1080, noise mean 0.076 px, std 4 px."""
    return make_scene(frames=1000, seed=101)


def _errors(calib, scene):
    return (rotation_error_deg(calib.virtual_rotation, scene.virtual_R),
            translation_error(calib.virtual_translation, scene.virtual_t))


def test_initialisation_alone_beats_the_paper(paper_scene):
    run = mg.calibrate(paper_scene.detections, paper_scene.intrinsics,
                       mg.CalibrateOptions(refine=False))
    rot, trans = _errors(run.calibration, paper_scene)
    assert rot < 0.3
    assert trans < 0.05          # metres, after scaling t to the true norm
    c = run.calibration
    assert c.frames_read == 1000 and c.frames_used > 950
    assert 0.8 < c.inlier_ratio <= 1.0


def test_distortion_is_removed_before_geometry():
    dist = np.array([-0.25, 0.08, 0.001, -0.001, -0.01])
    scene = make_scene(frames=400, seed=103, distortion=dist)
    good = mg.calibrate(scene.detections, scene.intrinsics, mg.CalibrateOptions(refine=False))
    rot, _ = _errors(good.calibration, scene)
    assert rot < 0.5
    # ignoring the distortion is measurably worse: the test can fail
    from mirrorgraph.intrinsics import Intrinsics
    naive = Intrinsics(scene.K, None, scene.image_size)
    bad = mg.calibrate(scene.detections, naive, mg.CalibrateOptions(refine=False))
    assert _errors(bad.calibration, scene)[0] > 2 * rot


def test_outliers_and_left_right_swaps(paper_scene):
    scene = make_scene(frames=600, seed=103, outlier_rate=0.3, lr_swap_rate=0.1)
    run = mg.calibrate(scene.detections, scene.intrinsics, mg.CalibrateOptions(refine=False))
    assert _errors(run.calibration, scene)[0] < 0.5
    assert run.calibration.lr_fixes > 0.5 * scene.lr_swapped.sum()


@pytest.mark.parametrize("estimator", ["eightpoint", "reflective8"])
def test_reference_estimators_run_and_are_reported(paper_scene, estimator):
    run = mg.calibrate(paper_scene.detections, paper_scene.intrinsics,
                       mg.CalibrateOptions(refine=False, estimator=estimator))
    assert run.calibration.estimator == estimator
    assert np.isclose(np.linalg.norm(run.calibration.normal), 1.0)
    assert run.calibration.to_dict()["estimator"] == estimator


def test_same_input_same_answer(paper_scene):
    a = mg.calibrate(paper_scene.detections, paper_scene.intrinsics, mg.CalibrateOptions(refine=False))
    b = mg.calibrate(paper_scene.detections, paper_scene.intrinsics, mg.CalibrateOptions(refine=False))
    assert np.array_equal(a.calibration.normal, b.calibration.normal)


def test_full_pipeline_with_refinement_and_metric_scale(paper_scene):
    s = paper_scene
    run = mg.calibrate(s.detections, s.intrinsics, mg.CalibrateOptions(subject_height=s.subject_height))
    c = run.calibration
    rot, _ = _errors(c, s)
    assert c.refined and c.scale == "subject_height"
    assert rot < 0.3
    assert abs(c.distance - s.distance) / s.distance < 0.03
    # the reported uncertainty is of the size of the actual error (not 10x off either way)
    assert 0.1 < rot / c.uncertainty["rotation_std_deg"] < 4.0 or rot < 0.05
    # metric 3D joints close to the truth
    from mirrorgraph.metrics import pa_mpjpe
    assert pa_mpjpe(run.joints3d, s.joints3d, run.valid3d) < 0.03


# ------------------------------------------------------------------------------ frame rate
def _fps_run(data, intrinsics, **kw):
    return mg.calibrate(data, intrinsics, mg.CalibrateOptions(**kw))


def test_fps_from_an_npz_that_carries_it(tmp_path):
    from mirrorgraph.io import write_paired_npz
    from mirrorgraph.io.motion import write_joints3d

    s = make_scene(frames=150, seed=7, fps=25.0)
    path = tmp_path / "paired.npz"
    write_paired_npz(s.paired(), path)
    run = _fps_run(str(path), s.intrinsics, subject_height=s.subject_height)
    assert (run.fps, run.fps_source) == (25.0, "input")
    c = run.calibration
    assert c.input["fps"] == 25.0 and c.input["fps_source"] == "input"
    assert not any("frame rate" in w for w in c.warnings)
    out = tmp_path / "motion.trc"
    write_joints3d(out, run.joints3d, run.valid3d, run.paired.frame_ids,
                   run.paired.skeleton.joints, run.fps)
    assert out.read_text().splitlines()[2].split("\t")[0] == "25"


def test_fps_default_is_reported_and_named_where_the_motion_is_written(tmp_path, capsys):
    from dataclasses import replace
    from mirrorgraph.cli import main
    from mirrorgraph.synth import write_scene
    s = make_scene(frames=150, seed=7)
    raw = replace(s.detections, fps=None)                  # as OpenPose / MMPose files
    run = _fps_run(raw, s.intrinsics)
    assert (run.fps, run.fps_source) == (30.0, "default")
    assert run.calibration.input["fps_source"] == "default"
    # the frame rate only matters to the 3D motion: no word from the calibration alone
    assert not any("frame rate" in w for w in run.calibration.warnings)
    # given by the user: its source
    run = _fps_run(raw, s.intrinsics, fps=50)
    assert (run.fps, run.fps_source) == (50.0, "option")
    # the CLI writing the 3D motion at the default says so, once, in the JSON too
    paths = write_scene(s, tmp_path / "scene", formats=("mmpose",))
    out = tmp_path / "c.json"
    assert main(["calibrate", str(paths["mmpose"]), "--intrinsics", str(paths["camera"]),
                 "--out", str(out), "--joints3d", str(tmp_path / "j.npz")]) == 0
    err = capsys.readouterr().err
    warned = [ln for ln in err.splitlines() if "frame rate" in ln]
    assert len(warned) == 1 and "default 30 fps" in warned[0] and "--fps" in warned[0] \
        and "--video" in warned[0] and "Options" not in warned[0]   # the CLI's words only
    assert any("frame rate" in w for w in json.loads(out.read_text())["warnings"])
    # --quiet: not on stderr, still in the JSON
    assert main(["calibrate", str(paths["mmpose"]), "--intrinsics", str(paths["camera"]),
                 "--out", str(out), "--joints3d", str(tmp_path / "j.npz"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert any("frame rate" in w for w in json.loads(out.read_text())["warnings"])
    assert main(["calibrate", str(paths["mmpose"]), "--intrinsics", str(paths["camera"]),
                 "--out", str(out), "--quiet"]) == 0
    assert "frame rate" not in capsys.readouterr().err


def test_fps_from_a_video_and_disagreements(tmp_path):
    import cv2
    from dataclasses import replace
    from mirrorgraph.preprocess import fps_from_video

    video = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (64, 48))
    for _ in range(3):
        w.write(np.zeros((48, 64, 3), np.uint8))
    w.release()
    assert fps_from_video(video) == 25.0
    s = make_scene(frames=150, seed=7)
    raw = replace(s.detections, fps=None)
    run = _fps_run(raw, s.intrinsics, video=str(video))
    assert (run.fps, run.fps_source) == (25.0, "video")
    assert not any("frame rate" in w for w in run.calibration.warnings)
    # the input's own 30 fps wins over the video's 25, and the disagreement is named
    run = _fps_run(s.detections, s.intrinsics, video=str(video))
    assert (run.fps, run.fps_source) == (30.0, "input")
    assert any("frame rate" in w and "25" in w and "30" in w for w in run.calibration.warnings)
    with pytest.raises(mg.InputError, match=r"nothing\.mp4.*field 'video'"):
        fps_from_video(tmp_path / "nothing.mp4")
    (tmp_path / "text.mp4").write_text("not a video")
    with pytest.raises(mg.InputError, match="field 'video'"):
        fps_from_video(tmp_path / "text.mp4")
    with pytest.raises(mg.InputError, match="field 'fps'"):
        _fps_run(raw, s.intrinsics, fps=-1.0, refine=False)
