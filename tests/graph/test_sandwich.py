"""The cluster-robust sandwich's parts (:mod:`mirrorgraph.graph.sandwich`)."""

from __future__ import annotations

import numpy as np
import pytest


def test_long_run_covariance_of_an_ar1_series_is_its_theoretical_value():
    """The sum of an AR(1) series of coefficient rho and unit innovations has variance
    T / (1 - rho)^2 (long run); the Newey-West estimate with Andrews' bandwidth finds it."""
    from mirrorgraph.graph.sandwich import andrews_bandwidth, long_run_covariance
    rng = np.random.default_rng(1)
    T, rho = 20000, 0.9
    e = rng.normal(size=(T, 1))
    x = np.zeros((T, 1))
    for t in range(1, T):
        x[t] = rho * x[t - 1] + e[t]
    assert 10 < andrews_bandwidth(x) < T / 10
    assert long_run_covariance(x)[0, 0] / T == pytest.approx(1 / (1 - rho) ** 2, rel=0.25)
    white = rng.normal(size=(T, 1))
    assert long_run_covariance(white)[0, 0] / T == pytest.approx(1.0, rel=0.1)


def test_covariance_max_is_at_least_both_in_every_direction():
    from mirrorgraph.graph.sandwich import covariance_max
    rng = np.random.default_rng(2)
    for _ in range(20):
        A = rng.normal(size=(3, 3))
        B = rng.normal(size=(3, 3))
        A, B = A @ A.T, B @ B.T
        C = covariance_max(A, B)
        assert np.linalg.eigvalsh(C - A).min() > -1e-9 * np.abs(C).max()
        assert np.linalg.eigvalsh(C - B).min() > -1e-9 * np.abs(C).max()
    A = np.diag([1.0, 4.0, 0.0])                         # rank 2, as a unit normal's
    np.testing.assert_allclose(covariance_max(A, 0.25 * A), A, atol=1e-12)
