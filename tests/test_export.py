"""Export to Pose2Sim / aniposelib: the flipped mirror camera, TOML files, triangulation."""

from __future__ import annotations

import json
import math
import tomllib

import cv2
import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph.result.mirror import Calibration, write_calibration
from mirrorgraph.errors import InputError
from mirrorgraph.export import (WORLD_FRAMES, camera_sections, export_calibration,
                                export_cameras, flip_camera_matrix, flip_distortion,
                                flip_mirror_keypoints)
from mirrorgraph.intrinsics import Intrinsics, load_intrinsics
from mirrorgraph.io.toml_writer import dumps
from mirrorgraph.skeletons import BODY_25, COCO_17

from tests.helpers import points_in_front, random_mirror

W, H = 1920, 1080
K0 = np.array([[1400.0, 0.0, 955.0], [0.0, 1410.0, 545.0], [0.0, 0.0, 1.0]])
DIST5 = np.array([-0.12, 0.03, 0.0011, -0.0007, -0.004])
#: All 14 OpenCV terms, small enough to stay invertible over the image.
DIST14 = np.array([-0.1, 0.02, 0.0012, -0.0009, -0.003, 0.001, -0.002, 0.0005,
                   0.0008, -0.0004, 0.0006, 0.0003, 0.002, -0.003])


def calib_dict(n, d, K=K0, dist=DIST5, size=(W, H)):
    return {"mirror": {"normal": list(map(float, n)), "distance": d},
            "intrinsics": {"K": np.asarray(K).tolist(),
                           "dist": None if dist is None else np.asarray(dist).tolist(),
                           "image_size": None if size is None else list(size)}}


def scene(seed=0, count=60):
    rng = np.random.default_rng(seed)
    n, d = random_mirror(rng)
    return n, d, points_in_front(rng, n, d, count)


def load_cams(path):
    """The cameras of a written file, read with tomllib the way the tools do."""
    doc = tomllib.loads(path.read_text())
    return [doc[k] for k in doc if k != "metadata"], doc


def cam_arrays(cam):
    K = np.array(cam["matrix"], float)
    dist = np.array(cam["distortions"], float)
    R, _ = cv2.Rodrigues(np.array(cam["rotation"], float))
    t = np.array(cam["translation"], float)
    return K, dist, R, t


