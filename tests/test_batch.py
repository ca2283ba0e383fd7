"""``mirrorgraph batch``: manifests, one task, the summary, and whole batches on Dask.

The Dask tests start real local clusters (a few seconds each): the default one of
``run_batch`` with two worker processes, and an in-process one whose scheduler address is
given as ``--scheduler``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.batch import (BatchResult, Recording, calibrate_recording, format_summary,
                               read_manifest, run_batch)
from mirrorgraph.cli.batch import add_parsers as add_batch_parser
from mirrorgraph.errors import InputError
from mirrorgraph.metrics import normal_angle_deg
from mirrorgraph.pipelines.mirror import CalibrateOptions
from mirrorgraph.synth import make_scene, read_ground_truth, write_scene

pytest.importorskip("dask.distributed")

FAST = CalibrateOptions(refine=False)


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """Three recordings: MMPose (60 frames), OpenPose (80 frames), and a broken one."""
    root = tmp_path_factory.mktemp("recordings")
    write_scene(make_scene(frames=60, seed=11), root / "gym", formats=("mmpose",))
    write_scene(make_scene(frames=80, seed=12, noise_std=3.0), root / "studio",
                formats=("openpose",))
    broken = root / "broken"
    write_scene(make_scene(frames=60, seed=13), broken, formats=("mmpose",))
    text = (broken / "keypoints_mmpose.json").read_text()
    (broken / "keypoints_mmpose.json").write_text(text[: len(text) // 3])   # truncated
    return root


def write_csv(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


def check_good(result: BatchResult, scene_dir: Path) -> None:
    assert result.ok, result.message
    cal = json.loads(Path(result.out).read_text())
    truth = read_ground_truth(scene_dir)
    assert np.allclose(cal["mirror"]["normal"], result.normal)
    assert normal_angle_deg(np.array(result.normal), truth["normal"]) < 1.0
    assert result.inlier_ratio > 0.8 and result.seconds > 0


# --------------------------------------------------------------------------- manifests
def test_csv_manifest_resolves_paths_and_defaults(tmp_path):
    (tmp_path / "sub").mkdir()
    csv = write_csv(tmp_path / "sub" / "runs.csv", [
        "keypoints,intrinsics,out,subject_height",
        "# a comment line",
        "a/keypoints_mmpose.json,a/camera.json,results/a.json,1.75",
        "",
        "b.npz,,,",
        "c/openpose, c/camera.yml ,, 1.6 "])
    recs = read_manifest(csv)
    base = tmp_path / "sub"
    assert [r.name for r in recs] == ["a/keypoints_mmpose.json", "b.npz", "c/openpose"]
    assert recs[0] == Recording(name="a/keypoints_mmpose.json",
                                keypoints=base / "a/keypoints_mmpose.json",
                                intrinsics=base / "a/camera.json", out=base / "results/a.json",
                                subject_height=1.75, where=f"{csv} line 3")
    assert recs[1].intrinsics is None and recs[1].subject_height is None
    assert recs[1].out == base / "b.calibration.json"
    assert recs[2].out == base / "openpose.calibration.json"
    assert recs[2].intrinsics == base / "c/camera.yml" and recs[2].subject_height == 1.6
    out = tmp_path / "outputs"
    assert read_manifest(csv, out_dir=out)[1].out == out / "b.calibration.json"
    # the keypoints column alone is enough
    only = write_csv(tmp_path / "only.csv", ["keypoints", "x.json"])
    assert read_manifest(only)[0].out == tmp_path / "x.calibration.json"


@pytest.mark.parametrize("lines, parts", [
    (["keypoints,intrinsics", "a.json,c.json,extra"], ["line 2", "3 fields"]),
    (["intrinsics,out", "c.json,o.json"], ["line 1", "'keypoints'"]),
    (["keypoints,camera", "a.json,c.json"], ["line 1", "'camera'", "unknown column"]),
    (["keypoints,keypoints", "a.json,b.json"], ["line 1", "twice"]),
    (["keypoints,out", ",o.json"], ["line 2", "field 'keypoints'", "empty"]),
    (["keypoints,subject_height", "a.json,tall"], ["line 2", "'subject_height'", "tall"]),
    (["keypoints,subject_height", "a.json,-1.7"], ["line 2", "'subject_height'"]),
    (["keypoints,subject_height", "a.json,nan"], ["line 2", "'subject_height'"]),
    (["keypoints,subject_height", "a.json,172"],
     ["line 2", "'subject_height'", "did you mean 1.72 m (centimetres given)?"]),
    (["keypoints,out", "a.json,same.json", "b.json,same.json"],
     ["line 3", "field 'out'", "line 2"]),
    (["keypoints", "x/k.json", "y/k.json"], ["line 3", "k.calibration.json", "line 2"]),
    (["keypoints"], ["lists no recording"]),
    (["# only a comment", ""], ["is empty"]),
])
def test_csv_manifest_errors_name_line_and_field(tmp_path, lines, parts):
    csv = write_csv(tmp_path / "m.csv", lines)
    with pytest.raises(InputError) as info:
        read_manifest(csv)
    msg = str(info.value)
    assert "m.csv" in msg and "\n" not in msg
    for part in parts:
        assert part in msg, (part, msg)


def test_manifest_file_errors(tmp_path):
    with pytest.raises(InputError, match="no such manifest"):
        read_manifest(tmp_path / "nope.csv")
    (tmp_path / "bin.csv").write_bytes(b"keypoints\n\xff\xfe\n")
    with pytest.raises(InputError, match="bin.csv.*UTF-8"):
        read_manifest(tmp_path / "bin.csv")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="empty.*no recording subfolders"):
        read_manifest(tmp_path / "empty")


def test_folder_manifest(scenes, tmp_path):
    recs = read_manifest(scenes)
    assert [r.name for r in recs] == ["broken", "gym", "studio"]
    gym = recs[1]
    assert gym.keypoints == scenes / "gym" / "keypoints_mmpose.json"
    assert gym.intrinsics == scenes / "gym" / "camera.json"
    assert gym.out == scenes / "gym" / "calibration.json"
    assert recs[2].keypoints == scenes / "studio" / "openpose"
    assert read_manifest(scenes, out_dir=tmp_path)[2].out == tmp_path / "studio.calibration.json"
    # a subfolder without keypoints is a recording that will fail, not a manifest error
    (tmp_path / "m" / ".hidden").mkdir(parents=True)
    (tmp_path / "m" / "notes").mkdir()
    (tmp_path / "m" / "pairs").mkdir()
    np.savez(tmp_path / "m" / "pairs" / "take1.npz", real=np.zeros((1, 17, 3)))
    recs = read_manifest(tmp_path / "m")
    assert [r.name for r in recs] == ["notes", "pairs"]
    assert recs[0].keypoints is None and recs[0].intrinsics is None
    assert recs[1].keypoints == tmp_path / "m" / "pairs" / "take1.npz"
    res = calibrate_recording(recs[0], FAST)
    assert not res.ok and "no keypoint input" in res.message and "notes" in res.message


# --------------------------------------------------------------------------- one task
def test_calibrate_recording_without_dask(scenes, tmp_path):
    good = Recording(name="gym", keypoints=scenes / "gym" / "keypoints_mmpose.json",
                     intrinsics=scenes / "gym" / "camera.json",
                     out=tmp_path / "new" / "folder" / "gym.json", subject_height=1.8)
    res = calibrate_recording(good, FAST)
    check_good(res, scenes / "gym")
    assert res.out == str(good.out) and res.distance is None
    assert any("subject_height" in w for w in res.warnings)     # needs the refinement
    # beside it, the run its report draws from
    from mirrorgraph.report import load_run
    assert json.loads(good.out.read_text())["report_data"] == "gym.report.npz"
    loaded = load_run(good.out)
    assert loaded.origin == "stored" and loaded.path == good.out.parent / "gym.report.npz"
    assert np.count_nonzero(loaded.run.inliers) == json.loads(good.out.read_text())["pairs_used"]

    out = tmp_path / "precious.json"
    out.write_text("precious")
    bad = Recording(name="broken", keypoints=scenes / "broken" / "keypoints_mmpose.json",
                    intrinsics=scenes / "broken" / "camera.json", out=out)
    res = calibrate_recording(bad, FAST)
    assert res.status == "failed" and res.out is None and res.normal is None
    assert "keypoints_mmpose.json" in res.message and "malformed JSON" in res.message
    assert "\n" not in res.message
    assert out.read_text() == "precious"
    # a bad option is a failed recording, too
    res = calibrate_recording(good, CalibrateOptions(refine=False, estimator="magic"))
    assert not res.ok and "estimator" in res.message


def test_format_summary_lists_every_result():
    results = [
        BatchResult(name="a", status="ok", out="a.json", normal=(0.1, -0.2, 0.97),
                    distance=3.25, inlier_ratio=0.954, rotation_std_deg=0.0412, seconds=1.5,
                    warnings=("w1", "w2")),
        BatchResult(name="bb", status="ok", out="bb.json", normal=(0.3, 0.0, 0.95),
                    inlier_ratio=1.0, seconds=0.25),
        BatchResult(name="broken", status="failed", message="x.json: malformed JSON",
                    seconds=0.01),
    ]
    text = format_summary(results)
    lines = text.splitlines()
    assert lines[0].split()[:3] == ["recording", "status", "normal"]
    assert "[+0.1000, -0.2000, +0.9700]" in lines[2] and "3.250 m" in lines[2]
    assert "95.4%" in lines[2] and "0.041 deg" in lines[2] and "(2 warnings)" in lines[2]
    assert "unknown" in lines[3] and "100.0%" in lines[3]
    assert lines[4].startswith("broken") and "FAILED" in lines[4]
    assert lines[4].endswith("x.json: malformed JSON")
    assert lines[-1] == "3 recordings: 2 ok, 1 failed"
    assert format_summary([]).splitlines()[-1] == "0 recordings: 0 ok, 0 failed"


# --------------------------------------------------------------------------- on Dask
def test_run_batch_on_a_local_cluster(scenes, tmp_path):
    csv = write_csv(tmp_path / "runs.csv", [
        "keypoints,intrinsics,out,subject_height",
        f"{scenes / 'gym' / 'keypoints_mmpose.json'},{scenes / 'gym' / 'camera.json'},"
        "out/gym.json,",
        f"{scenes / 'broken' / 'keypoints_mmpose.json'},{scenes / 'broken' / 'camera.json'},"
        "out/broken.json,",
        f"{scenes / 'studio' / 'openpose'},{scenes / 'studio' / 'camera.json'},,1.7"])
    recs = read_manifest(csv)
    seen = []
    results = run_batch(recs, workers=2, options=FAST,
                        progress=lambda r, done, total: seen.append((r.name, done, total)))
    assert [r.name for r in results] == [r.name for r in recs]
    gym, broken, studio = results
    check_good(gym, scenes / "gym")
    check_good(studio, scenes / "studio")
    assert studio.out == str(tmp_path / "openpose.calibration.json")
    assert broken.status == "failed" and not (tmp_path / "out" / "broken.json").exists()
    assert "broken" in broken.message and "keypoints_mmpose.json" in broken.message
    assert sorted(d for _, d, _ in seen) == [1, 2, 3] and {t for *_, t in seen} == {3}

    summary = format_summary(results)
    for r in recs:
        assert r.name in summary
    assert "FAILED" in summary and summary.endswith("3 recordings: 2 ok, 1 failed")


def batch_cli(argv: list[str]) -> int:
    """``mirrorgraph batch ...`` through cli.batch.add_parsers (as cli.build_parser wires it)."""
    parser = argparse.ArgumentParser(prog="mirrorgraph")
    sub = parser.add_subparsers(dest="command", required=True)
    add_batch_parser(sub)
    args = parser.parse_args(argv)
    return args.func(args)


def test_batch_command_on_an_existing_scheduler(scenes, tmp_path, capsys):
    from dask.distributed import LocalCluster

    report = tmp_path / "report.json"
    # an in-process cluster listening on TCP stands in for a remote one
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp://",
                      dashboard_address=None) as cluster:
        code = batch_cli(["batch", str(scenes), "--scheduler", cluster.scheduler_address,
                          "--no-refine", "--out-dir", str(tmp_path / "cal"),
                          "--summary", str(report)])
    cap = capsys.readouterr()
    assert code == 2, cap.err                       # one recording failed
    assert "calibrating 3 recordings on tcp://" in cap.err
    assert cap.err.count("FAILED") == 1 and "[3/3]" in cap.err
    assert cap.out.rstrip().endswith("3 recordings: 2 ok, 1 failed")
    for name in ("broken", "gym", "studio"):
        assert name in cap.out
    assert (tmp_path / "cal" / "gym.calibration.json").is_file()
    assert not (tmp_path / "cal" / "broken.calibration.json").exists()
    rows = json.loads(report.read_text())
    assert [r["status"] for r in rows] == ["failed", "ok", "ok"]
    assert rows[1]["normal"] == pytest.approx(
        json.loads((tmp_path / "cal" / "gym.calibration.json").read_text())["mirror"]["normal"])


def test_batch_command_exit_codes_without_a_cluster(tmp_path, capsys):
    with pytest.raises(InputError, match="no such manifest"):
        batch_cli(["batch", str(tmp_path / "missing.csv")])
    with pytest.raises(InputError, match="field 'workers'"):
        run_batch([Recording(name="x", keypoints=None, intrinsics=None, out=tmp_path / "x")],
                  workers=0)
    assert run_batch([]) == []


@pytest.mark.parametrize("option", ["--seed=-1", "--seed=x", "--seed=1.5"])
def test_batch_refuses_the_seeds_calibrate_refuses(tmp_path, capsys, option):
    from mirrorgraph.cli import main

    assert main(["calibrate", "kp.json", "--out", str(tmp_path / "c.json"), option]) == 2
    calibrate_err = capsys.readouterr().err
    assert main(["batch", str(tmp_path / "missing.csv"), option]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "--seed" in err
    same = lambda e: e.split("--seed")[1].split(" (see ")[0]     # noqa: E731 - the message
    assert same(err) == same(calibrate_err)


def test_batch_is_wired_into_the_cli(tmp_path, capsys):
    from mirrorgraph.cli import build_parser, main

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    if "batch" not in sub.choices:
        pytest.skip("cli.build_parser does not add the batch command yet")
    assert main(["batch", str(tmp_path / "missing.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "missing.csv" in err


# --------------------------------------------------------------------------- calibrate's options
@pytest.fixture(scope="module")
def scheduler():
    """An in-process cluster listening on TCP (a remote one's stand-in), its address."""
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp://",
                      dashboard_address=None) as cluster:
        yield cluster.scheduler_address


