"""The command line end to end: synth -> calibrate on every format, and bad input."""

import json
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph.cli import main
from mirrorgraph.graph.options import GaugeOptions
from mirrorgraph.metrics import rotation_error_deg
from mirrorgraph.synth import read_ground_truth


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("scene")
    assert main(["synth", "--out", str(out), "--frames", "300", "--seed", "21",
                 "--outliers", "0.05", "--lr-swaps", "0.05", "--missing", "0.02",
                 "--extra-people", "0.05", "--single", "0.05", "--quiet"]) == 0
    return out


def _check_calibration(path: Path, truth: dict, max_deg: float) -> dict:
    cal = json.loads(path.read_text())
    n = np.array(cal["mirror"]["normal"])
    R = np.array(cal["virtual_camera"]["R"])
    t = np.array(cal["virtual_camera"]["t"])
    # self-consistency: R and t follow from the normal (and distance)
    R2, t2 = geo.virtual_camera_from_mirror(n, cal["mirror"]["distance"] or 0.5)
    assert np.allclose(R, R2, atol=1e-9) and np.allclose(t, t2, atol=1e-9)
    F = np.array(cal["fundamental_matrix"])
    assert np.allclose(F, -F.T)
    assert rotation_error_deg(R, truth["R"]) < max_deg
    return cal


@pytest.mark.parametrize("fmt", ["keypoints_mmpose.json", "openpose", "easymocap", "keypoints.npz"])
def test_calibrate_every_format(scene_dir, tmp_path, fmt, capsys):
    truth = read_ground_truth(scene_dir)
    out = tmp_path / "cal.json"
    code = main(["calibrate", str(scene_dir / fmt), "--intrinsics", str(scene_dir / "camera.json"),
                 "--out", str(out), "--no-refine"])
    assert code == 0, capsys.readouterr().err
    cal = _check_calibration(out, truth, 0.5)
    assert cal["scale"] == "unknown" and cal["mirror"]["distance"] is None
    assert np.isclose(np.linalg.norm(cal["virtual_camera"]["t"]), 1.0)
    assert "mirror normal" in capsys.readouterr().out


def test_calibrate_quiet_prints_nothing(scene_dir, tmp_path, capsys):
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(scene_dir / "keypoints_mmpose.json"), "--intrinsics",
                 str(scene_dir / "camera.json"), "--out", str(out), "--no-refine", "--quiet"]) == 0
    assert capsys.readouterr().out == ""


def test_calibrate_without_intrinsics_warns_and_reports_epipole(scene_dir, tmp_path, capsys):
    out = tmp_path / "cal.json"
    truth = read_ground_truth(scene_dir)
    assert main(["calibrate", str(scene_dir / "keypoints_mmpose.json"), "--image-size",
                 "1920x1080", "--out", str(out), "--no-refine"]) == 0
    cal = json.loads(out.read_text())
    assert cal["intrinsics"]["approximate"] is True
    assert any("approximate" in w for w in cal["warnings"])
    assert "warning:" in capsys.readouterr().err
    # the epipole in pixels does not depend on K
    e_true = geo.epipole_pixels(geo.epipole_from_normal(truth["K"], truth["normal"]))
    assert np.linalg.norm(np.array(cal["epipole_px"]) - e_true) < 0.02 * np.linalg.norm(e_true - [960, 540])


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _error_of(args, capsys) -> str:
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    return err


def test_bad_inputs_give_one_line_errors(tmp_path, scene_dir, capsys):
    cam = str(scene_dir / "camera.json")
    out = tmp_path / "never.json"
    bad_json = _write(tmp_path / "bad.json", '[{"frame_id": 0, "instances": [')
    assert "bad.json" in _error_of(["calibrate", str(bad_json), "--intrinsics", cam, "--out", str(out)], capsys)
    wrong = _write(tmp_path / "wrong.json", json.dumps(
        [{"frame_id": 0, "instances": [{"keypoints": [[1.0, 2.0]] * 13, "keypoint_scores": [1.0] * 13}]}]))
    assert "wrong.json" in _error_of(["calibrate", str(wrong), "--intrinsics", cam, "--out", str(out)], capsys)
    nan = _write(tmp_path / "nan.json", json.dumps(
        [{"frame_id": 3, "instances": [{"keypoints": [[1.0, 2.0]] * 16 + [[float("nan"), 1.0]],
                                        "keypoint_scores": [1.0] * 17}]}]))
    err = _error_of(["calibrate", str(nan), "--intrinsics", cam, "--out", str(out)], capsys)
    assert "nan.json" in err and "frame 3" in err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert "empty" in _error_of(["calibrate", str(empty), "--intrinsics", cam, "--out", str(out)], capsys)
    no_k = _write(tmp_path / "noK.json", json.dumps({"image_size": [1920, 1080]}))
    assert "noK.json" in _error_of(["calibrate", str(scene_dir / "keypoints_mmpose.json"),
                                    "--intrinsics", str(no_k), "--out", str(out)], capsys)
    missing = str(tmp_path / "nope.json")
    assert "nope.json" in _error_of(["calibrate", missing, "--intrinsics", cam, "--out", str(out)], capsys)
    assert not out.exists()


