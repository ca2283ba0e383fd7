"""The synthetic rigs of several people (:func:`mirrorgraph.synth.rig_people.make_rig_people`)."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.synth.camera import project
from mirrorgraph.synth.rig_people import MIN_SPACING, SNAPSHOT_GAP, make_rig_people


def test_detections_are_the_people_seen():
    rig = make_rig_people(3, 3, frames=40, seed=0, noise_std=0.0, occlusion_rate=1.0)
    assert rig.joints3d.shape == (3, 40, 25, 3)
    for c, name in enumerate(rig.camera_names):
        R, C = rig.poses[c][:3, :3], rig.poses[c][:3, 3]
        for t in (0, 20, 39):
            for row, p in zip(rig.detections[name].people[t], rig.owner[name][t]):
                uv = project(rig.K[c], (rig.joints3d[p, t] - C) @ R)
                ok = row[:, 2] > 0
                np.testing.assert_allclose(row[ok, :2], uv[ok], atol=1e-6)
        hidden = rig.occluded[name]
        assert hidden.any(1).all()                      # every person hidden once
        for p in range(3):
            for t in np.flatnonzero(hidden[p]):
                assert p not in rig.owner[name][t]
    centres = rig.joints3d.mean(2)[..., [0, 2]]
    d = np.linalg.norm(centres[:, None] - centres[None], axis=-1)
    assert d[~np.eye(3, dtype=bool)].min() > 0.5 * MIN_SPACING


def test_snapshots_and_errors():
    rig = make_rig_people(3, 2, frames=5, seed=1, snapshots=True)
    assert np.all(np.diff(rig.frame_ids) == SNAPSHOT_GAP)
    with pytest.raises(ValueError, match="cameras"):
        make_rig_people(1, 2)
    with pytest.raises(ValueError, match="occlusion_rate"):
        make_rig_people(3, 2, occlusion_rate=2.0)
