"""Each output joint's own uncertainty (mirrorgraph.graph.joints_uncertainty) against the truth."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph import geometry as geo
from mirrorgraph.graph.joints_uncertainty import (chain_marginals, mirror_plane_projections,
                                                  position_std, triangulated_covariance,
                                                  with_scale)
from mirrorgraph.synth import make_wide_scene


def banded(rng, B: int, N: int) -> tuple[np.ndarray, ...]:
    """``B`` random positive definite matrices of ``N`` 3x3 blocks, band width two."""
    n = 3 * N
    H = np.zeros((B, n, n))
    for b in range(B):
        A = rng.normal(size=(n + 4, n))
        M = A.T @ A
        for i in range(N):
            for j in range(N):
                if abs(i - j) > 2:
                    M[3 * i:3 * i + 3, 3 * j:3 * j + 3] = 0.0
        H[b] = M + n * np.eye(n)
    blk = lambda b, i, k: (H[b, 3 * i:3 * i + 3, 3 * (i + k):3 * (i + k) + 3]  # noqa: E731
                           if i + k < N else np.zeros((3, 3)))
    parts = [np.array([[blk(b, i, k) for i in range(N)] for b in range(B)]) for k in range(3)]
    return H, *parts


def pixels(P: np.ndarray, X: np.ndarray) -> np.ndarray:
    y = X @ P[:, :3].T + P[:, 3]
    return y[:, :2] / y[:, 2:]


@pytest.mark.parametrize("N", [1, 2, 5, 16, 33])
@pytest.mark.parametrize("B", [3, 6])
@pytest.mark.parametrize("group", [2, 3, 8])
def test_chain_marginals_are_the_inverse_blocks(N, group, B):
    H, diag, off1, off2 = banded(np.random.default_rng(N), B, N)
    got = chain_marginals(diag, off1, off2, group)
    inv = np.linalg.inv(H)
    want = np.array([[inv[b, 3 * i:3 * i + 3, 3 * i:3 * i + 3] for i in range(N)]
                     for b in range(B)])
    assert np.abs(got - want).max() < 1e-12 * np.abs(want).max()
    rhs = np.random.default_rng(N + 1).normal(size=(B, N, 3))
    x, again = chain_marginals(diag, off1, off2, group, rhs=rhs)
    solved = np.linalg.solve(H, rhs.reshape(B, 3 * N, 1)).reshape(B, N, 3)
    assert np.abs(x - solved).max() < 1e-12 * np.abs(solved).max()
    assert np.array_equal(again, got)


def test_rays_alone_and_a_depth_nothing_fixes():
    """Two rays at a wide angle give a tight point; a point on the mirror's normal through
    the camera has its two rays on one line: its depth is left to nothing."""
    K = np.array([[1000.0, 0, 640], [0, 1000.0, 360], [0, 0, 1]])
    n, d = np.array([0.3, 0.0, 0.954]), 4.0
    n /= np.linalg.norm(n)
    good = np.array([[-0.5, 0.2, 2.5]])
    bad = (0.5 * d * n)[None]                       # on the line camera - mirror, along n
    bad = bad + np.array([[1e-3, 0.0, 0.0]])
    views = mirror_plane_projections(K, n, d)
    P = views(np.zeros(0))
    for X, expect_small in ((good, True), (bad, False)):
        uv = [pixels(p, X) for p in P]
        cov = triangulated_covariance(views, None, X, uv, [np.ones(1, bool)] * 2, 2.0)
        assert np.allclose(cov, geo.triangulation_covariance(P, X, [np.ones(1, bool)] * 2, 2.0))
        w = np.linalg.eigvalsh(cov[0])
        if expect_small:
            assert np.sqrt(w[-1]) < 0.05
        else:
            assert np.sqrt(w[-1]) > 1.0 and np.sqrt(w[-1]) > 100 * np.sqrt(w[0])
    # the plane's uncertainty adds to the rays' (with the body's gauge too, less its scale)
    Cz = np.diag([1e-4, 1e-4, 1e-4])
    X = np.array([[-0.5, 0.2, 2.5], [0.3, -0.4, 2.8], [0.1, 0.6, 2.2]])
    uv = [pixels(p, X) for p in P]
    ones = [np.ones(3, bool)] * 2
    rays = triangulated_covariance(views, None, X, uv, ones, 2.0)
    plane = triangulated_covariance(views, Cz, X, uv, ones, 2.0)
    gauge = triangulated_covariance(views, Cz, X, uv, ones, 2.0, frames=np.zeros(3, int))
    assert np.all(np.linalg.eigvalsh(plane - rays) > -1e-12)
    assert np.all(np.linalg.eigvalsh(gauge - rays) > -1e-12)
    assert not np.allclose(gauge, plane)


def test_scale_share_is_along_the_point():
    X = np.array([[1.0, 2.0, 2.0]])
    cov = with_scale(np.zeros((1, 3, 3)), X, 0.02)
    assert position_std(cov)[0] == pytest.approx(0.02 * 3.0)
    assert np.allclose(cov[0] @ X[0], 0.02 ** 2 * 9.0 * X[0])


@pytest.fixture(scope="module")
def wide_run():
    warnings.filterwarnings("ignore")
    sc = make_wide_scene(0, "wide", "iid", 300)
    run = mg.calibrate(sc.detections, mg.Intrinsics(K=sc.K, image_size=sc.image_size),
                       mg.CalibrateOptions(subject_height=sc.subject_height))
    return sc, run


def test_every_output_joint_has_a_std_that_covers_its_error(wide_run):
    sc, run = wide_run
    assert run.joints_std is not None and run.joints_cov is not None
    T, J = run.valid3d.shape
    assert run.joints_std.shape == (T, J) and run.joints_cov.shape == (T, J, 3, 3)
    ok = run.valid3d
    # a std for every output joint (the graph's and the completed ones), none elsewhere
    assert np.isfinite(run.joints_std[ok]).all() and np.isnan(run.joints_std[~ok]).all()
    assert run.completed[ok].any() and (~run.completed[ok]).any()
    assert np.allclose(run.joints_std[ok], position_std(run.joints_cov[ok]))
    assert (run.joints_std_shape[ok] <= run.joints_std[ok] + 1e-12).all()
    truth = np.asarray(sc.joints3d, float)
    err = np.linalg.norm(run.joints3d - truth, axis=-1)[ok]
    z = err / run.joints_std[ok]
    # metres against the metric std (the subject's height known to 2 %): never thin
    assert np.percentile(z, 99) < 3.0 and np.mean(z > 3) < 0.005
    # the shape at the calibration's scale: the std is the size of the error
    f = np.sum(truth[ok] * run.joints3d[ok]) / np.sum(run.joints3d[ok] ** 2)
    zs = (np.linalg.norm(f * run.joints3d - truth, axis=-1)[ok]
          / (f * run.joints_std_shape[ok]))
    assert 0.4 < np.median(zs) < 1.5
    assert np.percentile(zs, 99) < 3.0
    for part in (run.completed[ok], ~run.completed[ok]):
        assert 0.3 < np.median(zs[part]) < 1.5


def test_low_parallax_joints_are_covered_too(wide_run):
    """Where the two rays meet at the smallest angles the depth is the priors' (the bones,
    the smoothness): their std covers their error as the others' does."""
    sc, run = wide_run
    cal = run.calibration
    ok = run.valid3d & ~run.completed
    X = run.joints3d[ok]
    S = geo.reflect_points(X, cal.normal, cal.distance)
    cosang = np.abs(np.sum(X * S, axis=1) / np.linalg.norm(X, axis=1)
                    / np.linalg.norm(S, axis=1))
    angle = np.degrees(np.arccos(np.clip(cosang, 0, 1)))
    truth = np.asarray(sc.joints3d, float)[ok]
    f = np.sum(truth * X) / np.sum(X ** 2)
    z = np.linalg.norm(f * X - truth, axis=-1) / (f * run.joints_std_shape[ok])
    low = angle <= np.percentile(angle, 10)
    assert np.median(z[low]) < 1.5 and np.percentile(z[low], 99) < 3.0


