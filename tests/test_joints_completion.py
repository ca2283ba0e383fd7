"""Single mirror: every keypoint seen in both views gets a 3D point, and ``joints`` speaks
the rig's words."""

from __future__ import annotations

import json

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.completion import anchor_gate, complete_mirror_joints
from mirrorgraph.joint_sets import mirror_joints, resolve_joints
from mirrorgraph.skeletons import skeleton_by_name
from mirrorgraph.synth import make_scene


@pytest.fixture(scope="module")
def body25():
    """BODY_25 (face and feet outside the calibration joints), 7 % outliers, 5 % swaps."""
    s = make_scene(frames=300, seed=1, skeleton="BODY_25", outlier_rate=0.07, lr_swap_rate=0.05)
    run = mg.calibrate(s.detections, s.intrinsics,
                       mg.CalibrateOptions(subject_height=s.subject_height))
    return s, run


def _left_out(run):
    return np.setdiff1d(np.arange(run.paired.skeleton.num_joints), run.joints)


def test_face_and_feet_are_triangulated_in_metres(body25):
    s, run = body25
    other = _left_out(run)
    names = {run.paired.skeleton.joints[j] for j in other}
    assert {"nose", "left_eye", "right_big_toe", "left_heel"} <= names
    seen = ((s.real_observed[..., 2] >= 0.3) & (s.mirror_observed[..., 2] >= 0.3))[:, other]
    got = run.valid3d[:, other]
    # nearly every keypoint seen in both views has a point (gross detector outliers,
    # 7 % a view, are what the gates drop)
    assert got.sum() > 0.8 * seen.sum()
    assert np.array_equal(run.completed[:, other], got)
    assert not run.completed[:, run.joints].any()          # the graph's joints are its own
    err = np.linalg.norm(run.joints3d - s.joints3d, axis=-1)[:, other][got]
    assert np.median(err) < 0.03                            # metres
    assert np.quantile(err, 0.95) < 0.08
    # as accurate as the graph's own joints, give or take a centimetre
    graph = run.valid3d & ~run.completed
    graph_err = np.linalg.norm(run.joints3d - s.joints3d, axis=-1)[graph]
    assert np.median(err) < np.median(graph_err) + 0.01


def test_the_count_is_in_the_run_and_the_json(body25, tmp_path):
    _, run = body25
    rec = run.calibration.refinement["completion"]
    assert rec["joints_completed"] == run.joints_completed > 1000
    assert rec["candidates"] >= (rec["joints_completed"] + rec["rejected_reprojection"]
                                 + rec["rejected_body"])
    out = tmp_path / "calibration.json"
    mg.write_calibration(out, run.calibration)
    assert json.loads(out.read_text())["refinement"]["completion"]["joints_completed"] \
        == run.joints_completed


def test_without_a_height_the_points_are_in_mirror_distances():
    s = make_scene(frames=200, seed=3, skeleton="BODY_25", outlier_rate=0.05)
    run = mg.calibrate(s.detections, s.intrinsics, mg.CalibrateOptions())
    assert run.calibration.scale == "unknown" and run.joints_completed > 0
    truth = s.joints3d / s.distance                           # unit: the mirror distance
    err = np.linalg.norm(run.joints3d - truth, axis=-1)
    graph = run.valid3d & ~run.completed
    assert np.median(err[run.completed]) < np.median(err[graph]) + 0.005
    # up to the unit-distance solution's own scale error (about 1 %): within 1.5 % of d
    X, m = run.joints3d, run.valid3d
    scale = np.sum(X[m] * truth[m]) / np.sum(X[m] ** 2)
    assert np.median(np.linalg.norm(scale * X - truth, axis=-1)[run.completed]) < 0.015


def test_completion_can_be_turned_off(body25):
    s, _ = body25
    run = mg.calibrate(s.detections, s.intrinsics,
                       mg.CalibrateOptions(subject_height=s.subject_height,
                                           complete_joints=False))
    assert not run.valid3d[:, _left_out(run)].any()
    assert run.joints_completed == 0 and "completion" not in run.calibration.refinement


@pytest.mark.parametrize("spec", ["all", ("all",), "ALL"])
def test_all_puts_every_keypoint_into_the_graph(body25, spec):
    s, _ = body25
    run = mg.calibrate(s.detections, s.intrinsics,
                       mg.CalibrateOptions(subject_height=s.subject_height, joints=spec,
                                           refine=spec == "all"))
    assert np.array_equal(run.joints, np.arange(25))
    if spec == "all":
        assert run.joints_completed == 0
        err = np.linalg.norm(run.joints3d - s.joints3d, axis=-1)[run.valid3d]
        assert np.median(err) < 0.03


