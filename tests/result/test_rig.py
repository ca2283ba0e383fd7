"""One result for one mirror and for rigs: the single mirror as the rig of one camera and one
mirror, a rig's camera and mirror as a single mirror's calibration, the rig JSON read back,
and one exporter that writes either (checked against the geometry and the synthetic truth)."""

import tomllib

import cv2
import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.errors import InputError
from mirrorgraph.export import export_calibration
from mirrorgraph.geometry import project, reflect_points
from mirrorgraph.result.rig import write_rig_json
from mirrorgraph.metrics import normal_angle_deg
from mirrorgraph.result.rig import RigCalibration, read_rig_calibration
from mirrorgraph.synth import make_rig, make_scene, write_rig


@pytest.fixture(scope="module")
def two_cams(tmp_path_factory):
    rig = make_rig("2cams1mirror", frames=120, seed=7)
    path = write_rig(rig, tmp_path_factory.mktemp("rig"))
    cal = mg.calibrate_rig(path, mg.CalibrateOptions(subject_height=rig.subject_height))
    return rig, cal


def test_a_single_mirror_is_the_rig_of_one_camera_and_one_mirror():
    scene = make_scene(frames=120, seed=5)
    cal = mg.calibrate(scene.detections, scene.intrinsics,
                       mg.CalibrateOptions(subject_height=scene.subject_height)).calibration
    rig = RigCalibration.from_mirror(cal)
    assert [c.name for c in rig.cameras] == ["camera"] and [m.name for m in rig.mirrors] == ["mirror"]
    assert rig.scale == "subject_height" and rig.mirrors[0].distance == cal.distance
    back = rig.mirror_view()
    assert np.array_equal(back.normal, cal.normal) and back.distance == cal.distance
    assert back.uncertainty["rotation_std_deg"] == cal.uncertainty["rotation_std_deg"]
    np.testing.assert_array_equal(back.uncertainty["normal_cov"], cal.uncertainty["normal_cov"])
    # an unknown scale stays unknown (lengths in mirror distances)
    un = mg.calibrate(scene.detections, scene.intrinsics).calibration
    assert RigCalibration.from_mirror(un).scale == "unknown"
    assert RigCalibration.from_mirror(un).mirror_view().distance is None


def test_a_rigs_mirror_seen_from_any_camera_is_a_single_mirror_in_its_frame(two_cams):
    rig, cal = two_cams
    n_w, d_w = rig.mirror("wall")
    for i, name in enumerate(rig.camera_names):
        if "wall" not in rig.sees[name]:
            continue
        view = cal.mirror_view(name, "wall")
        P = np.asarray(rig.poses[i])                      # camera-to-world, the truth
        n_true = P[:3, :3].T @ n_w
        d_true = d_w - n_w @ P[:3, 3]
        err = normal_angle_deg(view.normal, n_true)
        std = view.uncertainty["rotation_std_deg"]
        assert err < max(4 * std, 0.05), (name, err, std)
        assert abs(view.distance - d_true) < 0.03 * d_true
        assert view.input["rig"] == {"camera": name, "mirror": "wall"}
    with pytest.raises(InputError, match="no camera"):
        cal.mirror_view("nobody")


def test_the_rig_json_reads_back(two_cams, tmp_path):
    _, cal = two_cams
    write_rig_json(cal, tmp_path / "rig.json")
    back = read_rig_calibration(tmp_path / "rig.json")
    assert [c.name for c in back.cameras] == [c.name for c in cal.cameras]
    for a, b in zip(back.cameras, cal.cameras):
        np.testing.assert_array_equal(a.pose, b.pose)
        np.testing.assert_array_equal(a.intrinsics.K, b.intrinsics.K)
        assert a.rotation_std_deg == b.rotation_std_deg
    for a, b in zip(back.mirrors, cal.mirrors):
        np.testing.assert_allclose(a.normal, b.normal, rtol=0, atol=1e-15)
        assert a.distance == b.distance and a.seen_by == b.seen_by
    # the subject's path stands for the joints the JSON does not hold
    k = back.joints3d.shape[0]
    assert back.joints3d.shape == (k, 1, 3) and 100 <= k <= 120 and back.valid.all()
    rows = np.searchsorted(cal.frame_ids, back.frame_ids)
    X = np.where(cal.valid[rows, :, None], cal.joints3d[rows], np.nan)
    np.testing.assert_allclose(back.joints3d[:, 0], np.nanmean(X, axis=1), atol=1e-5)
    (tmp_path / "bad.json").write_text('{"cameras": [{"name": "a"}], "mirrors": []}')
    with pytest.raises(InputError, match="bad.json"):
        read_rig_calibration(tmp_path / "bad.json")


@pytest.mark.parametrize("fmt", ["pose2sim", "anipose"])
def test_one_exporter_writes_a_rig_with_its_mirror_views(two_cams, tmp_path, fmt):
    """A rig JSON through ``export_calibration``: every camera, then every camera's view
    through the mirror as the camera of the flipped image; each projects the rig's points
    (and their reflections, flipped) where the rig does."""
    rig, cal = two_cams
    write_rig_json(cal, tmp_path / "rig.json")
    assert export_calibration(tmp_path / "rig.json", fmt, tmp_path / "out.toml") == []
    doc = tomllib.loads((tmp_path / "out.toml").read_text())
    sections = [doc[k] for k in doc if k != "metadata"]
    names = [s["name"] for s in sections]
    views = [f"{c}_wall" for c in rig.camera_names if "wall" in rig.sees[c]]
    assert names == list(rig.camera_names) + views
    X = np.asarray(rig.joints3d)[::10].reshape(-1, 3)
    X = X[np.isfinite(X).all(1)]
    n_w, d_w = cal.mirrors[0].normal, cal.mirrors[0].distance
    for s in sections:
        K = np.array(s["matrix"], float)
        R = cv2.Rodrigues(np.array(s["rotation"], float))[0]
        t = np.array(s["translation"], float)
        got = project(K, X @ R.T + t)
        cam = cal.camera(s["name"].split("_wall")[0])
        if s["name"].endswith("_wall"):                    # the reflection, flipped
            S = reflect_points(X, n_w, d_w)
            want = project(cam.intrinsics.K, S @ cam.R.T + cam.t)
            want[:, 0] = s["size"][0] - want[:, 0]
        else:
            want = project(cam.intrinsics.K, X @ cam.R.T + cam.t)
        np.testing.assert_allclose(got, want, atol=1e-6)


def test_report_and_export_commands_take_a_rigs_json(two_cams, tmp_path, capsys):
    pytest.importorskip("matplotlib", reason="the plot extra; the test command installs it")
    from mirrorgraph.cli import main

    _, cal = two_cams
    write_rig_json(cal, tmp_path / "rig.json")
    assert main(["report", str(tmp_path / "rig.json"), "--out", str(tmp_path / "fig"),
                 "--quiet"]) == 0
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == ["rig_residuals.png",
                                                                    "rig_top_view.png"]
    assert main(["export", str(tmp_path / "rig.json"), "--to", "pose2sim",
                 str(tmp_path / "c.toml")]) == 0
    assert "every camera of the rig" in capsys.readouterr().out
    doc = tomllib.loads((tmp_path / "c.toml").read_text())
    assert [k for k in doc if k != "metadata"] == ["cam01", "cam02", "cam01_wall", "cam02_wall"]
    assert main(["report", str(tmp_path / "rig.json"), "--out", str(tmp_path / "f2"),
                 "--video", "x.mp4"]) == 2
    assert "a rig's report is drawn from its JSON alone" in capsys.readouterr().err
