"""mirrorgraph.initial.pair_scores: the epipolar distance's quantiles per candidate."""

from __future__ import annotations

import numpy as np

from mirrorgraph import geometry as geo
from mirrorgraph.initial.pair_scores import _quantile_distance


def test_quantiles_are_numpys_over_each_candidates_known_joints():
    """Each candidate's quantiles equal :func:`numpy.nanquantile` (its "linear" method)
    over the joints both detections have; ``inf`` with fewer than ``min_joints``."""
    rng = np.random.default_rng(5)
    M, J = 300, 17
    a = rng.normal(600.0, 250.0, (M, J, 3))
    b = rng.normal(600.0, 250.0, (M, J, 3))
    a[rng.random((M, J)) < 0.4] = np.nan
    b[rng.random((M, J)) < 0.2] = np.nan
    e = np.array([-300.0, 450.0, 1.0])
    joints = np.arange(2, J)
    q = np.array([0.1, 0.5, 0.9])
    got = _quantile_distance(e, a, b, joints, 5, q)
    d = geo.epipolar_distances(e, a[:, joints, :2], b[:, joints, :2])
    count = np.isfinite(d).sum(1)
    assert (count < 5).any() and (count >= 5).any()
    want = np.full((len(q), M), np.inf)
    for m in np.flatnonzero(count >= 5):
        want[:, m] = np.quantile(d[m][np.isfinite(d[m])], q)
    assert np.array_equal(np.isinf(got), np.isinf(want))
    np.testing.assert_allclose(got[np.isfinite(want)], want[np.isfinite(want)], rtol=1e-12)
