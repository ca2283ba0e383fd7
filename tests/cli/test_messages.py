"""What the command line says: warnings once, progress bars that count up to their real
total, the solver's error never rising within a pass, and the texts of its messages."""

from __future__ import annotations

import io
import json
import re
import sys

import numpy as np
import pytest

from mirrorgraph.anthropometry import height_problem
from mirrorgraph.cli import main
from mirrorgraph.progress import Progress, SolveProgress
from mirrorgraph.synth import make_scene, write_scene


class FakeTTY(io.StringIO):
    """A text stream that says it is a terminal: progress bars draw on it."""

    def isatty(self) -> bool:
        return True


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("scene")
    write_scene(make_scene(frames=150, seed=4, outlier_rate=0.05, lr_swap_rate=0.05), out,
                formats=("mmpose",))
    return out


def run_cli(argv, monkeypatch, *, tty: bool = False) -> tuple[int, str, str]:
    """``main(argv)`` with stdout and stderr captured (stderr a fake terminal if ``tty``)."""
    out, err = io.StringIO(), (FakeTTY() if tty else io.StringIO())
    monkeypatch.setattr(sys, "stdout", out)
    monkeypatch.setattr(sys, "stderr", err)
    monkeypatch.setattr(Progress, "min_interval", 0.0)     # draw every update
    code = main(argv)
    monkeypatch.undo()
    return code, out.getvalue(), err.getvalue()


BAR = re.compile(r"^(?P<label>[a-z ]+?) (?:\[(?P<bar>[#-]{24})\] )?(?P<done>\d+)"
                 r"(?:/(?P<total>\d+))? +[\d.]+s ?(?P<info>.*)$")


def bar_lines(err: str) -> dict[str, list[dict]]:
    """Every drawn state of every progress line, by label, in order."""
    lines: dict[str, list[dict]] = {}
    for piece in err.replace("\n", "\r").split("\r"):
        m = BAR.match(piece.strip())
        if m:
            d = m.groupdict()
            d["done"] = int(d["done"])
            d["total"] = None if d["total"] is None else int(d["total"])
            d["filled"] = d["bar"].count("#") if d["bar"] else None
            lines.setdefault(d["label"], []).append(d)
    return lines


def assert_counts_up(states: list[dict]) -> None:
    done = [s["done"] for s in states]
    assert done == sorted(done), done
    filled = [s["filled"] for s in states if s["filled"] is not None]
    assert filled == sorted(filled), filled          # the bar never moves back
    totals = {s["total"] for s in states if s["total"] is not None}
    assert len(totals) <= 1, totals                  # one total, never revised
    if totals:
        assert max(done) <= totals.pop()


# --------------------------------------------------------------------------- warnings
def test_every_warning_is_printed_once(scene_dir, tmp_path, monkeypatch):
    code, out, err = run_cli(["calibrate", str(scene_dir / "keypoints_mmpose.json"),
                              "--image-size", "1920x1080", "--out", str(tmp_path / "c.json"),
                              "--no-refine"], monkeypatch)
    assert code == 0, err
    warnings = json.loads((tmp_path / "c.json").read_text())["warnings"]
    assert any("no intrinsics" in w for w in warnings)
    printed = [ln for ln in (out + err).splitlines() if ln.startswith("warning: ")]
    assert sorted(printed) == sorted(f"warning: {w}" for w in warnings)
    assert "warning:" not in out                     # warnings on stderr, the summary on stdout
    assert "mirror normal" in out


def test_quiet_silences_warnings_which_stay_in_the_json(scene_dir, tmp_path, monkeypatch):
    code, out, err = run_cli(["calibrate", str(scene_dir / "keypoints_mmpose.json"),
                              "--image-size", "1920x1080", "--out", str(tmp_path / "c.json"),
                              "--no-refine", "--quiet"], monkeypatch)
    assert code == 0 and out == "" and err == ""
    warnings = json.loads((tmp_path / "c.json").read_text())["warnings"]
    assert sum("no intrinsics given" in w for w in warnings) == 1


