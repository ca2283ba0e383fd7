"""The keypoint readers on files shaped exactly as the tools write them.

Each fixture is written here, with numbers of our own, in the layout, key order, extra
keys and "missing" markers of one tool's real output (where each was read is in the
reader modules' docstrings):

* EasyMocap / Mirrored-Human ``annots``: ``[0, 0, -1]`` for a joint the annotator left
  out, leftover coordinates with confidence 0, confidences a little above 1, 7-number
  boxes, integer boxes, ``area``, ``isKeyframe``, hands and face, a person of boxes only;
* OpenPose ``--write_json``: ``0 0 0`` for missing joints, a confidence of 1.40701
  (openpose issue #615), face and hand arrays, ``part_candidates``, an empty
  ``pose_keypoints_2d`` (body detector off);
* Pose2Sim (RTMLib) OpenPose-style files: JSON ``NaN`` joints for people tracked but not
  seen, SimCC scores above 1 and <= 0, HALPE_26, names without ``_keypoints``;
* MMPose: the inferencer's video file and per-image files, the demo scripts' video and
  single-image ``{"meta_info", "instance_info"}`` files, scores above 1 and <= 0.

Each test checks the parsed arrays and the ``read_notes`` counts; malformed variants
still give the one-line error naming file, frame and field. The last tests calibrate a
synthetic scene written as Mirrored-Human-like annotations.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.cli import main
from mirrorgraph.errors import InputError
from mirrorgraph.io import detect_format, read_keypoints
from mirrorgraph.keypoints import ReadNotes
from mirrorgraph.metrics import normal_angle_deg
from mirrorgraph.skeletons import BODY_25, COCO_17, HALPE_26
from mirrorgraph.synth import make_scene, write_scene


# ----------------------------------------------------------------------------- helpers

def xy(x0: float, y0: float, J: int) -> np.ndarray:
    """``(J, 2)`` distinct pixel coordinates of one made-up person."""
    j = np.arange(J, dtype=float)
    return np.column_stack([x0 + 7.25 * j, y0 + 13.5 * j])


def conf(J: int, start: float = 0.62) -> np.ndarray:
    """``(J,)`` confidences in (0, 1) of one made-up person."""
    return start + 0.35 * (np.arange(J) % 5) / 5


def triples(x0: float, y0: float, J: int = 25) -> list[list[float]]:
    """EasyMocap ``keypoints``: ``[[x, y, c], ...]``."""
    return np.column_stack([xy(x0, y0, J), conf(J)]).tolist()


def flat(x0: float, y0: float, J: int = 25) -> list[float]:
    """OpenPose ``pose_keypoints_2d``: ``[x0, y0, c0, x1, ...]``."""
    return np.column_stack([xy(x0, y0, J), conf(J)]).ravel().tolist()


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def expect_error(parts, fn, *args, **kwargs) -> InputError:
    with pytest.raises(InputError) as info:
        fn(*args, **kwargs)
    msg = str(info.value)
    assert "\n" not in msg
    for part in parts:
        assert str(part) in msg, f"{part!r} not in {msg!r}"
    return info.value


def assert_missing(kp: np.ndarray, joints) -> None:
    """Joints ``joints`` of a ``(J, 3)`` person are missing the mirrorgraph way."""
    assert np.isnan(kp[joints, :2]).all() and (kp[joints, 2] == 0).all()


def notes(**counts) -> ReadNotes:
    return ReadNotes(**counts)


# ----------------------------------------------------------------------------- EasyMocap

def mirrored_human_file(folder: Path, frame: int, annots: list) -> Path:
    """A Mirrored-Human annotation file: ``json.dump(..., indent=4)`` of the keys in the
    order of ``data/sample-videos.zip`` (filename, height, width, annots, isKeyframe)."""
    doc = {"filename": f"images/demo_clip/{frame:06d}.jpg", "height": 1080, "width": 1920,
           "annots": annots, "isKeyframe": True}
    return write(folder / f"{frame:06d}.json", json.dumps(doc, indent=4))


def test_mirrored_human_annotations_read_as_shipped(tmp_path):
    """The issue's file: ``[0, 0, -1]`` at person 1, joint 15 is a missing joint."""
    folder = tmp_path / "annots" / "backflip"
    # frame 160: the person (feet left out with leftover coordinates and confidence 0,
    # a head score of 1.057) and the reflection (feet left out as [0, 0, -1])
    p0 = triples(900.0, 250.0)
    p0[0][2] = 1.0569981336593628
    for j in range(15, 25):
        p0[j] = [0.7139892578125, 0.9325408935546875, 0.0]
    p1 = triples(120.0, 260.0)
    for j in range(15, 24):
        p1[j] = [0.0, 0.0, -1.0]
    p1[24] = [0.0, -2.842170943040401e-14, -1.0]
    mirrored_human_file(folder, 160, [
        {"bbox": [749.7139892578125, 225.9325408935547, 1135.6378173828125,
                  466.8799743652344, 1.0, 1.0, 0.0],
         "personID": 0, "keypoints": p0, "isKeyframe": True, "area": 148937.20111465454},
        {"bbox": [32, 252, 275, 462, 0, 0, 1], "personID": 1, "keypoints": p1,
         "isKeyframe": False}])
    # frame 161: the reflection entirely left out; frame 162: nobody annotated
    mirrored_human_file(folder, 161, [
        {"bbox": [726, 202, 1143, 484, 0, 0, 1], "personID": 0,
         "keypoints": triples(905.0, 251.0), "isKeyframe": False},
        {"bbox": [30, 250, 270, 460, 0, 0, 1], "personID": 1,
         "keypoints": [[0.0, 0.0, -1.0]] * 25, "isKeyframe": False}])
    mirrored_human_file(folder, 162, [])

    assert detect_format(folder) == "easymocap"
    det = read_keypoints(folder, skeleton="BODY_25")
    assert det.format == "easymocap" and det.skeleton is BODY_25
    assert det.image_size == (1920, 1080)
    np.testing.assert_array_equal(det.frame_ids, [160, 161, 162])
    assert [p.shape for p in det.people] == [(2, 25, 3), (1, 25, 3), (0, 25, 3)]
    a, b = det.people[0]
    np.testing.assert_array_equal(a[:15, :2], xy(900.0, 250.0, 25)[:15])
    assert a[0, 2] == 1.0                                      # 1.057 clipped
    np.testing.assert_allclose(a[1:15, 2], conf(25)[1:15])
    assert_missing(a, slice(15, 25))
    assert_missing(b, slice(15, 25))                           # [0, 0, -1]
    np.testing.assert_array_equal(b[:15, :2], xy(120.0, 260.0, 25)[:15])
    np.testing.assert_array_equal(det.people[1][0, :, :2], xy(905.0, 251.0, 25))
    assert det.read_notes == notes(
        joints_missing_zero_confidence=10, joints_missing_negative_confidence=10 + 25,
        scores_clipped_above_1=1, max_confidence_read=1.0569981336593628,
        people_without_joints=1, frames_without_people=1)
    assert det.read_notes.as_dict()["joints_missing_negative_confidence"] == 35
    assert "35 joints of negative confidence" in det.read_notes.summary()


