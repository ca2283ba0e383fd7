"""Tests of the BVH reader and its forward kinematics (mirrorgraph.io.bvh)."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.io.bvh import parse_bvh, read_bvh, slerp_matrices
from mirrorgraph.synth.mocap import CMU_UNIT_M, cmu_example_path


@pytest.fixture(scope="module")
def cmu():
    return read_bvh(cmu_example_path())


def test_cmu_take_is_parsed(cmu):
    assert cmu.frames == 2752 and cmu.fps == 120.0
    assert len(cmu.joint_names) == 31
    for name in ("Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
                 "RightUpLeg", "Spine", "Spine1", "Neck", "Neck1", "Head", "LeftShoulder",
                 "LeftArm", "LeftForeArm", "LeftHand", "RightHand"):
        assert cmu.has(name), name
    assert cmu.channels[0] == ("Xposition", "Yposition", "Zposition", "Zrotation",
                               "Yrotation", "Xrotation")
    assert cmu.values.shape == (2752, 6 + 30 * 3)
    # the thigh: 7.16 CMU units = 0.40 m, at every frame
    P = cmu.positions()
    thigh = np.linalg.norm(P[:, cmu.index("LeftLeg")] - P[:, cmu.index("LeftUpLeg")], axis=-1)
    assert thigh * CMU_UNIT_M == pytest.approx(np.full(2752, 0.404), abs=0.002)
    assert np.ptp(thigh) < 1e-9


# --------------------------------------------------------------------------- a tiny file
TINY = """\
HIERARCHY
ROOT Root
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT A
\t{
\t\tOFFSET 1 0 0
\t\tCHANNELS 3 Xrotation Yrotation Zrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 2 0 0
\t\t}
\t}
\tJOINT B {
\t\tOFFSET 0 0 3
\t\tCHANNELS 1 yrotation
\t\tEnd Site { OFFSET 1 0 0 }
\t}
}
MOTION
Frames: 2
Frame Time: 0.5
0 0 0 0 0 0 0 0 0 0
10 20 30 90 0 0 90 90 0 90
"""


def test_tiny_bvh_forward_kinematics_by_hand():
    m = parse_bvh(TINY, source="tiny.bvh")
    assert m.names == ("Root", "A", "A_EndSite", "B", "B_EndSite")
    assert list(m.parents) == [-1, 0, 1, 0, 3]
    assert m.channels[3] == ("Yrotation",) and m.fps == 2.0 and m.frames == 2
    P, G = m.forward_kinematics()
    rest = np.array([[0, 0, 0], [1, 0, 0], [3, 0, 0], [0, 0, 3], [1, 0, 3]], float)
    assert np.allclose(P[0], rest) and np.allclose(m.rest_positions(), rest)
    # frame 1: root at (10, 20, 30) turned 90 deg about z (x -> y, y -> -x).
    # A = root + Rz (1, 0, 0); A's tip = A + Rz Rx Ry (2, 0, 0): Ry takes it to
    # (0, 0, -2), Rx to (0, 2, 0), Rz to (-2, 0, 0) (intrinsic order as listed).
    # B = root + Rz (0, 0, 3); B's tip = B + Rz Ry (1, 0, 0) = B + (0, 0, -1).
    want = np.array([[10, 20, 30], [10, 21, 30], [8, 21, 30], [10, 20, 33], [10, 20, 32]],
                    float)
    assert np.allclose(P[1], want, atol=1e-12)
    for R in G[1]:
        assert np.allclose(R @ R.T, np.eye(3)) and np.linalg.det(R) == pytest.approx(1.0)
    # resampling at 4 fps: the middle sample turns every joint half way (slerp)
    P4, G4 = m.resample(4.0)
    assert len(P4) == 3 and np.allclose(P4[[0, 2]], P)
    assert np.allclose(P4[1, 0], [5, 10, 15])
    c = np.cos(np.pi / 4)
    assert np.allclose(G4[1, 0], [[c, -c, 0], [c, c, 0], [0, 0, 1]])   # Rz(45 deg)
    tip = P4[1, 2] - P4[1, 1]
    assert np.linalg.norm(tip) == pytest.approx(2.0)     # rigid, not a chord


@pytest.mark.parametrize("edit, line, words", [
    (("OFFSET 1 0 0", "OFFSET 1 zero 0"), 8, "expected a number"),
    (("CHANNELS 1 yrotation", "CHANNELS 1 Wrotation"), 17, "unknown channel"),
    (("CHANNELS 3 Xrotation", "CHANNELS 4 Xrotation"), 10, "declares 4"),
    (("0 0 0 0 0 0 0 0 0 0", "0 0 0 0 0 0 0 0 0"), 24, "has 9 values"),
    (("10 20 30 90 0 0 90 90 0 90", "10 20 30 90 0 0 90 x 0 90"), 25, "not a number"),
    (("Frames: 2", "Frames: 3"), 25, "only 2 frame lines"),
    (("0 0 0 0 0 0 0 0 0 0\n10 20 30 90 0 0 90 90 0 90",
      "0 0 0 0 0 0 0 0 0\n10 20 30 90 0 0 90 90 0 90 0"), 24, "has 9 values"),
    (("10 20 30 90 0 0 90 90 0 90", "10 20 30 90 0 0 90 nan 0 90"), 25, "not finite"),
    (("Frame Time: 0.5", "Frame Time: -1"), 23, "positive"),
    (("MOTION\n", ""), 21, "expected 'ROOT' or 'MOTION'"),
    (("\t}\n}\nMOTION", "\t}\nMOTION"), 19, "expected '}'"),
    (("JOINT B {", "JOINT A {"), 15, "used twice"),
    (("HIERARCHY", "HIERARCHIES"), 1, "HIERARCHY"),
])
def test_malformed_bvh_names_file_and_line(tmp_path, edit, line, words):
    old, new = edit
    assert old in TINY
    path = tmp_path / "bad.bvh"
    path.write_text(TINY.replace(old, new, 1))
    with pytest.raises(InputError) as info:
        read_bvh(path)
    msg = str(info.value)
    assert str(path) in msg and f"line {line}:" in msg and words in msg, msg


def test_missing_or_empty_file(tmp_path):
    with pytest.raises(InputError, match="no such BVH file"):
        read_bvh(tmp_path / "nope.bvh")
    empty = tmp_path / "empty.bvh"
    empty.write_text("")
    with pytest.raises(InputError, match="empty"):
        read_bvh(empty)


def test_slerp_turns_a_fraction_of_the_way_on_the_shortest_arc():
    rng = np.random.default_rng(3)
    from scipy.spatial.transform import Rotation
    R0 = Rotation.random(50, random_state=rng).as_matrix()
    w = rng.normal(size=(50, 3))
    w *= (rng.uniform(0.0, np.pi - 1e-3, 50) / np.linalg.norm(w, axis=1))[:, None]
    R1 = R0 @ Rotation.from_rotvec(w).as_matrix()
    u = rng.uniform(0, 1, 50)
    want = R0 @ Rotation.from_rotvec(w * u[:, None]).as_matrix()
    assert np.allclose(slerp_matrices(R0, R1, u), want, atol=1e-9)
    assert np.allclose(slerp_matrices(R0, R1, 0.0), R0, atol=1e-12)
    assert np.allclose(slerp_matrices(R0, R1, 1.0), R1, atol=1e-9)
    # broadcasting over joints: (T, J, 3, 3) with a (T, 1) fraction
    out = slerp_matrices(R0.reshape(5, 10, 3, 3), R1.reshape(5, 10, 3, 3), u[:5, None])
    assert out.shape == (5, 10, 3, 3)
    assert np.allclose(out[2, 7], R0[27] @ Rotation.from_rotvec(w[27] * u[2]).as_matrix())
