"""Following people over time in one camera (:mod:`mirrorgraph.rigs.tracking`): no track
across frames far apart."""

from __future__ import annotations

import numpy as np

from mirrorgraph.rigs.tracking import TRACK_MAX_GAP, jumping, segments, track_labelled


def test_segments_cut_where_the_frames_jump():
    ids = np.array([0, 1, 2, 2 + TRACK_MAX_GAP, 3 + 2 * TRACK_MAX_GAP + 1, 4000])
    assert segments(ids).tolist() == [0, 0, 0, 0, 1, 2]
    assert segments(None, 3).tolist() == [0, 0, 0]


def test_no_track_crosses_a_jump_of_the_frames():
    """Two people standing still in four frames: consecutive frames share their tracks;
    the same frames as snapshots far apart share none."""
    J = 25
    a = np.zeros((J, 3))
    a[:, 0], a[:, 1], a[:, 2] = np.arange(J) * 3.0, 100.0, 0.9
    b = a.copy()
    b[:, 0] += 400.0
    frames = [np.stack([a, b])] * 4
    joints = np.arange(J)
    ids, _ = track_labelled(frames, joints, 0.3)
    assert len(set(np.concatenate(ids).tolist())) == 2
    ids, _ = track_labelled(frames, joints, 0.3, frame_ids=np.arange(4) * 2250)
    assert len(set(np.concatenate(ids).tolist())) == 8


def test_people_placed_anew_every_frame_jump_and_a_video_does_not():
    """Snapshots numbered frame after frame are told from a video by the people's moves."""
    from mirrorgraph.synth.rig_people import make_rig_people

    for snapshots in (True, False):
        rig = make_rig_people(3, 3, frames=30, seed=3, snapshots=snapshots, noise_std=4.0,
                              outlier_rate=0.02)
        joints = rig.skeleton.calibration_joints
        for name in rig.camera_names:
            people = rig.detections[name].people
            assert jumping(people, joints, 0.3) == snapshots
            cut = segments(np.arange(30), 30, people, joints)
            assert cut.tolist() == (list(range(30)) if snapshots else [0] * 30)
