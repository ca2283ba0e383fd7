"""Every camera's person on snapshots (:func:`mirrorgraph.rigs.observations.load_observations`),
against the synthetic truth: the reference camera's person a frame, matched in every other
camera without following anyone over time."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mirrorgraph.rigs.config import load_rig_config
from mirrorgraph.rigs.observations import load_observations
from mirrorgraph.rigs.people import candidate_index
from mirrorgraph.synth.rig_people import make_rig_people, write_rig_people


@pytest.mark.parametrize("numbered", ["far apart", "frame after frame"])
def test_snapshots_every_camera_holds_the_reference_person(tmp_path, numbered):
    """Snapshots 2250 frames apart, or the same numbered 0, 1, 2, ...: each camera's person
    is the first camera's in every frame both hold one (the first camera's person is a
    frame's most confident detection, any of the four people)."""
    T = 30
    rig = make_rig_people(3, 4, frames=T, seed=6, snapshots=True, noise_std=4.0,
                          outlier_rate=0.02)
    if numbered == "frame after frame":
        rig.detections = {n: replace(d, frame_ids=np.arange(T))
                          for n, d in rig.detections.items()}
    obs = load_observations(load_rig_config(write_rig_people(rig, tmp_path)))
    who = []
    for c, cam in enumerate(obs.cameras):
        own, ix = rig.owner[rig.camera_names[c]], candidate_index(cam)
        who.append(np.array([own[t][ix[t]] if ix[t] >= 0 else -1 for t in range(T)]))
    assert len(set(who[0][who[0] >= 0].tolist())) > 1        # not one person followed
    for w in who[1:]:
        both = (who[0] >= 0) & (w >= 0)
        assert np.count_nonzero(both) >= 0.8 * T
        assert np.all(w[both] == who[0][both])
