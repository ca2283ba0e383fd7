"""Every person paired with their own reflection and tracked (mirrorgraph.initial.people),
and the layout of several people (mirrorgraph.skeletons.people_skeleton)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mirrorgraph.anthropometry import bone_kind
from mirrorgraph.initial.people import PeopleOptions, pair_people, split_people
from mirrorgraph.skeletons import COCO_17, people_skeleton
from mirrorgraph.synth.crowd import make_crowd


def _truth(crowd, pairing):
    """Wrong pairs, identity switches and the true people each track follows."""
    wrong = switches = 0
    owners = []
    for k in range(pairing.num_people):
        own = []
        for t, (a, b) in enumerate(pairing.detections[:, k]):
            if a < 0:
                continue
            tp, tr = crowd.truth_person[t], crowd.truth_reflection[t]
            wrong += int(tp[a] != tp[b] or tr[a] or not tr[b])
            own.append(tp[a])
        switches += int(np.count_nonzero(np.diff(own) != 0))
        owners.append(int(np.bincount(own).argmax()))
    return wrong, switches, owners


@pytest.fixture(scope="module")
def crowd():
    return make_crowd(people=3, frames=200, seed=3, occluded_rate=0.5, outlier_rate=0.03,
                      lr_swap_rate=0.05)


def test_every_person_with_their_own_reflection(crowd):
    pairing = pair_people(crowd.detections)
    wrong, switches, owners = _truth(crowd, pairing)
    pairs = int(np.count_nonzero(pairing.detections[..., 0] >= 0))
    both = sum(int(np.count_nonzero(~crowd.occluded[p].any(0))) for p in range(3))
    assert pairs > 0.9 * both                      # every person, not one a frame
    assert wrong <= 0.01 * pairs
    assert switches == 0
    assert sorted(set(owners)) == [0, 1, 2]
    e = crowd.K @ crowd.normal
    e_est = pairing.epipole
    assert np.linalg.norm(e_est[:2] / e_est[2] - e[:2] / e[2]) < 50.0       # px, the pairing's own
    # the people side by side, labels of the reflection flipped to the real joints
    R = split_people(pairing.paired.real, pairing.num_people)
    M = split_people(pairing.paired.mirror, pairing.num_people)
    k, t = 0, int(np.flatnonzero(pairing.detections[:, 0, 0] >= 0)[0])
    a, b = pairing.detections[t, k]
    np.testing.assert_array_equal(R[k, t], crowd.detections.people[t][a])
    refl = crowd.detections.people[t][b]
    assert crowd.truth_reflection[t][b]
    assert (np.array_equal(M[k, t], refl[COCO_17.flip], equal_nan=True)
            or np.array_equal(M[k, t], refl, equal_nan=True))   # a left/right confusion


def test_frames_far_apart_are_not_continued(crowd):
    raw = crowd.detections
    gap = replace(raw, frame_ids=np.where(np.arange(len(raw.frame_ids)) < 100, raw.frame_ids,
                                          raw.frame_ids + 10_000))
    pairing = pair_people(gap, people=PeopleOptions(max_gap=60))
    det = pairing.detections[..., 0] >= 0
    for k in range(pairing.num_people):       # no track spans the gap
        assert not (det[:100, k].any() and det[100:, k].any())
    assert pairing.num_people >= 6


def test_people_skeleton():
    sk = people_skeleton(COCO_17, 3)
    J = COCO_17.num_joints
    assert sk.num_joints == 3 * J
    np.testing.assert_array_equal(sk.flip, np.concatenate([COCO_17.flip + p * J
                                                           for p in range(3)]))
    assert len(sk.bones) == 3 * len(COCO_17.bones)
    assert (sk.bone_index // J == np.repeat(np.arange(3), len(COCO_17.bones))[:, None]).all()
    assert bone_kind("left_femur@2") == "femur" and bone_kind("left_femur") == "femur"
    assert people_skeleton(COCO_17, 1) is COCO_17
