"""The error metrics and the Cramer-Rao bound (mirrorgraph.metrics)."""

from __future__ import annotations

import numpy as np

from mirrorgraph import geometry as geo
from mirrorgraph.metrics import cramer_rao_mirror, normal_angle_deg

def test_cramer_rao_bound_matches_monte_carlo(K):
    """The bound equals the spread of the maximum-likelihood estimate (small noise)."""
    from scipy.optimize import least_squares
    rng = np.random.default_rng(0)
    n = np.array([0.5, 0.1, 0.86])
    n /= np.linalg.norm(n)
    d, sigma = 3.0, 2.0
    X = rng.uniform([-0.5, -0.8, 2.0], [0.5, 0.8, 3.0], (12, 3))
    bound = cramer_rao_mirror(K, n, d, X, sigma)
    B = geo.tangent_basis(n)

    def images(nv, Xv):
        return np.concatenate([geo.project(K, Xv),
                               geo.project(K, geo.reflect_points(Xv, nv, d))], -1)

    errs = []
    for _ in range(30):
        obs = images(n, X) + rng.normal(0, sigma, (len(X), 4))

        def res(p):
            nv = n + B @ p[:2]
            return (images(nv / np.linalg.norm(nv), p[2:].reshape(-1, 3)) - obs).ravel()

        p = least_squares(res, np.concatenate([[0.0, 0.0], X.ravel()])).x
        nv = n + B @ p[:2]
        errs.append(2 * normal_angle_deg(nv / np.linalg.norm(nv), n))
    rms = float(np.sqrt(np.mean(np.square(errs))))
    assert 0.7 * bound["rot_rms_deg"] < rms < 1.4 * bound["rot_rms_deg"]
    assert bound["rot_median_deg"] < bound["rot_rms_deg"]
    # the bound scales with the noise
    assert np.isclose(cramer_rao_mirror(K, n, d, X, 2 * sigma)["rot_rms_deg"],
                      2 * bound["rot_rms_deg"])


def test_rotation_error_is_exact_for_small_and_half_turn_angles():
    """``rotation_error_deg`` against rotations of known angle, from 1e-7 deg (where the
    ``arccos`` of the trace loses every digit) to 179.9999 deg."""
    from scipy.spatial.transform import Rotation

    from mirrorgraph.metrics import rotation_error_deg

    rng = np.random.default_rng(3)
    for angle in (0.0, 1e-7, 1e-4, 0.01, 1.0, 90.0, 179.9999):
        R0 = Rotation.random(random_state=rng).as_matrix()
        axis = rng.normal(size=3)
        dR = Rotation.from_rotvec(np.radians(angle) * axis / np.linalg.norm(axis)).as_matrix()
        got = rotation_error_deg(R0, R0 @ dR)
        assert abs(got - angle) <= 1e-9 + 1e-9 * angle, (angle, got)
