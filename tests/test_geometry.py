"""Round trips and identities of the mirror geometry, against ground truth."""

import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph.errors import DegenerateGeometryError

from tests.helpers import points_in_front, random_mirror


def test_virtual_camera_round_trip_and_reflection():
    rng = np.random.default_rng(0)
    for _ in range(20):
        n, d = random_mirror(rng)
        R, t = geo.virtual_camera_from_mirror(n, d)
        assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
        n2, d2 = geo.mirror_from_virtual_camera(R, t)
        assert np.allclose(n2, n) and np.isclose(d2, d)
        X = rng.normal(size=(10, 3))
        # X_virtual = D (R X + t) is the reflection S(X)
        assert np.allclose((X @ R.T + t) @ geo.D_FLIP.T, geo.reflect_points(X, n, d))
        # reflecting twice is the identity; the plane is fixed
        S = geo.reflect_points(X, n, d)
        assert np.allclose(geo.reflect_points(S, n, d), X)
        P = X - ((X @ n) - d)[:, None] * n
        assert np.allclose(geo.reflect_points(P, n, d), P)


def test_normalize_plane_orients_and_refuses_degenerate():
    n, d = geo.normalize_plane(np.array([0, 0, -2.0]), -6.0)
    assert np.allclose(n, [0, 0, 1]) and np.isclose(d, 3.0)
    with pytest.raises(DegenerateGeometryError):
        geo.normalize_plane(np.zeros(3), 1.0)
    with pytest.raises(DegenerateGeometryError):
        geo.normalize_plane(np.array([0, 0, 1.0]), 0.0)


def test_fundamental_is_skew_and_satisfied(scene_points):
    K, n, d, X, u, um = scene_points
    F = geo.fundamental_from_mirror(K, n)
    assert np.allclose(F, -F.T)
    # F ~ K^-T E K^-1 with E = 2 d [n]_x
    F2 = np.linalg.inv(K).T @ geo.essential_from_mirror(n, d) @ np.linalg.inv(K)
    F2 /= np.linalg.norm(F2)
    assert np.allclose(F, F2) or np.allclose(F, -F2)
    alg = np.einsum("ni,ij,nj->n", geo.to_homogeneous(um), F, geo.to_homogeneous(u))
    assert np.abs(alg).max() < 1e-12
    assert geo.epipolar_distances(geo.epipole_from_fundamental(F), u, um).max() < 1e-9
    assert geo.epipolar_distances_fundamental(F, u, um).max() < 1e-9


def test_epipole_is_image_of_normal(scene_points):
    K, n, d, X, u, um = scene_points
    e = geo.epipole_from_normal(K, n)
    assert np.allclose(geo.normal_from_epipole(K, e), n)
    assert np.allclose(geo.normal_from_epipole(K, -e), n)
    # the epipole is where the reflected point of a ray along n projects
    e_px = geo.epipole_pixels(e)
    assert np.allclose(geo.project(K, 1e9 * n), e_px, atol=1e-3)
    # the reflection lies between the joint and the epipole (mirror faces camera)
    assert np.all(np.linalg.norm(um - e_px, axis=1) < np.linalg.norm(u - e_px, axis=1))


def test_sampson_distance_matches_noise_level(scene_points):
    K, n, d, X, u, um = scene_points
    rng = np.random.default_rng(1)
    e = geo.epipole_from_normal(K, n)
    r = geo.signed_epipolar_distances(e, u + rng.normal(0, 3, u.shape), um + rng.normal(0, 3, u.shape))
    assert 2.4 < np.std(r) < 3.6  # first order: std of the per-coordinate noise