def annot2string_layout(doc: dict) -> str:
    """EasyMocap's annotator layout (``save_annot``): four-space indents, boxes with two
    decimals, one keypoint row a line with ``%7.2f``, ``isKeyframe`` last."""
    def rows(a, indent):
        pad = " " * indent
        return "[\n" + ",\n".join(pad + "[" + ", ".join(f"{v:7.2f}" for v in r) + "]"
                                  for r in a) + "\n" + " " * (indent - 4) + "]"

    out = ['{\n', f'    "filename": "{doc["filename"]}",\n',
           f'    "height": {doc["height"]},\n', f'    "width": {doc["width"]},\n',
           '    "annots": [\n']
    for n, annot in enumerate(doc["annots"]):
        ind = " " * 12
        out.append(" " * 8 + "{\n" + ind + f'"personID": {annot["personID"]},\n')
        for key in ("bbox", "bbox_handl2d", "bbox_handr2d", "bbox_face2d"):
            if key in annot:
                out.append(ind + f'"{key}": [' + ", ".join(f"{v:.2f}" for v in annot[key])
                           + "],\n")
        for key in ("keypoints", "handl2d", "handr2d", "face2d"):
            if key in annot:
                out.append(ind + f'"{key}": ' + rows(annot[key], 16) + ",\n")
        out.append(ind + f'"isKeyframe": {"true" if annot["isKeyframe"] else "false"}\n')
        out.append(" " * 8 + "}" + (",\n" if n < len(doc["annots"]) - 1 else "\n"))
    out.append('    ],\n    "isKeyframe": false\n}\n')
    return "".join(out)


