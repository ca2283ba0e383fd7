"""The factor graph end to end: rig, builder, optimiser, refine_mirror, chunked solve.

Scenes come from mirrorgraph.synth.make_scene (4 px detector noise as in MirrorCalib's
protocol); the initial mirror is the true one tilted by 1 deg, i.e. a 2 deg error of the
virtual camera's rotation.
"""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph.graph import (Camera, Mirror, RefineOptions, Rig, View,
                               rotation_std_from_normal_cov)
from mirrorgraph.pipelines.solve import refine_mirror
from mirrorgraph.graph.builder import build_problem
from mirrorgraph.graph.problem import extract_planes
from mirrorgraph.graph.chunked import chunk_ranges, spread_blocks
from mirrorgraph.graph.optimizer import LevenbergMarquardt, LMParams
from mirrorgraph.graph.reduction import mirror_reduction
from mirrorgraph.keypoints import PairedKeypoints
from mirrorgraph.skeletons import COCO_17
from mirrorgraph.metrics import mirror_rotation_error_deg as rotation_error_deg
from mirrorgraph.synth import make_scene, tilted_normal as tilted


# --------------------------------------------------------------------------- helpers

def noisy_copy(scene, rng: np.random.Generator, std: float = 4.0) -> PairedKeypoints:
    """The scene's clean keypoints with fresh Gaussian noise (same geometry, new draw)."""
    base = scene.paired()
    real, mirror = base.real.copy(), base.mirror.copy()
    real[..., :2] = scene.real_clean + rng.normal(0.076, std, scene.real_clean.shape)
    mirror[..., :2] = scene.mirror_clean + rng.normal(0.076, std, scene.mirror_clean.shape)
    return PairedKeypoints(skeleton=base.skeleton, frame_ids=base.frame_ids, real=real,
                           mirror=mirror)


@pytest.fixture(scope="module")
def scene():
    return make_scene(frames=300, seed=3, noise_std=4.0)


@pytest.fixture(scope="module")
def refined(scene):
    p = scene.paired()
    n0 = tilted(scene.normal, 1.0, np.random.default_rng(0))
    calls = []
    res = refine_mirror(p, scene.K, n0, p.valid(),
                        options=RefineOptions(subject_height=scene.subject_height),
                        progress=lambda i, e: calls.append((i, e)))
    return p, n0, res, calls


# --------------------------------------------------------------------------- refine_mirror
def test_refined_is_better_than_the_initial_mirror(scene, refined):
    _, n0, res, _ = refined
    init = rotation_error_deg(n0, scene.normal)
    err = rotation_error_deg(res.normal, scene.normal)
    assert init == pytest.approx(2.0, abs=1e-6)
    assert err < 0.25 * init
    assert err < 4.0 * res.rotation_std_deg


def test_result_fields(scene, refined):
    p, _, res, calls = refined
    T, J = p.real.shape[:2]
    assert res.joints3d.shape == (T, J, 3) and res.valid.shape == (T, J)
    assert np.isfinite(res.joints3d[res.valid]).all()
    assert np.isnan(res.joints3d[~res.valid]).all()
    assert not res.valid[:, scene.skeleton.index("nose")].any()       # not a calibration joint
    assert res.scale == "subject_height"
    assert res.normal_cov.shape == (3, 3)
    assert np.allclose(res.normal_cov @ res.normal, 0.0, atol=1e-12)  # tangent to the sphere
    assert res.rotation_std_deg == pytest.approx(rotation_std_from_normal_cov(res.normal_cov))
    assert 0 < res.distance_std < 0.1 * res.distance
    assert 1.0 < res.rms_direct_px < 6.0 and 1.0 < res.rms_mirror_px < 6.0
    assert res.iterations >= len(calls) >= 2          # solves; progress counts accepted steps
    assert calls[-1][1] == pytest.approx(res.final_error)
    assert set(res.timings) >= {"build", "solve", "marginals", "total"}
    assert {"reprojection", "bone_length", "symmetry", "anthropometry",
            "length_sum_gauge"} <= set(res.priors)
    assert {"bone_length", "smoothness"} <= set(res.priors["joints_pass"])
    assert "hip" not in res.priors                                    # COCO has no mid-hip
    assert set(res.bone_lengths) == {b for b in scene.skeleton.bone_names}


