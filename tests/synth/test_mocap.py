"""Tests of motion capture as the motion of a synthetic person (mirrorgraph.synth.mocap)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.anthropometry import expected_bone_lengths
from mirrorgraph.errors import InputError
from mirrorgraph.skeletons import BODY_25, COCO_17
from mirrorgraph.synth import make_scene, write_scene
from mirrorgraph.synth.body import FULL_INDEX
from mirrorgraph.io.bvh import read_bvh
from mirrorgraph.synth.mocap import cmu_example_path, load_motion, pingpong_indices

#: The CMU take shipped as package data (mirrorgraph/data/cmu_01_01.bvh): nothing
#: outside the repository is needed.
CMU_FILE = cmu_example_path()


@pytest.fixture(scope="module")
def cmu_path() -> Path:
    if not CMU_FILE.is_file():
        pytest.fail(f"the CMU motion-capture take is missing: expected {CMU_FILE} "
                    "(package data of mirrorgraph, mirrorgraph/data/README.md)")
    return CMU_FILE


def test_cmu_take_is_package_data():
    """The take lives in the package (a fresh clone has it), and is declared as
    package data, so that an installed mirrorgraph has it too."""
    import tomllib

    import mirrorgraph

    root = Path(mirrorgraph.__file__).resolve().parent
    assert CMU_FILE.resolve() == root / "data" / "cmu_01_01.bvh"
    assert (root / "data" / "README.md").is_file()
    pyproject = root.parent / "pyproject.toml"
    if pyproject.is_file():                         # a source checkout
        data = tomllib.loads(pyproject.read_text())["tool"]["setuptools"]["package-data"]
        assert "data/*.bvh" in data["mirrorgraph"]


@pytest.fixture(scope="module")
def cmu(cmu_path):
    return read_bvh(cmu_path)


@pytest.fixture(scope="module")
def take30(cmu):
    return load_motion(cmu, 30.0)


def _bones(X: np.ndarray, skeleton=BODY_25) -> dict[str, np.ndarray]:
    """Bone name -> (T,) lengths of joints ``(T, 25, 3)`` in FULL_JOINTS order."""
    out = {}
    for name, (a, b) in skeleton.bones.items():
        out[name] = np.linalg.norm(X[:, FULL_INDEX[a]] - X[:, FULL_INDEX[b]], axis=-1)
    return out


# --------------------------------------------------------------------------- the CMU take
def test_mapped_take_is_rigid_symmetric_and_human(cmu, take30):
    X = take30.joints
    assert X.shape == (688, 25, 3)                        # 2751 frames after the T-pose / 4
    assert take30.skipped == 1 and take30.source_frames == 2752 and take30.fps == 30.0
    assert np.all(np.isfinite(X))
    bones = _bones(X)
    for name, length in bones.items():
        assert np.ptp(length) < 1e-9, name                # rigid after mapping and resampling
    for left, right in BODY_25.symmetric_bones:
        a, b = bones[left][0], bones[right][0]
        assert abs(a - b) / max(a, b) < 0.06, (left, right, a, b)
    assert bones["left_femur"][0] == pytest.approx(0.404, abs=0.002)
    H = take30.height
    assert 1.45 < H < 1.65
    # limbs within 15 % of Winter's table for this height (the CMU hip joints lie
    # 0.15 m apart, half the table's hip width, so the pelvis is left out)
    table = expected_bone_lengths(BODY_25, H)
    for name, length in bones.items():
        if "pelvis" not in name:
            assert length[0] == pytest.approx(table[name], rel=0.15), name
    # head and foot points hang rigidly on their segments, mirror-symmetric
    I = FULL_INDEX
    for a, b in (("left_eye", "left_ear"), ("right_eye", "right_ear"), ("nose", "left_eye"),
                 ("left_heel", "left_ankle"), ("right_heel", "right_ankle")):
        d = np.linalg.norm(X[:, I[a]] - X[:, I[b]], axis=-1)
        assert np.ptp(d) < 1e-9, (a, b)
    d_l = np.linalg.norm(X[:, I["nose"]] - X[:, I["left_eye"]], axis=-1)
    d_r = np.linalg.norm(X[:, I["nose"]] - X[:, I["right_eye"]], axis=-1)
    assert np.allclose(d_l, d_r, atol=1e-9)
    # standing on the floor (y = 0, up): the feet touch it in the median frame, the
    # nose is at ~0.9 of the height, the head above the feet in every frame
    feet = [I[f"{s}_{p}"] for s in ("left", "right") for p in ("heel", "big_toe", "small_toe")]
    assert np.median(X[:, feet, 1].min(1)) == pytest.approx(0.0, abs=0.01)
    assert X[:, feet, 1].min() > -0.1
    assert np.median(X[:, I["nose"], 1]) == pytest.approx(0.91 * H, abs=0.05)
    assert np.all(X[:, I["nose"], 1] > X[:, feet, 1].max(1) + 0.5)
    # no jumps: the reference T-pose of the file's first frame is left out
    assert np.linalg.norm(np.diff(X, axis=0), axis=-1).max() < 0.25   # m per 1/30 s


def test_resampling_picks_every_fourth_frame_and_stays_rigid(cmu, take30):
    full = load_motion(cmu, 120.0)
    assert len(full) == 2751
    assert np.allclose(full.joints[::4], take30.joints, atol=1e-12)
    assert full.floor == take30.floor and full.height == take30.height
    t25 = load_motion(cmu, 25.0)                           # between frames: interpolated
    assert len(t25) == 2750 * 25 // 120 + 1
    for name, length in _bones(t25.joints).items():
        assert np.ptp(length) < 1e-9, name
    # sample 1 at 1/25 s lies 0.8 of the way from 120-fps frame 4 to 5
    j = FULL_INDEX["left_wrist"]
    lo, hi = full.joints[4, j], full.joints[5, j]
    assert np.linalg.norm(t25.joints[1, j] - (0.2 * lo + 0.8 * hi)) < 0.01 * np.linalg.norm(
        hi - lo) + 1e-4


def test_clip_is_in_the_body_frame_and_ping_pongs(take30):
    c = take30.clip(1500)
    I = FULL_INDEX
    first = c[0]
    assert first[I["mid_hip"], 0] == pytest.approx(0.0, abs=1e-12)
    assert first[I["mid_hip"], 2] == pytest.approx(0.0, abs=1e-12)
    left = first[I["left_hip"]] - first[I["right_hip"]] \
        + first[I["left_shoulder"]] - first[I["right_shoulder"]]
    assert left[0] > 0 and abs(left[2]) < 1e-12          # x left, facing +z
    assert np.allclose(c[:688, :, 1], take30.joints[:, :, 1])   # heights unchanged
    # back and forth: no jump where the take ends
    assert np.array_equal(pingpong_indices(3, 7), [0, 1, 2, 1, 0, 1, 2])
    assert np.allclose(c[688], c[686]) and np.allclose(c[1374], c[0])
    step = np.linalg.norm(np.diff(c, axis=0), axis=-1).max()
    assert step <= np.linalg.norm(np.diff(take30.joints, axis=0), axis=-1).max() + 1e-9


def test_mapping_or_scene_of_an_unusable_take(tmp_path):
    from tests.io.test_bvh import TINY

    tiny = tmp_path / "tiny.bvh"
    tiny.write_text(TINY)
    with pytest.raises(InputError, match="no joint for left_hip"):
        load_motion(tiny)
    with pytest.raises(InputError, match="nope.bvh"):
        make_scene(frames=10, motion=tmp_path / "nope.bvh")


# --------------------------------------------------------------------------- make_scene
def _assert_valid_scene(s) -> None:
    """The checks of tests/synth/test_synth.py: visible, in front of camera and mirror, rigid."""
    w, h = s.image_size
    margin = s.placement["margin_px"]
    for P in (s.real_clean, s.mirror_clean, s.real_image, s.mirror_image):
        assert np.all(P >= margin - 1e-6)
        assert np.all(P[..., 0] <= w - margin + 1e-6) and np.all(P[..., 1] <= h - margin + 1e-6)
    X = s.joints3d
    assert np.all(X[..., 2] > 0.5 - 1e-9) and np.all(s.reflect(X)[..., 2] > 0.5 - 1e-9)
    assert np.all(X @ s.normal <= s.distance - 0.2 + 1e-9)
    x = X[..., :2] / X[..., 2:]
    assert np.allclose(x * [s.K[0, 0], s.K[1, 1]] + s.K[:2, 2], s.real_clean)
    ij = s.skeleton.bone_index
    lengths = np.linalg.norm(X[:, ij[:, 0]] - X[:, ij[:, 1]], axis=-1)
    assert np.ptp(lengths, axis=0).max() < 1e-9
    assert all(p.shape[1:] == (s.skeleton.num_joints, 3) for p in s.detections.people)


def test_make_scene_with_motion_capture(cmu_path, take30, tmp_path):
    s = make_scene(frames=300, seed=3, skeleton="BODY_25", motion=cmu_path,
                   outlier_rate=0.05, missing_rate=0.05)
    _assert_valid_scene(s)
    assert len(s) == 300 and s.body is None
    assert s.subject_height == pytest.approx(take30.height)
    assert s.options["motion"] == str(cmu_path) and s.motion["take_frames"] == 688
    assert s.motion["scale"] == 1.0 and not s.motion["pingpong"]
    # the 3D joints are the take, placed rigidly: distances between joints agree
    cols = [FULL_INDEX[n] for n in BODY_25.joints]
    local = take30.clip(300)[:, cols]
    d_scene = np.linalg.norm(s.joints3d[:, 0] - s.joints3d[:, 8], axis=-1)
    d_take = np.linalg.norm(local[:, 0] - local[:, 8], axis=-1)
    assert np.allclose(d_scene, d_take, atol=1e-9)
    # the person really moves: jumps forward over metres
    assert np.ptp(s.joints3d[:, 8], axis=0).max() > 2.0

    paths = write_scene(s, tmp_path, formats=("npz",))
    gt = json.loads(paths["ground_truth"].read_text())
    assert gt["options"]["motion"] == str(cmu_path)
    assert gt["subject_height"] == pytest.approx(take30.height)

    again = make_scene(frames=300, seed=3, skeleton="BODY_25", motion=cmu_path,
                       outlier_rate=0.05, missing_rate=0.05)
    assert np.array_equal(again.joints3d, s.joints3d)


def test_make_scene_with_motion_scaled_and_looped(cmu_path, take30):
    s = make_scene(frames=800, seed=5, skeleton=COCO_17, motion=cmu_path,
                   subject_height=1.80, fov_deg=75.0)
    _assert_valid_scene(s)
    assert s.subject_height == 1.80 and s.motion["pingpong"]
    assert s.motion["scale"] == pytest.approx(1.80 / take30.height)
    femur = np.linalg.norm(s.joints3d[0, COCO_17.index("left_hip")]
                           - s.joints3d[0, COCO_17.index("left_knee")])
    assert femur == pytest.approx(0.404 * 1.80 / take30.height, abs=0.003)
