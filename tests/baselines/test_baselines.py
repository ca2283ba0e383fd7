"""Smoke tests of the comparison baselines (mirrorgraph.baselines) and of bench/compare.py.

The paper's method needs torch and the aniposelib adapter needs aniposelib (the
``bench`` extra); their tests are skipped, saying so, when the library is missing.
The geometry of both (flip convention, triangulation, the Cramer-Rao bound) is
tested without them.
"""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph import metrics
from mirrorgraph.baselines import triangulate_virtual
from mirrorgraph.baselines.anipose import flip_points, flipped_intrinsics
from mirrorgraph.synth import make_scene

from tests.helpers import REPO_ROOT


def _has(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


needs_torch = pytest.mark.skipif(not _has("torch"), reason="torch is not installed "
                                 "(pip install 'mirrorgraph[bench]')")
needs_aniposelib = pytest.mark.skipif(not _has("aniposelib"), reason="aniposelib is not "
                                      "installed (pip install 'mirrorgraph[bench]')")


def _proper(R: np.ndarray) -> bool:
    return np.allclose(R.T @ R, np.eye(3), atol=1e-9) and np.isclose(np.linalg.det(R), 1.0)


@pytest.fixture(scope="module")
def clean_scene():
    return make_scene(frames=40, seed=5, noise_std=0.0, noise_mean=0.0)


# --------------------------------------------------------------------------- geometry
def test_flipped_image_camera_is_the_virtual_camera_with_proper_rotation(K):
    """Flipping the image (x -> W - x, cx -> W - cx) turns the virtual camera into (R, t)."""
    rng = np.random.default_rng(0)
    W = 1920
    n = np.array([0.4, -0.1, 0.9])
    n /= np.linalg.norm(n)
    d = 3.2
    X = rng.uniform([-0.5, -0.8, 1.5], [0.5, 0.8, 2.5], (30, 3))
    um = geo.project(K, geo.reflect_points(X, n, d))
    R, t = geo.virtual_camera_from_mirror(n, d)
    assert _proper(R)
    Kf = flipped_intrinsics(K, W)
    # an ordinary right-handed camera (R, t) with K_f sees the flipped image
    assert np.allclose(geo.project(Kf, X @ R.T + t), flip_points(um, W), atol=1e-9)
    assert np.allclose(flip_points(flip_points(um, W), W), um)


def test_triangulate_virtual_recovers_points(K):
    rng = np.random.default_rng(1)
    n = np.array([-0.3, 0.05, 0.95])
    n /= np.linalg.norm(n)
    d = 2.8
    X = rng.uniform([-0.5, -0.8, 1.2], [0.5, 0.8, 2.2], (25, 3))
    u = geo.project(K, X)
    um = geo.project(K, geo.reflect_points(X, n, d))
    R, t = geo.virtual_camera_from_mirror(n, d)
    Y = triangulate_virtual(K, R, t, u, um)
    assert np.allclose(Y, X, atol=1e-8)
    um[3] = np.nan
    assert np.isnan(triangulate_virtual(K, R, t, u, um)[3]).all()


# --------------------------------------------------------------------------- the paper
@needs_torch
def test_paper_method_without_refinement_is_exact_on_noiseless_data(clean_scene):
    from mirrorgraph.baselines.paper import PaperOptions, mirrorcalib_paired
    sc = clean_scene
    res = mirrorcalib_paired(sc.paired(), sc.K, options=PaperOptions(refine=False))
    assert _proper(res.rotation)
    assert metrics.rotation_error_deg(res.rotation, sc.virtual_R) < 1e-4
    assert metrics.normal_angle_deg(res.normal, sc.normal) < 1e-4
    used = sc.paired().valid()[:, sc.skeleton.calibration_joints]
    assert res.inliers[:, sc.skeleton.calibration_joints].sum() == used.sum()


@needs_torch
def test_paper_method_refines_and_returns_a_rotation():
    from mirrorgraph.baselines.paper import DEFAULT_WEIGHTS, PaperOptions, mirrorcalib_paired
    sc = make_scene(frames=60, seed=3, noise_std=3.0)
    res = mirrorcalib_paired(sc.paired(fix_lr=False), sc.K, options=PaperOptions(steps=3))
    assert _proper(res.rotation) and _proper(res.initial_rotation)
    assert metrics.rotation_error_deg(res.rotation, sc.virtual_R) < 10.0
    assert res.steps >= 1
    first = res.history[1]
    # every loss is balanced to 1 at the detections (hip is absent in COCO-17), so the
    # objective starts at the sum of the weights; one L-BFGS step must lower it
    start = sum(w for k, w in DEFAULT_WEIGHTS.items() if k in res.lambdas)
    assert "hip" not in res.lambdas
    assert np.isfinite(first["total"]) and first["total"] < start
    # the refined joints moved, but stayed near the detections (robust reprojection term)
    j = sc.skeleton.calibration_joints
    shift = np.linalg.norm(res.real_refined[:, j] - sc.paired().real[:, j, :2], axis=-1)
    assert 0.0 < np.nanmedian(shift) < 10.0
    assert np.isfinite(res.joints3d[:, j]).any()
    assert res.inliers.sum() > 0.5 * np.isfinite(shift).sum()


def test_paper_method_says_how_to_install_torch(monkeypatch):
    from mirrorgraph.baselines import BenchDependencyError
    from mirrorgraph.baselines.paper import mirrorcalib_paired
    monkeypatch.setitem(sys.modules, "torch", None)           # import torch -> ImportError
    sc = make_scene(frames=20, seed=2)
    with pytest.raises(BenchDependencyError, match=r"mirrorgraph\[bench\]"):
        mirrorcalib_paired(sc.paired(), sc.K)


# --------------------------------------------------------------------------- aniposelib
@needs_aniposelib
def test_anipose_adapter_flip_convention_on_noiseless_data(clean_scene):
    """Start bundle adjustment 3 deg and 10 % off the truth: it must come back to it."""
    from mirrorgraph.baselines.anipose import AniposeOptions, calibrate_anipose_paired
    sc = clean_scene
    R_true, t_true = sc.virtual_R, sc.virtual_t
    a = np.radians(3.0)
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    start = (Rz @ R_true, 1.1 * (Rz @ t_true))
    res = calibrate_anipose_paired(sc.paired(), sc.K,
                                   options=AniposeOptions(initial_pose=start))
    assert _proper(res.rotation)
    assert metrics.rotation_error_deg(res.initial_rotation, R_true) > 2.9
    assert metrics.rotation_error_deg(res.rotation, R_true) < 0.01
    assert metrics.normal_angle_deg(res.normal, sc.normal) < 0.01
    assert res.error < 0.05                     # px, median reprojection error
    j = sc.skeleton.calibration_joints
    X = res.joints3d[:, j] * (2 * sc.distance)  # unit |t| = 1 -> metres
    assert np.nanmax(np.abs(X - sc.joints3d[:, j])) < 1e-3


@needs_aniposelib
def test_anipose_adapter_runs_with_the_users_initialisation():
    from mirrorgraph.baselines.anipose import AniposeOptions, calibrate_anipose_paired
    sc = make_scene(frames=60, seed=4, noise_std=2.0)
    res = calibrate_anipose_paired(sc.paired(fix_lr=False), sc.K,
                                   options=AniposeOptions(init="essential"))
    assert _proper(res.rotation)
    assert np.isclose(np.linalg.norm(res.translation), 1.0)
    assert np.isfinite(res.error)


# --------------------------------------------------------------------------- bench/compare.py
@pytest.fixture(scope="module")
def compare():
    spec = importlib.util.spec_from_file_location("bench_compare",
                                                  REPO_ROOT / "bench" / "compare.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod            # dataclasses look their module up by name
    try:
        spec.loader.exec_module(mod)
    except BaseException:
        sys.modules.pop(spec.name, None)
        raise
    return mod


def test_correlated_noise_has_the_asked_std_and_correlation(compare):
    e = compare._ar1_noise(np.random.default_rng(0), (2, 4000, 17, 2), 0.9, 4.0)
    assert abs(e.std() - 4.0) < 0.2
    r = np.corrcoef(e[:, 1:].ravel(), e[:, :-1].ravel())[0, 1]
    assert abs(r - 0.9) < 0.02


def test_compare_scores_a_perturbed_scene(compare):
    case = compare.Case("bias", 4.0, 0, dict(frames=60, bias_px=4.0, ar_rho=0.5))
    prep = compare.build_case(case)
    # the reflection keeps its detector labels in the raw detections
    assert len(prep.raw.people[0]) == 2
    for method in ("baseline1", "mg_init"):
        rec = compare.evaluate(method, prep, 0)
        assert rec["ok"], rec
        assert 0 <= rec["rot_deg"] < 20 and rec["pampjpe_mm"] > 0 and rec["time_s"] > 0
    bound = compare.scene_bound(prep)
    assert 0 < bound["rot_median_deg"] < 1.0
