"""Rigs with bystanders: the subject is followed in every camera and mirror, against the truth.

In front of a mirror everyone has a reflection: a bystander's (person, reflection)
pair fits the mirror as well as the subject's, so a choice frame by frame switches
identity. The rigs here have a bystander near the subject (``make_rig(...,
bystanders=1)``: their own body, motion and height, seen directly and in every
mirror, present in 40-80 % of the frames); the subject's detections are those of
the same seed without bystanders, so the calibration must come out the same.
"""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.cli import main
from mirrorgraph.errors import DegenerateGeometryError, InputError
from mirrorgraph.metrics import normal_angle_deg, rotation_error_deg
from mirrorgraph.initial.pairing import pair_candidates, pair_reflections, paired_people
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.pipelines.rig import calibrate_rig
from mirrorgraph.rigs.config import load_rig_config
from mirrorgraph.rigs.observations import load_observations
from mirrorgraph.synth.rig import PERSON, make_rig, read_rig_ground_truth, write_rig

FRAMES = 150
#: seeds whose bystander pairs with a reflection in many frames: frame by frame
#: (``pair_reflections``) the subject is chosen in only ~60 % of them
SEEDS = {"2cams1mirror": 3, "1cam2mirrors": 3, "4cams": 0}


@pytest.fixture(scope="module", params=sorted(SEEDS))
def crowded(request, tmp_path_factory):
    """``(rig, its rig.toml, load_observations)`` of a rig with one bystander."""
    kind = request.param
    rig = make_rig(kind, frames=FRAMES, seed=SEEDS[kind], noise_std=4.0, bystanders=1)
    path = write_rig(rig, tmp_path_factory.mktemp(kind))
    return rig, path, load_observations(load_rig_config(path))