def test_metric_distance_with_known_height(scene, refined):
    _, _, res, _ = refined
    assert res.distance == pytest.approx(scene.distance, rel=0.03)
    # and the body comes out metric too
    femur = np.mean([res.bone_lengths["left_femur"], res.bone_lengths["right_femur"]])
    true = np.linalg.norm(scene.joints3d[0, scene.skeleton.index("left_hip")]
                          - scene.joints3d[0, scene.skeleton.index("left_knee")])
    assert femur == pytest.approx(true, rel=0.05)


def test_unit_distance_without_height(scene, refined):
    p, n0, metric, _ = refined
    res = refine_mirror(p, scene.K, n0, p.valid())
    assert res.scale == "unit_distance" and res.distance == 1.0 and res.distance_std == 0.0
    # the same mirror (the gauge does not change it), the joints in units of d
    assert rotation_error_deg(res.normal, metric.normal) < 0.2 * metric.rotation_std_deg
    both = res.valid & metric.valid
    np.testing.assert_allclose(res.joints3d[both] * metric.distance, metric.joints3d[both],
                               atol=0.01)


def test_marginal_std_agrees_with_the_error_spread():
    """Several noise draws on one scene: RMS error vs the reported RMS std (factor 2)."""
    scene = make_scene(frames=200, seed=5, noise_std=0.0)
    rng = np.random.default_rng(11)
    errs, stds = [], []
    for _ in range(6):
        p = noisy_copy(scene, rng)
        res = refine_mirror(p, scene.K, tilted(scene.normal, 1.0, rng), p.valid(),
                            options=RefineOptions(subject_height=scene.subject_height))
        errs.append(rotation_error_deg(res.normal, scene.normal))
        stds.append(res.rotation_std_deg)
    rms_err = float(np.sqrt(np.mean(np.square(errs))))
    std = float(np.mean(stds))
    assert 0.5 < rms_err / std < 2.0, (errs, stds)


def test_frame_gaps_do_not_break_smoothness():
    scene = make_scene(frames=300, seed=4, noise_std=4.0)
    p = scene.paired()
    keep = np.ones(len(p), dtype=bool)
    keep[[40, 41, 90]] = False          # short gaps: bridged by non-uniform differences
    keep[150:190] = False               # a long gap: no factor across it
    q = PairedKeypoints(skeleton=p.skeleton, frame_ids=p.frame_ids[keep], real=p.real[keep],
                        mirror=p.mirror[keep])
    res = refine_mirror(q, scene.K, tilted(scene.normal, 1.0, np.random.default_rng(2)),
                        q.valid(), options=RefineOptions(subject_height=scene.subject_height))
    assert rotation_error_deg(res.normal, scene.normal) < 4.0 * res.rotation_std_deg
    # the smoothness factors: every joint, consecutive estimates, no step longer than 4
    fid = q.frame_ids
    expected = 0
    for j in scene.skeleton.calibration_joints:
        rows = np.flatnonzero(res.valid[:, j])
        steps = np.diff(fid[rows])
        expected += int(np.count_nonzero((steps[:-1] <= 4) & (steps[1:] <= 4)))
    assert res.priors["joints_pass"]["smoothness"]["factors"] == expected
    # joints on either side of the long gap are estimated, and move smoothly
    assert res.valid[149].any() and res.valid[150].any()