# --------------------------------------------------------------------------- progress
def test_progress_of_calibrate_and_report_counts_up(scene_dir, tmp_path, monkeypatch):
    code, out, err = run_cli(["calibrate", str(scene_dir / "keypoints_mmpose.json"),
                              "--intrinsics", str(scene_dir / "camera.json"),
                              "--out", str(tmp_path / "c.json"), "--fps", "30",
                              "--report", str(tmp_path / "rep")], monkeypatch, tty=True)
    assert code == 0, err
    bars = bar_lines(err)
    assert {"robust initialisation", "solving the graph", "drawing the report"} <= set(bars)
    for states in bars.values():
        assert_counts_up(states)
    # the RANSAC's total is a running estimate: only the last line shows it, the real one
    init = bars["robust initialisation"]
    assert all(s["total"] is None for s in init[:-1])
    assert init[-1]["total"] == init[-1]["done"] > 0
    cal = json.loads((tmp_path / "c.json").read_text())
    assert init[-1]["done"] == cal["ransac_iterations"]
    # the graph: within a pass the error of the accepted steps never rises
    errors: dict[int, list[float]] = {}
    for s in bars["solving the graph"]:
        m = re.match(r"pass (\d+): error (\S+) -> (\S+)", s["info"])
        assert m, s["info"]
        errors.setdefault(int(m.group(1)), []).append(float(m.group(3)))
        assert float(m.group(3)) <= float(m.group(2))
    assert list(errors) == sorted(errors)
    for values in errors.values():
        assert values == sorted(values, reverse=True), values
    # drawing the report: 1/5 ... 5/5
    draw = bars["drawing the report"]
    assert draw[-1]["done"] == draw[-1]["total"] == 6
    assert f"wrote 6 figures to {tmp_path / 'rep'}" in out


def test_no_progress_off_a_terminal_or_when_quiet(scene_dir, tmp_path, monkeypatch):
    args = ["calibrate", str(scene_dir / "keypoints_mmpose.json"), "--intrinsics",
            str(scene_dir / "camera.json"), "--out", str(tmp_path / "c.json"), "--fps", "30",
            "--no-refine"]
    _, _, err = run_cli(args, monkeypatch)
    assert not bar_lines(err) and "\r" not in err
    _, out, err = run_cli(args + ["--quiet"], monkeypatch, tty=True)
    assert out == "" and err == ""


def test_estimated_total_is_never_shown_before_it_is_known():
    stream = FakeTTY()
    bar = Progress("robust initialisation", stream=stream)
    bar.min_interval = 0.0
    for it, planned in ((1, 267), (2, 40), (3, 80), (30, 50), (50, 50)):
        bar.estimate(it, planned)
    bar.close()
    states = bar_lines(stream.getvalue())["robust initialisation"]
    assert_counts_up(states)
    assert [s["total"] for s in states] == [None] * 5 + [50]


def test_solve_progress_starts_a_pass_where_the_error_rises():
    stream = FakeTTY()
    bar = Progress("solving the graph", stream=stream)
    bar.min_interval = 0.0
    closed = []
    solve = SolveProgress(bar, on_first=lambda: closed.append(True))
    for it, e in enumerate((1700, 1568, 6636, 6137, 4663, 4663, 5200, 5100), 1):
        solve(it, e)
    assert closed == [True] and solve.passes == 3
    assert solve.info == "pass 3: error 5200 -> 5100"
    assert bar.done == 8


def test_video_sampling_shows_progress(tmp_path, monkeypatch):
    cv2 = pytest.importorskip("cv2")
    pytest.importorskip("matplotlib")
    import mirrorgraph as mg
    from mirrorgraph.report.video import overlay_samples

    scene = make_scene(frames=30, seed=1)
    run = mg.calibrate(scene.detections, scene.intrinsics, mg.CalibrateOptions(refine=False))
    video = tmp_path / "v.mp4"
    w, h = scene.image_size
    vw = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (w, h))
    for i in range(30):
        vw.write(np.full((h, w, 3), 30 + i, np.uint8))
    vw.release()
    stream = FakeTTY()
    monkeypatch.setattr(sys, "stderr", stream)
    monkeypatch.setattr(Progress, "min_interval", 0.0)
    out = overlay_samples(video, run, tmp_path, count=4)
    monkeypatch.undo()
    states = bar_lines(stream.getvalue())["sampling video frames"]
    assert_counts_up(states)
    assert states[-1]["done"] == states[-1]["total"] == len(out) == 4


