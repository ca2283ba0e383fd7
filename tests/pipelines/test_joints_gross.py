"""The 3D joints users take home, against the truth: no joint far off where the detector
swaps the person's left and right in both views (the body's labels, not its geometry)."""

import numpy as np

import mirrorgraph as mg
from mirrorgraph.synth import make_scene


def test_swapped_frames_leave_no_joint_far_off():
    scene = make_scene(frames=400, seed=31, lr_swap_rate=0.05, lr_swap_views="both",
                       outlier_rate=0.03)
    K = mg.Intrinsics(K=scene.K, dist=scene.dist, image_size=scene.image_size)
    run = mg.calibrate(scene.detections, K,
                       mg.CalibrateOptions(subject_height=scene.subject_height, fps=scene.fps))
    truth = scene.joints3d[np.searchsorted(scene.frame_ids, run.paired.frame_ids)]
    err = np.linalg.norm(run.joints3d - truth, axis=-1)[run.valid3d]
    assert run.calibration.input["body_lr_fixes"] > 0
    assert run.valid3d.mean() > 0.9
    assert (err > 0.3).mean() < 0.005
    assert err.max() < 1.0
