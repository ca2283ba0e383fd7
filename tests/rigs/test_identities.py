"""Who is who across snapshots (:mod:`mirrorgraph.rigs.identities`): people told apart by
their bone lengths, against the synthetic truth."""

from __future__ import annotations

import numpy as np

from mirrorgraph.rigs.identities import calibration_bones, slots_by_body
from mirrorgraph.rigs.people import associate_people
from mirrorgraph.skeletons import skeleton_by_name
from mirrorgraph.synth.rig_people import make_rig_people

from .test_people import _observed, _owners


def test_slots_by_body_tell_people_apart_by_their_bones():
    """Three bodies 1.60 / 1.75 / 1.90 m tall, their bones measured with 3 % noise and some
    missing in 40 stretches, a person absent from a fifth of them: each slot one body."""
    rng = np.random.default_rng(0)
    B = len(calibration_bones(skeleton_by_name("BODY_25")))
    shape = rng.uniform(0.15, 0.45, B)
    heights = np.array([1.60, 1.75, 1.90])
    lengths, stretch, who = [], [], []
    for s in range(40):
        for p in rng.permutation(3):
            if rng.random() < 0.2:
                continue
            lb = shape * heights[p] * (1 + rng.normal(0, 0.03, B))
            lb[rng.random(B) < 0.2] = np.nan
            lengths.append(lb)
            stretch.append(s)
            who.append(p)
    slot = slots_by_body(np.array(lengths), np.array(stretch), 3)
    who, stretch = np.array(who), np.array(stretch)
    for s in np.unique(stretch):                     # one person of a stretch a slot
        assert len(set(slot[stretch == s])) == np.count_nonzero(stretch == s)
    for k in range(3):
        mine = who[slot == k]
        assert np.bincount(mine, minlength=3).max() == len(mine)


def test_snapshots_people_keep_their_slot_by_body():
    """A rig of snapshots (people turned and placed anew each frame): the association with
    the rig puts each person in one slot over the snapshots, by their bones (heights
    1.74-1.95 m here); a slot of a packing would hold whoever is free."""
    rig = make_rig_people(4, 3, frames=30, seed=17, snapshots=True, noise_std=4.0,
                          outlier_rate=0.02)
    a = associate_people(_observed(rig), rig.K, rig.poses)
    owners = _owners(rig, a)
    held = [owners[..., p][owners[..., p] >= 0] for p in range(a.count)]
    pure = sum(np.bincount(h).max() for h in held if len(h))
    total = sum(len(h) for h in held)
    detected = sum(len(o) for n in rig.camera_names for o in rig.owner[n])
    assert total >= 0.9 * detected
    assert pure >= 0.95 * total
