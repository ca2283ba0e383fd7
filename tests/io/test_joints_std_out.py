"""Each joint's std in the 3D motion files: the npz's ``joints_std``, C3D's residuals."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from mirrorgraph.io.motion import write_joints3d


def motion(seed=0, T=12, J=4):
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(T, J, 3)) + [0.0, 0.0, 3.0]
    valid = rng.random((T, J)) > 0.2
    std = rng.uniform(0.004, 0.09, (T, J))
    std[0, 0] = np.nan                          # a valid joint whose std is unknown
    valid[0, 0] = True
    return X, valid, std, ["nose", "left_eye", "right_eye", "left_ear"][:J]


def test_npz_holds_joints_std_where_valid(tmp_path):
    X, valid, std, names = motion()
    path = tmp_path / "m.npz"
    write_joints3d(path, X, valid, None, names, 30.0, "m", joints_std=std)
    z = np.load(path)
    assert z["joints_std"].shape == valid.shape
    assert np.allclose(z["joints_std"][valid], std[valid], equal_nan=True)
    assert np.isnan(z["joints_std"][~valid]).all()
    write_joints3d(path, X, valid, None, names, 30.0, "m")
    assert "joints_std" not in np.load(path)            # none given: none written
    assert "joints_std_shape" not in np.load(path) and "scale_rel_std" not in np.load(path)
    # the scale's share apart: the shape's std per joint, the scale's relative std per run
    shape = 0.5 * std
    write_joints3d(path, X, valid, None, names, 30.0, "m", joints_std=std,
                   joints_std_shape=shape, scale_rel_std=0.02)
    z = np.load(path)
    assert np.allclose(z["joints_std_shape"][valid], shape[valid], equal_nan=True)
    assert np.isnan(z["joints_std_shape"][~valid]).all()
    assert float(z["scale_rel_std"]) == 0.02
    with pytest.raises(ValueError, match="joints_std"):
        write_joints3d(path, X, valid, None, names, 30.0, "m", joints_std=std[:, :2])


@pytest.mark.parametrize("scale", [1.0, 40.0])
def test_c3d_residuals_are_the_stds_in_millimetres(tmp_path, scale):
    c3d = pytest.importorskip("c3d", reason="the c3d package is missing")
    X, valid, std, names = motion()
    std = std * scale                                     # up to 3.6 m: a coarser grid
    path = tmp_path / "m.c3d"
    write_joints3d(path, X, valid, np.arange(len(X)), names, 30.0, "m", joints_std=std)
    with open(path, "rb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reader = c3d.Reader(fh)
        step = abs(float(reader.point_scale))
        got = np.array([p[:, 3] for _, p, _ in reader.read_frames()])          # (T, J)
    mm = 1000.0 * std
    assert step == max(1.0, np.ceil(np.nanmax(mm[valid]) / 255.0))
    known = valid & np.isfinite(std)
    assert np.all(np.abs(got[known] - mm[known]) <= 0.5 * step + 1e-6)
    assert np.all(got[known] >= step)                    # never 0, C3D's "modelled"
    assert np.all(got[valid & ~np.isfinite(std)] == 0.0)  # unknown: no estimate
    assert np.all(got[~valid] == -1.0)                    # invalid points
