"""Pairing person and reflection on synthetic detections with known truth."""

import warnings

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.keypoints import RawDetections
from mirrorgraph.initial.clip_left_right import clip_left_right
from mirrorgraph.initial.left_right import fix_left_right
from mirrorgraph.initial.pairing import pair_detections
from mirrorgraph.synth import make_scene


def _agreement(paired, scene):
    """Fraction of paired frames whose real/mirror rows match the clean truth."""
    ok = np.isfinite(paired.real[..., 0]).any(1)
    d_real = np.nanmedian(np.linalg.norm(paired.real[ok, :, :2] - scene.real_clean[ok], axis=-1), 1)
    d_mirr = np.nanmedian(np.linalg.norm(paired.mirror[ok, :, :2] - scene.mirror_clean[ok], axis=-1), 1)
    return np.mean((d_real < 20) & (d_mirr < 20)), ok


def test_pairs_shuffled_people_and_flips_reflection():
    scene = make_scene(frames=300, seed=11)
    paired = pair_detections(scene.detections)
    agree, ok = _agreement(paired, scene)
    assert ok.mean() > 0.97
    assert agree > 0.99
    assert paired.lr_fixes == 0


def test_left_right_confusions_are_detected_per_frame():
    scene = make_scene(frames=300, seed=12, lr_swap_rate=0.2)
    paired = pair_detections(scene.detections)
    agree, _ = _agreement(paired, scene)
    assert agree > 0.98
    assert abs(paired.lr_fixes - scene.lr_swapped.sum()) <= 0.05 * len(scene.lr_swapped)


def test_missing_single_and_extra_people():
    scene = make_scene(frames=300, seed=13, single_person_rate=0.15, extra_person_rate=0.2,
                       missing_rate=0.05, outlier_rate=0.05)
    paired = pair_detections(scene.detections)
    agree, ok = _agreement(paired, scene)
    assert agree > 0.97
    # frames with one person detected cannot be paired
    one = np.array([len(p) < 2 for p in scene.detections.people])
    assert not ok[one].any()


def test_fix_left_right_on_paired_input():
    scene = make_scene(frames=300, seed=14, lr_swap_rate=0.15)
    truth = scene.paired()
    # make the reflection's labels wrong where the detector swapped them
    bad = truth.mirror.copy()
    flip = truth.skeleton.flip
    bad[scene.lr_swapped] = bad[scene.lr_swapped][:, flip]
    from dataclasses import replace
    fixed = fix_left_right(replace(truth, mirror=bad))

    def right(p):
        return np.mean(np.isclose(p.mirror[..., 0], truth.mirror[..., 0])
                       | np.isnan(truth.mirror[..., 0]))

    assert right(fixed) > 0.99
    assert abs(fixed.lr_fixes - scene.lr_swapped.sum()) <= 3
    # then the whole clip's decision, as calibrate runs them on paired input
    clipped, _ = clip_left_right(fixed, scene.K)
    assert right(clipped) > 0.99
    assert abs(clipped.lr_fixes - scene.lr_swapped.sum()) <= 3


def test_reflection_missing_everywhere_is_an_input_error():
    scene = make_scene(frames=50, seed=15)
    lonely = RawDetections(skeleton=scene.skeleton, frame_ids=scene.detections.frame_ids,
                           people=[p[:1] for p in scene.detections.people], source="lonely.json")
    with pytest.raises(InputError, match="lonely.json.*reflection is missing"):
        pair_detections(lonely)


