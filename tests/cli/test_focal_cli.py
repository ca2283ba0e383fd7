"""The command line without intrinsics (issue 17): ``calibrate`` estimates the focal
length by default, ``--fov`` holds it near the guess (its spread in the stds), ``--principal-point free`` refuses
given intrinsics with one line."""

import json

import numpy as np
import pytest

from mirrorgraph.cli import main


def test_cli_estimates_by_default_and_fov_holds_it_near_the_guess(tmp_path, capsys):
    d = tmp_path / "scene"
    assert main(["synth", "--out", str(d), "--frames", "200", "--seed", "3", "--focal", "1100",
                 "--quiet"]) == 0
    assert main(["calibrate", str(d / "keypoints_mmpose.json"), "--image-size", "1920x1080",
                 "--out", str(tmp_path / "a.json"), "--quiet"]) == 0
    a = json.loads((tmp_path / "a.json").read_text())["intrinsics"]
    assert "estimated" in a and a["K"][0][0] != pytest.approx(1662.77, rel=1e-3)
    assert main(["calibrate", str(d / "keypoints_mmpose.json"), "--image-size", "1920x1080",
                 "--fov", "60", "--out", str(tmp_path / "b.json"), "--quiet"]) == 0
    b = json.loads((tmp_path / "b.json").read_text())
    # --fov: the focal length held near the guess with its spread, which is in the stds
    guess = 960.0 / np.tan(np.radians(30.0))
    assert b["intrinsics"]["approximate"]
    assert b["intrinsics"]["estimated"]["focal_prior_std_px"] == pytest.approx(0.1 * guess)
    assert b["uncertainty"]["focal_std_px"] > 0
    capsys.readouterr()
    assert main(["calibrate", str(d / "keypoints_mmpose.json"), "--intrinsics",
                 str(d / "camera.json"), "--principal-point", "free",
                 "--out", str(tmp_path / "c.json"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--principal-point" in err and "Traceback" not in err
