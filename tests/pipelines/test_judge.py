"""The run's judgement of its own geometry (``mirrorgraph.pipelines.judge``)."""

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.pipelines.judge import LOW_PARALLAX_DEG, median_ray_angle_deg
from mirrorgraph.synth import make_wide_scene


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
