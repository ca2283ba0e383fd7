"""``mirrorgraph live`` on a video file: BlazePose frame by frame (the ``video`` extra and
the Pose2Sim demo videos; skipped with the reason where missing)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.video.conftest import demo, models  # noqa: F401  (the shared fixtures)

cv2 = pytest.importorskip("cv2")


def _clip(demo: Path, path: Path, count: int = 12) -> Path:  # noqa: F811
    from mirrorgraph.synth.mirror_clip import MirrorComposite
    from mirrorgraph.video.reader import frames

    comp = MirrorComposite()
    canvases = [comp.compose(f) for _, f in frames(demo / "Demo_SinglePerson" / "videos" /
                                                   "cam01.mp4", start=40, end=40 + count)]
    h, w = canvases[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (w, h))
    for c in canvases:
        out.write(cv2.cvtColor(c, cv2.COLOR_RGB2BGR))
    out.release()
    return path


def test_a_video_source_gives_every_person_of_every_frame(demo, models, tmp_path):  # noqa: F811
    from mirrorgraph.live.sources import open_source

    src = open_source(_clip(demo, tmp_path / "clip.mp4"), realtime=False)
    assert src.kind == "video" and src.skeleton.name == "BLAZEPOSE" and src.fps == 30.0
    frames = list(src.frames)
    assert [f.frame_id for f in frames] == list(range(12))
    assert all(f.people.shape[1:] == (33, 3) for f in frames)
    assert np.mean([len(f.people) >= 2 for f in frames]) > 0.8     # person and reflection


def test_live_command_on_a_video(demo, models, tmp_path, capsys):  # noqa: F811
    from mirrorgraph.cli import main

    clip = _clip(demo, tmp_path / "clip.mp4")
    out = tmp_path / "v.jsonl"
    assert main(["live", str(clip), "--jsonl", str(out), "--as-fast-as-possible"]) == 0
    lines = [json.loads(s) for s in out.read_text().splitlines()]
    assert len(lines) == 12 and all(ln["skipped"] is None for ln in lines)
    assert len(lines[0]["joints3d"]) == 33
    # 12 frames: fewer than the first window's 60, the mirror is still initialising
    assert lines[-1]["status"] == "initialising" and lines[-1]["mirror"]["normal"] is None
    assert "wrote 12 lines" in capsys.readouterr().out
