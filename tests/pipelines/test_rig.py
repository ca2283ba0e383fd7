"""Rigs: several cameras and mirrors calibrated from the people in view, against ground truth."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.cli import main
from mirrorgraph.errors import InputError
from mirrorgraph.metrics import normal_angle_deg, rotation_error_deg
from mirrorgraph.pipelines.rig import calibrate_rig
from mirrorgraph.result.rig import virtual_extrinsics
from mirrorgraph.rigs.config import load_rig_config
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.geometry import camera_projection, mirror_projection, triangulate
from mirrorgraph.synth.rig import make_rig, write_rig


def _errors(cal, rig):
    """Per camera (rotation deg, metric position m, scale-aligned position m), the rig scale
    factor truth/estimate, and per mirror (normal deg, distance m)."""
    est = np.array([c.pose[:3, 3] for c in cal.cameras])
    tru = np.array([np.asarray(P)[:3, 3] for P in rig.poses])
    if len(est) > 1:
        s = float(np.sum(est * tru) / np.sum(est * est))
    else:
        d_est = np.array([m.distance for m in cal.mirrors])
        d_tru = np.array([rig.mirrors[rig.mirror_names.index(m.name)][1] for m in cal.mirrors])
        s = float(d_est @ d_tru / (d_est @ d_est))
    cams = [(rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3]),
             float(np.linalg.norm(c.pose[:3, 3] - np.asarray(P)[:3, 3])),
             float(np.linalg.norm(s * c.pose[:3, 3] - np.asarray(P)[:3, 3])))
            for c, P in zip(cal.cameras, rig.poses)]
    mirrors = {}
    for m in cal.mirrors:
        n, d = rig.mirrors[rig.mirror_names.index(m.name)]
        mirrors[m.name] = (normal_angle_deg(m.normal, n), abs(m.distance - d))
    return cams, s, mirrors


@pytest.fixture(scope="module")
def four_cams(tmp_path_factory):
    rig = make_rig("4cams", frames=300, seed=0, noise_std=4.0)
    path = write_rig(rig, tmp_path_factory.mktemp("4cams"))
    return rig, path, calibrate_rig(path)


def test_a_healthy_rig_has_no_camera_marked(four_cams):
    """Every camera of a sound rig keeps nearly all of its keypoints: none failed, the
    JSON says so per camera."""
    _, _, cal = four_cams
    assert not cal.failed_cameras
    doc = cal.to_dict()["cameras"]
    assert all(c["status"] == "ok" and c["reason"] is None and c["fit_share"] > 0.95
               for c in doc), [(c["name"], c["fit_share"]) for c in doc]
    assert not any("failed" in w for w in cal.warnings)


def test_four_camera_rig_meets_the_accuracy_target(four_cams):
    """The issue's target: 4 cameras, 4 px, 300 frames: every camera within 0.5 deg and 2 cm.

    Positions are compared after one scale factor for the whole rig (MirrorCalib's
    translation metric is scale-aligned): the metric scale rests on the subject's
    proportions, checked separately below."""
    rig, _, cal = four_cams
    cams, s, _ = _errors(cal, rig)
    assert [c.name for c in cal.cameras] == rig.camera_names
    assert np.allclose(cal.cameras[0].pose, np.eye(4))
    for rot, _, aligned in cams[1:]:
        assert rot < 0.5
        assert aligned < 0.02
    # metric scale from the subject height: within 1% (the subject's bones differ from
    # Winter's proportions by a few tenths of a per cent here)
    assert abs(s - 1.0) < 0.01
    assert cal.scale == "subject_height"
    assert "stature" in cal.summary() and cal.to_dict()["scale_source"] == cal.scale_source


def test_marginals_are_the_size_of_the_errors(four_cams):
    rig, _, cal = four_cams
    cams, _, _ = _errors(cal, rig)
    rot_err = np.array([c[0] for c in cams[1:]])
    rot_std = np.array([c.rotation_std_deg for c in cal.cameras[1:]])
    assert np.all(rot_std > 0) and cal.cameras[0].rotation_std_deg == 0
    # a handful of cameras: the RMS error and the RMS std agree within a factor of 3
    ratio = np.sqrt(np.mean(rot_err ** 2)) / np.sqrt(np.mean(rot_std ** 2))
    assert 1 / 3 < ratio < 3


def test_three_dimensional_joints_in_the_world_frame(four_cams):
    rig, _, cal = four_cams
    sk = rig.skeleton
    J = sk.calibration_joints
    ok = cal.valid[:, J]
    err = np.linalg.norm(cal.joints3d[:, J][ok] - rig.joints3d[:, J][ok], axis=-1)
    assert ok.mean() > 0.9
    assert np.median(err) < 0.03


def test_every_joint_has_a_std_that_covers_its_error(four_cams):
    rig, _, cal = four_cams
    assert cal.joints_std is not None and cal.joints_std.shape == cal.valid.shape
    ok = cal.valid
    assert np.isfinite(cal.joints_std[ok]).all() and np.isnan(cal.joints_std[~ok]).all()
    err = np.linalg.norm(cal.joints3d[ok] - rig.joints3d[ok], axis=-1)
    z = err / cal.joints_std[ok]
    # the metric std (the height known to 2 %) never thin; not wildly wide either
    assert np.percentile(z, 99) < 3.0 and np.median(z) > 0.05


@pytest.mark.parametrize("kind", ["2cams1mirror", "1cam2mirrors"])
def test_rigs_with_mirrors(tmp_path, kind):
    rig = make_rig(kind, frames=200, seed=1, noise_std=4.0)
    cal = calibrate_rig(write_rig(rig, tmp_path))
    cams, s, mirrors = _errors(cal, rig)
    assert sorted(mirrors) == sorted(rig.mirror_names)
    # by default every keypoint in the direct views, the limbs through the mirrors
    assert len(cal.refinement["joints"]["direct"]) == rig.skeleton.num_joints
    assert len(cal.refinement["joints"]["through_mirrors"]) == len(rig.skeleton.calibration_joints)
    for rot, _, aligned in cams[1:]:
        assert rot < 0.5
        assert aligned < 0.03
    for name, (angle, _) in mirrors.items():
        assert angle < 0.25, name
        m = cal.mirror(name)
        assert 0 < m.rotation_std_deg < 1.0
        assert set(m.seen_by) == {c for c, ms in rig.sees.items() if name in ms}
    # metric scale: the stature measured on the joints from ankle to eyes equals the
    # subject's height (population figures only below the ankle and above the eyes)
    assert cal.scale_source.startswith("stature measured from ankle to eyes")
    assert cal.refinement["stature"]["height"] == pytest.approx(rig.subject_height)
    assert abs(s - 1.0) < 0.01
    # the joints the graph did not use (face and feet through the mirrors) come out
    # triangulated with the calibrated rig
    sk = rig.skeleton
    other = [sk.index(n) for n in ("left_eye", "right_ear", "nose", "left_heel", "right_big_toe")]
    ok = cal.valid[:, other]
    assert ok.mean() > 0.9
    err = np.linalg.norm(cal.joints3d[:, other][ok] - rig.joints3d[:, other][ok], axis=-1)
    assert np.median(err) < 0.03


def test_without_height_lengths_are_in_subject_heights(tmp_path):
    rig = make_rig("2cams1mirror", frames=150, seed=2)
    path = write_rig(rig, tmp_path, include_height=False)
    cal = calibrate_rig(path)
    assert cal.scale == "unit_height" and cal.subject_height is None
    cams, _, _ = _errors(cal, rig)
    # the baseline in subject heights: the true baseline over the true height, to 5%
    baseline = np.linalg.norm(np.asarray(rig.poses[1])[:3, 3]) / rig.subject_height
    assert np.linalg.norm(cal.cameras[1].pose[:3, 3]) == pytest.approx(baseline, rel=0.05)
    assert "subject heights" in cal.to_dict()["length_unit"]


def test_frame_offsets_put_cameras_on_one_clock(tmp_path):
    """A camera whose files start later, with its offset in the rig file, gives the same rig."""
    rig = make_rig("4cams", frames=120, seed=3)
    shift = 17
    rig.detections["cam02"].frame_ids = rig.detections["cam02"].frame_ids + shift
    path = write_rig(rig, tmp_path)
    text = path.read_text()
    parts = text.split("[[cameras]]")
    parts[2] = parts[2].replace("frame_offset = 0", f"frame_offset = {shift}")
    path.write_text("[[cameras]]".join(parts))
    cal = calibrate_rig(path)
    cams, _, _ = _errors(cal, rig)
    assert cams[1][0] < 0.5 and cams[1][2] < 0.03


def test_pose2sim_toml_triangulates_the_truth(four_cams, tmp_path):
    """The written calibration.toml, read back as a Pose2Sim file, projects the truth.

    The truth is brought to the calibration's scale first: the metric scale carries the
    synthetic subject's proportions (this seed's head and feet are 0.7 % off Winter's,
    a few cm at the far cameras), which is not what this test is about."""
    from mirrorgraph.io.camera_toml import read_camera_toml
    from mirrorgraph.export import write_rig_toml

    rig, _, cal = four_cams
    out = tmp_path / "calibration.toml"
    write_rig_toml(cal, out)
    cams = read_camera_toml(out)
    assert list(cams) == rig.camera_names
    sk = rig.skeleton
    X = rig.joints3d[:, sk.calibration_joints].reshape(-1, 3)
    _, s, _ = _errors(cal, rig)                  # truth = s x calibration
    for name, P in zip(rig.camera_names, rig.poses):
        P = np.asarray(P)
        uv_true = camera_projection(rig.K[rig.camera_names.index(name)], P)
        Xh = np.column_stack([X, np.ones(len(X))])
        a = Xh @ uv_true.T
        b = np.column_stack([X / s, np.ones(len(X))]) @ cams[name].projection_matrix.T
        px = np.linalg.norm(a[:, :2] / a[:, 2:] - b[:, :2] / b[:, 2:], axis=1)
        assert np.median(px) < 6.0, name


def test_virtual_cameras_of_the_flipped_image(tmp_path):
    """With --with-virtual each view through a mirror becomes an ordinary camera of the
    flipped image: with the flipped keypoints it triangulates the real joints."""
    from mirrorgraph.export import flip_camera_matrix
    from mirrorgraph.io.camera_toml import read_camera_toml

    rig = make_rig("1cam2mirrors", frames=60, seed=4, noise_std=0.0)
    cal = calibrate_rig(write_rig(rig, tmp_path))
    out = tmp_path / "calibration.toml"
    assert main(["calibrate-rig", str(tmp_path / "rig.toml"), "--out", str(out),
                 "--with-virtual", "--quiet"]) == 0
    cams = read_camera_toml(out)
    assert set(cams) == {"cam01", "cam01_mirror_left", "cam01_mirror_right"}
    # virtual_extrinsics agrees with the reflection: pi(K' (R X + t)) = flip(pi(K S(X)))
    K = rig.K[0]
    W = rig.image_size[0]
    X = rig.joints3d[:5].reshape(-1, 3)
    for m in cal.mirrors:
        R, t = virtual_extrinsics(cal.cameras[0].pose, m.normal, m.distance)
        a = (X @ R.T + t) @ flip_camera_matrix(K, W).T
        P = mirror_projection(K, cal.cameras[0].pose, m.normal, m.distance)
        b = np.column_stack([X, np.ones(len(X))]) @ P.T
        assert np.allclose(a[:, 0] / a[:, 2], W - b[:, 0] / b[:, 2], atol=1e-6)
        assert np.allclose(a[:, 1] / a[:, 2], b[:, 1] / b[:, 2], atol=1e-6)
    doc = json.loads(out.with_suffix(".json").read_text())
    assert {m["name"] for m in doc["mirrors"]} == {"mirror_left", "mirror_right"}
    assert doc["scale"] == "subject_height"


def test_triangulate_views_exact_without_noise():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (50, 3)) + [0, 0, 5]
    K = np.array([[1000.0, 0, 960], [0, 1000.0, 540], [0, 0, 1]])
    P1 = camera_projection(K, np.eye(4))
    pose = np.eye(4)
    pose[:3, 3] = [1.0, 0.0, 0.0]
    P2 = mirror_projection(K, pose, np.array([0.6, 0.0, 0.8]), 6.0)

    def proj(P):
        h = np.column_stack([X, np.ones(len(X))]) @ P.T
        return h[:, :2] / h[:, 2:]

    mask = np.ones(len(X), bool)
    Y, ok = triangulate([P1, P2], [proj(P1), proj(P2)], [mask, mask])
    assert ok.all() and np.allclose(Y, X, atol=1e-8)
    one = mask.copy()
    one[:10] = False
    Y, ok = triangulate([P1, P2], [proj(P1), proj(P2)], [mask, one])
    assert not ok[:10].any() and np.isnan(Y[:10]).all()


# --------------------------------------------------------------------------- bad input
def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "rig.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, field", [
    ("[[cameras]\nname = 'a'", None),
    ("subject_height = 1.7", "cameras"),
    ("[[cameras]]\nname = 'a'\nkeypoints = 'missing.json'", "cameras[0].keypoints"),
    ("[[cameras]]\nname = 'a'\nkeypoints = '.'\nmirrors = ['wall']", "cameras[0].mirrors"),
    ("[[cameras]]\nname = 'a'\nkeypoints = '.'\nlens = 3", "cameras[0]"),
    ("[[cameras]]\nname = 'a'\nkeypoints = '.'\nskeleton = 'BODY_99'", "cameras[0].skeleton"),
    ("subject_height = -1\n[[cameras]]\nname = 'a'\nkeypoints = '.'", "subject_height"),
    ("[[cameras]]\nname = 'a'\nkeypoints = '.'\nframe_offset = 1.5", "cameras[0].frame_offset"),
    ("[[cameras]]\nname = 'a'\nkeypoints = '.'\n[[cameras]]\nname = 'a'\nkeypoints = '.'",
     "cameras[1].name"),
    ("[[cameras]]\nname = 'a'\nkeypoints = '.'\n[[mirrors]]\nname = 'wall'", "mirrors"),
    ("joints = 3\n[[cameras]]\nname = 'a'\nkeypoints = '.'", "joints"),
    ("joints = 'some'\n[[cameras]]\nname = 'a'\nkeypoints = '.'", "joints"),
])
def test_malformed_rig_files_name_the_field(tmp_path, text, field):
    path = _write(tmp_path, text)
    with pytest.raises(InputError) as exc:
        load_rig_config(path)
    assert str(path) in str(exc.value)
    if field is not None:
        assert exc.value.field == field


def test_cli_bad_rig_is_one_line(tmp_path, capsys):
    path = _write(tmp_path, "[[cameras]]\nname = 'a'\nkeypoints = 'nope'")
    assert main(["calibrate-rig", str(path), "--out", str(tmp_path / "c.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "keypoints" in err[0] and "rig.toml" in err[0]
    assert not (tmp_path / "c.toml").exists()


def test_camera_that_never_sees_the_person_with_the_others(tmp_path):
    """A camera whose keypoints belong to other frames cannot be placed: a clear error
    naming the camera and its frames."""
    rig = make_rig("4cams", frames=60, seed=5)
    rig.detections["cam03"].frame_ids = rig.detections["cam03"].frame_ids + 1000
    path = write_rig(rig, tmp_path)
    with pytest.raises(InputError, match="cam03's frames 1000..1059"):
        calibrate_rig(path)


def test_rig_toml_written_by_synth_is_the_documented_form(tmp_path):
    rig = make_rig("2cams1mirror", frames=10, seed=0)
    path = write_rig(rig, tmp_path)
    doc = tomllib.loads(path.read_text())
    assert set(doc) == {"subject_height", "cameras", "mirrors"}
    cfg = load_rig_config(path)
    assert [c.name for c in cfg.cameras] == rig.camera_names
    assert cfg.cameras[0].intrinsics_section == rig.camera_names[0]


def test_a_bystander_does_not_break_the_rig(tmp_path):
    """A second person, more confident than the subject in one camera: the subject is
    found there by epipolar consistency with the first camera."""
    from mirrorgraph.geometry import camera_projection

    rig = make_rig("4cams", frames=150, seed=6)
    rng = np.random.default_rng(0)
    other = make_rig("4cams", frames=150, seed=11).joints3d     # another person, motion
    other = other - np.nanmean(other, axis=(0, 1)) + np.nanmean(rig.joints3d, axis=(0, 1)) \
        + np.array([1.2, 0.0, 0.6])
    for ci, name in enumerate(rig.camera_names):
        P = camera_projection(rig.K[ci], rig.poses[ci])
        h = np.concatenate([other, np.ones(other.shape[:-1] + (1,))], -1) @ P.T
        uv = h[..., :2] / h[..., 2:] + rng.normal(0, 4.0, other.shape[:-1] + (2,))
        conf = 1.0 if name == "cam03" else 0.05          # cam03 prefers the bystander
        det = rig.detections[name]
        det.people = [np.concatenate([p, np.column_stack([uv[t], np.full(uv.shape[1], conf)])[None]])
                      for t, p in enumerate(det.people)]
    cal = calibrate_rig(write_rig(rig, tmp_path))
    cams, _, _ = _errors(cal, rig)
    for rot, _, aligned in cams[1:]:
        assert rot < 0.5 and aligned < 0.03
    assert cal.to_dict()["cameras"][2]["matched_frames"] > 100


def test_every_joint_when_asked(tmp_path):
    """Face and feet too (the default in direct views): more data, a smaller std."""
    rig = make_rig("4cams", frames=120, seed=7)
    path = write_rig(rig, tmp_path)
    limbs = calibrate_rig(path, CalibrateOptions(joints="limbs"))
    every = calibrate_rig(path)
    assert len(every.refinement["joints"]["direct"]) == rig.skeleton.num_joints
    assert len(limbs.refinement["joints"]["direct"]) == len(rig.skeleton.calibration_joints)
    for a, b in zip(limbs.cameras[1:], every.cameras[1:]):
        assert b.rotation_std_deg < 0.85 * a.rotation_std_deg
    cams, _, _ = _errors(every, rig)
    assert max(c[0] for c in cams) < 0.5
    with pytest.raises(InputError, match="unknown joint"):
        calibrate_rig(path, CalibrateOptions(joints="left_wrist,tail,nose,neck"))


def test_rig_report_figures(tmp_path):
    pytest.importorskip("matplotlib", reason="the plot extra; the test command installs it")
    rig = make_rig("1cam2mirrors", frames=60, seed=8)
    path = write_rig(rig, tmp_path / "rig")
    out = tmp_path / "calibration.toml"
    assert main(["calibrate-rig", str(path), "--out", str(out), "--report",
                 str(tmp_path / "report"), "--quiet"]) == 0
    for name in ("rig_top_view.png", "rig_residuals.png"):
        data = (tmp_path / "report" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


@pytest.mark.parametrize("skeleton, fmt", [("HALPE_26", "mmpose"), ("BODY_25B", "openpose")])
def test_pose2sim_layouts_in_a_rig(tmp_path, skeleton, fmt):
    """Pose2Sim's layouts (RTMPose HALPE_26, OpenPose BODY_25B), named or detected."""
    rig = make_rig("2cams1mirror", frames=120, seed=9, skeleton=skeleton)
    path = write_rig(rig, tmp_path, fmt)
    cal = calibrate_rig(path)
    assert cal.skeleton == skeleton
    cams, _, mirrors = _errors(cal, rig)
    assert cams[1][0] < 0.5 and cams[1][2] < 0.03
    assert mirrors["wall"][0] < 0.25


