"""Every person associated across a rig's cameras (:func:`mirrorgraph.rigs.people.associate_people`),
against the synthetic truth of :func:`mirrorgraph.synth.rig_people.make_rig_people`."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.intrinsics import Intrinsics
from mirrorgraph.rigs.observations import CameraObservations, RigObservations
from mirrorgraph.rigs.people import PeopleAssociation, associate_people
from mirrorgraph.synth.rig_people import make_rig_people


def _observed(rig, tmp_path=None) -> RigObservations:
    """The rig's detections as the observations the association reads (every detection a
    candidate, no subject chosen: the one-person path is not what is tested here)."""
    T, J = len(rig.frame_ids), rig.skeleton.num_joints
    cams = []
    for name, K in zip(rig.camera_names, rig.K):
        real = np.full((T, J, 3), np.nan)
        real[..., 2] = 0.0
        cams.append(CameraObservations(name=name, intrinsics=Intrinsics(K=K), real=real,
                                       people=list(rig.detections[name].people)))
    return RigObservations(skeleton=rig.skeleton, frame_ids=rig.frame_ids, cameras=cams,
                           mirrors=())


def _owners(rig, a: PeopleAssociation) -> np.ndarray:
    """``(C, T, P)`` the true person of each slot's detection (-1: none)."""
    out = np.full((len(a.index),) + a.index[0].shape, -1)
    for c, ix in enumerate(a.index):
        own = rig.owner[rig.camera_names[c]]
        for t, p in zip(*np.nonzero(ix >= 0)):
            out[c, t, p] = own[t][ix[t, p]]
    return out


def _slot_people(owners: np.ndarray) -> list[set]:
    return [set(owners[..., p][owners[..., p] >= 0].tolist()) for p in range(owners.shape[-1])]


def test_every_person_in_one_slot_each(tmp_path):
    """Four people, four cameras, occlusions and left/right swaps: with the true rig each
    slot holds one person only, every person is found, and every detection seen by two
    cameras is kept but for the swapped ones."""
    rig = make_rig_people(4, 4, frames=80, seed=5, occlusion_rate=0.6, lr_swap_rate=0.03,
                          outlier_rate=0.02)
    obs = _observed(rig, tmp_path)
    a = associate_people(obs, rig.K, rig.poses)
    owners = _owners(rig, a)
    assert a.count == 4 and a.people_found == 4
    assert sorted(min(s) for s in _slot_people(owners)) == [0, 1, 2, 3]
    assert all(len(s) == 1 for s in _slot_people(owners))
    detections = sum(len(o) for own in rig.owner.values() for o in own)
    kept = int(np.count_nonzero(owners >= 0))
    assert kept >= 0.95 * detections
    assert a.lr_dropped > 0                       # the swapped labels are left out
    assert a.changed(a) == 0.0 and a.changed(None) == 1.0


def test_occluded_person_keeps_their_slot(tmp_path):
    """A person hidden from a camera for 5-20 frames comes back in their own slot there."""
    rig = make_rig_people(3, 3, frames=90, seed=8, occlusion_rate=1.0)
    obs = _observed(rig, tmp_path)
    a = associate_people(obs, rig.K, rig.poses)
    owners = _owners(rig, a)
    assert all(len(s) == 1 for s in _slot_people(owners))
    for c, name in enumerate(rig.camera_names):
        hidden = rig.occluded[name]
        for p in range(3):
            slot = int(np.flatnonzero([p in s for s in _slot_people(owners)])[0])
            after = np.flatnonzero(hidden[p])
            if len(after) and after[-1] + 1 < 90:
                t = after[-1] + 1                  # the first frame seen again
                assert owners[c, t, slot] == p


def test_snapshots_share_no_track(tmp_path):
    """Snapshots far apart: no continuity assumed, still one person a slot a frame and no
    detection given to another person."""
    rig = make_rig_people(4, 3, frames=30, seed=2, snapshots=True)
    obs = _observed(rig, tmp_path)
    a = associate_people(obs, rig.K, rig.poses)
    owners = _owners(rig, a)
    for t in range(30):                           # within a frame a slot is one person
        for p in range(a.count):
            who = owners[:, t, p]
            assert len(set(who[who >= 0].tolist())) <= 1
    seen = sum(int(np.count_nonzero(np.sum(owners[:, t] >= 0, axis=0) >= 2))
               for t in range(30))
    assert seen >= 0.95 * 30 * 3


def test_wrong_rig_associates_nothing_wrong(tmp_path):
    """With a camera placed wrong its detections join no one (nothing else fits)."""
    rig = make_rig_people(3, 2, frames=40, seed=4)
    obs = _observed(rig, tmp_path)
    poses = [np.array(P) for P in rig.poses]
    R = poses[2][:3, :3]
    c, s = np.cos(0.3), np.sin(0.3)
    poses[2][:3, :3] = R @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    a = associate_people(obs, rig.K, poses)
    owners = _owners(rig, a)
    assert all(len(s) <= 1 for s in _slot_people(owners))
    assert np.count_nonzero(owners[2] >= 0) < 0.1 * np.count_nonzero(owners[0] >= 0)


@pytest.mark.parametrize("snapshots", [False, True])
def test_observations_in_the_people_layout(tmp_path, snapshots):
    rig = make_rig_people(3, 2, frames=20, seed=1, snapshots=snapshots)
    obs = _observed(rig, tmp_path)
    a = associate_people(obs, rig.K, rig.poses)
    po = a.observations(obs)
    J = obs.skeleton.num_joints
    assert po.skeleton.num_joints == a.count * J
    assert po.cameras[0].real.shape == (20, a.count * J, 3)
    t, p = np.argwhere(a.index[1] >= 0)[0]
    np.testing.assert_array_equal(po.cameras[1].real[t, p * J:(p + 1) * J],
                                  obs.cameras[1].people[t][a.index[1][t, p]])
