"""The report: PNG figures of a calibration run and the video overlay."""

from __future__ import annotations

import builtins
import json

import numpy as np
import pytest

pytest.importorskip("matplotlib")
cv2 = pytest.importorskip("cv2")

import mirrorgraph as mg  # noqa: E402
from mirrorgraph.report import (FIGURES, make_report, report_data, require_matplotlib,  # noqa: E402
                                run_from_calibration)
from mirrorgraph.synth import make_scene  # noqa: E402


@pytest.fixture(scope="module")
def scene_run():
    scene = make_scene(frames=150, seed=2, outlier_rate=0.05)
    run = mg.calibrate(scene.detections, scene.intrinsics,
                       mg.CalibrateOptions(subject_height=scene.subject_height))
    return scene, run


def _blank_video(path, size, frames=20, fps=30.0):
    w, h = size
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    assert vw.isOpened()
    for i in range(frames):
        vw.write(np.full((h, w, 3), 40 + i, np.uint8))
    vw.release()


def test_report_writes_every_figure(scene_run, tmp_path):
    _scene, run = scene_run
    steps = []
    out = make_report(run, tmp_path / "rep", progress=steps.append)
    assert set(out) == set(FIGURES)
    for name, path in out.items():
        assert path.exists() and path.suffix == ".png"
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        img = cv2.imread(str(path))
        assert img is not None and img.shape[0] >= 400 and img.shape[1] >= 600, name
        assert img.std() > 5, f"{name} looks blank"
    assert any("residuals" in s for s in steps)


def test_report_data_before_and_after(scene_run):
    scene, run = scene_run
    data = report_data(run)
    calib = run.calibration
    # before uses the initial normal, after the refined one: they differ, both are good
    assert not np.allclose(data.epi_before, data.epi_after)
    assert np.median(data.epi_after[data.inlier]) < 5.0
    assert np.median(data.epi_before[data.inlier]) < 5.0
    fin = np.isfinite(data.reproj_after[data.inlier])
    assert fin.mean() > 0.9 and np.median(data.reproj_after[data.inlier][fin]) < 6.0
    # the initial epipole is the image of the initial normal
    e0 = calib.intrinsics.K @ calib.initial_normal
    assert np.allclose(data.initial_epipole, e0[:2] / e0[2])
    # bone lengths are metric and near the truth's scale (femur ~ 0.25 of height)
    k = data.bone_names.index("left_femur")
    assert 0.18 < np.nanmedian(data.bones_after[:, k]) / scene.subject_height < 0.32
    # refinement holds bones steadier than the initial triangulation
    assert np.nanmedian(np.nanstd(data.bones_after, 0)) < np.nanmedian(np.nanstd(data.bones_before, 0))
    # the epipole ellipse comes from the normal covariance: positive definite
    assert data.epipole_cov is not None and np.all(np.linalg.eigvalsh(data.epipole_cov) > 0)


def test_image_plane_shows_the_epipole(scene_run):
    from mirrorgraph.report import figures
    plt = require_matplotlib()
    _scene, run = scene_run
    data = report_data(run)
    fig = figures.image_plane(data)
    ax = fig.axes[0]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    e = data.epipole
    assert min(x0, x1) < e[0] < max(x0, x1) and min(y0, y1) < e[1] < max(y0, y1)
    assert y0 > y1    # y axis points down, as in the image
    plt.close(fig)
    fig = figures.residuals(data)
    for ax in fig.axes:       # filled bars (before) and a step outline (after), both non-empty
        bars = [p.get_height() for p in ax.patches if hasattr(p, "get_height")]
        outline = [p for p in ax.patches if not hasattr(p, "get_height")]
        assert sum(bars) > 0 and outline
    plt.close(fig)


def test_video_overlay_and_render(scene_run, tmp_path):
    scene, run = scene_run
    video = tmp_path / "in.mp4"
    _blank_video(video, scene.image_size, frames=20)
    out = make_report(run, tmp_path / "rep", video=video, render=tmp_path / "out.mp4",
                      max_frames=3, progress_bar=False)
    overlays = [k for k in out if k.startswith("overlay_")]
    assert len(overlays) == 3
    img = cv2.imread(str(out[overlays[0]]))
    assert img.shape[:2] == (scene.image_size[1], scene.image_size[0])
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 10     # something was drawn
    cap = cv2.VideoCapture(str(out["video"]))
    assert cap.isOpened()
    n, ok = 0, True
    while ok:
        ok, frame = cap.read()
        n += ok
    cap.release()
    assert n == 20 and not list(tmp_path.glob(".*part*"))


def test_video_of_another_size_is_refused(scene_run, tmp_path):
    _scene, run = scene_run
    video = tmp_path / "small.mp4"
    _blank_video(video, (320, 240), frames=3)
    with pytest.raises(mg.InputError, match="320x240"):
        make_report(run, tmp_path / "rep", video=video)
    with pytest.raises(mg.InputError, match="--video"):
        make_report(run, tmp_path / "rep2", render=tmp_path / "x.mp4")


def test_run_from_calibration_file(scene_run, tmp_path):
    scene, run = scene_run
    path = tmp_path / "calibration.json"
    mg.write_calibration(path, run.calibration)
    again = run_from_calibration(path, scene.detections)
    assert np.allclose(again.calibration.normal, run.calibration.normal)
    assert np.allclose(again.calibration.initial_normal, run.calibration.initial_normal)
    assert again.inliers.sum() > 0.8 * run.inliers.sum()
    out = make_report(again, tmp_path / "rep")
    assert all(p.exists() for p in out.values())
    assert json.loads(path.read_text())["mirror"]["distance"] == again.calibration.distance


def test_without_matplotlib_says_how_to_install(monkeypatch):
    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ImportError("no matplotlib")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)
    with pytest.raises(mg.MirrorgraphError, match=r"pip install 'mirrorgraph\[plot\]'"):
        require_matplotlib()
