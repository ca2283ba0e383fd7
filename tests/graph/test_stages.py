"""The solve driver's joints pass: the observations the body exposes are left out."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.graph import RefineOptions, stages
from mirrorgraph.graph.outliers import one_view_outliers
from mirrorgraph.metrics import pa_mpjpe
from mirrorgraph.pipelines.solve import refine_mirror
from mirrorgraph.synth import make_scene


def test_one_view_outliers_leave_every_joint_an_observation():
    nan = np.nan
    direct = np.array([[3.0, 25.0, 30.0, nan, 50.0]])
    mirror = np.array([[4.0, 5.0, 40.0, 60.0, nan]])
    d, m = one_view_outliers([direct, mirror], 20.0)
    # under the threshold: kept; one view over: that view; both over: the worse one
    # only; a joint seen once over it: that view (the joint keeps its other one: none
    # here, which the rig's masks decide, not this rule)
    assert d.tolist() == [[False, True, False, False, True]]
    assert m.tolist() == [[False, False, True, True, False]]
    assert not (d & m).any()


def _scene(seed: int):
    sc = make_scene(frames=240, seed=seed, noise_std=4.0, epipolar_outlier_rate=0.08)
    return sc, sc.paired()


@pytest.mark.parametrize("seed", [0, 1])
def test_the_joints_pass_leaves_out_keypoints_displaced_along_their_epipolar_line(
        seed, monkeypatch):
    """A keypoint moved along its epipolar line fits both views with its joint slid in
    depth; once the joints pass holds the joint with every bone and the smoothness its
    residual shows and it is left out: most of the observations left out are displaced
    ones, and the joints they touched come closer to the truth than with them kept."""
    sc, p = _scene(seed)
    rows = np.searchsorted(sc.frame_ids, p.frame_ids)
    truth = sc.joints3d[rows]
    displaced = np.stack([sc.epipolar_outlier_mask_real, sc.epipolar_outlier_mask_mirror])[:, rows]
    assert displaced.any()
    opts = RefineOptions(subject_height=sc.subject_height)
    seen = []
    gate = stages.one_view_outliers

    def spy(residuals, threshold):
        out = gate(residuals, threshold)
        seen.append(np.stack(out))
        return out

    monkeypatch.setattr(stages, "one_view_outliers", spy)
    gated = refine_mirror(p, sc.K, sc.normal, p.valid(), options=opts)
    assert len(seen) == 1
    dropped = seen[0]
    assert dropped.sum() >= 10
    assert (dropped & displaced).sum() >= 0.8 * dropped.sum()

    monkeypatch.setattr(stages, "one_view_outliers",
                        lambda residuals, threshold: [np.zeros_like(r, bool) for r in residuals])
    kept = refine_mirror(p, sc.K, sc.normal, p.valid(), options=opts)
    touched = displaced.any(0) & gated.valid & kept.valid
    err = [np.linalg.norm(r.joints3d - truth, axis=-1)[touched] for r in (gated, kept)]
    assert np.median(err[0]) < 0.8 * np.median(err[1]), [np.median(e) for e in err]
    both = gated.valid & kept.valid
    assert pa_mpjpe(gated.joints3d, truth, both) < pa_mpjpe(kept.joints3d, truth, both)


def test_without_observations_drops_exactly_their_factors():
    """The reprojection factors left are those of the observations kept: the graph's error
    at a point moved off one observation loses exactly that observation's term."""
    import gtsam

    from mirrorgraph.graph.builder import build_problem
    from mirrorgraph.graph.problem import X_BASE, without_observations
    from mirrorgraph.graph.rig import single_mirror_rig

    sc = make_scene(frames=12, seed=3, noise_std=0.0)
    p = sc.paired()
    sk = p.skeleton
    used = p.valid()
    rig = single_mirror_rig(sk, p.frame_ids, sc.K, p.real[..., :2], p.mirror[..., :2], used,
                            sc.normal, sc.distance, sk.calibration_joints)
    jm = np.zeros(sk.num_joints, bool)
    jm[sk.calibration_joints] = True
    rows = np.searchsorted(sc.frame_ids, p.frame_ids)
    problem = build_problem(rig, sc.joints3d[rows], used & jm, [(sc.normal, sc.distance)],
                            RefineOptions(), priors=False)
    T, J = problem.used.shape
    t, j = 5, int(sk.calibration_joints[3])
    drop = [np.zeros((T, J), bool), np.zeros((T, J), bool)]
    drop[1][t, j] = True                                   # the reflection's observation
    out = without_observations(problem, drop)
    assert out.reprojection.size() == problem.reprojection.size() - 1
    assert not out.rig.views[1].mask[t, j] and out.rig.views[0].mask[t, j]
    assert problem.rig.views[1].mask[t, j]                 # the problem itself unchanged
    # the joint moved: both views' terms grow in the full graph, only the direct one here
    values = gtsam.Values(problem.values)
    key = int(X_BASE) + t * J + j
    moved = values.atPoint3(key) + np.array([0.05, 0.0, 0.0])
    values.erase(key)
    values.insertPoint3(key, moved)
    grown = float(problem.reprojection.error(values)) - float(
        problem.reprojection.error(problem.values))
    kept = float(out.reprojection.error(values)) - float(out.reprojection.error(problem.values))
    assert 0.0 < kept < grown
    # the one factor left on that joint is the direct view's (the point's key alone; a
    # reflection's factor also holds the virtual camera's pose)
    on = [out.reprojection.at(i).keys() for i in range(out.reprojection.size())
          if key in out.reprojection.at(i).keys()]
    assert len(on) == 1 and list(on[0]) == [key]
    with pytest.raises(ValueError):
        without_observations(problem, [np.zeros((T, J), bool)])