def test_an_outlier_along_the_epipolar_line_is_dropped():
    """An error along the epipolar line costs no reprojection: the body gate catches it."""
    s = make_scene(frames=120, seed=5, skeleton="BODY_25")
    p = s.paired()
    sk = s.skeleton
    nose = sk.index("nose")
    K, n, d = s.K, s.normal, s.distance
    known = np.zeros(p.real.shape[:2], bool)
    known[:, sk.calibration_joints] = True
    X = np.where(known[..., None], s.joints3d, np.nan)
    # frame 40: the reflection's nose moved 60 px along its epipolar line
    e = mg.geometry.epipole_pixels(mg.geometry.epipole_from_normal(K, n))
    u = p.mirror[40, nose, :2]
    p.mirror[40, nose, :2] = u + 60.0 * (e - u) / np.linalg.norm(e - u)
    out = complete_mirror_joints(p, K, n, d, X, known, joints=sk.calibration_joints,
                                 min_confidence=0.3, threshold_px=10.0)
    assert not out.completed[40, nose] and out.rejected_body >= 1
    assert out.completed[:, nose].sum() > 100
    good = out.completed[:, nose]
    assert np.median(np.linalg.norm(out.joints3d[good, nose] - s.joints3d[good, nose], axis=-1)) \
        < 0.03


def test_anchor_gate_keeps_consistent_points():
    rng = np.random.default_rng(0)
    T = 200
    base = rng.normal(size=(T, 1, 3))
    pts = np.concatenate([base, base + [0.3, 0, 0], base + [0, 0.2, 0]], axis=1)
    pts += rng.normal(scale=0.005, size=pts.shape)
    known = np.zeros((T, 3), bool)
    known[:, :2] = True
    new = ~known
    pts[7, 2] += [0, 0.5, 0]
    keep = anchor_gate(pts, known, new)
    assert not keep[7, 2] and keep[:, 2].sum() == T - 1


# ------------------------------------------------------------------------- joints words
@pytest.mark.parametrize("name", ["COCO_17", "BODY_25", "HALPE_26"])
def test_single_mirror_and_rig_resolve_the_same_words(name):
    from mirrorgraph.pipelines import rig as rig_pipeline

    assert rig_pipeline.resolve_joints is resolve_joints          # one parser for both
    sk = skeleton_by_name(name)
    every, limbs = np.arange(sk.num_joints), np.asarray(sk.calibration_joints)
    for spec, want in ((None, (every, limbs)), ("auto", (every, limbs)),
                       ("limbs", (limbs, limbs)), ("all", (every, every)), (["all"], (every, every))):
        got = resolve_joints(sk, spec)
        assert all(np.array_equal(a, b) for a, b in zip(got, want)), spec
    names = "left_wrist,right_wrist,left_hip,right_hip,nose"
    chosen = sorted(sk.index(n) for n in names.split(","))
    assert np.array_equal(resolve_joints(sk, names)[0], chosen)
    assert np.array_equal(mirror_joints(sk, "auto"), sk.calibration_joints)
    assert np.array_equal(mirror_joints(sk, ["all"]), np.arange(sk.num_joints))


def test_unknown_or_too_few_joints_are_refused_naming_the_words():
    sk = skeleton_by_name("COCO_17")
    with pytest.raises(mg.InputError, match=r"field 'joints'.*unknown joint\(s\) tail.*auto, limbs, all"):
        mirror_joints(sk, ("left_wrist", "tail"))
    with pytest.raises(mg.InputError, match="at least 4 joints"):
        mirror_joints(sk, "left_wrist,right_wrist")


def test_the_cli_takes_all(tmp_path):
    from mirrorgraph.cli import main
    from mirrorgraph.io import write_keypoints

    s = make_scene(frames=120, seed=2, skeleton="BODY_25")
    kp = tmp_path / "openpose"
    write_keypoints(s.detections, kp, "openpose")
    cam = tmp_path / "camera.json"
    cam.write_text(json.dumps({"K": s.K.tolist(), "image_size": list(s.image_size)}))
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(kp), "--intrinsics", str(cam), "--out", str(out),
                 "--joints", "all", "--no-refine", "--quiet", "--skeleton", "BODY_25"]) == 0
    assert len(json.loads(out.read_text())["input"]["joints"]) == 25


def test_smoothed_tracks_fix_a_low_parallax_depth_and_their_std_covers_it():
    # one joint moving smoothly 5 m away, measured with a depth std 40 times its lateral
    # one (two rays meeting at a small angle); the smoothing takes the depth's noise
    # down, and the reported std covers what is left
    from mirrorgraph.completion import smooth_tracks

    rng = np.random.default_rng(3)
    T = 600
    t = np.arange(T)
    truth = np.stack([0.3 * np.sin(t / 40.0), 0.1 * np.cos(t / 25.0), 5.0 + 0.2 * np.sin(t / 60.0)], -1)
    sd = np.array([0.005, 0.005, 0.2])
    meas = truth + rng.normal(size=(T, 3)) * sd
    info = np.broadcast_to(np.diag(1.0 / sd ** 2), (T, 3, 3)).copy()
    frames = np.delete(t, np.arange(100, 110))             # a gap the chain must not span
    keep = np.isin(t, frames)
    pts, cov = smooth_tracks(meas[keep][:, None], info[keep][:, None], np.ones((keep.sum(), 1), bool),
                             frames, sigma=0.002, max_gap=4)
    err = np.linalg.norm(pts[:, 0] - truth[keep], axis=-1)
    raw = np.linalg.norm(meas[keep] - truth[keep], axis=-1)
    assert np.median(err) < 0.4 * np.median(raw)
    assert (err > 0.3).mean() == 0 and (raw > 0.3).mean() > 0.05
    z = err / np.sqrt(np.trace(cov[:, 0], axis1=-2, axis2=-1))
    assert 0.4 < np.median(z) < 1.5 and np.quantile(z, 0.99) < 3.0


