"""The report: PNG figures of a calibration run and the video overlay."""

from __future__ import annotations

import json
import re

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
    fin = np.isfinite(data.reproj_graph[data.inlier])
    assert fin.mean() > 0.9 and np.median(data.reproj_graph[data.inlier][fin]) < 6.0
    # like with like: each pair triangulated on its own with either mirror, so the refined
    # mirror fits the pairs at least as well as the initial one (the graph's joints are
    # held to rigid bones, not fitted pair by pair: their residual is a third series)
    assert np.all(np.isfinite(data.reproj_after[data.inlier]))
    assert np.median(data.reproj_after[data.inlier]) <= 1.01 * np.median(
        data.reproj_before[data.inlier])
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


@pytest.mark.parametrize("suffix", [".mp4", ".webm"])
def test_the_rendered_video_is_in_a_codec_browsers_play_or_says_not(scene_run, tmp_path,
                                                                      suffix):
    """H.264 in .mp4 where OpenCV has it, else mp4v and one line saying browsers do not
    play it; VP9 in .webm (no line)."""
    scene, run = scene_run
    video = tmp_path / "in.mp4"
    _blank_video(video, scene.image_size, frames=5)
    said = []
    out = make_report(run, tmp_path / "rep", video=video, render=tmp_path / f"out{suffix}",
                      max_frames=1, progress_bar=False, warn=said.append)
    cap = cv2.VideoCapture(str(out["video"]))
    fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode().lower()
    cap.release()
    if suffix == ".webm":
        assert fourcc in ("vp90", "vp80") and said == []
    elif fourcc in ("avc1", "h264"):
        assert said == []
    else:
        assert fourcc in ("mp4v", "fmp4") and len(said) == 1
        assert "out.mp4" in said[0] and "browsers" in said[0] and ".webm" in said[0]


def test_video_of_another_size_is_refused(scene_run, tmp_path):
    _scene, run = scene_run
    video = tmp_path / "small.mp4"
    _blank_video(video, (320, 240), frames=3)
    with pytest.raises(mg.InputError, match="320x240"):
        make_report(run, tmp_path / "rep", video=video)
    with pytest.raises(mg.InputError, match="field 'render': .*; pass video$"):
        make_report(run, tmp_path / "rep2", render=tmp_path / "x.mp4")


def test_run_from_calibration_file(scene_run, tmp_path):
    scene, run = scene_run
    path = tmp_path / "calibration.json"
    mg.write_calibration(path, run.calibration)       # no .report.npz: recomputed exactly
    again = run_from_calibration(path, scene.detections)
    assert np.allclose(again.calibration.normal, run.calibration.normal, rtol=0, atol=1e-12)
    assert np.allclose(again.calibration.initial_normal, run.calibration.initial_normal)
    assert np.array_equal(again.inliers, run.inliers)
    assert np.array_equal(again.joints3d, run.joints3d, equal_nan=True)
    out = make_report(again, tmp_path / "rep")
    assert all(p.exists() for p in out.values())
    assert json.loads(path.read_text())["mirror"]["distance"] == again.calibration.distance


# --------------------------------------------------------------------------- report == calibrate --report
@pytest.fixture(scope="module")
def scene_files(tmp_path_factory):
    from mirrorgraph.synth import write_scene
    root = tmp_path_factory.mktemp("files")
    scene = make_scene(frames=150, seed=5, outlier_rate=0.05, lr_swap_rate=0.05)
    write_scene(scene, root, formats=("mmpose",))
    return scene, root


