"""Every factor of mirrorgraph.factors: residuals and analytic Jacobians against central
differences taken through GTSAM's own retractions, plus the geometric identities the
factor graph relies on (mirror view = camera with negated fx, reflected pose, ...)."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import C, L, P, V, X

from mirrorgraph import geometry as geo
from mirrorgraph.factors import (AnthropometricRatioFactor, BoneLengthFactor, DistancePriorFactor,
                                 HeightPriorFactor, HipColinearityFactor, MirrorLinkFactor,
                                 ReprojectionFactors, SmoothnessFactor, SymmetryFactor,
                                 mirror_residuals, mirrored_calibration, plane_from_gtsam,
                                 plane_to_gtsam, reflected_pose, robust_pixel_noise)
from mirrorgraph.factors.mirror_link import (so3_left_jacobian_inverse, so3_log,
                                             so3_right_jacobian_inverse)

K = np.array([[1500.0, 0.0, 955.0], [0.0, 1480.0, 545.0], [0.0, 0.0, 1.0]])


# --------------------------------------------------------------------------- helpers
def numeric_jacobian(factor: gtsam.NonlinearFactor, values: gtsam.Values, eps: float = 1e-6
                     ) -> np.ndarray:
    """Central differences of the whitened error w.r.t. each key's tangent (GTSAM retract)."""
    cols = []
    zero = values.zeroVectors()
    for key in factor.keys():
        dim = len(zero.at(key))
        for i in range(dim):
            step = np.zeros(dim)
            step[i] = eps
            plus, minus = gtsam.VectorValues(), gtsam.VectorValues()
            plus.insert(key, step)
            minus.insert(key, -step)
            cols.append((factor.whitenedError(values.retract(plus))
                         - factor.whitenedError(values.retract(minus))) / (2 * eps))
    return np.stack(cols, axis=1)


def assert_jacobians(factor: gtsam.NonlinearFactor, values: gtsam.Values, *, rtol: float = 1e-6,
                     atol: float = 1e-6) -> None:
    """The linearised factor's A equals the numerical Jacobian of the whitened error."""
    A, b = factor.linearize(values).jacobian()
    N = numeric_jacobian(factor, values)
    scale = max(1.0, float(np.abs(A).max()))
    np.testing.assert_allclose(A, N, rtol=rtol, atol=atol * scale)
    np.testing.assert_allclose(-b, factor.whitenedError(values), rtol=1e-9, atol=1e-9)


def set_point(values: gtsam.Values, key: int, x: np.ndarray) -> None:
    """Replace a Point3 (``Values.update`` from numpy would pick the dynamic-vector overload)."""
    values.erase(key)
    values.insertPoint3(key, np.asarray(x, dtype=float))


def random_plane(rng):
    n = rng.normal(size=3)
    n[2] = abs(n[2]) + 1.0
    return n / np.linalg.norm(n), float(rng.uniform(2.0, 5.0))


# --------------------------------------------------------------------------- SO(3) helpers
def test_so3_inverse_jacobians_match_numerical():
    rng = np.random.default_rng(0)
    theta = rng.normal(size=3) * 0.4
    R = gtsam.Rot3.Expmap(theta).matrix()
    eps = 1e-6
    for J_inv, perturb in ((so3_right_jacobian_inverse(theta), lambda d: R @ gtsam.Rot3.Expmap(d).matrix()),
                           (so3_left_jacobian_inverse(theta), lambda d: gtsam.Rot3.Expmap(d).matrix() @ R)):
        num = np.stack([(so3_log(perturb(e)) - so3_log(perturb(-e))) / (2 * eps)
                        for e in np.eye(3) * eps], axis=1)
        np.testing.assert_allclose(J_inv, num, atol=1e-7)


# --------------------------------------------------------------------------- plane & pose
def test_plane_round_trip_and_gtsam_convention():
    n, d = np.array([0.0, 0.6, 0.8]), 2.5
    p = plane_to_gtsam(n, d)
    n2, d2 = plane_from_gtsam(p)
    np.testing.assert_allclose(n2, n, atol=1e-12)
    assert d2 == pytest.approx(d)
    # GTSAM's n.X + d_gtsam = 0 holds for points of our plane n.X = d
    coeffs = p.planeCoefficients()
    X = 3.0 * np.array([1.0, 0.0, 0.0]) + d * n
    assert coeffs[:3] @ X + coeffs[3] == pytest.approx(0.0, abs=1e-12)


