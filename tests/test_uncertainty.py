"""The reported uncertainty follows the noise actually in the data (a posteriori sigma)."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.graph.result import residual_noise_px
from mirrorgraph.intrinsics import Intrinsics
from mirrorgraph.pipeline import CalibrateOptions, calibrate
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
    from mirrorgraph.rigs import calibrate_rig
    from mirrorgraph.synth.rig import make_rig, write_rig

    rig = make_rig("4cams", frames=100, seed=2, noise_std=2.0)
    cal = calibrate_rig(write_rig(rig, tmp_path))
    rep = cal.refinement["priors"]["reprojection"]
    assert rep["a_posteriori_sigma_px"] == pytest.approx(2.0, rel=0.1)
    assert rep["covariance_scaled_by"] == pytest.approx(0.25, rel=0.25)
