"""What ``mirrorgraph live`` (mirrorgraph/cli/live.py) says after a stream, run in a fresh
process as a user runs it."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest


def test_a_file_that_ends_before_its_first_mirror_says_so(tmp_path):
    """A 62-frame file played at its frame rate: the first window (60 frames) is solved
    by the worker while the last frames go by, so the mirror comes after the last line.
    The summary names the mirror; a warning says that no line holds 3D joints and what
    gives them. Where the solve beats the stream the lines have joints and nothing is
    said."""
    run = [sys.executable, "-m", "mirrorgraph"]
    subprocess.run([*run, "synth", "--out", "s", "--frames", "62", "--seed", "1",
                    "--formats", "mmpose", "--video-frames", "0", "--quiet"], check=True,
                   cwd=tmp_path)
    proc = subprocess.run([*run, "live", "s/keypoints_mmpose.json", "--intrinsics",
                           "s/camera.json", "--jsonl", "l.jsonl"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    lines = [json.loads(ln) for ln in (tmp_path / "l.jsonl").read_text().splitlines()]
    assert len(lines) == 62 and "mirror normal" in proc.stdout
    joints = any(X is not None for ln in lines for X in ln["joints3d"])
    said = [ln for ln in proc.stderr.splitlines() if "no line of l.jsonl holds 3D joints" in ln]
    assert len(said) == (0 if joints else 1), proc.stderr
    if said:
        assert said[0].startswith("warning: the mirror came after the last frame")
        assert "--as-fast-as-possible" in said[0]


def test_a_stated_height_std_reaches_the_live_scale(tmp_path):
    """``live --height-sigma 0.005``: the metric scale's std of the last line holds the
    stated 0.5 % in place of the default's prior in quadrature, the rest (the stature's
    spread and sampling) within 0.2 %, so the distance's std narrower; the mirror the
    same."""
    import numpy as np

    from mirrorgraph.cli import main
    from mirrorgraph.graph.options import GaugeOptions

    assert main(["synth", "--out", str(tmp_path / "s"), "--frames", "240", "--seed", "21",
                 "--formats", "mmpose", "--video-frames", "0", "--quiet"]) == 0
    last = {}
    for flag in ([], ["--height-sigma", "0.005"]):
        out = tmp_path / f"l{len(flag)}.jsonl"
        assert main(["live", str(tmp_path / "s" / "keypoints_mmpose.json"), "--intrinsics",
                     str(tmp_path / "s" / "camera.json"), "--subject-height", "1.7",
                     "--jsonl", str(out), "--as-fast-as-possible", "--quiet", *flag]) == 0
        last[bool(flag)] = json.loads(out.read_text().splitlines()[-1])["mirror"]
    stated, default = last[True], last[False]
    rest = default["scale_rel_std"] ** 2 - GaugeOptions().height_sigma ** 2
    assert rest > 0
    # the rest within 0.2 %
    assert stated["scale_rel_std"] == pytest.approx(np.sqrt(0.005 ** 2 + rest), rel=2e-3)
    assert stated["distance_std"] < default["distance_std"]
    assert stated["normal"] == default["normal"]
