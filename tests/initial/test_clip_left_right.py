"""The whole clip's left/right decision against synthetic scenes whose crossed labels are
known: a view crossed for the whole clip or in long runs, and the detectors that cross
none (controls)."""

from dataclasses import replace

import numpy as np
import pytest

from mirrorgraph.initial.clip_left_right import (clip_left_right, clip_left_right_people,
                                                 crossed_states, handedness)
from mirrorgraph.initial.pairing import pair_detections
from mirrorgraph.initial.people import pair_people
from mirrorgraph.pipelines.mirror import calibrate
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.metrics import mirror_rotation_error_deg
from mirrorgraph.synth import make_scene
from mirrorgraph.synth.crowd import make_crowd
from mirrorgraph.synth.detector import crossed_runs, sample_detector_params


def _wrong(paired, scene):
    """``(T, 2)`` truth: the paired frame's direct view (``[:, 0]``) and reflection
    (``[:, 1]``) carry their left/right labels crossed (the left/right joints nearer the
    counterpart's clean image); False where a view is unseen."""
    flip = scene.skeleton.flip
    sided = np.flatnonzero(flip != np.arange(len(flip)))
    idx = np.searchsorted(scene.frame_ids, paired.frame_ids)
    out = []
    for view, clean in ((paired.real, scene.real_image), (paired.mirror, scene.mirror_image)):
        c = clean[idx]
        d = view[:, sided, None, :2] - np.stack([c[:, sided], c[:, flip[sided]]], 2)
        dist = np.linalg.norm(d, axis=-1)                               # (T, J', 2)
        ok = np.isfinite(dist).all(-1)
        same = np.where(ok, dist[..., 0], 0.0).sum(1)
        cross = np.where(ok, dist[..., 1], 0.0).sum(1)
        out.append((cross < same) & ok.any(1))
    return np.stack(out, -1)


def _right_share(paired, scene):
    both = (paired.real[..., 2] > 0).any(1) & (paired.mirror[..., 2] > 0).any(1)
    return 1.0 - _wrong(paired, scene)[both].any(1).mean()


@pytest.mark.parametrize("view, fraction, seed", [("real", 1.0, 31), ("mirror", 1.0, 32),
                                                  ("real", 0.5, 33), ("mirror", 0.4, 34)])
def test_crossed_runs_and_clips_are_put_right(view, fraction, seed):
    scene = make_scene(frames=400, seed=seed, lr_crossed_view=view, lr_crossed_fraction=fraction,
                       lr_crossed_run=80)
    crossed = scene.lr_swapped_real if view == "real" else scene.lr_swapped
    assert crossed.mean() > 0.25                        # the scene holds crossed runs
    paired = pair_detections(scene.detections)
    fixed, n = clip_left_right(paired, scene.K)
    assert n > 0
    assert _right_share(fixed, scene) >= 0.95


def test_a_whole_clip_crossed_with_the_realistic_detector_is_put_right():
    params = sample_detector_params(np.random.default_rng(35), "realistic")
    scene = make_scene(frames=400, seed=35, lr_crossed_view="real", **params)
    paired = pair_detections(scene.detections)
    assert _right_share(paired, scene) < 0.5            # the pairing alone keeps them
    fixed, _ = clip_left_right(paired, scene.K)
    assert _right_share(fixed, scene) >= 0.95


@pytest.mark.parametrize("model, seed", [("iid", 36), ("realistic", 37)])
def test_detectors_that_cross_no_run_keep_their_labels(model, seed):
    params = sample_detector_params(np.random.default_rng(seed), model)
    scene = make_scene(frames=400, seed=seed, **params)
    paired = pair_detections(scene.detections)
    fixed, n = clip_left_right(paired, scene.K)
    # the realistic detector's single-frame swaps (3 % of each view) may be put right
    # here; nothing else changes
    assert _right_share(fixed, scene) >= _right_share(paired, scene)
    changed = crossed_states(paired, scene.K).any(1)
    swapped = _wrong(paired, scene).any(1)
    assert (changed & ~swapped).mean() <= 0.01
    if model == "iid":
        assert n == 0