def test_triangulation_exact_and_noisy(scene_points):
    K, n, d, X, u, um = scene_points
    assert np.abs(geo.triangulate_mirror(K, n, d, u, um) - X).max() < 1e-9
    rng = np.random.default_rng(2)
    noisy = geo.triangulate_mirror(K, n, d, u + rng.normal(0, 1, u.shape), um + rng.normal(0, 1, u.shape))
    assert np.median(np.linalg.norm(noisy - X, axis=1)) < 0.03
    # NaN rows stay NaN, the others are unaffected
    u2 = u.copy()
    u2[0] = np.nan
    out = geo.triangulate_mirror(K, n, d, u2, um)
    assert np.isnan(out[0]).all() and np.allclose(out[1:], X[1:])


def test_gauss_newton_lowers_reprojection_error(scene_points):
    K, n, d, X, u, um = scene_points
    rng = np.random.default_rng(5)
    nu, num = u + rng.normal(0, 2, u.shape), um + rng.normal(0, 2, u.shape)

    def rms(Y):
        r = np.r_[geo.project(K, Y) - nu, geo.project(K, geo.reflect_points(Y, n, d)) - num]
        return np.sqrt(np.mean(r ** 2))
    assert rms(geo.triangulate_mirror(K, n, d, nu, num, iterations=3)) < \
        rms(geo.triangulate_mirror(K, n, d, nu, num, iterations=0))


def test_orient_normal_by_cheirality(scene_points):
    K, n, d, X, u, um = scene_points
    assert np.allclose(geo.orient_normal(K, -n, u, um), n)
    assert np.allclose(geo.orient_normal(K, n, u, um), n)


def test_decompose_reflective_essential():
    rng = np.random.default_rng(4)
    for _ in range(10):
        n, d = random_mirror(rng)
        R_true, t_true = geo.virtual_camera_from_mirror(n, d)
        R, t, n2 = geo.decompose_reflective_essential(geo.essential_from_mirror(n, d) * rng.uniform(-3, 3))
        assert np.allclose(R, R_true, atol=1e-9)
        assert np.allclose(n2, n) and np.allclose(t, t_true / np.linalg.norm(t_true))


def test_points_helper_in_front():
    rng = np.random.default_rng(9)
    n, d = random_mirror(rng)
    X = points_in_front(rng, n, d, 50)
    assert np.all(X @ n < d) and np.all(X[:, 2] > 0)


def test_symmetric_3x3_in_closed_form():
    """solve_sym3 / sym3_adjugate (the triangulations' normal equations) against LAPACK,
    on matrices conditioned up to 1e6 (two rays meeting at a small angle)."""
    rng = np.random.default_rng(3)
    Q = np.linalg.qr(rng.normal(size=(500, 3, 3)))[0]
    lam = np.stack([np.ones(500), rng.uniform(1e-3, 1, 500), 10.0 ** rng.uniform(-6, 0, 500)], 1)
    H = (Q * lam[:, None, :]) @ Q.transpose(0, 2, 1) * rng.uniform(1e-4, 1e4, (500, 1, 1))
    b = rng.normal(size=(500, 3))
    six = np.stack([H[:, a, c] for a, c in geo.SYM3])
    want = np.linalg.solve(H, b[..., None])[..., 0]
    scale = np.linalg.norm(want, axis=1)
    got = geo.solve_sym3(six, b.T).T
    assert np.all(np.linalg.norm(got - want, axis=1) <= 1e-8 * scale)
    adj, det = geo.sym3_adjugate(six)
    assert np.allclose(det, np.linalg.det(H), rtol=1e-8)
    again = geo.sym3_product(adj, b.T).T / det[:, None]
    assert np.all(np.linalg.norm(again - want, axis=1) <= 1e-8 * scale)


