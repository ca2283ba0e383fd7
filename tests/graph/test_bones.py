"""Bone lengths measured from triangulated joints, against the synthetic body's own."""

from __future__ import annotations

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.errors import InputError
from mirrorgraph.graph import RefineOptions
from mirrorgraph.graph.bones import bone_table, integrated_bone_lengths
from mirrorgraph.graph.rig import single_mirror_rig, triangulate_rig
from mirrorgraph.synth import make_wide_scene

PIXEL_SIGMA = 4.0      # the generator's iid detector noise, px


def _undistorted(intr, uv: np.ndarray) -> np.ndarray:
    if not intr.has_distortion:
        return uv
    flat = uv.reshape(-1, 2).copy()
    ok = np.isfinite(flat).all(1)
    flat[ok] = intr.undistort_points(flat[ok])
    return flat.reshape(uv.shape)


def _triangulated(seed: int, geometry: str, frames: int):
    """A scene's joints triangulated with its true mirror, and the estimator's inputs."""
    sc = make_wide_scene(seed, geometry, "iid", frames)
    intr = sc.intrinsics
    real = _undistorted(intr, np.where(sc.missing_real[..., None], np.nan,
                                       sc.real_observed[..., :2].astype(float)))
    mirror = _undistorted(intr, np.where(sc.missing_mirror[..., None], np.nan,
                                         sc.mirror_observed[..., :2].astype(float)))
    mask = np.isfinite(real).all(-1) & np.isfinite(mirror).all(-1)
    rig = single_mirror_rig(sc.skeleton, sc.frame_ids, intr.K, real, mirror, mask, sc.normal,
                            sc.distance, np.arange(sc.skeleton.num_joints))
    planes = [(np.asarray(sc.normal, float), float(sc.distance))]
    tri, ok = triangulate_rig(rig, [v.mask for v in rig.views], [rig.cameras[0].pose], planes)
    names, pairs = bone_table(rig)
    row = {n: i for i, n in enumerate(names)}
    partners = np.full(len(names), -1)
    for left, right in sc.skeleton.symmetric_bones:
        partners[row[left]], partners[row[right]] = row[right], row[left]
    true = np.median(np.linalg.norm(sc.joints3d[:, pairs[:, 0]] - sc.joints3d[:, pairs[:, 1]],
                                    axis=-1), axis=0)
    return dict(rig=rig, tri=tri, ok=ok, planes=planes, names=names, pairs=pairs,
                partners=partners, true=true, skeleton=sc.skeleton)


def _ratios(s: dict, ok: np.ndarray | None = None, partners: bool = True) -> dict[str, float]:
    est = integrated_bone_lengths(s["rig"], s["tri"], s["ok"] if ok is None else ok, s["planes"],
                                s["pairs"], PIXEL_SIGMA,
                                partners=s["partners"] if partners else None)
    return dict(zip(s["names"], est / s["true"]))


def test_lengths_at_low_parallax_match_the_body():
    """The person near the camera-mirror line (rays a few degrees apart, depth noise as
    long as a bone): every bone, left and right, within 8 % of its length, the limbs'
    mean within 2 %; a moment estimate (the mean of ``|d|^2 - tr S``) gave a thigh 29 %
    short there and no length for three bones."""
    ratio = _ratios(_triangulated(0, "low_parallax", 300))
    assert all(np.isfinite(v) for v in ratio.values()), ratio
    assert max(abs(v - 1.0) for v in ratio.values()) < 0.08, ratio
    limbs = [v for b, v in ratio.items() if b.startswith(("left_", "right_"))]
    assert abs(np.mean(limbs) - 1.0) < 0.02, ratio


def test_lengths_at_wide_parallax_stay_exact():
    """Where every joint is well triangulated the lengths are the body's to 3 %, each
    bone measured alone as well as with its partner."""
    s = _triangulated(0, "wide", 300)
    for partners in (True, False):
        ratio = _ratios(s, partners=partners)
        assert max(abs(v - 1.0) for v in ratio.values()) < 0.03, (partners, ratio)


def test_a_bone_seen_in_too_few_frames_takes_its_partners_length():
    """A left forearm seen in 5 frames (under ``min_frames``) takes the right one's
    length, the body's to 2 %; measured alone it has none."""
    s = _triangulated(0, "wide", 300)
    ok = s["ok"].copy()
    ok[5:, s["skeleton"].joints.index("left_wrist")] = False
    paired = _ratios(s, ok)
    assert paired["left_ulna"] == paired["right_ulna"]
    assert abs(paired["left_ulna"] - 1.0) < 0.02, paired
    assert np.isnan(_ratios(s, ok, partners=False)["left_ulna"])