def test_mirror_view_is_a_camera_with_negated_fx():
    """The reflected pose with Cal3_S2(-fx, ...) projects X where the camera sees S(X)."""
    rng = np.random.default_rng(1)
    n, d = random_plane(rng)
    pose = reflected_pose(n, d)
    cam = gtsam.PinholeCameraCal3_S2(pose, mirrored_calibration(K))
    for _ in range(20):
        Xw = rng.normal(size=3) * 0.5 + np.array([0.0, 0.0, 0.6 * d])
        expected = geo.project(K, geo.reflect_points(Xw, n, d))
        np.testing.assert_allclose(cam.project(Xw), expected, atol=1e-9)
    # the proper rotation of the virtual camera: H diag(-1, 1, 1), centre 2 d n
    np.testing.assert_allclose(pose.rotation().matrix(), geo.householder(n) @ geo.D_FLIP,
                               atol=1e-12)
    np.testing.assert_allclose(pose.translation(), 2 * d * n, atol=1e-12)
    # and it is the inverse of geometry.virtual_camera_from_mirror's extrinsics
    R, t = geo.virtual_camera_from_mirror(n, d)
    np.testing.assert_allclose(pose.rotation().matrix().T, R, atol=1e-12)
    np.testing.assert_allclose(-R @ pose.translation(), t, atol=1e-12)


# --------------------------------------------------------------------------- reprojection
def test_reprojection_factors_jacobians_and_residuals():
    rng = np.random.default_rng(2)
    n, d = random_plane(rng)
    noise = robust_pixel_noise(3.0, None)
    fac = ReprojectionFactors(K, noise)
    Xw = np.array([0.2, -0.1, 0.55 * d])
    uv = geo.project(K, Xw) + rng.normal(size=2)
    uvm = geo.project(K, geo.reflect_points(Xw, n, d)) + rng.normal(size=2)
    values = gtsam.Values()
    values.insertPoint3(X(0), Xw + 0.01)
    values.insert(V(0), reflected_pose(n, d))
    f_direct, f_mirror = fac.direct(uv, X(0)), fac.mirror(uvm, V(0), X(0))
    assert_jacobians(f_direct, values)
    assert_jacobians(f_mirror, values)
    # the mirror residual is pi(K S(X)) - u' (unwhitened), its X-Jacobian the chain rule
    np.testing.assert_allclose(f_mirror.unwhitenedError(values),
                               mirror_residuals(K, n, d, Xw + 0.01, uvm), atol=1e-9)
    A = f_mirror.linearize(values).jacobian()[0][:, 6:] * 3.0          # unwhiten (sigma 3)
    eps = 1e-6
    num = np.stack([(mirror_residuals(K, n, d, Xw + 0.01 + e, uvm)
                     - mirror_residuals(K, n, d, Xw + 0.01 - e, uvm)) / (2 * eps)
                    for e in np.eye(3) * eps], axis=1)
    np.testing.assert_allclose(A, num, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("kernel", ["geman_mcclure", "huber", "cauchy", None])
def test_robust_noise_kernels(kernel):
    noise = robust_pixel_noise(4.0, kernel, 10.0)
    if kernel is None:
        assert isinstance(noise, gtsam.noiseModel.Isotropic)
    else:
        assert isinstance(noise, gtsam.noiseModel.Robust)
    with pytest.raises(ValueError):
        robust_pixel_noise(4.0, "nonsense")


def test_geman_mcclure_downweights_outliers():
    """Residual of 100 px costs (almost) no more than one of 30 px: bounded influence."""
    fac = ReprojectionFactors(K, robust_pixel_noise(4.0, "geman_mcclure", 10.0))
    values = gtsam.Values()
    values.insertPoint3(X(0), np.array([0.0, 0.0, 3.0]))
    u0 = geo.project(K, np.array([0.0, 0.0, 3.0]))
    e = [fac.direct(u0 + np.array([r, 0.0]), X(0)).error(values) for r in (3.0, 30.0, 100.0)]
    assert e[0] < e[1] < e[2] < 1.2 * e[1]


# --------------------------------------------------------------------------- mirror link
@pytest.mark.parametrize("with_camera_key", [True, False])
def test_mirror_link_jacobians(with_camera_key):
    rng = np.random.default_rng(3)
    n, d = random_plane(rng)
    cam = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3) * 0.3), rng.normal(size=3))
    virt = reflected_pose(n, d, cam).compose(gtsam.Pose3.Expmap(rng.normal(size=6) * 0.05))
    values = gtsam.Values()
    values.insert(P(0), plane_to_gtsam(n, d))
    values.insert(V(0), virt)
    values.insert(C(0), cam)
    link = MirrorLinkFactor(1e-2, 2e-2, camera_pose=cam)
    factor = link.make(P(0), V(0), C(0) if with_camera_key else None)
    assert_jacobians(factor, values, rtol=1e-5, atol=1e-7)