def test_no_two_people_and_degenerate_geometry(tmp_path, scene_dir, capsys):
    cam = str(scene_dir / "camera.json")
    out = tmp_path / "never.json"
    frames = json.loads((scene_dir / "keypoints_mmpose.json").read_text())
    frames = frames["instance_info"] if isinstance(frames, dict) else frames
    for f in frames:
        f["instances"] = f["instances"][:1]
    single = _write(tmp_path / "single.json", json.dumps(frames))
    err = _error_of(["calibrate", str(single), "--intrinsics", cam, "--out", str(out)], capsys)
    assert "single.json" in err and "reflection" in err
    # a 'scene' whose pairs all lie on one line cannot fix the epipole
    kp = [[100.0 + 30 * j, 500.0] for j in range(17)]
    kp2 = [[x + 400.0, y] for x, y in kp]
    line = [{"frame_id": t, "instances": [{"keypoints": kp, "keypoint_scores": [1.0] * 17},
                                          {"keypoints": kp2, "keypoint_scores": [1.0] * 17}]}
            for t in range(20)]
    flat = _write(tmp_path / "flat.json", json.dumps(line))
    err = _error_of(["calibrate", str(flat), "--intrinsics", cam, "--out", str(out)], capsys)
    assert "flat.json" in err
    assert not out.exists()


def test_existing_output_survives_a_failed_run(tmp_path, scene_dir, capsys):
    out = _write(tmp_path / "cal.json", "precious")
    bad = _write(tmp_path / "bad.json", "{")
    main(["calibrate", str(bad), "--intrinsics", str(scene_dir / "camera.json"), "--out", str(out)])
    capsys.readouterr()
    assert out.read_text() == "precious"