def test_completed_face_joints_are_smoothed_where_their_rays_meet_at_a_small_angle():
    # a far mirror behind the person (rays meeting at 8 deg): the face, outside the graph,
    # has a two-view depth std of ~0.17 m in each frame
    from mirrorgraph.synth import make_wide_scene
    from mirrorgraph.synth.mocap import cmu_example_path

    s = make_wide_scene(0, "wide", "iid", 400, motion=str(cmu_example_path()))
    assert s.placement["parallax_deg"] < 10
    run = mg.calibrate(s.detections, s.intrinsics,
                       mg.CalibrateOptions(subject_height=s.subject_height))
    truth = s.joints3d[np.searchsorted(s.frame_ids, run.paired.frame_ids)]
    err = np.linalg.norm(run.joints3d - truth, axis=-1)
    done = run.completed
    assert done.sum() > 1000
    assert (err[done] > 0.3).mean() < 0.01
    ratio = err[done] / run.joints_std[done]
    assert 0.4 < np.median(ratio) < 1.5


def _face_completion(seed: int, head: bool):
    """The face of a realistic-detector scene completed beside the true limbs and mirror:
    its error, its std, and the layout."""
    from mirrorgraph.synth import make_wide_scene

    s = make_wide_scene(seed, "wide", "realistic", 300)
    names = list(s.skeleton.joints)
    face = [names.index(n) for n in ("nose", "left_eye", "right_eye", "left_ear", "right_ear")]
    limbs = np.setdiff1d(np.arange(len(names)), face)
    known = np.zeros(s.joints3d.shape[:2], bool)
    known[:, limbs] = True
    X = np.where(known[..., None], s.joints3d, np.nan)
    done = complete_mirror_joints(
        s.paired(), s.K, s.normal, s.distance, X, known, joints=limbs, min_confidence=0.3,
        threshold_px=15.0, pixel_sigma=4.0, smoothness=(0.002 * s.subject_height, 4),
        head=(names, s.subject_height, None) if head else None)
    got = done.completed[:, face]
    err = np.linalg.norm(done.joints3d - s.joints3d, axis=-1)[:, face][got]
    std = np.sqrt(np.trace(done.cov, axis1=-2, axis2=-1))[:, face][got]
    return s, err, std


def test_the_head_prior_holds_a_low_parallax_face_to_the_trunk():
    # rays meeting at 10 deg and a per-label detector bias that differs between the views:
    # the face's triangulated depth runs tenths of a metre off; held to where the trunk
    # puts a head (Winter's landmark heights, the neck's range of motion) it does not
    s, free, _ = _face_completion(2, head=False)
    assert s.placement["parallax_deg"] < 12
    _, held, std = _face_completion(2, head=True)
    assert (free > 0.3).mean() > 0.01 and (held > 0.3).mean() == 0
    assert np.median(held) < 0.75 * np.median(free)
    # the bias the frames share is in the std: the error over it as a Gaussian's
    z = held / std
    assert 0.5 < np.median(z) < 1.6 and np.quantile(z, 0.99) < 6


def test_head_prior_places_the_face_above_the_shoulders():
    from mirrorgraph.anthropometry import LANDMARK_HEIGHT
    from mirrorgraph.completion import HEAD_PRIOR_SIGMA, head_prior

    names = ["nose", "left_shoulder", "right_shoulder", "left_hip", "right_hip", "left_eye"]
    P = np.zeros((2, 6, 3))
    P[:, 1], P[:, 2] = [0.2, -1.4, 4.0], [-0.2, -1.4, 4.0]       # y down: shoulders above
    P[:, 3], P[:, 4] = [0.1, -0.9, 4.0], [-0.1, -0.9, 4.0]       # the hips
    known = np.zeros((2, 6), bool)
    known[:, 1:5] = True
    known[1, 3] = False                                          # no hips: no prior
    mean, info = head_prior(P, known, names, 1.8)
    rise = (LANDMARK_HEIGHT["eye"] - LANDMARK_HEIGHT["shoulder"]) * 1.8
    assert np.allclose(mean[0, 5], [0.0, -1.4 - rise, 4.0])
    assert mean[0, 0, 1] > mean[0, 5, 1]                         # the nose below the eyes
    assert np.allclose(np.linalg.inv(info[0, 5]), (HEAD_PRIOR_SIGMA * 1.8) ** 2 * np.eye(3))
    assert np.isnan(mean[1]).all() and np.isnan(mean[0, 1:5]).all()
    assert 0.055 < HEAD_PRIOR_SIGMA < 0.07
    assert head_prior(P, known, ["a", "b", "c", "d", "e", "f"], 1.8) is None