def test_a_video_solved_in_chunks_has_its_stds_too(monkeypatch):
    """Longer than one graph (here 200 frames a graph): the chunks' joints get theirs."""
    from mirrorgraph.graph import RefineOptions

    warnings.filterwarnings("ignore")
    sc = make_wide_scene(1, "wide", "iid", 450)
    opts = mg.CalibrateOptions(subject_height=sc.subject_height)
    opts.refine_options = RefineOptions(max_graph_frames=200, chunk_block_frames=50)
    import mirrorgraph.graph.joints_uncertainty as ju

    seen = []
    chunked = ju._chunked

    def spy(*args):
        state = args[0]
        # the joints pass's observations: the calibration's, less any it left out
        assert len(state.joints_masks) == len(state.view_masks) == 2
        assert all(not (j & ~v).any() for j, v in zip(state.joints_masks, state.view_masks))
        seen.append(True)
        return chunked(*args)

    monkeypatch.setattr(ju, "_chunked", spy)
    run = mg.calibrate(sc.detections, mg.Intrinsics(K=sc.K, image_size=sc.image_size), opts)
    assert seen                                        # the chunks' path was taken
    ok = run.valid3d
    assert np.isfinite(run.joints_std[ok]).all() and np.isnan(run.joints_std[~ok]).all()
    truth = np.asarray(sc.joints3d, float)
    f = np.sum(truth[ok] * run.joints3d[ok]) / np.sum(run.joints3d[ok] ** 2)
    zs = (np.linalg.norm(f * run.joints3d - truth, axis=-1)[ok]
          / (f * run.joints_std_shape[ok]))
    assert 0.3 < np.median(zs) < 1.5 and np.percentile(zs, 99) < 3.0


