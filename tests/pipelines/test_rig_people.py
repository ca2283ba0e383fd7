"""``calibrate_rig`` from every person (``people="all"``) against the ground truth of a
small synthetic rig of several people (:mod:`mirrorgraph.synth.rig_people`)."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.metrics import rotation_error_deg
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.pipelines.rig import calibrate_rig
from mirrorgraph.synth.rig_people import make_rig_people, write_rig_people


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A 3-camera rig of 3 people (occlusions, 2 % outliers): both runs."""
    rig = make_rig_people(3, 3, frames=60, seed=21, outlier_rate=0.02, occlusion_rate=0.5)
    path = write_rig_people(rig, tmp_path_factory.mktemp("rp"))
    return rig, {m: calibrate_rig(path, CalibrateOptions(people=m)) for m in ("one", "all")}


def _rotations(rig, cal) -> np.ndarray:
    return np.array([rotation_error_deg(c.pose[:3, :3], P[:3, :3])
                     for c, P in zip(cal.cameras[1:], rig.poses[1:])])


def test_every_person_calibrates_better(runs):
    rig, cal = runs
    one, every = _rotations(rig, cal["one"]), _rotations(rig, cal["all"])
    assert every.max() < 0.15
    assert np.median(every) < np.median(one)
    assert cal["all"].num_people == 3 and cal["one"].num_people == 1
    rec = cal["all"].refinement["people"]
    assert rec["mode"] == "all" and rec["count"] == 3 and rec["found"] == 3
    assert rec["rounds"][0]["solved"]
    assert "people: 3 in the one graph" in cal["all"].summary()
    assert not any("calibrating from the one seen longest" in w for w in cal["all"].warnings)


def test_every_persons_joints(runs):
    """Each person's joints (one scale for the rig, from the cameras' centres) within a
    few centimetres of their true joints, every person found once."""
    rig, cal = runs
    c = cal["all"]
    Ce = np.array([x.pose[:3, 3] for x in c.cameras[1:]])
    Ct = np.array([P[:3, 3] for P in rig.poses[1:]])
    s = float(np.sum(Ce * Ct) / np.sum(Ce * Ce))
    X, ok = c.people_joints3d * s, c.people_valid
    assert X.shape == (3,) + rig.joints3d.shape[1:]
    np.testing.assert_array_equal(c.joints3d, c.people_joints3d[0])
    found = []
    for p in range(3):
        err = [np.nanmedian(np.linalg.norm(X[p][ok[p]] - rig.joints3d[q][ok[p]], axis=-1))
               for q in range(3)]
        found.append(int(np.argmin(err)))
        assert min(err) < 0.03
    assert sorted(found) == [0, 1, 2]


def test_people_option_checked():
    with pytest.raises(InputError, match="people"):
        CalibrateOptions(people="everyone").checked()


def test_track_weights_count_independent_frames():
    """A joint standing still for 100 frames weighs about one frame's worth (plus the
    scatter's share), a joint that moves farther than the constant error every frame
    weighs 1, a column never seen 1."""
    from mirrorgraph.pipelines.rig_people import DETECTOR_BIAS_PX, track_weights

    rng = np.random.default_rng(0)
    T = 100
    real = np.zeros((2, T, 3, 3))
    real[..., 2] = 1.0
    real[:, :, 0, :2] = 500.0 + 3.0 + rng.uniform(0, 2, (2, T, 2))      # still, one cell
    real[:, :, 1, 0] = 100.0 + 3 * DETECTOR_BIAS_PX * np.arange(T)        # walks
    real[:, :, 1, 1] = 300.0
    real[:, :, 2] = (np.nan, np.nan, 0.0)                                 # never seen
    w = track_weights(real, pixel_sigma=4.0)
    rho = (DETECTOR_BIAS_PX / 4.0) ** 2
    np.testing.assert_allclose(w[:, 0], (1 + rho) / (1 + rho * T))        # one cluster
    assert (w[:, 0] * T < 2.0).all()
    np.testing.assert_allclose(w[:, 1:], 1.0)
