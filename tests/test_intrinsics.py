"""Intrinsics: loading JSON / OpenCV YAML, FOV approximation, undistortion."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.intrinsics import (DEFAULT_FOV_DEG, Intrinsics, intrinsics_from_fov,
                                    load_intrinsics, parse_image_size)

K = np.array([[1400.0, 0.0, 955.0], [0.0, 1410.0, 545.0], [0.0, 0.0, 1.0]])
DIST = np.array([-0.28, 0.09, 0.0012, -0.0008, -0.012])


def write(path: Path, obj) -> Path:
    path.write_text(obj if isinstance(obj, str) else json.dumps(obj))
    return path


def expect_error(path, *parts):
    with pytest.raises(InputError) as info:
        load_intrinsics(path)
    for part in (str(path), *parts):
        assert part in str(info.value), f"{part!r} not in {str(info.value)!r}"
    return info.value


# ----------------------------------------------------------------------------- loading

def test_load_json(tmp_path):
    path = write(tmp_path / "cam.json", {"K": K.tolist(), "dist": DIST.tolist(),
                                         "image_size": [1920, 1080]})
    intr = load_intrinsics(path)
    np.testing.assert_array_equal(intr.K, K)
    np.testing.assert_array_equal(intr.dist, DIST)
    assert intr.image_size == (1920, 1080) and intr.source == str(path)
    assert not intr.approximate
    assert (intr.fx, intr.fy, intr.cx, intr.cy) == (1400.0, 1410.0, 955.0, 545.0)
    d = intr.to_dict()
    assert d["K"] == K.tolist() and d["dist"] == DIST.tolist() and d["image_size"] == [1920, 1080]
    json.dumps(d)


def test_load_json_minimal(tmp_path):
    intr = load_intrinsics(write(tmp_path / "cam.json", {"K": K.tolist()}))
    assert intr.dist is None and intr.image_size is None
    assert intr.to_dict()["dist"] is None


def test_load_opencv_yaml_written_by_opencv(tmp_path):
    path = tmp_path / "cam.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1920)
    fs.write("image_height", 1080)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", DIST.reshape(-1, 1))
    fs.release()
    intr = load_intrinsics(path)
    np.testing.assert_allclose(intr.K, K)
    np.testing.assert_allclose(intr.dist, DIST)
    assert intr.image_size == (1920, 1080)


def test_load_opencv_yaml_1_0_header_without_suffix(tmp_path):
    text = ("%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
            "   dt: d\n   data: [ 800., 0., 320., 0., 800., 240., 0., 0., 1. ]\n")
    intr = load_intrinsics(write(tmp_path / "camera.txt", text))
    assert intr.fx == 800.0 and intr.cy == 240.0 and intr.dist is None
    assert intr.image_size is None


@pytest.mark.parametrize("obj,parts", [
    ("{\"K\": [[1, 0", ["malformed JSON"]),
    ([1, 2], ["JSON object"]),
    ({"dist": [0, 0, 0, 0]}, ["'K'", "missing"]),
    ({"K": [[1, 0, 0], [0, 1, 0]]}, ["'K'", "3x3"]),
    ({"K": "eye"}, ["'K'"]),
    ({"K": [[1400, 0, 955], [0, 1410, 545], [0, 0, float("nan")]]}, ["'K'", "non-finite"]),
    ({"K": [[1400, 0, 955], [0, 1410, 545], [0, 0.1, 1]]}, ["'K'", "[0, 0, 1]"]),
    ({"K": [[-5, 0, 955], [0, 1410, 545], [0, 0, 1]]}, ["'K'", "positive"]),
    ({"K": [[1400, 0, 955], [0, 0, 545], [0, 0, 1]]}, ["'K'", "positive"]),
    ({"K": [[1, 1, 0], [1, 1, 0], [0, 0, 1]]}, ["'K'", "singular"]),
    ({"K": K.tolist(), "dist": [0.1, 0.2, 0.3]}, ["'dist'", "OpenCV takes"]),
    ({"K": K.tolist(), "dist": [0.1, 0.2, 0.3, float("inf")]}, ["'dist'", "non-finite"]),
    ({"K": K.tolist(), "dist": "none"}, ["'dist'"]),
    ({"K": K.tolist(), "image_size": [1920]}, ["'image_size'"]),
    ({"K": K.tolist(), "image_size": [1920, -1]}, ["'image_size'", "positive integers"]),
    ({"K": K.tolist(), "image_size": [1920.5, 1080]}, ["'image_size'", "positive integers"]),
    ({"K": K.tolist(), "image_size": ["a", 1080]}, ["'image_size'"]),
])
def test_load_json_errors(tmp_path, obj, parts):
    expect_error(write(tmp_path / "cam.json", obj), *parts)


def test_load_file_errors(tmp_path):
    expect_error(tmp_path / "missing.json", "no such file")
    path = tmp_path / "bin.json"
    path.write_bytes(b"\xff\xfe\x00\x01")
    expect_error(path, "UTF-8")


@pytest.mark.parametrize("text,parts", [
    ("%YAML:1.0\ncamera_matrix: [1, 2\n  : : :\n", ["malformed OpenCV YAML"]),
    ("%YAML:1.0\ndistortion_coefficients: [0, 0, 0, 0]\n", ["'camera_matrix'", "missing"]),
    ("%YAML:1.0\ncamera_matrix: 5\n", ["'camera_matrix'"]),
    ("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
     "  data: [1, 2, 3, 4]\n", ["'camera_matrix'", "not an OpenCV matrix"]),
    ("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 2\n  cols: 2\n  dt: d\n"
     "  data: [1, 0, 0, 1]\n", ["'camera_matrix'", "3x3"]),
    ("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
     "  data: [800, 0, 320, 0, 800, 240, 0, 0, 1]\nimage_width: 64.5\nimage_height: 48\n",
     ["'image_width'", "integer"]),
    ("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
     "  data: [800, 0, 320, 0, 800, 240, 0, 0, 1]\nimage_width: 640\n",
     ["'image_height'", "together"]),
    ("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
     "  data: [800, 0, 320, 0, 800, 240, 0, 0, 1]\nimage_width: 0\nimage_height: 48\n",
     ["'image_width'", "positive"]),
])
def test_load_yaml_errors(tmp_path, text, parts):
    expect_error(write(tmp_path / "cam.yml", text), *parts)


# ----------------------------------------------------------------------------- approximations

def test_intrinsics_from_fov():
    intr = intrinsics_from_fov((1920, 1080))
    assert DEFAULT_FOV_DEG == 60.0 and intr.approximate and intr.dist is None
    assert intr.image_size == (1920, 1080)
    assert intr.fx == intr.fy == pytest.approx(960.0 / math.tan(math.radians(30.0)))
    assert (intr.cx, intr.cy) == (960.0, 540.0)
    # the horizontal FOV really is the one asked for: the image edges are +-fov/2
    wide = intrinsics_from_fov("640x480", fov_deg=90.0)
    assert math.degrees(2 * math.atan(320.0 / wide.fx)) == pytest.approx(90.0)
    for bad in (0.0, 180.0, float("nan")):
        with pytest.raises(InputError, match="fov_deg"):
            intrinsics_from_fov((640, 480), bad)


@pytest.mark.parametrize("text,size", [("1920x1080", (1920, 1080)), (" 640 X 480 ", (640, 480)),
                                       ("1280,720", (1280, 720)), ((800, 600), (800, 600))])
def test_parse_image_size(text, size):
    assert parse_image_size(text) == size


@pytest.mark.parametrize("text", ["1920", "1920x", "axb", "0x1080", "1920x1080x3", "-5x4",
                                  (1920,), (1.5, 2)])
def test_parse_image_size_errors(text):
    with pytest.raises(InputError, match="image_size"):
        parse_image_size(text)


# ----------------------------------------------------------------------------- undistortion

def test_undistort_round_trip_against_project_points():
    rng = np.random.default_rng(0)
    # rays filling most of a 1920x1080 image, depths 1..6 m
    xy = rng.uniform([-0.6, -0.35], [0.6, 0.35], (400, 2))
    pts3d = np.column_stack([xy, np.ones(len(xy))]) * rng.uniform(1, 6, (len(xy), 1))
    zero = np.zeros(3)
    distorted, _ = cv2.projectPoints(pts3d, zero, zero, K, DIST)
    ideal, _ = cv2.projectPoints(pts3d, zero, zero, K, None)
    distorted, ideal = distorted.reshape(-1, 2), ideal.reshape(-1, 2)
    assert np.abs(distorted - ideal).max() > 20.0                      # real distortion
    intr = Intrinsics(K=K, dist=DIST, image_size=(1920, 1080))
    # (..., 2) shapes kept, NaN rows stay NaN
    pts = distorted.reshape(20, 20, 2).copy()
    pts[3, 4] = np.nan
    pts[5, 6, 0] = np.nan
    out = intr.undistort_points(pts)
    assert out.shape == (20, 20, 2)
    nan = np.zeros((20, 20), bool)
    nan[3, 4] = nan[5, 6] = True
    assert np.isnan(out[nan]).all() and np.isfinite(out[~nan]).all()
    err = np.linalg.norm(out[~nan] - ideal.reshape(20, 20, 2)[~nan], axis=-1)
    assert err.max() < 1e-3
    assert np.isnan(pts[3, 4]).all() and pts[0, 0, 0] == distorted[0, 0]   # input untouched


def test_undistort_identity_without_distortion():
    pts = np.array([[[10.0, 20.0], [np.nan, np.nan]]])
    for dist in (None, np.zeros(5)):
        out = Intrinsics(K=K, dist=dist).undistort_points(pts)
        np.testing.assert_array_equal(out, pts)
        assert out is not pts
    assert Intrinsics(K=K).undistort_points(np.empty((0, 2))).shape == (0, 2)
    with pytest.raises(ValueError):
        Intrinsics(K=K, dist=DIST).undistort_points(np.zeros((4, 3)))


def test_an_undetermined_focal_length_names_its_cause():
    """Where the bones hold the focal length and only the initial search disagrees, the
    warning says so and gives both figures; where the data leave it open, it does not."""
    from mirrorgraph.intrinsics import estimated_intrinsics, intrinsics_from_fov

    guess = intrinsics_from_fov((1920, 1080), 60.0)
    K = np.array([[1136.2, 0, 960.0], [0, 1136.2, 540.0], [0, 0, 1]])
    base = {"estimated": True, "determined": False, "focal_px": 1136.2, "std_px": 290.3}
    held = dict(base, undetermined={"data_open": False, "search_px": 1428.2,
                                    "data_rel_std": 0.0117, "fov_deg": 80.4})
    warnings = []
    out = estimated_intrinsics(guess, K, held, 60.0, warnings)
    assert out.approximate and len(warnings) == 1
    assert "1136 +- 290 px (26%)" in warnings[0]
    assert "the bones hold it to 1%" in warnings[0] and "1428 px" in warnings[0]
    open_ = dict(base, undetermined={"data_open": True, "search_px": 1428.2,
                                     "data_rel_std": 0.4, "fov_deg": 80.4})
    warnings = []
    estimated_intrinsics(guess, K, open_, 60.0, warnings)
    assert "not determined by the data" in warnings[0] and "1428 px" not in warnings[0]
