"""The bad-input suite of outputs and contradictory inputs, as a user hits them.

Each case runs ``mirrorgraph`` as a user would and checks the contract of
docs/guide/errors.md: one line ``error: ...`` naming the cause, exit status 2, no
traceback, and every file the user had exactly as it was (nothing half-written, no
temporary left behind).
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.cli import main
from mirrorgraph.synth import make_rig, make_scene, write_rig, write_scene

PRECIOUS = b"precious: the user's own file\n"


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    """A 60-frame mirror scene (MMPose keypoints, camera.json) and its calibration with
    3D joints (c.json, c.report.npz, j.npz) made by the CLI."""
    root = tmp_path_factory.mktemp("scene")
    write_scene(make_scene(frames=60, seed=5), root, formats=("mmpose",))
    assert main(["calibrate", str(root / "keypoints_mmpose.json"), "--intrinsics",
                 str(root / "camera.json"), "--out", str(root / "c.json"), "--joints3d",
                 str(root / "j.npz"), "--quiet"]) == 0
    return root


@pytest.fixture(scope="module")
def rig(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("rig")
    write_rig(make_rig("2cams1mirror", frames=40, seed=1), root, "openpose")
    return root


def snapshot(folder: Path) -> dict:
    """Every entry under ``folder``: its kind and, for a file, its bytes."""
    out = {}
    for p in sorted(folder.rglob("*")):
        st = os.lstat(p)
        if stat.S_ISREG(st.st_mode):
            out[str(p)] = p.read_bytes()
        else:
            out[str(p)] = stat.S_IFMT(st.st_mode)
    return out


def refused(argv, capfd, folder: Path, *, names: tuple = ()) -> str:
    """``main(argv)`` exits 2 with one ``error:`` line naming ``names``, and ``folder``
    is as it was (nothing written, nothing left behind)."""
    before = snapshot(folder)
    code = main([str(a) for a in argv])
    cap = capfd.readouterr()
    assert code == 2, (code, cap.err)
    assert cap.err.startswith("error: ") and cap.err.count("\n") == 1, cap.err
    assert "Traceback" not in cap.err + cap.out
    for name in names:
        assert str(name) in cap.err, (name, cap.err)
    assert snapshot(folder) == before, "a failed run changed the user's files"
    return cap.err


def calibrate_args(scene: Path, out: Path, *extra) -> list:
    return ["calibrate", scene / "keypoints_mmpose.json", "--intrinsics", scene / "camera.json",
            "--out", out, "--quiet", *extra]


@pytest.fixture()
def work(tmp_path) -> Path:
    """A user's folder holding a calibration they want to keep."""
    (tmp_path / "keep.json").write_bytes(PRECIOUS)
    return tmp_path


# ----------------------------------------------------------------------------- calibrate
def test_missing_folder_of_joints3d_leaves_calibration_untouched(scene, work, capfd):
    refused(calibrate_args(scene, work / "keep.json", "--joints3d", work / "nodir/out.npz"),
            capfd, work, names=("nodir", "--joints3d"))
    assert not (work / "keep.report.npz").exists()


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".bvh", ".c3d", ".trc"])
def test_folder_as_joints3d_named_not_a_temporary(scene, work, capfd, suffix):
    (work / f"d{suffix}").mkdir()
    err = refused(calibrate_args(scene, work / "keep.json", "--subject-height", "1.7",
                                 "--joints3d", work / f"d{suffix}"), capfd, work,
                  names=(f"d{suffix}", "is a folder"))
    assert ".tmp" not in err


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes read-only files")
def test_read_only_joints3d_refused(scene, work, capfd):
    ro = work / "ro.npz"
    ro.write_bytes(PRECIOUS)
    ro.chmod(0o444)
    refused(calibrate_args(scene, work / "keep.json", "--joints3d", ro), capfd, work,
            names=("ro.npz", "read-only"))


def test_fifo_as_output_refused_and_kept_a_fifo(scene, work, capfd):
    os.mkfifo(work / "pipe.npz")
    refused(calibrate_args(scene, work / "keep.json", "--joints3d", work / "pipe.npz"), capfd,
            work, names=("pipe.npz", "FIFO"))
    assert stat.S_ISFIFO(os.lstat(work / "pipe.npz").st_mode)


def test_device_as_output_refused(scene, work, capfd):
    refused(calibrate_args(scene, "/dev/null"), capfd, work, names=("/dev/null", "device"))


