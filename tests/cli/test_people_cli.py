"""``mirrorgraph calibrate --people all``: every person's 3D motion from a gym scene."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mirrorgraph.cli import main
from mirrorgraph.io import write_keypoints
from mirrorgraph.metrics import mirror_rotation_error_deg
from mirrorgraph.synth.crowd import make_crowd


def test_calibrate_every_person(tmp_path, capsys):
    crowd = make_crowd(people=3, frames=150, seed=3, occluded_rate=0.5)
    write_keypoints(crowd.detections, tmp_path / "k.json", "mmpose", meta=True)
    (tmp_path / "camera.json").write_text(json.dumps(
        {"K": crowd.K.tolist(), "image_size": list(crowd.image_size)}))
    tallest = float(crowd.heights.max())
    code = main(["calibrate", str(tmp_path / "k.json"), "--intrinsics",
                 str(tmp_path / "camera.json"), "--out", str(tmp_path / "c.json"),
                 "--people", "all", "--subject-height", f"{tallest:.4f}", "--fps", "30",
                 "--joints3d", str(tmp_path / "people.npz"), "--quiet"])
    assert code == 0, capsys.readouterr().err
    cal = json.loads((tmp_path / "c.json").read_text())
    assert mirror_rotation_error_deg(np.array(cal["mirror"]["normal"]), crowd.normal) < 0.2
    assert abs(cal["mirror"]["distance"] / crowd.distance - 1) < 0.05
    assert cal["input"]["people"]["count"] == 3
    with np.load(tmp_path / "people.npz") as f:
        assert f["joints3d"].shape == (3, 150, 17, 3)
        assert str(f["unit"]) == "m"
        # each person's std with the metric scale's share, as one person's npz holds it:
        # the height's prior and the stature's measurement (the distance's std holds the
        # data's share besides, ``uncertainty.distance_rel_std``)
        parts = cal["uncertainty"]["distance_rel_std"]
        rel = float(np.hypot(parts["height"], parts["measurement"]))
        assert float(f["scale_rel_std"]) == pytest.approx(rel, rel=1e-9)
        assert cal["uncertainty"]["distance_std"] / cal["mirror"]["distance"] == \
            pytest.approx(parts["total"], rel=1e-9)
        assert parts["total"] >= rel
        ok = f["valid"]
        assert f["joints_std"].shape == f["joints_std_shape"].shape == ok.shape
        want = np.hypot(f["joints_std_shape"][ok],
                        rel * np.linalg.norm(f["joints3d"][ok], axis=-1))
        assert np.allclose(f["joints_std"][ok], want, rtol=1e-6)
        assert np.isnan(f["joints_std"][~ok]).all()
    code = main(["calibrate", str(tmp_path / "k.json"), "--out", str(tmp_path / "d.json"),
                 "--intrinsics", str(tmp_path / "camera.json"), "--people", "all",
                 "--height-of", "oldest"])
    assert code == 2
    assert "--height-of" in capsys.readouterr().err


def test_report_and_view_draw_every_person(tmp_path, capsys):
    """--report and --view of a run of every person, and ``report``/``view`` of its stored
    run afterwards: each person's distance to the mirror, each person's bones."""
    pytest.importorskip("matplotlib")
    rr = pytest.importorskip("rerun", reason="rerun-sdk (the view extra) is missing")
    crowd = make_crowd(people=3, frames=90, seed=3)
    write_keypoints(crowd.detections, tmp_path / "k.json", "mmpose", meta=True)
    (tmp_path / "camera.json").write_text(json.dumps(
        {"K": crowd.K.tolist(), "image_size": list(crowd.image_size)}))
    code = main(["calibrate", str(tmp_path / "k.json"), "--intrinsics",
                 str(tmp_path / "camera.json"), "--out", str(tmp_path / "c.json"),
                 "--people", "all", "--subject-height", f"{crowd.heights.max():.4f}",
                 "--report", str(tmp_path / "rep"), "--view", str(tmp_path / "r.rrd"),
                 "--quiet"])
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "rep" / "scene3d.png").is_file()
    from mirrorgraph.report import figures, load_run, report_data

    run = load_run(tmp_path / "c.json").run
    gaps = np.sort(figures.mirror_gap(report_data(run)))
    assert np.allclose(gaps, np.sort(crowd.person_to_mirror), atol=0.15), gaps
    assert "3 people" in figures.scene3d(report_data(run))._suptitle.get_text()
    # the stored run again: report and view need nothing but the calibration
    assert main(["report", str(tmp_path / "c.json"), "--out", str(tmp_path / "rep2"),
                 "--quiet"]) == 0, capsys.readouterr().err
    assert main(["view", str(tmp_path / "c.json"), "--save", str(tmp_path / "v.rrd")]) == 0
    for rrd in ("r.rrd", "v.rrd"):
        strips = {}
        for chunk in rr.chunk.RrdReader(tmp_path / rrd).stream().to_chunks():
            if chunk.entity_path == "/world/person/bones":
                rb = chunk.to_record_batch()
                col = [n for n in rb.schema.names if n.endswith("strips")]
                if col and "frame" in rb.schema.names:
                    for f, v in zip(rb.column("frame").to_pylist(),
                                    rb.column(col[0]).to_pylist()):
                        strips[f] = len(v)
        assert strips and max(strips.values()) >= 3 * 12, (rrd, strips)
