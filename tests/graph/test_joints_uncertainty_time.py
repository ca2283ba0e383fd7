"""The joints' std under a detector whose noise is correlated in time
(mirrorgraph.graph.joints_uncertainty.time_correlation_factor) against the truth."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.factors.smoothness import SmoothnessFactor
from mirrorgraph.graph import joints_uncertainty as ju
from mirrorgraph.synth.detector import correlated_noise


def ar1(rng, shape: tuple, rho: float) -> np.ndarray:
    """Unit-variance AR(1) noise along the first axis (the synthetic detector's,
    :func:`mirrorgraph.synth.detector.correlated_noise`, whose frames are its axis 1)."""
    return correlated_noise(rng, (1, *shape), rho)[0]


def smoothed_chain(T: int, J: int, sigma_px: float, smooth_sigma: float):
    """``J`` joints over ``T`` frames, each frame's estimate of std ``sigma_px`` per axis
    and the joints pass's second-difference smoothness: the per-frame and the smoothed
    covariances (the module's own chain solve) and the band to smooth estimates with."""
    used = np.ones((T, J), bool)
    info = np.broadcast_to(np.eye(3) / sigma_px ** 2, (T, J, 3, 3)).copy()
    frame = np.broadcast_to(np.eye(3) * sigma_px ** 2, (T, J, 3, 3)).copy()
    band = ju._smoothness_band(used, np.arange(T), SmoothnessFactor(smooth_sigma, 4))
    smoothed = ju._chain_solve(frame, used, band.copy(), info)
    return frame, smoothed, band, info


def smoothed_errors(rng, rho: float, T: int, J: int, R: int, s: float, band, info):
    """``R`` runs of ``J`` joints whose per-frame estimates are off by AR(1) noise of std
    ``s`` (truth 0), smoothed by the chain: the noise ``(T, R, J, 3)`` and the smoothed
    errors' squared lengths ``(R, J, T)``."""
    noise = s * ar1(rng, (T, R, J, 3), rho)
    diag = band[0] + np.moveaxis(info, 0, 1)                                # (J, T, 3, 3)
    rhs = np.einsum("jtab,trjb->rjta", np.moveaxis(info, 0, 1), noise).reshape(R * J, T, 3)
    est, _ = ju.chain_marginals(np.tile(diag, (R, 1, 1, 1)), np.tile(band[1], (R, 1, 1, 1)),
                                np.tile(band[2], (R, 1, 1, 1)), rhs=rhs)
    return noise, np.sum(est.reshape(R, J, T, 3) ** 2, -1)


@pytest.mark.parametrize("rho", [0.6, 0.9, 0.97])
def test_the_widened_std_covers_the_smoothed_error_under_ar1_noise(rho):
    """Each frame's estimate off by AR(1) noise, smoothed (64 runs): the variance the
    factor adds is the error's own increase over iid noise (within 20 %: one run's
    autocorrelation), and the widened std covers the error's spread (0.8-1.1 of it; the
    stated one holds the smoothness's share of a moving joint too, which a still one
    leaves unused), where the iid one misses it (by 2x and more at 0.9). On iid noise the
    factor is ~1."""
    T, J, R, s = 400, 2, 64, 2.0
    frame, smoothed, band, info = smoothed_chain(T, J, s, 0.3)
    inside = slice(50, -50)                                   # the chain's ends aside
    stated = np.trace(smoothed, axis1=-2, axis2=-1)[inside].T               # (J, T')
    _, iid = smoothed_errors(np.random.default_rng(2), 0.0, T, J, R, s, band, info)
    noise, err2 = smoothed_errors(np.random.default_rng(3), rho, T, J, R, s, band, info)
    spread_iid = np.mean(iid, axis=0)[:, inside]
    spread = np.mean(err2, axis=0)[:, inside]
    # the residual series no point fits: one coordinate of one run's own noise
    f = ju.time_correlation_factor(noise[:, 0, :, 0] / s, frame, smoothed)
    f_iid = ju.time_correlation_factor(ar1(np.random.default_rng(4), (T, J), 0.0), frame,
                                       smoothed)
    assert np.all(np.abs(f_iid - 1.0) < 0.1)
    added = np.median((f[inside].T - 1.0) * stated)
    assert 0.8 < added / np.median(spread - spread_iid) < 1.2
    ratio = np.sqrt(np.median(spread / (stated * f[inside].T)))
    assert 0.8 < ratio < 1.1, ratio
    if rho >= 0.9:
        assert np.sqrt(np.median(spread / stated)) > 2.0            # what the iid std misses


def test_epipolar_residual_is_the_noise_no_point_fits():
    """Four whitened rows ``A dX + noise``: the component is the same whatever ``dX``
    (the point's error), and its series keeps the noise's autocorrelation."""
    rng = np.random.default_rng(1)
    T = 3000
    A = rng.normal(size=(T, 4, 3)) * 0.01 + rng.normal(size=(1, 4, 3))    # slowly varying
    noise = ar1(rng, (T, 4), 0.8)
    cells = np.repeat(np.arange(T), 4)
    a = ju.epipolar_residuals(cells, A.reshape(-1, 3), noise.reshape(-1), T)
    moved = noise + np.einsum("tij,tj->ti", A, rng.normal(size=(T, 3)) * 50.0)
    b = ju.epipolar_residuals(cells, A.reshape(-1, 3), moved.reshape(-1), T)
    np.testing.assert_allclose(a, b, atol=1e-8)
    rho = ju.residual_autocorrelation(a[:, None], np.zeros(1, np.int64), 3)[0]
    np.testing.assert_allclose(rho, 0.8 ** np.arange(1, 4), atol=0.06)
    # a joint-frame with other than four rows has none
    c = ju.epipolar_residuals(cells[:-1], A.reshape(-1, 3)[:-1], noise.reshape(-1)[:-1], T)
    assert np.isnan(c[-1]) and np.isfinite(c[:-1]).all()


@pytest.mark.parametrize("rho", [0.0, 0.8])
def test_the_live_runs_residuals_keep_the_noises_autocorrelation(rho):
    """The live run's record of each frame's two views (a mirror 2 m off, pixels off by
    AR(1) noise): the pooled autocorrelation is the noise's, and the factor on a
    covariance a filter shrank ``n``-fold is ~1 for iid noise, well above for AR(1),
    within ``[1, n]``."""
    from mirrorgraph.live.noise_in_time import NoiseInTime

    rng = np.random.default_rng(5)
    T, J = 1500, 6
    K = np.array([[900.0, 0, 640], [0, 900.0, 360], [0, 0, 1]])
    normal, d = np.array([0.6, 0.0, 0.8]), 4.0
    H = np.eye(3) - 2.0 * np.outer(normal, normal)
    X = np.array([0.0, 0.0, 3.5]) + rng.normal(size=(J, 3)) * 0.3

    def pix(Y):
        y = Y @ K.T
        return y[:, :2] / y[:, 2:]

    u0, um0 = pix(X), pix(X @ H.T + 2.0 * d * normal)
    noise = 2.0 * ar1(rng, (T, J, 4), rho)
    cov = np.broadcast_to(np.eye(3) * 1e-4, (J, 3, 3))
    keep = np.ones((J, 2), bool)
    nt = NoiseInTime(J)
    for t in range(T):
        nt.record(t, np.arange(J), K, normal, d, X, u0 + noise[t, :, :2],
                  um0 + noise[t, :, 2:], keep, cov)
    ac = nt.autocorrelation()
    np.testing.assert_allclose(ac[:4], rho ** np.arange(1, 5), atol=0.05)
    f = nt.factor(T - 1, np.arange(J), cov / 8.0, 0)
    assert np.all((f >= 1.0) & (f <= 8.0))
    if rho == 0.0:
        assert np.all(f < 1.15)
    else:
        assert np.all(f > 3.0)


@pytest.mark.parametrize("rho", [0.0, 0.9])
def test_completed_joints_factor_reads_their_own_rays(rho):
    """Points triangulated from a camera and its mirror view, their pixels off by AR(1)
    noise, a covariance smoothed 6-fold: the factor is the chain's own (the kernel's
    cross terms at the rays' autocorrelation), ~1 for iid noise."""
    from mirrorgraph import geometry as geo

    rng = np.random.default_rng(7)
    T, J = 800, 3
    K = np.array([[900.0, 0, 640], [0, 900.0, 360], [0, 0, 1]])
    views = [geo.camera_projection(K, np.eye(4)),
             geo.mirror_projection(K, np.eye(4), np.array([0.6, 0.0, 0.8]), 4.0)]
    X = np.array([0.0, 0.0, 3.5]) + rng.normal(size=(J, 3)) * 0.3
    t, j = (a.ravel() for a in np.meshgrid(np.arange(T), np.arange(J), indexing="ij"))
    noise = ar1(rng, (T, J, 4), rho).reshape(-1, 4)
    pix = []
    for v, P in enumerate(views):
        y = X[j] @ P[:, :3].T + P[:, 3]
        pix.append(y[:, :2] / y[:, 2:] + noise[:, 2 * v:2 * v + 2])
    frame = np.broadcast_to(np.eye(3), (T, J, 3, 3))
    f = ju.rays_time_correlation_factor(views, X[j], pix, t, j, frame, frame / 6.0)
    if rho == 0.0:
        assert np.all(np.abs(f - 1.0) < 0.1)
    else:
        widths, acf = ju._smoother_kernels()
        expected = 1.0 + 2.0 * 6.0 * np.interp(np.log(6.0), np.log(widths),
                                               acf @ rho ** np.arange(1, acf.shape[1] + 1))
        np.testing.assert_allclose(f, expected, rtol=0.15)