def test_mirror_link_is_zero_exactly_at_the_reflection():
    rng = np.random.default_rng(4)
    n, d = random_plane(rng)
    cam = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3) * 0.2), rng.normal(size=3))
    values = gtsam.Values()
    values.insert(P(0), plane_to_gtsam(n, d))
    values.insert(V(0), reflected_pose(n, d, cam))
    f = MirrorLinkFactor(camera_pose=cam).make(P(0), V(0))
    assert np.abs(f.unwhitenedError(values)).max() < 1e-12


def test_normal_tilt_turns_the_virtual_camera_twice_as_much():
    n = np.array([0.3, 0.1, 1.0])
    n /= np.linalg.norm(n)
    axis = np.cross(n, [1.0, 0.0, 0.0])
    axis /= np.linalg.norm(axis)
    theta = 1e-3
    n2 = np.cos(theta) * n + np.sin(theta) * np.cross(axis, n)
    R1 = reflected_pose(n, 2.0).rotation().matrix()
    R2 = reflected_pose(n2, 2.0).rotation().matrix()
    assert np.linalg.norm(so3_log(R1.T @ R2)) == pytest.approx(2 * theta, rel=1e-6)


# --------------------------------------------------------------------------- body priors
def _frame_values(rng, count):
    values = gtsam.Values()
    pts = rng.normal(size=(count, 3)) * 0.3 + np.array([0.0, 0.0, 3.0])
    for i, p in enumerate(pts):
        values.insertPoint3(X(i), p)
    return values, pts


def test_bone_length_factors_jacobians_and_residual():
    rng = np.random.default_rng(5)
    values, pts = _frame_values(rng, 5)
    bones = np.array([[0, 1], [1, 2], [3, 4], [0, 3]])
    lengths = np.array([0.4, 0.3, 0.25, 0.5])
    g = gtsam.NonlinearFactorGraph()
    BoneLengthFactor(0.02).add(g, [X(int(i)) for i in bones[:, 0]],
                               [X(int(i)) for i in bones[:, 1]], lengths)
    assert g.size() == 4
    expected = np.linalg.norm(pts[bones[:, 0]] - pts[bones[:, 1]], axis=1) - lengths
    r, Ja, Jb = BoneLengthFactor.evaluate(pts[bones[:, 0]], pts[bones[:, 1]], lengths)
    np.testing.assert_allclose(r, expected, atol=1e-12)
    for i in range(4):
        f = g.at(i)
        np.testing.assert_allclose(f.unwhitenedError(values), [expected[i]], atol=1e-12)
        assert_jacobians(f, values)
        H = f.linearize(values).jacobian()[0] * 0.02           # whitened by sigma
        np.testing.assert_allclose(H[:, :3], Ja[i][None], atol=1e-9)
        np.testing.assert_allclose(H[:, 3:], Jb[i][None], atol=1e-9)


def test_symmetry_anthropometry_and_gauge_jacobians():
    rng = np.random.default_rng(6)
    values = gtsam.Values()
    Lv = rng.uniform(0.2, 0.5, 6)
    values.insert(L(0), Lv)
    n, d = random_plane(rng)
    values.insert(P(0), plane_to_gtsam(n, d))
    sym = SymmetryFactor(0.01).make(L(0), 1, 4)
    assert sym.unwhitenedError(values)[0] == pytest.approx(Lv[1] - Lv[4])
    anth = AnthropometricRatioFactor(0.05).make(L(0), 2, [0, 3], 0.75)
    assert anth.unwhitenedError(values)[0] == pytest.approx(Lv[2] / Lv[[0, 3]].mean() - 0.75)
    height = HeightPriorFactor(2.0, rel_sigma=0.01).make(L(0))
    assert height.unwhitenedError(values)[0] == pytest.approx(Lv.sum() - 2.0)
    dist = DistancePriorFactor(1.5, sigma=0.1).make(P(0))
    assert dist.unwhitenedError(values)[0] == pytest.approx(d - 1.5)
    for f in (sym, anth, height, dist):
        assert_jacobians(f, values)


