"""The reported uncertainty follows the noise actually in the data (a posteriori sigma)."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.graph.result import residual_noise_px
from mirrorgraph.intrinsics import Intrinsics
from mirrorgraph.pipelines.mirror import CalibrateOptions, calibrate
from mirrorgraph.synth.scene import make_scene


def test_residual_noise_counts_degrees_of_freedom():
    rng = np.random.default_rng(0)
    r = rng.normal(0.0, 3.0, 20000)
    assert residual_noise_px(float(np.sum(r ** 2)), 20000, 0) == pytest.approx(3.0, rel=0.02)
    # residuals of a fit are smaller than the noise by sqrt(1 - u/m)
    shrunk = r * np.sqrt(0.25)
    assert residual_noise_px(float(np.sum(shrunk ** 2)), 20000, 15000) == pytest.approx(3.0, rel=0.02)
    assert np.isnan(residual_noise_px(1.0, 4, 4))


def _run(noise: float):
    scene = make_scene(frames=500, seed=3, noise_std=noise)
    c = calibrate(scene.detections, Intrinsics(K=scene.K, image_size=scene.image_size),
                  CalibrateOptions(subject_height=scene.subject_height)).calibration
    return c.refinement["priors"]["reprojection"], c.uncertainty["rotation_std_deg"]


def test_single_mirror_std_scales_with_the_detector_noise():
    """The graph assumes 4 px; at 1 px and 8 px the reported std follows the data."""
    low, std_low = _run(1.0)
    high, std_high = _run(8.0)
    assert low["a_posteriori_sigma_px"] == pytest.approx(1.0, rel=0.1)
    assert high["a_posteriori_sigma_px"] == pytest.approx(8.0, rel=0.1)
    assert low["covariance_scaled_by"] == pytest.approx(1 / 16, rel=0.25)
    assert std_high / std_low == pytest.approx(8.0, rel=0.25)


def test_rig_reports_the_noise_it_saw(tmp_path):
    from mirrorgraph.pipelines.rig import calibrate_rig
    from mirrorgraph.synth.rig import make_rig, write_rig

    rig = make_rig("4cams", frames=100, seed=2, noise_std=2.0)
    cal = calibrate_rig(write_rig(rig, tmp_path))
    rep = cal.refinement["priors"]["reprojection"]
    assert rep["a_posteriori_sigma_px"] == pytest.approx(2.0, rel=0.1)
    assert rep["covariance_scaled_by"] == pytest.approx(0.25, rel=0.25)
    # every estimated camera: the robust figure, never below the marginals, beside them
    for c in cal.cameras[1:]:
        assert 0 < c.marginal_rotation_std_deg <= c.rotation_std_deg \
            <= 3 * c.marginal_rotation_std_deg
    d = cal.to_dict()
    assert {"rotation_std_deg", "marginal_rotation_std_deg"} <= set(d["cameras"][1]["uncertainty"])


# --------------------------------------------------------------------------- the robust figure
def _calibrate_scene(**kw):
    from mirrorgraph.metrics import mirror_rotation_error_deg
    from mirrorgraph.synth import make_wide_scene
    sc = make_wide_scene(1, "gym", "iid", 800, **kw)
    run = calibrate(sc.detections, sc.intrinsics, CalibrateOptions())
    u = run.calibration.uncertainty
    return run, u, mirror_rotation_error_deg(run.calibration.normal, sc.normal)


def test_the_robust_figure_is_the_marginal_one_under_iid_noise_and_wider_under_a_bias():
    """iid 4 px: the headline std stays within 1.5x the marginal one. A per-label bias of
    4 px (the same offset of a detector label in every frame): the marginals are many
    times too small for the error, the headline several times wider (how well it is
    calibrated over many scenes: bench/RESULTS_uncertainty.md)."""
    _, iid, _ = _calibrate_scene()
    assert iid["marginal_rotation_std_deg"] <= iid["rotation_std_deg"] \
        <= 1.5 * iid["marginal_rotation_std_deg"]
    assert set(iid["robust"]) >= {"time_rotation_std_deg", "jack_joint_rotation_std_deg",
                                  "chosen", "ratio_to_marginal"}
    run, biased, err = _calibrate_scene(joint_bias_px=4.0, joint_bias_shared=True)
    assert err > 5 * biased["marginal_rotation_std_deg"]
    assert biased["rotation_std_deg"] > 3 * biased["marginal_rotation_std_deg"]
    assert biased["robust"]["ratio_to_marginal"] > 3.0
    np.testing.assert_allclose(np.asarray(biased["normal_cov"]) @ run.calibration.normal, 0.0,
                               atol=1e-12)


def test_the_sensitivity_report_says_what_the_calibration_rests_on():
    run, u, _ = _calibrate_scene()
    sens = run.calibration.sensitivity
    pairs = sens["leave_out"]["joint_pairs"]
    assert len(pairs) == 6 and all(len(p["joints"]) == 2 for p in pairs)
    assert all(p["rotation_change_deg"] >= 0 for p in pairs)
    segs = sens["leave_out"]["segments"]
    assert len(segs) == 10 and segs[0]["frames"][0] == 0
    assert sum(s["information_share"] for s in segs) == pytest.approx(1.0, rel=1e-6)
    # each segment alone: about sqrt(10) times the whole video's (iid) std
    alone = np.median([s["rotation_std_deg_alone"] for s in segs])
    assert alone / u["marginal_rotation_std_deg"] == pytest.approx(np.sqrt(10), rel=0.35)
    fn = sens["frames_needed"]
    assert np.all(np.diff(fn["rotation_std_deg"]) < 0)
    i = fn["frames"].index(1000)
    assert fn["iid_rotation_std_deg"][i] == pytest.approx(
        u["marginal_rotation_std_deg"] * np.sqrt(800 / 1000), rel=1e-6)


def test_the_covariance_is_computed_when_the_last_solves_were_all_damped():
    """A scene whose last stage met a nearly singular point, so that every one of its
    solves was damped (no undamped information to read the covariance from): the
    information is taken at the solution (bench_uncertainty's outliers/20 had none)."""
    from mirrorgraph.synth import make_wide_scene
    sc = make_wide_scene(20, "gym", "iid", 1000, outlier_rate=0.10, epipolar_outlier_rate=0.05)
    run = calibrate(sc.detections, sc.intrinsics, CalibrateOptions())
    u = run.calibration.uncertainty
    assert np.isfinite(u["rotation_std_deg"]) and np.isfinite(u["marginal_rotation_std_deg"])
    assert 0 < u["marginal_rotation_std_deg"] <= u["rotation_std_deg"] < 1.0


def test_the_region_of_a_few_clusters_covers_what_it_says():
    """A covariance estimated from G clusters: Hotelling's quantile covers 90 % of the
    errors of their mean; the Gaussian's chi-square, which ignores the covariance's own
    noise, covers markedly less at G = 6 (the joint pairs of COCO's body)."""
    from mirrorgraph.graph.uncertainty import region_threshold

    rng = np.random.default_rng(3)
    A = np.array([[2.0, 0.3], [0.3, 0.5]])
    for G in (6, 20):
        x = rng.multivariate_normal([0.0, 0.0], A, size=(20000, G))
        m = x.mean(1)
        d = x - m[:, None]
        S = np.einsum("rgi,rgj->rij", d, d) / (G - 1) / G      # the covariance of the mean
        m2 = np.einsum("ri,rij,rj->r", m, np.linalg.inv(S), m)
        hot = np.mean(m2 <= region_threshold(2, G))
        assert hot == pytest.approx(0.90, abs=0.01)
        gauss = np.mean(m2 <= region_threshold(2, None))
        if G == 6:
            assert gauss < 0.80
    assert region_threshold(2, None) == pytest.approx(4.605, abs=1e-3)
    assert region_threshold(2, 10_000) == pytest.approx(4.605, rel=2e-3)


def test_the_calibration_reports_its_90_percent_region():
    from mirrorgraph.graph.uncertainty import region_rotation_deg

    run, unc, _ = _calibrate_scene(joint_bias_px=4.0, joint_bias_shared=True)
    robust = unc["robust"]
    assert robust["clusters"] >= 3
    assert unc["rotation_90_deg"] == pytest.approx(
        region_rotation_deg(np.asarray(unc["normal_cov"]), robust["clusters"]), rel=1e-9)
    # wider than the Gaussian region of the same covariance, which is wider than one std
    assert unc["rotation_90_deg"] > region_rotation_deg(np.asarray(unc["normal_cov"])) \
        > unc["rotation_std_deg"]
    assert "90 % region" in run.calibration.summary()


def test_a_mirror_made_uncertain_by_a_detectors_bias_is_warned_as_such():
    """A per-label bias of 4 px: the joint pairs disagree about the mirror, and the warning
    says so (more frames would not help), not that the geometry is poor."""
    from mirrorgraph.synth import make_wide_scene

    sc = make_wide_scene(1, "gym", "iid", 600, joint_bias_px=4.0, joint_bias_shared=True)
    calib = calibrate(sc.detections, sc.intrinsics, CalibrateOptions()).calibration
    assert calib.uncertainty["rotation_std_deg"] > 0.5
    warned = [w for w in calib.warnings if "poorly determined" in w]
    assert warned and "joint pairs disagree" in warned[0]


def test_a_rig_reports_what_each_camera_and_mirror_rests_on(tmp_path):
    """Per estimated camera and mirror, as for one mirror: the information shares of the
    segments add up to one, a tenth of the video alone gives about sqrt(10) times the
    (iid) std of the whole, and the predicted std falls with more frames."""
    from mirrorgraph.pipelines.rig import calibrate_rig
    from mirrorgraph.synth.rig import make_rig, write_rig

    rig = make_rig("2cams1mirror", frames=200, seed=1, noise_std=3.0)
    cal = calibrate_rig(write_rig(rig, tmp_path))
    sens = cal.sensitivity
    names = {c.name for c in cal.cameras[1:]} | {m.name for m in cal.mirrors}
    assert set(sens) == names
    for c in cal.cameras[1:] + cal.mirrors:
        s = sens[c.name]
        segs = s["leave_out"]["segments"]
        assert len(segs) == 10
        assert sum(x["information_share"] for x in segs) == pytest.approx(1.0, rel=1e-6)
        alone = np.median([x["rotation_std_deg_alone"] for x in segs])
        assert alone / c.marginal_rotation_std_deg == pytest.approx(np.sqrt(10), rel=0.35)
        assert all(p["rotation_change_deg"] >= 0 for p in s["leave_out"]["joint_pairs"])
        assert np.all(np.diff(s["frames_needed"]["rotation_std_deg"]) < 0)
    assert cal.to_dict()["sensitivity"] == sens


def test_the_regions_closed_forms_are_scipys_quantiles():
    """dim = 2 in closed form, any other dim through scipy.special: Hotelling's T^2 and
    chi^2 against SciPy's quantiles for every cluster count and a few levels."""
    from scipy.special import chdtri, fdtri

    from mirrorgraph.graph.uncertainty import region_threshold
    for level in (0.5, 0.9, 0.95, 0.99):
        for dim in (1, 2, 3, 6):
            assert region_threshold(dim, None, level) == pytest.approx(
                chdtri(dim, 1 - level), rel=1e-13)
            G = np.arange(dim + 1, 3000)
            ours = np.array([region_threshold(dim, int(g), level) for g in G])
            theirs = dim * (G - 1) / (G - dim) * fdtri(dim, G - dim, level)
            np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=0)