def test_a_rig_takes_the_height_once(tmp_path):
    """``calibrate_rig(subject_height=...)`` and ``options.subject_height`` are one
    setting: two different heights are refused (before any reading), not one ignored."""
    from mirrorgraph.errors import InputError
    from mirrorgraph.graph.options import RefineOptions

    rig = make_rig("2cams1mirror", frames=10, seed=0)
    path = write_rig(rig, tmp_path)
    with pytest.raises(InputError, match="give the height once"):
        calibrate_rig(path, CalibrateOptions(subject_height=1.8,
                                             refine_options=RefineOptions(subject_height=1.7)))
    with pytest.raises(InputError, match="not a human height"):
        calibrate_rig(path, CalibrateOptions(refine_options=RefineOptions(subject_height=175.0)))


def _unnamed_skeleton(path: Path) -> Path:
    """The rig file without its ``skeleton = ...`` lines (the layout from the keypoints)."""
    lines = path.read_text().splitlines()
    path.write_text("\n".join(x for x in lines if not x.startswith("skeleton")) + "\n")
    return path


def _hide_eyes(rig, camera: str) -> None:
    """``camera`` sees the subject from behind: BODY_25B's joints 1 and 2 (the eyes), which
    tell it from BODY_25, never confident there (in place)."""
    for p in rig.detections[camera].people:
        if len(p):
            p[:, 1:3, 2] = 0.0


