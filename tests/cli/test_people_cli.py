"""``mirrorgraph calibrate --people all``: every person's 3D motion from a gym scene."""

from __future__ import annotations

import json

import numpy as np

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
    code = main(["calibrate", str(tmp_path / "k.json"), "--out", str(tmp_path / "d.json"),
                 "--intrinsics", str(tmp_path / "camera.json"), "--people", "all",
                 "--height-of", "oldest"])
    assert code == 2
    assert "--height-of" in capsys.readouterr().err
