"""The principal point without a camera matrix (issue 23), against ground truth.

A camera whose principal point lies 20 px off the image centre, calibrated from the
image size alone: the principal point is a variable of the graph with the spread of
real cameras as its prior, and the mirror's reported std holds the error the offset
causes, where holding it at the centre (the old assumption) gave a std a small
fraction of that error. Plus the pieces: the prior's information in the sandwich
(:func:`~mirrorgraph.graph.scores.intrinsics_prior_spread`) and the shares of a
rotation's variance (:func:`~mirrorgraph.graph.uncertainty.intrinsics_contributions`).
"""

import dataclasses

import numpy as np
import pytest

import mirrorgraph as mg
from mirrorgraph.intrinsics import Intrinsics
from mirrorgraph.metrics import mirror_rotation_error_deg
from mirrorgraph.synth import make_scene

OFFSET = np.array([20.0, -6.0])          # px: the camera's principal point off the centre


@pytest.fixture(scope="module")
def scene():
    """A favourable scene (focal 1100 px) seen by a camera whose principal point is
    ``OFFSET`` off the centre: a pinhole image moves rigidly with its principal point,
    so every keypoint of both views moves by the offset (exact without distortion)."""
    sc = make_scene(frames=300, seed=11, focal_px=1100.0)
    p = sc.paired()
    shift = np.r_[OFFSET, 0.0]
    p = dataclasses.replace(p, real=p.real + shift, mirror=p.mirror + shift)
    K = np.array(sc.K, dtype=float)
    K[:2, 2] += OFFSET
    return sc, p, K


def test_a_principal_point_20px_off_is_inside_the_std(scene):
    sc, p, K = scene
    opts = mg.CalibrateOptions(image_size=sc.image_size, subject_height=sc.subject_height)
    cal = mg.calibrate(p, None, opts).calibration
    err = mirror_rotation_error_deg(cal.normal, sc.normal)
    u = cal.uncertainty
    assert err <= u["rotation_90_deg"] and err < 2.0 * u["rotation_std_deg"]
    est = cal.intrinsics.estimated
    assert est["principal_point_estimated"]
    assert all(10.0 < s <= 19.3 for s in u["principal_point_std_px"])     # the prior's 19.2
    assert abs(cal.intrinsics.K[0, 2] - K[0, 2]) < 2.5 * u["principal_point_std_px"][0]
    assert abs(cal.intrinsics.K[0, 0] / K[0, 0] - 1) < 0.05
    assert set(u["contributions"]) == {"focal_length", "principal_point"}
    assert u["contributions"]["principal_point"] > 0.3
    # the distance's std holds the principal point too
    assert abs(cal.distance / sc.distance - 1) <= 2.5 * u["distance_std"] / cal.distance

    # the old assumption: the true focal length, the principal point held at the centre,
    # gives a std a small fraction of the error the offset causes
    centred = K.copy()
    centred[:2, 2] = np.asarray(sc.image_size, float) / 2
    held = mg.calibrate(p, Intrinsics(K=centred, dist=None, image_size=sc.image_size,
                                      source="true focal, centred"),
                        dataclasses.replace(opts, image_size=None)).calibration
    e_held = mirror_rotation_error_deg(held.normal, sc.normal)
    assert e_held > 0.5 and e_held > 4.0 * held.uncertainty["rotation_std_deg"]
    # and with the true intrinsics the known path is as it was: tight and right
    known = mg.calibrate(p, Intrinsics(K=K, dist=None, image_size=sc.image_size, source="truth"),
                         dataclasses.replace(opts, image_size=None)).calibration
    e_known = mirror_rotation_error_deg(known.normal, sc.normal)
    assert e_known < 0.2 and e_known <= known.uncertainty["rotation_90_deg"]
    assert "contributions" not in known.uncertainty


