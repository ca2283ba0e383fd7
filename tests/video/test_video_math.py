"""The video path's math without a model: anchors, decoding, NMS, crops, heat maps,
detection views, pose NMS (keypoint similarity, boxes, on-body), box tracking, the
Qualisys reader and the BlazePose layout."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.io.motion import trc_marker_name
from mirrorgraph.io.qualisys import read_qca
from mirrorgraph.skeletons import BLAZEPOSE, skeleton_for_count
from mirrorgraph.synth.mirror_clip import MirrorComposite, mirror_homography
from mirrorgraph.video.blazepose import (crop_matrix, decode_detections, refine_from_heatmap,
                                         roi_from_keypoints, ssd_anchors, weighted_nms)
from mirrorgraph.video.rtm import BoxTracker
from mirrorgraph.video.nms import (BLAZEPOSE_SIGMAS, on_body_matrix, oks_matrix, pose_boxes,
                                   pose_nms)
from mirrorgraph.video.track import detection_views, same_body


def test_anchor_layout_of_the_pose_detector():
    a = ssd_anchors()
    assert a.shape == (2254, 2)                         # the model's output count
    np.testing.assert_allclose(a[0], [0.5 / 28, 0.5 / 28])
    np.testing.assert_allclose(a[1], a[0])              # two anchors a cell at stride 8
    np.testing.assert_allclose(a[2], [1.5 / 28, 0.5 / 28])   # row-major cells
    np.testing.assert_allclose(a[1568], [0.5 / 14, 0.5 / 14])  # stride 16 starts after 28*28*2
    np.testing.assert_allclose(a[-6:], np.full((6, 2), 6.5 / 7))  # 3 merged layers, 6 a cell


def test_decoding_and_weighted_nms():
    anchors = np.array([[0.5, 0.5], [0.5, 0.5], [0.2, 0.3]])
    raw = np.zeros((3, 12))
    raw[0, :4] = [0, 0, 44.8, 44.8]                     # a 0.2-wide box on the anchor
    raw[1, :4] = [2.24, 0, 44.8, 44.8]                  # the same, shifted 0.01
    raw[2, :4] = [0, 0, 22.4, 22.4]
    raw[:, 4:6] = [22.4, -22.4]                         # keypoint 0: +0.1, -0.1
    scores = np.array([3.0, 1.0, 0.5, ])
    boxes, kps, s = decode_detections(raw, scores, anchors, min_score=0.5)
    assert len(s) == 3
    np.testing.assert_allclose(boxes[0], [0.4, 0.4, 0.6, 0.6])
    np.testing.assert_allclose(kps[2, 0], [0.3, 0.2])
    b, k, s2 = weighted_nms(boxes, kps, s, iou_threshold=0.3)
    assert len(s2) == 2                                 # the two overlapping boxes merged
    w = s[:2] / s[:2].sum()
    np.testing.assert_allclose(b[0], w @ boxes[:2])     # score-weighted mean
    assert s2[0] == pytest.approx(s[0])                 # the best one's score
    np.testing.assert_allclose(b[1], boxes[2])
    # below the threshold nothing is decoded
    assert len(decode_detections(raw, np.full(3, -5.0), anchors)[2]) == 0


def test_roi_and_crop_follow_the_body_axis():
    hip = np.array([[500.0, 600.0]])
    up = roi_from_keypoints(hip, hip + [0, -200])[0]     # body circle point straight up
    np.testing.assert_allclose(up, [500, 600, 2 * 200 * 1.25, 0], atol=1e-9)
    right = roi_from_keypoints(hip, hip + [200, 0])[0]   # lying, head to the right
    assert right[3] == pytest.approx(np.pi / 2)
    M = crop_matrix(right, 256)
    centre = M @ [128, 128, 1]
    top = M @ [128, 0, 1]                                # the crop's top edge, middle
    np.testing.assert_allclose(centre, [500, 600])
    np.testing.assert_allclose(top, [500 + 250, 600], atol=1e-9)   # towards the head


def test_heatmap_refinement_moves_only_confident_landmarks():
    hm = np.full((64, 64, 2), -20.0)
    rows, cols = np.mgrid[0:64, 0:64]
    hm[..., 0] = 8.0 - ((rows - 30) ** 2 + (cols - 20) ** 2)   # a peak at column 20, row 30
    hm[..., 1] = -3.0                                            # nothing confident
    xy = np.array([[21.5 / 64, 29.5 / 64], [0.4, 0.4]])
    out = refine_from_heatmap(xy, hm)
    np.testing.assert_allclose(out[0], [20 / 64, 30 / 64], atol=2e-3)
    np.testing.assert_allclose(out[1], xy[1])
    outside = refine_from_heatmap(np.array([[1.2, 0.5], [0.5, 0.5]]), hm)
    np.testing.assert_allclose(outside[0], [1.2, 0.5])


def test_detection_views_cover_the_frame():
    for w, h in ((1920, 1080), (1080, 1920), (640, 480)):
        views = detection_views(w, h, flip=True, tiles=True)
        assert views[0] == (False, (0, 0, w, h)) and views[1] == (True, (0, 0, w, h))
        covered = np.zeros((h, w), bool)
        for _, (x0, y0, x1, y1) in views[2:]:
            assert 0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h and x1 - x0 == y1 - y0
            covered[y0:y1, x0:x1] = True
        assert covered.all()
    assert len(detection_views(1920, 1080, flip=False, tiles=True)) == 7


def test_box_tracker_keeps_ids_through_motion_and_gaps():
    tr = BoxTracker()
    a, b = np.array([0, 0, 10, 20.0]), np.array([50, 0, 60, 20.0])
    ids0 = tr.step(np.stack([a, b]), 0)
    ids1 = tr.step(np.stack([b + [1, 0, 1, 0], a + [1, 0, 1, 0]]), 1)   # order swapped
    np.testing.assert_array_equal(ids1, ids0[::-1])
    tr.step(np.zeros((0, 4)), 2)                                         # nobody
    ids3 = tr.step(np.stack([a + [2, 0, 2, 0]]), 3)
    assert ids3[0] == ids0[0]
    ids4 = tr.step(np.stack([a + [200, 0, 200, 0]]), 4)                  # somewhere else
    assert ids4[0] not in ids0


def test_blazepose_layout():
    assert BLAZEPOSE.num_joints == 33 and skeleton_for_count(33) is BLAZEPOSE
    spots = {0: "nose", 2: "left_eye", 5: "right_eye", 9: "left_mouth", 11: "left_shoulder",
             16: "right_wrist", 23: "left_hip", 28: "right_ankle", 29: "left_heel",
             32: "right_big_toe"}
    for i, name in spots.items():
        assert BLAZEPOSE.joints[i] == name
    f = BLAZEPOSE.flip
    assert BLAZEPOSE.joints[f[9]] == "right_mouth" and f[0] == 0
    assert set(BLAZEPOSE.bones) >= {"left_femur", "right_ulna", "shoulder_width", "hip_width"}
    # Pose2Sim's marker names of its BLAZEPOSE tree (its "Lknee" spelled as the others)
    if importlib.util.find_spec("anytree") and importlib.util.find_spec("Pose2Sim"):
        from Pose2Sim.skeletons import BLAZEPOSE as P2S
        from anytree import PreOrderIter
        named = [(n.id, n.name) for n in PreOrderIter(P2S) if n.id is not None]
        assert len(named) >= 20
        for idx, name in named:
            assert trc_marker_name(BLAZEPOSE.joints[idx]).lower() == name.lower(), (idx, name)


def _pose2sim_root() -> Path:
    spec = importlib.util.find_spec("Pose2Sim")
    if spec is None:
        pytest.skip("pose2sim is not installed (the test command installs it with --no-deps)")
    return Path(list(spec.submodule_search_locations)[0])


def test_qualisys_reader_on_the_demo_calibration(tmp_path):
    cams = read_qca(_pose2sim_root() / "Demo_SinglePerson" / "calibration" / "Calib.qca.txt")
    assert list(cams) == ["cam01", "cam02", "cam03", "cam04"]
    c = cams["cam01"]
    np.testing.assert_allclose(c.centre, [1.4602323709212087, -1.9091590482454608,
                                          1.8965058524092062])
    np.testing.assert_allclose(c.K[0, 0], 107599.671875 / 64)
    assert c.size == (1088, 1920)
    np.testing.assert_allclose(c.R @ c.R.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(c.R) == pytest.approx(1.0)
    # every camera looks at the middle of the capture volume (in front, inside the image)
    for cam in cams.values():
        p = cam.projection @ [0.0, 0.0, 1.0, 1.0]
        assert p[2] > 0 and 0 < p[0] / p[2] < cam.size[0] and 0 < p[1] / p[2] < cam.size[1]
    bad = tmp_path / "bad.qca.txt"
    bad.write_text("<calibration><cameras><camera serial='c'><fov_video left='0' top='0' "
                   "right='9' bottom='9'/></camera></cameras></calibration>")
    with pytest.raises(InputError, match="c.transform"):
        read_qca(bad)


def test_mirror_homography_keeps_pixels_on_lines_through_the_epipole():
    K = np.array([[800.0, 0, 400], [0, 800, 300], [0, 0, 1]])
    n = np.array([np.sin(1.2), 0.1, np.cos(1.2)])
    n /= np.linalg.norm(n)
    H = mirror_homography(K, n, 1.5, 3.0)
    e = K @ n
    for x in ([100.0, 200, 1], [350, 500, 1], [700, 50, 1]):
        y = H @ x
        assert abs(np.linalg.det(np.stack([np.asarray(x), y, e]))) < 1e-6 * np.linalg.norm(y) \
            * np.linalg.norm(e) * np.linalg.norm(x)
    comp = MirrorComposite()
    p = np.array([[100.0, 200.0]])
    back = comp.to_reflection(comp.to_person(p), 1080)
    np.testing.assert_allclose(back, [[(1079 - 100) * 0.4 + 1200, 200 * 0.4 + 140]])


#: A standing person's BlazePose landmarks, in heights (x right of the mid-hip, y up).
_STICK = {"nose": (0.0, 0.90), "eye_inner": (0.02, 0.92), "eye": (0.03, 0.92),
          "eye_outer": (0.04, 0.92), "ear": (0.06, 0.91), "mouth": (0.02, 0.87),
          "shoulder": (0.12, 0.80), "elbow": (0.16, 0.62), "wrist": (0.18, 0.46),
          "pinky": (0.19, 0.42), "index": (0.18, 0.41), "thumb": (0.16, 0.43),
          "hip": (0.08, 0.50), "knee": (0.09, 0.27), "ankle": (0.09, 0.05),
          "heel": (0.08, 0.02), "big_toe": (0.12, 0.0)}


def _person(x: float, y_feet: float, height: float) -> np.ndarray:
    """``(33, 2)`` image px of a standing person (the person's left on the image's right,
    as a person facing the camera), feet at ``y_feet``."""
    out = np.zeros((33, 2))
    for j, name in enumerate(BLAZEPOSE.joints):
        side, _, part = name.partition("_")
        if name == "nose":
            side, part = "", "nose"
        dx, up = _STICK[part]
        out[j] = [x + (dx if side == "left" else -dx) * height, y_feet - up * height]
    return out


def test_object_keypoint_similarity_is_cocos():
    """OKS of a pose and the same pose moved by d px at every keypoint is, by COCO's
    definition, mean_i exp(-d^2 / (2 s^2 (2 sigma_i)^2)) with s^2 the (mean) box area;
    1 for the same pose, ~0 for another person beside it; labels swapped left/right
    count as the same pose only with ``flip``."""
    a = _person(300, 900, 600)
    vis = np.ones((3, 33))
    d = 12.0
    b = a + [d / np.sqrt(2), d / np.sqrt(2)]
    c = _person(800, 900, 600)
    o = oks_matrix(np.stack([a, b, c]), vis)
    box = pose_boxes(a[None], vis[:1])[0]
    area = (box[2] - box[0]) * (box[3] - box[1])
    expect = np.mean(np.exp(-d ** 2 / (2 * area * (2 * BLAZEPOSE_SIGMAS) ** 2)))
    assert o[0, 1] == pytest.approx(expect, rel=1e-9) and 0.5 < expect < 0.95
    np.testing.assert_allclose(np.diag(o), 1.0)
    np.testing.assert_allclose(o, o.T)
    assert o[0, 2] < 1e-3
    swapped = a[BLAZEPOSE.flip]
    plain = oks_matrix(np.stack([a, swapped]), vis[:2])[0, 1]
    flipped = oks_matrix(np.stack([a, swapped]), vis[:2], flip=BLAZEPOSE.flip)[0, 1]
    assert plain < 0.5 and flipped == pytest.approx(1.0)
    # only keypoints both see count: a pose wrong where one of them is unseen
    wrong = a.copy()
    wrong[25:] += 200                                      # legs off by 200 px
    v = np.ones((2, 33))
    v[1, 25:] = 0.1                                        # ... and unseen
    assert oks_matrix(np.stack([a, wrong]), v)[0, 1] == pytest.approx(1.0)


def test_pose_nms_keeps_one_skeleton_per_person():
    """A person with three duplicates (jittered, labels swapped left/right, labels
    scrambled on the upper body as from a crop turned the wrong way), their reflection (mirror
    image, 0.8x, beside them) and a bystander half overlapping them: one skeleton each
    for the person, the reflection and the bystander, the first of each kept."""
    rng = np.random.default_rng(3)
    person = _person(400, 1000, 700)
    jitter = person + rng.normal(0, 4, person.shape)
    swapped = person[BLAZEPOSE.flip] + rng.normal(0, 4, person.shape)
    scrambled = person[rng.choice(25, 33)]          # upper-body points, any labels
    reflection = _person(1100, 950, 560)[BLAZEPOSE.flip]            # a mirror image
    bystander = _person(400 + 0.3 * 700, 1000, 650)
    poses = np.stack([person, jitter, swapped, scrambled, reflection, bystander])
    vis = np.ones(poses.shape[:2])
    keep = pose_nms(poses, vis, flip=BLAZEPOSE.flip)
    np.testing.assert_array_equal(keep, [0, 4, 5])
    # without the on-body test the scrambled skeleton (OKS near 0) stays
    assert 3 in pose_nms(poses, vis, flip=BLAZEPOSE.flip, on_body=None)
    # ... and, by keypoints alone (no box test), without flip the swapped one
    assert 2 in pose_nms(poses, vis, on_body=None, iou_threshold=1.0)
    assert 2 not in pose_nms(poses, vis, flip=BLAZEPOSE.flip, on_body=None, iou_threshold=1.0)
    # the order is the preference: the duplicate first is the one kept
    np.testing.assert_array_equal(pose_nms(poses[[1, 0, 4]], vis[:3], flip=BLAZEPOSE.flip),
                                  [0, 2])
    body = on_body_matrix(poses, vis, np.array([[11, 12]]))
    assert body[3, 0] == pytest.approx(1.0) and body[5, 0] < 0.85 and body[4, 0] == 0.0


def test_same_body_merges_one_person_seen_in_two_views():
    """Detector keypoints (mid-hip, body-circle point, ...) of one person from the whole
    frame and from a tile agree within a fraction of the body circle; a person beside,
    or a far smaller one at the same place, are others."""
    base = np.array([[500.0, 600], [500, 300], [500, 450], [500, 350]])
    tile = base + [12.0, -8.0]
    beside = base + [400.0, 0.0]
    small = base.copy()
    small[1] = [500, 520]                                   # radius 80 against 300
    same = same_body(np.stack([base, tile, beside, small]))
    assert same[0, 1] and same[1, 0] and not same[0, 2] and not same[0, 3]
