"""Cameras not started together: every camera's time offset found from the people, against
synthetic rigs with known offsets (whole and fractional, both signs)."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.metrics import rotation_error_deg
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.pipelines.rig import calibrate_rig
from mirrorgraph.rigs.clocks import resample
from mirrorgraph.synth.rig import write_rig
from mirrorgraph.synth.rig_clocks import unsynchronised_rig

#: cam02 late by whole frames, cam03 early by a fraction, cam04 late by a fraction.
OFFSETS = (0.0, 7.0, -4.5, 2.3)


@pytest.fixture(scope="module")
def offset_rig(tmp_path_factory):
    rig = unsynchronised_rig("4cams", OFFSETS, frames=300, seed=0, noise_std=4.0)
    path = write_rig(rig, tmp_path_factory.mktemp("clocks"))
    return rig, path, calibrate_rig(path)


def test_offsets_found_to_a_tenth_of_a_frame_with_stds_that_cover(offset_rig):
    rig, _, cal = offset_rig
    found = np.array([c.time_offset_frames for c in cal.cameras])
    std = np.array([c.time_offset_std for c in cal.cameras])
    assert [c.time_offset_source for c in cal.cameras] == ["reference"] + ["search"] * 3
    err = np.abs(found - np.array(OFFSETS))
    assert err.max() < 0.15, found
    assert np.all(err[1:] < 4 * std[1:]), (found, std)
    for c, P in zip(cal.cameras[1:], rig.poses[1:]):
        assert rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3]) < 0.6


def test_offsets_in_the_json_and_the_summary(offset_rig):
    _, _, cal = offset_rig
    doc = cal.to_dict()
    cam = {c["name"]: c for c in doc["cameras"]}
    assert cam["cam02"]["time_offset_frames"] == pytest.approx(7.0, abs=0.15)
    assert cam["cam02"]["time_offset_std"] > 0 and cam["cam01"]["time_offset_std"] == 0
    assert "time offset +7.0" in cal.summary() or "time offset +6.9" in cal.summary(), \
        cal.summary()
    # the rig file said 0: the warning names what the people say
    assert any("cam02" in w and "frame_offset = 0" in w for w in cal.warnings), cal.warnings


def test_fixed_offsets_are_taken_as_given(offset_rig, tmp_path):
    """With --fixed-offsets the rig file's offsets hold: the right ones give the rig, and
    nothing is searched."""
    rig, path, _ = offset_rig
    text = path.read_text().split("[[cameras]]")
    for i, o in enumerate(OFFSETS):
        text[i + 1] = text[i + 1].replace("frame_offset = 0", f"frame_offset = {int(o)}")
    fixed = path.parent / "fixed.toml"
    fixed.write_text("[[cameras]]".join(text))
    cal = calibrate_rig(fixed, CalibrateOptions(time_offsets="fixed"))
    assert [c.time_offset_frames for c in cal.cameras] == [int(o) for o in OFFSETS]
    assert [c.time_offset_source for c in cal.cameras] == ["reference"] + ["given"] * 3
    assert not any("time offset" in w for w in cal.warnings)


def test_given_offsets_centre_the_search(offset_rig):
    """A rig file's offset near the truth is the search's centre: an offset 20 frames off
    the rig file's zero is found within a window of 15 about it."""
    _, path, _ = offset_rig
    text = path.read_text().split("[[cameras]]")
    text[2] = text[2].replace("frame_offset = 0", "frame_offset = 12")
    near = path.parent / "near.toml"
    near.write_text("[[cameras]]".join(text))
    cal = calibrate_rig(near)
    assert cal.cameras[1].time_offset_frames == pytest.approx(7.0, abs=0.15)
    assert any("cam02" in w and "frame_offset = 12" in w for w in cal.warnings)


def test_resample_moves_a_trajectory_by_a_fraction():
    t = np.arange(10, dtype=float)
    a = np.stack([t, 2 * t, np.ones(10)], -1)[:, None, :]          # (T, 1, 3)
    b = resample(a, 0.25)
    assert np.allclose(b[:-1, 0, 0], t[:-1] + 0.25) and np.allclose(b[:-1, 0, 1], 2 * t[:-1] + 0.5)
    assert np.isnan(b[-1, 0, 0]) and b[-1, 0, 2] == 0
    c = resample(a, -1.5)
    assert np.allclose(c[2:, 0, 0], t[2:] - 1.5) and np.isnan(c[:2, 0, 0]).all()