def test_output_that_is_the_input_refused(scene, tmp_path, capfd):
    kp = tmp_path / "kp.json"
    shutil.copy(scene / "keypoints_mmpose.json", kp)
    refused(["calibrate", kp, "--intrinsics", scene / "camera.json", "--out", kp], capfd,
            tmp_path, names=("kp.json", "is the input"))


def test_report_given_a_file_refused(scene, work, capfd):
    refused(calibrate_args(scene, work / "keep.json", "--report", work / "keep.json"), capfd,
            work, names=("--report", "is a file"))


def test_view_into_missing_folder_refused_before_the_run(scene, work, capfd):
    refused(calibrate_args(scene, work / "keep.json", "--view", work / "nodir/x.rrd"), capfd,
            work, names=("nodir",))


def test_two_outputs_one_file_refused(scene, work, capfd):
    refused(calibrate_args(scene, work / "keep.json", "--joints3d", work / "keep.report.npz"),
            capfd, work, names=("keep.report.npz",))


def test_full_disk_mid_run_leaves_everything_as_it_was(scene, work, capfd, monkeypatch):
    """The disk fills while the 3D joints are written, after the calibration JSON was:
    one line, exit 2, the old calibration kept, no report data, no temporary left."""
    import mirrorgraph.io.motion as motion

    def full(*_a, **_k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(work / "j.npz"))

    monkeypatch.setattr(motion, "write_joints3d", full)
    err = refused(calibrate_args(scene, work / "keep.json", "--joints3d", work / "j.npz"),
                  capfd, work)
    assert "No space left" in err


