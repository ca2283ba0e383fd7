"""Tests of the synthetic scene generator (mirrorgraph.synth)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from mirrorgraph.skeletons import BODY_25, COCO_17, COCO_18
from mirrorgraph.synth import SyntheticScene, make_scene, read_ground_truth, write_scene
from mirrorgraph.synth.body import make_body

ALL_RATES = dict(outlier_rate=0.1, lr_swap_rate=0.2, missing_rate=0.1,
                 single_person_rate=0.1, extra_person_rate=0.2)


@pytest.fixture(scope="module")
def noisy() -> SyntheticScene:
    return make_scene(frames=3000, seed=11, skeleton="BODY_25", **ALL_RATES)


@pytest.fixture(scope="module")
def exact() -> SyntheticScene:
    """No noise at all, but swaps: observations equal the clean points."""
    return make_scene(frames=300, seed=4, noise_mean=0.0, noise_std=0.0, lr_swap_rate=0.3)


def _people_equal(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))


def test_same_seed_same_scene_other_seed_other_scene():
    kw = dict(frames=200, skeleton="COCO_18", **ALL_RATES)
    a, b, c = make_scene(seed=3, **kw), make_scene(seed=3, **kw), make_scene(seed=4, **kw)
    for name in ("K", "normal", "joints3d", "real_clean", "mirror_clean", "outlier_mask_real",
                 "outlier_mask_mirror", "lr_swapped", "real_observed", "mirror_observed"):
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name
    assert a.distance == b.distance and a.subject_height == b.subject_height
    assert _people_equal(a.detections.people, b.detections.people)
    assert not np.allclose(a.joints3d, c.joints3d)
    assert not np.allclose(a.normal, c.normal)


@pytest.mark.parametrize("skeleton", [COCO_17, BODY_25, COCO_18])
def test_bones_rigid_and_left_right_symmetric(skeleton):
    s = make_scene(frames=600, seed=7, skeleton=skeleton.name)
    assert s.joints3d.shape == (600, skeleton.num_joints, 3)
    ij = skeleton.bone_index
    lengths = np.linalg.norm(s.joints3d[:, ij[:, 0]] - s.joints3d[:, ij[:, 1]], axis=-1)
    assert np.ptp(lengths, axis=0).max() < 1e-9
    by_name = dict(zip(skeleton.bone_names, lengths[0]))
    for left, right in skeleton.symmetric_bones:
        assert abs(by_name[left] - by_name[right]) < 1e-9
    # lengths are those of the body model, scaled by the subject's height
    expected = s.body.bone_lengths(skeleton, s.subject_height)
    for name, value in by_name.items():
        assert value == pytest.approx(expected[name], rel=1e-9)
    # and within a few percent of the anthropometric table (Winter 2009)
    from mirrorgraph.anthropometry import expected_bone_lengths
    table = expected_bone_lengths(skeleton, s.subject_height)
    for name, value in by_name.items():
        assert value == pytest.approx(table[name], rel=0.12)


def test_body_is_symmetric_and_of_the_given_height():
    body = make_body(np.random.default_rng(0))
    assert body.stature == pytest.approx(1.0, abs=1e-12)
    for pt in body.foot.values():
        assert pt.shape == (3,)
    s = make_scene(frames=300, seed=2, skeleton="BODY_25", subject_height=1.80)
    j = {n: i for i, n in enumerate(s.skeleton.joints)}
    X = s.joints3d
    # the eyes, ears, toes and heels of both sides lie at equal distances from the
    # neck / mid-hip / ankle they hang on, at every frame
    for a, b, ref in (("left_eye", "right_eye", "neck"), ("left_ear", "right_ear", "neck"),
                      ("left_heel", "right_heel", None), ("left_big_toe", "right_big_toe", None)):
        if ref is None:
            da = np.linalg.norm(X[:, j[a]] - X[:, j["left_ankle"]], axis=-1)
            db = np.linalg.norm(X[:, j[b]] - X[:, j["right_ankle"]], axis=-1)
        else:
            da = np.linalg.norm(X[:, j[a]] - X[:, j[ref]], axis=-1)
            db = np.linalg.norm(X[:, j[b]] - X[:, j[ref]], axis=-1)
        assert np.abs(da - db).max() < 1e-9
        assert np.ptp(da) < 1e-9
    # the person is roughly as tall as asked: head above floor ~ height when upright
    up = s.placement["R_body"] @ np.array([0.0, 1.0, 0.0])
    heights = (X - s.placement["origin"]) @ up
    assert 1.5 < heights[:, j["nose"]].max() < 1.80
    assert heights[:, [j["left_heel"], j["right_heel"]]].min() > -1e-6


def test_clean_projections_match_independent_recomputation():
    s = make_scene(frames=400, seed=5, skeleton="COCO_17")
    X = s.joints3d.reshape(-1, 3)
    img, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), s.K, None)
    assert np.allclose(img.reshape(s.real_clean.shape), s.real_clean, atol=1e-6)
    # reflection by the Householder formula ...
    n, d = s.normal, s.distance
    assert np.linalg.norm(n) == pytest.approx(1.0) and d > 0
    S = X - 2 * (X @ n - d)[:, None] * n
    img, _ = cv2.projectPoints(S, np.zeros(3), np.zeros(3), s.K, None)
    assert np.allclose(img.reshape(s.mirror_clean.shape), s.mirror_clean, atol=1e-6)
    # ... and through the virtual camera: S(X) = D (R X + t)
    R, t = s.virtual_R, s.virtual_t
    assert np.allclose(R @ R.T, np.eye(3)) and np.linalg.det(R) == pytest.approx(1.0)
    V = (X @ R.T + t) @ s.D.T
    h = V @ s.K.T
    assert np.allclose((h[:, :2] / h[:, 2:]).reshape(s.mirror_clean.shape), s.mirror_clean,
                       atol=1e-6)
    assert s.intrinsics.image_size == s.image_size and np.array_equal(s.intrinsics.K, s.K)


@pytest.mark.parametrize("seed", range(6))
def test_everything_visible_in_front_of_camera_and_mirror(seed):
    s = make_scene(frames=500, seed=seed)
    w, h = s.image_size
    for P in (s.real_clean, s.mirror_clean):
        assert np.all(P[..., 0] > 0) and np.all(P[..., 0] < w)
        assert np.all(P[..., 1] > 0) and np.all(P[..., 1] < h)
        margin = s.placement["margin_px"]
        assert np.all(P >= margin - 1e-6)
        assert np.all(P[..., 0] <= w - margin + 1e-6) and np.all(P[..., 1] <= h - margin + 1e-6)
    X = s.joints3d
    assert np.all(X[..., 2] > 0)
    assert np.all(s.reflect(X)[..., 2] > 0)
    assert np.all(X @ s.normal < s.distance)
    assert 1.55 <= s.subject_height <= 1.95 and 2.5 <= s.distance <= 4.5
    angle = np.degrees(np.arccos(s.normal[2]))
    assert 10 <= angle <= 60


def test_options_are_obeyed_and_motion_is_smooth():
    s = make_scene(frames=900, seed=9, mirror_angle_deg=25.0, mirror_distance=4.0,
                   subject_height=1.70, image_size=(1280, 720), fov_deg=70.0)
    assert np.degrees(np.arccos(s.normal[2])) == pytest.approx(25.0)
    assert s.distance == 4.0 and s.subject_height == 1.70 and s.image_size == (1280, 720)
    assert s.K[0, 0] == pytest.approx(640 / np.tan(np.radians(35)))
    assert abs(s.K[0, 2] - 640) <= 4 and abs(s.K[1, 2] - 360) <= 4
    step = np.linalg.norm(np.diff(s.joints3d, axis=0), axis=-1)
    assert step.max() < 0.15                       # m per frame at 30 fps: no jumps
    acc = np.linalg.norm(np.diff(s.joints3d, 2, axis=0), axis=-1)
    assert acc.max() < 0.08
    # the person moves: squats, arm raises, turning
    assert np.ptp(s.joints3d, axis=0).max() > 0.5


def test_impossible_placement_is_refused():
    with pytest.raises(ValueError, match="cannot place"):
        make_scene(frames=30, seed=0, mirror_distance=0.8, subject_height=1.9,
                   mirror_angle_deg=10.0)
    with pytest.raises(ValueError):
        make_scene(frames=10, outlier_rate=1.5)


def test_noise_statistics():
    s = make_scene(frames=2000, seed=21)
    r = np.concatenate([(s.real_observed[..., :2] - s.real_clean).ravel(),
                        (s.mirror_observed[..., :2] - s.mirror_clean).ravel()])
    assert len(r) == 2000 * 17 * 2 * 2
    assert r.mean() == pytest.approx(0.076, abs=0.03)
    assert r.std() == pytest.approx(4.0, rel=0.02)
    assert np.all(np.isfinite(r))
    conf = s.real_observed[..., 2]
    assert conf.min() >= 0.3 and conf.max() <= 1.0 and 0.7 < conf.mean() < 0.95
    # what the detector outputs is these observations: two people in every frame
    assert all(p.shape == (2, 17, 3) for p in s.detections.people)


def test_rates_of_outliers_swaps_missing_and_people(noisy):
    s = noisy
    T, J = s.joints3d.shape[:2]
    observed_r, observed_m = ~s.missing_real, ~s.missing_mirror
    out_rate = (s.outlier_mask_real.sum() + s.outlier_mask_mirror.sum()) / (
        observed_r.sum() + observed_m.sum())
    assert out_rate == pytest.approx(0.1, abs=0.01)
    # outliers are 30-150 px from the truth, inliers within noise
    for obs, img, mask, seen in ((s.real_observed, s.real_image, s.outlier_mask_real, observed_r),
                                 (s.mirror_observed, s.mirror_image, s.outlier_mask_mirror,
                                  observed_m)):
        err = np.linalg.norm(obs[..., :2] - img, axis=-1)
        w, h = s.image_size
        inside = np.all((obs[..., :2] > 0) & (obs[..., :2] < [w - 1, h - 1]), -1)
        e_out = err[mask & inside]
        assert e_out.min() >= 30 - 1e-9 and e_out.max() <= 150 + 1e-9
        assert err[seen & ~mask].max() < 8 * 4.0
        # outliers have lower confidence on average, but not separably
        c_in, c_out = obs[seen & ~mask, 2], obs[mask, 2]
        assert c_out.mean() < c_in.mean() - 0.1
        assert c_out.max() > c_in.min() + 0.3
    # missing: 10 % of joint observations, plus one person in 10 % of the frames
    miss = np.concatenate([s.missing_real, s.missing_mirror])
    assert miss.mean() == pytest.approx(1 - 0.9 * 0.95, abs=0.01)
    single = s.real_detected ^ s.mirror_detected
    assert np.all(np.isnan(s.real_observed[s.missing_real][:, :2]))
    assert np.all(s.real_observed[s.missing_real][:, 2] == 0)
    assert single.mean() == pytest.approx(0.1 + 2 * 0.02, abs=0.03)
    # swaps in ~20 % of the frames where the reflection is seen
    assert s.lr_swapped[s.mirror_detected].mean() == pytest.approx(0.2, abs=0.03)
    assert not s.lr_swapped[~s.mirror_detected].any()
    assert s.extra_person.mean() == pytest.approx(0.2, abs=0.03)
    counts = np.array([len(p) for p in s.detections.people])
    assert np.array_equal(counts, s.real_detected.astype(int) + s.mirror_detected
                          + s.extra_person)
    # bystanders lie whole inside the image
    w, h = s.image_size
    allp = np.concatenate(s.detections.people)
    xy = allp[allp[..., 2] > 0][:, :2]
    assert np.all(xy >= 0) and np.all(xy[:, 0] <= w - 1) and np.all(xy[:, 1] <= h - 1)
    assert np.all((allp[..., 2] == 0) == np.isnan(allp[..., 0]))


def test_people_come_in_random_order(noisy):
    s = noisy
    first_is_real = []
    for t, people in enumerate(s.detections.people[:500]):
        if len(people) == 2 and s.real_detected[t] and s.mirror_detected[t]:
            first_is_real.append(np.array_equal(people[0], s.real_observed[t], equal_nan=True))
    assert 0.35 < np.mean(first_is_real) < 0.65


def test_reflection_is_labelled_flipped_by_the_detector(exact):
    s = exact
    sk = s.skeleton
    lw, rw = sk.index("left_wrist"), sk.index("right_wrist")
    seen_plain = seen_swapped = False
    for t in range(len(s)):
        people = s.detections.people[t]
        assert len(people) == 2
        is_real = [np.allclose(p[:, :2], s.real_clean[t]) for p in people]
        assert sum(is_real) == 1
        refl = people[is_real.index(False)]
        if s.lr_swapped[t]:
            assert np.allclose(refl[lw, :2], s.mirror_clean[t, lw])
            seen_swapped = True
        else:
            # the detector's left wrist of the reflection images the real right wrist
            assert np.allclose(refl[lw, :2], s.mirror_clean[t, rw])
            assert np.allclose(refl[:, :2], s.mirror_clean[t][sk.flip])
            seen_plain = True
    assert seen_plain and seen_swapped


def test_paired_is_the_perfect_pairing(noisy, exact):
    p = exact.paired()
    assert np.allclose(p.real[..., :2], exact.real_clean)
    assert np.allclose(p.mirror[..., :2], exact.mirror_clean)     # swaps fixed
    assert p.lr_fixes == exact.lr_swapped.sum() > 0
    raw = exact.paired(fix_lr=False)
    sw = exact.lr_swapped
    assert np.allclose(raw.mirror[sw][..., :2], exact.mirror_clean[sw][:, exact.skeleton.flip])
    assert np.allclose(raw.mirror[~sw][..., :2], exact.mirror_clean[~sw])

    s = noisy
    p = s.paired()
    assert p.real.shape == p.mirror.shape == (len(s), s.skeleton.num_joints, 3)
    assert np.array_equal(p.frame_ids, s.frame_ids) and p.image_size == s.image_size
    ok = p.valid() & ~s.outlier_mask_real & ~s.outlier_mask_mirror
    assert ok.mean() > 0.5
    assert np.abs(p.real[..., :2] - s.real_clean)[ok].max() < 8 * 4.0
    assert np.abs(p.mirror[..., :2] - s.mirror_clean)[ok].max() < 8 * 4.0
    assert np.all(p.real[~s.real_detected][..., 2] == 0)
    assert np.all(p.mirror[~s.mirror_detected][..., 2] == 0)


def test_distortion_is_opencv_consistent():
    dist = np.array([-0.25, 0.08, 0.001, -0.0015, -0.01])
    s = make_scene(frames=200, seed=6, distortion=dist, noise_mean=0.0, noise_std=0.0)
    assert np.array_equal(s.dist, dist)
    img, _ = cv2.projectPoints(s.joints3d.reshape(-1, 3), np.zeros(3), np.zeros(3), s.K, dist)
    assert np.allclose(img.reshape(s.real_image.shape), s.real_image, atol=1e-6)
    obs = s.real_observed[..., :2]
    assert np.allclose(obs, s.real_image)
    assert not np.allclose(obs, s.real_clean, atol=1.0)
    und = s.intrinsics.undistort_points(np.concatenate([obs, s.mirror_observed[..., :2]]))
    assert np.allclose(und, np.concatenate([s.real_clean, s.mirror_clean]), atol=1e-4)


def test_write_scene_and_read_back(tmp_path):
    from mirrorgraph.intrinsics import load_intrinsics
    from mirrorgraph.io import read_keypoints

    s = make_scene(frames=40, seed=8, skeleton="BODY_25", distortion=[-0.1, 0.01, 0, 0, 0],
                   **ALL_RATES)
    paths = write_scene(s, tmp_path)
    for name in ("mmpose", "openpose", "easymocap", "npz", "camera", "ground_truth",
                 "joints3d"):
        assert paths[name].exists(), name
    assert paths["mmpose"].name == "keypoints_mmpose.json" and paths["openpose"].is_dir()

    for fmt in ("mmpose", "openpose", "easymocap"):
        det = read_keypoints(paths[fmt])
        assert det.skeleton.name == "BODY_25"
        got = {int(f): p for f, p in zip(det.frame_ids, det.people)}
        for t, people in zip(s.frame_ids, s.detections.people):
            q = got.get(int(t), np.zeros((0, 25, 3)))
            assert q.shape == people.shape, (fmt, t)
            seen = people[..., 2] > 0
            assert np.array_equal(q[..., 2] > 0, seen), (fmt, t)
            assert np.allclose(q[seen], people[seen], atol=1e-3), (fmt, t)

    paired = read_keypoints(paths["npz"])          # flipped on reading
    raw = s.paired(fix_lr=False)
    assert np.allclose(paired.mirror, raw.mirror, equal_nan=True)
    assert np.allclose(paired.real, raw.real, equal_nan=True)

    intr = load_intrinsics(paths["camera"])
    assert np.allclose(intr.K, s.K) and intr.image_size == s.image_size
    assert np.allclose(intr.dist, s.dist)

    gt = read_ground_truth(tmp_path)
    assert np.allclose(gt["normal"], s.normal) and gt["distance"] == pytest.approx(s.distance)
    assert np.allclose(gt["R"], s.virtual_R) and np.allclose(gt["t"], s.virtual_t)
    assert np.allclose(gt["K"], s.K) and np.allclose(gt["joints3d"], s.joints3d)
    assert list(gt["joint_names"]) == list(BODY_25.joints)
    assert gt["skeleton"] == "BODY_25" and gt["frames"] == 40 and gt["seed"] == 8
    assert gt["options"]["outlier_rate"] == 0.1 and gt["subject_height"] == s.subject_height
    assert read_ground_truth(paths["ground_truth"])["fps"] == 30.0


def test_write_scene_without_distortion_omits_dist(tmp_path):
    import json
    s = make_scene(frames=5, seed=1)
    paths = write_scene(s, tmp_path, formats=("npz",))
    assert set(paths) == {"npz", "camera", "ground_truth", "joints3d"}
    cam = json.loads(paths["camera"].read_text())
    assert "dist" not in cam and cam["image_size"] == [1920, 1080]


def test_population_bodies_spread_each_segment_as_adults_do():
    # the same draws, each kind scaled by its own spread among adults: the widths twice
    # the femur's, and make_scene changes the body only (camera, mirror, noise the same)
    from mirrorgraph.anthropometry import HEIGHT_FRACTION_CV
    from mirrorgraph.synth.body import POPULATION_VARIATION

    a = make_body(np.random.default_rng(5))
    b = make_body(np.random.default_rng(5), variation="population")
    for kind in ("femur", "hip_width", "shoulder_width"):
        za = (a.factors[kind] - 1.0) / 0.03
        assert (b.factors[kind] - 1.0) == pytest.approx(za * HEIGHT_FRACTION_CV[kind], abs=1e-12)
    assert POPULATION_VARIATION["hip_width"] == HEIGHT_FRACTION_CV["hip_width"] == 0.06
    assert b.stature == pytest.approx(1.0, abs=1e-12)
    factors = np.array([[make_body(np.random.default_rng(k), variation="population").factors[w]
                         for w in ("femur", "hip_width")] for k in range(400)])
    spread = factors.std(0)
    assert 0.02 < spread[0] < 0.03 and 0.045 < spread[1] < 0.06      # clipped at 2 std
    s0 = make_scene(frames=20, seed=3)
    s1 = make_scene(frames=20, seed=3, body_variation="population")
    assert np.array_equal(s0.K, s1.K) and np.array_equal(s0.normal, s1.normal)
    assert s1.options["body_variation"] == "population" and "body_variation" not in s0.options
    assert not np.allclose(s0.joints3d, s1.joints3d)
    with pytest.raises(ValueError, match="population"):
        make_body(np.random.default_rng(0), variation="wide")
