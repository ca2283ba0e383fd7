"""Minimal, linear and reference solvers, and the generic RANSAC, against ground truth."""

import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph.errors import DegenerateGeometryError
from mirrorgraph.initial.estimators import estimate_epipole, estimate_mirror
from mirrorgraph.metrics import rotation_error_deg
from mirrorgraph.initial.ransac import RansacOptions, ransac, required_iterations
from mirrorgraph.initial.solvers import (SimilarityNormalizer, epipole_from_two_pairs,
                                 epipole_least_squares, pair_lines)
from mirrorgraph.initial.solvers.eightpoint import (fundamental_eight_point,
                                            fundamental_reflective_eight_point)

from tests.helpers import points_in_front, random_mirror


def _same_point(a, b):
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    return min(np.linalg.norm(a - b), np.linalg.norm(a + b))


def test_two_point_solver_is_exact(scene_points):
    K, n, d, X, u, um = scene_points
    e_true = geo.epipole_from_normal(K, n)
    lines = pair_lines(u, um)
    rng = np.random.default_rng(0)
    for _ in range(20):
        i, j = rng.choice(len(u), 2, replace=False)
        (e,) = epipole_from_two_pairs(lines[[i, j]])
        assert _same_point(e, e_true) < 1e-9


def test_two_point_solver_refuses_identical_lines():
    lines = pair_lines(np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([[2.0, 2.0], [3.0, 3.0]]))
    assert epipole_from_two_pairs(lines) == []


def test_shared_normalisation_keeps_F_skew(scene_points):
    K, n, d, X, u, um = scene_points
    T = SimilarityNormalizer.fit(u, um)
    e_n = epipole_least_squares(pair_lines(T.apply(u), T.apply(um)))
    F = T.matrix.T @ geo.skew(e_n) @ T.matrix           # back to pixels
    assert np.allclose(F, -F.T, atol=1e-12 * np.abs(F).max())
    assert _same_point(T.epipole_to_pixels(e_n), geo.epipole_from_normal(K, n)) < 1e-9


def test_reference_eight_point_solvers_exact_on_noiseless(scene_points):
    K, n, d, X, u, um = scene_points
    # OpenCV's nine-unknown solve is less well conditioned on mirror data
    for solver, tol_px in ((fundamental_eight_point, 1e-3), (fundamental_reflective_eight_point, 1e-6)):
        F = solver(u, um)
        assert geo.epipolar_distances_fundamental(F, u, um).max() < tol_px
        R, _t, n2 = geo.decompose_reflective_essential(K.T @ F @ K)
        assert rotation_error_deg(R, geo.virtual_camera_from_mirror(n, d)[0]) < 1e3 * tol_px
        assert np.allclose(n2, n, atol=1e3 * tol_px)
    with pytest.raises(DegenerateGeometryError):
        fundamental_eight_point(u[:5], um[:5])


def _noisy_scene(seed, count=6000, noise=4.0, outliers=0.3):
    rng = np.random.default_rng(seed)
    K = np.array([[1400.0, 0, 960], [0, 1400.0, 540], [0, 0, 1]])
    n, d = random_mirror(rng, 40.0)
    X = points_in_front(rng, n, d, count)
    u = geo.project(K, X) + rng.normal(0.076, noise, (count, 2))
    um = geo.project(K, geo.reflect_points(X, n, d)) + rng.normal(0.076, noise, (count, 2))
    bad = rng.random(count) < outliers
    um[bad] += rng.uniform(30, 150, (bad.sum(), 1)) * np.stack(
        [np.cos(a := rng.uniform(0, 2 * np.pi, bad.sum())), np.sin(a)], 1)
    return K, n, d, u, um, bad


def test_reflective_ransac_recovers_mirror_with_30_percent_outliers():
    K, n, d, u, um, bad = _noisy_scene(1)
    est = estimate_mirror(u, um, K)
    R_true = geo.virtual_camera_from_mirror(n, d)[0]
    assert rotation_error_deg(geo.virtual_camera_from_mirror(est.normal, 1)[0], R_true) < 0.1
    assert est.normal @ n > 0.999
    # the inliers are mostly the true inliers
    assert np.mean(est.inliers[~bad]) > 0.9
    assert np.mean(est.inliers[bad]) < 0.2
    assert np.allclose(est.fundamental, -est.fundamental.T)