def test_easymocap_tool_annotations(tmp_path):
    """EasyMocap's own files: OpenPose zeros, hands and face, a person of a box only
    (YOLO stage), ``keypoints2d`` (read by ``read_annot``), extra top-level keys."""
    folder = tmp_path / "annots" / "1"
    kp = triples(400.0, 100.0)
    for j in (15, 16, 22):
        kp[j] = [0.0, 0.0, 0.0]
    hand = np.column_stack([xy(650.0, 420.0, 21), conf(21)]).tolist()
    face = np.column_stack([xy(430.0, 80.0, 70), conf(70)]).tolist()
    doc = {"filename": "images/1/000000.jpg", "height": 1080, "width": 1920, "annots": [
        {"personID": 0, "bbox": [380.5, 90.25, 640.0, 900.0, 0.81], "keypoints": kp,
         "bbox_handl2d": [640.0, 410.0, 800.0, 700.0, 0.5], "handl2d": hand,
         "handr2d": [[0.0, 0.0, 0.0]] * 21, "face2d": face, "isKeyframe": False},
        {"personID": 1, "bbox": [100.0, 120.0, 300.0, 880.0, 0.93], "isKeyframe": False}],
        "isKeyframe": False}
    text = annot2string_layout(doc)
    assert '"keypoints": [\n                [ 400.00,  100.00,    0.62],' in text
    write(folder / "000000.json", text)
    other = {"filename": "images/1/000001.jpg", "height": 1080, "width": 1920,
             "annots": [{"id": 0, "keypoints2d": triples(402.0, 101.0), "bbox": [0, 0, 1, 1, 1],
                         "class": "human"}],
             "isKeyframe": False, "camera": "1"}
    write(folder / "000001.json", json.dumps(other, indent=4))

    det = read_keypoints(folder, skeleton="BODY_25")
    assert [p.shape for p in det.people] == [(1, 25, 3), (1, 25, 3)]
    p = det.people[0][0]
    assert_missing(p, [15, 16, 22])
    np.testing.assert_allclose(p[0], [400.0, 100.0, 0.62], atol=0.005)  # %7.2f
    np.testing.assert_allclose(det.people[1][0, :, :2], xy(402.0, 101.0, 25))
    assert det.read_notes == notes(joints_missing_zero_confidence=3,
                                   max_confidence_read=pytest.approx(0.9, abs=0.01),
                                   people_without_keypoints=1)


@pytest.mark.parametrize("bad,parts", [
    # still malformed: a score far above what heat maps give, NaN (EasyMocap never
    # writes it), a wrong count, a wrong type
    (lambda kp: kp[3].__setitem__(2, 2.0), ["confidence 2.0", "person 1, joint 3"]),
    (lambda kp: kp[3].__setitem__(0, math.nan), ["non-finite x", "person 1, joint 3"]),
    (lambda kp: kp.pop(), ["annots[1].keypoints", "24 keypoints"]),
    (lambda kp: kp[3].__setitem__(2, "0.5"), ["annots[1].keypoints", "numbers"]),
])
def test_easymocap_malformed_still_refused(tmp_path, bad, parts):
    folder = tmp_path / "annots"
    p1 = triples(120.0, 260.0)
    p1[20] = [0.0, 0.0, -1.0]
    bad(p1)
    path = mirrored_human_file(folder, 7, [
        {"bbox": [0, 0, 1, 1, 1], "personID": 0, "keypoints": triples(900.0, 250.0)},
        {"bbox": [0, 0, 1, 1, 1], "personID": 1, "keypoints": p1}])
    err = expect_error([path, "frame 7", *parts], read_keypoints, folder, skeleton="BODY_25")
    assert err.frame == 7


