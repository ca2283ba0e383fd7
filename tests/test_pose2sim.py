"""The Pose2Sim export and the rig calibration open in Pose2Sim itself and triangulate to mirrorgraph's joints.

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


def test_pose2sim_triangulates_with_a_calibrated_rig(tmp_path):
    """calibrate-rig's calibration.toml in Pose2Sim: its projection matrices of every real
    camera and every virtual one (flipped image) triangulate the rig's true joints."""
    from mirrorgraph.synth.rig import make_rig, write_rig

    rig = make_rig("1cam2mirrors", frames=150, seed=2, noise_std=1.0)
    path = write_rig(rig, tmp_path / "rig")
    toml = tmp_path / "calibration.toml"
    assert main(["calibrate-rig", str(path), "--out", str(toml), "--with-virtual",
                 "--quiet"]) == 0
    P = p2s.computeP(toml)
    assert len(P) == 3                           # cam01, cam01_mirror_left, cam01_mirror_right
    sk = rig.skeleton
    W = rig.image_size[0]
    joints = sk.calibration_joints
    views = {v: [] for v in ("real", "mirror_left", "mirror_right")}
    for t in range(0, 150, 15):
        people = rig.detections["cam01"].people[t]
        which = rig.detection_views["cam01"][t]
        for view_name, person in zip(which, people):
            key = "real" if view_name == "person" else view_name
            if key in views:
                views[key].append((t, person))
    frames = sorted(set(t for t, _ in views["real"]) & set(t for t, _ in views["mirror_left"])
                    & set(t for t, _ in views["mirror_right"]))
    assert len(frames) >= 5
    by = {k: dict(v) for k, v in views.items()}
    from mirrorgraph.geometry import camera_projection, mirror_projection, triangulate
    doc = __import__("json").loads(toml.with_suffix(".json").read_text())
    K = np.asarray(doc["cameras"][0]["intrinsics"]["K"])
    pose = np.asarray(doc["cameras"][0]["pose_camera_to_world"])
    mirrors = {m["name"]: (np.asarray(m["normal"]), m["distance"]) for m in doc["mirrors"]}
    ours_P = [camera_projection(K, pose), mirror_projection(K, pose, *mirrors["mirror_left"]),
              mirror_projection(K, pose, *mirrors["mirror_right"])]
    theirs, ours, truth = [], [], []
    for t in frames:
        real = by["real"][t]
        left = flip_mirror_keypoints(by["mirror_left"][t], W, sk)
        right = flip_mirror_keypoints(by["mirror_right"][t], W, sk)
        for j in joints:
            obs = [real[j], left[j], right[j]]
            if not all(o[2] > 0 for o in obs):
                continue
            theirs.append(p2s.weighted_triangulation(P, [o[0] for o in obs], [o[1] for o in obs],
                                                     [1.0, 1.0, 1.0])[:3])
            raw = [by["real"][t][j, :2], by["mirror_left"][t][sk.flip][j, :2],
                   by["mirror_right"][t][sk.flip][j, :2]]
            X, ok = triangulate(ours_P, [r[None] for r in raw], [np.ones(1, bool)] * 3)
            ours.append(X[0])
            truth.append(rig.joints3d[t, j])
    theirs, ours, truth = (np.asarray(a, float) for a in (theirs, ours, truth))
    assert len(theirs) > 50
    # Pose2Sim's matrices are our views, the virtual ones of the flipped image (u -> W - u)
    Xh = np.column_stack([truth, np.ones(len(truth))])
    for i, (Pt, Po) in enumerate(zip(P, ours_P)):
        a, b = Xh @ np.asarray(Pt).T, Xh @ Po.T
        ua, ub = a[:, :2] / a[:, 2:], b[:, :2] / b[:, 2:]
        if i:
            ub[:, 0] = W - ub[:, 0]
        assert np.abs(ua - ub).max() < 1e-6
    # and both triangulate alike (two DLTs weigh the noisy rows differently: mm)
    assert np.median(np.linalg.norm(theirs - ours, axis=1)) < 0.003
    # and the truth, up to the metric scale (the subject's proportions vs Winter's)
    s = float(np.sum(theirs * truth) / np.sum(theirs * theirs))
    assert abs(s - 1) < 0.05
    assert np.median(np.linalg.norm(s * theirs - truth, axis=1)) < 0.02
