"""The metric scale of a single-mirror refinement from the subject's measured stature
(mirrorgraph.pipelines.scale), against synthetic scenes of known height.

Each test hands :func:`scale_by_stature` a refinement that is the truth of
:func:`mirrorgraph.synth.make_scene` at a wrong scale (``g`` times too large), with the
limbs estimated (the calibration joints) and the eyes or head top not: those it
triangulates from the person and the reflection itself.

A height of 0, a negative or a non-finite one is refused, naming the field.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph.errors import InputError
from mirrorgraph.graph import RefineOptions
from mirrorgraph.graph.options import GaugeOptions
from mirrorgraph.graph.result import RefinementResult
from mirrorgraph.pipelines.scale import scale_by_stature
from mirrorgraph.stature import LIMB_PROPORTIONS
from mirrorgraph.keypoints import PairedKeypoints
from mirrorgraph.stature import MIN_FRAMES, estimate_stature, stature_joints
from mirrorgraph.synth import make_scene

FRAMES = 150


def _limbs_at_scale(scene, g: float) -> RefinementResult:
    """The scene's mirror and limbs, every length ``g`` times the truth."""
    sk = scene.skeleton
    T, J = scene.joints3d.shape[:2]
    valid = np.zeros((T, J), dtype=bool)
    valid[:, sk.calibration_joints] = True
    X = np.where(valid[..., None], scene.joints3d * g, np.nan)
    return RefinementResult(
        normal=np.asarray(scene.normal, float), distance=float(scene.distance) * g,
        scale="subject_height", joints3d=X, valid=valid, inliers=valid.copy(),
        bone_lengths={"left_femur": 0.43 * g, "right_humerus": 0.31 * g},
        normal_cov=np.eye(3) * 1e-6, rotation_std_deg=0.1, distance_std=0.01 * g,
        rms_direct_px=4.0, rms_mirror_px=4.0, iterations=5, final_error=1.0, priors={},
        timings={})


def _stature_on(res: RefinementResult, paired: PairedKeypoints, K) -> float:
    """The stature measured on ``res``: its joints plus the chain's joints it lacks,
    triangulated with its own mirror (what the rescaling measures)."""
    X, valid = np.array(res.joints3d), np.array(res.valid)
    chain = stature_joints(paired.skeleton)
    seen = paired.valid()[:, chain] & ~valid[:, chain]
    t, k = np.nonzero(seen)
    Y = geo.triangulate_mirror(K, res.normal, res.distance, paired.real[t, chain[k], :2],
                               paired.mirror[t, chain[k], :2])
    X[t, chain[k]] = Y
    valid[t, chain[k]] = np.isfinite(Y).all(-1)
    return estimate_stature(X, valid, paired.skeleton).height


@pytest.fixture(scope="module", params=["BODY_25", "COCO_17", "HALPE_26"])
def scene(request):
    """4 px detector noise; BODY_25 and COCO_17 measure to the eyes, HALPE_26 to the head top."""
    return make_scene(frames=FRAMES, seed=2, skeleton=request.param)


@pytest.mark.parametrize("g", [0.7, 1.13, 1.6])
def test_the_rescaled_stature_is_the_given_height(scene, g):
    paired = scene.paired()
    res = _limbs_at_scale(scene, g)
    H = scene.subject_height
    out = scale_by_stature(res, paired, scene.K, H)
    assert out.stature["height"] == pytest.approx(H, rel=1e-12)
    # measured again, independently, on what came out
    assert _stature_on(out, paired, scene.K) == pytest.approx(H, rel=1e-9)
    # and that is the true scale: only the ankle-to-floor and eye-to-vertex parts rest
    # on population figures, so the mirror lands within 1 % of the truth from 13-60 % off
    assert out.distance == pytest.approx(scene.distance, rel=0.01)
    used = out.valid
    err = np.linalg.norm(out.joints3d[used] - scene.joints3d[used], axis=-1)
    assert np.median(err) < 0.01 * np.median(np.linalg.norm(scene.joints3d[used], axis=-1))
    top = "head_top" if "head_top" in scene.skeleton.joints else "eyes"
    assert out.stature["top"] == top and top.replace("_", " ") in out.scale_source