def _picked(chosen: np.ndarray, truth: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """``(T,)`` the chosen ``(T, J, 3)`` rows are the true view (median joint within 25 px
    of the noise-free ``(T, J, 2)``; a bystander is hundreds of pixels away)."""
    d = np.linalg.norm(chosen[:, joints, :2] - truth[:, joints], axis=-1)
    d = np.where(np.isfinite(d), d, np.inf)
    return np.median(d, axis=1) < 25.0


# --------------------------------------------------------------------------- synthetic data
def test_bystanders_are_added_to_the_same_rig():
    """Same seed: the same rig and subject detections; the bystander's rows come on top,
    named and labelled like the subject's views (reflections flipped)."""
    kw = dict(frames=60, seed=4, noise_std=0.0)
    plain = make_rig("2cams1mirror", **kw)
    rig = make_rig("2cams1mirror", bystanders=1, **kw)
    assert np.array_equal(plain.joints3d, rig.joints3d)
    assert all(np.array_equal(a, b) for a, b in zip(plain.poses, rig.poses))
    assert len(rig.bystanders) == 1 and "bystanders" not in plain.options
    by = rig.bystanders[0]
    assert by.name == "bystander1" and 1.55 <= by.height <= 1.95
    assert 0.4 * 60 - 1 <= by.present.sum() <= 0.8 * 60 + 1
    gap = np.linalg.norm((by.joints3d - rig.joints3d).mean(axis=(0, 1)))
    assert 0.8 < gap < 3.0
    flip = rig.skeleton.flip
    for k, cam in enumerate(rig.camera_names):
        assert set(rig.views[cam]) == {PERSON, "wall", "bystander1", "bystander1/wall"}
        assert not rig.views[cam]["bystander1"].detected[~by.present].any()
        assert rig.views[cam]["bystander1"].detected[by.present].mean() > 0.5
        direct = rig.project(k, by.joints3d)
        mirrored = rig.project(k, rig.reflect(by.joints3d, "wall"))
        for t, (rows, names) in enumerate(zip(rig.detections[cam].people,
                                              rig.detection_views[cam])):
            subject = [i for i, n in enumerate(names) if not n.startswith("bystander")]
            assert np.array_equal(rows[subject], plain.detections[cam].people[t],
                                  equal_nan=True)
            assert tuple(names[i] for i in subject) == plain.detection_views[cam][t]
            for row, name in zip(rows, names):
                if name.startswith("bystander"):
                    real = row if name == "bystander1" else row[flip]   # undo the labels
                    uv = direct if name == "bystander1" else mirrored
                    seen = real[:, 2] > 0
                    assert np.allclose(real[seen, :2], uv[t, seen], atol=1e-6)


def test_a_rig_with_bystanders_is_written_with_its_truth(tmp_path):
    rig = make_rig("1cam2mirrors", frames=30, seed=2, bystanders=2)
    gt = read_rig_ground_truth(write_rig(rig, tmp_path))
    assert [b["name"] for b in gt["bystanders"]] == ["bystander1", "bystander2"]
    assert np.allclose(gt["bystanders_joints3d"], [b.joints3d for b in rig.bystanders])
    assert gt["options"]["bystanders"] == 2
    assert main(["synth-rig", "2cams1mirror", "--out", str(tmp_path / "cli"), "--frames", "20",
                 "--bystanders", "1", "--quiet"]) == 0
    assert read_rig_ground_truth(tmp_path / "cli")["options"]["bystanders"] == 1


# --------------------------------------------------------------------------- pairing
def test_two_mirrors_are_found_among_two_people_and_four_reflections():
    """A 90 deg corner of two mirrors: the lines joining any two reflections are nearly
    horizontal, and with a bystander a far epipole on the horizon explains more pairs
    than either mirror (this seed: the first RANSAC finds it). The set of epipoles that
    explains the frames as people with a reflection in each mirror is kept."""
    rig = make_rig("1cam2mirrors", frames=FRAMES, seed=5, bystanders=1)
    cands = pair_candidates(rig.detections["cam01"], 2)
    K = rig.K[0]
    found = [np.linalg.solve(K, e) for e in cands.epipoles]
    for name in rig.mirror_names:
        n, _ = rig.mirror_in_camera(0, name)                  # the epipole is K n
        angle = min(np.degrees(np.arccos(min(1.0, abs(n @ f) / np.linalg.norm(f))))
                    for f in found)
        assert angle < 1.0, name
    # every frame's subject is among the candidates for the person
    names = rig.detection_views["cam01"]
    people = paired_people(cands)
    assert np.mean([PERSON in [names[t][i] for i in people[t]] for t in range(FRAMES)]) > 0.97


def test_a_mirror_without_a_pair_in_a_frame_leaves_it_empty():
    """Frames where only one mirror shows the person: the other mirror has no reflection
    there (it used to get a copy of the person)."""
    rig = make_rig("1cam2mirrors", frames=60, seed=1)
    raw = rig.detections["cam01"]
    gone = np.arange(0, 60, 3)
    for t in gone:
        keep = [n != "mirror_right" for n in rig.detection_views["cam01"][t]]
        raw.people[t] = raw.people[t][keep]
    pairing = pair_reflections(raw, 2)
    right = int(np.argmax([np.linalg.solve(rig.K[0], e)[0] * np.sign(e[2])
                           for e in pairing.epipoles]))
    assert np.all(pairing.reflections[right][gone, :, 2] == 0)
    assert np.isnan(pairing.reflections[right][gone, :, :2]).all()
    assert (pairing.real[gone, :, 2] > 0).any(1).all()


# --------------------------------------------------------------------------- observations
def test_the_subject_is_picked_in_every_camera_and_mirror(crowded):
    rig, _, obs = crowded
    joints = rig.skeleton.calibration_joints
    for cam in obs.cameras:
        views = rig.views[cam.name]
        # the test means something: the bystander is there, and with mirrors pairs too
        assert views["bystander1"].detected.mean() > 0.3, cam.name
        for name, chosen in [(PERSON, cam.real), *cam.reflections.items()]:
            truth = views[name]
            picked = _picked(chosen, truth.clean, joints)
            assert picked[truth.detected].mean() >= 0.95, (cam.name, name)
            # and never the bystander where the subject is not seen
            assert not (np.isfinite(chosen[..., 0]).any(1) & ~truth.detected).any()


def test_a_warning_names_the_camera_with_several_people(crowded, tmp_path):
    rig, _, obs = crowded
    what = "have reflections" if rig.kind != "4cams" else "are in view"
    assert any(w.startswith(f"camera cam01: 2 people {what}; calibrating from the one seen "
                            "longest") for w in obs.warnings), obs.warnings
    alone = make_rig(rig.kind, frames=FRAMES, seed=SEEDS[rig.kind], noise_std=4.0)
    plain = load_observations(load_rig_config(write_rig(alone, tmp_path)))
    assert not any("people are in view" in w or "people have reflections" in w
               for w in plain.warnings), plain.warnings
    # alone, the subject's detections are the same: so is what is kept of them
    for a, b in zip(plain.cameras, obs.cameras):
        assert np.array_equal(a.real, b.real, equal_nan=True)
        for m in a.reflections:
            assert np.array_equal(a.reflections[m], b.reflections[m], equal_nan=True)


# --------------------------------------------------------------------------- calibration
def _errors(cal, rig) -> tuple[list[float], list[float], dict[str, float]]:
    """Camera rotation errors (deg), scale-aligned positions (m), mirror normal errors (deg)."""
    est = np.array([c.pose[:3, 3] for c in cal.cameras])
    tru = np.array([np.asarray(P)[:3, 3] for P in rig.poses])
    s = float(np.sum(est * tru) / max(np.sum(est * est), 1e-12))
    rot = [rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3])
           for c, P in zip(cal.cameras, rig.poses)]
    pos = [float(np.linalg.norm(s * c.pose[:3, 3] - np.asarray(P)[:3, 3]))
           for c, P in zip(cal.cameras, rig.poses)]
    normals = {m.name: normal_angle_deg(m.normal, rig.mirror(m.name)[0]) for m in cal.mirrors}
    return rot, pos, normals


