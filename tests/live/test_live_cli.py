"""``mirrorgraph live`` end to end: a keypoint file replayed into JSON lines, and the
one-line refusals."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mirrorgraph.cli import main
from mirrorgraph.metrics import mirror_rotation_error_deg
from mirrorgraph.synth import read_ground_truth


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("live_scene")
    assert main(["synth", "--out", str(out), "--frames", "300", "--seed", "21",
                 "--subject-height", "1.7", "--formats", "mmpose,npz", "--quiet"]) == 0
    return out


@pytest.mark.parametrize("fmt", ["keypoints_mmpose.json", "keypoints.npz"])
def test_live_replays_keypoints_into_json_lines(scene_dir, tmp_path, fmt, capsys):
    out = tmp_path / "live.jsonl"
    assert main(["live", str(scene_dir / fmt), "--intrinsics", str(scene_dir / "camera.json"),
                 "--subject-height", "1.7", "--jsonl", str(out),
                 "--as-fast-as-possible"]) == 0
    said = capsys.readouterr().out
    assert "wrote 300 lines" in said and "status calibrated" in said
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(lines) == 300 and [ln["frame"] for ln in lines] == list(range(300))
    assert lines[0]["status"] == "initialising" and lines[0]["mirror"]["normal"] is None
    last = lines[-1]
    assert last["status"] == "calibrated" and last["mirror"]["scale"] == "subject_height"
    truth = read_ground_truth(scene_dir)
    assert mirror_rotation_error_deg(np.array(last["mirror"]["normal"]), truth["normal"]) < 1.0
    joints = [X for X in last["joints3d"] if X is not None]
    assert joints and all(len(X) == 3 for X in joints)
    assert "NaN" not in out.read_text()


def test_live_quiet_prints_nothing(scene_dir, tmp_path, capsys):
    out = tmp_path / "q.jsonl"
    assert main(["live", str(scene_dir / "keypoints_mmpose.json"), "--image-size", "1920x1080",
                 "--jsonl", str(out), "--as-fast-as-possible", "--quiet"]) == 0
    said = capsys.readouterr()
    assert said.out == "" and said.err == ""
    last = json.loads(out.read_text().splitlines()[-1])
    assert last["mirror"]["focal_px"] is not None and last["mirror"]["distance_std"] is None


def test_a_camera_that_cannot_be_opened_is_one_line(tmp_path, capsys):
    assert main(["live", "97", "--image-size", "640x480", "--jsonl",
                 str(tmp_path / "c.jsonl")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: camera 97") and "cannot be opened" in err[0]
    assert not (tmp_path / "c.jsonl").exists()


def test_refusals_name_the_field(scene_dir, tmp_path, capsys):
    kp = str(scene_dir / "keypoints_mmpose.json")
    assert main(["live", str(tmp_path / "none.json"), "--image-size", "640x480",
                 "--jsonl", str(tmp_path / "a.jsonl")]) == 2
    assert "none.json" in capsys.readouterr().err
    assert main(["live", kp, "--jsonl", str(tmp_path / "b.jsonl"), "--image-size", "640x480",
                 "--view", str(tmp_path / "x.txt")]) == 2
    err = capsys.readouterr().err
    assert "--view" in err or "rerun" in err.lower()
    assert main(["live", kp, "--jsonl", str(tmp_path)]) == 2
    assert "folder" in capsys.readouterr().err


def test_view_records_the_stream_to_an_rrd(scene_dir, tmp_path):
    pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")
    rrd = tmp_path / "live.rrd"
    assert main(["live", str(scene_dir / "keypoints_mmpose.json"), "--intrinsics",
                 str(scene_dir / "camera.json"), "--jsonl", str(tmp_path / "v.jsonl"),
                 "--as-fast-as-possible", "--view", str(rrd), "--quiet"]) == 0
    assert rrd.stat().st_size > 10000


def test_the_live_viewer_without_a_display_is_refused_before_the_stream(scene_dir, tmp_path,
                                                                      capsys, monkeypatch):
    pytest.importorskip("rerun", reason="the view extra (rerun-sdk) is not installed")
    monkeypatch.setattr("sys.platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "n.jsonl"
    assert main(["live", str(scene_dir / "keypoints_mmpose.json"), "--intrinsics",
                 str(scene_dir / "camera.json"), "--jsonl", str(out), "--view"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "display" in err[0] and not out.exists()


@pytest.mark.parametrize("inline", [False, True])
def test_a_short_file_has_joints_on_every_frame_after_the_first_window(tmp_path, inline):
    """100 frames replayed flat out, inline and with the worker: every frame from the
    first window's end on (frame 60: the first 60 frames with two people) has 3D joints
    and the mirror, in the worker's case too (the stream waits for the first mirror)."""
    scene = tmp_path / "s"
    assert main(["synth", "--out", str(scene), "--frames", "100", "--seed", "1",
                 "--formats", "mmpose", "--quiet"]) == 0
    out = tmp_path / "l.jsonl"
    assert main(["live", str(scene / "keypoints_mmpose.json"), "--intrinsics",
                 str(scene / "camera.json"), "--subject-height", "1.75", "--jsonl", str(out),
                 "--as-fast-as-possible", "--quiet"] + ["--inline"] * inline) == 0
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    # every frame once, in order, each written 9 frames late (solved again with them)
    assert [ln["frame"] for ln in lines] == list(range(100))
    assert {ln["lag_frames"] for ln in lines} == {9}
    with_joints = [ln["frame"] for ln in lines
                   if any(X is not None for X in ln["joints3d"])]
    assert with_joints == list(range(60, 100))
    assert all(ln["mirror"]["normal"] is not None for ln in lines[59:])


def test_inline_needs_a_file_replayed_flat_out(scene_dir, tmp_path, capsys):
    assert main(["live", str(scene_dir / "keypoints_mmpose.json"), "--intrinsics",
                 str(scene_dir / "camera.json"), "--jsonl", str(tmp_path / "i.jsonl"),
                 "--inline"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--inline" in err[0] and "--as-fast-as-possible" in err[0]


def test_a_stated_keypoint_placement_reaches_the_live_scale(scene_dir, tmp_path):
    """``--keypoint-offset 0``: the windows' stature carries no keypoint placement, so the
    live scale's std (``mirror.scale_rel_std``) is smaller than the default's, the same
    frames replayed inline."""
    stds = {}
    for flag in ([], ["--keypoint-offset", "0"]):
        out = tmp_path / f"l{len(flag)}.jsonl"
        assert main(["live", str(scene_dir / "keypoints_mmpose.json"), "--intrinsics",
                     str(scene_dir / "camera.json"), "--subject-height", "1.7", "--jsonl",
                     str(out), "--as-fast-as-possible", "--inline", "--quiet", *flag]) == 0
        last = json.loads(out.read_text().splitlines()[-1])
        stds[bool(flag)] = last["mirror"]["scale_rel_std"]
    from mirrorgraph.graph.options import GaugeOptions

    assert GaugeOptions().height_sigma <= stds[True] < stds[False] - 0.01