def test_similarity_align_recovers_a_known_similarity_and_matches_scipy():
    """``dst = s R src + t`` recovered exactly, batched, with weights; the rotation of
    noisy points equals SciPy's ``align_vectors`` on the centred points (same weights);
    NaN where a weighted point is missing or fewer than 3 carry weight."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(11)
    R = Rotation.random(4, random_state=rng).as_matrix()               # (4, 3, 3)
    s = rng.uniform(0.5, 2.0, 4)
    t = rng.normal(size=(4, 3))
    src = rng.normal(size=(4, 9, 3))
    dst = s[:, None, None] * np.einsum("bij,bnj->bni", R, src) + t[:, None, :]
    R_, s_, t_ = geo.similarity_align(src, dst)
    np.testing.assert_allclose(R_, R, atol=1e-12)
    np.testing.assert_allclose(s_, s, rtol=1e-12)
    np.testing.assert_allclose(t_, t, atol=1e-12)

    w = rng.uniform(0.1, 2.0, 9)
    noisy = dst[0] + rng.normal(0, 0.05, dst[0].shape)
    R1, _, _ = geo.similarity_align(src[0], noisy, w)
    mean = lambda x: (w[:, None] * x).sum(0) / w.sum()  # noqa: E731
    ref = Rotation.align_vectors(noisy - mean(noisy), src[0] - mean(src[0]), weights=w)[0]
    np.testing.assert_allclose(R1, ref.as_matrix(), atol=1e-10)

    holes = dst.copy()
    holes[1, 3] = np.nan
    w2 = np.ones((4, 9))
    w2[2, 2:] = 0.0
    _, s2, _ = geo.similarity_align(src, holes, w2)
    assert np.isnan(s2[1]) and np.isnan(s2[2]) and np.isfinite(s2[[0, 3]]).all()
    w2[1, 3] = 0.0                                   # the hole left out: aligned again
    R3, s3, _ = geo.similarity_align(src, holes, w2)
    np.testing.assert_allclose(R3[1], R[1], atol=1e-12)


def test_ray_angles_fold_rays_pointing_opposite_ways():
    """A joint on the line from the camera to the mirror, between them, has rays pointing
    opposite ways (180 deg apart as directions): as ill-conditioned as parallel ones."""
    n, d = np.array([0.0, 0.0, 1.0]), 5.0
    on_axis = np.array([[0.0, 0.0, 3.0]])
    assert geo.mirror_ray_angles_deg(on_axis, n, d)[0] == pytest.approx(0.0, abs=1e-6)
    # rays at 30 and at 150 deg as directions: the same conditioning, 30 deg
    for angle in (30.0, 150.0):
        # a point X whose directions X and X - 2 d n are `angle` apart, found on a line
        x = np.linspace(0.1, 20.0, 20000)
        pts = np.stack([x, np.zeros_like(x), np.full_like(x, 2.0)], 1)
        a = pts / np.linalg.norm(pts, axis=1, keepdims=True)
        b = pts - 2 * d * n
        b /= np.linalg.norm(b, axis=1, keepdims=True)
        raw = np.degrees(np.arccos(np.clip(np.sum(a * b, 1), -1, 1)))
        k = int(np.argmin(np.abs(raw - angle)))
        assert raw[k] == pytest.approx(angle, abs=0.1)
        assert geo.mirror_ray_angles_deg(pts[k], n, d) == pytest.approx(
            min(angle, 180.0 - angle), abs=0.1)


def test_project_with_jacobian_matches_projection_and_finite_differences():
    rng = np.random.default_rng(4)
    K = np.array([[1200.0, 0.5, 950.0], [0.0, 1180.0, 540.0], [0.0, 0.0, 1.0]])
    n, d = geo.normalize_plane(np.array([0.3, -0.1, 1.0]), 4.0)
    P = K @ np.column_stack([geo.householder(n), 2.0 * d * n])     # the mirror's view
    X = rng.normal([0.2, 0.1, 3.0], 0.5, (40, 3))
    for A, Y in ((K, X), (P, X)):
        u, J = geo.project_with_jacobian(A, Y)
        ref = geo.project(K, Y) if A is K else geo.project(K, geo.reflect_points(Y, n, d))
        np.testing.assert_allclose(u, ref, atol=1e-9)
        h = 1e-6
        fd = np.stack([(geo.project_with_jacobian(A, Y + h * e)[0]
                        - geo.project_with_jacobian(A, Y - h * e)[0]) / (2 * h)
                       for e in np.eye(3)], axis=-1)
        np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-3)
