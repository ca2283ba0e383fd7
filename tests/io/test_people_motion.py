"""Every person's 3D motion written (mirrorgraph.io.people_motion)."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.io.people_motion import person_paths, write_people_joints3d
from mirrorgraph.skeletons import COCO_17


@pytest.fixture
def motion():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(3, 20, COCO_17.num_joints, 3)) + [0.0, 0.0, 4.0]
    valid = rng.random((3, 20, COCO_17.num_joints)) > 0.1
    return X, valid


def test_npz_has_a_person_axis(tmp_path, motion):
    X, valid = motion
    path = tmp_path / "people.npz"
    assert write_people_joints3d(path, X, valid, np.arange(20) + 5, COCO_17.joints, 30.0) \
        == [path]
    with np.load(path) as f:
        assert f["joints3d"].shape == (3, 20, 17, 3)
        np.testing.assert_array_equal(f["valid"], valid)
        np.testing.assert_allclose(f["joints3d"][valid], X[valid])
        assert np.isnan(f["joints3d"][~valid]).all()
        assert list(f["people"]) == ["P0", "P1", "P2"]
        np.testing.assert_array_equal(f["frame_ids"], np.arange(20) + 5)


def test_one_trc_a_person(tmp_path, motion):
    X, valid = motion
    out = write_people_joints3d(tmp_path / "m.trc", X, valid, None, COCO_17.joints, 30.0)
    assert out == person_paths(tmp_path / "m.trc", 3)
    assert [p.name for p in out] == ["m_P0.trc", "m_P1.trc", "m_P2.trc"]
    lines = out[1].read_text().splitlines()
    assert "LKnee" in lines[3] and "P1_" not in lines[3]


def test_one_trc_prefixed_labels(tmp_path, motion):
    X, valid = motion
    path = tmp_path / "all.trc"
    write_people_joints3d(path, X, valid, None, COCO_17.joints, 30.0, layout="prefixed")
    header = path.read_text().splitlines()[3].split("\t")
    assert "P0_LKnee" in header and "P2_RAnkle" in header
    assert path.read_text().splitlines()[2].split("\t")[3] == str(3 * 17)


def test_prefixed_needs_marker_labels(tmp_path, motion):
    X, valid = motion
    with pytest.raises(InputError, match="prefixed"):
        write_people_joints3d(tmp_path / "a.csv", X, valid, None, COCO_17.joints, 30.0,
                              layout="prefixed")
