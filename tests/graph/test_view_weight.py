"""A view's per-joint weight (:attr:`mirrorgraph.graph.rig.View.weight`) scales the
information of its reprojection terms and nothing else."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph import geometry as geo
from mirrorgraph.graph import Camera, Mirror, RefineOptions, Rig, View
from mirrorgraph.graph.builder import build_problem
from mirrorgraph.skeletons import COCO_17


def _error(weight):
    rng = np.random.default_rng(3)
    K = np.array([[1400.0, 0.0, 960.0], [0.0, 1400.0, 540.0], [0.0, 0.0, 1.0]])
    n, d = np.array([0.3, 0.0, 1.0]) / np.linalg.norm([0.3, 0.0, 1.0]), 4.0
    T, J = 10, COCO_17.num_joints
    pts = rng.uniform([-0.5, -0.7, 2.2], [0.5, 0.7, 2.8], size=(T, J, 3))
    mask = np.zeros((T, J), bool)
    mask[:, COCO_17.calibration_joints] = True
    direct = geo.project(K, pts) + rng.normal(scale=3.0, size=(T, J, 2))
    mirror = geo.project(K, geo.reflect_points(pts, n, d)) + rng.normal(scale=3.0, size=(T, J, 2))
    rig = Rig(cameras=(Camera("cam", K),), mirrors=(Mirror("m", n, d),),
              views=(View("direct", "cam", None, direct, mask, weight=weight),
                     View("m", "cam", "m", mirror, mask)),
              skeleton=COCO_17, frame_ids=np.arange(T), joints=COCO_17.calibration_joints)
    opts = RefineOptions(robust_kernel=None)
    problem = build_problem(rig, pts, mask, [(n, d)], opts, priors=False)
    # the direct view's own squared error, px, at the true joints
    r = (geo.project(K, pts) - direct)[mask]
    return problem.reprojection.error(problem.values), 0.5 * np.sum(r ** 2) / opts.pixel_sigma ** 2


def test_weight_scales_the_views_information():
    J = COCO_17.num_joints
    full, direct = _error(None)
    assert direct > 1.0
    quarter, _ = _error(np.full(J, 0.25))
    assert full - quarter == pytest.approx(0.75 * direct, rel=1e-9)
    # per joint: half of the columns at 0.25
    w = np.ones(J)
    w[::2] = 0.25
    mixed, _ = _error(w)
    assert quarter < mixed < full
    assert _error(np.ones(J))[0] == pytest.approx(full, rel=1e-12)
