"""The rig's report (:mod:`mirrorgraph.report.rig`) of a run of every person
(``calibrate-rig --people all --report``, in a fresh process): every person's path,
skeleton, residuals and kept share, against the synthetic rig's ground truth."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mirrorgraph.synth.rig_people import make_rig_people, write_rig_people

PEOPLE = 3


@pytest.fixture(scope="module")
def people_run(tmp_path_factory):
    pytest.importorskip("matplotlib", reason="the plot extra; the test command installs it")
    tmp = tmp_path_factory.mktemp("rig_people_report")
    truth = make_rig_people(3, PEOPLE, frames=40, seed=6)
    path = write_rig_people(truth, tmp / "rig", subject_height=1.75)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    proc = subprocess.run([sys.executable, "-m", "mirrorgraph", "calibrate-rig", str(path),
                           "--out", str(tmp / "c.toml"), "--people", "all", "--report",
                           str(tmp / "rep")], capture_output=True, text=True, env=env,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr
    assert f"people: {PEOPLE} in the one graph" in proc.stdout
    return truth, tmp, json.loads((tmp / "c.json").read_text())


def test_every_persons_residuals_and_paths_are_written(people_run):
    truth, tmp, doc = people_run
    for name in ("rig_top_view.png", "rig_residuals.png"):
        assert (tmp / "rep" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    people = doc["refinement"]["people"]
    assert people["count"] == PEOPLE and len(people["views"]) == PEOPLE
    pooled = doc["refinement"]["views"]
    for v, record in pooled.items():       # every person's share adds up to the view's
        assert sum(t[v]["observations"] for t in people["views"] if v in t) == \
            record["observations"]
        assert sum(t[v]["offered"] for t in people["views"] if v in t) == record["offered"]
    for t in people["views"]:
        assert set(t) == set(truth.camera_names)
        assert all(0 < r["observations"] <= r["offered"] and 0 < r["rms_px"] < 12
                   for r in t.values())
    # each path where a different true person walks (the rig's scale from its cameras)
    est = np.array([c["pose_camera_to_world"] for c in doc["cameras"]])[:, :3, 3]
    true = np.array(truth.poses)[:, :3, 3]
    s = float(np.sum(est * true) / np.sum(true * true))
    paths = doc["people_paths"]
    assert len(paths) == PEOPLE and paths[0] == doc["subject_path"]
    where = np.array([np.median(np.array(p["xyz"]), 0) for p in paths]) / s
    X = truth.joints3d
    true_where = np.array([np.nanmedian(np.nanmean(X[p], axis=1), 0) for p in range(PEOPLE)])
    gap = np.linalg.norm(where[:, None, [0, 2]] - true_where[None, :, [0, 2]], axis=-1)
    assert sorted(gap.argmin(1)) == list(range(PEOPLE)), gap
    assert gap.min(1).max() < 0.25, gap


def test_every_person_is_drawn(people_run):
    import matplotlib.pyplot as plt

    from mirrorgraph.report.rig import rig_residuals, rig_top_view
    from mirrorgraph.result.rig import read_rig_calibration

    truth, tmp, doc = people_run
    calib = read_rig_calibration(tmp / "c.json")
    assert calib.people_joints3d.shape[0] == PEOPLE
    fig = rig_top_view(calib)
    gids = [ln.get_gid() for ln in fig.axes[0].get_lines()]
    assert {f"path P{p}" for p in range(PEOPLE)} <= set(gids)
    assert not any(str(g).startswith("skeleton") for g in gids)    # no joints in the JSON
    plt.close(fig)
    fig = rig_residuals(calib)
    rms, keep = fig.axes[:2]
    for p, table in enumerate(doc["refinement"]["people"]["views"]):
        bars = [b for b in rms.patches if b.get_gid() == f"rms P{p}"]
        assert np.allclose(sorted(b.get_height() for b in bars),
                           sorted(r["rms_px"] for r in table.values()))
        shares = [b.get_height() for b in keep.patches if b.get_gid() == f"keep P{p}"]
        assert len(shares) == len(truth.camera_names)
        assert np.allclose(shares, [100 * table[c]["observations"] / table[c]["offered"]
                                    for c in truth.camera_names])
    plt.close(fig)
    # with every person's joints at hand (the run's own, here the truth's): their skeletons
    ok = np.isfinite(truth.joints3d).all(-1)
    full = replace(calib, frame_ids=truth.frame_ids, people_joints3d=truth.joints3d,
                   people_valid=ok, joints3d=truth.joints3d[0], valid=ok[0],
                   skeleton=truth.skeleton.name)
    fig = rig_top_view(full)
    gids = [ln.get_gid() for ln in fig.axes[0].get_lines()]
    bones = len(truth.skeleton.bone_index)
    for p in range(PEOPLE):
        assert gids.count(f"skeleton P{p}") >= 0.8 * bones, (p, gids.count(f"skeleton P{p}"))
    assert "skeletons at frame" in fig.axes[0].get_title()
    plt.close(fig)
