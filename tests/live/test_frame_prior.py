"""The per-frame bone prior of the live run (mirrorgraph.live.frame_prior) against the truth."""

from __future__ import annotations

import numpy as np

from mirrorgraph import geometry as geo
from mirrorgraph.live.frame_prior import refine_with_bones
from mirrorgraph.synth import make_wide_scene


def _frame_data(sc, t, rng, noise=4.0):
    X = sc.joints3d[t]
    u = geo.project(sc.K, X) + rng.normal(0.0, noise, (len(X), 2))
    um = geo.project(sc.K, geo.reflect_points(X, sc.normal, sc.distance)) + rng.normal(
        0.0, noise, (len(X), 2))
    return X, u, um


def _bones(sc):
    sk = sc.skeleton
    pairs = np.array([[sk.index(a), sk.index(b)] for a, b in sk.bones.values()])
    L = np.linalg.norm(sc.joints3d[0][pairs[:, 0]] - sc.joints3d[0][pairs[:, 1]], axis=1)
    return pairs, L


def test_without_bones_it_is_the_two_rays_triangulation():
    sc = make_wide_scene(0, "wide", "iid", 50)
    X, u, um = _frame_data(sc, 10, np.random.default_rng(0))
    X0 = geo.triangulate_mirror(sc.K, sc.normal, sc.distance, u, um, iterations=1)
    Xr, cov = refine_with_bones(sc.K, sc.normal, sc.distance, X0, u, um, np.arange(len(X)),
                                np.zeros((0, 2), int), np.zeros(0), 4.0, 0.02)
    eye, ones = np.eye(4), np.ones(len(X), bool)
    views = [geo.camera_projection(sc.K, eye),
             geo.mirror_projection(sc.K, eye, sc.normal, sc.distance)]
    ref = geo.triangulation_covariance(views, X0, [ones, ones], 4.0)
    assert np.abs(Xr - X0).max() < 2e-3              # one more Gauss-Newton step, metres
    assert np.allclose(cov, ref, rtol=0.02)


def test_the_bones_bring_the_joints_nearer_and_their_std_covers_it():
    """Over 60 frames of 4 px noise, the bones (at their true lengths, 1 % spread) bring
    the joints nearer the truth than their two rays alone, with a smaller std that still
    covers the error (its RMS over the std near 1)."""
    sc = make_wide_scene(3, "wide", "iid", 200)
    pairs, L = _bones(sc)
    rng = np.random.default_rng(1)
    e_rays, e_bones, z = [], [], []
    for t in range(0, 180, 3):
        X, u, um = _frame_data(sc, t, rng)
        X0 = geo.triangulate_mirror(sc.K, sc.normal, sc.distance, u, um, iterations=1)
        Xr, cov = refine_with_bones(sc.K, sc.normal, sc.distance, X0, u, um,
                                    np.arange(len(X)), pairs, L, 4.0, 0.01 * sc.subject_height)
        e_rays.append(np.linalg.norm(X0 - X, axis=1))
        e_bones.append(np.linalg.norm(Xr - X, axis=1))
        z.append(e_bones[-1] / np.sqrt(np.trace(cov, axis1=1, axis2=2)))
    e_rays, e_bones, z = map(np.concatenate, (e_rays, e_bones, z))
    assert np.sqrt(np.mean(e_bones ** 2)) < 0.95 * np.sqrt(np.mean(e_rays ** 2))
    assert 0.5 < np.sqrt(np.mean(z ** 2)) < 2.0


def test_a_joint_far_off_its_bone_is_pulled_back_robustly():
    """One joint's mirror pixel 60 px off along x (an outlier the reprojection threshold
    let through): the bones' Huber loss brings it back nearer than the rays put it."""
    sc = make_wide_scene(3, "wide", "iid", 50)
    pairs, L = _bones(sc)
    X, u, um = _frame_data(sc, 20, np.random.default_rng(2), noise=1.0)
    j = sc.skeleton.index("left_knee")
    um[j, 0] += 60.0
    X0 = geo.triangulate_mirror(sc.K, sc.normal, sc.distance, u, um, iterations=1)
    Xr, _ = refine_with_bones(sc.K, sc.normal, sc.distance, X0, u, um, np.arange(len(X)),
                              pairs, L, 1.0, 0.01 * sc.subject_height)
    assert np.linalg.norm(Xr[j] - X[j]) < 0.5 * np.linalg.norm(X0[j] - X[j])
