"""What ``mirrorgraph live`` (mirrorgraph/cli/live.py) says after a stream, run in a fresh
process as a user runs it."""

from __future__ import annotations

import json
import subprocess
import sys


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