def _gym_alone(scenes, tmp_path, subject_height: str = "") -> Path:
    """A manifest of the gym recording only, writing ``tmp_path/gym.json``."""
    gym = scenes / "gym"
    manifest = tmp_path / "runs.csv"
    manifest.write_text("keypoints,intrinsics,out,subject_height\n"
                        f"{gym / 'keypoints_mmpose.json'},{gym / 'camera.json'},"
                        f"{tmp_path / 'gym.json'},{subject_height}\n")
    return manifest


def test_batch_joints_are_the_joints_calibrated_from(scenes, scheduler, tmp_path, capsys):
    chosen = ["left_shoulder", "right_shoulder", "left_hip", "right_hip", "left_knee",
              "right_knee"]
    used = {}
    for name, extra in (("default", []), ("chosen", ["--joints", " , ".join(chosen)])):
        code = batch_cli(["batch", str(_gym_alone(scenes, tmp_path)), "--scheduler", scheduler,
                          "--no-refine", "--quiet", *extra])
        assert code == 0, capsys.readouterr().out
        used[name] = json.loads((tmp_path / "gym.json").read_text())["input"]["joints"]
    assert used["chosen"] == chosen
    assert len(used["default"]) > len(chosen) and set(chosen) < set(used["default"])


def test_batch_scale_from_limbs_reaches_the_scale(scenes, scheduler, tmp_path, capsys):
    # the manifest's height replaces the options' one: the scale source must survive that
    code = batch_cli(["batch", str(_gym_alone(scenes, tmp_path, subject_height="1.75")),
                      "--scheduler", scheduler, "--scale-from", "limbs", "--quiet"])
    assert code == 0, capsys.readouterr().out
    cal = json.loads((tmp_path / "gym.json").read_text())
    assert cal["input"]["scale_from"] == "limbs" and cal["input"]["subject_height"] == 1.75
    assert cal["refinement"]["scale_source"].endswith("as asked (scale_from = limbs)")
    assert cal["mirror"]["distance"] is not None


