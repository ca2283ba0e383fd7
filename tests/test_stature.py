"""Stature from 3D joints (mirrorgraph.stature) against synthetic subjects of known height."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mirrorgraph.anthropometry import LANDMARK_HEIGHT, expected_bone_lengths
from mirrorgraph.skeletons import skeleton_by_name
from mirrorgraph.stature import estimate_stature
from mirrorgraph.synth.body import make_body, skeleton_points
from mirrorgraph.synth.motion import generate_motion


def _subject(seed: int | None, skeleton: str = "BODY_25", frames: int = 200, height: float = 1.75):
    rng = np.random.default_rng(seed if seed is not None else 0)
    body = make_body(None if seed is None else rng)
    sk = skeleton_by_name(skeleton)
    pts = skeleton_points(generate_motion(body, frames, 30.0, rng), sk) * height
    return sk, pts, np.ones(pts.shape[:2], bool), body


def test_the_average_body_measures_its_height():
    sk, pts, valid, _ = _subject(None)
    est = estimate_stature(pts, valid, sk)
    assert est is not None and est.top == "eyes"
    assert est.height == pytest.approx(1.75, rel=0.003)
    assert est.unmeasured_fraction == pytest.approx(LANDMARK_HEIGHT["ankle"] + 1 - LANDMARK_HEIGHT["eye"])


def test_individual_bodies_closer_than_limb_proportions():
    """Each segment kind varies by 3 %: the stature chain leaves only the feet and the
    head above the eyes to the population figures, the limb bones carry all of it."""
    chain, limbs = [], []
    for seed in range(20):
        sk, pts, valid, body = _subject(seed)
        chain.append(estimate_stature(pts, valid, sk).height / 1.75 - 1)
        true = body.bone_lengths(sk, 1.75)
        winter = expected_bone_lengths(sk, 1.75)
        limbs.append(sum(winter.values()) / sum(true.values()) - 1)
    chain, limbs = np.abs(chain), np.abs(limbs)
    assert np.sqrt(np.mean(chain ** 2)) < 0.5 * np.sqrt(np.mean(limbs ** 2))
    assert chain.max() < 0.01


@pytest.mark.parametrize("skeleton", ["BODY_25B", "HALPE_26"])
def test_head_top_replaces_the_eyes(skeleton):
    sk, pts, valid, _ = _subject(3, skeleton)
    est = estimate_stature(pts, valid, sk)
    assert est.top == "head_top"
    assert est.unmeasured_fraction == pytest.approx(LANDMARK_HEIGHT["ankle"])
    assert est.height == pytest.approx(1.75, rel=0.01)


def test_scales_with_the_points_and_ignores_a_few_wrong_frames():
    sk, pts, valid, _ = _subject(5)
    base = estimate_stature(pts, valid, sk).height
    assert estimate_stature(2.5 * pts, valid, sk).height == pytest.approx(2.5 * base, rel=1e-9)
    noisy = pts.copy()
    rng = np.random.default_rng(1)
    bad = rng.random(len(pts)) < 0.1
    noisy[bad] += rng.normal(0.0, 0.5, noisy[bad].shape)          # 10 % of the frames wrecked
    assert estimate_stature(noisy, valid, sk).height == pytest.approx(base, rel=0.01)


def test_nothing_to_measure_gives_none():
    sk, pts, valid, _ = _subject(6, frames=30)
    no_ankles = valid.copy()
    no_ankles[:, [sk.index("left_ankle"), sk.index("right_ankle")]] = False
    assert estimate_stature(pts, no_ankles, sk) is None
    few = valid.copy()
    few[5:] = False                                                  # 5 frames < MIN_FRAMES
    assert estimate_stature(pts, few, sk) is None
    assert estimate_stature(np.full_like(pts, np.nan), valid, sk) is None


# --------------------------------------------------------------------------- in the pipelines
def _calibrate(scene, scale_from: str):
    from mirrorgraph.graph.options import RefineOptions
    from mirrorgraph.intrinsics import Intrinsics
    from mirrorgraph.pipelines.mirror import CalibrateOptions, calibrate

    opts = CalibrateOptions(subject_height=scene.subject_height,
                            refine_options=RefineOptions(scale_from=scale_from))
    return calibrate(scene.detections, Intrinsics(K=scene.K, image_size=scene.image_size),
                     opts).calibration


def test_single_mirror_distance_in_metres_from_the_stature():
    """A subject whose limbs are 2.6 % off Winter's (seed 0): the limb gauge carries that
    into d, the stature (measured on the joints, eyes triangulated through the mirror)
    does not."""
    from mirrorgraph.synth.scene import make_scene

    scene = make_scene(frames=600, seed=0, skeleton="COCO_17")
    stat = _calibrate(scene, "stature")
    limbs = _calibrate(scene, "limbs")
    assert stat.refinement["scale_source"].startswith("stature measured from ankle to eyes")
    assert stat.refinement["stature"]["height"] == pytest.approx(scene.subject_height)
    assert "as asked" in limbs.refinement["scale_source"]
    # the limbs' scale kept: the stature measured on it, not set to the height
    assert limbs.refinement["stature"]["scale_from"] == "limbs"
    assert limbs.refinement["stature"]["height"] != pytest.approx(scene.subject_height)
    err_stature = abs(stat.distance / scene.distance - 1)
    err_limbs = abs(limbs.distance / scene.distance - 1)
    assert err_stature < 0.01
    assert err_stature < 0.5 * err_limbs
    # the same mirror: only the scale differs
    assert stat.normal == pytest.approx(limbs.normal, abs=1e-9)
    assert not any("scale:" in w for w in stat.warnings)


def test_unknown_scale_source_is_refused():
    from mirrorgraph.errors import InputError
    from mirrorgraph.graph.options import RefineOptions

    with pytest.raises(InputError, match="scale_from"):
        RefineOptions(scale_from="bones")


def test_a_leg_measured_long_on_one_side_is_the_measurements_spread():
    """The two legs of a body agree (its segments vary by kind, not by side); a detector
    that places one side's joints with a bias measures one leg long: ``side_rel_diff`` is
    ``|L - R| / (L + R)``, the spread :func:`~mirrorgraph.stature.measurement_rel_std`
    adds to the metric scale."""
    from mirrorgraph.stature import keypoint_rel_std, measurement_rel_std, unmeasured_rel_std

    sk, pts, valid, _ = _subject(3)
    est = estimate_stature(pts, valid, sk)
    assert est.side_rel_diff < 0.005
    assert measurement_rel_std(est) == pytest.approx(np.sqrt(
        est.side_rel_diff ** 2 + keypoint_rel_std(est.top) ** 2
        + unmeasured_rel_std(est.top) ** 2))
    long = pts.copy()
    hip = long[:, [sk.index("right_hip")]]
    for j in ("right_knee", "right_ankle"):                 # the right leg 30 % longer
        long[:, sk.index(j)] = hip[:, 0] + 1.3 * (long[:, sk.index(j)] - hip[:, 0])
    est = estimate_stature(long, valid, sk)
    assert est.side_rel_diff == pytest.approx(0.3 / 2.3, abs=0.01)
    assert est.scaled(2.0).side_rel_diff == est.side_rel_diff
    assert measurement_rel_std(None) == 0.0


def test_the_distance_std_holds_the_legs_disagreement():
    """A detector placing the reflection's right knee and ankle 20 px off: the legs
    measured 2.6 % apart, the distance's std widened by that spread over the height's
    prior (``height_sigma``) and the end keypoints' 2.7 % (the scale's measurement error
    the data show), and it still covers the error."""
    from mirrorgraph.keypoints import PairedKeypoints
    from mirrorgraph.synth.scene import make_scene

    s = make_scene(frames=300, seed=0, skeleton="COCO_17")
    stds = {}
    for px in (0.0, 20.0):
        m = s.mirror_observed.copy()
        for j in ("right_knee", "right_ankle"):
            m[:, s.skeleton.index(j), 0] += px
        paired = PairedKeypoints(skeleton=s.skeleton, frame_ids=s.frame_ids,
                                 real=s.real_observed, mirror=m, source="biased.npz",
                                 image_size=s.image_size)
        c = _calibrate_paired(paired, s)
        side = c.refinement["stature"]["side_rel_diff"]
        stds[px] = c.uncertainty["distance_std"] / c.distance
        assert abs(c.distance / s.distance - 1) < 2 * stds[px]
    from mirrorgraph.stature import keypoint_rel_std

    assert side > 0.01
    from mirrorgraph.graph.options import GaugeOptions

    prior = GaugeOptions().height_sigma
    assert stds[20.0] >= np.sqrt(prior ** 2 + side ** 2 + keypoint_rel_std("eyes") ** 2) - 1e-4
    assert stds[20.0] > stds[0.0] + 0.002


def _calibrate_paired(paired, scene):
    from mirrorgraph.pipelines.mirror import CalibrateOptions, calibrate

    return calibrate(paired, scene.intrinsics,
                     CalibrateOptions(subject_height=scene.subject_height)).calibration


def _legs_stretched(pts: np.ndarray, sk, factor: float) -> np.ndarray:
    """``pts`` with each knee and ankle moved away from its hip by ``factor``: both legs
    lengthened alike (``(..., 2)`` image points or ``(..., 3)`` joints)."""
    out = pts.copy()
    for side in ("left", "right"):
        hip = out[:, sk.index(f"{side}_hip")].copy()
        for j in ("knee", "ankle"):
            i = sk.index(f"{side}_{j}")
            out[:, i] = hip + factor * (out[:, i] - hip)
    return out


def test_bodies_measured_right_agree_with_the_population():
    """Twenty synthetic subjects (each segment kind 3 % off Winter's): the segments'
    heights over the chain's stay within the spread of adults and keypoints, nothing is
    added."""
    from mirrorgraph.stature import bones_rel_spread

    spreads = []
    for seed in range(20):
        sk, pts, valid, _ = _subject(seed)
        est = estimate_stature(pts, valid, sk)
        assert set(est.bone_ratios) == {"leg", "arm", "trunk", "shoulder_width", "hip_width"}
        assert bones_rel_spread(est.bone_ratios) == est.bones_rel_spread
        spreads.append(est.bones_rel_spread)
    assert sum(s > 0 for s in spreads) <= 1


def test_legs_lengthened_alike_are_the_measurements_spread():
    """Both legs 40 % long (a detector's bias the legs' difference cannot see): the stature
    comes out ~22 % long, the legs agree, and the segments' disagreement (legs long against
    arms, widths and trunk) holds the error; 20 % long (stature +11 %) stays within what
    adults and keypoints' placement give (nothing added)."""
    from mirrorgraph.stature import keypoint_rel_std, measurement_rel_std, unmeasured_rel_std

    sk, pts, valid, _ = _subject(3)
    est = estimate_stature(_legs_stretched(pts, sk, 1.4), valid, sk)
    err = est.height / 1.75 - 1
    assert err > 0.15 and est.side_rel_diff < 0.005
    assert err / 2 < est.bones_rel_spread < 2 * err
    assert estimate_stature(_legs_stretched(pts, sk, 1.2), valid, sk).bones_rel_spread == 0.0
    assert measurement_rel_std(est) == pytest.approx(np.sqrt(
        est.side_rel_diff ** 2 + est.bones_rel_spread ** 2 + keypoint_rel_std(est.top) ** 2
        + unmeasured_rel_std(est.top) ** 2))
    assert measurement_rel_std(est.to_dict()) == pytest.approx(measurement_rel_std(est))
    assert est.scaled(3.0).bones_rel_spread == est.bones_rel_spread


