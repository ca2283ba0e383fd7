"""The torso's distances (mirrorgraph.factors.torso): which pairs a skeleton gets, and the
range factor's residual and Jacobians against central differences."""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import X

from mirrorgraph.factors import TORSO_CORNERS, TorsoFactors, torso_pairs
from mirrorgraph.skeletons import BODY_25, COCO_17, people_skeleton


def _named(sk, pairs):
    return {frozenset((sk.joints[a], sk.joints[b])) for a, b in pairs}


def test_coco_gets_the_sides_and_diagonals_not_the_widths():
    pairs = torso_pairs(COCO_17.joints, COCO_17.bone_index)
    assert _named(COCO_17, pairs) == {
        frozenset(("left_shoulder", "left_hip")), frozenset(("right_shoulder", "right_hip")),
        frozenset(("left_shoulder", "right_hip")), frozenset(("right_shoulder", "left_hip"))}


def test_body25_has_no_width_bone_so_gets_all_six():
    pairs = torso_pairs(BODY_25.joints, BODY_25.bone_index)
    assert len(pairs) == 6
    assert all(set(p) <= set(TORSO_CORNERS) for p in _named(BODY_25, pairs))


def test_each_person_gets_their_own_and_a_missing_corner_none():
    sk = people_skeleton(COCO_17, 2)
    pairs = torso_pairs(sk.joints, sk.bone_index)
    assert len(pairs) == 8
    tags = {frozenset(n.partition("@")[2] for n in p) for p in _named(sk, pairs)}
    assert all(len(t) == 1 for t in tags)              # never across two people
    names = [n for n in COCO_17.joints if n != "right_hip"]
    assert len(torso_pairs(names, np.zeros((0, 2), int))) == 0


def test_residual_and_jacobians_match_central_differences():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=3), rng.normal(size=3) + 1.0
    L, sigma = 0.45, 0.03
    g = gtsam.NonlinearFactorGraph()
    TorsoFactors(sigma).add(g, np.array([X(0)]), np.array([X(1)]), np.array([L]))
    v = gtsam.Values()
    v.insertPoint3(X(0), a)
    v.insertPoint3(X(1), b)
    r = (np.linalg.norm(a - b) - L) / sigma
    assert np.isclose(g.error(v), 0.5 * r * r)
    lin = g.linearize(v).jacobian()[0]
    eps = 1e-6
    num = []
    for k in range(6):
        d = np.zeros(6)
        d[k] = eps
        p, m = np.concatenate([a, b]) + d, np.concatenate([a, b]) - d
        num.append((np.linalg.norm(p[:3] - p[3:]) - np.linalg.norm(m[:3] - m[3:]))
                   / (2 * eps) / sigma)
    assert np.allclose(np.abs(lin[0]), np.abs(num), atol=1e-6)
    r_np, Ja, Jb = TorsoFactors.evaluate(a[None], b[None], np.array([L]))
    assert np.isclose(r_np[0], r * sigma)
    assert np.allclose(Ja[0] / sigma, num[:3], atol=1e-6)
    assert np.allclose(Jb[0] / sigma, num[3:], atol=1e-6)