# --------------------------------------------------------------------------- texts
def test_export_names_the_cameras_as_written(scene_dir, tmp_path, monkeypatch):
    import tomllib

    cal = tmp_path / "c.json"
    assert run_cli(["calibrate", str(scene_dir / "keypoints_mmpose.json"), "--intrinsics",
                    str(scene_dir / "camera.json"), "--out", str(cal), "--no-refine",
                    "--quiet"], monkeypatch)[0] == 0
    for fmt, real, mirror in (("pose2sim", "[cam_01]", "[cam_02]"),
                              ("anipose", "[cam_0] 'real'", "[cam_1] 'mirror'")):
        toml = tmp_path / f"{fmt}.toml"
        code, out, _ = run_cli(["export", str(cal), "--to", fmt, str(toml)], monkeypatch)
        assert code == 0
        assert f"{real} the real camera" in out and f"{mirror} the mirror's virtual camera" in out
        sections = [k for k, v in tomllib.loads(toml.read_text()).items()
                    if isinstance(v, dict) and "matrix" in v]
        assert sections == [real[1:].split("]")[0], mirror[1:].split("]")[0]]
        assert "'real' and 'mirror'" not in out


def test_matplotlib_hint_matches_the_readme(monkeypatch, tmp_path, without_matplotlib):
    from mirrorgraph.report import INSTALL_HINT

    assert "pip install 'mirrorgraph[plot]'" in INSTALL_HINT
    assert "pip install -e '.[plot]'" in INSTALL_HINT          # docs/guide/report.md, in a clone
    code, _, err = run_cli(["report", str(tmp_path / "c.json"), "--out", str(tmp_path / "r")],
                           monkeypatch)
    assert code == 2 and err.count("\n") == 1 and INSTALL_HINT in err


def test_subject_height_in_centimetres_is_named(monkeypatch, tmp_path):
    assert height_problem(1.75) is None
    assert "did you mean 1.75 m (centimetres given)?" in height_problem(175)
    assert "did you mean 1.8 m (millimetres given)?" in height_problem(1800)
    assert "did you mean" not in height_problem(30)
    for cmd in (["calibrate", "kp.json", "--out", str(tmp_path / "c.json")],
                ["calibrate-rig", "rig.toml", "--out", str(tmp_path / "c.toml")]):
        code, _, err = run_cli(cmd + ["--subject-height", "175"], monkeypatch)
        assert code == 2 and err.count("\n") == 1
        assert "175 m is not a human height" in err and "1.75 m (centimetres given)" in err


def test_a_keypoint_offset_that_is_no_placement_is_one_line(monkeypatch, tmp_path):
    """``--keypoint-offset`` on every command that takes ``--subject-height``: a negative,
    a non-numeric or a centimetre value is refused in one line, exit 2."""
    for cmd in (["calibrate", "kp.json", "--out", str(tmp_path / "c.json")],
                ["calibrate-rig", "rig.toml", "--out", str(tmp_path / "c.toml")],
                ["batch", "m.csv"],
                ["live", "kp.json", "--jsonl", str(tmp_path / "l.jsonl")]):
        for bad, said in (("-0.01", "must be a non-negative number of metres"),
                          ("abc", "not a number of metres"),
                          ("3", "give metres, e.g. 0.03 for 3 cm")):
            code, _, err = run_cli(cmd + [f"--keypoint-offset={bad}"], monkeypatch)
            assert code == 2 and err.count("\n") == 1, (cmd, bad, err)
            assert "--keypoint-offset" in err and said in err, err
        code, _, err = run_cli(cmd + ["--keypoint-offset", "-0.01"], monkeypatch)
        assert code == 2 and err.count("\n") == 1, (cmd, err)


def test_a_height_sigma_that_is_no_fraction_is_one_line(monkeypatch, tmp_path):
    """``--height-sigma`` on every command that takes ``--keypoint-offset``: a negative, a
    non-numeric or a percentage value is refused in one line that names the flag, exit 2."""
    for cmd in (["calibrate", "kp.json", "--out", str(tmp_path / "c.json")],
                ["calibrate-rig", "rig.toml", "--out", str(tmp_path / "c.toml")],
                ["batch", "m.csv"],
                ["live", "kp.json", "--jsonl", str(tmp_path / "l.jsonl")]):
        for bad, said in (("-0.01", "must be a non-negative fraction of the height"),
                          ("nan", "must be a non-negative fraction of the height"),
                          ("1.3%", "not a fraction"),
                          ("0.5", "give a fraction, e.g. 0.005 for 0.5 %")):
            code, _, err = run_cli(cmd + [f"--height-sigma={bad}"], monkeypatch)
            assert code == 2 and err.count("\n") == 1, (cmd, bad, err)
            assert "--height-sigma" in err and said in err, err


