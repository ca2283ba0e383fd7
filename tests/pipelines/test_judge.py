"""The run's judgement of its own geometry (``mirrorgraph.pipelines.judge``)."""

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.pipelines.judge import LOW_PARALLAX_DEG, median_ray_angle_deg, ray_angles_deg
from mirrorgraph.synth import make_wide_scene


def test_ray_angles_fold_rays_pointing_opposite_ways():
    """A joint on the line from the camera to the mirror, between them, has rays pointing
    opposite ways (180 deg apart as directions): as ill-conditioned as parallel ones."""
    n, d = np.array([0.0, 0.0, 1.0]), 5.0
    on_axis = np.array([[0.0, 0.0, 3.0]])
    assert ray_angles_deg(on_axis, n, d)[0] == pytest.approx(0.0, abs=1e-6)
    # rays at 30 and at 150 deg as directions: the same conditioning, 30 deg
    for angle in (30.0, 150.0):
        # a point X with the angle between X and X - 2 d n equal to `angle`: place it on a
        # circle through both centres (the inscribed angle theorem) and check it numerically
        x = np.linspace(0.1, 20.0, 20000)
        pts = np.stack([x, np.zeros_like(x), np.full_like(x, 2.0)], 1)
        a = pts / np.linalg.norm(pts, axis=1, keepdims=True)
        b = pts - 2 * d * n
        b /= np.linalg.norm(b, axis=1, keepdims=True)
        raw = np.degrees(np.arccos(np.clip(np.sum(a * b, 1), -1, 1)))
        k = int(np.argmin(np.abs(raw - angle)))
        assert raw[k] == pytest.approx(angle, abs=0.1)
        assert ray_angles_deg(pts[k], n, d) == pytest.approx(min(angle, 180.0 - angle), abs=0.1)


@pytest.mark.parametrize("geometry, low", [("low_parallax", True), ("favourable", False)])
def test_low_parallax_is_warned_with_the_scale_std(geometry, low):
    """A person near the line from the camera to the mirror gets a warning naming the
    rays' angle and the metric scale's std; a favourable scene none."""
    sc = make_wide_scene(0, geometry, "iid", 300)
    true = median_ray_angle_deg(sc.joints3d, np.isfinite(sc.joints3d).all(-1), sc.normal,
                                sc.distance)
    assert (true < LOW_PARALLAX_DEG) == low, true
    run = mg.calibrate(sc.detections, sc.intrinsics,
                       mg.CalibrateOptions(subject_height=float(sc.subject_height)))
    found = [w for w in run.calibration.warnings if w.startswith("low parallax")]
    if low:
        assert len(found) == 1, run.calibration.warnings
        assert f"std {100 * run.scale_rel_std:.0f}%" in found[0]
    else:
        assert not found, found