def test_the_rescaling_is_a_pure_change_of_scale(scene):
    paired = scene.paired()
    res = _limbs_at_scale(scene, 1.13)
    out = scale_by_stature(res, paired, scene.K, scene.subject_height)
    f = out.distance / res.distance
    assert f == pytest.approx(1 / 1.13, rel=0.01)
    np.testing.assert_array_equal(out.normal, res.normal)
    np.testing.assert_array_equal(out.valid, res.valid)
    np.testing.assert_allclose(out.joints3d[out.valid], f * res.joints3d[res.valid], rtol=1e-12)
    # the std: the normal's through the stature, the height's prior and the stature
    # measurement's own (the end keypoints' placement)
    from mirrorgraph.stature import measurement_rel_std

    rel = measurement_rel_std(out.stature)
    assert rel > 0.02
    _std_of_parts(out, rel)
    assert out.bone_lengths == pytest.approx({b: f * v for b, v in res.bone_lengths.items()})
    # the images do not change: the same pixels in the camera and in the mirror
    X, Y = res.joints3d[res.valid], out.joints3d[out.valid]
    np.testing.assert_allclose(geo.project(scene.K, Y), geo.project(scene.K, X), atol=1e-9)
    np.testing.assert_allclose(
        geo.project(scene.K, geo.reflect_points(Y, out.normal, out.distance)),
        geo.project(scene.K, geo.reflect_points(X, res.normal, res.distance)), atol=1e-9)
    # the input is left as it was
    assert res.distance == pytest.approx(1.13 * scene.distance) and res.stature is None


def _std_of_parts(out: RefinementResult, measurement: float,
                  height_sigma: float = GaugeOptions().height_sigma) -> dict:
    """``out.distance_std`` is its parts' quadrature: the data's (the normal's through the
    stature and the stature's sampling), the height's prior and ``measurement``."""
    parts = out.stature["distance_rel_std"]
    assert parts["measurement"] == pytest.approx(measurement, rel=1e-12)
    assert parts["height"] == height_sigma
    assert parts["data"] == pytest.approx(math.hypot(parts["normal"], parts["sampling"]))
    assert parts["normal"] > 0 and parts["sampling"] > 0
    assert parts["total"] == pytest.approx(
        math.sqrt(parts["data"] ** 2 + height_sigma ** 2 + measurement ** 2), rel=1e-12)
    assert out.distance_std == pytest.approx(parts["total"] * out.distance, rel=1e-12)
    return parts


def test_the_result_does_not_depend_on_the_scale_it_started_from(scene):
    paired = scene.paired()
    outs = [scale_by_stature(_limbs_at_scale(scene, g), paired, scene.K, 1.8)
            for g in (0.5, 1.0, 2.5)]
    for o in outs[1:]:
        assert o.distance == pytest.approx(outs[0].distance, rel=1e-9)
        np.testing.assert_allclose(o.joints3d, outs[0].joints3d, rtol=1e-9)
    # and the given height sets it: a 10 % taller subject, a 10 % larger scene
    taller = scale_by_stature(_limbs_at_scale(scene, 1.0), paired, scene.K, 1.98)
    assert taller.distance == pytest.approx(1.1 * outs[0].distance, rel=1e-9)


def _kept_limb_scale(res: RefinementResult, out: RefinementResult) -> None:
    assert out.scale_source == LIMB_PROPORTIONS and out.stature is None
    assert out.distance == res.distance and out.distance_std == res.distance_std
    np.testing.assert_array_equal(out.joints3d, res.joints3d)
    assert out.bone_lengths == res.bone_lengths