# ----------------------------------------------------------------------------- OpenPose

OPENPOSE_EMPTY_PARTS = ("face_keypoints_2d", "hand_left_keypoints_2d",
                        "hand_right_keypoints_2d", "pose_keypoints_3d", "face_keypoints_3d",
                        "hand_left_keypoints_3d", "hand_right_keypoints_3d")


def openpose_person(pose: list, **parts) -> dict:
    person = {"person_id": [-1], "pose_keypoints_2d": pose}
    person.update({k: parts.get(k, []) for k in OPENPOSE_EMPTY_PARTS})
    return person


def test_openpose_write_json_output(tmp_path):
    folder = tmp_path / "op"
    a = flat(600.0, 200.0)
    for j in (15, 16, 17, 18, 24):
        a[3 * j:3 * j + 3] = [0, 0, 0]
    a[3 * 5 + 2] = 1.40701                              # openpose issue #615
    face = np.column_stack([xy(610.0, 150.0, 70), conf(70)]).ravel().tolist()
    doc0 = {"version": 1.3, "people": [
        openpose_person(a, face_keypoints_2d=face),
        openpose_person(flat(1300.0, 210.0))],
        "part_candidates": [{str(k): ([600.0 + k, 200.0, 0.8] if k % 3 else [])
                             for k in range(25)}]}
    # frame 2: the body detector off for one person (face only), another person seen
    doc2 = {"version": 1.3, "people": [openpose_person([], face_keypoints_2d=face),
                                       openpose_person(flat(1290.0, 205.0))]}
    for t, doc in ((0, doc0), (1, {"version": 1.3, "people": []}), (2, doc2)):
        write(folder / f"clip_{t:012d}_keypoints.json",
              json.dumps(doc, separators=(",", ":")))

    det = read_keypoints(folder, skeleton="BODY_25")
    assert det.format == "openpose"
    assert [p.shape for p in det.people] == [(2, 25, 3), (0, 25, 3), (1, 25, 3)]
    p = det.people[0][0]
    assert_missing(p, [15, 16, 17, 18, 24])
    assert p[5, 2] == 1.0
    np.testing.assert_array_equal(p[:5, :2], xy(600.0, 200.0, 25)[:5])
    np.testing.assert_array_equal(det.people[2][0, :, :2], xy(1290.0, 205.0, 25))
    assert det.read_notes == notes(joints_missing_zero_confidence=5,
                                   scores_clipped_above_1=1, max_confidence_read=1.40701,
                                   people_without_keypoints=1, frames_without_people=1)


def test_pose2sim_rtmlib_output(tmp_path):
    """Pose2Sim's ``save_to_openpose``: ``json.dump`` (so ``NaN`` tokens), HALPE_26,
    ``{video}_{frame:06d}.json``, SimCC scores above 1 and <= 0."""
    folder = tmp_path / "pose" / "cam01_json"
    J = 26
    a = flat(700.0, 180.0, J)
    a[3 * 0 + 2] = 1.1228                               # a SimCC logit maximum
    a[3 * 21:3 * 21 + 3] = [-14.5, 33.25, -0.0571]      # not found: score <= 0
    nan_person = [math.nan] * (3 * J)
    frames = [[a, flat(1250.0, 190.0, J)],
              [nan_person, flat(1252.0, 191.0, J)],    # person 0 tracked but unseen
              [nan_person]]                              # the exception path
    for t, people in enumerate(frames):
        doc = {"version": 1.3, "people": [openpose_person(p) for p in people]}
        text = json.dumps(doc)
        assert "NaN" in text or t == 0
        write(folder / f"cam01_{t:06d}.json", text)

    assert detect_format(folder) == "openpose"
    det = read_keypoints(folder)
    assert det.skeleton is HALPE_26
    assert [p.shape for p in det.people] == [(2, J, 3), (1, J, 3), (0, J, 3)]
    p = det.people[0][0]
    assert p[0, 2] == 1.0
    assert_missing(p, [21])
    np.testing.assert_array_equal(det.people[1][0, :, :2], xy(1252.0, 191.0, J))
    assert det.read_notes == notes(joints_missing_negative_confidence=1,
                                   joints_missing_nan=2 * J, scores_clipped_above_1=1,
                                   max_confidence_read=1.1228, people_without_joints=2,
                                   frames_without_people=1)


