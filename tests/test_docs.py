"""Documentation tests: the ``mirrorgraph`` commands of the README and of every page of
docs/ (their ``bash`` blocks), parsed by the command line's own parser, and the README's
commands run as written."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import re
import shlex
from pathlib import Path

import pytest

from mirrorgraph.cli import _command, build_parser, main

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def documented_commands(page: Path) -> list[list[str]]:
    """The argv of every ``mirrorgraph`` command in the page's ``bash`` blocks: line
    continuations joined, comments and ``&&`` chains split off; a synopsis' optional
    ``[...]`` parts kept (brackets dropped); a placeholder ``...`` command left out."""
    found = []
    for block in re.findall(r"```(?:bash|sh|console)\n(.*?)```", page.read_text(), re.S):
        for line in block.replace("\\\n", " ").splitlines():
            for part in line.split("&&"):
                words = shlex.split(part.replace("[", " ").replace("]", " "), comments=True)
                if words and words[0].endswith("mirrorgraph") and "..." not in words:
                    found.append(words[1:])
    return found


CASES = [(page.relative_to(ROOT).as_posix(), argv) for page in PAGES
         for argv in documented_commands(page)]


def test_the_pages_hold_commands():
    assert len(CASES) >= 15
    assert {argv[0] for _, argv in CASES} >= {"synth", "calibrate", "detect", "live",
                                               "report", "calibrate-rig"}


@pytest.mark.parametrize("page, argv", CASES, ids=[f"{p}:{' '.join(a)[:60]}" for p, a in CASES])
def test_a_documented_command_parses(page, argv):
    """Every option exists and every required one is given."""
    command = _command(argv)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            build_parser([command] if command else []).parse_args(argv)
        except SystemExit as exc:
            assert not exc.code, f"{page}: mirrorgraph {' '.join(argv)}: {err.getvalue()}"


def test_the_readmes_commands_run(tmp_path, monkeypatch):
    """The README's commands, in order, in an empty folder: each exits 0 and writes what
    the next one reads; ``calibrate scene/clip.mp4`` where BlazePose's runtime (LiteRT,
    the video extra) is installed; then the README's Python on the same files."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MIRRORGRAPH_CACHE", str(tmp_path / "cache"))
    commands = documented_commands(ROOT / "README.md")
    run = [argv for argv in commands if argv[0] in ("synth", "calibrate")]
    assert len(run) >= 3
    video = importlib.util.find_spec("ai_edge_litert") is not None
    clip = [argv for argv in run if argv[0] == "calibrate" and argv[1].endswith(".mp4")]
    assert clip, "the README calibrates the synthetic scene's clip.mp4"
    for argv in run:
        if argv in clip and not video:
            continue
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(argv + ["--quiet"]) == 0, argv
    assert (tmp_path / "calibration.json").is_file() and (tmp_path / "joints3d.npz").is_file()
    if video:
        assert (tmp_path / "clip_calibration.json").is_file()
    (tmp_path / "calibration.json").unlink()
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert blocks, "the README shows the pipeline from Python"
    for code in blocks:                      # the Python of the README, on the same files
        namespace: dict = {}
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(code, "README.md", "exec"), namespace)
    assert (tmp_path / "calibration.json").is_file()
    assert namespace["joints3d"].shape[:2] == namespace["joints_std"].shape
