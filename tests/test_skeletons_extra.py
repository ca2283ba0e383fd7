"""BODY_25B and HALPE_26 layouts, and telling BODY_25 from BODY_25B by the data."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.anthropometry import expected_bone_lengths, height_fractions
from mirrorgraph.cli.args import error_message
from mirrorgraph.errors import InputError
from mirrorgraph.io import read_keypoints, write_keypoints, write_paired_npz
from mirrorgraph.keypoints import PairedKeypoints, RawDetections
from mirrorgraph.skeleton_guess import (BODY_25_BELOW, BODY_25B_ABOVE, MIN_DETECTIONS,
                                        body25_ratios, guess_skeleton)
from mirrorgraph.skeletons import (BODY_25, BODY_25B, COCO_17, COCO_18, HALPE_26, SKELETONS,
                                   Skeleton, skeleton_by_name, skeleton_for_count,
                                   skeletons_for_count)
from mirrorgraph.synth import make_scene
from mirrorgraph.synth.body import (FULL_INDEX, FULL_JOINTS, make_body, skeleton_columns,
                                    skeleton_points)
from mirrorgraph.synth.motion import generate_motion

FACE_AND_FEET = ("nose", "eye", "ear", "head_top", "toe", "heel")


# ----------------------------------------------------------------------------- layouts

@pytest.mark.parametrize("skeleton,spots", [
    # OpenPose POSE_BODY_25B_BODY_PARTS (UpperNeck = neck, HeadTop = head_top)
    (BODY_25B, {0: "nose", 1: "left_eye", 2: "right_eye", 4: "right_ear", 5: "left_shoulder",
                10: "right_wrist", 11: "left_hip", 16: "right_ankle", 17: "neck",
                18: "head_top", 19: "left_big_toe", 20: "left_small_toe", 21: "left_heel",
                22: "right_big_toe", 23: "right_small_toe", 24: "right_heel"}),
    # Halpe-FullBody body points 0-25 (Head = head_top, Hip = mid_hip)
    (HALPE_26, {0: "nose", 2: "right_eye", 6: "right_shoulder", 9: "left_wrist",
                12: "right_hip", 15: "left_ankle", 17: "head_top", 18: "neck",
                19: "mid_hip", 20: "left_big_toe", 21: "right_big_toe", 22: "left_small_toe",
                23: "right_small_toe", 24: "left_heel", 25: "right_heel"}),
])
def test_published_orders(skeleton, spots):
    assert skeleton.num_joints == {"BODY_25B": 25, "HALPE_26": 26}[skeleton.name]
    assert len(set(skeleton.joints)) == skeleton.num_joints
    assert skeleton.joints[:17] == COCO_17.joints          # both start with COCO-17
    for i, name in spots.items():
        assert skeleton.joints[i] == name and skeleton.index(name) == i


@pytest.mark.parametrize("skeleton", list(SKELETONS.values()), ids=list(SKELETONS))
def test_flip_is_an_involution_swapping_sides(skeleton):
    f = skeleton.flip
    np.testing.assert_array_equal(np.sort(f), np.arange(skeleton.num_joints))
    np.testing.assert_array_equal(f[f], np.arange(skeleton.num_joints))
    for i, name in enumerate(skeleton.joints):
        if name.startswith("left_"):
            assert skeleton.joints[f[i]] == "right_" + name[5:]
        elif name.startswith("right_"):
            assert skeleton.joints[f[i]] == "left_" + name[6:]
        else:
            assert f[i] == i


@pytest.mark.parametrize("skeleton", list(SKELETONS.values()), ids=list(SKELETONS))
def test_bones_calibration_joints_and_anthropometry(skeleton):
    for a, b in skeleton.bones.values():
        assert skeleton.has(a) and skeleton.has(b)
    assert skeleton.bone_index.shape == (len(skeleton.bones), 2)
    for left, right in skeleton.symmetric_bones:
        assert left in skeleton.bones and right in skeleton.bones
    names = [skeleton.joints[i] for i in skeleton.calibration_joints]
    assert len(names) == len(skeleton.calibration_joint_names)
    assert not any(part in n for n in names for part in FACE_AND_FEET)
    fractions = height_fractions(skeleton)
    assert set(fractions) == set(skeleton.bones)
    assert all(0 < v < 0.3 for v in fractions.values())
    lengths = expected_bone_lengths(skeleton, 1.75)
    assert lengths["left_femur"] == pytest.approx(0.245 * 1.75)


def test_derived_bones_of_the_new_layouts():
    assert {"left_scapular", "right_scapular", "hip_width"} <= set(BODY_25B.bones)
    assert BODY_25B.mid_hip is None and "shoulder_width" not in BODY_25B.bones
    assert {"left_scapular", "right_scapular", "left_pelvis",
            "right_pelvis"} <= set(HALPE_26.bones)
    assert HALPE_26.mid_hip == "mid_hip"
    assert set(BODY_25B.calibration_joint_names) == set(COCO_17.calibration_joint_names) | {"neck"}
    assert set(HALPE_26.calibration_joint_names) == set(BODY_25.calibration_joint_names)


def test_lookup_by_name_and_count():
    for name in ("body_25b", "BODY-25B", " Body_25B "):
        assert skeleton_by_name(name) is BODY_25B
    for name in ("HALPE-26", "halpe_26"):
        assert skeleton_by_name(name) is HALPE_26
    with pytest.raises(ValueError, match="HALPE_26"):     # the list of known names
        skeleton_by_name("HALPE_136")
    assert skeletons_for_count(25) == (BODY_25, BODY_25B)
    assert skeleton_for_count(17) is COCO_17 and skeleton_for_count(18) is COCO_18
    assert skeleton_for_count(26) is HALPE_26 and skeleton_for_count(20) is None
    with pytest.raises(ValueError, match="BODY_25 or BODY_25B"):
        skeleton_for_count(25)


# ----------------------------------------------------------------------------- synthetic body

def test_head_top_of_the_body_model_is_exact():
    rng = np.random.default_rng(4)
    body = make_body(rng)
    full = generate_motion(body, 40, 30.0, rng)                  # (T, 25, 3), units of height
    pts = skeleton_points(full, HALPE_26)
    np.testing.assert_array_equal(pts[:, :17], full[:, skeleton_columns(COCO_17)])
    top = pts[:, HALPE_26.index("head_top")]
    # rigid in the head: the model's distances from the vertex to the nose and the ears
    vertex = np.array([0.0, body.lengths["head_top"], 0.0])
    for name, offset in (("nose", body.head["nose"]), ("left_ear", body.head["ear"])):
        d = np.linalg.norm(top - full[:, FULL_INDEX[name]], axis=-1)
        np.testing.assert_allclose(d, np.linalg.norm(vertex - offset), rtol=1e-9)
    # and above the eyes: the vertex is the highest point of a standing person's head
    assert (top[:, 1] > full[:, FULL_INDEX["left_eye"], 1]).all()
    np.testing.assert_array_equal(skeleton_points(full, BODY_25),
                                  full[:, skeleton_columns(BODY_25)])
    with pytest.raises(ValueError, match="head_top"):
        skeleton_columns(BODY_25B)
    tail = Skeleton(name="TAIL", joints=("nose", "tail"), bones={}, symmetric_bones=(),
                    mid_hip=None, calibration_joint_names=())
    with pytest.raises(ValueError, match="'tail'"):
        skeleton_points(full, tail)


def _project(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    x = X @ K.T
    return x[..., :2] / x[..., 2:3]


def detections_as(scene, skeleton, seed: int, noise_px: float = 4.0,
                  outlier_rate: float = 0.05) -> RawDetections:
    """The person and reflection of a BODY_25 scene's 3D joints, as ``skeleton`` detections.

    Pinhole projection of the joints ``X`` and of their reflections ``S(X)``; the
    reflection is labelled as a detector sees it (``[:, skeleton.flip]``); Gaussian
    noise of ``noise_px`` per coordinate, outliers moved 30-150 px, confidences 0.5-1.
    """
    rng = np.random.default_rng(seed)
    full = scene.joints3d[:, [BODY_25.index(n) for n in FULL_JOINTS]]
    X = skeleton_points(full, skeleton)                                 # (T, J, 3) m
    n, d = scene.normal, scene.distance
    views = []
    for Y, labels in ((X, None), (X - 2.0 * ((X @ n) - d)[..., None] * n, skeleton.flip)):
        uv = _project(scene.K, Y)
        if labels is not None:
            uv = uv[:, labels]
        uv = uv + rng.normal(0.0, noise_px, uv.shape)
        out = rng.random(uv.shape[:2]) < outlier_rate
        ang = rng.uniform(0, 2 * np.pi, uv.shape[:2])
        rad = rng.uniform(30, 150, uv.shape[:2])
        uv[out] += (np.stack([np.cos(ang), np.sin(ang)], -1) * rad[..., None])[out]
        views.append(np.concatenate([uv, rng.uniform(0.5, 1.0, uv.shape[:2] + (1,))], -1))
    people = [np.stack([views[0][t], views[1][t]]) for t in range(len(X))]
    return RawDetections(skeleton=skeleton, frame_ids=np.asarray(scene.frame_ids), people=people,
                         image_size=scene.image_size)


# ----------------------------------------------------------------------------- 25 keypoints

@pytest.fixture(scope="module")
def scenes():
    """Three BODY_25 scenes with the detector model's outliers, swaps and bystanders."""
    return [make_scene(frames=50, seed=s, skeleton="BODY_25", outlier_rate=0.05,
                       lr_swap_rate=0.05, missing_rate=0.05, extra_person_rate=0.05)
            for s in (1, 2, 3)]