@pytest.mark.parametrize("value,c,parts", [
    (math.nan, 0, ["non-finite x", "person 0, joint 4"]),   # NaN x only: not a NaN joint
    (math.nan, 2, ["non-finite confidence", "person 0, joint 4"]),
    (math.inf, 1, ["non-finite y", "person 0, joint 4"]),
    ("NaN", 0, ["people[0].pose_keypoints_2d", "numbers"]),
])
def test_openpose_malformed_still_refused(tmp_path, value, c, parts):
    a = flat(600.0, 200.0)
    a[3 * 4 + c] = value
    path = write(tmp_path / "op" / "v_000000000003_keypoints.json",
                 json.dumps({"version": 1.3, "people": [openpose_person(a)]}))
    expect_error([path, "frame 3", *parts], read_keypoints, tmp_path / "op",
                 skeleton="BODY_25")


# ----------------------------------------------------------------------------- MMPose

def mmpose_instance(x0: float, y0: float, scores=None, J: int = 17) -> dict:
    """One instance as ``split_instances`` writes it: the bbox double-nested."""
    s = conf(J, 0.71) if scores is None else np.asarray(scores, float)
    return {"keypoints": xy(x0, y0, J).tolist(), "keypoint_scores": s.tolist(),
            "bbox": [[x0 - 20.0, y0 - 30.0, x0 + 140.0, y0 + 260.0]], "bbox_score": 0.9731}


COCO_META = {"dataset_name": "coco", "num_keypoints": 17,
             "keypoint_id2name": {str(i): n for i, n in enumerate(COCO_17.joints)},
             "flip_indices": [int(i) for i in COCO_17.flip],
             "sigmas": {"__ndarray__": [0.026] * 17, "dtype": "float32", "shape": [17]}}


def test_mmpose_inferencer_video_predictions(tmp_path):
    s = conf(17, 0.71)
    s[[0, 1]] = [1.3125, 1.0862956]                     # RSN / SimCC scores above 1
    s[[9, 10]] = [-0.2, 0.0]                            # not found
    doc = [{"frame_id": 0, "instances": [mmpose_instance(800.0, 300.0, s),
                                         mmpose_instance(300.0, 310.0)]},
           {"frame_id": 1, "instances": [mmpose_instance(802.0, 301.0)]},
           {"frame_id": 2, "instances": []}]
    path = write(tmp_path / "predictions" / "clip.json", json.dumps(doc, indent="  "))
    det = read_keypoints(path)
    assert det.format == "mmpose" and det.skeleton is COCO_17
    assert [p.shape for p in det.people] == [(2, 17, 3), (1, 17, 3), (0, 17, 3)]
    p = det.people[0][0]
    np.testing.assert_array_equal(p[:, :2][[0, 1, 2]], xy(800.0, 300.0, 17)[[0, 1, 2]])
    assert (p[[0, 1], 2] == 1.0).all()
    assert_missing(p, [9, 10])
    assert det.read_notes == notes(joints_missing_zero_confidence=1,
                                   joints_missing_negative_confidence=1,
                                   scores_clipped_above_1=2, max_confidence_read=1.3125,
                                   frames_without_people=1)