def test_candidates_are_every_pair_of_every_frame_in_order():
    """The vectorised candidate list equals the plain loop over frames and pairs."""
    from mirrorgraph.initial.pair_candidates import PairingOptions, candidates, masked

    s = make_scene(frames=300, seed=9, extra_person_rate=0.3, single_person_rate=0.2,
                   missing_rate=0.1)
    rng = np.random.default_rng(0)
    people = list(s.detections.people)
    for t in range(0, 300, 17):                       # crowds beyond max_people too
        extra = rng.uniform(0, 1000, (int(rng.integers(1, 8)), 17, 3))
        people[t] = np.concatenate([people[t], extra])
    raw = RawDetections(skeleton=s.skeleton, frame_ids=s.frame_ids, people=people)
    opts = PairingOptions(max_people=4)
    got = candidates(raw, opts)
    frame, a, b, ia, ib = [], [], [], [], []
    for t, p in enumerate(people):
        if len(p) < 2:
            continue
        p = masked(p, opts.min_confidence)
        index = np.arange(len(p))
        if len(p) > opts.max_people:
            index = np.sort(np.argsort(-p[..., 2].mean(1), kind="stable")[:opts.max_people])
        for i, k in zip(*np.triu_indices(len(index), 1)):
            frame.append(t)
            a.append(p[index[i]])
            b.append(p[index[k]][s.skeleton.flip])
            ia.append(index[i])
            ib.append(index[k])
    assert np.array_equal(got.frame, frame) and np.array_equal(got.ia, ia)
    assert np.array_equal(got.ib, ib)
    assert np.array_equal(got.a, np.array(a), equal_nan=True)
    assert np.array_equal(got.b, np.array(b), equal_nan=True)


def test_frame_scores_are_the_noise_for_a_reflection():
    from mirrorgraph.initial.pair_scores import frame_scores

    s = make_scene(frames=200, seed=4, single_person_rate=0.2)
    from mirrorgraph.geometry import epipole_from_normal
    e = epipole_from_normal(s.K, s.normal)
    raw_scores = frame_scores(s.detections, e)
    both = s.real_detected & s.mirror_detected
    assert np.isnan(raw_scores[~both]).all() and np.isfinite(raw_scores[both]).all()
    assert 1.5 < np.median(raw_scores[both]) < 5.0           # 4 px noise
    # paired input: the same frames, the same scores
    paired_scores = frame_scores(s.paired(), e)
    assert np.allclose(paired_scores[both], raw_scores[both])
    low = frame_scores(s.detections, e, quantile=(0.5, 0.3))
    assert low.shape == (2, 200) and np.all(low[1][both] <= low[0][both])


def test_nanmedian_rows_is_numpys_nanmedian():
    from mirrorgraph.initial.pair_candidates import nanmedian_rows

    rng = np.random.default_rng(5)
    for n in (1, 2, 7, 12, 17):
        x = rng.normal(0, 10, (300, n))
        x[rng.random(x.shape) < 0.3] = np.nan
        x[0] = np.nan
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            expected = np.nanmedian(x, axis=1)
        np.testing.assert_array_equal(nanmedian_rows(x), expected)
    assert nanmedian_rows(np.zeros((3, 0))).shape == (3,)


def test_one_frame_pairing_is_the_batch_pairing():
    """pair_frame_with_epipole gives every frame what pair_with_epipoles gives it, with
    left/right swaps, single people and bystanders among the frames, and recovers the
    true person and reflection."""
    from mirrorgraph.initial.pairing import (pair_frame_with_epipole, pair_reflections,
                                             pair_with_epipoles)

    scene = make_scene(frames=200, seed=14, lr_swap_rate=0.2, single_person_rate=0.1,
                       extra_person_rate=0.15)
    raw = scene.detections
    e = pair_reflections(raw, 1).epipoles[0]
    sk = raw.skeleton
    right = 0
    counts = set()
    for t, people in enumerate(raw.people):
        one = RawDetections(sk, np.array([t]), [people])
        batch = pair_with_epipoles(one, [e])
        real, mirror = pair_frame_with_epipole(people, e, sk)
        np.testing.assert_array_equal(real, batch.real[0])
        np.testing.assert_array_equal(mirror, batch.reflections[0][0])
        counts.add(min(len(people), 3))
        if np.isfinite(real[:, 0]).any():
            d = np.nanmedian(np.linalg.norm(real[:, :2] - scene.real_clean[t], axis=-1))
            dm = np.nanmedian(np.linalg.norm(mirror[:, :2] - scene.mirror_clean[t], axis=-1))
            right += bool(d < 20 and dm < 20)
    assert counts == {1, 2, 3}
    assert right > 0.8 * len(raw.people)
