"""The Rerun recording of ``view`` / ``--view``, read back with Rerun's own reader
(``rerun.chunk.RrdReader``): cameras, virtual cameras, mirrors, skeleton and reflection
over time, per-joint uncertainty, video frames with keypoints and epipolar lines; for
one mirror and for a rig."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mirrorgraph.cli import main

rr = pytest.importorskip("rerun", reason="rerun-sdk (the view extra) is missing")
cv2 = pytest.importorskip("cv2")

FRAMES = 60


def read_rrd(path):
    """``{entity: {component: {frame (None if static): value}}}`` of a recording."""
    from rerun.chunk import RrdReader

    out: dict = {}
    for chunk in RrdReader(path).stream().to_chunks():
        rb = chunk.to_record_batch()
        names = rb.schema.names
        frames = (rb.column("frame").to_pylist() if "frame" in names else [None] * rb.num_rows)
        for name in names:
            if name in ("rerun.controls.RowId", "frame", "time"):
                continue
            for f, v in zip(frames, rb.column(name).to_pylist()):
                out.setdefault(chunk.entity_path, {}).setdefault(name, {})[f] = v
    return out


def static(rec, entity, component):
    return rec[entity][component][None]


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    """A scene, its video (blank frames of the image size), calibrated with --view."""
    d = tmp_path_factory.mktemp("view")
    assert main(["synth", "--out", str(d / "scene"), "--frames", str(FRAMES), "--seed", "4",
                 "--quiet"]) == 0
    cam = json.loads((d / "scene" / "camera.json").read_text())
    W, H = cam["image_size"]
    writer = cv2.VideoWriter(str(d / "clip.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (W, H))
    for f in range(FRAMES):
        img = np.full((H, W, 3), 40, np.uint8)
        cv2.putText(img, str(f), (50, 200), cv2.FONT_HERSHEY_SIMPLEX, 5, (255, 255, 255), 8)
        writer.write(img)
    writer.release()
    assert main(["calibrate", str(d / "scene" / "keypoints_mmpose.json"), "--intrinsics",
                 str(d / "scene" / "camera.json"), "--subject-height", "1.75",
                 "--out", str(d / "cal.json"), "--joints3d", str(d / "j.npz"),
                 "--video", str(d / "clip.mp4"), "--view", str(d / "run.rrd"), "--quiet"]) == 0
    return d


def test_calibrate_view_holds_cameras_mirror_and_motion(single):
    from rerun.chunk import RrdReader

    reader = RrdReader(single / "run.rrd")
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1   # with its layout
    rec = read_rrd(single / "run.rrd")
    cal = json.loads((single / "cal.json").read_text())
    n, d = np.array(cal["mirror"]["normal"]), cal["mirror"]["distance"]
    K = np.array(cal["intrinsics"]["K"])
    W, H = cal["intrinsics"]["image_size"]
    # the real camera at the origin, its pinhole K and size
    assert np.allclose(static(rec, "/world/cameras/camera", "Transform3D:translation"), 0)
    K_rec = np.array(static(rec, "/world/cameras/camera/image", "Pinhole:image_from_camera"))
    assert np.allclose(K_rec.reshape(3, 3, order="F"), K, rtol=1e-6)
    assert np.allclose(static(rec, "/world/cameras/camera/image", "Pinhole:resolution"), [W, H])
    # the virtual camera: centre 2 d n (the origin reflected), the flipped image's K,
    # a rotation R^T with R = D (I - 2 n n^T) (calibration.json's virtual_camera.R)
    c = np.array(static(rec, "/world/virtual_cameras/mirror_camera", "Transform3D:translation"))
    assert np.allclose(c, 2 * d * n, atol=1e-5)
    R_wc = np.array(static(rec, "/world/virtual_cameras/mirror_camera",
                           "Transform3D:mat3x3")).reshape(3, 3, order="F")
    assert np.allclose(R_wc, np.array(cal["virtual_camera"]["R"]).T, atol=1e-6)
    Kv = np.array(static(rec, "/world/virtual_cameras/mirror_camera/image",
                         "Pinhole:image_from_camera")).reshape(3, 3, order="F")
    assert np.isclose(Kv[0, 2], W - K[0, 2]) and np.isclose(Kv[0, 0], K[0, 0])
    # the mirror quad lies on n.X = d and covers where the reflections were seen
    quad = np.array(static(rec, "/world/mirrors/mirror/surface", "Mesh3D:vertex_positions"))
    assert quad.shape == (4, 3) and np.allclose(quad @ n, d, atol=1e-4)
    side = np.linalg.norm(quad[1] - quad[0]), np.linalg.norm(quad[2] - quad[1])
    assert min(side) > 0.3 and max(side) < 10           # a person-sized part of a wall
    # the skeleton over time: the --joints3d file's joints, frame by frame
    j = np.load(single / "j.npz")
    X, ok, ids = j["joints3d"], j["valid"], j["frame_ids"]
    joints = rec["/world/person/joints"]["Points3D:positions"]
    reflected = rec["/world/reflections/mirror/joints"]["Points3D:positions"]
    assert sorted(joints) == sorted(int(f) for f in ids)
    for t in (0, len(ids) // 2, len(ids) - 1):
        got = np.array(joints[int(ids[t])])
        assert np.allclose(got, X[t][ok[t]], atol=1e-5)
        S = X[t][ok[t]] - 2 * ((X[t][ok[t]] @ n) - d)[:, None] * n
        assert np.allclose(np.array(reflected[int(ids[t])]), S, atol=1e-5)
        assert len(rec["/world/person/bones"]["LineStrips3D:strips"][int(ids[t])]) >= 12


def test_uncertainty_ellipsoids_are_the_two_view_covariance(single):
    """Half sizes = sqrt of the eigenvalues of (J_r^T J_r / s_r^2 + J_m^T J_m / s_m^2)^-1,
    with the Jacobians taken here by finite differences of the two projections."""
    rec = read_rrd(single / "run.rrd")
    cal = json.loads((single / "cal.json").read_text())
    n, d = np.array(cal["mirror"]["normal"]), cal["mirror"]["distance"]
    K = np.array(cal["intrinsics"]["K"])
    s_r, s_m = cal["refinement"]["rms_direct_px"], cal["refinement"]["rms_mirror_px"]
    j = np.load(single / "j.npz")
    t, f = 5, int(j["frame_ids"][5])
    X = j["joints3d"][t][j["valid"][t]]
    half = np.array(rec["/world/person/uncertainty"]["Ellipsoids3D:half_sizes"][f])
    centres = np.array(rec["/world/person/uncertainty"]["Ellipsoids3D:centers"][f])
    assert np.allclose(centres, X, atol=1e-5)

    def proj(P):
        p = P @ K.T
        return p[:2] / p[2]

    def reflected(P):
        return proj(P - 2 * (P @ n - d) * n)

    for k in range(len(X)):
        info = np.zeros((3, 3))
        for fn, s in ((proj, s_r), (reflected, s_m)):
            J = np.stack([(fn(X[k] + e) - fn(X[k] - e)) / 2e-6 for e in np.eye(3) * 1e-6], 1)
            info += J.T @ J / s**2
        want = np.sqrt(np.linalg.eigvalsh(np.linalg.inv(info)))
        assert np.allclose(np.sort(half[k]), want, rtol=1e-3)
    # depth along the rays is the poorly determined direction: centimetres, not microns
    assert 1e-3 < half.max() < 0.5


def test_video_frames_keypoints_and_epipolar_lines(single):
    rec = read_rrd(single / "run.rrd")
    cal = json.loads((single / "cal.json").read_text())
    e = np.array(cal["epipole_px"])
    base = "/world/cameras/camera/image"
    blobs = rec[base]["EncodedImage:blob"]
    assert len(blobs) >= FRAMES - 5                  # every frame with keypoints
    f0 = min(blobs)
    blob = blobs[f0][0] if isinstance(blobs[f0][0], (list, bytes)) else blobs[f0]
    img = cv2.imdecode(np.asarray(bytearray(blob), np.uint8), cv2.IMREAD_COLOR)
    W, H = cal["intrinsics"]["image_size"]
    assert img.shape == (H, W, 3)
    lines = rec[f"{base}/epipolar_lines"]["LineStrips2D:strips"]
    real = rec[f"{base}/keypoints"]["Points2D:positions"]
    mirror = rec[f"{base}/reflection"]["Points2D:positions"]

    def distance(p, q, x):                            # of points x from lines p-q
        d = q - p
        return np.abs(d[:, 0] * (x - p)[..., 1] - d[:, 1] * (x - p)[..., 0]) \
            / np.linalg.norm(d, axis=1)

    residuals, checked = [], 0
    for f in lines:
        seg = np.array(lines[f])                      # (N, 2, 2)
        u, v = np.array(real[f]), np.array(mirror[f])
        if not len(seg) == len(u) == len(v):          # a joint missing in one view
            continue
        checked += 1
        p, q = seg[:, 0], seg[:, 1]
        # each line is the joint's epipolar line: through the epipole and the joint ...
        assert distance(p, q, e).max() < 0.5
        assert distance(p, q, u).max() < 0.05
        residuals.append(distance(p, q, v))          # ... the reflection near it
        # ... and spans the image: its ends on the border
        on_border = (np.isclose(seg[..., 0], 0, atol=0.5) | np.isclose(seg[..., 0], W, atol=0.5)
                     | np.isclose(seg[..., 1], 0, atol=0.5) | np.isclose(seg[..., 1], H, atol=0.5))
        assert on_border.all()
    assert checked >= 10
    assert np.median(np.concatenate(residuals)) < 10
    epipole = np.array(static(rec, f"{base}/epipole", "Points2D:positions"))
    assert np.allclose(epipole[0], e, atol=1e-2)


def test_view_command_from_the_kept_run_and_from_joints3d(single, capsys):
    out = single / "again.rrd"
    assert main(["view", str(single / "cal.json"), "--save", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    rec = read_rrd(out)
    assert "/world/person/joints" in rec and "/world/cameras/camera/image/keypoints" in rec
    out2 = single / "from_npz.rrd"
    assert main(["view", str(single / "cal.json"), "--joints3d", str(single / "j.npz"),
                 "--video", str(single / "clip.mp4"), "--max-video-frames", "7",
                 "--save", str(out2), "--quiet"]) == 0
    rec2 = read_rrd(out2)
    assert len(rec2["/world/cameras/camera/image"]["EncodedImage:blob"]) == 7
    # the joints file's frames are the kept run's: its 2D keypoints are drawn too
    assert rec2["/world/cameras/camera/image/keypoints"]["Points2D:positions"]
    assert np.allclose(rec2["/world/person/joints"]["Points3D:positions"][10],
                       rec["/world/person/joints"]["Points3D:positions"][10])


def test_view_errors_are_one_line(single, tmp_path, capsys):
    cal = str(single / "cal.json")
    for argv, words in (
            (["view", cal, "--save", str(tmp_path / "x.mp4")], "must end in .rrd"),
            (["view", cal, "--joints3d", str(single / "j.csv"), "--save",
              str(tmp_path / "x.rrd")], "give the .npz"),
            (["view", str(single / "j.npz"), "--save", str(tmp_path / "x.rrd")], "error:"),
            (["view", cal, "--video", str(tmp_path / "none.mp4"), "--save",
              str(tmp_path / "x.rrd")], "no such video"),
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and words in err and "Traceback" not in err
    assert not (tmp_path / "x.rrd").exists()


def test_view_without_a_display_names_the_recording(single, tmp_path, monkeypatch, capsys):
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))      # where the recording goes
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    assert main(["view", str(single / "cal.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no display" in err
    kept = err.split("the recording is ")[1].split(";")[0]
    assert kept.startswith(str(tmp_path)) and read_rrd(kept)["/world/person/joints"]


def test_calibrate_rig_view_and_view_of_a_rig(tmp_path, capsys):
    rig = tmp_path / "rig"
    assert main(["synth-rig", "2cams1mirror", "--out", str(rig), "--frames", "60", "--quiet"]) == 0
    out = tmp_path / "rig.rrd"
    assert main(["calibrate-rig", str(rig / "rig.toml"), "--out", str(rig / "cal.toml"),
                 "--joints3d", str(rig / "j.npz"), "--view", str(out), "--quiet"]) == 0
    doc = json.loads((rig / "cal.json").read_text())
    for path in (out, tmp_path / "again.rrd"):
        if path != out:
            assert main(["view", str(rig / "cal.toml"), "--joints3d", str(rig / "j.npz"),
                         "--save", str(path), "--quiet"]) == 0
        rec = read_rrd(path)
        summary = static(rec, "/summary", "TextDocument:text")
        assert "camera cam02" in str(summary) and "mirror wall" in str(summary)
        for cam in doc["cameras"]:
            pose = np.array(cam["pose_camera_to_world"])
            got = static(rec, f"/world/cameras/{cam['name']}", "Transform3D:translation")
            assert np.allclose(got, pose[:3, 3], atol=1e-5)
        for m in doc["mirrors"]:
            n, d = np.array(m["normal"]), m["distance"]
            quad = np.array(static(rec, f"/world/mirrors/{m['name']}/surface",
                                   "Mesh3D:vertex_positions"))
            assert np.allclose(quad @ n, d, atol=1e-4)
            for c in m["seen_by"]:
                centre = np.array(static(rec, f"/world/cameras/{c}", "Transform3D:translation"))
                virtual = np.array(static(rec, f"/world/virtual_cameras/{c}_{m['name']}",
                                          "Transform3D:translation"))
                assert np.allclose(virtual, centre - 2 * (centre @ n - d) * n, atol=1e-4)
            assert f"/world/reflections/{m['name']}/joints" in rec
        j = np.load(rig / "j.npz")
        f = int(j["frame_ids"][3])
        assert np.allclose(rec["/world/person/joints"]["Points3D:positions"][f],
                           j["joints3d"][3][j["valid"][3]], atol=1e-5)
    assert main(["view", str(rig / "cal.toml"), "--video", str(rig / "x.mp4"),
                 "--save", str(tmp_path / "v.rrd")]) == 2
    assert "not of a rig" in capsys.readouterr().err


def test_c3d_and_bvh_from_calibrate(single, tmp_path):
    """--joints3d out.c3d / out.bvh through the command line; .c3d needs metres."""
    pytest.importorskip("c3d")
    scene = single / "scene"
    base = ["calibrate", str(scene / "keypoints_mmpose.json"), "--intrinsics",
            str(scene / "camera.json"), "--quiet"]
    for suffix in (".c3d", ".bvh"):
        out = tmp_path / f"m{suffix}"
        assert main(base + ["--subject-height", "1.75", "--out", str(tmp_path / "c.json"),
                            "--joints3d", str(out)]) == 0
        assert out.stat().st_size > 1000
        assert main(base + ["--out", str(tmp_path / "d.json"), "--joints3d",
                            str(tmp_path / f"n{suffix}")]) == 2
    assert not (tmp_path / "d.json").exists()


def test_view_takes_the_joints_calibrate_wrote_where_frames_lack_a_pair(tmp_path):
    """``calibrate --joints3d j.npz`` on keypoints where some frames hold one person, then
    ``view c.json --joints3d j.npz``: the joints file has a row for every frame read and
    is this calibration's (a fresh process each, as a user runs them)."""
    import subprocess
    import sys

    run = [sys.executable, "-m", "mirrorgraph"]
    subprocess.run([*run, "synth", "--out", "scene", "--frames", "60", "--seed", "4",
                    "--single", "0.2", "--formats", "mmpose", "--video-frames", "0",
                    "--quiet"], check=True, cwd=tmp_path)
    subprocess.run([*run, "calibrate", "scene/keypoints_mmpose.json", "--intrinsics",
                    "scene/camera.json", "--out", "c.json", "--joints3d", "j.npz", "--quiet"],
                   check=True, cwd=tmp_path)
    doc = json.loads((tmp_path / "c.json").read_text())
    assert doc["frames_paired"] < doc["frames_read"] == 60
    proc = subprocess.run([*run, "view", "c.json", "--joints3d", "j.npz", "--save", "v.rrd"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "v.rrd").is_file()
