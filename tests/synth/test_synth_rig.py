"""Tests of the synthetic multi-camera / multi-mirror rigs (mirrorgraph.synth.rig)."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from mirrorgraph.synth import SyntheticRig, make_rig, read_rig_ground_truth, write_rig
from mirrorgraph.synth.rig import KINDS, PERSON, _Mirror, _path_visible

EXPECTED = {
    "4cams": (["cam01", "cam02", "cam03", "cam04"], [],
              {"cam01": [], "cam02": [], "cam03": [], "cam04": []}),
    "2cams1mirror": (["cam01", "cam02"], ["wall"], {"cam01": ["wall"], "cam02": ["wall"]}),
    "1cam2mirrors": (["cam01"], ["mirror_left", "mirror_right"],
                     {"cam01": ["mirror_left", "mirror_right"]}),
}


@pytest.fixture(scope="module", params=[(k, 90.0) for k in KINDS]
                + [("1cam2mirrors", 60.0), ("1cam2mirrors", 120.0)], ids=str)
def exact(request) -> SyntheticRig:
    """Noise-free rig (double reflections on: they only matter for 1cam2mirrors)."""
    kind, angle = request.param
    return make_rig(kind, frames=120, seed=5, noise_std=0.0, double_reflections=True,
                    corner_angle_deg=angle)


def _pi(K: np.ndarray, Xc: np.ndarray) -> np.ndarray:
    uvw = Xc @ K.T
    return uvw[..., :2] / uvw[..., 2:3]


def _expected_image(rig: SyntheticRig, cam: int, view: str) -> np.ndarray:
    """``(T, J, 2)`` recomputed from the world-frame truth alone, real-joint labels."""
    X = rig.joints3d
    if view != PERSON:
        seq = view.replace("+", ">").split(">")       # merged double: either order
        for name in reversed(seq):                    # the camera meets seq[0] first
            n, d = rig.mirrors[rig.mirror_names.index(name)]
            X = X - 2.0 * ((X @ n) - d)[..., None] * n
    P = rig.poses[cam]
    Xc = (X - P[:3, 3]) @ P[:3, :3]                   # R^T (X - C)
    return _pi(rig.K[cam], Xc)


def _rotation_ok(R: np.ndarray) -> bool:
    return np.allclose(R.T @ R, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(R), 1.0)


# --------------------------------------------------------------------------- structure
@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_has_its_cameras_mirrors_and_visibility(kind):
    rig = make_rig(kind, frames=300, seed=2)
    cams, mirrors, sees = EXPECTED[kind]
    T, J = 300, rig.skeleton.num_joints
    assert rig.kind == kind and rig.camera_names == cams and rig.mirror_names == mirrors
    assert rig.sees == sees
    assert rig.skeleton.name == "BODY_25" and rig.joints3d.shape == (T, J, 3)
    assert np.array_equal(rig.frame_ids, np.arange(T))
    assert len(rig.K) == len(rig.poses) == len(cams) and rig.image_size == (1920, 1080)
    assert np.array_equal(rig.poses[0], np.eye(4))
    for P in rig.poses:
        assert P.shape == (4, 4) and _rotation_ok(P[:3, :3])
        assert np.array_equal(P[3], [0, 0, 0, 1])
    assert 1.55 <= rig.subject_height <= 1.95
    for (n, d), name in zip(rig.mirrors, rig.mirror_names):
        assert n.shape == (3,) and np.isclose(np.linalg.norm(n), 1.0) and d > 0
        # the person stays on the reflective side, 0.2 m away at least
        assert (rig.joints3d @ n - d).max() <= -0.2
        for cam in cams:
            if name in rig.sees[cam]:
                C = rig.poses[rig.camera_index(cam)][:3, 3]
                assert n @ C < d                      # every viewer on the reflective side
                n_c, d_c = rig.mirror_in_camera(cam, name)
                assert d_c > 0 and np.isclose(np.linalg.norm(n_c), 1.0)
    for cam in cams:
        det = rig.detections[cam]
        assert det.image_size == (1920, 1080) and det.fps == 30.0 and len(det) == T
        views = rig.views[cam]
        assert set(views) == {PERSON, *rig.sees[cam]}    # no double reflections by default
        # the whole person in >= 90 % of the frames, each reflection in >= 75 %
        assert views[PERSON].visible.all(-1).mean() >= 0.9
        assert views[PERSON].detected.mean() >= 0.95
        for m in rig.sees[cam]:
            assert views[m].visible.all(-1).mean() >= 0.75 and views[m].detected.mean() >= 0.9
            assert views[m].flipped and not views[PERSON].flipped
        # one detection per detected view, each frame
        counts = sum(v.detected.astype(int) for v in views.values())
        assert [len(p) for p in det.people] == list(counts)
        assert [len(v) for v in rig.detection_views[cam]] == list(counts)
        # mirrors listed left first: increasing x of the normal in that camera
        xs = [rig.mirror_in_camera(cam, m)[0][0] for m in rig.sees[cam]]
        assert xs == sorted(xs)


def _room(rig: SyntheticRig) -> tuple[np.ndarray, np.ndarray]:
    """Room axes (X, Y up, Z) as world-frame columns, and the room origin in the world."""
    A = rig.placement["room_to_world"]
    return A[:3, :3], A[:3, 3]


def test_geometry_of_the_four_camera_rig():
    rig = make_rig("4cams", frames=200, seed=9)
    axes, origin = _room(rig)
    centre_r = (rig.joints3d.reshape(-1, 3) - origin) @ axes       # room coordinates
    centre_r = centre_r.mean(0)
    az = []
    for k, P in enumerate(rig.poses):
        C_r = axes.T @ (P[:3, 3] - origin)
        assert 1.0 <= C_r[1] <= 1.6                                 # camera height
        horiz = (C_r - centre_r)[[0, 2]]
        assert 3.0 - 1e-9 <= np.hypot(*horiz) <= 5.0 + 1e-9
        az.append(np.degrees(np.arctan2(*horiz)))
        # looking at the person: their centre projects near the image centre
        u = rig.project(k, rig.joints3d.reshape(-1, 3).mean(0))
        assert abs(u[0] - 960) < 100 and abs(u[1] - 540) < 150
        # every camera level up to its pitch: roll within 2 deg
        x_r = axes.T @ P[:3, 0]
        assert abs(np.degrees(np.arcsin(x_r[1]))) <= 2.0 + 1e-9
    steps = np.diff(np.array(az) - az[0]) % 360.0
    assert np.all((steps >= 70.0) & (steps <= 110.0)), steps


def test_two_cameras_one_mirror_are_apart_on_the_same_side():
    rig = make_rig("2cams1mirror", frames=200, seed=4)
    n, d = rig.mirror("wall")
    p = rig.placement
    assert 40.0 <= p["camera_separation_deg"] <= 90.0
    assert all(15.0 <= abs(a) <= 60.0 for a in p["camera_azimuth_deg"])
    z0, z1 = rig.poses[0][:3, 2], rig.poses[1][:3, 2]
    assert np.degrees(np.arccos(z0 @ z1)) > 20.0
    for P in rig.poses:
        assert P[:3, 3] @ n < d
    # the reflection in the image is the person's image through the mirror
    for cam in rig.camera_names:
        assert rig.views[cam]["wall"].detected.mean() > 0.95


# --------------------------------------------------------------------------- projections
def test_noise_free_detections_are_the_projections_of_the_truth(exact):
    rig = exact
    flip = rig.skeleton.flip
    checked = 0
    for k, cam in enumerate(rig.camera_names):
        expected = {v: _expected_image(rig, k, v) for v in rig.views[cam]}
        for t, (people, names) in enumerate(zip(rig.detections[cam].people,
                                                 rig.detection_views[cam])):
            assert len(people) == len(names)
            for person, name in zip(people, names):
                view = rig.views[cam][name]
                real = person[flip] if view.flipped else person   # undo the detector's labels
                seen = real[:, 2] > 0
                assert np.array_equal(seen, view.visible[t])
                assert np.abs(real[seen, :2] - expected[name][t, seen]).max() < 1e-6
                assert np.all(np.isnan(real[~seen, :2]))
                # and it is not any other view's projection
                for other, uv in expected.items():
                    if other != name:
                        assert np.nanmax(np.abs(real[seen, :2] - uv[t, seen])) > 1.0
                checked += 1
        # the stored clean points are the same projections
        for name, view in rig.views[cam].items():
            vis = view.visible
            assert np.abs(view.clean[vis] - expected[name][vis]).max(initial=0.0) < 1e-6
    assert checked > 100


def test_double_reflections_only_when_asked():
    kw = dict(frames=60, seed=3, noise_std=0.0)
    plain = make_rig("1cam2mirrors", **kw)
    both = make_rig("1cam2mirrors", double_reflections=True, **kw)
    assert set(plain.views["cam01"]) == {PERSON, "mirror_left", "mirror_right"}
    # a 90 deg corner: both orders give one virtual person, seen whole, labels unflipped
    double = both.views["cam01"]["mirror_left+mirror_right"]
    assert not double.flipped and double.paths == (("mirror_left", "mirror_right"),
                                                   ("mirror_right", "mirror_left"))
    assert double.detected.mean() > 0.9
    assert np.array_equal(plain.joints3d, both.joints3d)
    assert sum(len(p) for p in both.detections["cam01"].people) == \
        sum(len(p) for p in plain.detections["cam01"].people) + int(double.detected.sum())
    # the double reflection is the person turned 180 deg about the corner edge
    nl, dl = both.mirror("mirror_left")
    nr, dr = both.mirror("mirror_right")
    assert abs(nl @ nr) < 1e-12
    X = both.joints3d
    V = both.reflect(both.reflect(X, "mirror_right"), "mirror_left")
    assert np.allclose(V, both.reflect(both.reflect(X, "mirror_left"), "mirror_right"))
    # at 60 deg two distinct double images
    acute = make_rig("1cam2mirrors", double_reflections=True, corner_angle_deg=60.0, **kw)
    names = set(acute.views["cam01"])
    assert {"mirror_left>mirror_right", "mirror_right>mirror_left"} <= names
    nl, _ = acute.mirror("mirror_left")
    nr, _ = acute.mirror("mirror_right")
    assert np.degrees(np.arccos(-nl @ nr)) == pytest.approx(60.0)
    assert set(make_rig("2cams1mirror", double_reflections=True, **kw).views["cam01"]) == \
        {PERSON, "wall"}


@pytest.mark.parametrize("angle", [90.0, 120.0])
def test_corner_mirrors_are_half_planes(angle):
    # corner edge along the y axis, the room (interior angle `angle`) around -z
    rng = np.random.default_rng(0)
    h = np.radians(angle) / 2
    nA, nB = np.array([np.cos(h), 0, np.sin(h)]), np.array([-np.cos(h), 0, np.sin(h)])
    A, B = _Mirror("a", nA, 0.0, [(nB, 0.0)]), _Mirror("b", nB, 0.0, [(nA, 0.0)])

    def in_room(n):
        P = np.column_stack([rng.uniform(-6, 6, n), rng.uniform(0, 2, n), rng.uniform(-8, 0, n)])
        return P[(P @ nA < -0.05) & (P @ nB < -0.05)]

    C, X = in_room(4000)[:1500], in_room(4000)[:1500]
    V, ok = _path_visible(C, X, (A,))
    assert np.allclose(V, X - 2.0 * (X @ nA)[:, None] * nA)
    lam = -(C @ nA) / ((V - C) @ nA)
    hit = C + lam[:, None] * (V - C)
    assert np.allclose(hit @ nA, 0.0, atol=1e-9)
    assert np.array_equal(ok, hit @ nB <= 0.0)            # on the mirror, not beyond the edge
    if angle <= 90.0:
        assert ok.all()          # the room and its image form a convex wedge: always seen
    else:
        assert 0.05 < ok.mean() < 0.99
    # a camera behind a mirror sees nothing in it
    _, ok = _path_visible(np.array([3.0, 1.0, 3.0]), X, (A,))
    assert not ok.any()
    # double reflections: the path meets a, then b, each on its surface
    V2, ok2 = _path_visible(C, X, (A, B))
    assert np.allclose(V2, (lambda Y: Y - 2.0 * (Y @ nA)[:, None] * nA)(
        X - 2.0 * (X @ nB)[:, None] * nB))
    assert ok2.any() and not ok2.all()


# --------------------------------------------------------------------------- labels, noise
def test_reflection_is_labelled_flipped_by_the_detector():
    rig = make_rig("2cams1mirror", frames=80, seed=6, noise_std=0.0)
    sk = rig.skeleton
    lw, rw = sk.index("left_wrist"), sk.index("right_wrist")
    virtual = rig.reflect(rig.joints3d, "wall")
    for k, cam in enumerate(rig.camera_names):
        uv = rig.project(k, virtual)
        for t, (people, names) in enumerate(zip(rig.detections[cam].people,
                                                 rig.detection_views[cam])):
            for person, name in zip(people, names):
                if name == "wall" and person[lw, 2] > 0:
                    # the detector's "left wrist" of the reflection images the real right one
                    assert np.allclose(person[lw, :2], uv[t, rw], atol=1e-6)
                elif name == PERSON:
                    assert np.allclose(person[lw, :2], rig.project(k, rig.joints3d[t, lw]))
    # with every frame swapped, the detector keeps the real joints' labels
    swapped = make_rig("2cams1mirror", frames=80, seed=6, noise_std=0.0, lr_swap_rate=1.0)
    v = swapped.views["cam01"]["wall"]
    assert np.array_equal(v.lr_swapped, v.detected)
    uv = swapped.project(0, swapped.reflect(swapped.joints3d, "wall"))
    for t, (people, names) in enumerate(zip(swapped.detections["cam01"].people,
                                             swapped.detection_views["cam01"])):
        for person, name in zip(people, names):
            if name == "wall":
                seen = person[:, 2] > 0
                assert np.allclose(person[seen, :2], uv[t, seen], atol=1e-6)


def test_same_seed_same_rig_other_seed_other_rig():
    kw = dict(frames=100, outlier_rate=0.05, missing_rate=0.05, lr_swap_rate=0.1,
              double_reflections=True)
    for kind in KINDS:
        a, b, c = (make_rig(kind, seed=s, **kw) for s in (7, 7, 8))
        assert np.array_equal(a.joints3d, b.joints3d)
        assert all(np.array_equal(x, y) for x, y in zip(a.K, b.K))
        assert all(np.array_equal(x, y) for x, y in zip(a.poses, b.poses))
        assert a.mirror_names == b.mirror_names and all(
            np.array_equal(m[0], q[0]) and m[1] == q[1] for m, q in zip(a.mirrors, b.mirrors))
        for cam in a.camera_names:
            pa, pb = a.detections[cam].people, b.detections[cam].people
            assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(pa, pb))
            assert a.detection_views[cam] == b.detection_views[cam]
        assert not np.allclose(a.joints3d, c.joints3d)


def test_noise_rates_and_random_order():
    rig = make_rig("1cam2mirrors", frames=1500, seed=1, noise_std=4.0, outlier_rate=0.1,
                   missing_rate=0.1, lr_swap_rate=0.2, subject_height=1.8)
    assert rig.subject_height == 1.8
    views = rig.views["cam01"]
    res, outl, miss, seen = [], 0, 0, 0
    for v in views.values():
        ok = v.detected[:, None] & v.visible & ~v.outliers & (v.observed[..., 2] > 0)
        res.append((v.observed[..., :2] - v.clean)[ok])
        outl += v.outliers[v.detected].sum()
        seen += (v.detected[:, None] & v.visible).sum()
        miss += (v.detected[:, None] & v.visible & (v.observed[..., 2] == 0)).sum()
        conf = v.observed[..., 2][v.observed[..., 2] > 0]
        assert conf.min() >= 0.3 and conf.max() <= 1.0
    res = np.concatenate(res)
    assert np.std(res) == pytest.approx(4.0, rel=0.05) and abs(res.mean()) < 0.1
    assert 0.07 < outl / seen < 0.11
    assert 0.05 < miss / seen < 0.12
    for m in ("mirror_left", "mirror_right"):
        v = views[m]
        assert 0.15 < v.lr_swapped[v.detected].mean() < 0.25
        assert not views[PERSON].lr_swapped.any()
    # the person is not always listed first
    first = [names[0] for names in rig.detection_views["cam01"] if len(names) > 1]
    share = first.count(PERSON) / len(first)
    assert 0.2 < share < 0.5


def test_joint_bias_is_constant_per_view_and_joint():
    """joint_bias_px: an offset per view and joint, the same in every frame, on top of the
    noise; without it the rig is the one of before (same seed, same detections)."""
    kw = dict(frames=400, seed=3, noise_std=4.0)
    plain = make_rig("2cams1mirror", **kw)
    biased = make_rig("2cams1mirror", joint_bias_px=3.0, **kw)
    assert np.array_equal(plain.joints3d, biased.joints3d)
    assert "joint_bias_px" not in plain.options and biased.options["joint_bias_px"] == 3.0
    means, spread = [], []
    for cam in biased.camera_names:
        for v in biased.views[cam].values():
            ok = v.detected[:, None] & v.visible
            err = np.where(ok[..., None], v.observed[..., :2] - v.clean, np.nan)
            means.append(np.nanmean(err, axis=0))                # (J, 2) per-joint offsets
            spread.append(np.nanstd(err, axis=0))
    means, spread = np.concatenate(means), np.concatenate(spread)
    assert np.nanstd(means) == pytest.approx(3.0, rel=0.25)      # the offsets
    assert np.nanmedian(spread) == pytest.approx(4.0, rel=0.1)   # the noise about them
    with pytest.raises(ValueError, match="joint_bias_px"):
        make_rig("4cams", frames=10, joint_bias_px=-1.0)


def test_options_are_checked():
    with pytest.raises(ValueError, match="unknown rig kind"):
        make_rig("3cams")
    for kw in (dict(frames=0), dict(noise_std=-1.0), dict(outlier_rate=1.5),
               dict(fov_deg=0.0), dict(subject_height=-1.0), dict(corner_angle_deg=170.0)):
        with pytest.raises(ValueError):
            make_rig("1cam2mirrors", **kw)
    with pytest.raises(ValueError, match="field of view"):
        make_rig("2cams1mirror", frames=60, fov_deg=10.0)


def test_options_are_obeyed():
    rig = make_rig("4cams", frames=50, seed=0, skeleton="COCO_17", image_size=(1280, 720),
                   fov_deg=70.0, subject_height=1.6)
    assert rig.skeleton.name == "COCO_17" and rig.joints3d.shape == (50, 17, 3)
    assert rig.image_size == (1280, 720) and rig.subject_height == 1.6
    f = 640 / np.tan(np.radians(35.0))
    assert all(np.isclose(K[0, 0], f) and abs(K[0, 2] - 640) <= 4 for K in rig.K)
    assert rig.options["fov_deg"] == 70.0 and rig.options["kind"] == "4cams"
    head = rig.joints3d[:, rig.skeleton.index("nose")]
    feet = rig.joints3d[:, [rig.skeleton.index("left_ankle"), rig.skeleton.index("right_ankle")]]
    up = _room(rig)[0][:, 1]
    stand = np.percentile(head @ up - feet.mean(1) @ up, 90)
    assert 1.25 < stand < 1.55, stand


# --------------------------------------------------------------------------- writing
@pytest.mark.parametrize("kind,fmt", [("2cams1mirror", "openpose"), ("1cam2mirrors", "mmpose"),
                                      ("4cams", "easymocap")])
def test_write_rig_round_trips(tmp_path, kind, fmt):
    from mirrorgraph.intrinsics import load_intrinsics
    from mirrorgraph.io import read_keypoints
    from mirrorgraph.io.camera_toml import read_camera_toml, rodrigues_to_rotation

    rig = make_rig(kind, frames=30, seed=3, outlier_rate=0.05, missing_rate=0.05,
                   lr_swap_rate=0.1, double_reflections=True)
    path = write_rig(rig, tmp_path, fmt=fmt)
    assert path == tmp_path / "rig.toml"
    with open(path, "rb") as f:
        doc = tomllib.load(f)
    assert set(doc) == {"subject_height", "cameras"} | ({"mirrors"} if rig.mirror_names else set())
    assert doc["subject_height"] == rig.subject_height
    assert [m["name"] for m in doc.get("mirrors", [])] == rig.mirror_names
    assert [c["name"] for c in doc["cameras"]] == rig.camera_names
    calib = read_camera_toml(tmp_path / doc["cameras"][0]["intrinsics"])
    for k, entry in enumerate(doc["cameras"]):
        cam = rig.camera_names[k]
        want = f"pose/{cam}.json" if fmt == "mmpose" else f"pose/{cam}_json"
        assert entry["keypoints"] == want and entry["frame_offset"] == 0
        assert entry["intrinsics"] == "Calib.toml" and entry["intrinsics_section"] == cam
        assert entry["skeleton"] == "BODY_25"
        assert entry.get("mirrors", []) == rig.sees[cam]
        assert ("mirrors" in entry) == bool(rig.sees[cam])
        det = read_keypoints(tmp_path / entry["keypoints"])
        assert det.skeleton.name == "BODY_25"
        got = {int(f): p for f, p in zip(det.frame_ids, det.people)}
        for t, people in zip(rig.frame_ids, rig.detections[cam].people):
            q = got.get(int(t), np.zeros((0, 25, 3)))
            assert q.shape == people.shape
            seen = people[..., 2] > 0
            assert np.array_equal(q[..., 2] > 0, seen)
            assert np.allclose(q[seen], people[seen], atol=1e-9)
        intr = load_intrinsics(tmp_path / entry["intrinsics"], camera=entry["intrinsics_section"])
        assert np.allclose(intr.K, rig.K[k], rtol=0, atol=1e-12)
        assert intr.image_size == rig.image_size
        # the extrinsics in the intrinsics file are identity / zero: unknown to the user
        assert np.array_equal(calib[cam].rotation, np.zeros(3))
        assert np.array_equal(calib[cam].translation, np.zeros(3))

    gt = json.loads((tmp_path / "ground_truth.json").read_text())
    assert gt["kind"] == kind and gt["skeleton"] == "BODY_25"
    back = read_rig_ground_truth(tmp_path)
    assert read_rig_ground_truth(path)["kind"] == kind
    assert back["camera_names"] == rig.camera_names and back["mirror_names"] == rig.mirror_names
    assert np.allclose(back["poses"], np.array(rig.poses), rtol=0, atol=1e-12)
    assert np.allclose(back["K"], np.array(rig.K))
    for k, P in enumerate(rig.poses):
        R = rodrigues_to_rotation(back["rvec"][k])
        assert np.allclose(R, P[:3, :3].T, atol=1e-12)
        assert np.allclose(back["R"][k], P[:3, :3].T, atol=1e-12)
        assert np.allclose(back["tvec"][k], -P[:3, :3].T @ P[:3, 3], atol=1e-12)
    for m, (n, d) in enumerate(rig.mirrors):
        assert np.allclose(back["normals"][m], n) and back["distances"][m] == pytest.approx(d)
    assert back["sees"] == rig.sees
    assert back["subject_height"] == rig.subject_height
    assert np.array_equal(back["joints3d"], rig.joints3d)
    assert np.array_equal(back["frame_ids"], rig.frame_ids)
    assert list(back["joint_names"]) == list(rig.skeleton.joints)


def test_write_rig_without_height(tmp_path):
    rig = make_rig("2cams1mirror", frames=10, seed=0)
    path = write_rig(rig, tmp_path, include_height=False)
    with open(path, "rb") as f:
        doc = tomllib.load(f)
    assert "subject_height" not in doc
    assert read_rig_ground_truth(tmp_path)["subject_height"] == rig.subject_height
    with pytest.raises(ValueError, match="format"):
        write_rig(rig, tmp_path / "x", fmt="npz")


def test_rig_file_is_accepted_by_the_rig_reader(tmp_path):
    from mirrorgraph.rigs import config
    rig = make_rig("1cam2mirrors", frames=10, seed=0)
    cfg = config.load_rig_config(write_rig(rig, tmp_path))
    assert [c.name for c in cfg.cameras] == rig.camera_names
    assert cfg.mirrors == tuple(rig.mirror_names)
    assert cfg.cameras[0].mirrors == tuple(rig.sees["cam01"])
    assert cfg.subject_height == rig.subject_height