def test_hip_colinearity_factor_jacobians():
    rng = np.random.default_rng(7)
    values, pts = _frame_values(rng, 3)
    f = HipColinearityFactor(scale=0.1, sigma=0.1).make(X(0), X(1), X(2))
    expected = np.cross(pts[1] - pts[0], pts[2] - pts[0]) / 0.01
    np.testing.assert_allclose(f.unwhitenedError(values), expected, atol=1e-9)
    assert_jacobians(f, values)
    # colinear hips: zero residual
    set_point(values, X(2), 2 * pts[0] - pts[1])
    assert np.abs(f.unwhitenedError(values)).max() < 1e-9


# --------------------------------------------------------------------------- smoothness
def test_smoothness_coefficients_exact_for_quadratic_motion_with_gaps():
    sm = SmoothnessFactor(0.01, max_gap=4)
    frames = np.array([[10, 11, 12], [10, 12, 13], [3, 7, 8]])
    acc = np.array([0.3, -1.2, 0.05])
    X3 = np.stack([np.outer(0.5 * (f - 9.0) ** 2, acc) + np.outer(f, [1.0, 2.0, 3.0])
                   for f in frames.astype(float)])                       # (3, 3, 3)
    a, J = sm.evaluate(X3, frames)
    np.testing.assert_allclose(a, np.tile(acc, (3, 1)), atol=1e-12)
    # Jacobian: blocks c_k I, checked numerically on the first triple
    eps = 1e-6
    num = np.stack([(sm.evaluate(X3[0] + e.reshape(3, 3), frames[0])[0]
                     - sm.evaluate(X3[0] - e.reshape(3, 3), frames[0])[0]) / (2 * eps)
                    for e in np.eye(9) * eps], axis=1)
    np.testing.assert_allclose(J[0], num, atol=1e-8)


def test_smoothness_triples_skip_long_gaps():
    sm = SmoothnessFactor(0.01, max_gap=4)
    frames = np.array([0, 1, 2, 4, 5, 20, 21, 22, 27])
    tri = sm.triples(frames)
    spans = frames[tri]
    assert len(tri) == 4                          # (0,1,2) (1,2,4) (2,4,5) (20,21,22)
    assert np.all(np.diff(spans, axis=1) <= 4)
    assert [20, 21, 22] in spans.tolist() and [21, 22, 27] not in spans.tolist()


def test_smoothness_factor_is_exact_and_matches_numerical_jacobian():
    rng = np.random.default_rng(8)
    values, pts = _frame_values(rng, 3)
    frames = np.array([5, 6, 8])
    sm = SmoothnessFactor(0.02)
    f = sm.make([X(0), X(1), X(2)], frames, values)
    # move the points: the (linear) factor stays exact away from its linearisation point
    moved = gtsam.Values(values)
    new = pts + rng.normal(size=(3, 3)) * 0.1
    for i in range(3):
        set_point(moved, X(i), new[i])
    a, _ = sm.evaluate(new, frames)
    assert f.error(moved) == pytest.approx(0.5 * np.sum(a ** 2) / 0.02 ** 2, rel=1e-9)
    # relinearised there: A is the analytic Jacobian [c0 I, c1 I, c2 I] / sigma (itself
    # checked numerically above) and -b the whitened acceleration at the moved points
    A, b = f.linearize(moved).jacobian()
    _, J = sm.evaluate(new, frames)
    np.testing.assert_allclose(A, J / 0.02, atol=1e-9)
    np.testing.assert_allclose(-b, a / 0.02, atol=1e-9)
    # add_many builds the same factors
    g = gtsam.NonlinearFactorGraph()
    sm.add_many(g, np.array([[X(0), X(1), X(2)]], dtype=np.uint64), frames[None], pts[None],
                values)
    assert g.error(moved) == pytest.approx(f.error(moved), rel=1e-12)


@pytest.mark.parametrize("kernel", ["geman_mcclure", "huber", "cauchy", "tukey"])
def test_kernel_weights_are_gtsams(kernel):
    from mirrorgraph.factors.reprojection import KERNELS, kernel_weights

    e = np.array([0.0, 0.3, 1.0, 2.0, 2.9, 4.5])
    m = KERNELS[kernel](2.5)
    np.testing.assert_allclose(kernel_weights(kernel, e, 2.5), [m.weight(x) for x in e],
                               rtol=1e-12)