def test_ratio_separates_the_layouts(scenes):
    for i, scene in enumerate(scenes):
        r25 = body25_ratios(np.concatenate([p for p in scene.detections.people if len(p)]))
        r25b = body25_ratios(np.concatenate(detections_as(scene, BODY_25B, i).people))
        assert len(r25) > 80 and len(r25b) > 80
        # measured: medians 0.04-0.13 (BODY_25) and 0.57-0.70 (BODY_25B) over 40 scenes
        assert np.median(r25) < 0.2 < BODY_25_BELOW
        assert np.median(r25b) > 0.5 > BODY_25B_ABOVE


@pytest.mark.parametrize("fmt,name", [("openpose", "op"), ("mmpose", "pred.json"),
                                      ("easymocap", "annots")])
def test_reader_tells_body_25_from_body_25b(tmp_path, scenes, fmt, name):
    scene = scenes[0]
    det_b = detections_as(scene, BODY_25B, 7)
    for skeleton, det in ((BODY_25, scene.detections), (BODY_25B, det_b)):
        path = tmp_path / f"{skeleton.name}_{name}"
        write_keypoints(det, path, fmt)
        back = read_keypoints(path)
        assert back.skeleton is skeleton
        # an explicit layout is taken as given, even a wrong one of the same count
        other = BODY_25B if skeleton is BODY_25 else BODY_25
        assert read_keypoints(path, skeleton=other.name).skeleton is other


