"""Keypoint readers/writers, format detection, atomic writes and JSON helpers."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.io import (atomic_path, atomic_write_bytes, atomic_write_text, detect_format,
                            read_json, read_keypoints, to_jsonable, write_json,
                            write_keypoints, write_paired_npz)
from mirrorgraph.keypoints import PairedKeypoints, RawDetections
from mirrorgraph.skeletons import BODY_25, COCO_17, COCO_18


# ----------------------------------------------------------------------------- helpers

def random_people(rng, n: int, J: int) -> np.ndarray:
    """``(n, J, 3)`` keypoints with about 20 % missing joints (NaN, conf 0)."""
    kp = np.concatenate([rng.uniform(0, 1900, (n, J, 2)), rng.uniform(0.05, 1.0, (n, J, 1))], -1)
    kp[rng.random((n, J)) < 0.2] = [np.nan, np.nan, 0.0]
    return kp


def random_detections(skeleton, seed: int = 0, image_size=None) -> RawDetections:
    rng = np.random.default_rng(seed)
    counts = [0, 1, 2, 3, 2, 0, 1]
    ids = np.cumsum(rng.integers(1, 5, len(counts))) + 3      # increasing, with gaps
    people = [random_people(rng, n, skeleton.num_joints) for n in counts]
    return RawDetections(skeleton=skeleton, frame_ids=ids, people=people,
                         image_size=image_size)


def assert_same_detections(a: RawDetections, b: RawDetections) -> None:
    assert a.skeleton.name == b.skeleton.name
    np.testing.assert_array_equal(a.frame_ids, b.frame_ids)
    assert b.frame_ids.dtype.kind == "i"
    assert len(a.people) == len(b.people)
    for pa, pb in zip(a.people, b.people):
        assert pa.shape == pb.shape
        np.testing.assert_array_equal(np.isnan(pa), np.isnan(pb))
        np.testing.assert_allclose(pa, pb, atol=1e-6, equal_nan=True)


def raises_input(match_parts, fn, *args, **kwargs) -> InputError:
    """Call ``fn``; assert an InputError whose message holds every part."""
    with pytest.raises(InputError) as info:
        fn(*args, **kwargs)
    msg = str(info.value)
    for part in match_parts:
        assert str(part) in msg, f"{part!r} not in {msg!r}"
    return info.value


def mmpose_doc(frames):
    """``frames``: list of (frame_id, [keypoints (J,2), ...]) -> predictions list."""
    return [{"frame_id": t, "instances": [
        {"keypoints": np.asarray(kp)[:, :2].tolist(), "keypoint_scores": [0.9] * len(kp),
         "bbox": [[0, 0, 1, 1]], "bbox_score": 1.0} for kp in insts]} for t, insts in frames]


def write_text(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def openpose_file(folder: Path, frame: int, people_flat, name: str | None = None) -> Path:
    doc = {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": flat}
                                      for flat in people_flat]}
    return write_text(folder / (name or f"video_{frame:012d}_keypoints.json"), json.dumps(doc))


def easymocap_file(folder: Path, frame: int, annots_kp, **extra) -> Path:
    doc = {"filename": f"{frame:06d}.jpg", "height": 480, "width": 640, **extra,
           "annots": [{"personID": i, "keypoints": kp, "bbox": [0, 0, 1, 1, 1],
                       "isKeyframe": False} for i, kp in enumerate(annots_kp)]}
    return write_text(folder / f"{frame:06d}.json", json.dumps(doc))


def good_flat(J=25, value=10.0):
    return [value, value, 0.5] * J


# ----------------------------------------------------------------------------- round trips

@pytest.mark.parametrize("fmt,skeleton,name", [
    ("mmpose", COCO_17, "pred.json"), ("mmpose", BODY_25, "pred.json"),
    ("openpose", BODY_25, "op"), ("openpose", COCO_18, "op"),
    ("easymocap", BODY_25, "annots"), ("easymocap", COCO_17, "annots")])
def test_round_trip(tmp_path, fmt, skeleton, name):
    size = (1920, 1080) if fmt == "easymocap" else None
    det = random_detections(skeleton, seed=hash(fmt) % 100, image_size=size)
    path = tmp_path / name
    write_keypoints(det, path, fmt)
    assert detect_format(path) == fmt
    # 25 keypoints are BODY_25 or BODY_25B; random joints do not tell which
    back = read_keypoints(path, skeleton="BODY_25" if skeleton is BODY_25 else None)
    assert isinstance(back, RawDetections)
    assert back.format == fmt and back.source == str(path)
    assert back.image_size == size and back.fps is None
    assert_same_detections(det, back)
    # missing joints really are written the format's way
    assert [p.shape[0] for p in back.people] == [0, 1, 2, 3, 2, 0, 1]


def test_round_trip_replaces_existing_folder(tmp_path):
    path = tmp_path / "op"
    write_keypoints(random_detections(BODY_25, 1), path, "openpose")
    det = random_detections(BODY_25, 2)
    det.frame_ids = det.frame_ids + 1000
    write_keypoints(det, path, "openpose")
    assert_same_detections(det, read_keypoints(path, skeleton="BODY_25"))
    assert sorted(os.listdir(tmp_path)) == ["op"]


def test_openpose_file_names_and_numeric_order(tmp_path):
    det = random_detections(BODY_25, 3)
    write_keypoints(det, tmp_path / "op", "openpose")
    names = sorted(os.listdir(tmp_path / "op"))
    assert names[0] == f"video_{det.frame_ids[0]:012d}_keypoints.json"
    # unpadded names are sorted by number, not lexically
    folder = tmp_path / "unpadded"
    for t in (10, 2, 33):
        openpose_file(folder, t, [good_flat(value=t)], name=f"clip_{t}_keypoints.json")
    det = read_keypoints(folder, skeleton="BODY_25")
    np.testing.assert_array_equal(det.frame_ids, [2, 10, 33])
    assert det.people[1][0, 0, 0] == 10.0


def test_easymocap_file_names(tmp_path):
    det = random_detections(COCO_17, 4, image_size=(640, 480))
    write_keypoints(det, tmp_path / "annots", "easymocap")
    assert sorted(os.listdir(tmp_path / "annots"))[0] == f"{det.frame_ids[0]:06d}.json"


def test_skeleton_option_and_default_when_nobody_seen(tmp_path):
    det = RawDetections(skeleton=COCO_18, frame_ids=np.array([0, 1]),
                        people=[np.empty((0, 18, 3)), np.empty((0, 18, 3))])
    write_keypoints(det, tmp_path / "op", "openpose")
    assert read_keypoints(tmp_path / "op").skeleton is BODY_25       # nothing to count
    back = read_keypoints(tmp_path / "op", skeleton="coco-18")
    assert back.skeleton is COCO_18 and back.people[0].shape == (0, 18, 3)


@pytest.mark.parametrize("mirror_flipped", [False, True])
def test_npz_round_trip(tmp_path, mirror_flipped):
    rng = np.random.default_rng(5)
    T = 9
    real, mirror = (random_people(rng, T, 25) for _ in range(2))
    paired = PairedKeypoints(skeleton=BODY_25, frame_ids=np.arange(T) * 2 + 7, real=real,
                             mirror=mirror, image_size=(1280, 720), fps=29.97)
    path = tmp_path / "pairs.npz"
    write_paired_npz(paired, path, mirror_flipped=mirror_flipped)
    stored = np.load(path)
    expect_stored = mirror if mirror_flipped else mirror[:, BODY_25.flip]
    np.testing.assert_array_equal(stored["mirror"], expect_stored)
    assert bool(stored["mirror_flipped"]) == mirror_flipped
    back = read_keypoints(path)
    assert isinstance(back, PairedKeypoints)
    assert back.format == "npz" and back.skeleton is BODY_25 and back.frames_read == T
    np.testing.assert_array_equal(back.frame_ids, paired.frame_ids)
    np.testing.assert_allclose(back.real, real, atol=1e-12, equal_nan=True)
    np.testing.assert_allclose(back.mirror, mirror, atol=1e-12, equal_nan=True)
    assert back.image_size == (1280, 720) and back.fps == pytest.approx(29.97)


def test_npz_minimal_flips_detector_labels(tmp_path):
    rng = np.random.default_rng(6)
    real, mirror = random_people(rng, 4, 17), random_people(rng, 4, 17)
    np.savez(tmp_path / "m.npz", real=real, mirror=mirror)
    back = read_keypoints(tmp_path / "m.npz")
    assert back.skeleton is COCO_17 and back.image_size is None and back.fps is None
    np.testing.assert_array_equal(back.frame_ids, np.arange(4))
    np.testing.assert_allclose(back.mirror, mirror[:, COCO_17.flip], equal_nan=True)
    # left wrist of the reflection as labelled by the detector is the real right wrist
    lw, rw = COCO_17.index("left_wrist"), COCO_17.index("right_wrist")
    np.testing.assert_array_equal(back.mirror[:, rw], mirror[:, lw])


def test_npz_sorts_frames_and_blanks_missing(tmp_path):
    real = np.ones((3, 17, 3))
    real[1, 4] = [5.0, 6.0, 0.0]                                  # conf 0, finite coords
    np.savez(tmp_path / "m.npz", real=real, mirror=np.ones((3, 17, 3)),
             frame_ids=np.array([9, 2, 5]), mirror_flipped=np.array(True))
    back = read_keypoints(tmp_path / "m.npz")
    np.testing.assert_array_equal(back.frame_ids, [2, 5, 9])
    assert np.isnan(back.real[0, 4, :2]).all() and back.real[0, 4, 2] == 0  # frame 2 first


# ----------------------------------------------------------------------------- MMPose variants

def test_mmpose_instance_info_variant_and_missing_scores(tmp_path):
    kp = np.arange(34, dtype=float).reshape(17, 2)
    doc = {"meta_info": {"dataset_name": "coco"},
           "instance_info": [{"frame_id": 4, "instances": [{"keypoints": kp.tolist()}]},
                             {"frame_id": 1, "instances": []}]}
    path = write_text(tmp_path / "demo.json", json.dumps(doc))
    det = read_keypoints(path)
    assert det.format == "mmpose" and det.skeleton is COCO_17
    np.testing.assert_array_equal(det.frame_ids, [1, 4])              # sorted
    assert det.people[0].shape == (0, 17, 3)
    np.testing.assert_array_equal(det.people[1][0, :, :2], kp)
    np.testing.assert_array_equal(det.people[1][0, :, 2], 1.0)


def test_confidence_slightly_above_one_is_clipped(tmp_path):
    doc = mmpose_doc([(0, [np.zeros((17, 2))])])
    doc[0]["instances"][0]["keypoint_scores"] = [1.0000001] + [1.2] + [0.5] * 15
    det = read_keypoints(write_text(tmp_path / "p.json", json.dumps(doc)))
    assert det.people[0][0, 0, 2] == 1.0 and det.people[0][0, 1, 2] == 1.0


def test_zero_confidence_means_missing(tmp_path):
    flat = good_flat(25)
    flat[3:6] = [0, 0, 0]
    flat[6:9] = [12.0, 13.0, 0.0]
    openpose_file(tmp_path / "op", 0, [flat])
    kp = read_keypoints(tmp_path / "op", skeleton="BODY_25").people[0][0]
    assert np.isnan(kp[1:3, :2]).all() and (kp[1:3, 2] == 0).all()
    assert np.isfinite(kp[0]).all()


# ----------------------------------------------------------------------------- detection

def test_detection_errors(tmp_path):
    (tmp_path / "empty").mkdir()
    raises_input([tmp_path / "empty", "no JSON"], read_keypoints, tmp_path / "empty")
    write_text(tmp_path / "txt" / "notes.txt", "hello")
    raises_input([tmp_path / "txt", "no JSON"], read_keypoints, tmp_path / "txt")
    raises_input([tmp_path / "nope", "no such"], read_keypoints, tmp_path / "nope")
    write_text(tmp_path / "x.csv", "1,2")
    raises_input([tmp_path / "x.csv", "unknown keypoint format"], read_keypoints,
                 tmp_path / "x.csv")
    single = openpose_file(tmp_path / "op", 0, [good_flat()])
    raises_input([single, "folder"], read_keypoints, single)
    write_text(tmp_path / "obj.json", json.dumps({"foo": 1}))
    raises_input([tmp_path / "obj.json", "not MMPose"], read_keypoints, tmp_path / "obj.json")
    write_text(tmp_path / "other" / "a.json", json.dumps([1, 2]))
    raises_input([tmp_path / "other", "neither OpenPose"], read_keypoints, tmp_path / "other")


@pytest.mark.parametrize("first", ["openpose", "easymocap"])
def test_mixed_folder(tmp_path, first):
    folder = tmp_path / "mixed"
    if first == "openpose":
        openpose_file(folder, 0, [good_flat()], name="000000_keypoints.json")
        bad = easymocap_file(folder, 1, [[[1, 1, 1]] * 25])
    else:
        easymocap_file(folder, 0, [[[1, 1, 1]] * 25])
        bad = openpose_file(folder, 1, [good_flat()], name="000001_keypoints.json")
    err = raises_input([folder, bad.name, "mixes"], read_keypoints, folder)
    assert err.source == str(bad)


# ----------------------------------------------------------------------------- bad MMPose input

def mm(tmp_path, doc, name="pred.json", raw: str | bytes | None = None) -> Path:
    path = tmp_path / name
    if raw is None:
        path.write_text(json.dumps(doc))
    elif isinstance(raw, bytes):
        path.write_bytes(raw)
    else:
        path.write_text(raw)
    return path


def test_mmpose_malformed_json(tmp_path):
    text = json.dumps(mmpose_doc([(0, [np.zeros((17, 2))])]))
    path = mm(tmp_path, None, raw=text[: len(text) // 2])
    raises_input([path, "malformed JSON", "line 1"], read_keypoints, path)
    path = mm(tmp_path, None, name="u.json", raw=b'[{"frame_id": 0, "instances": "\xff\xfe"}]')
    raises_input([path, "UTF-8"], read_keypoints, path)


@pytest.mark.parametrize("mutate,parts", [
    (lambda d: d[1]["instances"][0].update(keypoints="abc"),
     ["frame 5", "instances[0].keypoints", "list"]),
    (lambda d: d[1]["instances"][0].update(keypoints=[["1", "2"]] * 17),
     ["frame 5", "instances[0].keypoints", "numbers"]),
    (lambda d: d[1]["instances"][0].update(keypoints=[[1, 2], [3]] + [[1, 2]] * 15),
     ["frame 5", "instances[0].keypoints", "rectangular"]),
    (lambda d: d[1]["instances"][0].update(keypoints=[[1, 2, 3]] * 17),
     ["frame 5", "instances[0].keypoints", "[x, y] pairs"]),
    (lambda d: d[1]["instances"][0].update(keypoint_scores=[0.5] * 16),
     ["frame 5", "instances[0].keypoint_scores", "16 scores for 17"]),
    (lambda d: d[1]["instances"][0]["keypoints"].__setitem__(3, [float("nan"), 1.0]),
     ["frame 5", "instances", "non-finite x", "joint 3"]),
    (lambda d: d[1]["instances"][0]["keypoint_scores"].__setitem__(2, float("inf")),
     ["frame 5", "instances", "non-finite confidence"]),
    # (scores <= 0 are missing and any finite score above 1 is clipped in MMPose's
    #  format: tests/io/test_io_real_formats.py)
    (lambda d: d[1]["instances"][0]["keypoint_scores"].__setitem__(2, float("nan")),
     ["frame 5", "instances", "non-finite confidence", "joint 2"]),
    (lambda d: d[1]["instances"][0]["keypoint_scores"].__setitem__(2, None),
     ["frame 5", "instances[0].keypoint_scores", "numbers"]),
    (lambda d: d[1]["instances"].append({"keypoints": [[1, 2]] * 18}),
     ["frame 5", "instances[1].keypoints", "18 keypoints", "COCO_17"]),
    (lambda d: d[1].update(frame_id=0), ["frame 0", "duplicate frame id"]),
    (lambda d: d[1].update(frame_id="5"), ["frame_id", "integer", "entry 1"]),
    (lambda d: d[1].pop("frame_id"), ["frame_id", "missing", "entry 1"]),
    (lambda d: d[1].update(instances={}), ["frame 5", "instances", "list"]),
    (lambda d: d.__setitem__(1, 7), ["frame entry 1"]),
])
def test_mmpose_bad_content(tmp_path, mutate, parts):
    doc = mmpose_doc([(0, [np.zeros((17, 2))]), (5, [np.ones((17, 2))])])
    mutate(doc)
    path = mm(tmp_path, doc)
    raises_input([path, *parts], read_keypoints, path)


def test_mmpose_counts(tmp_path):
    path = mm(tmp_path, mmpose_doc([(0, [np.zeros((20, 2))])]))
    raises_input([path, "frame 0", "20 keypoints match no known skeleton"], read_keypoints, path)
    path = mm(tmp_path, mmpose_doc([(0, [np.zeros((17, 2))]), (1, [np.zeros((25, 2))])]),
              name="b.json")
    raises_input([path, "frame 1", "25 keypoints"], read_keypoints, path)
    path = mm(tmp_path, mmpose_doc([(3, [np.zeros((17, 2))])]), name="c.json")
    raises_input([path, "frame 3", "skeleton BODY_25 has 25"], read_keypoints, path,
                 skeleton="BODY_25")
    raises_input([path, "skeleton", "unknown skeleton"], read_keypoints, path, skeleton="H36M")


def test_mmpose_zero_frames(tmp_path):
    path = mm(tmp_path, [])
    raises_input([path, "no frames"], read_keypoints, path)
    path = mm(tmp_path, {"meta_info": {}, "instance_info": []}, name="d.json")
    raises_input([path, "no frames"], read_keypoints, path)
    path = mm(tmp_path, {"meta_info": {}, "instance_info": "x"}, name="e.json")
    raises_input([path, "instance_info"], read_keypoints, path)


# ----------------------------------------------------------------------------- bad OpenPose input

def test_openpose_bad_content(tmp_path):
    cases = [   # (people of frame 3, preceded by a good frame 0?, message parts)
        ([good_flat()[:-1]], True, ["frame 3", "people[0].pose_keypoints_2d", "multiple of 3"]),
        ([good_flat(25), good_flat(18)], False,
         ["frame 3", "people[1].pose_keypoints_2d", "18 keypoints"]),
        (["1 2 3"], True, ["frame 3", "people[0].pose_keypoints_2d", "list"]),
        ([good_flat(19)], False, ["frame 3", "people[0].pose_keypoints_2d", "no known skeleton"]),
        # NaN only where Pose2Sim writes it (a whole joint NaN, NaN, NaN)
        ([[1.0, 1.0, float("nan")] * 25], True,
         ["frame 3", "people", "non-finite confidence", "joint 0"]),
        ([[float("nan"), 1.0, 0.0] * 25], True, ["frame 3", "people", "non-finite x"]),
        ([[1.0, 1.0, float("inf")] * 25], True, ["frame 3", "people", "non-finite"]),
    ]
    for i, (people, good_first, parts) in enumerate(cases):
        folder = tmp_path / f"case{i}"
        if good_first:
            openpose_file(folder, 0, [good_flat()])
        bad = openpose_file(folder, 3, people)
        raises_input([bad, *parts], read_keypoints, folder)


def test_openpose_frame_count_differs_between_frames(tmp_path):
    openpose_file(tmp_path, 0, [good_flat(18)])
    bad = openpose_file(tmp_path, 1, [good_flat(25)])
    raises_input([bad, "frame 1", "25 keypoints, but skeleton COCO_18 has 18"],
                 read_keypoints, tmp_path)


def test_openpose_file_level_errors(tmp_path):
    a = tmp_path / "a"
    openpose_file(a, 0, [good_flat()])
    bad = write_text(a / "video_000000000001_keypoints.json", '{"people": [{"pose_k')
    raises_input([bad, "malformed JSON"], read_keypoints, a)
    b = tmp_path / "b"
    openpose_file(b, 0, [good_flat()])
    bad = openpose_file(b, 0, [good_flat()], name="video_keypoints.json")
    raises_input([bad, "no frame number"], read_keypoints, b)
    c = tmp_path / "c"
    openpose_file(c, 0, [good_flat()], name="x_7_keypoints.json")
    openpose_file(c, 0, [good_flat()], name="y_0007_keypoints.json")
    raises_input([c, "frame 7", "duplicate"], read_keypoints, c)
    d = tmp_path / "d"
    bad = write_text(d / "v_000000000000_keypoints.json", json.dumps({"people": 3}))
    raises_input([bad, "frame 0", "people", "list"], read_keypoints, d)
    e = tmp_path / "e"
    doc = '{"people": [{"pose_keypoints_2d": [NaN' + ', 1' * 74 + "]}]}"
    bad = write_text(e / "v_000000000004_keypoints.json", doc)
    raises_input([bad, "frame 4", "non-finite x", "joint 0"], read_keypoints, e)


# ----------------------------------------------------------------------------- bad EasyMocap input

def test_easymocap_bad_content(tmp_path):
    kp = [[1.0, 2.0, 0.5]] * 25
    cases = [
        (dict(annots_kp=[[[1.0, 2.0]] * 25]), ["frame 2", "annots[0].keypoints", "triples"]),
        (dict(annots_kp=[kp, kp[:17]]), ["frame 2", "annots[1].keypoints", "17 keypoints"]),
        (dict(annots_kp=["nope"]), ["frame 2", "annots[0].keypoints"]),
        (dict(annots_kp=[kp], width=-5), ["frame 2", "width", "not positive"]),
        (dict(annots_kp=[kp], width=800), ["frame 2", "width", "differs"]),
        (dict(annots_kp=[kp], height="480"), ["frame 2", "height", "integer"]),
        (dict(annots_kp=[[[1.0, float("inf"), 0.5]] * 25]), ["frame 2", "non-finite y"]),
        (dict(annots_kp=[[[float("nan"), float("nan"), -1.0]] * 25]),
         ["frame 2", "non-finite x"]),
        (dict(annots_kp=[[[1.0, 2.0, 2.0]] * 25]),
         ["frame 2", "annots", "confidence 2.0", "person 0, joint 0"]),
        (dict(annots_kp=[None]), ["frame 2", "annots[0].keypoints", "list"]),
    ]
    for i, (kwargs, parts) in enumerate(cases):
        folder = tmp_path / f"case{i}"
        easymocap_file(folder, 1, [kp])
        bad = easymocap_file(folder, 2, **kwargs)
        raises_input([bad, *parts], read_keypoints, folder)


def test_easymocap_image_size_optional(tmp_path):
    kp = [[1.0, 2.0, 0.5]] * 25
    write_text(tmp_path / "000003.json", json.dumps({"annots": [{"keypoints": kp}]}))
    det = read_keypoints(tmp_path, skeleton="BODY_25")
    assert det.image_size is None and det.frame_ids.tolist() == [3]


# ----------------------------------------------------------------------------- bad npz input

def npz(tmp_path, name="p.npz", **arrays) -> Path:
    base = {"real": np.ones((3, 17, 3)) * 0.5, "mirror": np.ones((3, 17, 3)) * 0.5}
    base.update(arrays)
    np.savez(tmp_path / name, **{k: v for k, v in base.items() if v is not None})
    return tmp_path / name


def with_value(index, value, J=17):
    a = np.ones((3, J, 3)) * 0.5
    a[index] = value
    return a


@pytest.mark.parametrize("arrays,parts", [
    (dict(mirror=None), ["mirror", "missing"]),
    (dict(mirror=np.ones((2, 17, 3))), ["mirror", "differs"]),
    (dict(real=np.ones((3, 17, 2))), ["real", "(T, J, 3)"]),
    (dict(real=np.zeros((0, 17, 3)), mirror=np.zeros((0, 17, 3))), ["no frames"]),
    (dict(real=with_value((1, 2, 2), np.nan)), ["frame 1", "real", "non-finite confidence"]),
    (dict(mirror=with_value((2, 0, 0), np.inf)), ["frame 2", "mirror", "non-finite x"]),
    (dict(real=with_value((1, 3, 1), np.nan)), ["frame 1", "real", "non-finite y"]),
    (dict(real=with_value((0, 3, 2), -1.0)), ["frame 0", "real", "confidence -1.0"]),
    (dict(real=np.ones((3, 20, 3)) * .5, mirror=np.ones((3, 20, 3)) * .5),
     ["real", "no known skeleton"]),
    (dict(skeleton=np.array("BODY_25")), ["real", "BODY_25 has 25"]),
    (dict(frame_ids=np.array([0, 4, 4])), ["frame 4", "duplicate"]),
    (dict(frame_ids=np.array([0.0, 1.0, 2.0])), ["frame_ids", "integers"]),
    (dict(mirror_flipped=np.array("yes")), ["mirror_flipped", "bool"]),
    (dict(image_size=np.array([640, -1])), ["image_size", "positive"]),
    (dict(fps=np.array(np.nan)), ["fps", "positive"]),
])
def test_npz_bad_content(tmp_path, arrays, parts):
    path = npz(tmp_path, **arrays)
    raises_input([path, *parts], read_keypoints, path)


def test_npz_bad_files(tmp_path):
    path = write_text(tmp_path / "fake.npz", "not a zip")
    raises_input([path, "not a readable .npz"], read_keypoints, path)
    path = npz(tmp_path)
    path.write_bytes(path.read_bytes()[:100])
    raises_input([path, ".npz"], read_keypoints, path)
    path = npz(tmp_path, name="s.npz", skeleton=np.array("COCO_17"))
    raises_input([path, "skeleton", "option says COCO_18"], read_keypoints, path,
                 skeleton="COCO_18")


def test_npz_nan_coordinates_allowed_only_when_missing(tmp_path):
    path = npz(tmp_path, real=with_value((1, 3), [np.nan, np.nan, 0.0]))
    back = read_keypoints(path)
    assert np.isnan(back.real[1, 3, :2]).all()


# ----------------------------------------------------------------------------- atomic writes

def test_atomic_path_keeps_existing_file_on_failure(tmp_path):
    target = tmp_path / "out.npz"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            assert tmp.parent == tmp_path and tmp.suffix == ".npz"
            tmp.write_text("half")
            raise RuntimeError("writer failed")
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["out.npz"]
    with atomic_path(target) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, a=np.arange(3))
    np.testing.assert_array_equal(np.load(target)["a"], np.arange(3))
    assert os.listdir(tmp_path) == ["out.npz"]


def test_atomic_write_text_and_bytes(tmp_path):
    atomic_write_text(tmp_path / "a.txt", "héllo")
    atomic_write_bytes(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "héllo"
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert sorted(os.listdir(tmp_path)) == ["a.txt", "b.bin"]


def test_failed_writers_leave_outputs_untouched(tmp_path):
    good = random_detections(BODY_25, 7)
    bad = random_detections(BODY_25, 8)
    bad.people[3] = "not an array"                       # fails mid-way through the frames
    for fmt, name in (("openpose", "op"), ("easymocap", "em"), ("mmpose", "p.json")):
        path = tmp_path / name
        write_keypoints(good, path, fmt)
        before = {p.name: p.read_bytes() for p in ([path] if path.is_file() else path.iterdir())}
        with pytest.raises(Exception):
            write_keypoints(bad, path, fmt)
        after = {p.name: p.read_bytes() for p in ([path] if path.is_file() else path.iterdir())}
        assert after == before
    assert sorted(os.listdir(tmp_path)) == ["em", "op", "p.json"]
    with pytest.raises(ValueError):
        write_keypoints(good, tmp_path / "x", "csv")


def test_write_paired_npz_failure_keeps_file(tmp_path):
    path = tmp_path / "p.npz"
    path.write_bytes(b"old")
    paired = PairedKeypoints(skeleton=BODY_25, frame_ids=np.arange(2),
                             real=np.ones((2, 25, 3)), mirror=np.ones((2, 17, 3)))
    with pytest.raises(IndexError):
        write_paired_npz(paired, path)
    assert path.read_bytes() == b"old" and os.listdir(tmp_path) == ["p.npz"]


# ----------------------------------------------------------------------------- JSON helpers

def test_to_jsonable_and_json_round_trip(tmp_path):
    obj = {"z": np.array([[1.0, np.nan], [np.inf, 2.5]], dtype=np.float32), "a": np.int64(3),
           "b": (np.bool_(True), np.float64(np.nan), [np.arange(2)]), "c": tmp_path}
    out = to_jsonable(obj)
    assert out == {"z": [[1.0, None], [None, 2.5]], "a": 3, "b": [True, None, [[0, 1]]],
                   "c": str(tmp_path)}
    assert type(out["a"]) is int
    write_json(tmp_path / "c.json", obj)
    text = (tmp_path / "c.json").read_text()
    assert list(json.loads(text)) == ["z", "a", "b", "c"]          # insertion order kept
    assert text.startswith('{\n  "z"')                               # indent=2
    assert read_json(tmp_path / "c.json") == out


def test_read_json_errors(tmp_path):
    path = write_text(tmp_path / "bad.json", '{"a": [1, 2')
    raises_input([path, "malformed JSON"], read_json, path)
    raises_input([tmp_path / "none.json", "no such file"], read_json, tmp_path / "none.json")


# ----------------------------------------------------------------------------- meta_info
@pytest.mark.parametrize("fmt, out", [("mmpose", "kp.json"), ("openpose", "op")])
def test_image_size_and_frame_rate_round_trip(tmp_path, fmt, out):
    """With ``meta`` the writers keep image size and frame rate (MMPose's meta_info, an
    OpenPose sidecar that no *.json reader takes for a frame); without, the files are as
    before and carry neither."""
    det = random_detections(COCO_17, image_size=(1920, 1080))
    det.fps = 25.0
    write_keypoints(det, tmp_path / out, fmt, meta=True)
    back = read_keypoints(tmp_path / out)
    assert back.image_size == (1920, 1080) and back.fps == 25.0
    assert_same_detections(det, back)
    if fmt == "openpose":
        assert not list((tmp_path / out).glob("meta_info*.json"))
        assert json.loads((tmp_path / out / "meta_info.txt").read_text())["fps"] == 25.0
    else:
        doc = json.loads((tmp_path / out).read_text())
        assert doc["meta_info"]["image_size"] == [1920, 1080]
        assert doc["meta_info"]["num_keypoints"] == 17
    plain = tmp_path / f"plain-{out}"
    write_keypoints(det, plain, fmt)
    again = read_keypoints(plain)
    assert again.image_size is None and again.fps is None


@pytest.mark.parametrize("meta, field", [
    ({"image_size": [0, 1080]}, "meta_info.image_size"),
    ({"image_size": [1920]}, "meta_info.image_size"),
    ({"image_size": "1920x1080"}, "meta_info.image_size"),
    ({"fps": -25}, "meta_info.fps"),
    ({"fps": True}, "meta_info.fps"),
])
def test_bad_meta_info_is_one_line(tmp_path, meta, field):
    det = random_detections(COCO_17)
    write_keypoints(det, tmp_path / "kp.json", "mmpose", meta=True)
    doc = json.loads((tmp_path / "kp.json").read_text())
    doc["meta_info"].update(meta)
    (tmp_path / "kp.json").write_text(json.dumps(doc))
    with pytest.raises(InputError) as e:
        read_keypoints(tmp_path / "kp.json")
    assert field in str(e.value) and "kp.json" in str(e.value) and "\n" not in str(e.value)
    write_keypoints(det, tmp_path / "op", "openpose", meta=True)
    (tmp_path / "op" / "meta_info.txt").write_text(json.dumps(meta))
    with pytest.raises(InputError) as e:
        read_keypoints(tmp_path / "op")
    assert field in str(e.value) and "meta_info.txt" in str(e.value)


def test_mmpose_demo_meta_info_without_size_reads(tmp_path):
    """MMPose's own demo writes the model's dataset_meta (no image size, no frame rate):
    read as before, neither known."""
    det = random_detections(COCO_17)
    write_keypoints(det, tmp_path / "kp.json", "mmpose")
    frames = json.loads((tmp_path / "kp.json").read_text())
    (tmp_path / "demo.json").write_text(json.dumps({"meta_info": {
        "dataset_name": "coco", "num_keypoints": 17, "sigmas": [0.026] * 17},
        "instance_info": frames}))
    back = read_keypoints(tmp_path / "demo.json")
    assert back.image_size is None and back.fps is None
    assert_same_detections(det, back)


def test_mmpose_read_at_once_is_the_frame_by_frame_reading():
    """A well-formed file is read in one pass over every instance; what it gives (people,
    missing and clipped scores, people without joints, empty frames, their counts) is
    what reading it frame by frame gives, and a wrong entry is still named."""
    from mirrorgraph.io import mmpose

    rng = np.random.default_rng(5)
    frames = []
    for t in [7, 2, 9, 4, 11]:                                 # unsorted ids
        inst = []
        for _ in range(int(rng.integers(0, 3))):
            xy = rng.uniform(0, 1900, (17, 2)).round(2)
            sc = rng.uniform(-0.2, 1.4, 17)                    # <= 0: missing; > 1: clipped
            if rng.random() < 0.3:
                sc[:] = 0.0                                    # nobody seen
            inst.append({"keypoints": xy.tolist(), "keypoint_scores": sc.tolist()})
        if t == 4:
            inst.append({"keypoints": [[1, 2]] * 17})           # integers, no scores
        frames.append({"frame_id": t, "instances": inst})
    fast = mmpose._read_at_once(frames, None, "x")
    assert fast is not None
    slow = mmpose._read_frames(frames, None, "x")
    assert_same_detections(fast, slow)
    assert fast.read_notes.as_dict() == slow.read_notes.as_dict()
    assert fast.read_notes.scores_clipped_above_1 > 0
    # not well formed: the frame-by-frame reading names it
    frames[2]["instances"].append({"keypoints": [[1, 2]] * 16, "keypoint_scores": [1] * 16})
    assert mmpose._read_at_once(frames, None, "x") is None
    with pytest.raises(InputError, match="16 keypoints"):
        mmpose.detections_from_mmpose(frames, source="x")