def test_metric_scale_under_a_biased_detector_at_low_parallax():
    """The person on the camera-mirror line under the realistic detector (per-label
    bias, correlated noise): the joints pass's lengths set the body the stature is
    measured on, so with the integrated likelihood's lengths the run's metric scale
    (its joints against the true ones, one least-squares factor about the camera) is
    within 10 %; the moments' lengths made it 30 % short, every joint far off."""
    sc = make_wide_scene(9, "wide", "realistic", 1000, body_variation="population")
    opts = mg.CalibrateOptions(subject_height=float(sc.subject_height), fps=30.0,
                               refine_options=RefineOptions(joints_bone_lengths="integrated"))
    run = mg.calibrate(sc.detections, sc.intrinsics, opts)
    rows = {int(f): i for i, f in enumerate(sc.frame_ids)}
    keep = np.array([int(f) in rows for f in run.paired.frame_ids])
    X = run.joints3d[keep]
    truth = sc.joints3d[[rows[int(f)] for f in run.paired.frame_ids[keep]]]
    given = run.valid3d[keep] & np.isfinite(X).all(-1)
    fit = float((X[given] * truth[given]).sum() / (X[given] ** 2).sum())
    assert abs(1.0 / fit - 1.0) < 0.10, 1.0 / fit - 1.0


def test_an_unknown_bone_length_method_is_refused():
    with pytest.raises(InputError, match="joints_bone_lengths"):
        RefineOptions(joints_bone_lengths="median")


def test_the_watson_weights_are_the_exponentials():
    """The concentrations' weights by squaring are ``exp(kappa (c^2 - [kappa > 0]))``."""
    from mirrorgraph.graph.bones import WATSON_KAPPAS, _watson_weights

    u = np.linspace(0.0, 1.0, 101) ** 2
    want = np.exp(WATSON_KAPPAS[:, None] * (u[None] - (WATSON_KAPPAS[:, None] > 0)))
    got = _watson_weights(u, WATSON_KAPPAS)
    assert got.shape == (len(WATSON_KAPPAS), len(u))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0.0)
    odd = np.array([3.0, -0.5, 6.0, 0.0, 7.0])          # no power of two apart: exp each
    np.testing.assert_allclose(_watson_weights(u, odd),
                               np.exp(odd[:, None] * (u[None] - (odd[:, None] > 0))),
                               rtol=1e-12, atol=0.0)


def test_the_grid_on_a_subsample_brackets_the_same_peak(monkeypatch):
    """The coarse grid on :data:`~mirrorgraph.graph.bones.GRID_FRAMES` spread frames of
    each bone gives the lengths the grid on all of them gives (the peak searched on all
    frames either way; Brent's tolerance is ``1e-3`` of the length), at low parallax
    where the likelihood is widest."""
    from mirrorgraph.graph import bones

    s = _triangulated(1, "low_parallax", 400)
    sub = np.array(list(_ratios(s).values()))
    monkeypatch.setattr(bones, "GRID_FRAMES", 10_000)
    full = np.array(list(_ratios(s).values()))
    assert np.all(np.isfinite(sub))
    np.testing.assert_allclose(sub, full, rtol=3e-3)


def test_a_frame_likelihood_takes_one_length_a_frame():
    """The frames' log-densities at one length each (the grid's single call) are those
    of one call per length, and the quadrature's density integrates to one over a
    bone's extent: ``p(d | L)`` on a ball about the origin, uniform directions."""
    from mirrorgraph.graph.bones import WATSON_KAPPAS, _frame_log_likelihood

    rng = np.random.default_rng(3)
    z, r = rng.normal(0.0, 0.2, 6), np.abs(rng.normal(0.2, 0.1, 6))
    var_z, var_r = rng.uniform(1e-3, 1e-2, 6), rng.uniform(1e-5, 1e-4, 6)
    lengths = np.array([0.2, 0.3, 0.4])
    both = _frame_log_likelihood(np.repeat(lengths, 6), np.tile(z, 3), np.tile(r, 3),
                                 np.tile(var_z, 3), np.tile(var_r, 3), WATSON_KAPPAS)
    each = np.concatenate([_frame_log_likelihood(x, z, r, var_z, var_r, WATSON_KAPPAS)
                           for x in lengths])
    np.testing.assert_allclose(both, each, rtol=1e-12, atol=1e-12)
    # the uniform sphere (kappa 0): the density of d integrates to one (a grid in z, r)
    zz, rr = np.meshgrid(np.linspace(-0.6, 0.6, 241), np.linspace(1e-4, 0.6, 240),
                         indexing="ij")
    n = zz.size
    dens = np.exp(_frame_log_likelihood(0.3, zz.ravel(), rr.ravel(), np.full(n, 4e-3),
                                        np.full(n, 4e-3), np.array([0.0]))[:, 0])
    mass = np.sum(dens * 2.0 * np.pi * rr.ravel()) * (1.2 / 240) * (0.6 - 1e-4) / 239
    assert abs(mass - 1.0) < 0.02, mass