def test_mmpose_demo_predictions_video_and_image(tmp_path):
    """``--save-predictions`` of the demo scripts: frames from 1 on a video, the bare
    list of instances on one image."""
    video = {"meta_info": COCO_META, "instance_info": [
        {"frame_id": 1, "instances": [mmpose_instance(500.0, 200.0)]},
        {"frame_id": 2, "instances": [mmpose_instance(501.0, 201.0),
                                      mmpose_instance(100.0, 205.0)]}]}
    det = read_keypoints(write(tmp_path / "results_clip.json", json.dumps(video, indent="\t")))
    np.testing.assert_array_equal(det.frame_ids, [1, 2])
    assert [len(p) for p in det.people] == [1, 2]
    image = {"meta_info": COCO_META,
             "instance_info": [mmpose_instance(500.0, 200.0), mmpose_instance(90.0, 210.0)]}
    path = write(tmp_path / "results_image.json", json.dumps(image, indent="\t"))
    assert detect_format(path) == "mmpose"
    det = read_keypoints(path)
    np.testing.assert_array_equal(det.frame_ids, [0])
    np.testing.assert_array_equal(det.people[0][1, :, :2], xy(90.0, 210.0, 17))
    # the inferencer's file for one image: the list of instances itself
    path = write(tmp_path / "000042.json", json.dumps([mmpose_instance(500.0, 200.0)]))
    assert read_keypoints(path).people[0].shape == (1, 17, 3)


def test_mmpose_inferencer_image_folder(tmp_path):
    """``MMPoseInferencer(...)(folder_of_frames, pred_out_dir=...)``: one file per image."""
    folder = tmp_path / "predictions"
    write(folder / "frame_000010.json", json.dumps([mmpose_instance(500.0, 200.0),
                                                    mmpose_instance(90.0, 210.0)], indent="  "))
    write(folder / "frame_000011.json", json.dumps([]))
    s = conf(17, 0.71)
    s[3] = -0.4
    write(folder / "frame_000012.json", json.dumps([mmpose_instance(503.0, 202.0, s)]))
    assert detect_format(folder) == "mmpose"
    calls = []
    det = read_keypoints(folder, progress=lambda i, n: calls.append((i, n)))
    assert det.format == "mmpose" and det.source == str(folder)
    np.testing.assert_array_equal(det.frame_ids, [10, 11, 12])
    assert [len(p) for p in det.people] == [2, 0, 1]
    assert_missing(det.people[2][0], [3])
    assert calls == [(1, 3), (2, 3), (3, 3)]
    assert det.read_notes == notes(joints_missing_negative_confidence=1,
                                   max_confidence_read=pytest.approx(0.99),
                                   frames_without_people=1)


def test_mmpose_malformed_still_refused(tmp_path):
    inst = mmpose_instance(500.0, 200.0)
    inst["keypoints"][4][1] = math.nan                 # MMPose writes no NaN
    path = write(tmp_path / "p.json", json.dumps([{"frame_id": 3, "instances": [inst]}]))
    expect_error([path, "frame 3", "instances", "non-finite y", "person 0, joint 4"],
                 read_keypoints, path)
    folder = tmp_path / "predictions"
    write(folder / "000001.json", json.dumps([mmpose_instance(500.0, 200.0)]))
    bad = write(folder / "000002.json", json.dumps({"version": 1.3, "people": []}))
    expect_error([bad, "mixes formats"], read_keypoints, folder)
    # a folder of whole-video prediction files is no per-image folder
    video = tmp_path / "videos"
    write(video / "a.json", json.dumps([{"frame_id": 0, "instances": []}]))
    expect_error([video, "a.json", "one predictions file"], read_keypoints, video)


# ----------------------------------------------------------------------------- npz

