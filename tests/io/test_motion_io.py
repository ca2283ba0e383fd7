"""3D motion out: .npz, .csv and OpenSim .trc, written and read back."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.export import WORLD_FRAMES
from mirrorgraph.io.motion import (CAMERA_FRAME, TRC_FROM_CAMERA, trc_marker_name,
                                   write_joints3d)
from mirrorgraph.skeletons import BODY_25, COCO_17

FPS = 30.0


def motion(skeleton=BODY_25, T=6, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.normal([0.0, 0.2, 3.0], 0.5, (T, skeleton.num_joints, 3))
    valid = rng.random((T, skeleton.num_joints)) > 0.2
    valid[2] = False                        # a frame with nothing
    X[0, 3] = np.nan                        # non-finite is invalid whatever `valid` says
    frame_ids = np.arange(T) * 2 + 10       # gaps and an offset
    return X, valid, frame_ids, list(skeleton.joints)


def parse_trc(path):
    """A TRC reader written from the format: header, marker names, X/Y/Z rows."""
    lines = path.read_text().split("\n")
    assert lines[-1] == ""
    lines = lines[:-1]
    first = lines[0].split("\t")
    assert first[:3] == ["PathFileType", "4", "(X/Y/Z)"] and first[3] == path.name
    keys, values = lines[1].split("\t"), lines[2].split("\t")
    header = dict(zip(keys, values))
    names = lines[3].split("\t")
    assert names[:2] == ["Frame#", "Time"]
    markers = [m for m in names[2:] if m]
    # each name spans 3 columns; Pose2Sim ends the line with one more tab
    assert names[2:] == [x for m in markers for x in (m, "", "")] + [""]
    xyz = lines[4].split("\t")
    assert xyz[:2] == ["", ""] and xyz[-1] == ""
    assert xyz[2:-1] == [f"{a}{i}" for i in range(1, len(markers) + 1) for a in "XYZ"]
    frames, times, data = [], [], []
    for line in lines[5:]:
        f = line.split("\t")
        assert len(f) == 2 + 3 * len(markers)
        frames.append(int(f[0]))
        times.append(float(f[1]))
        data.append([float(v) if v != "" else np.nan for v in f[2:]])
    data = np.array(data).reshape(len(frames), len(markers), 3)
    return header, markers, np.array(frames), np.array(times), data


def test_npz_round_trip(tmp_path):
    X, valid, ids, names = motion()
    path = tmp_path / "joints3d.npz"
    write_joints3d(path, X, valid, ids, names, FPS, "m")
    with np.load(path) as z:
        ok = valid & np.isfinite(X).all(-1)
        np.testing.assert_array_equal(z["valid"], ok)
        np.testing.assert_array_equal(z["joints3d"][ok], X[ok])
        assert np.isnan(z["joints3d"][~ok]).all()
        np.testing.assert_array_equal(z["frame_ids"], ids)
        assert z["frame_ids"].dtype == np.int64
        assert z["joint_names"].tolist() == names
        assert float(z["fps"]) == FPS and str(z["unit"]) == "m"
        assert str(z["frame"]) == CAMERA_FRAME
    write_joints3d(path, X, None, None, names, None, "mirror distance")
    with np.load(path) as z:
        assert np.isnan(z["fps"]) and str(z["unit"]) == "mirror distance"
        np.testing.assert_array_equal(z["frame_ids"], np.arange(len(X)))
        np.testing.assert_array_equal(z["valid"], np.isfinite(X).all(-1))


def test_csv_round_trip(tmp_path):
    X, valid, ids, names = motion(COCO_17)
    path = tmp_path / "joints3d.csv"
    write_joints3d(path, X, valid, ids, names, FPS, "m")
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0][:5] == ["frame", "time", "nose_x", "nose_y", "nose_z"]
    assert rows[0][-1] == "right_ankle_z" and len(rows[0]) == 2 + 3 * len(names)
    assert len(rows) == 1 + len(X)
    ok = valid & np.isfinite(X).all(-1)
    for t, row in enumerate(rows[1:]):
        assert int(row[0]) == ids[t] and float(row[1]) == ids[t] / FPS
        vals = row[2:]
        for j in range(len(names)):
            cell = vals[3 * j:3 * j + 3]
            if ok[t, j]:
                assert [float(v) for v in cell] == X[t, j].tolist()     # exact
            else:
                assert cell == ["", "", ""]
    write_joints3d(path, X, valid, ids, names, None, "m")              # no frame rate: no time
    with open(path, newline="") as f:
        assert all(r[1] == "" for r in list(csv.reader(f))[1:])


def test_trc_round_trip_pose2sim_layout(tmp_path):
    X, valid, ids, names = motion(BODY_25)
    path = tmp_path / "trial.trc"
    write_joints3d(path, X, valid, ids, names, FPS, "m")
    header, markers, frames, times, data = parse_trc(path)
    assert list(header) == ["DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units",
                            "OrigDataRate", "OrigDataStartFrame", "OrigNumFrames"]
    assert float(header["DataRate"]) == FPS and float(header["CameraRate"]) == FPS
    assert int(header["NumFrames"]) == len(X) and int(header["NumMarkers"]) == 25
    assert header["Units"] == "m" and int(header["OrigDataStartFrame"]) == ids[0]
    assert markers[:9] == ["Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder",
                           "LElbow", "LWrist", "CHip"]
    assert markers[19:] == ["LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel"]
    np.testing.assert_array_equal(frames, ids)
    np.testing.assert_allclose(times, ids / FPS, atol=1e-6)
    ok = valid & np.isfinite(X).all(-1)
    assert np.isnan(data[~ok]).all() and np.isfinite(data[ok]).all()
    # Y up: (X, Y, Z) = (z, -y, x) of the camera frame
    expect = np.stack([X[..., 2], -X[..., 1], X[..., 0]], -1)
    np.testing.assert_allclose(data[ok], expect[ok], rtol=0, atol=5e-7)
    # lengths are kept (a rotation), and so is handedness
    assert np.isclose(np.linalg.det(TRC_FROM_CAMERA), 1.0)
    np.testing.assert_allclose(TRC_FROM_CAMERA @ TRC_FROM_CAMERA.T, np.eye(3))


def test_trc_axes_match_pose2sim_from_z_up_export():
    """Pose2Sim triangulates in the calibration's world and turns Z-up into Y-up
    (X->Y, Y->Z, Z->X column reorder) before writing .trc: with the z_up export this
    gives exactly the axes write_joints3d uses."""
    zup2yup = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    np.testing.assert_array_equal(zup2yup @ WORLD_FRAMES["z_up"], TRC_FROM_CAMERA)


def test_trc_units_and_errors(tmp_path):
    X, valid, ids, names = motion(COCO_17, T=3)
    path = tmp_path / "mm.trc"
    write_joints3d(path, X * 1000.0, valid, ids, names, FPS, "mm")
    _, markers, _, _, data = parse_trc(path)
    assert markers[:3] == ["Nose", "LEye", "REye"] and markers[-1] == "RAnkle"
    ok = valid & np.isfinite(X).all(-1)
    np.testing.assert_allclose(data[ok], (X @ TRC_FROM_CAMERA.T)[ok], atol=5e-7)
    with pytest.raises(InputError, match="not metres"):
        write_joints3d(tmp_path / "x.trc", X, valid, ids, names, FPS, "mirror distance")
    with pytest.raises(InputError, match="frame rate"):
        write_joints3d(tmp_path / "x.trc", X, valid, ids, names, None, "m")
    with pytest.raises(InputError, match="frame rate must be a positive"):
        write_joints3d(tmp_path / "x.csv", X, valid, ids, names, 0.0, "m")
    with pytest.raises(InputError, match="unknown 3D motion format '.fbx'"):
        write_joints3d(tmp_path / "x.fbx", X, valid, ids, names, FPS, "m")
    assert not any(p.name.startswith("x") for p in tmp_path.iterdir())   # nothing left behind
    with pytest.raises(ValueError):
        write_joints3d(tmp_path / "x.npz", X, valid[:, :3], ids, names, FPS, "m")
    with pytest.raises(ValueError):
        write_joints3d(tmp_path / "x.npz", X, valid, ids, names[:3], FPS, "m")
    custom = tmp_path / "custom.trc"
    write_joints3d(custom, X, valid, ids, names, FPS, "m",
                   marker_names=[f"M{i}" for i in range(len(names))])
    assert parse_trc(custom)[1] == [f"M{i}" for i in range(len(names))]


def test_marker_names():
    assert [trc_marker_name(n) for n in ("left_knee", "right_hip", "nose", "neck", "mid_hip",
                                         "left_big_toe", "right_small_toe", "left_ear")] == \
        ["LKnee", "RHip", "Nose", "Neck", "CHip", "LBigToe", "RSmallToe", "LEar"]
    # every canonical name of every skeleton maps to a distinct marker
    for skel in (COCO_17, BODY_25):
        m = [trc_marker_name(n) for n in skel.joints]
        assert len(set(m)) == len(m)


@pytest.mark.parametrize("layout", ["BODY_25", "BODY_25B", "HALPE_26", "COCO_17"])
def test_marker_names_are_pose2sims(layout):
    """Every marker of a layout has the name Pose2Sim's skeleton of that layout gives the
    same keypoint (its ids are the detector's indices)."""
    why = "Pose2Sim is not installed (the README's test command installs it)"
    pytest.importorskip("anytree", reason=why)
    p2s = pytest.importorskip("Pose2Sim.skeletons", reason=why)
    from anytree import PreOrderIter

    from mirrorgraph.io.motion import trc_marker_names
    from mirrorgraph.skeletons import skeleton_by_name

    sk = skeleton_by_name(layout)
    theirs = {n.id: n.name for n in PreOrderIter(getattr(p2s, layout)) if n.id is not None}
    ours = trc_marker_names(sk.joints)
    for i, name in theirs.items():
        assert ours[i] == name, (layout, i, sk.joints[i])


def test_writes_are_atomic(tmp_path):
    X, valid, ids, names = motion(T=3)
    path = tmp_path / "out.trc"
    path.write_text("old")
    with pytest.raises(ValueError):
        write_joints3d(path, X, valid, ids, names, FPS, "m", marker_names=["only one"])
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.trc"]