def test_paired_npz_without_a_name_is_told_apart(tmp_path, scenes):
    scene = scenes[1]
    det_b = detections_as(scene, BODY_25B, 3)
    for skeleton, det in ((BODY_25, scene.detections), (BODY_25B, det_b)):
        if skeleton is BODY_25:
            real, mirror = scene.real_observed, scene.mirror_observed
        else:
            real = np.stack([p[0] for p in det.people])
            mirror = np.stack([p[1] for p in det.people])[:, BODY_25B.flip]   # real-joint labels
        path = tmp_path / f"{skeleton.name}.npz"
        write_paired_npz(PairedKeypoints(skeleton=skeleton, frame_ids=scene.frame_ids,
                                         real=real, mirror=mirror), path)
        with np.load(path) as z:                          # an older file: no skeleton name
            arrays = {k: z[k] for k in z.files if k != "skeleton"}
        np.savez(path, **arrays)
        back = read_keypoints(path)
        assert back.skeleton is skeleton
        np.testing.assert_allclose(back.mirror, mirror, equal_nan=True)


def test_too_few_detections_is_an_input_error_naming_the_file(tmp_path, scenes):
    det = detections_as(scenes[2], BODY_25B, 5)
    keep = MIN_DETECTIONS // 2 - 1                       # two people a frame
    few = RawDetections(skeleton=BODY_25B, frame_ids=det.frame_ids[:keep],
                        people=det.people[:keep])
    path = tmp_path / "few_frames"
    write_keypoints(few, path, "openpose")
    with pytest.raises(InputError) as info:
        read_keypoints(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(str(path))
    assert "skeleton=BODY_25 " in msg and "skeleton=BODY_25B" in msg    # the argument
    assert "--skeleton BODY_25 or --skeleton BODY_25B" in error_message(info.value)   # the CLI
    assert read_keypoints(path, skeleton="BODY_25B").skeleton is BODY_25B


def test_data_that_do_not_separate_is_an_input_error(tmp_path):
    rng = np.random.default_rng(0)
    people = [np.concatenate([rng.uniform(0, 1900, (2, 25, 2)), np.ones((2, 25, 1))], -1)
              for _ in range(40)]                       # joints anywhere: median ratio ~0.4
    det = RawDetections(skeleton=BODY_25, frame_ids=np.arange(40), people=people)
    path = tmp_path / "pred.json"
    write_keypoints(det, path, "mmpose")
    with pytest.raises(InputError, match="do not tell them apart") as info:
        read_keypoints(path)
    assert str(path) in str(info.value) and "skeleton=BODY_25B" in str(info.value)
    with pytest.raises(InputError, match="only 0 confident"):
        guess_skeleton((BODY_25, BODY_25B), np.zeros((30, 25, 3)), source="x.json")
    with pytest.raises(InputError, match="skeleton=COCO_17"):      # nothing to tell them by
        guess_skeleton((COCO_17, COCO_18), np.zeros((30, 17, 3)), source="x.json")


def test_count_mismatch_after_an_ambiguous_first_person(tmp_path, scenes):
    det = scenes[0].detections
    people = [p.copy() for p in det.people]
    people[3] = np.full((1, 18, 3), 0.5)                 # a COCO-18 person in frame 3
    path = tmp_path / "mixed"
    write_keypoints(RawDetections(skeleton=BODY_25, frame_ids=det.frame_ids, people=people),
                    path, "openpose")
    with pytest.raises(InputError, match="18 keypoints, but skeleton BODY_25 or BODY_25B has 25"):
        read_keypoints(path)


def test_halpe_26_is_found_by_its_count(tmp_path):
    rng = np.random.default_rng(2)
    people = [np.concatenate([rng.uniform(0, 1000, (2, 26, 2)), np.full((2, 26, 1), 0.9)], -1)
              for _ in range(3)]
    det = RawDetections(skeleton=HALPE_26, frame_ids=np.arange(3), people=people)
    write_keypoints(det, tmp_path / "pred.json", "mmpose")
    assert read_keypoints(tmp_path / "pred.json").skeleton is HALPE_26


def test_the_layout_of_several_people_by_its_name():
    from mirrorgraph.errors import InputError
    from mirrorgraph.skeletons import people_skeleton, skeleton_by_name

    three = people_skeleton(skeleton_by_name("COCO_17"), 3)
    again = skeleton_by_name(three.name.lower())
    assert again.joints == three.joints and again.bones == three.bones
    for bad in ("COCO_17@1", "COCO_17@x", "NOPE@3"):
        with pytest.raises(InputError):
            skeleton_by_name(bad)
