"""The joints a rig's graph left out, triangulated with the solved rig
(mirrorgraph.completion.complete_rig_joints) and compared with the synthetic truth.

Each test gives :func:`complete_joints` a rig solved exactly (the true camera poses and
mirror planes of :func:`mirrorgraph.synth.make_rig`) whose graph estimated the limbs only,
as ``joints = "limbs"`` does; the face and the feet are left to the completion. The
observations are the detector's (4 px noise), in the rig's real-joint labels.
"""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.completion import complete_rig_joints as complete_joints
from mirrorgraph.rigs.observations import CameraObservations, RigObservations
from mirrorgraph.pipelines.solve import RigSolution
from mirrorgraph.synth.rig import KINDS, PERSON, make_rig

FRAMES = 120
THRESHOLD_PX = 20.0      # RefineOptions().outlier_threshold, the rig pipeline's default


def _observations(rig) -> RigObservations:
    """Every camera's person and reflections as the rig's sorted observations."""
    cams = []
    for name in rig.camera_names:
        views = rig.views[name]
        cams.append(CameraObservations(
            name=name, intrinsics=rig.intrinsics(name), real=views[PERSON].observed.copy(),
            reflections={m: views[m].observed.copy() for m in rig.sees[name]}))
    return RigObservations(skeleton=rig.skeleton, frame_ids=rig.frame_ids, cameras=cams,
                           mirrors=tuple(rig.mirror_names))


def _limbs_only(rig) -> RigSolution:
    """The true rig, with the graph's joints = the limbs (at their true positions)."""
    used = np.zeros(rig.joints3d.shape[:2], dtype=bool)
    used[:, rig.skeleton.calibration_joints] = True
    return RigSolution(poses=[np.asarray(P, float) for P in rig.poses],
                       planes=[(np.asarray(n, float), float(d)) for n, d in rig.mirrors],
                       mirror_names=list(rig.mirror_names), camera_cov=[], plane_cov=[],
                       plane_basis=[], points=np.where(used[..., None], rig.joints3d, np.nan),
                       used=used, view_names=[], view_rms_px=[], view_counts=[],
                       view_observed=[], bone_lengths={}, rejected=0, iterations=0,
                       priors={}, timings={})


def _left_out(rig) -> np.ndarray:
    return np.setdiff1d(np.arange(rig.skeleton.num_joints), rig.skeleton.calibration_joints)


def _views_seeing(obs: RigObservations) -> np.ndarray:
    """``(T, J)`` number of views (direct and through mirrors) that detected each joint."""
    count = 0
    for cam in obs.cameras:
        for kp in [cam.real, *cam.reflections.values()]:
            count = count + (np.isfinite(kp[..., :2]).all(-1) & (kp[..., 2] > 0))
    return count


@pytest.fixture(scope="module", params=KINDS)
def rig(request):
    return make_rig(request.param, frames=FRAMES, seed=1, noise_std=4.0)


def test_left_out_joints_are_completed_near_the_truth(rig):
    obs, sol = _observations(rig), _limbs_only(rig)
    out = complete_joints(obs, sol, THRESHOLD_PX)
    face_feet = _left_out(rig)
    assert len(face_feet) >= 5                      # BODY_25: nose, eyes, ears, feet
    seen_twice = _views_seeing(obs)[:, face_feet] >= 2
    filled = out.used[:, face_feet]
    assert not (filled & ~seen_twice).any()         # two views at least
    assert filled[seen_twice].mean() > 0.95
    err = np.linalg.norm(out.points[:, face_feet] - rig.joints3d[:, face_feet], axis=-1)[filled]
    assert np.isfinite(err).all()
    assert np.median(err) < 0.02                    # metres, 4 px noise at 3-7 m
    assert np.percentile(err, 99) < 0.06
    # every left-out joint gets its 3D point, not only the easy ones
    for k, j in enumerate(face_feet):
        assert filled[:, k].sum() > 0.8 * seen_twice[:, k].sum(), rig.skeleton.joints[j]


def test_the_graph_joints_are_left_as_they_are(rig):
    obs, sol = _observations(rig), _limbs_only(rig)
    out = complete_joints(obs, sol, THRESHOLD_PX)
    assert np.array_equal(out.used[sol.used], sol.used[sol.used])
    assert np.array_equal(out.points[sol.used], sol.points[sol.used])
    # the rig is not touched: completion takes no part in the calibration
    for P, Q in zip(out.poses, sol.poses):
        assert np.array_equal(P, Q)
    assert all(np.array_equal(a[0], b[0]) and a[1] == b[1] for a, b in zip(out.planes, sol.planes))


def test_a_complete_solution_is_returned_unchanged(rig):
    obs = _observations(rig)
    full = _limbs_only(rig)
    full.used[:] = True
    full.points = rig.joints3d.copy()
    assert complete_joints(obs, full, THRESHOLD_PX) is full


def test_a_joint_seen_in_one_view_only_stays_missing():
    rig = make_rig("2cams1mirror", frames=FRAMES, seed=1, noise_std=4.0)
    obs, sol = _observations(rig), _limbs_only(rig)
    nose = rig.skeleton.index("nose")
    frames = np.arange(0, FRAMES, 3)
    # hide the nose from every view but camera 1's direct one in a third of the frames
    for i, cam in enumerate(obs.cameras):
        for kp in ([] if i == 0 else [cam.real]) + list(cam.reflections.values()):
            kp[frames, nose] = [np.nan, np.nan, 0.0]
    out = complete_joints(obs, sol, THRESHOLD_PX)
    assert not out.used[frames, nose].any()
    assert np.isnan(out.points[frames, nose]).all()
    others = np.setdiff1d(np.arange(FRAMES), frames)
    assert out.used[others, nose].mean() > 0.95


def test_outliers_are_rejected_before_the_final_triangulation():
    """10 % of the detections are gross errors (30-150 px): the round of rejection at the
    outlier threshold keeps the completed joints near the truth, where one triangulation
    of every view would be decimetres off."""
    rig = make_rig("4cams", frames=FRAMES, seed=2, noise_std=4.0, outlier_rate=0.1)
    obs, sol = _observations(rig), _limbs_only(rig)
    face_feet = _left_out(rig)

    def errors(threshold):
        out = complete_joints(obs, sol, threshold)
        filled = out.used[:, face_feet]
        err = np.linalg.norm(out.points[:, face_feet] - rig.joints3d[:, face_feet], axis=-1)
        return err[filled], filled

    robust, filled = errors(THRESHOLD_PX)
    plain, everything = errors(np.inf)             # nothing rejected
    assert filled.mean() > 0.7 and everything.mean() > filled.mean()
    assert np.percentile(robust, 90) < 0.04
    assert np.percentile(robust, 90) < 0.4 * np.percentile(plain, 90)
    assert np.median(robust) < 0.02
