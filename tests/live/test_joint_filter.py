"""Each joint's track over time (mirrorgraph.live.joint_filter): the filter and its
fixed-lag smoother against the batch estimate, the outlier gate, restarts."""

from __future__ import annotations

import numpy as np

from mirrorgraph.completion import smooth_tracks
from mirrorgraph.live.joint_filter import JointFilter


def _tracks(T=40, J=3, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(T)[:, None, None]
    truth = 0.5 * np.sin(0.15 * t + np.arange(J)[None, :, None] + np.arange(3)) + 4.0
    A = rng.normal(size=(T, J, 3, 3)) * 0.02
    cov = A @ A.transpose(0, 1, 3, 2) + 1e-4 * np.eye(3)        # anisotropic, as two rays
    z = truth + np.einsum("tjab,tjb->tja", np.linalg.cholesky(cov), rng.normal(size=(T, J, 3)))
    return truth, z, cov


def test_the_filter_and_its_lag_are_the_batch_estimate_of_the_frames_so_far():
    # no gate: the filter's newest point is the maximum a posteriori point over every
    # frame so far under the second-difference prior (completion.smooth_tracks), and the
    # smoother's frame `lag` back is that batch's point at that frame
    truth, z, cov = _tracks()
    T, J = z.shape[:2]
    sigma, lag = 0.01, 4
    f = JointFilter(J, sigma, max_gap=4, gate_chi2=np.inf, velocity_std=100.0, lag=lag)
    info = np.linalg.inv(cov)
    ids = np.arange(T)
    mask = np.ones((T, J), bool)
    for t in range(T):
        X, C, taken = f.step(t, np.arange(J), z[t], cov[t])
        assert taken.all()
        if t < 3:
            continue
        S, Cs = smooth_tracks(z[:t + 1], info[:t + 1], mask[:t + 1], ids[:t + 1], sigma, 4)
        np.testing.assert_allclose(X, S[t], atol=2e-5)
        np.testing.assert_allclose(C, Cs[t], rtol=2e-3, atol=1e-9)
        if t >= lag + 3:
            Xs, Ps = f.smoothed(t - lag)
            np.testing.assert_allclose(Xs, S[t - lag], atol=2e-5)
            np.testing.assert_allclose(Ps, Cs[t - lag], rtol=2e-3, atol=1e-9)


def test_an_outlier_is_gated_and_a_lasting_jump_restarts_the_track():
    truth, z, cov = _tracks(T=60, J=1, seed=1)
    f = JointFilter(1, 0.01, max_gap=4, restart_after=3)
    z = z.copy()
    z[30, 0] += [0.0, 0.0, 0.8]                         # one frame 0.8 m off in depth
    z[45:, 0] += [1.0, 0.0, 0.0]                        # the person moved: a lasting jump
    out, taken = np.zeros((60, 3)), np.zeros(60, bool)
    for t in range(60):
        X, _, k = f.step(t, [0], z[t:t + 1, 0], cov[t:t + 1, 0])
        out[t], taken[t] = X[0], k[0]
    assert not taken[30] and np.linalg.norm(out[30] - truth[30, 0]) < 0.1
    assert taken[31:45].all()
    assert not taken[45:47].any() and taken[47:].all()  # two gated, the third restarts
    assert np.linalg.norm(out[50:] - z[50:, 0], axis=1).max() < 0.2


def test_a_joint_unseen_longer_than_the_gap_starts_a_new_track():
    # frames 0-9, nothing for five frames (more than max_gap), then 15-29: a new track,
    # and the smoother never reaches back across its start
    truth, z, cov = _tracks(T=30, J=1, seed=2)
    z = z.copy()
    z[15:, 0] += 2.0                                    # somewhere else entirely
    f = JointFilter(1, 0.01, max_gap=4, lag=25)
    for t in list(range(10)) + list(range(15, 30)):
        X, _, taken = f.step(t, [0], z[t:t + 1, 0], cov[t:t + 1, 0])
        assert taken.all()
        if t == 9:
            at9 = X[0].copy()
        if t == 15:
            np.testing.assert_allclose(X[0], z[15, 0])     # started from its measurement
    Xs, _ = f.smoothed(9)
    np.testing.assert_allclose(Xs[0], at9)
    Xs, Cs = f.smoothed(20)
    assert np.linalg.norm(Xs[0] - truth[20, 0] - 2.0) < 0.1 and np.isfinite(Cs).all()


def test_a_new_unit_mid_track_scales_every_state_once():
    # the same stream in two units: a filter switched from the first to the second
    # (scale(), then the measurements and the prior in the new unit) smooths every frame
    # after the switch exactly as the filter that ran in the second unit throughout,
    # the frames whose lag spans the switch included
    truth, z, cov = _tracks(T=30)
    T, J = z.shape[:2]
    sigma, lag, f, switch = 0.01, 4, 1.7, 15
    a = JointFilter(J, sigma * f, max_gap=4, gate_chi2=np.inf, velocity_std=100.0 * f,
                    lag=lag)
    b = JointFilter(J, sigma, max_gap=4, gate_chi2=np.inf, velocity_std=100.0, lag=lag)
    for t in range(T):
        if t == switch:
            b.scale(f)
            b.sigma = sigma * f
        unit = f if t >= switch else 1.0
        a.step(t, np.arange(J), f * z[t], f * f * cov[t])
        b.step(t, np.arange(J), unit * z[t], unit * unit * cov[t])
        if t >= switch:
            (xa, Pa), (xb, Pb) = a.smoothed(t - lag), b.smoothed(t - lag)
            np.testing.assert_allclose(xb, xa, rtol=1e-9)
            np.testing.assert_allclose(Pb, Pa, rtol=1e-6, atol=1e-15)
            np.testing.assert_allclose(b.x, a.x, rtol=1e-9)


def test_a_restarted_track_keeps_its_velocity_through_an_outlier():
    """A track started on three measurements 0.5 m off (a new track takes them), the
    truth after: it restarts on the truth's third, then takes an outlier 0.5 m off
    (young tracks are not gated) and a measurement that says little along it. The
    restarted track keeps the velocity it had (:meth:`JointFilter.step`), so the outlier
    moves its position, not its motion: within 0.5 m of the truth throughout, and on
    it after (measured: 0.02 m; a restart at rest with a free velocity flies off along
    the outlier, 1.99 m three frames later)."""
    rng = np.random.default_rng(0)
    f = JointFilter(1, sigma=0.01, max_gap=10)
    err = []
    for t in range(30):
        truth = np.array([0.01 * t, 0.0, 3.0])
        z = truth + rng.normal(0.0, 0.01, 3)
        R = 0.01 ** 2 * np.eye(3)
        if t in (0, 1, 2, 6):
            z = z + np.array([0.0, 0.0, 0.5])
        if t == 7:
            R = np.diag([0.01, 0.01, 0.3]) ** 2
        X, _, _ = f.step(t, np.array([0]), z[None], R[None])
        err.append(float(np.linalg.norm(X[0] - truth)))
    err = np.array(err)
    assert err[5] < 0.05                      # restarted on the truth
    assert err[5:].max() < 0.55, err[5:12]
    assert err[8:].max() < 0.05, err[8:12]