def test_the_handedness_of_a_body_and_of_its_mirror_image():
    rng = np.random.default_rng(0)
    # left shoulder, right shoulder, left hip, right hip, nose, eyes, ears of a person
    # facing +z, up -y, their left at -x (camera frame: x right, y down, z forward)
    X = np.array([[-0.2, -1.4, 0], [0.2, -1.4, 0], [-0.1, -0.9, 0], [0.1, -0.9, 0],
                  [0, -1.6, 0.1], [-0.03, -1.63, 0.08], [0.03, -1.63, 0.08],
                  [-0.07, -1.6, 0], [0.07, -1.6, 0]], float)
    X = X + rng.normal(0, 0.005, X.shape)
    assert handedness(X) > 0.8
    flip = np.array([1, 0, 3, 2, 4, 6, 5, 8, 7])
    assert handedness(X[flip]) < -0.8                  # labels crossed
    mirrored = X * np.array([-1.0, 1.0, 1.0])            # its mirror image, labels kept
    assert handedness(mirrored) < -0.8


def test_crossed_runs_have_the_asked_share():
    runs = crossed_runs(np.random.default_rng(1), 20000, 0.4, 60)
    assert abs(runs.mean() - 0.4) < 0.08
    starts = np.count_nonzero(np.diff(runs.astype(int)) == 1)
    assert 40 < runs.sum() / max(starts, 1) < 90
    assert crossed_runs(np.random.default_rng(1), 50, 1.0, 60).all()
    assert not crossed_runs(np.random.default_rng(1), 50, 0.0, 60).any()


def test_calibrate_with_the_person_crossed_for_the_whole_clip():
    scene = make_scene(frames=300, seed=38, geometry="gym", lr_crossed_view="real")
    run = calibrate(scene.detections, scene.intrinsics,
                    CalibrateOptions(refine=False, left_right="clip"))
    assert mirror_rotation_error_deg(run.calibration.normal, scene.normal) < 1.0
    assert _right_share(run.paired, scene) >= 0.95
    frame = calibrate(scene.detections, scene.intrinsics,
                      CalibrateOptions(refine=False, left_right="frame"))
    assert _right_share(frame.paired, scene) < 0.5      # each frame alone keeps them crossed


@pytest.mark.parametrize("views", ["real", "both"])
def test_each_persons_track_is_decided_apart(views):
    crowd = make_crowd(people=3, frames=200, seed=3, occluded_rate=0.3)
    pairing = pair_people(crowd.detections)
    paired, base = pairing.paired, pairing.base
    J, flip = base.num_joints, base.flip
    block = np.arange(J, 2 * J)                          # the second person's track
    crossed = paired.real.copy(), paired.mirror.copy()
    crossed[0][:, block] = paired.real[:, block][:, flip]
    if views == "both":                                  # consistent, a body whose left is its right
        crossed[1][:, block] = paired.mirror[:, block][:, flip]
    bad = replace(paired, real=crossed[0], mirror=crossed[1])
    fixed, n = clip_left_right_people(bad, base, crowd.K, pairing.epipole)
    assert n > 0
    seen = (paired.real[:, block, 2] > 0).any(1)
    same = [np.isclose(np.nan_to_num(f[:, block, :2]), np.nan_to_num(o[:, block, :2])).all((1, 2))
            for f, o in ((fixed.real, paired.real), (fixed.mirror, paired.mirror))]
    assert (same[0] & same[1])[seen].mean() >= 0.95
    others = np.r_[0:J, 2 * J:3 * J]
    for f, o in ((fixed.real, paired.real), (fixed.mirror, paired.mirror)):
        kept = np.isclose(np.nan_to_num(f[:, others]), np.nan_to_num(o[:, others])).all((1, 2))
        assert kept.mean() >= 0.99