def _same_figure_numbers(a, b):
    """The numbers the figures are drawn from are the same (exactly, NaN where NaN)."""
    assert np.array_equal(a.inlier, b.inlier)
    assert np.array_equal(a.t_idx, b.t_idx) and np.array_equal(a.j_idx, b.j_idx)
    for name in ("u", "um", "epi_before", "epi_after", "reproj_before", "reproj_after",
                 "reproj_graph",
                 "joints_before", "joints_after", "bones_before", "bones_after"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and np.allclose(x, y, rtol=1e-12, atol=0, equal_nan=True), name
    assert np.array_equal(a.normal, b.normal) and a.distance == b.distance
    assert a.bone_reference == b.bone_reference


@pytest.mark.parametrize("height", [None, "1.75"])
def test_report_shows_the_calibrations_own_run(scene_files, tmp_path, height, capsys):
    from mirrorgraph.cli import main
    from mirrorgraph.report import load_run

    scene, root = scene_files
    kp, cam = root / "keypoints_mmpose.json", root / "camera.json"
    cal = tmp_path / "c.json"
    args = ["calibrate", str(kp), "--intrinsics", str(cam), "--out", str(cal), "--fps", "30",
            "--report", str(tmp_path / "rep")] + (["--subject-height", height] if height else [])
    assert main(args) == 0
    assert "wrote 6 figures to" in capsys.readouterr().out
    doc = json.loads(cal.read_text())
    assert doc["report_data"] == "c.report.npz" and (tmp_path / "c.report.npz").exists()
    # the run calibrate had in memory (the same pipeline and options: it is deterministic)
    memory = mg.calibrate(kp, mg.load_intrinsics(cam), mg.CalibrateOptions(
        subject_height=None if height is None else float(height), fps=30.0)
        if "fps" in mg.CalibrateOptions.__dataclass_fields__ else
        mg.CalibrateOptions(subject_height=None if height is None else float(height)))
    assert memory.calibration.normal.tolist() == doc["mirror"]["normal"]
    want = report_data(memory)
    stored = load_run(cal)                                  # no keypoints needed
    assert stored.origin == "stored" and not stored.warnings
    recomputed = load_run(cal, kp, report_data=None)
    assert recomputed.origin == "recomputed" and not recomputed.warnings
    assert "the same mirror" in recomputed.message
    for loaded in (stored, recomputed):
        got = report_data(loaded.run)
        _same_figure_numbers(want, got)
        # the inlier fraction the figures show is the calibration's
        assert np.count_nonzero(got.inlier) == doc["pairs_used"]
        assert len(got.inlier) == doc["pairs_total"]
    # and the command says which it did
    assert main(["report", str(cal), "--out", str(tmp_path / "r1")]) == 0
    out = capsys.readouterr().out
    assert f"figures of the run stored in {tmp_path / 'c.report.npz'}" in out
    assert "wrote 6 figures to" in out
    assert main(["report", str(cal), str(kp), "--recompute", "--out", str(tmp_path / "r2")]) == 0
    assert "recomputed from" in capsys.readouterr().out


def test_stale_or_missing_report_data(scene_files, tmp_path, capsys):
    from mirrorgraph.cli import main
    from mirrorgraph.report import load_run

    scene, root = scene_files
    kp, cam = root / "keypoints_mmpose.json", root / "camera.json"
    cal = tmp_path / "c.json"
    assert main(["calibrate", str(kp), "--intrinsics", str(cam), "--out", str(cal), "--fps",
                 "30", "--no-refine", "--quiet"]) == 0
    doc = json.loads(cal.read_text())
    n = np.array(doc["mirror"]["normal"]) + [0.0, 1e-3, 0.0]
    doc["mirror"]["normal"] = (n / np.linalg.norm(n)).tolist()
    cal.write_text(json.dumps(doc))
    # another calibration's run is not drawn: recomputed, with a warning saying why
    loaded = load_run(cal, kp)
    assert loaded.origin == "recomputed"
    assert any("c.report.npz" in w and "another calibration" in w for w in loaded.warnings)
    assert any("recomputed mirror is" in w for w in loaded.warnings)
    # without keypoints: the ones calibration.json records, with the same warning
    capsys.readouterr()
    assert main(["report", str(cal), "--out", str(tmp_path / "r")]) == 0
    captured = capsys.readouterr()
    said = captured.out + captured.err
    assert "another calibration" in said and f"recomputing the run from {kp}" in said
    # --recompute alone: the recorded keypoints
    assert main(["report", str(cal), "--recompute", "--out", str(tmp_path / "r3")]) == 0
    assert f"recomputed from {kp}" in capsys.readouterr().out
    # the recorded keypoints gone: one line saying what to do
    doc["input"]["source"] = str(tmp_path / "moved.json")
    cal.write_text(json.dumps(doc))
    assert main(["report", str(cal), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "c.report.npz" in err
    assert "KEYPOINTS" in err and "--report" in err
    assert main(["report", str(cal), "--recompute", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "moved.json" in err
    (tmp_path / "c.report.npz").unlink()
    assert main(["report", str(cal), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "keypoints" in err and "missing" in err


def test_a_failed_write_leaves_calibration_and_run_alone(scene_files, tmp_path, monkeypatch):
    from mirrorgraph import cli

    scene, root = scene_files
    cal = tmp_path / "c.json"
    cal.write_text("precious")
    (tmp_path / "c.report.npz").write_bytes(b"old")

    def broken(*_a, **_k):
        raise OSError(28, "No space left on device", str(cal))
    monkeypatch.setattr("mirrorgraph.report.store.write_json", broken)   # where it is looked up
    code = cli.main(["calibrate", str(root / "keypoints_mmpose.json"), "--intrinsics",
                     str(root / "camera.json"), "--out", str(cal), "--no-refine", "--quiet",
                     "--fps", "30"])
    assert code != 0
    assert cal.read_text() == "precious" and (tmp_path / "c.report.npz").read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json", "c.report.npz"]


# --------------------------------------------------------------------------- figures' texts
def _legend_texts(ax):
    leg = ax.get_legend()
    return [t.get_text() for t in leg.get_texts()] if leg else []


@pytest.mark.parametrize("metric", [True, False])
def test_bone_length_legends_have_enough_digits(scene_run, metric):
    from mirrorgraph.report import figures
    plt = require_matplotlib()
    _scene, run = scene_run
    data = report_data(run)
    if not metric:         # the same run without a metric scale: lengths in mirror distances
        from dataclasses import replace
        data = replace(data, unit="mirror distance", joints_before=data.joints_before / data.distance,
                       joints_after=data.joints_after / data.distance,
                       bones_before=data.bones_before / data.distance,
                       bones_after=data.bones_after / data.distance,
                       bone_reference={k: v / data.distance for k, v in data.bone_reference.items()},
                       distance=1.0)
    fig = figures.bone_lengths(data)
    texts = [t for ax in fig.axes for t in _legend_texts(ax)]
    sds = [t for t in texts if " sd " in t]
    assert len(sds) == 2 * len(data.bone_names)
    for t in sds:
        m = re.search(r"sd (\d+\.?\d*)( cm)? \((\d+\.\d) %\)", t)
        assert m, t
        digits = m.group(1).replace(".", "").lstrip("0")
        assert len(digits) >= 2 and float(m.group(1)) > 0, t     # never "sd 0.0"
        assert bool(m.group(2)) == metric, t
    refs = [t for t in texts if t.startswith("refined length")]
    assert len(refs) == len(data.bone_names)
    for t in refs:
        value = t.split()[2]
        assert len(value.replace(".", "").lstrip("0")) >= 3, t
    title = fig._suptitle.get_text()
    assert ("mirror distance" in title) != metric
    plt.close(fig)


def test_scene3d_is_readable(scene_run):
    from mirrorgraph.report import figures
    plt = require_matplotlib()
    _scene, run = scene_run
    data = report_data(run)
    fig = figures.scene3d(data)
    title = fig._suptitle.get_text()
    assert "unit: metres" in title and f"{data.distance:.3f} m" in title
    assert title.count("mirror distance") == 0
    top, edge = fig.axes[:2]
    for ax in (top, edge):        # orthographic, equal scales: distances read as they are
        assert ax.name == "rectilinear" and ax.get_aspect() == 1.0
    # seen along the mirror: the mirror a vertical line at d, the person in front of it
    # and the reflection as far behind it
    (gap,) = figures.mirror_gap(data)
    assert 0 < gap < data.distance
    lines = {gid: [ln for ln in edge.get_lines() if ln.get_gid() == gid]
             for gid in ("mirror", "skeleton", "reflection")}
    assert len(lines["mirror"]) == 1 and set(lines["mirror"][0].get_xdata()) == {data.distance}
    assert lines["skeleton"] and lines["reflection"]
    assert max(max(ln.get_xdata()) for ln in lines["skeleton"]) < data.distance
    assert min(min(ln.get_xdata()) for ln in lines["reflection"]) > data.distance
    assert [ln for ln in top.get_lines() if ln.get_gid() == "mirror"]
    # the gap's label sits above every joint of the skeletons drawn, in display pixels
    fig.canvas.draw()
    (label,) = [t for t in edge.texts if t.get_gid() == "gap"]
    box = label.get_window_extent()
    tops = [edge.transData.transform(np.c_[ln.get_xdata(), ln.get_ydata()])[:, 1].max()
            for ln in lines["skeleton"]]
    assert box.y0 >= max(tops)
    plt.close(fig)
    # without a metric scale the unit is said once, and is not "metres"
    from dataclasses import replace
    fig = figures.scene3d(replace(data, unit="mirror distance"))
    title = fig._suptitle.get_text()
    assert "unit: the camera-to-mirror distance" in title and "unit: metres" not in title
    plt.close(fig)


def test_without_matplotlib_says_how_to_install(without_matplotlib):
    with pytest.raises(mg.MirrorgraphError, match=r"pip install 'mirrorgraph\[plot\]'"):
        require_matplotlib()


def test_unrefined_figures_do_not_claim_a_refinement(scene_run):
    from mirrorgraph.report import figures
    plt = require_matplotlib()
    scene, _run = scene_run
    run = mg.calibrate(scene.detections, scene.intrinsics, mg.CalibrateOptions(refine=False))
    data = report_data(run)
    assert not data.refined
    # joints only where the run kept the pair
    ok = np.isfinite(data.joints_after[data.t_idx, data.j_idx]).all(-1)
    assert np.array_equal(ok, data.inlier)
    fig = figures.bone_lengths(data)
    texts = [t for ax in fig.axes for t in _legend_texts(ax)]
    assert texts and all(t.startswith("initial") for t in texts)
    assert "did not run" in fig._suptitle.get_text()
    plt.close(fig)
    fig = figures.residuals(data)
    texts = [t for ax in fig.axes for t in _legend_texts(ax)]
    assert texts and not any("after" in t for t in texts)
    plt.close(fig)
    fig = figures.scene3d(data)
    assert "not refined" in fig._suptitle.get_text()
    plt.close(fig)
