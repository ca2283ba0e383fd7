"""3D motion out as C3D and BVH, read back by readers independent of the writers.

C3D: written with the ``c3d`` package, read with ``ezc3d`` (a C++ library): every
marker within 1e-4 m of the joints, Pose2Sim's names, millimetres, the ``.trc``
axes. BVH: read with :mod:`mirrorgraph.io.bvh` (written for CMU motion capture,
before the writer) and also by an FK written here from the format: the root
within 1 mm and every bone's direction within 1 deg of the joints', one length
per bone.
"""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.io.bvh import read_bvh
from mirrorgraph.io.motion import (TRC_FROM_CAMERA, check_motion_path, regular_frames,
                                   trc_marker_names, write_joints3d)
from mirrorgraph.synth import make_scene

FPS = 30.0


def scene_motion(skeleton="COCO_17", frames=40, seed=3, jitter=0.01):
    """A person's joints with the detector-like wobble of bone lengths (``jitter`` m),
    some joints missing and frames in steps of 2 with a gap."""
    sc = make_scene(frames=frames, seed=seed, skeleton=skeleton)
    rng = np.random.default_rng(seed)
    X = sc.joints3d + rng.normal(0, jitter, sc.joints3d.shape)
    valid = rng.random(X.shape[:2]) > 0.1
    keep = np.ones(frames, bool)
    keep[10:13] = False                                 # frames without a pair
    ids = (np.arange(frames) * 2 + 6)[keep]
    return X[keep], valid[keep], ids, list(sc.skeleton.joints)


# --------------------------------------------------------------------------- C3D
@pytest.mark.parametrize("skeleton", ["COCO_17", "BODY_25", "HALPE_26"])
def test_c3d_markers_read_back_by_ezc3d(tmp_path, skeleton):
    ezc3d = pytest.importorskip("ezc3d", reason="ezc3d (the independent reader) is missing")
    pytest.importorskip("c3d", reason="the c3d package (the writer) is missing")
    X, valid, ids, names = scene_motion(skeleton)
    path = tmp_path / "motion.c3d"
    write_joints3d(path, X, valid, ids, names, FPS, "m")
    c = ezc3d.c3d(str(path))
    point = c["parameters"]["POINT"]
    assert point["LABELS"]["value"] == trc_marker_names(names)
    assert point["UNITS"]["value"] == ["mm"]
    assert point["RATE"]["value"][0] == pytest.approx(FPS / 2)       # every 2nd frame
    assert point["X_SCREEN"]["value"] == ["+Z"] and point["Y_SCREEN"]["value"] == ["+Y"]
    data = c["data"]["points"]                                     # (4, J, T')
    rows, step = regular_frames(ids)
    assert step == 2 and data.shape[2] == len(rows) == len(ids) + 3
    got = data[:3].transpose(2, 1, 0) / 1000.0                     # (T', J, 3) metres
    at = (ids - rows[0]) // step
    want = X @ TRC_FROM_CAMERA.T
    assert np.abs(got[at][valid] - want[valid]).max() < 1e-4
    assert np.isnan(got[at][~valid]).all()                        # missing markers
    gap = np.setdiff1d(np.arange(len(rows)), at)
    assert np.isnan(got[gap]).all()                                # frames without a pair
    # C3D counts from 1 at the point rate; ezc3d reports it from 0
    assert c["header"]["points"]["first_frame"] == ids[0] // step
    assert c["header"]["points"]["last_frame"] == ids[-1] // step


def test_c3d_refuses_what_it_cannot_write(tmp_path):
    pytest.importorskip("c3d", reason="the c3d package (the writer) is missing")
    X, valid, ids, names = scene_motion(frames=5)
    with pytest.raises(InputError, match="not metres"):
        write_joints3d(tmp_path / "x.c3d", X, valid, ids, names, FPS, "mirror distance")
    with pytest.raises(InputError, match="frame rate"):
        write_joints3d(tmp_path / "x.c3d", X, valid, ids, names, None, "m")
    assert not list(tmp_path.iterdir())
    with pytest.raises(InputError, match="C3D needs metres"):
        check_motion_path("out.c3d", metric=False)
    with pytest.raises(InputError, match="must end in"):
        check_motion_path("out.fbx", metric=True)
    check_motion_path("out.bvh", metric=None)