def test_demo_prints_a_path_only_when_it_is_kept(tmp_path, monkeypatch):
    code, out, err = run_cli(["demo", "--frames", "120"], monkeypatch)
    assert code == 0, err
    assert "temporary folder, deleted at the end" in out
    assert "/tmp" not in out.split("\n")[0] and ".json" not in out.split("\n")[0]
    keep = tmp_path / "kept"
    code, out, err = run_cli(["demo", "--frames", "120", "--keep", str(keep)], monkeypatch)
    assert code == 0, err
    assert str(keep / "keypoints_mmpose.json") in out and (keep / "calibration.json").exists()
    assert (keep / "calibration.report.npz").exists()
    assert f"kept the scene and calibration.json in {keep}" in out


# --------------------------------------------------------------------------- errors
def test_the_library_names_arguments_and_the_command_line_names_flags(tmp_path, monkeypatch):
    """One condition, one error type (an InputError, which is a ValueError), said in the
    words of whoever was called: the argument from Python, the flag from the CLI."""
    import dataclasses

    import mirrorgraph as mg
    from mirrorgraph.io import write_keypoints

    scene = make_scene(frames=40, seed=4)
    path = tmp_path / "no_size.json"                   # keypoints without an image size
    write_keypoints(dataclasses.replace(scene.detections, image_size=None), path, "mmpose")
    with pytest.raises(ValueError) as info:
        mg.calibrate(str(path), None)
    assert isinstance(info.value, mg.InputError)
    assert str(info.value) == f"{path}: no intrinsics and no image size; pass intrinsics or " \
                              "image_size"
    code, _out, err = run_cli(["calibrate", str(path), "--out", str(tmp_path / "c.json")],
                              monkeypatch)
    assert code == 2
    assert err == f"error: {path}: no intrinsics and no image size; pass --intrinsics FILE " \
                  "or --image-size WxH\n"
    assert not (tmp_path / "c.json").exists()


def test_an_error_describes_its_arguments_as_a_front_end_calls_them():
    from mirrorgraph.cli.args import FLAGS, error_message
    from mirrorgraph.errors import InputError

    e = InputError("must be at least 1, got 0", field="workers")
    assert str(e) == "field 'workers': must be at least 1, got 0"
    assert error_message(e) == "field '--workers': must be at least 1, got 0"
    e = InputError("fits BODY_25 or BODY_25B", source="k.json",
                   fix=("skeleton=BODY_25", "skeleton=BODY_25B"))
    assert str(e) == "k.json: fits BODY_25 or BODY_25B; pass skeleton=BODY_25 or " \
                     "skeleton=BODY_25B"
    assert e.describe(FLAGS) == "k.json: fits BODY_25 or BODY_25B; pass --skeleton BODY_25 " \
                                "or --skeleton BODY_25B"
    # a field of a file keeps its name: image_size in camera.json is not --image-size
    e = InputError("must be two positive integers", source="camera.json", field="image_size")
    assert error_message(e) == str(e) == "camera.json, field 'image_size': must be two " \
                                         "positive integers"
    # unmapped arguments keep their names; errors that are not input errors are as they are
    assert InputError("x", field="noise", fix=("seed",)).describe({}) == \
        "field 'noise': x; pass seed"
    assert error_message(RuntimeError("boom")) == "boom"


def test_the_same_condition_raises_the_same_type():
    """Unknown names of a skeleton, an estimator, a keypoint or camera file format: an
    InputError (a ValueError) from whichever function is given them."""
    import numpy as np

    from mirrorgraph.errors import InputError
    from mirrorgraph.initial.estimators import estimate_mirror
    from mirrorgraph.io import write_keypoints
    from mirrorgraph.io.camera_toml import camera_document
    from mirrorgraph.skeletons import skeleton_by_name

    scene = make_scene(frames=20, seed=1)
    with pytest.raises(InputError, match="unknown skeleton 'H36M'"):
        skeleton_by_name("H36M")
    with pytest.raises(InputError, match="field 'estimator': unknown estimator 'best'"):
        estimate_mirror(np.zeros((10, 2)), np.zeros((10, 2)), scene.K, estimator="best")
    with pytest.raises(InputError, match="field 'fmt': unknown keypoint format 'csv'"):
        write_keypoints(scene.detections, "x.csv", "csv")
    with pytest.raises(InputError, match="field 'style': unknown camera file style 'vicon'"):
        camera_document([], style="vicon")