def test_outliers_are_rejected_and_the_mirror_stays_accurate():
    scene = make_scene(frames=300, seed=6, noise_std=4.0, outlier_rate=0.1)
    p = scene.paired()
    n0 = tilted(scene.normal, 1.0, np.random.default_rng(3))
    res = refine_mirror(p, scene.K, n0, p.valid(),
                        options=RefineOptions(subject_height=scene.subject_height))
    outlier = (scene.outlier_mask_real | scene.outlier_mask_mirror) & p.valid()
    calib = np.zeros(outlier.shape[1], dtype=bool)
    calib[scene.skeleton.calibration_joints] = True
    outlier &= calib
    kept = np.count_nonzero(res.inliers & outlier) / np.count_nonzero(outlier)
    assert kept < 0.25                          # most outliers rejected...
    assert np.count_nonzero(res.inliers & ~outlier) > 0.9 * np.count_nonzero(~outlier & calib
                                                                               & p.valid())
    err = rotation_error_deg(res.normal, scene.normal)
    assert err < 4.0 * res.rotation_std_deg      # ...and the mirror is as good as its std says
    assert res.distance == pytest.approx(scene.distance, rel=0.05)


def test_long_video_is_solved_in_chunks():
    scene = make_scene(frames=700, seed=7, noise_std=4.0)
    p = scene.paired()
    n0 = tilted(scene.normal, 1.0, np.random.default_rng(4))
    opts = RefineOptions(subject_height=scene.subject_height)
    single = refine_mirror(p, scene.K, n0, p.valid(), options=opts)
    from dataclasses import replace
    chunked = refine_mirror(p, scene.K, n0, p.valid(),
                            options=replace(opts, max_graph_frames=300, chunk_block_frames=100,
                                            workers=2))
    assert any(s["name"].startswith("chunk pass") for s in chunked.stages)
    # the chunks solved in two processes or in this one: the same result
    serial = refine_mirror(p, scene.K, n0, p.valid(),
                           options=replace(opts, max_graph_frames=300, chunk_block_frames=100,
                                           workers=1))
    np.testing.assert_allclose(serial.normal, chunked.normal, atol=1e-12)
    np.testing.assert_allclose(serial.joints3d, chunked.joints3d, atol=1e-9, equal_nan=True)
    assert rotation_error_deg(chunked.normal, single.normal) < 0.5 * single.rotation_std_deg
    assert chunked.rotation_std_deg == pytest.approx(single.rotation_std_deg, rel=0.2)
    assert chunked.valid.sum() > 0.95 * single.valid.sum()
    both = chunked.valid & single.valid
    assert np.median(np.linalg.norm(chunked.joints3d[both] - single.joints3d[both], axis=-1)) \
        < 0.01
    # the joints pass runs chunk by chunk too: the joints are as close to the truth
    assert any(s["name"].startswith("joints pass") and "chunks" in s["name"]
               for s in chunked.stages)
    truth = scene.joints3d[both]
    err_single = np.median(np.linalg.norm(single.joints3d[both] - truth, axis=-1))
    err_chunked = np.median(np.linalg.norm(chunked.joints3d[both] - truth, axis=-1))
    assert err_chunked < 1.2 * err_single
    rough = refine_mirror(p, scene.K, n0, p.valid(),
                          options=replace(opts, max_graph_frames=300, chunk_block_frames=100,
                                          joints_smoothness_sigma=None))
    err_rough = np.median(np.linalg.norm(rough.joints3d[both] - truth, axis=-1))
    assert err_chunked < 0.8 * err_rough


def test_chunk_helpers():
    m = spread_blocks(1000, 300, 100)
    assert m.sum() == 300
    assert m[:100].all() and m[-100:].all()
    assert spread_blocks(200, 300, 100).all()
    r = chunk_ranges(1000, 300)
    assert r[0][0] == 0 and r[-1][1] == 1000 and len(r) == 4
    assert all(b - a <= 300 for a, b in r)


def test_bad_inputs():
    scene = make_scene(frames=20, seed=1)
    p = scene.paired()
    from mirrorgraph.errors import DegenerateGeometryError, InputError
    with pytest.raises(InputError):
        refine_mirror(p, scene.K, scene.normal, p.valid()[:5])
    with pytest.raises(InputError):
        refine_mirror(p, scene.K, np.zeros(3), p.valid())
    with pytest.raises(DegenerateGeometryError):
        refine_mirror(p, scene.K, scene.normal, np.zeros_like(p.valid()))


