"""Tests of the scene geometries and detector models beyond the favourable scenes
(mirrorgraph.synth.geometry, .detector, .sampling; make_scene(geometry=...),
make_rig(geometry=...))."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph.synth import (DEFAULT_GEOMETRY, PRESETS, make_rig, make_scene, make_wide_scene,
                               scene_geometry_stats)
from mirrorgraph.synth.detector import DETECTORS, EPIPOLAR_OUTLIER_PX
from mirrorgraph.synth.geometry import geometry_stats, pair_by_epipole
from mirrorgraph.synth.rig_placement import RIG_PRESETS

from tests.helpers import REPO_ROOT

FIXTURES = REPO_ROOT.parent / "shared" / "fixtures"

#: Summaries of make_scene's output before presets existed (commit 2eedefd), for
#: the same arguments: the "favourable" preset must reproduce them exactly.
REFERENCE = [
    (dict(frames=60, seed=5), dict(
        K=[1662.7687752661222, 0.0, 962.440023389963, 0.0, 1662.7687752661222, 542.4635263178919],
        normal=[-0.22838316065208128, 0.03845791790616359, 0.9728114516600267],
        distance=4.359856971054491, height=1.557633384489745, joints_sum=3712.757080067673,
        joints_sq=9831.45948934025, real_obs=1925881.8687803717, mirror_obs=1547270.6687330054,
        people=120, first=[976.8203245131346, 357.04513703093903, 0.9142461187972131],
        swaps=0, outliers=0, attempts=1)),
    (dict(frames=80, seed=2, outlier_rate=0.1, lr_swap_rate=0.2, missing_rate=0.1,
          extra_person_rate=0.2, noise_correlation=0.5, joint_bias_px=2.0), dict(
        K=[1662.7687752661222, 0.0, 958.0928970739945, 0.0, 1662.7687752661222, 538.387929147313],
        normal=[0.5402646163036942, 0.10958727252172665, 0.8343289363743002],
        distance=3.6915806342637194, height=1.8294094054093835, joints_sum=3610.578160559886,
        joints_sq=25921.02137920888, real_obs=1148944.3295639635, mirror_obs=1780927.8564405977,
        people=173, first=[900.9766887776586, 482.33029280577597, 0.6352299737390641],
        swaps=11, outliers=225, attempts=2)),
]


@pytest.mark.parametrize("kwargs, ref", REFERENCE)
def test_favourable_reproduces_the_original_generator(kwargs, ref):
    s = make_scene(geometry="favourable", **kwargs)
    tight = dict(rtol=1e-12, atol=1e-9)
    assert np.allclose(s.K[:2].ravel(), ref["K"], **tight)
    assert np.allclose(s.normal, ref["normal"], **tight)
    assert s.distance == pytest.approx(ref["distance"], rel=1e-12)
    assert s.subject_height == pytest.approx(ref["height"], rel=1e-12)
    assert float(s.joints3d.sum()) == pytest.approx(ref["joints_sum"], rel=1e-10)
    assert float((s.joints3d ** 2).sum()) == pytest.approx(ref["joints_sq"], rel=1e-10)
    assert float(np.nansum(s.real_observed)) == pytest.approx(ref["real_obs"], rel=1e-10)
    assert float(np.nansum(s.mirror_observed)) == pytest.approx(ref["mirror_obs"], rel=1e-10)
    assert sum(len(p) for p in s.detections.people) == ref["people"]
    assert np.allclose(s.detections.people[0][0, 0], ref["first"], **tight)
    assert int(s.lr_swapped.sum()) == ref["swaps"]
    assert int(s.outlier_mask_real.sum() + s.outlier_mask_mirror.sum()) == ref["outliers"]
    assert s.placement["attempts"] == ref["attempts"]
    assert "geometry" not in s.options and not s.lr_swapped_real.any()


def test_default_is_the_default_geometry():
    a, b = make_scene(frames=50, seed=9), make_scene(frames=50, seed=9, geometry=DEFAULT_GEOMETRY)
    for name in ("K", "normal", "joints3d", "real_observed", "mirror_observed"):
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name
    with pytest.raises(ValueError, match="unknown geometry"):
        make_scene(frames=10, geometry="cathedral")
    with pytest.raises(ValueError, match="not both"):
        make_scene(frames=10, fov_deg=60.0, focal_px=1000.0)


@pytest.fixture(scope="module")
def preset_scenes():
    return {g: [make_scene(frames=120, seed=s, geometry=g) for s in range(6)]
            for g in ("gym", "wide", "low_parallax")}


@pytest.mark.parametrize("name", ["gym", "wide", "low_parallax"])
def test_preset_ranges_are_respected(preset_scenes, name):
    gp = PRESETS[name]
    eps = 1e-9
    for s in preset_scenes[name]:
        p = s.placement
        n, d, X = s.normal, s.distance, s.joints3d
        assert p["geometry"] == name and s.options["geometry"] == name
        assert gp.mirror_distance[0] - eps <= d <= gp.mirror_distance[1] + eps
        angle = np.degrees(np.arccos(n[2]))
        assert gp.mirror_angle_deg[0] - 1e-6 <= angle <= gp.mirror_angle_deg[1] + 1e-6
        assert s.K[0, 0] == s.K[1, 1] == p["focal_px"]
        assert gp.focal_px[0] <= p["focal_px"] <= gp.focal_px[1]
        assert gp.person_to_mirror[0] - eps <= p["person_to_mirror"] <= gp.person_to_mirror[1] + eps
        assert gp.camera_height[0] - eps <= p["camera_height"] <= gp.camera_height[1] + eps
        if gp.parallax_deg is not None:
            assert gp.parallax_deg[0] - eps <= p["parallax_deg"] <= gp.parallax_deg[1] + eps
        # a vertical mirror (up to its lean) in the world the tilted camera sees
        n_world = p["R_world"].T @ n
        assert abs(n_world[1]) <= np.sin(np.radians(gp.mirror_lean_deg)) + 1e-9
        # valid: person and reflection inside the image, in front of the camera, the
        # person between the camera and the mirror
        w, h = s.image_size
        m = p["margin_px"]
        for uv in (s.real_clean, s.mirror_clean):
            assert uv[..., 0].min() >= m - 1e-6 and uv[..., 0].max() <= w - m + 1e-6
            assert uv[..., 1].min() >= m - 1e-6 and uv[..., 1].max() <= h - m + 1e-6
        S = s.reflect(X)
        assert X[..., 2].min() >= 0.5 - eps and S[..., 2].min() >= 0.5 - eps
        assert (X @ n).min() >= -eps and (X @ n).max() <= d - 0.2 + eps
        # the reflection tall enough to be detected
        height_px = np.ptp(s.mirror_clean[..., 1], axis=1).max()
        assert height_px >= 0.5 * gp.min_reflection_px


def _stats(scenes):
    return np.array([[st["epipole_px"], st["ray_deg_median"], st["ray_deg_p5"]]
                     for st in map(scene_geometry_stats, scenes)])


def test_presets_reach_the_fixtures_regime(preset_scenes):
    """The independent generator's scenes sit ~300 px from the epipole with rays ~25 deg
    apart (5th percentile 4-9 deg); the favourable scenes ~2000 px and ~70 deg."""
    fav = _stats([make_scene(frames=120, seed=s) for s in range(6)])
    assert np.median(fav[:, 0]) > 1000 and np.median(fav[:, 1]) > 50
    gym, wide, low = (_stats(preset_scenes[g]) for g in ("gym", "wide", "low_parallax"))
    assert np.median(gym[:, 0]) < 700 and np.median(gym[:, 1]) < 45
    assert (low[:, 0] < 400).all() and (low[:, 1] < 25).all() and (low[:, 2] < 10).all()
    # the wide ranges span both regimes
    assert wide[:, 0].min() < 500 and wide[:, 0].max() > 1200
    inside = np.concatenate([gym, low])
    regime = (inside[:, 0] < 450) & (inside[:, 1] < 35) & (inside[:, 2] < 12)
    assert regime.sum() >= 4


@pytest.mark.skipif(not FIXTURES.is_dir(), reason=f"no fixtures in {FIXTURES}")
def test_fixtures_lie_within_the_presets(preset_scenes):
    import mirrorgraph as mg
    from mirrorgraph.io import read_keypoints

    ours = _stats(preset_scenes["gym"] + preset_scenes["low_parallax"])
    for folder in sorted(FIXTURES.glob("scene_*")):
        truth = json.loads((folder / "truth.json").read_text())
        K = mg.load_intrinsics(folder / "camera.json").K
        raw = read_keypoints(folder / "keypoints.json")
        n = np.asarray(truth["normal"])
        u, v = pair_by_epipole(raw.people, K, n, raw.skeleton.flip, raw.skeleton.calibration_joints)
        st = geometry_stats(K, n, u, v)
        assert st["pairs"] > 5000
        for k, key in enumerate(("epipole_px", "ray_deg_median", "ray_deg_p5")):
            assert ours[:, k].min() <= st[key] <= ours[:, k].max(), (folder.name, key)


def test_outliers_along_the_epipolar_line():
    s = make_scene(frames=200, seed=3, geometry="gym", noise_std=0.0, noise_mean=0.0,
                   epipolar_outlier_rate=0.2)
    moved = np.stack([s.epipolar_outlier_mask_real, s.epipolar_outlier_mask_mirror])
    assert 0.15 < moved.mean() < 0.25
    assert (s.outlier_mask_real >= s.epipolar_outlier_mask_real).all()
    assert (s.outlier_mask_mirror >= s.epipolar_outlier_mask_mirror).all()
    obs = np.stack([s.real_observed[..., :2], s.mirror_observed[..., :2]])
    clean = np.stack([s.real_clean, s.mirror_clean])
    shift = np.linalg.norm(obs - clean, axis=-1)
    assert shift[moved].min() >= EPIPOLAR_OUTLIER_PX[0] - 1e-6
    assert shift[moved].max() <= EPIPOLAR_OUTLIER_PX[1] + 1e-6
    assert shift[~moved].max() < 1e-9
    # still on the epipolar line: no epipolar test can reject them ...
    e = geo.epipole_from_normal(s.K, s.normal)
    epi = geo.epipolar_distances(e, obs[0], obs[1])
    assert epi[moved.any(0)].max() < 1e-6
    # ... but the depth triangulated from them is wrong
    X = geo.triangulate_mirror(s.K, s.normal, s.distance, obs[0], obs[1])
    err = np.linalg.norm(X - s.joints3d, axis=-1)
    assert np.median(err[moved.any(0)]) > 0.1 and err[moved.any(0)].min() > 0.01
    assert err[~moved.any(0)].max() < 1e-6
    # confidences of outliers: lower on average
    conf = np.stack([s.real_observed[..., 2], s.mirror_observed[..., 2]])
    assert conf[moved].mean() < conf[~moved].mean() - 0.1


def test_left_right_swaps_in_both_views():
    kw = dict(frames=600, seed=2, geometry="gym", noise_std=0.0, noise_mean=0.0, lr_swap_rate=0.2)
    one, both = make_scene(**kw), make_scene(lr_swap_views="both", **kw)
    assert not one.lr_swapped_real.any() and one.lr_swapped.any()
    assert np.array_equal(one.lr_swapped, both.lr_swapped)       # the reflection's draw kept
    assert 0.12 < both.lr_swapped_real.mean() < 0.28 and 0.12 < both.lr_swapped.mean() < 0.28
    assert (both.lr_swapped & both.lr_swapped_real).any()
    flip = both.skeleton.flip
    # the detector's rows: the person's labels swapped exactly in those frames
    for t in range(len(both)):
        want = both.real_observed[t][flip] if both.lr_swapped_real[t] else both.real_observed[t]
        assert any(np.array_equal(p, want, equal_nan=True) for p in both.detections.people[t])
    raw = both.paired(fix_lr=False)
    changed = ~np.all(np.isclose(raw.real, both.real_observed, equal_nan=True), axis=(1, 2))
    assert np.array_equal(changed, both.lr_swapped_real)
    fixed = both.paired()
    assert np.array_equal(fixed.real, both.real_observed, equal_nan=True)
    assert fixed.lr_fixes == int((both.lr_swapped ^ both.lr_swapped_real).sum())
    with pytest.raises(ValueError, match="lr_swap_views"):
        make_scene(frames=10, lr_swap_views="left")


def test_shared_bias_follows_the_detector_label():
    s = make_scene(frames=50, seed=4, noise_std=0.0, noise_mean=0.0, joint_bias_px=3.0,
                   joint_bias_shared=True)
    b_real = s.real_observed[..., :2] - s.real_clean             # (T, J, 2)
    b_mirror = s.mirror_observed[..., :2] - s.mirror_clean
    assert np.allclose(b_real, b_real[:1]) and np.allclose(b_mirror, b_mirror[:1])
    flip = s.skeleton.flip
    assert np.allclose(b_mirror[0], b_real[0][flip] * np.array([-1.0, 1.0]))
    assert 1.0 < np.std(b_real[0]) < 6.0


def test_wide_scenes_are_reproducible_and_draw_the_detector():
    a = make_wide_scene(4, "wide", "realistic", frames=100)
    b = make_wide_scene(4, "wide", "realistic", frames=100)
    assert np.array_equal(a.real_observed, b.real_observed, equal_nan=True)
    spec = DETECTORS["realistic"]
    for key in ("noise_correlation", "joint_bias_px"):
        lo, hi = spec[key]
        assert lo <= a.options[key] <= hi
    assert a.options["lr_swap_views"] == "both" and a.options["epipolar_outlier_rate"] == 0.05
    assert a.epipolar_outlier_mask_real.mean() > 0.02
    c = make_wide_scene(4, "favourable", "iid", frames=100)
    assert "geometry" not in c.options and c.options["noise_std"] == 4.0


@pytest.mark.parametrize("kind", ["2cams1mirror", "1cam2mirrors", "4cams"])
def test_rig_geometries(kind):
    g = RIG_PRESETS["wide"]
    for seed in range(2):
        rig = make_rig(kind, frames=40, seed=seed, geometry="wide")
        assert rig.options["geometry"] == "wide"
        assert all(g.focal_px[0] <= K[0, 0] == K[1, 1] <= g.focal_px[1] for K in rig.K)
        for cname, P in zip(rig.camera_names, rig.poses):
            for mname in rig.sees[cname]:
                n, d = rig.mirrors[rig.mirror_names.index(mname)]
                dist = abs(d - n @ P[:3, 3])
                assert g.camera_to_mirror[0] - 1e-9 <= dist <= g.camera_to_mirror[1] + 1e-9
        if kind == "2cams1mirror":
            lo, hi = g.person_to_mirror
            assert lo <= rig.placement["person_to_mirror_m"] <= hi
    a, b = make_rig(kind, frames=30, seed=1), make_rig(kind, frames=30, seed=1,
                                                        geometry="favourable")
    assert np.array_equal(a.joints3d, b.joints3d) and "geometry" not in a.options


def test_ray_angles_from_pixels_match_the_3d_rays():
    from mirrorgraph.synth.geometry import parallax_deg, ray_angles_deg

    s = make_scene(frames=40, seed=3, geometry="wide")
    X = s.joints3d.reshape(-1, 3)
    px = ray_angles_deg(s.K, s.normal, s.real_clean.reshape(-1, 2), s.mirror_clean.reshape(-1, 2))
    assert np.allclose(px, parallax_deg(X, s.normal, s.distance), atol=1e-9)
    st = scene_geometry_stats(s)
    e = geo.epipole_pixels(geo.epipole_from_normal(s.K, s.normal))
    cal = s.skeleton.calibration_joints
    assert st["epipole_px"] == pytest.approx(
        np.median(np.linalg.norm(s.real_clean[:, cal] - e, axis=-1)))