def test_shares_of_a_rotation_variance():
    from mirrorgraph.graph.uncertainty import intrinsics_contributions
    from gtsam.symbol_shorthand import K, P

    # a plane (3: the normal's two coordinates, the distance) with unit noise of its own,
    # moved by f in its first coordinate and by 2 cx in its second; f, cx, cy unit
    z_keys = [(P(0), 3), (K(0), 3)]
    Ax = np.zeros((3, 3))
    Ax[0, 0], Ax[1, 1] = 1.0, 2.0
    C = np.zeros((6, 6))
    C[:3, :3] = np.eye(3) + Ax @ Ax.T
    C[:3, 3:], C[3:, :3], C[3:, 3:] = Ax, Ax.T, np.eye(3)
    share = intrinsics_contributions(C, z_keys)
    # var(n0) = 1 + 1 (f), var(n1) = 1 + 4 (cx): f explains 1 of 7, the pp 4 of 7
    assert share["focal_length"] == pytest.approx(1 / 7)
    assert share["principal_point"] == pytest.approx(4 / 7)


def test_the_warning_names_what_dominates_the_std():
    from mirrorgraph.pipelines.judge import poor_mirror_cause

    n = np.array([0.0, np.sin(np.radians(40)), np.cos(np.radians(40))])   # 40 deg off axis
    u = {"contributions": {"focal_length": 0.8, "principal_point": 0.1}}
    assert poor_mirror_cause(u, n).startswith("the unknown focal length dominates it (")
    u = {"contributions": {"focal_length": 0.2, "principal_point": 0.7}}
    assert poor_mirror_cause(u, n).startswith("the unknown principal point")
    # the intrinsics a minor share: the geometry's measured causes, each when it holds
    u = {"contributions": {"focal_length": 0.2, "principal_point": 0.1}}
    assert "low parallax" in poor_mirror_cause(u, n, ray_angle_deg=9.0)
    square = np.array([0.0, np.sin(np.radians(8)), np.cos(np.radians(8))])
    assert "square-on (8 deg" in poor_mirror_cause(u, square, ray_angle_deg=30.0)
    edge = np.array([0.0, np.sin(np.radians(75)), np.cos(np.radians(75))])
    assert "edge-on (75 deg" in poor_mirror_cause(u, edge, ray_angle_deg=30.0)
    assert "too little motion" in poor_mirror_cause(u, n, ray_angle_deg=30.0, motion_px=4.0)
    assert "joint pairs disagree" in poor_mirror_cause(
        {"contributions": {}, "robust": {"chosen": "two_way"}}, n)
    # known intrinsics: no contributions at all, the geometry speaks
    assert "low parallax" in poor_mirror_cause({}, n, ray_angle_deg=12.0)


def test_a_long_video_without_intrinsics_keeps_their_uncertainty(scene, monkeypatch):
    """Above ``max_graph_frames`` the video is solved in chunks that hold the intrinsics a
    spread subset estimated: what their uncertainty brings to the mirror is added to the
    chunks' figures (it was not: the std of a held, guessed camera)."""
    import mirrorgraph.graph.solve as solve_module
    from mirrorgraph.graph import RefineOptions

    calls = []
    chunked = solve_module.solve_chunked
    monkeypatch.setattr(solve_module, "solve_chunked",
                        lambda *a, **k: calls.append(1) or chunked(*a, **k))
    sc, p, K = scene
    opts = mg.CalibrateOptions(image_size=sc.image_size, subject_height=sc.subject_height,
                               refine_options=RefineOptions(max_graph_frames=120, workers=1))
    cal = mg.calibrate(p, None, opts).calibration
    assert calls                                          # the chunked solve it is
    err = mirror_rotation_error_deg(cal.normal, sc.normal)
    u = cal.uncertainty
    # the principal point's 19 px at f = 1100 px alone turn the virtual camera by ~1 deg
    assert u["rotation_std_deg"] > 0.7
    assert err <= u["rotation_90_deg"]