def mirror_pixels(n, d, X, K=K0, dist=None):
    """Our own model of the mirror view: pi(K S(X)), with the real lens' distortion."""
    S = geo.reflect_points(X, n, d)
    if dist is None:
        return geo.project(K, S)
    out, _ = cv2.projectPoints(S.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return out.reshape(-1, 2)


def real_pixels(X, K=K0, dist=None):
    if dist is None:
        return geo.project(K, X)
    out, _ = cv2.projectPoints(X.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return out.reshape(-1, 2)


def undistort(u, K, dist):
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    src = np.ascontiguousarray(u, dtype=float).reshape(-1, 1, 2)
    if hasattr(cv2, "undistortPointsIter"):      # OpenCV 4
        return cv2.undistortPointsIter(src, K, dist, None, K, crit).reshape(-1, 2)
    return cv2.undistortPoints(src, K, dist, R=None, P=K, criteria=crit).reshape(-1, 2)


def dlt(cams, views):
    """Linear triangulation as Pose2Sim / aniposelib do it: undistort each view with its
    own K and distortion, then the null vector of the stacked x P3 - P1, y P3 - P2 rows."""
    Ps, us = [], []
    for cam, u in zip(cams, views):
        K, dist, R, t = cam_arrays(cam)
        Ps.append(K @ np.hstack([R, t[:, None]]))
        us.append(undistort(u, K, dist))
    out = []
    for i in range(len(us[0])):
        A = []
        for P, u in zip(Ps, us):
            A += [u[i, 0] * P[2] - P[0], u[i, 1] * P[2] - P[1]]
        _, _, Vt = np.linalg.svd(np.array(A))
        out.append(Vt[-1, :3] / Vt[-1, 3])
    return np.array(out)


# ----------------------------------------------------------------------------- the flip math

def test_flip_camera_matrix_is_F_K_D():
    K = np.array([[1400.0, 2.5, 955.0], [0.0, 1410.0, 545.0], [0.0, 0.0, 1.0]])
    Kp = flip_camera_matrix(K, W)
    np.testing.assert_array_equal(Kp, [[1400.0, -2.5, W - 955.0], [0.0, 1410.0, 545.0],
                                       [0.0, 0.0, 1.0]])


def test_flip_distortion_negates_p2_s1_s2_tauy():
    np.testing.assert_array_equal(flip_distortion(DIST5), DIST5 * [1, 1, 1, -1, 1])
    sign = np.ones(14)
    sign[[3, 8, 9, 13]] = -1
    np.testing.assert_array_equal(flip_distortion(DIST14), DIST14 * sign)
    assert flip_distortion(None).size == 0
    d = DIST5.copy()
    flip_distortion(d)
    np.testing.assert_array_equal(d, DIST5)          # input untouched


@pytest.mark.parametrize("world", ["camera", "z_up"])
@pytest.mark.parametrize("fmt", ["pose2sim", "anipose"])
def test_flipped_camera_reproduces_mirror_projection_exactly(tmp_path, fmt, world):
    """pi(K S(X)) flipped x -> W - x equals pi(K' (R X_w + t)) of the exported camera."""
    K = np.array([[1400.0, 1.5, 955.0], [0.0, 1410.0, 545.0], [0.0, 0.0, 1.0]])
    for seed in range(4):
        n, d, X = scene(seed)
        path = tmp_path / f"{seed}.toml"
        assert export_calibration(calib_dict(n, d, K=K, dist=None), fmt, path, world=world) == []
        (real, mirror), _ = load_cams(path)
        Xw = X @ WORLD_FRAMES[world].T
        u_m = mirror_pixels(n, d, X, K)
        Kp, dist, R, t = cam_arrays(mirror)
        assert not np.any(dist)
        assert np.isclose(np.linalg.det(R), 1.0) and Kp[0, 0] > 0 and Kp[1, 1] > 0
        Y = Xw @ R.T + t
        assert np.all(Y[:, 2] > 0)                       # in front of the flipped camera
        np.testing.assert_allclose(geo.project(Kp, Y), np.c_[W - u_m[:, 0], u_m[:, 1]],
                                   rtol=0, atol=1e-9)
        Kr, _, Rr, tr = cam_arrays(real)                 # and the real camera is the real one
        np.testing.assert_allclose(geo.project(Kr, Xw @ Rr.T + tr), geo.project(K, X),
                                   rtol=0, atol=1e-9)


@pytest.mark.parametrize("length", [4, 5, 8, 12, 14])
def test_flipped_distortion_reproduces_the_lens_exactly(length):
    """With every OpenCV distortion term: the raw mirror pixels, flipped, are what the
    flipped camera with the flipped coefficients projects (cv2.projectPoints both)."""
    dist = DIST14[:length]
    n, d, X = scene(7, 200)
    (real, mirror), warnings = export_cameras(calib_dict(n, d, dist=dist), "pose2sim")
    assert warnings == []
    u_m = mirror_pixels(n, d, X, dist=dist)
    got, _ = cv2.projectPoints(X.reshape(-1, 1, 3), mirror.rotation, mirror.translation,
                               mirror.matrix, mirror.distortions)
    np.testing.assert_allclose(got.reshape(-1, 2), np.c_[W - u_m[:, 0], u_m[:, 1]],
                               rtol=0, atol=1e-9)
    # negating p1 instead of p2 would not do: the test has the power to tell
    wrong = mirror.distortions.copy()
    wrong[[2, 3]] = -wrong[[2, 3]]
    bad, _ = cv2.projectPoints(X.reshape(-1, 1, 3), mirror.rotation, mirror.translation,
                               mirror.matrix, wrong)
    assert np.abs(bad.reshape(-1, 2) - np.c_[W - u_m[:, 0], u_m[:, 1]]).max() > 1e-3


# ----------------------------------------------------------------------------- files

@pytest.mark.parametrize("fmt", ["pose2sim", "anipose"])
def test_written_toml_round_trips_with_tomllib(tmp_path, fmt):
    n, d, _ = scene(1)
    path = tmp_path / "calib.toml"
    export_calibration(calib_dict(n, d), fmt, path)
    cams, doc = load_cams(path)
    assert list(doc) == (["cam_01", "cam_02", "metadata"] if fmt == "pose2sim"
                         else ["cam_0", "cam_1", "metadata"])
    assert doc["metadata"] == {"adjusted": False, "error": 0.0}
    real, mirror = cams
    keys = ["name", "size", "matrix", "distortions", "rotation", "translation"]
    assert list(real) == keys + (["fisheye"] if fmt == "pose2sim" else [])
    if fmt == "pose2sim":
        assert (real["name"], mirror["name"]) == ("cam_01", "cam_02")
        assert real["size"] == [1920.0, 1080.0] and all(type(v) is float for v in real["size"])
        assert real["fisheye"] is False and len(real["distortions"]) == 5   # k3 != 0
    else:
        assert (real["name"], mirror["name"]) == ("real", "mirror")
        assert real["size"] == [1920, 1080] and all(type(v) is int for v in real["size"])
        assert len(real["distortions"]) == 5
    for cam in cams:   # every number of the camera blocks is a float
        for key in ("matrix", "distortions", "rotation", "translation"):
            assert all(type(v) is float for v in np.ravel(cam[key]).tolist()), key
    np.testing.assert_array_equal(real["matrix"], K0)
    np.testing.assert_array_equal(real["rotation"], [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(real["translation"], [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(mirror["matrix"], flip_camera_matrix(K0, W))
    R, t = geo.virtual_camera_from_mirror(n, d)
    np.testing.assert_allclose(cv2.Rodrigues(np.array(mirror["rotation"]))[0], R, atol=1e-14)
    np.testing.assert_array_equal(mirror["translation"], t)   # metres, bit-exact
    assert np.isclose(np.linalg.norm(mirror["translation"]), 2 * d)
    text = path.read_text()
    assert text.startswith("# Written by mirrorgraph") and "x -> 1920 - x" in text


@pytest.mark.parametrize("fmt", ["pose2sim", "anipose"])
def test_the_tools_toml_reader_reads_the_same(tmp_path, fmt):
    """Pose2Sim and aniposelib read calibrations with the older ``toml`` package."""
    toml = pytest.importorskip("toml", reason="the 'toml' package (Pose2Sim's and "
                               "aniposelib's TOML reader) is not installed")
    n, d, _ = scene(2)
    path = tmp_path / "calib.toml"
    export_calibration(calib_dict(n, d, dist=DIST14), fmt, path, world="z_up")
    assert toml.load(str(path)) == tomllib.loads(path.read_text())


@pytest.mark.parametrize("world", ["camera", "z_up"])
@pytest.mark.parametrize("fmt", ["pose2sim", "anipose"])
def test_triangulating_flipped_keypoints_reproduces_the_joints(tmp_path, fmt, world):
    """A person and the detector's view of their reflection: the real view unchanged,
    the reflection flipped and relabelled, triangulated by DLT with the two cameras
    from the TOML, give the 3D joints (in the chosen world frame)."""
    n, d, X = scene(3, COCO_17.num_joints)
    path = tmp_path / "calib.toml"
    export_calibration(calib_dict(n, d), fmt, path, world=world)
    cams, _ = load_cams(path)
    u_real = real_pixels(X, dist=DIST5)
    # the detector labels the reflection as it sees it: its "left_x" is the real right_x
    u_mirror_detector = mirror_pixels(n, d, X, dist=DIST5)[COCO_17.flip]
    u_mirror = flip_mirror_keypoints(u_mirror_detector, W, COCO_17)
    got = dlt(cams, [u_real, u_mirror])
    np.testing.assert_allclose(got, X @ WORLD_FRAMES[world].T, rtol=0, atol=1e-7)
    # without the relabelling, the same keypoints give a different (wrong) skeleton
    wrong = dlt(cams, [u_real, flip_mirror_keypoints(u_mirror_detector, W, np.arange(17))])
    assert np.abs(wrong - X @ WORLD_FRAMES[world].T).max() > 0.05


def test_unknown_scale_uses_unit_distance_and_warns(tmp_path):
    """distance null: translation for d = 1 (the unit of mirrorgraph's joints3d then);
    triangulation equals mirrorgraph's own triangulation with d = 1."""
    n, d, X = scene(4)
    path = tmp_path / "calib.toml"
    warnings = export_calibration(calib_dict(n, None, dist=None), "pose2sim", path)
    assert len(warnings) == 1 and "mirror distance" in warnings[0] and "metres" in warnings[0]
    cams, _ = load_cams(path)
    assert np.isclose(np.linalg.norm(cams[1]["translation"]), 2.0)
    u, um = geo.project(K0, X), geo.project(K0, geo.reflect_points(X, n, d))
    ours = geo.triangulate_mirror(K0, n, 1.0, u, um)
    theirs = dlt(cams, [u, np.c_[W - um[:, 0], um[:, 1]]])
    np.testing.assert_allclose(theirs, ours, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours, X / d, atol=1e-9)
    assert "mirror distance (scale unknown)" in path.read_text()


def test_export_from_calibration_file_and_object(tmp_path):
    n, d, _ = scene(5)
    intr = Intrinsics(K=K0, dist=DIST5, image_size=(W, H), source="cam.json")
    cal = Calibration(normal=n, distance=d, scale="subject_height", estimator="reflective",
                      intrinsics=intr, initial_normal=n)
    write_calibration(tmp_path / "calibration.json", cal)
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    assert export_calibration(tmp_path / "calibration.json", "pose2sim", a) == []
    assert export_calibration(cal, "pose2sim", b) == []
    ta, tb = a.read_text(), b.read_text()
    assert "from calibration.json." in ta and "from a calibration in memory." in tb
    assert tomllib.loads(ta) == tomllib.loads(tb)


def test_approximate_intrinsics_warn_and_aniposelib_long_distortion(tmp_path):
    n, d, _ = scene(6)
    obj = calib_dict(n, d, dist=DIST14)
    obj["intrinsics"]["approximate"] = True
    warnings = export_calibration(obj, "aniposelib", tmp_path / "c.toml")
    assert any("intrinsics are approximate (a field-of-view guess" in w for w in warnings)
    assert any("14 distortion coefficients" in w for w in warnings)
    cams, _ = load_cams(tmp_path / "c.toml")
    assert len(cams[0]["distortions"]) == 14


def test_errors_name_file_and_field(tmp_path):
    n, d, _ = scene(0)
    good = calib_dict(n, d)
    with pytest.raises(InputError, match="unknown export format 'blender'"):
        export_calibration(good, "blender", tmp_path / "x.toml")
    with pytest.raises(InputError, match="unknown world frame"):
        export_calibration(good, "pose2sim", tmp_path / "x.toml", world="y_up")
    no_size = calib_dict(n, d, size=None)
    with pytest.raises(InputError, match="image size is needed"):
        export_calibration(no_size, "pose2sim", tmp_path / "x.toml")
    assert export_calibration(no_size, "pose2sim", tmp_path / "x.toml", image_size=(W, H)) == []
    bad = calib_dict(n, d)
    bad["mirror"]["normal"] = [0, 0]
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(bad))
    with pytest.raises(InputError) as info:
        export_calibration(path, "pose2sim", tmp_path / "y.toml")
    assert str(path) in str(info.value) and "mirror.normal" in str(info.value)
    bad = calib_dict(n, -1.0)
    path.write_text(json.dumps(bad))
    with pytest.raises(InputError, match="mirror.distance"):
        export_calibration(path, "pose2sim", tmp_path / "y.toml")
    path.write_text(json.dumps({"mirror": {"normal": [0, 0, 1], "distance": 2.0}}))
    with pytest.raises(InputError, match="'intrinsics'"):
        export_calibration(path, "pose2sim", tmp_path / "y.toml")
    assert not (tmp_path / "y.toml").exists()
    # a failed export leaves an existing file alone
    (tmp_path / "y.toml").write_text("old")
    with pytest.raises(InputError):
        export_calibration(path, "pose2sim", tmp_path / "y.toml")
    assert (tmp_path / "y.toml").read_text() == "old"


# ----------------------------------------------------------------------------- keypoints

def test_flip_mirror_keypoints_recipe():
    rng = np.random.default_rng(0)
    kp = np.concatenate([rng.uniform(0, W, (3, 25, 2)), rng.uniform(0.1, 1, (3, 25, 1))], -1)
    kp[0, 4] = [0.0, 0.0, 0.0]              # OpenPose's missing joint
    kp[1, 7] = [np.nan, np.nan, 0.0]        # mirrorgraph's missing joint
    out = flip_mirror_keypoints(kp, W, "BODY_25")
    flip = BODY_25.flip
    for j, name in enumerate(BODY_25.joints):
        src = kp[:, flip[j]]
        if name.startswith("left_"):
            assert BODY_25.joints[flip[j]] == "right_" + name[5:]
        seen = src[:, 2] > 0
        np.testing.assert_array_equal(out[seen, j, 0], W - src[seen, 0])
        np.testing.assert_array_equal(out[:, j, 1:], src[:, 1:])
    np.testing.assert_array_equal(out[0, flip[4]], [0.0, 0.0, 0.0])
    assert np.isnan(out[1, flip[7], :2]).all()
    np.testing.assert_allclose(flip_mirror_keypoints(out, W, BODY_25), kp, rtol=0,
                               atol=1e-9)                                      # involution
    xy = flip_mirror_keypoints(kp[..., :2], W, BODY_25)                          # (x, y) only
    np.testing.assert_array_equal(xy[2], out[2, :, :2])
    with pytest.raises(ValueError):
        flip_mirror_keypoints(kp, W, COCO_17)


# ----------------------------------------------------------------------------- aniposelib

def test_aniposelib_loads_and_triangulates(tmp_path):
    try:
        from aniposelib.cameras import CameraGroup
    except Exception as e:  # ImportError, or its own dependencies failing to import
        pytest.skip(f"aniposelib is not installed ({type(e).__name__}: {e}); it is an "
                    "optional check of the exported file, not a dependency")
    n, d, X = scene(8, COCO_17.num_joints)
    path = tmp_path / "calibration.toml"
    export_calibration(calib_dict(n, d), "anipose", path)
    cgroup = CameraGroup.load(str(path))
    assert [c.get_name() for c in cgroup.cameras] == ["real", "mirror"]
    u_real = real_pixels(X, dist=DIST5)
    u_mirror = flip_mirror_keypoints(mirror_pixels(n, d, X, dist=DIST5)[COCO_17.flip], W,
                                     COCO_17)
    p3d = np.asarray(cgroup.triangulate(np.stack([u_real, u_mirror]), undistort=True))
    # aniposelib's undistortion runs a fixed number of iterations: close, not bit-exact
    np.testing.assert_allclose(p3d, X, rtol=0, atol=1e-6)
    # without distortion its own projection reproduces both views exactly
    export_calibration(calib_dict(n, d, dist=None), "anipose", path)
    cgroup = CameraGroup.load(str(path))
    u_real = real_pixels(X)
    u_mirror = flip_mirror_keypoints(mirror_pixels(n, d, X)[COCO_17.flip], W, COCO_17)
    proj = np.asarray(cgroup.project(X)).reshape(2, -1, 2)
    np.testing.assert_allclose(proj[0], u_real, rtol=0, atol=1e-9)
    np.testing.assert_allclose(proj[1], u_mirror, rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------- intrinsics

@pytest.mark.parametrize("fmt,real,mirror", [("pose2sim", "cam_01", "cam_02"),
                                             ("anipose", "real", "mirror")])
def test_load_intrinsics_from_exported_toml(tmp_path, fmt, real, mirror):
    n, d, _ = scene(2)
    path = tmp_path / "calib.toml"
    export_calibration(calib_dict(n, d), fmt, path)
    intr = load_intrinsics(path, camera=real)
    np.testing.assert_array_equal(intr.K, K0)
    np.testing.assert_array_equal(intr.dist, DIST5)
    assert intr.image_size == (W, H) and str(path) in intr.source
    key = "cam_1" if fmt == "anipose" else "cam_02"
    by_key = load_intrinsics(path, camera=key)                   # the section key works too
    np.testing.assert_array_equal(by_key.K, flip_camera_matrix(K0, W))
    assert load_intrinsics(path, camera=mirror).source == by_key.source
    with pytest.raises(InputError) as info:
        load_intrinsics(path)
    msg = str(info.value)
    assert "holds 2 cameras" in msg and str(path) in msg
    assert all(name in msg for name in (real, mirror))
    with pytest.raises(InputError, match="no camera section or name 'side'"):
        load_intrinsics(path, camera="side")


def test_load_intrinsics_toml_variants(tmp_path):
    one = tmp_path / "one.toml"
    one.write_text(dumps({"cam_01": {"name": "cam_01", "size": [1088.0, 1920.0],
                                     "matrix": K0.tolist(), "distortions": DIST5[:4].tolist(),
                                     "rotation": [0.1, 0.2, 0.3], "translation": [1.0, 2, 3],
                                     "fisheye": False},
                          "metadata": {"adjusted": False, "error": 0.0}}))
    intr = load_intrinsics(one)                       # a single camera needs no camera=
    assert intr.image_size == (1088, 1920) and intr.dist.tolist() == DIST5[:4].tolist()
    nodist = tmp_path / "nodist.toml"
    nodist.write_text(dumps({"cam_0": {"name": "a", "matrix": K0.tolist()}}))
    assert load_intrinsics(nodist).dist is None and load_intrinsics(nodist).image_size is None

    def fails(doc, *parts, text=None, camera=None):
        p = tmp_path / "bad.toml"
        p.write_text(text if text is not None else dumps(doc))
        with pytest.raises(InputError) as info:
            load_intrinsics(p, camera=camera)
        for part in (str(p), *parts):
            assert part in str(info.value), (part, str(info.value))

    fails(None, "malformed TOML", text="[cam_01\nmatrix = 1")
    fails({"metadata": {"error": 0.0}}, "no camera table")
    fails({"cam_01": {"matrix": [[1.0, 0.0], [0.0, 1.0]]}}, "cam_01.matrix", "3x3")
    fails({"cam_01": {"matrix": K0.tolist(), "fisheye": True}}, "cam_01.fisheye", "fisheye")
    fails({"cam_01": {"matrix": K0.tolist(), "size": [1920.5, 1080.0]}}, "cam_01.size")
    fails({"cam_01": {"matrix": K0.tolist(), "distortions": [0.1, 0.2, 0.3]}},
          "cam_01.distortions", "3 distortion coefficients")
    fails({"cam_01": {"matrix": [[0.0, 0, 1], [0, 1, 1], [0, 0, 1]]}}, "cam_01.matrix",
          "focal lengths")
    fails({"cam_01": {"matrix": K0.tolist(), "distortions": ["a"]}}, "cam_01.distortions")
    fails({"a": {"name": "x", "matrix": K0.tolist()}, "b": {"name": "x", "matrix": K0.tolist()}},
          "several cameras are named 'x'", camera="x")
    js = tmp_path / "cam.json"
    js.write_text(json.dumps({"K": K0.tolist()}))
    with pytest.raises(InputError, match="camera= selects a camera of a .toml file"):
        load_intrinsics(js, camera="cam_01")


# ----------------------------------------------------------------------------- TOML writer

def test_toml_writer_round_trip():
    doc = {"title": 'say "hi"\\ \t\n\u0001 é', "n": 3, "on": True,
           "table": {"f": 1.0, "g": 1e-5, "h": -2.5e300, "big": 1e16, "ints": [1, 2],
                     "nested": [[1.0, 2.0], [3.0, 4.0]], "empty": [], "np": np.arange(3.0),
                     "npint": np.int64(7), "npf": np.float32(0.5), "key with space": "x",
                     "sub": {"deep": {"x": -0.0}}},
           "special": {"nan": math.nan, "inf": math.inf, "ninf": -math.inf}}
    text = dumps(doc, header="line one\nline two")
    assert text.startswith("# line one\n# line two\n\ntitle = ")
    back = tomllib.loads(text)
    assert back["title"] == doc["title"] and back["n"] == 3 and back["on"] is True
    t = back["table"]
    assert t["f"] == 1.0 and type(t["f"]) is float and "f = 1.0" in text
    assert (t["g"], t["h"], t["big"]) == (1e-5, -2.5e300, 1e16) and type(t["big"]) is float
    assert t["ints"] == [1, 2] and type(t["ints"][0]) is int
    assert t["nested"] == [[1.0, 2.0], [3.0, 4.0]] and t["empty"] == []
    assert t["np"] == [0.0, 1.0, 2.0] and t["npint"] == 7 and t["npf"] == 0.5
    assert t["key with space"] == "x" and math.copysign(1, t["sub"]["deep"]["x"]) == -1
    assert math.isnan(back["special"]["nan"]) and back["special"]["ninf"] == -math.inf
    mixed = tomllib.loads(dumps({"a": [1, 2.5, np.int32(3)], "b": [[1, 2], [0.5, 1]]}))
    assert mixed == {"a": [1.0, 2.5, 3.0], "b": [[1, 2], [0.5, 1.0]]}
    assert all(type(v) is float for v in mixed["a"])
    for bad in ({"x": None}, {"x": [{"a": 1}]}, {"x": object()}, {1: 2}):
        with pytest.raises(TypeError):
            dumps(bad)


@pytest.mark.parametrize("fmt", ["pose2sim", "anipose", "aniposelib"])
def test_camera_sections_are_the_ones_written(tmp_path, fmt):
    n, d, _X = scene(3)
    out = tmp_path / "c.toml"
    export_calibration(calib_dict(n, d), fmt, out)
    doc = tomllib.loads(out.read_text())
    written = [(k, v["name"]) for k, v in doc.items() if isinstance(v, dict) and "matrix" in v]
    assert written == list(camera_sections(fmt))
    with pytest.raises(InputError, match="unknown export format"):
        camera_sections("opencv")