def test_a_rig_is_a_recording_too(tmp_path):
    """One options object, one batch: a folder holding a single mirror's recording and a
    rig's (``rig.toml``) calibrates both, each as its front end does; the rig's cameras
    come within the synthetic truth and its files are those of ``calibrate-rig``."""
    from mirrorgraph.metrics import rotation_error_deg
    from mirrorgraph.result.rig import read_rig_calibration
    from mirrorgraph.synth import make_rig, write_rig

    root = tmp_path / "recs"
    write_scene(make_scene(frames=60, seed=11), root / "gym", formats=("mmpose",))
    rig = make_rig("2cams1mirror", frames=80, seed=3)
    write_rig(rig, root / "studio")
    recs = read_manifest(root)
    assert recs[1].keypoints == root / "studio" / "rig.toml" and recs[1].intrinsics is None
    res = calibrate_recording(recs[1], CalibrateOptions(subject_height=rig.subject_height))
    assert res.ok and res.cameras == 2 and res.normal is None, res.message
    cal = read_rig_calibration(res.out)
    err = rotation_error_deg(cal.cameras[1].pose[:3, :3], np.asarray(rig.poses[1])[:3, :3])
    assert err < 0.5
    assert (root / "studio" / "calibration.toml").is_file()
    assert "rig of 2 cameras" in format_summary([res])
    # a CSV row naming a rig file with intrinsics is refused, naming the line and field
    csv = write_csv(tmp_path / "m.csv", ["keypoints,intrinsics",
                                         f"{root / 'studio' / 'rig.toml'},{root / 'gym' / 'camera.json'}"])
    bad = calibrate_recording(read_manifest(csv)[0], FAST)
    assert not bad.ok and "m.csv line 2" in bad.message and "intrinsics" in bad.message
