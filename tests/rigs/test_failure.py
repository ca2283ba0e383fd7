"""A rig camera that fits under half of its keypoints: marked failed with its likeliest
cause, never written with exit 0 (synthetic rigs with a known cause).

A camera's wrong ``frame_offset`` is the cause tested here: with the offsets taken as given
(``time_offsets="fixed"``, ``--fixed-offsets``); the default search undoes it
(tests/rigs/test_clocks.py)."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from mirrorgraph.cli import main
from mirrorgraph.cli.rig import EXIT_FAILED_CAMERA
from mirrorgraph.errors import DegenerateGeometryError, FailedCameraError
from mirrorgraph.initial.rig import observed
from mirrorgraph.metrics import rotation_error_deg
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.pipelines.rig import calibrate_rig
from mirrorgraph.rigs.config import load_rig_config
from mirrorgraph.rigs.failure import failure_cause, fit_shares, scan_offsets
from mirrorgraph.rigs.observations import load_observations
from mirrorgraph.synth.rig import make_rig, write_rig


#: The rig files' frame offsets as given (no search).
FIXED = CalibrateOptions(time_offsets="fixed")


def _shifted_rig(folder, shift: int, camera: int = 2, seed: int = 0, fps: float = 30.0):
    """The 4-camera synthetic rig with camera ``camera``'s ``frame_offset`` set to
    ``shift`` in its rig file: its frames ``shift`` frames off the others'."""
    rig = make_rig("4cams", frames=300, seed=seed, noise_std=4.0, fps=fps)
    path = write_rig(rig, folder)
    parts = path.read_text().split("[[cameras]]")
    parts[camera + 1] = parts[camera + 1].replace("frame_offset = 0",
                                                  f"frame_offset = {shift}")
    shifted = folder / "rig_shifted.toml"
    shifted.write_text("[[cameras]]".join(parts))
    return rig, shifted


def _points(obs):
    out = []
    for cam in obs.cameras:
        p = np.asarray(cam.real[..., :2], float).copy()
        p[~observed(cam.real)] = np.nan
        out.append(p)
    return out


def test_fit_shares_pool_a_cameras_views():
    shares = fit_shares(["a", "b"], ["a", "a/m", "b"], [10, 5, 3], [10, 10, 12])
    assert shares == {"a": (15, 20), "b": (3, 12)}


def test_scan_finds_a_ten_frame_shift_and_nothing_in_a_synchronised_camera(tmp_path):
    """The shifted camera's epipolar consistency peaks at the true shift, the fix it names
    is the frame offset that undoes it; a synchronised camera's best shift is 0."""
    _, path = _shifted_rig(tmp_path, 10)
    cfg = load_rig_config(path)
    obs = load_observations(cfg, time_offsets="fixed")
    pts, Ks = _points(obs), [c.intrinsics.K for c in obs.cameras]
    scan = scan_offsets(pts, Ks, 2, [0, 1, 3], 8.0)
    assert scan.best == -10
    assert scan.at(-10) > 0.9 > scan.at(0) + 0.2
    cause = failure_cause(scan, cfg.cameras[2].frame_offset)
    assert "time offset" in cause and "frame_offset = 0" in cause, cause
    assert scan_offsets(pts, Ks, 1, [0, 3], 8.0, window=4).best == 0


def test_failure_cause_without_data_or_without_an_offset():
    from mirrorgraph.rigs.failure import OffsetScan
    shifts = np.arange(-2, 3)
    few = OffsetScan(shifts, np.full(5, 0.3), np.full(5, 0.8), np.full(5, 40))
    assert failure_cause(few).startswith("too few keypoints")
    late = OffsetScan(shifts, np.array([.3, .9, .4, .3, .3]), np.array([.8, .1, .7, .8, .8]),
                      np.full(5, 5000))
    assert "shifted by -3 " in failure_cause(late, 0, frame_step=3)
    assert "frame_offset = 2 " in failure_cause(late, 5, frame_step=3)
    flat = OffsetScan(shifts, np.array([.30, .31, .32, .31, .30]),
                      np.array([.80, .79, .78, .79, .80]), np.full(5, 5000))
    assert failure_cause(flat).startswith("its people do not match")