def test_without_the_eyes_in_the_mirror_the_limb_scale_stays():
    """The eyes seen directly but never in the reflection: they cannot be triangulated,
    the stature cannot be measured, the limb-proportion scale is kept and said so."""
    scene = make_scene(frames=FRAMES, seed=2)
    p = scene.paired()
    mirror = p.mirror.copy()
    for name in ("left_eye", "right_eye"):
        mirror[:, scene.skeleton.index(name)] = [np.nan, np.nan, 0.0]
    blind = PairedKeypoints(skeleton=p.skeleton, frame_ids=p.frame_ids, real=p.real,
                            mirror=mirror, source=p.source)
    res = _limbs_at_scale(scene, 1.13)
    _kept_limb_scale(res, scale_by_stature(res, blind, scene.K, scene.subject_height))


def test_too_few_frames_keep_the_limb_scale():
    """Each segment needs MIN_FRAMES frames: a shorter video keeps the limb scale."""
    scene = make_scene(frames=MIN_FRAMES - 1, seed=2)
    res = _limbs_at_scale(scene, 1.13)
    _kept_limb_scale(res, scale_by_stature(res, scene.paired(), scene.K, scene.subject_height))
    # one frame more, and it is measured
    scene = make_scene(frames=MIN_FRAMES + 5, seed=2)
    out = scale_by_stature(_limbs_at_scale(scene, 1.13), scene.paired(), scene.K,
                           scene.subject_height)
    assert out.stature is not None and out.distance == pytest.approx(scene.distance, rel=0.02)


def test_eyes_triangulated_behind_the_mirror_are_not_used():
    """The eyes' rows of the person and of the reflection swapped: the two rays then meet
    at the eyes' mirror image, behind the mirror. Those points are no eyes: without
    others the stature cannot be measured and the limb scale stays."""
    scene = make_scene(frames=FRAMES, seed=2)
    p = scene.paired()
    real, mirror = p.real.copy(), p.mirror.copy()
    eyes = [scene.skeleton.index("left_eye"), scene.skeleton.index("right_eye")]
    real[:, eyes], mirror[:, eyes] = p.mirror[:, eyes], p.real[:, eyes]
    swapped = PairedKeypoints(skeleton=p.skeleton, frame_ids=p.frame_ids, real=real,
                              mirror=mirror, source=p.source)
    # (the same rows triangulated: behind the plane, where the reflection is)
    ok = swapped.valid()[:, eyes]
    Y = geo.triangulate_mirror(scene.K, scene.normal, scene.distance, real[:, eyes][ok][:, :2],
                               mirror[:, eyes][ok][:, :2])
    assert np.mean(Y @ scene.normal > scene.distance) > 0.99
    res = _limbs_at_scale(scene, 1.13)
    _kept_limb_scale(res, scale_by_stature(res, swapped, scene.K, scene.subject_height))


@pytest.mark.parametrize("height", [0.0, -1.7, math.nan, math.inf])
def test_a_height_that_is_no_height_is_refused(height):
    scene = make_scene(frames=40, seed=2)
    res = _limbs_at_scale(scene, 1.0)
    with pytest.raises(InputError, match="subject_height"):
        scale_by_stature(res, scene.paired(), scene.K, height)


@pytest.mark.parametrize("height", [0.0, -1.7, math.nan])
def test_refine_options_name_a_height_that_is_no_height(height):
    with pytest.raises(InputError, match="subject_height"):
        RefineOptions(subject_height=height, marginals=False)


def test_legs_reconstructed_long_widen_the_distance_std(scene):
    """The truth with every knee and ankle 40 % further from its hip (a reconstruction
    stretched along both legs alike): the stature comes out long and the distance short;
    the legs agree, and the segments' disagreement (legs against arms, trunk, widths) is
    the std's measurement term, which covers the error."""
    from mirrorgraph.stature import keypoint_rel_std, measurement_rel_std, unmeasured_rel_std

    sk, paired = scene.skeleton, scene.paired()
    res = _limbs_at_scale(scene, 1.0)
    X = np.array(res.joints3d)
    for side in ("left", "right"):
        hip = X[:, sk.index(f"{side}_hip")].copy()
        for j in ("knee", "ankle"):
            i = sk.index(f"{side}_{j}")
            X[:, i] = hip + 1.4 * (X[:, i] - hip)
    out = scale_by_stature(replace(res, joints3d=X), paired, scene.K, scene.subject_height)
    err = out.distance / scene.distance - 1
    assert err < -0.1 and out.stature["side_rel_diff"] < 0.005
    rel = measurement_rel_std(out.stature)
    top = out.stature["top"]
    assert rel == pytest.approx(np.sqrt(out.stature["bones_rel_spread"] ** 2
                                        + keypoint_rel_std(top) ** 2
                                        + unmeasured_rel_std(top) ** 2)) and rel > 0.1
    _std_of_parts(out, rel)
    assert abs(err) < 2 * out.distance_std / out.distance