def test_ransac_is_deterministic_by_seed():
    K, n, d, u, um, _ = _noisy_scene(2, count=2000)
    a = estimate_epipole(u, um, seed=5)
    b = estimate_epipole(u, um, seed=5)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_eightpoint_baseline_is_worse_than_reflective():
    K, n, d, u, um, bad = _noisy_scene(3, outliers=0.1)
    R_true = geo.virtual_camera_from_mirror(n, d)[0]
    errs = {}
    for name in ("reflective", "eightpoint", "reflective8"):
        est = estimate_mirror(u, um, K, estimator=name)
        errs[name] = rotation_error_deg(geo.virtual_camera_from_mirror(est.normal, 1)[0], R_true)
    assert errs["reflective"] < 0.1
    assert errs["eightpoint"] > 3 * errs["reflective"]
    assert errs["reflective8"] < 2.0


def test_degenerate_data_is_refused():
    with pytest.raises(DegenerateGeometryError, match="usable"):
        estimate_epipole(np.array([[0.0, 0.0]]), np.array([[50.0, 0.0]]))
    # all pairs on one line: the epipole is not determined
    u = np.stack([np.linspace(0, 500, 30), np.zeros(30)], 1)
    um = u + np.array([40.0, 0.0])
    with pytest.raises(DegenerateGeometryError):
        estimate_epipole(u, um)


def test_generic_ransac_fits_a_line_with_outliers():
    rng = np.random.default_rng(0)
    x = rng.uniform(-10, 10, 300)
    y = 2 * x + 1 + rng.normal(0, 0.1, 300)
    y[:90] = rng.uniform(-30, 30, 90)

    def solver(idx):
        (x1, x2), (y1, y2) = x[idx], y[idx]
        return [] if x1 == x2 else [((y2 - y1) / (x2 - x1), y1 - x1 * (y2 - y1) / (x2 - x1))]

    scored = []

    def residuals(m, idx=None):
        scored.append(300 if idx is None else len(idx))
        sel = slice(None) if idx is None else idx
        return np.abs(y[sel] - (m[0] * x[sel] + m[1]))

    def refit(mask, _m):
        return tuple(np.polyfit(x[mask], y[mask], 1))

    res = ransac(300, 2, solver, residuals, RansacOptions(threshold=0.4, seed=1), refit=refit)
    assert abs(res.model[0] - 2) < 0.01 and abs(res.model[1] - 1) < 0.05
    assert res.inliers[90:].mean() > 0.95 and res.inliers[:90].mean() < 0.1
    assert set(scored) == {300}
    # hypotheses scored on a subset of 100: the same line, the inliers judged on all 300
    scored.clear()
    sub = ransac(300, 2, solver, residuals, RansacOptions(threshold=0.4, seed=1, max_scored=100),
                 refit=refit)
    assert abs(sub.model[0] - 2) < 0.01 and abs(sub.model[1] - 1) < 0.05
    assert sub.inliers.shape == (300,) and sub.inliers[90:].mean() > 0.95
    assert 100 in scored and scored[-1] == 300
    assert required_iterations(0.5, 2, 0.99) == pytest.approx(np.log(0.01) / np.log(0.75))
    assert ransac(1, 2, solver, residuals, RansacOptions(threshold=1.0)) is None


def test_refine_epipole_recovers_the_true_epipole_through_outliers():
    """Pairs collinear with a known epipole: exact without noise; with 1.5 px noise and
    15 % gross outliers (80 px), within a little of the fit to the inliers alone (the
    oracle) from a start 10-75 px off."""
    from mirrorgraph.initial.solvers.reflective import refine_epipole

    def px(x):
        return x[:2] / x[2]

    rng = np.random.default_rng(3)
    for k in range(20):
        e = np.array([*rng.uniform(-3000, 4000, 2), 1.0])         # the epipole, pixels
        n = int(rng.integers(40, 200))
        u = rng.uniform(0, 1920, (n, 2))
        um = u + (e[:2] - u) * rng.uniform(0.05, 0.5, (n, 1))
        e0 = e + np.array([*rng.normal(0, 30, 2), 0])
        assert _same_point(refine_epipole(e0, u, um), e) < 1e-9
        clean = um + rng.normal(0, 1.5, (n, 2))
        noisy = clean.copy()
        bad = rng.random(n) < 0.15
        noisy[bad] += rng.normal(0, 80, (bad.sum(), 2))
        fit = np.linalg.norm(px(refine_epipole(e0, u, noisy)) - e[:2])
        oracle = np.linalg.norm(px(refine_epipole(e0, u[~bad], clean[~bad])) - e[:2])
        assert fit < 2.5 * oracle + 2.0, (k, fit, oracle)