@pytest.mark.parametrize("kind", ["2cams1mirror", "1cam2mirrors"])
def test_calibration_with_a_bystander_as_accurate_as_without(tmp_path, kind):
    kw = dict(frames=FRAMES, seed=SEEDS[kind], noise_std=4.0)
    busy = make_rig(kind, bystanders=1, **kw)
    alone = make_rig(kind, **kw)
    # the one-person path (the subject followed; --people all adds the bystander)
    one = CalibrateOptions(people="one")
    cal = calibrate_rig(write_rig(busy, tmp_path / "busy"), one)
    ref = calibrate_rig(write_rig(alone, tmp_path / "alone"), one)
    rot, pos, normals = _errors(cal, busy)
    rot0, _, normals0 = _errors(ref, alone)
    assert sorted(normals) == sorted(busy.mirror_names)
    for r, r0, p in zip(rot[1:], rot0[1:], pos[1:]):
        assert r < 0.5 and p < 0.03
        assert abs(r - r0) < 0.05
    for name, angle in normals.items():
        assert angle < 0.2, name
        assert abs(angle - normals0[name]) < 0.05, name
    assert any("2 people have reflections" in w for w in cal.warnings)


# --------------------------------------------------------------------------- errors
def test_no_person_in_common_with_the_first_camera_is_an_error(tmp_path, capsys):
    """cam02's keypoints are of another take (no frame in common with cam01): nothing is
    seen at once; the error names the camera and the frames, not the people."""
    rig = make_rig("2cams1mirror", frames=60, seed=SEEDS["2cams1mirror"], bystanders=1)
    rig.detections["cam02"].frame_ids = rig.detections["cam02"].frame_ids + 1000
    path = write_rig(rig, tmp_path)
    with pytest.raises(InputError, match="camera cam02's frames 1000..1059 .*share none with "
                                         "camera cam01's 0..59"):
        load_observations(load_rig_config(path))
    assert main(["calibrate-rig", str(path), "--out", str(tmp_path / "c.toml"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cam02" in err[0] and "Traceback" not in err[0]


def _swap_camera_person(rig, other, camera: str, frames: np.ndarray) -> None:
    """Give ``camera`` the keypoints of ``other``'s person (another walk, seen by another
    camera placement) in ``frames``, in place."""
    people = rig.detections[camera].people
    for t in frames:
        people[t] = other.detections[camera].people[t]


def test_a_camera_that_sees_only_someone_else_is_an_error(tmp_path):
    """cam02 given another person's keypoints in every frame: none fit the rig, and the
    error names the camera (no traceback, no garbage pose)."""
    rig = make_rig("4cams", frames=120, seed=5, noise_std=4.0)
    other = make_rig("4cams", frames=120, seed=12, noise_std=4.0)
    _swap_camera_person(rig, other, "cam02", np.arange(120))
    with pytest.raises(DegenerateGeometryError, match="camera cam02"):
        calibrate_rig(write_rig(rig, tmp_path))


def test_a_camera_that_sometimes_sees_someone_else_drops_those_frames(tmp_path):
    """The subject leaves cam02's view and someone else walks in (the last 30 % of the
    frames, one person a frame): those frames do not fit the first camera's person
    and are dropped; the calibration is that of the frames that do."""
    rig = make_rig("4cams", frames=120, seed=5, noise_std=4.0)
    other = make_rig("4cams", frames=120, seed=12, noise_std=4.0)
    wrong = np.arange(84, 120)
    _swap_camera_person(rig, other, "cam02", wrong)
    path = write_rig(rig, tmp_path)
    obs = load_observations(load_rig_config(path))
    cam02 = obs.cameras[1]
    kept = (cam02.real[..., 2] > 0).any(1)
    assert kept[wrong].mean() < 0.05 and kept[:84].mean() > 0.95
    cal = calibrate_rig(path)
    errors = [rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3])
              for c, P in zip(cal.cameras[1:], rig.poses[1:])]
    assert max(errors) < 0.5
    assert not any(w.startswith("view ") for w in cal.warnings)


def test_views_that_lost_most_keypoints_are_named():
    from mirrorgraph.pipelines.judge import MIN_KEPT_FRACTION, judge_rig

    out = judge_rig([], [], {}, view_names=["cam01", "cam02", "cam02/wall"],
                    view_counts=[990, 300, 0], view_observed=[1000, 1000, 0],
                    mirror_spread_deg={"wall": 1.0})
    assert MIN_KEPT_FRACTION == 0.5
    assert len(out) == 1 and out[0].startswith("view cam02: only 30 % of its keypoints fit")


def test_between_people_seen_as_long_the_one_who_moves_most_is_the_subject():
    """Two people in every frame (track 0 found first, standing still; track 1 walking):
    the subject is the one who moves; a person seen in far fewer frames does not win
    on motion."""
    from mirrorgraph.rigs.tracking import subject_track, track_motion
    rng = np.random.default_rng(0)
    T, J = 60, 17
    still = np.concatenate([rng.normal(500, 2, (T, J, 2)), np.ones((T, J, 1))], -1)
    walk = np.concatenate([rng.normal(900, 2, (T, J, 2)) + np.linspace(0, 400, T)[:, None, None],
                           np.ones((T, J, 1))], -1)
    people = [np.stack([still[t], walk[t]]) for t in range(T)]
    tracks = [np.array([0, 1]) for _ in range(T)]
    joints = np.arange(J)
    motion = track_motion(tracks, people, joints, 0.3)
    assert motion[1] > 50 * motion[0]
    assert subject_track(tracks)[0] == 0                       # frames alone: a tie
    assert subject_track(tracks, motion)[0] == 1
    short = [np.array([0, 1]) if t < T // 2 else np.array([0]) for t in range(T)]
    people_short = [p if t < T // 2 else p[:1] for t, p in enumerate(people)]
    assert subject_track(short, track_motion(short, people_short, joints, 0.3))[0] == 0


# --------------------------------------------------------------------------- left/right swaps
def _swap_subject_labels(rig, camera: str, frames: np.ndarray) -> None:
    """Swap the left/right labels of ``camera``'s subject detection in ``frames``, as a
    detector does on a person turning (BlazePose on Pose2Sim's demo videos), in place."""
    flip = rig.skeleton.flip
    clean = rig.views[camera][PERSON].clean
    joints = rig.skeleton.calibration_joints
    for t in frames:
        p = np.array(rig.detections[camera].people[t], dtype=float)
        if not len(p):
            continue
        d = np.nanmedian(np.linalg.norm(p[:, joints, :2] - clean[t, joints], axis=-1), axis=1)
        i = int(np.nanargmin(d))
        if d[i] < 25.0:
            p[i] = p[i][flip]
            rig.detections[camera].people[t] = p


def test_left_right_swaps_neither_split_the_subject_nor_refuse_a_camera(tmp_path):
    """BlazePose swaps a turning subject's left and right labels in one camera and not in
    another (Pose2Sim's Demo_SinglePerson, issue #24: each swap started a new track of
    the rig's tracker and the swapped frames were outliers to every track's geometry, so
    that a camera could be refused). Here the subject's labels are swapped in blocks of
    frames, differently in every camera, a bystander in view: every camera keeps the
    subject in the frames whose labels agree with the first camera's and never the
    bystander. (Not asserted: the calibration from these; where a camera's labels
    disagree with the first camera's in half the frames, frames with two candidates
    that fit as labelled still pair the wrong sides: issue #24, what is left.)"""
    kw = dict(frames=FRAMES, seed=SEEDS["4cams"], noise_std=4.0, bystanders=1)
    rig = make_rig("4cams", **kw)
    blocks = np.arange(FRAMES) // 10
    swaps = {"cam01": blocks % 4 == 1, "cam02": blocks % 2 == 0, "cam03": blocks % 3 == 0,
             "cam04": blocks % 3 == 2}
    for cam, where in swaps.items():
        _swap_subject_labels(rig, cam, np.flatnonzero(where))
    path = write_rig(rig, tmp_path / "swapped")
    obs = load_observations(load_rig_config(path))
    joints, flip = rig.skeleton.calibration_joints, rig.skeleton.flip
    for cam in obs.cameras:
        truth = rig.views[cam.name][PERSON]
        as_given = np.where(swaps[cam.name][:, None, None], truth.clean[:, flip], truth.clean)
        picked = _picked(cam.real, as_given, joints)
        agree = truth.detected & (swaps[cam.name] == swaps["cam01"])
        assert picked[agree].mean() >= 0.95, cam.name
        kept = (cam.real[..., 2] > 0).any(1)          # and whatever is kept is the subject
        either = picked | _picked(cam.real, truth.clean[:, flip], joints) \
            | _picked(cam.real, truth.clean, joints)
        assert either[kept].all(), cam.name


def test_the_first_camera_follows_the_moving_subject_through_a_left_right_swap():
    """Pose2Sim's Demo_MultiPerson (issue #24): in the first camera the subject turns and
    the detector swaps their left and right labels from one frame on, moving the joints
    as labelled by more than the tracker's gate (208 px, 23 px with the labels swapped),
    while a second person stands still in every frame. Tracked as labelled, the subject
    was split into two tracks (56 + 44 frames) and the person standing still, seen in all
    100, was followed (cam02 then refused). The first camera's tracker reads the swap, as
    the other cameras' do: the subject is one track, and the one who moves."""
    from mirrorgraph.rigs.observations import _follow_subject, _Sorting
    from mirrorgraph.skeletons import BLAZEPOSE
    rng = np.random.default_rng(0)
    T, J = 60, BLAZEPOSE.num_joints
    side = np.array([-1.0 if n.startswith("left") else 1.0 if n.startswith("right") else 0.0
                     for n in BLAZEPOSE.joints])
    body = np.stack([120.0 * side, np.linspace(-300.0, 300.0, J)], -1)     # (J, 2), px

    def person(x0: np.ndarray) -> np.ndarray:                              # (T, J, 3)
        xy = body[None] + x0[:, None, :] + rng.normal(0, 2, (len(x0), J, 2))
        return np.concatenate([xy, np.ones((len(x0), J, 1))], -1)

    still = person(np.tile([900.0, 1000.0], (T, 1)))
    walk = person(np.stack([np.linspace(300.0, 500.0, T), np.full(T, 900.0)], -1))
    swapped = np.arange(T) >= T // 2
    walk_as_detected = np.where(swapped[:, None, None], walk[:, BLAZEPOSE.flip], walk)
    people = [np.stack([still[t], walk_as_detected[t]]) for t in range(T)]
    sorting = _Sorting(real=np.zeros((T, J, 3)), reflections={}, lr_fixes=0,
                       people=people)
    warnings: list[str] = []
    _follow_subject("cam01", sorting, BLAZEPOSE, [], warnings)
    assert np.allclose(sorting.real, walk_as_detected)