def test_the_chunks_covariance_is_the_graphs_on_the_joints_pass_observations():
    """A long video's joints' covariance (the chunks' graphs are not kept: each joint's
    own rays, the smoothness, the bias, the mirror) on the observations the joints pass
    kept, where it left some out: the one graph's covariance of the same solution with
    the bones and the hip aside (which the chunks' formula leaves out), to 1e-6; on the
    calibration's observations (the left-out ones counted) it is not."""
    from dataclasses import replace

    from mirrorgraph.graph import RefineOptions
    from mirrorgraph.graph import joints_uncertainty as ju
    from mirrorgraph.graph.solve import solve
    from mirrorgraph.graph.stage_config import single_mirror_config
    from mirrorgraph.pipelines.solve import prepare, with_intrinsics
    from mirrorgraph.synth import make_scene

    warnings.filterwarnings("ignore")
    sc = make_scene(frames=240, seed=0, noise_std=4.0, epipolar_outlier_rate=0.08)
    p = sc.paired()
    opts = RefineOptions(subject_height=sc.subject_height)
    rig = prepare(p, sc.K, sc.normal, p.valid(), None, opts)
    state = solve(rig, opts, single_mirror_config(opts), height=opts.subject_height)
    rig = with_intrinsics(rig, state.intrinsics)
    kept = [np.asarray(v.mask, bool) for v in state.problem.rig.views]
    left = (state.view_masks[0] & ~kept[0]) | (state.view_masks[1] & ~kept[1])
    assert left.sum() >= 50                         # views of joints the joints pass left out
    graph = position_std(ju.graph_joints_covariance(
        state, replace(opts, use_bone_length=False, use_hip=False), joints_pass=True, rig=rig))
    empty = np.full(state.used.shape + (3, 3), np.nan)
    chunks = position_std(ju._chunked(replace(state, problem=None, joints_masks=kept), opts,
                                      True, 1.0, rig, empty.copy()))
    ok = np.isfinite(graph)
    assert ok.sum() > 2000 and np.array_equal(ok, np.isfinite(chunks))
    np.testing.assert_allclose(chunks[ok], graph[ok], rtol=1e-6)
    counted = position_std(ju._chunked(replace(state, problem=None), opts, True, 1.0, rig,
                                       empty.copy()))
    assert np.median(np.abs(counted[left] / graph[left] - 1)) > 0.05