@pytest.fixture(scope="module")
def late_rig(tmp_path_factory):
    """cam03 15 frames off: the rig keeps under half of its keypoints."""
    return _shifted_rig(tmp_path_factory.mktemp("late"), 15)


def test_a_camera_under_half_is_refused_with_its_cause(late_rig):
    _, path = late_rig
    with pytest.raises(FailedCameraError) as info:
        calibrate_rig(path, FIXED)
    assert isinstance(info.value, DegenerateGeometryError)
    assert info.value.cameras == ("cam03",)
    msg = str(info.value)
    assert "\n" not in msg and "camera cam03 failed" in msg and "time offset" in msg, msg
    assert "frame_offset = 0" in msg, msg
    cal = info.value.calibration
    assert [c.status for c in cal.cameras] == ["ok", "ok", "failed", "ok"]


def test_keep_failed_writes_the_others_marks_it_and_exits_3(late_rig, tmp_path, capsys):
    rig, path = late_rig
    out = tmp_path / "calibration.toml"
    assert main(["calibrate-rig", str(path), "--out", str(out), "--fixed-offsets"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cam03" in err[0] and "--keep-failed" in err[0], err
    assert not out.exists() and not out.with_suffix(".json").exists()

    code = main(["calibrate-rig", str(path), "--out", str(out), "--keep-failed",
                 "--with-virtual", "--fixed-offsets"])
    assert code == EXIT_FAILED_CAMERA == 3
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and "camera cam03 failed" in err[0] and "time offset" in err[0]
    toml = tomllib.loads(out.read_text())
    assert "cam03" not in toml and {"cam01", "cam02", "cam04"} <= set(toml)
    doc = json.loads(out.with_suffix(".json").read_text())
    status = {c["name"]: (c["status"], c["fit_share"], c["reason"]) for c in doc["cameras"]}
    assert status["cam03"][0] == "failed" and status["cam03"][1] < 0.5
    assert "time offset" in status["cam03"][2]
    assert all(s == "ok" and f > 0.9 and r is None
               for n, (s, f, r) in status.items() if n != "cam03")
    # the cameras kept are where they are (the shifted one costs them nothing)
    for c in doc["cameras"]:
        if c["name"] != "cam03":
            i = rig.camera_names.index(c["name"])
            R = np.asarray(c["pose_camera_to_world"])[:3, :3]
            assert rotation_error_deg(R, np.asarray(rig.poses[i])[:3, :3]) < 0.5


def test_a_camera_refused_by_the_matching_names_its_time_offset(tmp_path):
    """At 15 fps a 10-frame shift leaves no track of cam03 consistent with cam01's person:
    the refusal says which offset undoes it."""
    _, path = _shifted_rig(tmp_path, 10, fps=15.0)
    with pytest.raises(DegenerateGeometryError) as info:
        calibrate_rig(path, FIXED)
    msg = str(info.value)
    assert "camera cam03" in msg and "time offset" in msg and "shifted by -10" in msg, msg
    assert "frame_offset = 0" in msg and "\n" not in msg


def test_a_camera_seeing_another_person_is_never_written(tmp_path, capsys):
    """cam03's keypoints from another recording (another person, another motion): refused
    with one line naming it, nothing written."""
    rig = make_rig("4cams", frames=300, seed=0, noise_std=4.0)
    path = write_rig(rig, tmp_path / "rig")
    other = write_rig(make_rig("4cams", frames=300, seed=5, noise_std=4.0), tmp_path / "other")
    text = path.read_text().replace('keypoints = "pose/cam03_json"',
                                    f'keypoints = "{other.parent / "pose" / "cam03_json"}"')
    (tmp_path / "rig" / "mixed.toml").write_text(text)
    out = tmp_path / "calibration.toml"
    code = main(["calibrate-rig", str(tmp_path / "rig" / "mixed.toml"), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and not out.exists()
    assert len(err) == 1 and "cam03" in err[0] and "time offset" not in err[0], err
