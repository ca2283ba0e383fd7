"""Every person before one mirror in the one graph (mirrorgraph.pipelines.people), against
the ground truth of a synthetic gym scene."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.intrinsics import Intrinsics
from mirrorgraph.metrics import mirror_rotation_error_deg, pa_mpjpe
from mirrorgraph.pipelines.mirror import calibrate
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.pipelines.people import calibrate_people
from mirrorgraph.stature import estimate_stature, keypoint_rel_std, measurement_rel_std
from mirrorgraph.synth.crowd import make_crowd


@pytest.fixture(scope="module")
def crowd():
    return make_crowd(people=3, frames=240, seed=3, occluded_rate=0.5)


def _owners(crowd, run):
    """Each track's true person (the owner of most of its person detections)."""
    out = []
    for k in range(run.num_people):
        own = [crowd.truth_person[t][a] for t, (a, _) in enumerate(run.pairing.detections[:, k])
               if a >= 0]
        out.append(int(np.bincount(own).argmax()))
    return out


@pytest.fixture(scope="module")
def runs(crowd):
    intr = Intrinsics(K=crowd.K, image_size=crowd.image_size)
    opts = CalibrateOptions(image_size=crowd.image_size, subject_height=None)
    one = calibrate(crowd.detections, intr, opts)
    tallest = float(crowd.heights.max())
    every = calibrate_people(crowd.detections, intr,
                             CalibrateOptions(image_size=crowd.image_size,
                                              subject_height=tallest))
    return one, every


def test_every_person_has_their_joints(crowd, runs):
    _, run = runs
    owners = _owners(crowd, run)
    assert sorted(set(owners)) == [0, 1, 2]
    limbs = np.zeros(crowd.skeleton.num_joints, dtype=bool)
    limbs[crowd.skeleton.calibration_joints] = True
    for p in range(3):
        k = owners.index(p)
        err = pa_mpjpe(run.joints3d[k], crowd.joints3d[p], run.valid3d[k] & limbs)
        assert err < 0.030, (p, err)                        # metres
        seen = ~crowd.occluded[p].any(0)                # both views of the person
        assert run.valid3d[k].any(-1)[seen].mean() > 0.9


def test_the_mirror_at_least_as_good_as_one_persons(crowd, runs):
    one, run = runs
    e_one = mirror_rotation_error_deg(one.calibration.normal, crowd.normal)
    e_all = mirror_rotation_error_deg(run.calibration.normal, crowd.normal)
    assert e_all <= e_one
    assert e_all < 0.1
    assert run.calibration.pairs_used > 2 * one.calibration.pairs_used


def test_one_height_scales_everyone(crowd, runs):
    _, run = runs
    cal = run.calibration
    assert cal.scale == "subject_height"
    assert abs(cal.distance / crowd.distance - 1.0) < 0.03
    owners = _owners(crowd, run)
    assert owners[run.height_person] == int(np.argmax(crowd.heights))
    for k, p in enumerate(owners):           # the others' statures follow from the mirror
        assert abs(run.statures[k] / crowd.heights[p] - 1.0) < 0.04, (k, run.statures)


def test_height_of_refuses_nonsense(crowd):
    with pytest.raises(InputError, match="height_of"):
        calibrate_people(crowd.detections, None, height_of="oldest")


def test_height_of_a_person_not_tracked_leaves_the_scale_unknown(crowd, runs):
    from mirrorgraph.pipelines.people import _scale_people

    _, run = runs
    factor, _, person, source, *_ = _scale_people(run.joints3d, run.valid3d, crowd.skeleton,
                                                  1.8, None, run.num_people)
    assert factor is None and person is None
    assert f"not among the {run.num_people} people" in source


def test_a_list_of_heights(crowd, runs):
    _, run = runs
    owners = _owners(crowd, run)
    heights = [float(crowd.heights[owners[0]]), None, None]
    again = calibrate_people(crowd.detections, Intrinsics(K=crowd.K, image_size=crowd.image_size),
                             CalibrateOptions(image_size=crowd.image_size), heights=heights)
    assert again.height_person is None
    assert abs(again.calibration.distance / crowd.distance - 1.0) < 0.03
    assert abs(again.statures[0] - heights[0]) < 1e-9


def test_each_persons_left_right_swaps_undone():
    """A detector mistaking which way each person faces (left/right labels swapped in both
    views, 10 % of frames per person): swapped back per person, no joint far off (left
    as given: 0.2-2.5 % of joints > 0.3 m off, PA-MPJPE 38-57 mm)."""
    crowd = make_crowd(people=3, frames=240, seed=5, lr_swap_rate=0.1, lr_swap_views="both")
    intr = Intrinsics(K=crowd.K, image_size=crowd.image_size)
    run = calibrate_people(crowd.detections, intr,
                           CalibrateOptions(image_size=crowd.image_size,
                                            subject_height=float(crowd.heights.max())))
    # undone by each track's clip decision (mirrorgraph.initial.clip_left_right) or by
    # the pairs' motion (body_left_right)
    assert run.calibration.input["body_lr_fixes"] + run.calibration.lr_fixes > 0
    owners = _owners(crowd, run)
    assert sorted(owners) == [0, 1, 2]
    for k, p in enumerate(owners):
        err = np.linalg.norm(run.joints3d[k] - crowd.joints3d[p], axis=-1)[run.valid3d[k]]
        assert (err > 0.3).mean() < 0.005, (k, (err > 0.3).mean())
        assert err.max() < 1.0, (k, err.max())
        assert pa_mpjpe(run.joints3d[k], crowd.joints3d[p], run.valid3d[k]) < 0.03


