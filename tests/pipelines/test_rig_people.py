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
    scatter's share), a joint that moves farther than a cell every frame weighs 1, a
    column never seen 1; without a constant error (``rho`` 0) every frame weighs 1."""
    from mirrorgraph.pipelines.rig_people import DETECTOR_BIAS_PX, track_weights

    rng = np.random.default_rng(0)
    T = 100
    real = np.zeros((2, T, 3, 3))
    real[..., 2] = 1.0
    real[:, :, 0, :2] = 500.0 + 3.0 + rng.uniform(0, 2, (2, T, 2))      # still, one cell
    real[:, :, 1, 0] = 100.0 + 3 * DETECTOR_BIAS_PX * np.arange(T)        # walks
    real[:, :, 1, 1] = 300.0
    real[:, :, 2] = (np.nan, np.nan, 0.0)                                 # never seen
    rho = 6.0
    for ids in (None, np.arange(T)):
        w = track_weights(real, rho, frame_ids=ids)
        np.testing.assert_allclose(w[:, 0], (1 + rho) / (1 + rho * T))    # one cluster
        assert (w[:, 0] * T < 2.0).all()
        np.testing.assert_allclose(w[:, 1:], 1.0)
    np.testing.assert_allclose(track_weights(real, 0.0), 1.0)
    # the scatter alone (4 px about one place) does not move a smoothed joint out of
    # its cell as often as the raw positions do
    real[:, :, 0, :2] = 505.0 + rng.normal(0.0, 4.0, (2, T, 2))
    raw, smooth = track_weights(real, rho), track_weights(real, rho, frame_ids=np.arange(T))
    assert (smooth[:, 0] < raw[:, 0]).all() and (smooth[:, 0] * T < 5.0).all()


def test_bias_ratio_measures_a_repeated_error():
    """Independent errors: ``rho`` about 0; a constant error per camera and joint of
    2.5x the scatter: about ``2.5^2``, under the true rig, per camera and person."""
    from mirrorgraph.geometry import camera_projection
    from mirrorgraph.pipelines.rig_people import bias_ratio

    rig = make_rig_people(3, 1, frames=150, seed=5, occlusion_rate=0.0)
    X = rig.joints3d[0]                                                   # (T, J, 3)
    Ps = [camera_projection(K, P) for K, P in zip(rig.K, rig.poses)]
    rng = np.random.default_rng(1)
    clean = np.stack([np.concatenate([(X @ P[:, :3].T + P[:, 3])[..., :2]
                                      / (X @ P[:, :3].T + P[:, 3])[..., 2:3],
                                      np.ones(X.shape[:2] + (1,))], -1) for P in Ps])
    cols = np.ones(X.shape[1], bool)
    ids = np.arange(len(X))
    noisy = clean.copy()
    noisy[..., :2] += rng.normal(0.0, 4.0, noisy[..., :2].shape)
    assert bias_ratio(noisy, ids, rig.K, rig.poses, cols, 40.0).shape == (3, 1)
    assert (bias_ratio(noisy, ids, rig.K, rig.poses, cols, 40.0) < 0.05).all()
    biased = noisy.copy()
    biased[..., :2] += rng.normal(0.0, 10.0, (3, 1, X.shape[1], 2))
    rho = bias_ratio(biased, ids, rig.K, rig.poses, cols, 60.0)
    assert ((rho > 3.0) & (rho < 10.0)).all(), rho
    # two people side by side, only the second biased: measured apart
    two = np.concatenate([noisy, biased], 2)
    rho = bias_ratio(two, ids, rig.K, rig.poses, np.ones(2 * X.shape[1], bool), 60.0, 2)
    assert (rho[:, 0] < 0.05).all() and (rho[:, 1] > 3.0).all(), rho
    # snapshots far apart: no consecutive frames, nothing measured
    assert (bias_ratio(biased, ids * 2250, rig.K, rig.poses, cols, 60.0) == 0.0).all()


def test_a_still_person_with_a_repeated_error_pulls_less(tmp_path, monkeypatch):
    """A rig of three people, one standing still with a constant 8 px error per camera and
    joint: with the track weights every camera is no worse than from one person and
    nearer the truth than the same graph weighing every frame alike (which is worse than
    one person), and the constant error is measured (``rho`` of the second round)."""
    import mirrorgraph.pipelines.rig_people as rp

    rig = make_rig_people(3, 3, frames=100, seed=22, still=1, bias_px=8.0,
                          outlier_rate=0.02, lr_swap_rate=0.02)
    path = write_rig_people(rig, tmp_path)
    cal = calibrate_rig(path, CalibrateOptions(people="all"))
    one = _rotations(rig, calibrate_rig(path, CalibrateOptions(people="one")))
    monkeypatch.setattr(rp, "TRACK_WEIGHTS", False)
    plain = calibrate_rig(path, CalibrateOptions(people="all"))
    weighted, flat = _rotations(rig, cal), _rotations(rig, plain)
    assert (weighted < flat).all(), (weighted, flat)
    assert (weighted <= one).all() and np.median(flat) > np.median(one), (weighted, one, flat)
    rounds = cal.refinement["people"]["rounds"]
    assert rounds[1]["solved"] and np.max(rounds[1]["rho"]) > 1.0