def test_export_to_pose2sim_and_anipose(scene_dir, tmp_path, capsys):
    import tomllib
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(scene_dir / "openpose"), "--intrinsics",
                 str(scene_dir / "camera.json"), "--out", str(cal), "--no-refine", "--quiet"]) == 0
    for fmt in ("pose2sim", "anipose"):
        out = tmp_path / f"{fmt}.toml"
        assert main(["export", str(cal), "--to", fmt, str(out)]) == 0
        cams = [v for v in tomllib.loads(out.read_text()).values()
                if isinstance(v, dict) and "matrix" in v]
        assert len(cams) == 2
        # the mirror camera is the flipped-image camera: principal point at W - cx
        K = np.array(json.loads(cal.read_text())["intrinsics"]["K"])
        W = json.loads(cal.read_text())["intrinsics"]["image_size"][0]
        cx = sorted(c["matrix"][0][2] for c in cams)
        assert np.allclose(cx, sorted([K[0, 2], W - K[0, 2]]))
    # unknown scale: the export warns, except under --quiet
    assert "warning" in capsys.readouterr().err
    assert main(["export", str(cal), "--to", "pose2sim", str(tmp_path / "q.toml"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_same_input_gives_byte_identical_output(scene_dir, tmp_path):
    outs = []
    for k in range(2):
        # the same options, --out's name included (the calibration names its .report.npz)
        (tmp_path / str(k)).mkdir()
        out = tmp_path / str(k) / "cal.json"
        j3d = tmp_path / str(k) / "j.csv"
        assert main(["calibrate", str(scene_dir / "easymocap"), "--intrinsics",
                     str(scene_dir / "camera.json"), "--out", str(out), "--subject-height", "1.7",
                     "--joints3d", str(j3d), "--quiet"]) == 0
        outs.append((out.read_bytes(), j3d.read_bytes(),
                     (tmp_path / str(k) / "cal.report.npz").read_bytes()))
    assert outs[0] == outs[1]


def test_joints3d_npz_carries_each_joints_std(scene_dir, tmp_path):
    j3d = tmp_path / "j.npz"
    assert main(["calibrate", str(scene_dir / "easymocap"), "--intrinsics",
                 str(scene_dir / "camera.json"), "--out", str(tmp_path / "cal.json"),
                 "--subject-height", "1.7", "--joints3d", str(j3d), "--quiet"]) == 0
    z = np.load(j3d)
    valid, std = z["valid"], z["joints_std"]
    assert std.shape == valid.shape and valid.any()
    assert np.isfinite(std[valid]).all() and np.isnan(std[~valid]).all()
    assert np.all(std[valid] > 0) and np.median(std[valid]) < 1.0      # metres, sane
    # the metric scale's share apart: joints_std^2 = joints_std_shape^2 + (scale |X|)^2
    shape, scale = z["joints_std_shape"], float(z["scale_rel_std"])
    assert scale >= GaugeOptions().height_sigma             # the height's prior at least
    X = z["joints3d"]
    back = np.hypot(shape[valid], scale * np.linalg.norm(X[valid], axis=-1))
    assert np.allclose(back, std[valid], rtol=1e-6)


def test_a_stated_keypoint_placement_reaches_the_run(scene_dir, tmp_path):
    """``--keypoint-offset 0`` (keypoints on the landmarks): recorded as the run's input and
    in its stature, the metric scale's std without the placement term (the height's prior,
    the measured spreads and the unmeasured parts' proportions in quadrature), smaller than the default's; the mirror the
    same."""
    cals, scales = {}, {}
    for flag in ([], ["--keypoint-offset", "0"]):
        out, j3d = tmp_path / f"c{len(flag)}.json", tmp_path / f"j{len(flag)}.npz"
        assert main(["calibrate", str(scene_dir / "easymocap"), "--intrinsics",
                     str(scene_dir / "camera.json"), "--out", str(out), "--subject-height",
                     "1.7", "--joints3d", str(j3d), "--quiet", *flag]) == 0
        cals[bool(flag)] = json.loads(out.read_text())
        scales[bool(flag)] = float(np.load(j3d)["scale_rel_std"])
    zero, default = cals[True], cals[False]
    assert zero["input"]["keypoint_offset"] == 0.0 and default["input"]["keypoint_offset"] is None
    st = zero["refinement"]["stature"]
    assert st["keypoint_offset"] == 0.0 and default["refinement"]["stature"]["keypoint_offset"] > 0
    assert "0.0 cm" in zero["refinement"]["scale_source"]
    from mirrorgraph.stature import unmeasured_rel_std

    assert scales[True] == pytest.approx(
        np.sqrt(GaugeOptions().height_sigma ** 2 + st["side_rel_diff"] ** 2
                + st["bones_rel_spread"] ** 2 + unmeasured_rel_std(st["top"]) ** 2), rel=1e-9)
    assert scales[True] < scales[False] - 0.01
    assert zero["uncertainty"]["distance_std"] < default["uncertainty"]["distance_std"]
    assert zero["mirror"]["normal"] == default["mirror"]["normal"]


def test_a_stated_height_std_reaches_the_run(scene_dir, tmp_path):
    """``--height-sigma 0.005`` (a height measured with a stadiometer): recorded as the
    run's input, the metric scale's std the stated 0.5 % and the measurement's own in
    quadrature (the default's prior in its place without the flag), the distance's std
    narrower and still holding the distance's error; the mirror and the joints the
    same."""
    from mirrorgraph.stature import measurement_rel_std

    truth = read_ground_truth(scene_dir)
    cals, npz = {}, {}
    for flag in ([], ["--height-sigma", "0.005"]):
        out, j3d = tmp_path / f"c{len(flag)}.json", tmp_path / f"j{len(flag)}.npz"
        assert main(["calibrate", str(scene_dir / "easymocap"), "--intrinsics",
                     str(scene_dir / "camera.json"), "--out", str(out), "--subject-height",
                     str(truth["subject_height"]), "--joints3d", str(j3d), "--quiet",
                     *flag]) == 0
        cals[bool(flag)], npz[bool(flag)] = json.loads(out.read_text()), np.load(j3d)
    stated, default = cals[True], cals[False]
    assert stated["input"]["height_sigma"] == 0.005
    assert default["input"]["height_sigma"] == GaugeOptions().height_sigma
    m = measurement_rel_std(stated["refinement"]["stature"])
    assert m == measurement_rel_std(default["refinement"]["stature"])
    assert float(npz[True]["scale_rel_std"]) == pytest.approx(np.hypot(0.005, m), rel=1e-9)
    assert float(npz[False]["scale_rel_std"]) == pytest.approx(
        np.hypot(GaugeOptions().height_sigma, m), rel=1e-9)
    d_std = stated["uncertainty"]["distance_std"]
    assert d_std < default["uncertainty"]["distance_std"]
    assert abs(stated["mirror"]["distance"] - truth["distance"]) < 3 * d_std
    assert stated["mirror"] == default["mirror"]
    assert np.array_equal(npz[True]["joints3d"], npz[False]["joints3d"], equal_nan=True)
    assert (npz[True]["joints_std"][npz[True]["valid"]]
            < npz[False]["joints_std"][npz[False]["valid"]]).all()
