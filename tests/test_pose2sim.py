"""The Pose2Sim export opens in Pose2Sim itself and triangulates to mirrorgraph's joints.

Pose2Sim is installed without its (heavy, GPU-oriented) dependencies by the test command;
only ``Pose2Sim.common`` is used: ``computeP`` (its projection matrices from our
``Calib.toml``) and ``weighted_triangulation`` (its DLT).
"""

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph import geometry as geo
from mirrorgraph.cli import main
from mirrorgraph.export import flip_mirror_keypoints
from mirrorgraph.synth import make_scene

p2s = pytest.importorskip("Pose2Sim.common", reason="Pose2Sim is not installed (the README's "
                          "test command installs it with --no-deps)")


def test_pose2sim_triangulates_our_joints(tmp_path):
    scene = make_scene(frames=120, seed=5, noise_std=0.0, noise_mean=0.0)
    run = mg.calibrate(scene.detections, scene.intrinsics,
                       mg.CalibrateOptions(subject_height=scene.subject_height))
    cal = tmp_path / "calibration.json"
    mg.write_calibration(cal, run.calibration)
    toml = tmp_path / "Calib.toml"
    assert main(["export", str(cal), "--to", "pose2sim", str(toml), "--quiet"]) == 0

    P = p2s.computeP(toml)          # a Path: rtoml reads a str as TOML text
    assert len(P) == 2
    paired = scene.paired()
    sk = paired.skeleton
    W = scene.image_size[0]
    # the user's recipe, on the detector's own labels of the reflection
    raw_mirror = paired.mirror[:, sk.flip]
    mirror_for_p2s = flip_mirror_keypoints(raw_mirror, W, sk)
    c = run.calibration
    frames = np.arange(0, 120, 10)
    joints = sk.calibration_joints
    ours = geo.triangulate_mirror(scene.K, c.normal, c.distance,
                                  paired.real[np.ix_(frames, joints)][..., :2],
                                  paired.mirror[np.ix_(frames, joints)][..., :2])
    theirs = np.array([[p2s.weighted_triangulation(
        P, [paired.real[t, j, 0], mirror_for_p2s[t, j, 0]],
        [paired.real[t, j, 1], mirror_for_p2s[t, j, 1]], [1.0, 1.0])[:3]
        for j in joints] for t in frames])
    assert np.abs(theirs - ours).max() < 1e-4            # metres
    # and both are the scene's joints up to the scale error of the height prior
    scale = scene.distance / c.distance
    assert np.median(np.linalg.norm(theirs * scale - scene.joints3d[np.ix_(frames, joints)], axis=-1)) < 0.01