def test_a_stated_keypoint_placement_sets_the_distance_std(scene):
    """The keypoints stated on the landmarks (``keypoint_offset`` 0, a fraction of the
    height): the same rescaling, its distance std holding the measured spreads alone
    (the legs apart, the segments' disagreement) beside the data's, smaller than with
    the literature's placement; 2 cm stated on the scene's subject: ``sqrt(2) 0.02 / H
    / (1 - u)`` in quadrature with them."""
    from mirrorgraph.stature import (keypoint_offset_fraction, measurement_rel_std,
                                     unmeasured_rel_std)

    paired, H = scene.paired(), scene.subject_height
    res = _limbs_at_scale(scene, 1.13)
    default = scale_by_stature(res, paired, scene.K, H)
    zero = scale_by_stature(res, paired, scene.K, H, keypoint_offset=0.0)
    assert zero.distance == default.distance and zero.stature["keypoint_offset"] == 0.0
    un = unmeasured_rel_std(zero.stature["top"])
    rel = math.sqrt(zero.stature["side_rel_diff"] ** 2 + zero.stature["bones_rel_spread"] ** 2
                    + un ** 2)
    assert measurement_rel_std(zero.stature) == pytest.approx(rel, rel=1e-12)
    _std_of_parts(zero, rel)
    assert zero.distance_std < default.distance_std
    two = scale_by_stature(res, paired, scene.K, H,
                           keypoint_offset=keypoint_offset_fraction(0.02, H))
    u = two.stature["unmeasured_fraction"]
    kp = math.sqrt(2) * 0.02 / H / (1 - u)
    assert measurement_rel_std(two.stature) == pytest.approx(
        math.sqrt(two.stature["side_rel_diff"] ** 2 + two.stature["bones_rel_spread"] ** 2
                  + kp ** 2 + un ** 2), rel=1e-9)
    assert "2.0 cm" in two.scale_source
    # the limbs' scale, asked for: its prior without the keypoints' share
    limbs0 = scale_by_stature(res, paired, scene.K, H, "limbs", keypoint_offset=0.0)
    limbs = scale_by_stature(res, paired, scene.K, H, "limbs")
    assert limbs0.distance_std < limbs.distance_std


def test_the_distance_std_covers_a_mirror_tilted_within_its_std():
    """A wide scene whose subject stands twice as far from the camera as the mirror's foot
    point, given the true height, the synthetic keypoints stated on the landmarks and a
    0.5 % height: the normal comes out within its std, and through the subject's lever arm
    that tilt puts the metric distance ~3 % off while the stature (the joints' scale) is
    right within 1 %. The distance's std holds the normal's share and covers the error."""
    from mirrorgraph.pipelines.mirror import CalibrateOptions, calibrate
    from mirrorgraph.synth import make_wide_scene

    sc = make_wide_scene(13, "wide", "iid", 1000, body_variation="population")
    opts = CalibrateOptions(subject_height=sc.subject_height,
                            refine_options=RefineOptions(keypoint_offset=0.0,
                                                         height_sigma=0.005))
    cal = calibrate(sc.detections, sc.intrinsics, opts).calibration
    err = cal.distance / sc.distance - 1.0
    std = cal.uncertainty["distance_std"] / cal.distance
    parts = cal.refinement["stature"]["distance_rel_std"]
    assert abs(err) > 0.02                      # beyond the height's and the stature's terms
    assert parts["normal"] > 3 * math.hypot(parts["height"], parts["measurement"])
    assert std == pytest.approx(parts["total"], rel=1e-9)
    assert abs(err) / std < 3