# --------------------------------------------------------------------------- the rig is generic
def test_two_mirrors_in_one_rig():
    """Three views (direct + two mirrors): both planes recovered by the same machinery."""
    rng = np.random.default_rng(12)
    K = np.array([[1400.0, 0.0, 960.0], [0.0, 1400.0, 540.0], [0.0, 0.0, 1.0]])
    mirrors = [(np.array([0.35, 0.0, 1.0]), 4.0), (np.array([-0.4, 0.1, 1.0]), 3.5)]
    mirrors = [(n / np.linalg.norm(n), d) for n, d in mirrors]
    T, J = 30, COCO_17.num_joints
    pts = rng.uniform([-0.5, -0.7, 2.2], [0.5, 0.7, 2.8], size=(T, J, 3))
    joints = COCO_17.calibration_joints
    mask = np.zeros((T, J), dtype=bool)
    mask[:, joints] = True
    cam = Camera("cam", K)
    views = [View("direct", "cam", None, geo.project(K, pts), mask)]
    for i, (n, d) in enumerate(mirrors):
        views.append(View(f"m{i}", "cam", f"mirror{i}",
                          geo.project(K, geo.reflect_points(pts, n, d)), mask))
    rig = Rig(cameras=(cam,), mirrors=tuple(Mirror(f"mirror{i}", n, d)
                                             for i, (n, d) in enumerate(mirrors)),
              views=tuple(views), skeleton=COCO_17, frame_ids=np.arange(T), joints=joints)
    start = [(tilted(n, 1.0, rng), d * (1.02 if i else 1.0)) for i, (n, d) in enumerate(mirrors)]
    noisy = pts + rng.normal(scale=0.01, size=pts.shape)
    opts = RefineOptions(robust_kernel=None)
    problem = build_problem(rig, noisy, mask, start, opts, priors=False)
    assert len(problem.virtual_keys) == 2 and len(problem.plane_keys) == 2
    red = mirror_reduction(problem, distance_gauge=mirrors[0][1])
    lm = LevenbergMarquardt(problem.reprojection, red, LMParams(max_iterations=15),
                            ordering=problem.point_ordering())
    res = lm.optimize(problem.values)
    assert res.converged
    for (n_true, d_true), (n, d) in zip(mirrors, extract_planes(problem, res.values)):
        assert rotation_error_deg(n, n_true) < 1e-4
        assert d == pytest.approx(d_true, rel=1e-6)