def test_one_skeleton_for_the_rig_from_the_cameras_that_tell(tmp_path, capsys):
    """Pose2Sim's demo as OpenPose BODY_25B JSON: a camera that sees the subject from behind
    cannot tell BODY_25B from BODY_25 on its own (issue #24: it was refused); the rig's
    other cameras decide for it. Where no camera can tell, the rig is refused in one line
    naming the rig file and the cameras."""
    rig = make_rig("4cams", frames=120, seed=1, noise_std=4.0, skeleton="BODY_25B")
    _hide_eyes(rig, "cam03")
    path = _unnamed_skeleton(write_rig(rig, tmp_path / "one", "openpose"))
    from mirrorgraph.io import read_keypoints
    with pytest.raises(InputError, match="only 0 confident detections"):
        read_keypoints(load_rig_config(path).cameras[2].keypoints)       # alone: refused
    cal = calibrate_rig(path)
    assert cal.skeleton == "BODY_25B"
    cams, _, _ = _errors(cal, rig)
    assert all(rot < 0.5 and aligned < 0.03 for rot, _, aligned in cams[1:]), cams
    for camera in ("cam01", "cam02", "cam04"):
        _hide_eyes(rig, camera)
    path = _unnamed_skeleton(write_rig(rig, tmp_path / "none", "openpose"))
    assert main(["calibrate-rig", str(path), "--out", str(tmp_path / "c.toml"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rig.toml" in err[0] and "cam01, cam02, cam03, cam04" in err[0], err
    assert 'skeleton = "BODY_25B"' in err[0]


def test_an_image_size_that_disagrees_with_the_keypoints_is_reported(tmp_path):
    """Pose2Sim's demo: its calibration states 1088 x 1920 where cameras 1 and 2 are 1080 x
    1920 videos (issue #24: nothing said so). One warning line per such camera, naming the
    camera, the intrinsics file (or the rig file's image_size), the keypoints and both
    sizes; none where they agree."""
    from mirrorgraph.rigs.observations import load_observations
    rig = make_rig("4cams", frames=40, seed=1, noise_std=4.0)
    path = write_rig(rig, tmp_path, "easymocap")            # its files carry the image size
    w, h = rig.image_size
    calib = tmp_path / "Calib.toml"
    text = calib.read_text()
    sections = text.split("[cam02]")
    assert len(sections) == 2 and f"size = [ {w:.1f}, {h:.1f} ]" in sections[1], text
    calib.write_text(sections[0] + "[cam02]" + sections[1].replace(
        f"size = [ {w:.1f}, {h:.1f} ]", f"size = [ {w:.1f}, {h + 8:.1f} ]", 1))
    rig_text = path.read_text().replace(          # cam04: no intrinsics, a wrong image_size
        'intrinsics = "Calib.toml"\nintrinsics_section = "cam04"\n',
        f"image_size = [{w}, {h - 8}]\n")
    path.write_text(rig_text)
    obs = load_observations(load_rig_config(path))
    about_size = [x for x in obs.warnings if "image" in x]
    assert len(about_size) == 2, obs.warnings
    cam02, cam04 = sorted(about_size)
    assert cam02.startswith("camera cam02: its intrinsics (") and str(calib) in cam02
    assert f"{w}x{h + 8} image" in cam02 and f"cam02_json) {w}x{h};" in cam02
    assert cam04.startswith("camera cam04: the rig file's image_size state") \
        and f"{w}x{h - 8} image" in cam04 and f"cam04_json) {w}x{h};" in cam04
    assert all("\n" not in x for x in about_size)


def test_a_single_mirror_calibrates_as_the_rig_of_one_camera(tmp_path):
    """The single mirror is the rig of one camera and one mirror: its keypoints and camera
    given to ``calibrate_rig`` as a one-camera rig file give the numbers ``calibrate``
    gives (the same solve: the configuration follows what varies, ``solve_config``; to
    1e-12 on bench/bench_one_camera_rig.py's 30 wide scenes), within its std of the truth."""
    import mirrorgraph as mg
    from mirrorgraph.metrics import mirror_rotation_error_deg, normal_angle_deg
    from mirrorgraph.synth import make_wide_scene, write_scene

    s = make_wide_scene(6, frames=300)
    write_scene(s, tmp_path, formats=("mmpose",))
    (tmp_path / "rig.toml").write_text(
        f'subject_height = {s.subject_height}\n[[cameras]]\nname = "camera"\n'
        'keypoints = "keypoints_mmpose.json"\nintrinsics = "camera.json"\nmirrors = ["mirror"]\n'
        '[[mirrors]]\nname = "mirror"\n')
    one = mg.calibrate(tmp_path / "keypoints_mmpose.json", s.intrinsics,
                       mg.CalibrateOptions(subject_height=s.subject_height)).calibration
    rig = mg.calibrate_rig(tmp_path / "rig.toml")
    m = rig.mirrors[0]
    np.testing.assert_allclose(m.normal, one.normal, rtol=0, atol=1e-9)
    assert m.distance == pytest.approx(one.distance, rel=1e-9)
    assert m.rotation_std_deg == pytest.approx(one.uncertainty["rotation_std_deg"], rel=1e-6)
    # the same parts; the stature's sampling std measured on the rig's completed joints
    # (the single mirror's: its graph's and the chain's triangulated) differs by ~1e-3 of it
    assert m.distance_std == pytest.approx(one.uncertainty["distance_std"], rel=1e-5)
    assert normal_angle_deg(m.normal, one.normal) < 1e-6
    assert mirror_rotation_error_deg(m.normal, s.normal) < 3 * m.rotation_std_deg
    assert abs(m.distance / s.distance - 1) < 0.02
    view = rig.mirror_view()                  # and back: the rig's view is a Calibration
    np.testing.assert_allclose(view.normal, m.normal, atol=1e-12)


def test_a_stated_keypoint_placement_narrows_the_rig_scale(tmp_path):
    """A rig's metric scale with the keypoints stated on the landmarks
    (``RefineOptions.keypoint_offset`` 0): the stature records it, the cameras' position
    stds (the scale's share in them) are smaller than with the literature's placement,
    and the rig is the same."""
    from mirrorgraph.graph import RefineOptions
    from mirrorgraph.stature import measurement_rel_std, unmeasured_rel_std

    rig = make_rig("2cams1mirror", frames=60, seed=1, noise_std=4.0)
    path = write_rig(rig, tmp_path)
    default = calibrate_rig(path)
    zero = calibrate_rig(path, CalibrateOptions(
        refine_options=RefineOptions(keypoint_offset=0.0)))
    st = zero.refinement["stature"]
    assert st["keypoint_offset"] == 0.0 and "0.0 cm" in zero.scale_source
    assert measurement_rel_std(st) == pytest.approx(np.sqrt(
        st["side_rel_diff"] ** 2 + st["bones_rel_spread"] ** 2
        + unmeasured_rel_std(st["top"]) ** 2), rel=1e-12)
    assert measurement_rel_std(st) < measurement_rel_std(default.refinement["stature"])
    far = int(np.argmax([np.linalg.norm(c.pose[:3, 3]) for c in default.cameras]))
    assert zero.cameras[far].position_std < default.cameras[far].position_std
    np.testing.assert_allclose(zero.cameras[far].pose, default.cameras[far].pose, atol=1e-9)


def test_a_60_fps_rig_holds_the_acceleration_prior_of_30_fps_in_h_per_s2(tmp_path, monkeypatch):
    """The rig's smoothness priors are stated at 30 fps and taken at the rig clock's frame
    interval (``PriorOptions.at_frame_rate``): a 60 fps rig's graph holds a quarter of the
    sigmas per frame^2, the same acceleration in h/s^2."""
    import mirrorgraph.pipelines.rig as rig_module
    from mirrorgraph.graph.options import RefineOptions

    seen = []
    solve = rig_module.solve_rig
    monkeypatch.setattr(rig_module, "solve_rig",
                        lambda rig, opts, *a, **k: seen.append(opts) or solve(rig, opts, *a, **k))
    path = write_rig(make_rig("2cams1mirror", frames=120, seed=1, fps=60.0), tmp_path)
    # the detections carry no frame rate: the rig file gives each camera's
    path.write_text(path.read_text().replace("frame_offset = 0", "frame_offset = 0\nfps = 60.0"))
    calibrate_rig(path)
    base = RefineOptions()
    assert seen and all(o.joints_smoothness_sigma == pytest.approx(base.joints_smoothness_sigma / 4)
                        and o.smoothness_sigma == pytest.approx(base.smoothness_sigma / 4)
                        for o in seen)