def test_the_distance_std_is_stated_as_one_persons_run_states_it(crowd, runs):
    """The people's distance std is one person's rule (mirrorgraph.pipelines.scale.
    distance_rel_parts) on the person whose stature sets the scale: the height's prior, the
    chosen person's stature measurement (its detector keypoint term included) and the
    data's share (the normal's covariance through their stature, their stature's
    sampling), in quadrature."""
    _, run = runs
    cal = run.calibration
    k = run.height_person
    est = estimate_stature(run.joints3d[k], run.valid3d[k], crowd.skeleton)
    rel = measurement_rel_std(est)
    assert rel >= keypoint_rel_std(est.top)                  # the end keypoints' share in it
    parts = cal.uncertainty["distance_rel_std"]
    hs = CalibrateOptions().graph.height_sigma
    assert parts["measurement"] == pytest.approx(rel, rel=1e-6)
    assert parts["height"] == hs
    assert parts["sampling"] == pytest.approx(est.sampling_rel_std, rel=1e-6)
    assert parts["normal"] > 0.0
    assert parts["data"] == pytest.approx(np.hypot(parts["normal"], parts["sampling"]))
    want = np.sqrt(hs ** 2 + rel ** 2 + parts["data"] ** 2)
    assert cal.uncertainty["distance_std"] / cal.distance == pytest.approx(want, rel=1e-6)
    assert abs(cal.distance - crowd.distance) < 3.0 * cal.uncertainty["distance_std"]


def test_each_persons_joints_std_holds_the_metric_scales_share(crowd, runs):
    """Each person's joints' std in metres with the metric scale's share, as one person's
    run holds it: ``joints_std^2 = joints_std_shape^2 + (scale_rel_std |X|)^2`` with
    ``scale_rel_std`` the distance's relative std; the scale fitted out, the shape's std
    covers each person's error against the truth."""
    _, run = runs
    cal, r = run.calibration, run.run
    parts = cal.uncertainty["distance_rel_std"]
    rel = float(np.hypot(parts["height"], parts["measurement"]))     # the scale's share
    assert r.scale_rel_std == pytest.approx(rel, rel=1e-9)
    assert run.joints_std.shape == run.joints_std_shape.shape == run.valid3d.shape
    owners = _owners(crowd, run)
    for k, p in enumerate(owners):
        ok = run.valid3d[k]
        X = run.joints3d[k][ok]
        want = np.hypot(run.joints_std_shape[k][ok], rel * np.linalg.norm(X, axis=-1))
        assert np.allclose(run.joints_std[k][ok], want, rtol=1e-6, atol=1e-12)
        truth = crowd.joints3d[p][ok]
        fit = float((X * truth).sum() / (X * X).sum())          # the scale about the camera
        z_shape = np.linalg.norm(fit * X - truth, axis=-1) / run.joints_std_shape[k][ok]
        assert 0.3 < np.median(z_shape) < 2.0, (k, np.median(z_shape))
        z = np.linalg.norm(X - truth, axis=-1) / run.joints_std[k][ok]
        assert np.percentile(z, 99) < 3.0, (k, np.percentile(z, 99))


def test_a_stated_keypoint_placement_is_each_persons_fraction_of_their_height(crowd, runs):
    """The people's scale with the keypoints' placement stated in metres: the chosen
    person's stature measured at ``offset / height`` (the height given is theirs), so the
    std holds ``sqrt(2) offset / height / (1 - u)``; 0 leaves the measured spreads and the
    unmeasured parts' proportions."""
    from mirrorgraph.stature import unmeasured_rel_std
    from mirrorgraph.pipelines.people import _scale_people

    _, run = runs
    k, H = run.height_person, float(crowd.heights.max())
    X, V = run.joints3d / run.calibration.distance, run.valid3d    # back to the run's unit
    rel0 = _scale_people(X, V, crowd.skeleton, H, None, "tallest", 0.0)[4]
    rel2 = _scale_people(X, V, crowd.skeleton, H, None, "tallest", 0.02)[4]
    rel = _scale_people(X, V, crowd.skeleton, H, None, "tallest")[4]
    est = estimate_stature(X[k], V[k], crowd.skeleton, keypoint_offset=0.0)
    assert rel0 == pytest.approx(np.sqrt(est.side_rel_diff ** 2 + est.bones_rel_spread ** 2
                                         + unmeasured_rel_std(est.top) ** 2), rel=1e-9)
    kp = np.sqrt(2) * 0.02 / H / (1 - est.unmeasured_fraction)
    assert rel2 == pytest.approx(np.sqrt(rel0 ** 2 + kp ** 2), rel=1e-6)
    assert rel0 < rel2 < rel
