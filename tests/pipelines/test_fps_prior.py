"""The acceleration priors stated at 30 fps and taken at the video's frame interval
(``PriorOptions.at_frame_rate``): the same motion gets the same prior in h/s^2 at any
frame rate, a 30 fps video (or one without a rate) the options as given."""

from dataclasses import replace

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.graph.options import REFERENCE_FPS, PriorOptions, RefineOptions
from mirrorgraph.metrics import pa_mpjpe
from mirrorgraph.synth import make_wide_scene


def _intr(sc):
    return mg.Intrinsics(K=sc.K, image_size=sc.image_size)


def _run(data, sc, **kw):
    return mg.calibrate(data, _intr(sc), mg.CalibrateOptions(subject_height=sc.subject_height,
                                                            **kw))


def _joints_pass_prior(run) -> float:
    """The joints pass's acceleration sigma as its graph held it, fraction of the height
    per frame^2 of the video (the bones' record gives the graph's height)."""
    p = run.calibration.refinement["priors"]["joints_pass"]
    h = p["bone_length"]["sigma"] / RefineOptions().bone_sigma
    return p["smoothness"]["sigma"] / h


def test_at_frame_rate_scales_both_sigmas_by_the_frame_interval_squared():
    o = RefineOptions(smoothness_sigma=0.8, joints_smoothness_sigma=0.01, bone_sigma=0.02)
    at60 = o.at_frame_rate(60.0)
    assert at60.joints_smoothness_sigma == pytest.approx(0.0025, rel=1e-15)
    assert at60.smoothness_sigma == pytest.approx(0.2, rel=1e-15)
    assert type(at60) is RefineOptions and at60.bone_sigma == 0.02
    assert at60.smoothness_max_gap == o.smoothness_max_gap          # frames of the video
    for fps in (24.0, 25.0, 29.97, 50.0, 120.0):                    # the same h / s^2
        a = o.at_frame_rate(fps)
        assert a.joints_smoothness_sigma * fps ** 2 == pytest.approx(0.01 * REFERENCE_FPS ** 2)
        assert a.smoothness_sigma * fps ** 2 == pytest.approx(0.8 * REFERENCE_FPS ** 2)
    assert o.at_frame_rate(REFERENCE_FPS) is o and o.at_frame_rate(30) is o
    assert RefineOptions(joints_smoothness_sigma=None).at_frame_rate(60.0) \
        .joints_smoothness_sigma is None
    assert PriorOptions().at_frame_rate(15.0).joints_smoothness_sigma == pytest.approx(0.04)
    for bad in (0, -30.0, float("nan"), float("inf"), None, "30", True):
        with pytest.raises(mg.InputError, match="field 'fps'"):
            o.at_frame_rate(bad)


def test_the_same_motion_at_30_and_60_fps_gets_the_same_prior_in_h_per_s2():
    # each video's rate from its input: the joints pass holds 0.01 h per frame^2 at
    # 30 fps, 0.0025 at 60, 9 h/s^2 both (per frame number it was 36 h/s^2 at 60 fps)
    per_s2 = {}
    for fps in (30.0, 60.0):
        sc = make_wide_scene(1, noise="iid", frames=200, fps=fps)
        run = _run(sc.detections, sc)
        assert (run.fps, run.fps_source) == (fps, "input")
        per_s2[fps] = _joints_pass_prior(run) * fps ** 2
    assert per_s2[30.0] == pytest.approx(0.01 * 900, rel=1e-9)
    assert per_s2[60.0] == pytest.approx(per_s2[30.0], rel=1e-9)


def test_a_60_fps_video_told_its_rate_is_nearer_the_truth():
    # the prior per frame number (the run told 30 fps) is 4x looser in h/s^2 than the
    # motion wants: PA-MPJPE 18.1 -> 12.8 mm here (seeds 0-3: 0.70-0.77 of it)
    sc = make_wide_scene(1, noise="iid", frames=300, fps=60.0)
    pa = {}
    for told in (30.0, 60.0):
        run = _run(sc.detections, sc, fps=told)
        pa[told] = pa_mpjpe(run.joints3d, sc.joints3d, run.valid3d)
    assert pa[60.0] < 0.85 * pa[30.0], pa


def test_a_gap_is_counted_in_frames_of_the_video():
    # every other frame of a 60 fps video (frame ids 0, 2, 4, ...: each step two frame
    # intervals) is the 30 fps video of the same motion (ids 0, 1, 2, ...): the joints
    # pass holds the same acceleration (0.01 h over a step of 2 / 60 s) and its joints
    # agree (per frame number, the 60 fps one was 4x looser: PA-MPJPE 36.6 against
    # 26.7 mm); the completed joints, which a small change of the mirror moves where
    # their rays meet at a small angle, are left out
    sc = make_wide_scene(1, noise="iid", frames=400, fps=60.0)
    d = sc.detections
    keep = np.arange(0, len(d.frame_ids), 2)
    people = [d.people[i] for i in keep]
    at60 = _run(replace(d, frame_ids=np.asarray(d.frame_ids)[keep], people=people), sc)
    at30 = _run(replace(d, frame_ids=np.arange(len(keep)), people=people, fps=30.0), sc)
    assert (at60.fps, at30.fps) == (60.0, 30.0)
    assert _joints_pass_prior(at60) == pytest.approx(_joints_pass_prior(at30) / 4, rel=1e-6)
    pa = [pa_mpjpe(r.joints3d, sc.joints3d[keep], r.valid3d & ~r.completed)
          for r in (at60, at30)]
    assert abs(pa[0] / pa[1] - 1) < 0.01, pa


def test_at_30_fps_or_without_a_rate_the_graph_holds_the_options_as_given():
    sc = make_wide_scene(2, noise="iid", frames=200)                # 30 fps
    told = _run(sc.detections, sc)
    unknown = _run(replace(sc.detections, fps=None), sc)            # the default 30
    assert told.fps_source == "input" and unknown.fps_source == "default"
    for run in (told, unknown):
        assert _joints_pass_prior(run) == pytest.approx(0.01, rel=1e-12)
    np.testing.assert_array_equal(told.joints3d, unknown.joints3d)
    np.testing.assert_array_equal(told.joints_std, unknown.joints_std)