def test_view_without_display_refused_before_the_run(scene, work, capfd, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if not sys.platform.startswith("linux"):
        pytest.skip("the display test is Linux's")
    err = refused(calibrate_args(scene, work / "keep.json", "--view"), capfd, work,
                  names=("--view OUT.rrd",))
    assert "--save" not in err


def test_successful_run_moves_every_output_into_place(scene, work, capfd):
    code = main([str(a) for a in calibrate_args(scene, work / "keep.json", "--joints3d",
                                                work / "j.csv", "--report", work / "rep")])
    assert code == 0
    assert json.loads((work / "keep.json").read_text())["mirror"]["normal"]
    assert (work / "keep.report.npz").is_file() and (work / "j.csv").is_file()
    assert sorted(p.name for p in (work / "rep").iterdir()) == sorted(
        ["bone_lengths.png", "image_plane.png", "residuals.png", "scene3d.png",
         "sensitivity.png", "uncertainty.png"])
    assert not [p for p in work.iterdir() if p.name.startswith(".")], "temporaries left"


def test_symlink_output_written_through(scene, work, capfd):
    real = work / "real.json"
    real.write_bytes(PRECIOUS)
    (work / "link.json").symlink_to(real)
    assert main([str(a) for a in calibrate_args(scene, work / "link.json")]) == 0
    assert (work / "link.json").is_symlink()
    assert json.loads(real.read_text())["mirror"]["normal"]


# ----------------------------------------------------------------------------- report, export
def test_report_video_that_is_a_folder_or_an_image(scene, work, capfd):
    (work / "x.mp4").mkdir()
    refused(["report", scene / "c.json", "--out", work / "rep", "--video", work / "x.mp4"],
            capfd, work, names=("x.mp4", "is a folder"))
    import cv2
    cv2.imwrite(str(work / "img.png"), np.zeros((32, 32, 3), np.uint8))
    shutil.copy(work / "img.png", work / "img.mp4")
    refused(["report", scene / "c.json", "--out", work / "rep", "--video", work / "img.mp4"],
            capfd, work, names=("img.mp4", "single image"))
    (work / "junk.mp4").write_bytes(b"\x00" * 200)
    err = refused(["report", scene / "c.json", "--out", work / "rep", "--video",
                   work / "junk.mp4"], capfd, work, names=("junk.mp4",))
    assert "ffmpeg" not in err.lower().replace("opencv's ffmpeg reader", "")


@pytest.mark.parametrize("schema", [99, "2", None, "missing"])
def test_schema_this_version_cannot_read(scene, work, capfd, schema):
    doc = json.loads((scene / "c.json").read_text())
    if schema == "missing":
        doc.pop("schema_version")
        doc.pop("mirrorgraph_version")
    else:
        doc["schema_version"] = schema
    (work / "odd.json").write_text(json.dumps(doc))
    refused(["export", work / "odd.json", "--to", "pose2sim", work / "out.toml"], capfd, work,
            names=("odd.json",))
    refused(["report", work / "odd.json", "--out", work / "rep"], capfd, work,
            names=("odd.json",))


def test_export_over_its_own_input_refused(scene, work, capfd):
    shutil.copy(scene / "c.json", work / "c.json")
    refused(["export", work / "c.json", "--to", "pose2sim", work / "c.json"], capfd, work,
            names=("is the input",))


# ----------------------------------------------------------------------------- view
def _npz(src: Path, dst: Path, **change) -> Path:
    with np.load(src) as z:
        d = {k: z[k] for k in z.files}
    for k, v in change.items():
        d[k] = v(d[k]) if callable(v) else v
    np.savez(dst, **d)
    return dst


def _set(X, t, j, c, v):
    X = X.copy()
    X[t, j, c] = v
    return X


@pytest.mark.parametrize("what,change,says", [
    ("huge", {"joints3d": lambda X: _set(X, 3, 4, 0, 1e300)}, "beyond"),
    ("depth0", {"joints3d": lambda X: _set(X, 3, 4, 2, 0.0)}, "against the camera"),
    ("frames", {"joints3d": lambda X: X[:-5], "valid": lambda v: v[:-5],
                "frame_ids": lambda f: f[:-5]}, "frames"),
    ("unit", {"unit": np.array("m")}, "metric scale"),
])
def test_view_refuses_joints_not_of_the_calibration(scene, work, capfd, what, change, says):
    bad = _npz(scene / "j.npz", work / f"{what}.npz", **change)
    refused(["view", scene / "c.json", "--joints3d", bad, "--save", work / "v.rrd"], capfd,
            work, names=(bad.name, says))


def test_view_refuses_truncated_npz_and_rig_joints(scene, rig, work, capfd):
    (work / "t.npz").write_bytes((scene / "j.npz").read_bytes()[:2000])
    refused(["view", scene / "c.json", "--joints3d", work / "t.npz", "--save", work / "v.rrd"],
            capfd, work, names=("t.npz",))
    with np.load(scene / "j.npz") as z:
        d = {k: z[k] for k in z.files}
    body25 = make_rig("2cams1mirror", frames=60, seed=1).skeleton.joints
    d["joints3d"] = np.ones((60, len(body25), 3))
    d["valid"] = np.ones((60, len(body25)), bool)
    d["joint_names"] = np.array(body25)
    np.savez(work / "other.npz", **d)
    refused(["view", scene / "c.json", "--joints3d", work / "other.npz", "--save",
             work / "v.rrd"], capfd, work, names=("other.npz", "another skeleton"))


def test_view_refuses_a_stale_kept_run(scene, work, capfd):
    doc = json.loads((scene / "c.json").read_text())
    doc["mirror"]["normal"] = (-np.asarray(doc["mirror"]["normal"])[[1, 0, 2]]).tolist()
    (work / "c.json").write_text(json.dumps(doc))
    shutil.copy(scene / "c.report.npz", work / "c.report.npz")
    refused(["view", work / "c.json", "--save", work / "v.rrd"], capfd, work,
            names=("c.report.npz", "--joints3d"))


# ----------------------------------------------------------------------------- rigs, batch
def test_rig_cameras_reading_one_folder_refused(rig, capfd):
    text = (rig / "rig.toml").read_text()
    (rig / "dup.toml").write_text(text.replace("pose/cam02_json", "pose/cam01_json"))
    refused(["calibrate-rig", rig / "dup.toml", "--out", rig / "d.toml"], capfd, rig,
            names=("cam01", "cam02", "same keypoints"))


def test_rig_camera_with_identical_copy_refused(rig, capfd):
    if not (rig / "pose/copy").exists():
        shutil.copytree(rig / "pose/cam01_json", rig / "pose/copy")
    text = (rig / "rig.toml").read_text()
    (rig / "dup2.toml").write_text(text.replace("pose/cam02_json", "pose/copy"))
    refused(["calibrate-rig", rig / "dup2.toml", "--out", rig / "d.toml"], capfd, rig,
            names=("cam01", "cam02", "identical keypoints"))


def test_rig_outputs_untouched_when_joints3d_cannot_be_written(rig, capfd):
    (rig / "out.toml").write_bytes(PRECIOUS)
    (rig / "out.json").write_bytes(PRECIOUS)
    refused(["calibrate-rig", rig / "rig.toml", "--out", rig / "out.toml", "--joints3d",
             rig / "nodir/r.bvh"], capfd, rig, names=("nodir",))


def test_rig_subject_height_range_is_the_command_lines(rig, capfd):
    text = (rig / "rig.toml").read_text()
    import re
    (rig / "tall.toml").write_text(re.sub(r"subject_height = [0-9.]+", "subject_height = 2.95",
                                          text))
    refused(["calibrate-rig", rig / "tall.toml", "--out", rig / "t.toml"], capfd, rig,
            names=("subject_height", "0.5 to 2.8"))


def test_batch_checks_its_summary_and_workers_first(scene, work, capfd):
    refused(["batch", scene, "--summary", work / "nodir/s.json"], capfd, work,
            names=("nodir", "--summary"))
    refused(["batch", scene, "--workers", "0"], capfd, work, names=("--workers",))


# ----------------------------------------------------------------------------- live
def live_args(scene: Path, jsonl, *extra) -> list:
    return ["live", scene / "keypoints_mmpose.json", "--intrinsics", scene / "camera.json",
            "--jsonl", jsonl, "--as-fast-as-possible", "--quiet", *extra]


def test_live_refuses_to_write_over_its_input(scene, capfd):
    refused(live_args(scene, scene / "keypoints_mmpose.json"), capfd, scene,
            names=("is the input",))


def test_live_jsonl_dash_is_standard_output(scene, work, capfd, monkeypatch):
    monkeypatch.chdir(work)
    assert main([str(a) for a in live_args(scene, "-")]) == 0
    out = capfd.readouterr().out.splitlines()
    assert len(out) == 60 and all(json.loads(line)["frame"] == i for i, line in enumerate(out))
    assert not (work / "-").exists()


def _one_person_each_frame(scene: Path, dst: Path, keep: int) -> Path:
    doc = json.loads((scene / "keypoints_mmpose.json").read_text())
    for e in doc:
        e["instances"] = e["instances"][:keep]
    dst.write_text(json.dumps(doc))
    return dst


@pytest.mark.parametrize("keep,says", [(1, "1 person"), (0, "0 with nobody")])
def test_live_refuses_what_calibrate_refuses(scene, work, capfd, keep, says):
    kp = _one_person_each_frame(scene, work / f"kp{keep}.json", keep)
    code = main([str(a) for a in ["live", kp, "--intrinsics", scene / "camera.json",
                                  "--jsonl", work / "l.jsonl", "--as-fast-as-possible",
                                  "--quiet"]])
    err = capfd.readouterr().err
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert "no mirror found" in err and ("one person" if keep else "nobody") in err


def test_live_tiny_image_size_refused_at_the_end(scene, work, capfd):
    code = main([str(a) for a in ["live", scene / "keypoints_mmpose.json", "--image-size",
                                  "10x10", "--jsonl", work / "l.jsonl",
                                  "--as-fast-as-possible", "--quiet"]])
    err = capfd.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "10x10" in err, err


def test_live_ctrl_c_one_line_and_complete_lines(scene, tmp_path):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) during a
    real-time live run with its background worker: exit 130, one line on stderr naming
    the file, no traceback (the worker's neither), every line of the file complete. At 1
    frame/s the 60 frames last a minute and the signal follows the second line: a first
    frame slowed by a loaded machine (the frames due meanwhile then come at once) leaves
    most of the run still paced when it lands."""
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    out = tmp_path / "l.jsonl"
    # a terminal's child: SIGINT raises KeyboardInterrupt whatever the runner ignores
    # (set in the child itself: a preexec_fn would fork a runner that JAX made threaded)
    start = ("import runpy, signal, sys; signal.signal(signal.SIGINT, "
             "signal.default_int_handler); sys.argv[0] = 'mirrorgraph'; "
             "runpy.run_module('mirrorgraph', run_name='__main__')")
    proc = subprocess.Popen([sys.executable, "-c", start, "live",
                             str(scene / "keypoints_mmpose.json"), "--intrinsics",
                             str(scene / "camera.json"), "--jsonl", str(out), "--fps", "1",
                             "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, env=env)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None and (
            not out.exists() or out.read_text().count("\n") < 2):
        time.sleep(0.05)
    sent = out.read_text().count("\n") if out.exists() else 0
    assert proc.poll() is None, ("the run ended before the signal", proc.returncode, sent)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, (proc.returncode, sent, err)
    assert "Traceback" not in err and err.count("\n") == 1, err
    lines = out.read_text().splitlines()
    assert str(out) in err and f"after {len(lines)} frames" in err, err
    assert [json.loads(line)["frame"] for line in lines] == list(range(len(lines)))


# ----------------------------------------------------------------------------- rig files
def _rig_variant(rig: Path, name: str, edit) -> Path:
    path = rig / name
    path.write_text(edit((rig / "rig.toml").read_text()))
    return path


def test_rig_of_one_view_says_why(rig, capfd):
    def one_camera(text: str) -> str:
        second = text.index("[[cameras]]", text.index("[[cameras]]") + 1)
        return text[:second].replace('mirrors = [ "wall" ]', "mirrors = []")
    refused(["calibrate-rig", _rig_variant(rig, "one.toml", one_camera), "--out",
             rig / "o.toml"], capfd, rig, names=("one camera and no mirror",))


def test_rig_frame_offset_beyond_every_frame_says_so(rig, capfd):
    def offset(text: str) -> str:
        last = text.rindex("frame_offset = 0")
        return text[:last] + "frame_offset = 1000000000" + text[last + len("frame_offset = 0"):]
    refused(["calibrate-rig", _rig_variant(rig, "off.toml", offset), "--out", rig / "o.toml"],
            capfd, rig, names=("frame_offset", "share none"))


def test_rig_intrinsics_leaving_keypoints_outside_warned(rig, capfd):
    """An intrinsics image size that leaves about a third of a camera's keypoints outside
    (less than the half that is refused): the run goes on and a warning names the camera."""
    from mirrorgraph.io import read_keypoints

    data = read_keypoints(rig / "pose" / "cam02_json")
    x = np.concatenate([p[..., 0].ravel() for p in data.people])
    width = int(np.nanpercentile(x, 65) / 1.1)
    calib = (rig / "Calib.toml").read_text()
    at = calib.rindex("size = [")
    end = calib.index("]", at)
    (rig / "Calib_small.toml").write_text(calib[:at] + f"size = [ {width}.0, 1080.0 ]"
                                          + calib[end + 1:])
    path = _rig_variant(rig, "small.toml", lambda t: t.replace('"Calib.toml"',
                                                               '"Calib_small.toml"'))
    code = main(["calibrate-rig", str(path), "--out", str(rig / "s.toml")])
    err = capfd.readouterr().err
    assert code == 0, err
    assert "camera cam02" in err and "lie outside its" in err, err


def test_cache_dir_that_is_a_file_refused(scene, work, capfd):
    (work / "cachefile").write_bytes(PRECIOUS)
    (work / "clip.mp4").write_bytes(b"\x00" * 64)
    refused(["calibrate", work / "clip.mp4", "--out", work / "c.json", "--cache-dir",
             work / "cachefile"], capfd, work, names=("--cache-dir", "is a file"))


def test_image_named_as_a_video_refused_as_input(work, capfd):
    import cv2
    cv2.imwrite(str(work / "img.png"), np.zeros((32, 32, 3), np.uint8))
    shutil.copy(work / "img.png", work / "img.mp4")
    refused(["calibrate", work / "img.mp4", "--out", work / "c.json"], capfd, work,
            names=("img.mp4", "single image"))
    refused(["detect", work / "img.mp4", "--out", work / "k.json"], capfd, work,
            names=("img.mp4", "single image"))


def test_viewer_failing_after_the_run_keeps_summary_and_files(scene, work, capfd, monkeypatch):
    """A display is set but Rerun's viewer exits at once: the calibration is written, the
    summary and the 'wrote' line are printed, and one warning names the recording (exit
    0: the calibration did not fail)."""
    import mirrorgraph.viewer.recording as recording

    def fails(path, wait=5.0):
        raise recording.InputError(f"Rerun's viewer did not open (exit status 1): the "
                                   f"recording is {path}; open it where there is a display "
                                   f"with 'rerun {path}', or write it to a file instead",
                                   fix=("save",))

    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(recording, "open_viewer", fails)
    argv = calibrate_args(scene, work / "keep.json", "--view")
    argv.remove("--quiet")
    code = main([str(a) for a in argv])
    cap = capfd.readouterr()
    assert code == 0, cap.err
    assert json.loads((work / "keep.json").read_text())["mirror"]["normal"]
    assert "mirror normal" in cap.out.lower() or "normal" in cap.out
    assert f"wrote {work / 'keep.json'}" in cap.out
    warnings_ = [ln for ln in cap.err.splitlines() if ln.startswith("warning: Rerun")]
    assert len(warnings_) == 1 and ".rrd" in warnings_[0] and "--view OUT.rrd" in warnings_[0]
    assert "--save" not in cap.err and "error:" not in cap.err
