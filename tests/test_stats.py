"""mirrorgraph.stats: the chi-square and F quantiles against SciPy's (#25)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import chdtri as scipy_chdtri
from scipy.special import fdtri as scipy_fdtri

from mirrorgraph.stats import chdtri, chi2_sf, f_cdf, fdtri

PROBABILITIES = (0.001, 0.01, 0.05, 0.1, 0.3173, 0.5, 0.683, 0.9, 0.95, 0.99, 0.999)


@pytest.mark.parametrize("df", [*range(1, 41), 50, 100, 1000, 10_000])
def test_chi_square_quantiles_match_scipy(df):
    for q in PROBABILITIES:
        assert chdtri(df, q) == pytest.approx(scipy_chdtri(df, q), rel=1e-12, abs=0)


@pytest.mark.parametrize("dfn", [*range(1, 13), 16, 20, 30, 40])
def test_f_quantiles_match_scipy(dfn):
    for dfd in (1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 15, 20, 30, 50, 100, 300, 1000, 3000, 10_000):
        for p in PROBABILITIES:
            assert fdtri(dfn, dfd, p) == pytest.approx(scipy_fdtri(dfn, dfd, p), rel=1e-12,
                                                       abs=0), (dfn, dfd, p)


def test_the_regions_quantiles_are_scipys_to_the_last_digits():
    """What uncertainty.region_threshold asks: 2 parameters, level 0.9, any cluster count."""
    from mirrorgraph.graph.uncertainty import REGION_LEVEL
    assert chdtri(2, 1 - REGION_LEVEL) == pytest.approx(scipy_chdtri(2, 1 - REGION_LEVEL),
                                                         rel=1e-15)
    G = np.arange(3, 20_001)
    ours = np.array([fdtri(2, g - 2, REGION_LEVEL) for g in G])
    np.testing.assert_allclose(ours, scipy_fdtri(2, G - 2, REGION_LEVEL), rtol=2e-15, atol=0)


def test_the_quantiles_invert_the_distributions():
    for df in (1, 2, 3, 7, 30):
        for q in (0.01, 0.1, 0.5, 0.9):
            assert chi2_sf(df, chdtri(df, q)) == pytest.approx(q, rel=1e-13)
    for dfn, dfd in ((1, 1), (2, 5), (3, 40), (6, 1000)):
        for p in (0.01, 0.5, 0.9, 0.99):
            assert f_cdf(dfn, dfd, fdtri(dfn, dfd, p)) == pytest.approx(p, rel=1e-13)


def test_the_ends_and_bad_arguments_are_scipys():
    for args in ((3, 0.0), (3, 1.0), (0, 0.5), (-1, 0.5), (2, 1.5), (2, -0.1)):
        ours, theirs = chdtri(*args), float(scipy_chdtri(*args))
        assert ours == theirs or (math.isnan(ours) and math.isnan(theirs)), args
    for args in ((3, 7, 0.0), (3, 7, 1.0), (0, 7, 0.5), (3, 0, 0.5), (3, 7, 1.5)):
        ours, theirs = fdtri(*args), float(scipy_fdtri(*args))
        assert ours == theirs or (math.isnan(ours) and math.isnan(theirs)), args