def test_an_upper_body_gone_wild_leaves_the_spread_alone():
    """Arms reconstructed 2.5 times too long and the legs, trunk and widths right: the
    stature is right and the arms, beyond any adult's proportions, are left out of the
    segments' disagreement."""
    sk, pts, valid, _ = _subject(3)
    wild = pts.copy()
    for side in ("left", "right"):
        sh = wild[:, sk.index(f"{side}_shoulder")].copy()
        for j in ("elbow", "wrist"):
            i = sk.index(f"{side}_{j}")
            wild[:, i] = sh + 2.5 * (wild[:, i] - sh)
    est = estimate_stature(wild, valid, sk)
    assert est.bone_ratios["arm"] > 2.0
    assert est.height == pytest.approx(estimate_stature(pts, valid, sk).height, rel=1e-9)
    assert est.bones_rel_spread == 0.0


def test_the_tests_threshold_is_the_normal_samples():
    """The one-sided point of the bones' robust scale: a seeded Monte Carlo of normal
    samples exceeds it in ``alpha`` of draws."""
    from mirrorgraph.stature import _median_abs_quantile

    rng = np.random.default_rng(0)
    for n, alpha in ((7, 0.05), (6, 0.05), (9, 0.2)):
        high_median = np.sort(np.abs(rng.standard_normal((40000, n))), axis=1)[:, n // 2]
        q = _median_abs_quantile(n, alpha)
        assert np.mean(high_median / 0.6744897501960817 > q) == pytest.approx(alpha, abs=0.006)


def test_the_distance_std_holds_legs_lengthened_alike():
    """A detector placing every knee and ankle 40 % further from its hip in both views:
    the distance comes out ~18 % short; the legs agree with each other, so their term
    adds nothing, and the segments' disagreement widens the std to cover the error (the
    height's 2 % alone: error/std ~9)."""
    from mirrorgraph.keypoints import PairedKeypoints
    from mirrorgraph.synth.scene import make_scene

    s = make_scene(frames=300, seed=0, skeleton="COCO_17")
    out = {}
    for k in (1.0, 1.4):
        paired = PairedKeypoints(skeleton=s.skeleton, frame_ids=s.frame_ids,
                                 real=_legs_stretched(s.real_observed, s.skeleton, k),
                                 mirror=_legs_stretched(s.mirror_observed, s.skeleton, k),
                                 source="biased.npz", image_size=s.image_size)
        c = _calibrate_paired(paired, s)
        out[k] = (c.distance / s.distance - 1, c.uncertainty["distance_std"] / c.distance,
                  c.refinement["stature"])
    err, std, stature = out[1.4]
    assert abs(err) > 0.1 and stature["side_rel_diff"] < 0.005
    assert abs(err) < 2 * std
    assert stature["rel_std"] > 0.1 and out[1.0][2]["bones_rel_spread"] == 0.0
    # unbiased: the height's 2 % and the end keypoints' 2.7 % (keypoint_rel_std)
    assert abs(out[1.0][0]) < 2 * out[1.0][1] and out[1.0][1] < 0.04


def test_the_sampling_std_covers_the_error_and_shrinks_with_the_frames():
    """Joints with 3 cm iid noise: the stature's sampling std is the spread of the height
    measured on independent stretches of frames (its error over it about 1, over 40
    draws), and four times the frames halve it."""
    sk, pts, valid, _ = _subject(None, frames=800)
    rng = np.random.default_rng(7)
    ref = estimate_stature(pts, valid, sk).height
    z, short, long = [], [], []
    for k in range(40):
        noisy = pts + rng.normal(0.0, 0.03, pts.shape)
        few = estimate_stature(noisy[:200], valid[:200], sk)
        many = estimate_stature(noisy, valid, sk)
        z.append((few.height - ref) / (few.sampling_rel_std * few.height))
        short.append(few.sampling_rel_std)
        long.append(many.sampling_rel_std)
    # the noise inflates every segment alike (a bias the sampling std does not hold): the
    # spread about the draws' own mean
    z = np.asarray(z) - np.mean(z)
    assert 0.5 < float(np.sqrt(np.mean(z ** 2))) < 2.0
    assert np.median(short) / np.median(long) == pytest.approx(2.0, rel=0.35)
    # too few frames for three blocks: not measured
    assert np.isnan(estimate_stature(pts[:25], valid[:25], sk).sampling_rel_std)


def _moved_along_trunk(pts: np.ndarray, sk, joints: dict[str, float]) -> np.ndarray:
    """``pts`` with each named joint moved by its distance (m, + towards the head) along
    the frame's trunk axis (mid-hip to mid-shoulder): a detector placing it above or
    below its landmark."""
    mid = lambda j: 0.5 * (pts[:, sk.index(f"left_{j}")] + pts[:, sk.index(f"right_{j}")])  # noqa: E731
    u = mid("shoulder") - mid("hip")
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    out = pts.copy()
    for name, d in joints.items():
        out[:, sk.index(name)] += d * u
    return out


def test_only_the_chains_end_keypoints_move_the_stature_and_its_std_covers_them():
    """A detector placing keypoints 3 cm off their landmarks along the body (Needham et
    al. 2021's few centimetres; :data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET` is
    1.7 % of 1.75 m): the knees, hips and shoulders inside the stacked chain leave the
    stature within 0.5 % (one segment gains what the next loses); the ankles placed 3 cm
    high and the eyes 3 cm low shorten it by 6 cm over the chain's measured 89.7 %
    (3.8 %), which the scale's std (the height's 2 % and
    :func:`~mirrorgraph.stature.keypoint_rel_std`) covers within 1.5 std, and the
    height's 2 % alone does not."""
    from mirrorgraph.stature import keypoint_rel_std, measurement_rel_std

    sk, pts, valid, _ = _subject(3)
    base = estimate_stature(pts, valid, sk).height
    inner = {f"{s}_{j}": 0.03 for s in ("left", "right") for j in ("knee", "hip", "shoulder")}
    moved = estimate_stature(_moved_along_trunk(pts, sk, inner), valid, sk).height
    assert abs(moved / base - 1) < 0.005
    ends = {**{f"{s}_ankle": 0.03 for s in ("left", "right")},
            **{f"{s}_eye": -0.03 for s in ("left", "right")}}
    est = estimate_stature(_moved_along_trunk(pts, sk, ends), valid, sk)
    err = est.height / base - 1
    assert err == pytest.approx(-0.06 / 1.75 / (1 - est.unmeasured_fraction), abs=0.005)
    std = np.hypot(0.02, measurement_rel_std(est))
    assert abs(err) < 1.5 * std and abs(err) > 1.5 * 0.02
    assert keypoint_rel_std("eyes") == pytest.approx(np.sqrt(2) * 0.017 / 0.897, rel=1e-3)
    assert keypoint_rel_std("head_top") == pytest.approx(np.sqrt(2) * 0.017 / 0.961, rel=1e-3)


def test_the_limbs_scale_std_holds_the_measurement_and_the_limbs_prior():
    """``scale_from = "limbs"``: the scale's std is the height's prior with the limbs' own
    rule (the subject's limb proportions and the limb ends' keypoints, the legs apart and
    the segments' disagreement measured on the result: one home,
    :func:`measurement_rel_std`), in the distance's std and the joints' scale share alike,
    not the height's prior alone; it covers the limbs' error (2.6 % on seed 0)."""
    from mirrorgraph.graph.options import RefineOptions
    from mirrorgraph.intrinsics import Intrinsics
    from mirrorgraph.pipelines.mirror import CalibrateOptions, calibrate
    from mirrorgraph.stature import keypoint_rel_std, limbs_rel_std, measurement_rel_std
    from mirrorgraph.synth.scene import make_scene

    scene = make_scene(frames=600, seed=0, skeleton="COCO_17")
    run = calibrate(scene.detections, Intrinsics(K=scene.K, image_size=scene.image_size),
                    CalibrateOptions(subject_height=scene.subject_height,
                                     refine_options=RefineOptions(scale_from="limbs")))
    c = run.calibration
    record = c.refinement["stature"]
    m = measurement_rel_std(record)
    assert m == measurement_rel_std(record, "limbs")         # the record says which rule
    assert m >= limbs_rel_std() > keypoint_rel_std("eyes")
    want = np.hypot(RefineOptions().height_sigma, m)
    assert run.scale_rel_std == pytest.approx(want, rel=1e-9)
    rel = c.uncertainty["distance_std"] / c.distance
    assert want - 1e-9 <= rel < want + 0.005
    err = abs(c.distance / scene.distance - 1)
    assert 0.01 < err < 2 * rel
    # not measured (no eyes): the limbs' prior alone; the stature's own path: nothing
    assert measurement_rel_std(None, "limbs") == pytest.approx(limbs_rel_std())
    assert measurement_rel_std(None) == 0.0


def test_a_rigs_limbs_scale_keeps_the_solution_and_measures_its_stature():
    """A rig's ``scale_from = "limbs"``: the solution as the gauge left it, the stature
    measured on it for the scale's std (the limbs' rule), as one mirror's."""
    from types import SimpleNamespace

    from mirrorgraph.pipelines.scale import scale_rig_by_stature
    from mirrorgraph.stature import LIMB_CHOSEN, limbs_rel_std, measurement_rel_std
    from mirrorgraph.synth.scene import make_scene

    scene = make_scene(frames=200, seed=1, skeleton="COCO_17")
    X = scene.joints3d * 1.04                                 # the limbs' scale: 4 % long
    sol = SimpleNamespace(points=X, used=np.isfinite(X).all(-1))
    out, source, stature = scale_rig_by_stature(sol, scene.skeleton, scene.subject_height,
                                                "limbs")
    assert out is sol and source == LIMB_CHOSEN
    assert stature.scale_from == "limbs"
    assert stature.height / scene.subject_height == pytest.approx(1.04, abs=0.01)
    assert measurement_rel_std(stature) >= limbs_rel_std()


def test_keypoints_stated_on_the_landmarks_leave_the_measured_terms():
    """A keypoint placement stated as 0 (keypoints on the landmarks: projected markers,
    synthetic): the chain's placement term is 0 and the measurement's std is the legs
    apart, the segments' disagreement and the unmeasured parts' proportions (ANSUR II's
    ankle and head heights) in quadrature; stated in metres the placement is
    ``sqrt(2) o / H / (1 - u)``, ``u`` the unmeasured fraction; the record carries it."""
    from mirrorgraph.anthropometry import KEYPOINT_OFFSET
    from mirrorgraph.stature import (keypoint_offset_fraction, keypoint_rel_std,
                                     measurement_rel_std, unmeasured_rel_std)

    sk, pts, valid, _ = _subject(3)
    long = pts.copy()
    hip = long[:, [sk.index("right_hip")]]
    for j in ("right_knee", "right_ankle"):                  # one leg 5 % longer
        long[:, sk.index(j)] = hip[:, 0] + 1.05 * (long[:, sk.index(j)] - hip[:, 0])
    default = estimate_stature(long, valid, sk)
    zero = estimate_stature(long, valid, sk, keypoint_offset=0.0)
    assert default.keypoint_offset == KEYPOINT_OFFSET and zero.keypoint_offset == 0.0
    assert zero.side_rel_diff == default.side_rel_diff > 0.01
    assert zero.bones_rel_spread == default.bones_rel_spread == 0.0   # a body measured right
    assert keypoint_rel_std(zero.top, 0.0) == 0.0
    # the documented sum: the measured spreads and the unmeasured parts' (eyes as top:
    # u = 0.039 + 0.064; ANSUR II's 0.41 % and 0.33 % over 1 - u), against the default's
    # four terms (the end keypoints' sqrt(2) o / (1 - u))
    u = unmeasured_rel_std(zero.top)
    assert u == pytest.approx(math.hypot(0.0041, 0.0033) / 0.897, rel=0.01)
    assert measurement_rel_std(zero) == pytest.approx(
        math.sqrt(zero.side_rel_diff ** 2 + zero.bones_rel_spread ** 2 + u ** 2), rel=1e-12)
    assert measurement_rel_std(default) == pytest.approx(math.sqrt(
        default.side_rel_diff ** 2 + default.bones_rel_spread ** 2
        + (math.sqrt(2) * KEYPOINT_OFFSET / 0.897) ** 2 + u ** 2), rel=1e-3)
    assert measurement_rel_std(zero) < measurement_rel_std(default) - 0.01
    # the JSON record and the scaled estimate keep the statement
    assert zero.to_dict()["keypoint_offset"] == 0.0
    assert measurement_rel_std(zero.to_dict()) == pytest.approx(measurement_rel_std(zero))
    assert measurement_rel_std(zero.scaled(2.0)) == pytest.approx(measurement_rel_std(zero))
    assert "0.0 cm" in zero.describe() and "as stated" in zero.describe()
    assert "Needham" in default.describe()
    # a record of before the setting reads as the literature's
    old = {k: v for k, v in default.to_dict().items() if k != "keypoint_offset"}
    assert measurement_rel_std(old) == pytest.approx(measurement_rel_std(default))
    # metres: 1 cm on a 1.60 m subject, eyes as top
    o = keypoint_offset_fraction(0.01, 1.60)
    assert o == pytest.approx(0.01 / 1.60)
    assert keypoint_rel_std("eyes", o) == pytest.approx(math.sqrt(2) * 0.01 / 1.60 / 0.897,
                                                        rel=1e-3)
    assert keypoint_offset_fraction(None, 1.60) == KEYPOINT_OFFSET
    assert keypoint_offset_fraction(0.01, None) == KEYPOINT_OFFSET


def test_a_stated_placement_is_checked_by_the_segments():
    """Both legs 40 % long (a biased reconstruction) measured by keypoints stated to lie on
    the landmarks: the segments' spread is the population's alone, so their disagreement
    is the larger and the measurement's std does not shrink below the error's share that
    the default's shows."""
    from mirrorgraph.stature import measurement_rel_std

    sk, pts, valid, _ = _subject(3)
    stretched = _legs_stretched(pts, sk, 1.4)
    default = estimate_stature(stretched, valid, sk)
    zero = estimate_stature(stretched, valid, sk, keypoint_offset=0.0)
    assert zero.bones_rel_spread > default.bones_rel_spread > 0.1
    assert measurement_rel_std(zero) > 0.1


def test_the_segments_and_limbs_spread_without_the_keypoints():
    """With the placement 0 each segment's spread is the population's alone
    (:data:`~mirrorgraph.anthropometry.HEIGHT_FRACTION_CV`) and the limbs' std their
    proportions' 1.9 %; the literature's placement gives the module's constants."""
    from mirrorgraph.anthropometry import HEIGHT_FRACTION_CV
    from mirrorgraph.stature import SEGMENT_REL_STD, limbs_rel_std, segment_rel_std

    assert segment_rel_std() == SEGMENT_REL_STD
    bare = segment_rel_std(0.0)
    for kind in ("trunk", "shoulder_width", "hip_width"):
        assert bare[kind] == pytest.approx(HEIGHT_FRACTION_CV[kind])
    assert all(bare[k] < SEGMENT_REL_STD[k] for k in bare)
    assert limbs_rel_std(0.0) == pytest.approx(0.019, abs=0.001)
    assert limbs_rel_std() == pytest.approx(math.hypot(limbs_rel_std(0.0), 0.040), abs=0.001)