# --------------------------------------------------------------------------- BVH
def parse_bvh_fk(text):
    """An FK written from the BVH format alone (not mirrorgraph.io.bvh): joint names,
    parents, offsets, channels; world positions of every joint for every frame."""
    tokens = text.split()
    names, parents, offsets, channels = [], [], [], []
    assert tokens[0] == "HIERARCHY"
    stack, i = [], 1
    while tokens[i] != "MOTION":
        t = tokens[i]
        if t in ("ROOT", "JOINT"):
            names.append(tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            i += 2
        elif t == "End":                         # End Site: a node without channels
            names.append(names[stack[-1]] + "/end")
            parents.append(stack[-1])
            channels.append([])
            i += 2
        elif t == "{":
            stack.append(len(names) - 1)
            i += 1
        elif t == "}":
            stack.pop()
            i += 1
        elif t == "OFFSET":
            offsets.append([float(v) for v in tokens[i + 1:i + 4]])
            i += 4
        elif t == "CHANNELS":
            n = int(tokens[i + 1])
            channels.append(tokens[i + 2:i + 2 + n])
            i += 2 + n
        else:
            raise AssertionError(t)
    frames = int(tokens[i + 2])
    frame_time = float(tokens[i + 5])
    values = np.array(tokens[i + 6:], float).reshape(frames, -1)

    def rot(axis, deg):
        a = np.radians(deg)
        c, s = np.cos(a), np.sin(a)
        R = np.zeros(a.shape + (3, 3))
        k = "XYZ".index(axis)
        i1, i2 = (k + 1) % 3, (k + 2) % 3          # right-handed: cyclic order
        R[..., k, k] = 1
        R[..., i1, i1] = c
        R[..., i2, i2] = c
        R[..., i1, i2] = -s
        R[..., i2, i1] = s
        return R

    world_R, world_p, col = {}, {}, 0
    for j, name in enumerate(names):
        R = np.broadcast_to(np.eye(3), (frames, 3, 3))
        p = np.broadcast_to(np.array(offsets[j]), (frames, 3)).copy()
        for ch in channels[j]:
            v = values[:, col]
            col += 1
            if ch.endswith("position"):
                p[:, "XYZ".index(ch[0])] += v
            else:
                R = R @ rot(ch[0], v)
        if parents[j] < 0:
            world_R[j], world_p[j] = R, p
        else:
            Rp = world_R[parents[j]]
            world_p[j] = world_p[parents[j]] + np.einsum("tij,tj->ti", Rp, p)
            world_R[j] = Rp @ R
    assert col == values.shape[1]
    pos = np.stack([world_p[j] for j in range(len(names))], axis=1)
    return names, parents, np.array(offsets), pos, frame_time


def data_points(X, names):
    """The joints in the .trc axes by marker name, with the root and neck of the
    hierarchy (the layout's own, or midpoints)."""
    Y = X @ TRC_FROM_CAMERA.T
    markers = trc_marker_names(names)
    pts = {m: Y[:, i] for i, m in enumerate(markers)}
    idx = {n: i for i, n in enumerate(names)}
    if "mid_hip" not in idx:
        pts["Hips"] = 0.5 * (Y[:, idx["left_hip"]] + Y[:, idx["right_hip"]])
    if "neck" not in idx:
        pts["Neck"] = 0.5 * (Y[:, idx["left_shoulder"]] + Y[:, idx["right_shoulder"]])
    return pts


@pytest.mark.parametrize("skeleton", ["COCO_17", "BODY_25", "HALPE_26"])
def test_bvh_forward_kinematics_follows_the_joints(tmp_path, skeleton):
    X, valid, ids, names = scene_motion(skeleton)
    valid[:] = True                     # every joint (gaps in time stay: interpolated)
    path = tmp_path / "motion.bvh"
    write_joints3d(path, X, valid, ids, names, FPS, "m")
    text = path.read_text()
    bnames, parents, offsets, pos, frame_time = parse_bvh_fk(text)
    rows, step = regular_frames(ids)
    assert frame_time == pytest.approx(step / FPS)
    assert pos.shape[0] == len(rows)
    at = (ids - rows[0]) // step
    pts = data_points(X, names)
    theirs = read_bvh(path)                        # mirrorgraph's reader agrees with this FK
    np.testing.assert_allclose(theirs.positions(), pos, atol=1e-9)
    root = bnames[0]
    assert root in ("Hips", "CHip", "Hip")
    assert np.abs(pos[at, 0] - pts[root]).max() < 1e-3            # within 1 mm
    bones = 0
    for j, name in enumerate(bnames):
        p = parents[j]
        if p < 0 or name.endswith("/end") or not np.any(offsets[j]):
            continue
        parent = bnames[p]
        while parent not in pts:                   # a zero-length joint: its parent's point
            p = parents[p]
            parent = bnames[p]
        want = pts[name] - pts[parent]
        got = pos[at, j] - pos[at, p]
        cos = np.sum(want * got, -1) / np.linalg.norm(want, axis=-1) / np.linalg.norm(got, axis=-1)
        angle = np.degrees(np.arccos(np.clip(cos, -1, 1)))
        assert angle.max() < 1.0, (name, angle.max())
        # one length per bone: the joints' median
        length = np.linalg.norm(got, axis=-1)
        assert np.ptp(length) < 1e-5
        assert length[0] == pytest.approx(np.median(np.linalg.norm(want, axis=-1)), abs=1e-5)
        bones += 1
    assert bones == len(pts) - 1          # every point but the root ends a bone


def test_bvh_with_missing_joints_and_errors(tmp_path):
    X, valid, ids, names = scene_motion("BODY_25")
    valid[:, names.index("left_big_toe")] = False        # never seen: left out
    path = tmp_path / "m.bvh"
    write_joints3d(path, X, valid, ids, names, FPS, "m")
    bnames = parse_bvh_fk(path.read_text())[0]
    assert "LBigToe" not in bnames and "RBigToe" in bnames
    with pytest.raises(InputError, match="not metres"):
        write_joints3d(tmp_path / "x.bvh", X, valid, ids, names, FPS, "subject height")
    with pytest.raises(InputError, match="frame rate"):
        write_joints3d(tmp_path / "x.bvh", X, valid, ids, names, None, "m")
    hips = [names.index(n) for n in ("left_hip", "right_hip", "mid_hip")]
    valid[:, hips] = False
    with pytest.raises(InputError, match="needs the hips"):
        write_joints3d(tmp_path / "x.bvh", X, valid, ids, names, FPS, "m")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.bvh"]
