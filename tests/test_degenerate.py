"""Degenerate geometry is refused with a reason, or answered with a warning, never garbage."""

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.keypoints import PairedKeypoints, RawDetections
from mirrorgraph.synth import make_scene


def test_too_few_pairs_are_refused():
    s = make_scene(frames=40, seed=1)
    p = s.paired()
    real, mirror = p.real.copy(), p.mirror.copy()
    real[1:, :, 2] = 0.0                         # one frame left: 12 pairs at most
    real[1:, :, :2] = np.nan
    tiny = PairedKeypoints(skeleton=p.skeleton, frame_ids=p.frame_ids, real=real[:1],
                           mirror=mirror[:1], source="tiny.npz")
    with pytest.raises(mg.DegenerateGeometryError, match="tiny.npz"):
        mg.calibrate(tiny, s.intrinsics, mg.CalibrateOptions(refine=False, joints=(
            "left_shoulder", "right_shoulder", "left_hip", "right_hip")))


def test_a_second_person_instead_of_the_reflection_is_flagged():
    a, b = make_scene(frames=300, seed=1), make_scene(frames=300, seed=2)
    people = [np.stack([ra, rb]) for ra, rb in zip(a.paired().real, b.paired().real)]
    raw = RawDetections(skeleton=a.skeleton, frame_ids=a.detections.frame_ids, people=people,
                        source="two_people.json")
    try:
        calib = mg.calibrate(raw, a.intrinsics, mg.CalibrateOptions(refine=False)).calibration
    except mg.MirrorgraphError as exc:           # refusing is an acceptable answer too
        assert "two_people.json" in str(exc)
        return
    assert any("second person" in w for w in calib.warnings), calib.warnings
    # and the genuine scene is not flagged
    good = mg.calibrate(a.detections, a.intrinsics, mg.CalibrateOptions(refine=False)).calibration
    assert not any("second person" in w for w in good.warnings)


def test_a_person_who_never_moves_is_flagged():
    s = make_scene(frames=200, seed=3)
    still = RawDetections(skeleton=s.skeleton, frame_ids=s.detections.frame_ids,
                          people=[s.detections.people[0]] * 200, source="still.json")
    calib = mg.calibrate(still, s.intrinsics, mg.CalibrateOptions(refine=False)).calibration
    assert any("hardly moves" in w for w in calib.warnings)
    moving = mg.calibrate(s.detections, s.intrinsics, mg.CalibrateOptions(refine=False)).calibration
    assert not any("hardly moves" in w for w in moving.warnings)


def test_an_ill_determined_mirror_is_reported_through_the_uncertainty():
    s = make_scene(frames=20, seed=4, noise_std=12.0)
    calib = mg.calibrate(s.detections, s.intrinsics, mg.CalibrateOptions()).calibration
    assert calib.uncertainty["rotation_std_deg"] > 0.5
    assert any("poorly determined" in w for w in calib.warnings)
    long = make_scene(frames=600, seed=4)
    good = mg.calibrate(long.detections, long.intrinsics, mg.CalibrateOptions()).calibration
    assert not any("poorly determined" in w for w in good.warnings)


def test_all_pairs_on_one_line_are_refused():
    kp = np.array([[100.0 + 30 * j, 500.0, 1.0] for j in range(17)])
    people = [np.stack([kp, kp + [400.0, 0.0, 0.0]])] * 20
    raw = RawDetections(skeleton=mg.skeletons.COCO_17, frame_ids=np.arange(20), people=people,
                        source="flat.json")
    from mirrorgraph.intrinsics import intrinsics_from_fov
    with pytest.raises(mg.DegenerateGeometryError, match="flat.json"):
        mg.calibrate(raw, intrinsics_from_fov((1920, 1080)), mg.CalibrateOptions(refine=False))