def test_npz_counts_clipped_scores(tmp_path):
    real = np.full((2, 17, 3), 0.5)
    real[0, 3, 2] = 1.2
    real[1, 4] = [np.nan, np.nan, 0.0]
    np.savez(tmp_path / "p.npz", real=real, mirror=np.full((2, 17, 3), 0.5))
    back = read_keypoints(tmp_path / "p.npz")
    assert back.real[0, 3, 2] == 1.0
    assert back.read_notes == notes(joints_missing_zero_confidence=1,
                                    scores_clipped_above_1=1, max_confidence_read=1.2)


def test_writers_then_readers_count_only_zeros(tmp_path):
    """What mirrorgraph writes is read back with nothing but joints of confidence 0."""
    scene = make_scene(frames=12, seed=4, skeleton="BODY_25", missing_rate=0.1)
    paths = write_scene(scene, tmp_path, formats=("mmpose", "openpose", "easymocap"))
    for fmt in ("mmpose", "openpose", "easymocap"):
        n = read_keypoints(paths[fmt], skeleton="BODY_25").read_notes
        assert n.joints_missing_zero_confidence > 0, fmt
        assert n == notes(joints_missing_zero_confidence=n.joints_missing_zero_confidence,
                          max_confidence_read=n.max_confidence_read), fmt
        assert n.max_confidence_read <= 1.0 and n.summary() == ""


# ----------------------------------------------------------------------------- end to end

def mirrored_human_scene(tmp_path: Path, frames: int = 300, seed: int = 11):
    """A synthetic scene written as EasyMocap annots, then edited into Mirrored-Human's
    shape: 8 % of the joints ``[0, 0, -1]``, the reflection's feet ``[0, 0, -1]`` in every
    tenth frame, 3 % of the confidences 1.02, 7-number boxes, ``area``."""
    scene = make_scene(frames=frames, seed=seed, skeleton="BODY_25")
    paths = write_scene(scene, tmp_path, formats=("easymocap",))
    rng = np.random.default_rng(seed)
    negative = clipped = 0
    for i, file in enumerate(sorted(paths["easymocap"].iterdir())):
        doc = json.loads(file.read_text())
        for annot in doc["annots"]:
            kp = np.asarray(annot["keypoints"], float)
            seen = kp[:, 2] > 0
            drop = seen & (rng.random(len(kp)) < 0.08)
            if i % 10 == 0:
                drop[19:25] |= seen[19:25]
            high = seen & ~drop & (rng.random(len(kp)) < 0.03)
            kp[drop] = [0.0, 0.0, -1.0]
            kp[high, 2] = 1.02
            negative += int(drop.sum())
            clipped += int(high.sum())
            annot["keypoints"] = kp.tolist()
            annot["bbox"] = [*annot["bbox"][:4], 1.0, 1.0, 0.0]
            annot["area"] = 1000.0
        file.write_text(json.dumps(doc, indent=4))
    return scene, paths, negative, clipped


def test_mirrored_human_like_scene_calibrates(tmp_path):
    scene, paths, negative, clipped = mirrored_human_scene(tmp_path)
    assert negative > 1000 and clipped > 100
    det = read_keypoints(paths["easymocap"], skeleton="BODY_25")
    assert det.read_notes.joints_missing_negative_confidence == negative
    assert det.read_notes.scores_clipped_above_1 == clipped
    assert det.read_notes.max_confidence_read == pytest.approx(1.02)
    run = mg.calibrate(paths["easymocap"], mg.load_intrinsics(paths["camera"]),
                       mg.CalibrateOptions(refine=False))
    assert normal_angle_deg(run.calibration.normal, scene.normal) < 0.5


def test_mirrored_human_like_scene_cli(tmp_path, capsys):
    scene, paths, _, _ = mirrored_human_scene(tmp_path, frames=200, seed=5)
    out = tmp_path / "calibration.json"
    code = main(["calibrate", str(paths["easymocap"]), "--intrinsics", str(paths["camera"]),
                 "--out", str(out), "--skeleton", "BODY_25"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "error" not in err
    cal = json.loads(out.read_text())
    assert normal_angle_deg(np.asarray(cal["mirror"]["normal"]), scene.normal) < 0.5
    assert cal["refined"] is True
