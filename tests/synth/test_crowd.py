"""Synthetic gym scenes (mirrorgraph.synth.crowd): the truth of every detection."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.synth.camera import project
from mirrorgraph.synth.crowd import make_crowd


@pytest.fixture(scope="module")
def crowd():
    return make_crowd(people=4, frames=120, seed=5, occluded_rate=1.0, noise_std=2.0)


def test_every_detection_is_whose_it_says(crowd):
    n, d = crowd.normal, crowd.distance
    flip = crowd.skeleton.flip
    for t in range(0, 120, 7):
        for det, p, refl in zip(crowd.detections.people[t], crowd.truth_person[t],
                                crowd.truth_reflection[t]):
            X = crowd.joints3d[p, t]
            if refl:
                X = (X - 2.0 * ((X @ n) - d)[:, None] * n)[flip]   # the detector's labels
            err = np.linalg.norm(det[:, :2] - project(crowd.K, X), axis=-1)
            assert np.nanmedian(err) < 8.0


def test_people_before_the_mirror_and_apart(crowd):
    X = crowd.joints3d
    assert np.all(X @ crowd.normal < crowd.distance)
    assert np.all((crowd.person_to_mirror > 0.5) & (crowd.person_to_mirror < 4.5))
    assert np.all((crowd.heights >= 1.55) & (crowd.heights <= 1.95))
    floor = X[:, 0].reshape(4, -1, 3).mean(1)
    gaps = [np.linalg.norm(floor[a] - floor[b]) for a in range(4) for b in range(a)]
    assert min(gaps) > 0.5


def test_occlusions_hide_detections(crowd):
    assert crowd.occluded.any()
    for p, v, t in zip(*np.nonzero(crowd.occluded)):
        listed = (crowd.truth_person[t] == p) & (crowd.truth_reflection[t] == bool(v))
        assert not listed.any()


def test_same_seed_same_scene():
    a = make_crowd(people=3, frames=30, seed=9)
    b = make_crowd(people=3, frames=30, seed=9)
    np.testing.assert_array_equal(a.joints3d, b.joints3d)
    for x, y in zip(a.detections.people, b.detections.people):
        np.testing.assert_array_equal(x, y)