def test_an_error_after_a_progress_bar_starts_on_its_own_line(monkeypatch):
    """A step that raises before closing its bar: the error line is not glued to the bar."""
    from mirrorgraph.cli import calibrate as calibrate_cli
    from mirrorgraph.errors import InputError

    def failing(args):
        bar = Progress("reading frames", total=10)     # drawn on the fake terminal
        bar.update(3)
        raise InputError("frame 4 has no joints", source="kp.json")

    monkeypatch.setattr(calibrate_cli, "cmd_calibrate", failing)
    code, out, err = run_cli(["calibrate", "kp.json", "--image-size", "640x480", "--out",
                              "c.json"], monkeypatch,
                             tty=True)
    assert code == 2 and out == ""
    last = err.rstrip("\n").split("\n")[-1]
    assert last.startswith("error: kp.json") and "frame 4" in last
    assert "reading frames" in err and "\rerror" not in err


def test_the_summary_and_help_name_the_flag_and_the_page(scene_dir, tmp_path, capsys):
    """Without a subject height the summary names the flag a user types; ``export
    --help`` points at the page that holds the conventions."""
    assert main(["calibrate", str(scene_dir / "keypoints_mmpose.json"), "--intrinsics",
                 str(scene_dir / "camera.json"), "--no-refine", "--out",
                 str(tmp_path / "c.json")]) == 0
    out = capsys.readouterr().out
    assert "give --subject-height METRES" in out and "give subject_height)" not in out
    assert main(["export", "--help"]) == 0
    assert "docs/guide/exports.md" in capsys.readouterr().out.replace("\n", " ").replace(
        "  ", " ")


def test_the_render_warning_names_the_file_written(tmp_path):
    """``report --render over.mp4`` on an OpenCV build without H.264 warns about
    ``over.mp4``, the file the user asked for, not the temporary it is staged in (a fresh
    process, as a user runs it)."""
    import subprocess

    from mirrorgraph.io.video_out import open_video_writer

    writer, fourcc, _ = open_video_writer(tmp_path / "probe.mp4", 30.0, (64, 48))
    writer.release()
    if fourcc != "mp4v":
        pytest.skip(f"this OpenCV build writes {fourcc}: no warning to name")
    scene = tmp_path / "scene"
    run = [sys.executable, "-m", "mirrorgraph"]
    subprocess.run([*run, "synth", "--out", scene, "--frames", "60", "--seed", "1",
                    "--geometry", "favourable", "--formats", "mmpose", "--video-frames",
                    "12", "--quiet"], check=True, cwd=tmp_path)
    subprocess.run([*run, "calibrate", scene / "keypoints_mmpose.json", "--intrinsics",
                    scene / "camera.json", "--out", "c.json", "--quiet"], check=True,
                   cwd=tmp_path)
    proc = subprocess.run([*run, "report", "c.json", "--out", "rep", "--video",
                           scene / "clip.mp4", "--render", "over.mp4", "--frames", "2"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "over.mp4").is_file()
    warned = [ln for ln in proc.stderr.splitlines() if "mp4v" in ln]
    assert len(warned) == 1, proc.stderr
    assert warned[0].startswith("warning: over.mp4: ") and ".tmp" not in warned[0], warned[0]
    assert "over.mp4" in proc.stdout and ".tmp" not in proc.stdout


def test_calibrate_names_every_file_it_wrote(scene_dir, tmp_path):
    """The last line names the calibration and the 3D motion (a fresh process)."""
    import subprocess

    proc = subprocess.run([sys.executable, "-m", "mirrorgraph", "calibrate",
                           scene_dir / "keypoints_mmpose.json", "--intrinsics",
                           scene_dir / "camera.json", "--out", "c.json", "--joints3d", "j.npz"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert re.search(r"^wrote c\.json and j\.npz in [\d.]+ s$", proc.stdout, re.M), proc.stdout
    assert (tmp_path / "c.json").is_file() and (tmp_path / "j.npz").is_file()


def test_too_short_a_clip_for_the_graph_names_the_file(tmp_path, capfd):
    """One frame: the initial estimate passes, the graph keeps under the keypoints a
    mirror needs; the refusal is one line naming the file and the mirror, exit 2."""
    write_scene(make_scene(frames=1, seed=3), tmp_path, formats=("mmpose",))
    kp = tmp_path / "keypoints_mmpose.json"
    code = main(["calibrate", str(kp), "--intrinsics", str(tmp_path / "camera.json"),
                 "--out", str(tmp_path / "o.json"), "--quiet"])
    err = capfd.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert str(kp) in err and "mirror mirror" in err and "other cameras" not in err, err
    assert not (tmp_path / "o.json").exists()