def test_reduced_covariance_matches_dense_inverse():
    from mirrorgraph.graph.optimizer import reduced_covariance
    from gtsam.symbol_shorthand import L, P
    rng = np.random.default_rng(13)
    A = rng.normal(size=(12, 7))
    H = A.T @ A
    cov = reduced_covariance(H, [(L(0), 4), (P(0), 3)])
    np.testing.assert_allclose(cov[P(0)], np.linalg.inv(H)[4:, 4:], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(cov[L(0)], np.linalg.inv(H)[:4, :4], rtol=1e-8, atol=1e-12)


def test_reduced_covariance_survives_a_tight_gauge_and_refuses_a_singular_system():
    """A gauge of weight 1e12 beside directions of weight 1e2 (GTSAM's Cholesky calls
    that indeterminate) is inverted; a direction nothing fixes gives NaN, not an error."""
    from mirrorgraph.graph.optimizer import reduced_covariance
    from gtsam.symbol_shorthand import L, P
    rng = np.random.default_rng(3)
    A = rng.normal(size=(20, 6)) * np.array([1e6, 1e6, 1e6, 10.0, 10.0, 10.0])
    H = A.T @ A
    cov = reduced_covariance(H, [(L(0), 3), (P(0), 3)])
    np.testing.assert_allclose(cov[P(0)], np.linalg.inv(H)[3:, 3:], rtol=1e-6)
    H[:, 5] = H[5, :] = 0.0
    assert np.isnan(reduced_covariance(H, [(L(0), 3), (P(0), 3)])[P(0)]).all()


def test_rotation_std_is_twice_the_normal_spread():
    """Isotropic tangent covariance sigma^2: the RMS rotation is 2 sqrt(2) sigma."""
    n = np.array([0.0, 0.0, 1.0])
    sigma = np.radians(0.01)
    cov = sigma ** 2 * (np.eye(3) - np.outer(n, n))
    assert rotation_std_from_normal_cov(cov) == pytest.approx(np.degrees(2 * np.sqrt(2) * sigma))
    # Monte Carlo: normals drawn with that covariance, virtual-camera rotation errors
    rng = np.random.default_rng(0)
    errs = []
    for _ in range(400):
        m = n + rng.multivariate_normal(np.zeros(3), cov)
        errs.append(rotation_error_deg(m / np.linalg.norm(m), n))
    rms = np.sqrt(np.mean(np.square(errs)))
    assert rms == pytest.approx(rotation_std_from_normal_cov(cov), rel=0.1)


def test_joints_pass_follows_the_held_mirror_to_first_order(scene, refined):
    """The joints pass's sensitivity to the mirror it holds: its joints at a plane moved by
    ``z`` are its joints at the plane plus ``sensitivity @ z`` (a chunked solve moves every
    chunk's joints by the shared step so, instead of solving them again), the torso's
    distances held at one reading as a chunk holds them."""
    from mirrorgraph.factors import plane_from_gtsam, plane_to_gtsam
    from mirrorgraph.graph.problem import extract_points, snap_virtual_poses
    from mirrorgraph.graph.rig import seen_twice, triangulate_rig
    from mirrorgraph.graph.stages import joints_pass
    from mirrorgraph.pipelines.solve import prepare

    p, _, res, _ = refined
    opts = RefineOptions(subject_height=scene.subject_height)
    rig = prepare(p, scene.K, res.normal, res.inliers, None, opts)
    plane0 = (np.asarray(res.normal), float(res.distance))
    masks = [np.asarray(v.mask, bool) for v in rig.views]
    pts, ok = triangulate_rig(rig, masks, [c.pose for c in rig.cameras], [plane0])
    ok &= seen_twice(masks) & np.isfinite(pts).all(-1)

    def solved(plane, torso):       # the joints pass from the same start, the plane held
        problem = build_problem(rig, pts, ok, [plane], opts, body_height=scene.subject_height,
                                bone_lengths=res.bone_lengths)
        snap_virtual_poses(problem, problem.values)
        jp, lm = joints_pass(problem, problem.values, res.bone_lengths, opts, sensitivity=True,
                             torso=torso)
        return extract_points(jp, lm.values), lm.sensitivity, jp

    torso = solved(plane0, None)[2].prior_info["torso"]["lengths"]
    assert len(torso) == 4
    x0, M, jp = solved(plane0, torso)
    assert M.shape == (len(jp.flat_index), 3, 3)
    # the plane turned by ~0.01 and ~0.06 deg, moved by 5 and 20 mm
    for z in (np.array([2e-4, -1e-4, 5e-3]), np.array([-1e-3, 5e-4, -2e-2])):
        x1, _, _ = solved(plane_from_gtsam(plane_to_gtsam(*plane0).retract(z)), torso)
        pred = x0.reshape(-1, 3).copy()
        pred[jp.flat_index] += M @ z
        moved = np.linalg.norm(x1 - x0, axis=-1)[jp.used]
        off = np.linalg.norm(x1 - pred.reshape(x0.shape), axis=-1)[jp.used]
        assert np.median(moved) > 1e-3                  # the joints follow the mirror...
        assert np.median(off) < 0.01 * np.median(moved)  # ...as the sensitivity says
        assert off.max() < 0.02 * moved.max()
