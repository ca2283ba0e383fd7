"""Cameras not started together: every camera's time offset found from the people, against
synthetic rigs with known offsets (whole and fractional, both signs) and a synchronised
one that must stay synchronised."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.io import write_keypoints
from mirrorgraph.metrics import rotation_error_deg
from mirrorgraph.pipelines.rig import calibrate_rig
from mirrorgraph.rigs.clocks import FRACTION_REACH, _sandwich, resample
from mirrorgraph.rigs.config import load_rig_config
from mirrorgraph.rigs.observations import load_observations
from mirrorgraph.synth.rig import write_rig
from mirrorgraph.synth.rig_clocks import unsynchronised_rig

#: cam02 late by whole frames, cam03 early by a fraction, cam04 late by a fraction.
OFFSETS = (0.0, 7.0, -4.5, 2.3)
#: Frames of the synthetic rigs (30 fps): short, for the suite's time.
FRAMES = 100


@pytest.fixture(scope="module")
def offset_rig(tmp_path_factory):
    rig = unsynchronised_rig("4cams", OFFSETS, frames=FRAMES, seed=0, noise_std=4.0)
    path = write_rig(rig, tmp_path_factory.mktemp("clocks"))
    return rig, path, calibrate_rig(path)


def _with_offsets(path, name: str, offsets: dict[str, int], keep=None):
    """A copy of a synthetic rig file with some cameras' ``frame_offset`` changed (and only
    the cameras ``keep``, where given)."""
    head, *tables = path.read_text().split("[[cameras]]")
    out = []
    for t in tables:
        cam = t.split('name = "')[1].split('"')[0]
        if keep is not None and cam not in keep:
            continue
        if cam in offsets:
            t = t.replace("frame_offset = 0", f"frame_offset = {offsets[cam]}")
        out.append(t)
    new = path.parent / name
    new.write_text("[[cameras]]".join([head, *out]))
    return new


def test_offsets_found_to_a_tenth_of_a_frame_with_stds_that_cover(offset_rig):
    rig, _, cal = offset_rig
    found = np.array([c.time_offset_frames for c in cal.cameras])
    std = np.array([c.time_offset_std for c in cal.cameras])
    assert [c.time_offset_source for c in cal.cameras] == ["reference"] + ["search"] * 3
    err = np.abs(found - np.array(OFFSETS))
    assert err.max() < 0.15, found
    assert np.all(err[1:] < 3 * std[1:] + 0.02), (found, std)
    for c, P in zip(cal.cameras[1:], rig.poses[1:]):
        assert rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3]) < 0.6


def test_offsets_in_the_json_and_the_summary(offset_rig):
    _, _, cal = offset_rig
    doc = cal.to_dict()
    cam = {c["name"]: c for c in doc["cameras"]}
    assert cam["cam02"]["time_offset_frames"] == pytest.approx(7.0, abs=0.15)
    assert cam["cam02"]["time_offset_std"] > 0 and cam["cam01"]["time_offset_std"] == 0
    line = next(ln for ln in cal.summary().splitlines() if ln.startswith("camera cam02"))
    assert "time offset +7.0" in line or "time offset +6.9" in line, line
    # the rig file said 0: the warning names what the people say
    assert any("cam02" in w and "frame_offset = 0" in w for w in cal.warnings), cal.warnings


def test_a_synchronised_rig_stays_synchronised(tmp_path):
    """Every camera on one clock: no camera is moved, by a whole frame or a fraction."""
    rig = unsynchronised_rig("4cams", (0, 0, 0, 0), frames=FRAMES, seed=0, noise_std=4.0)
    obs = load_observations(load_rig_config(write_rig(rig, tmp_path)))
    assert [c.clock.offset for c in obs.cameras] == [0.0] * 4, [c.clock for c in obs.cameras]
    assert not any("time offset" in w for w in obs.warnings), obs.warnings


def test_fixed_offsets_are_taken_as_given(offset_rig):
    """With the offsets taken as given (``--fixed-offsets``) the rig file's hold and nothing
    is searched; the frames are placed by them."""
    _, path, _ = offset_rig
    fixed = _with_offsets(path, "fixed.toml", {"cam02": 7, "cam03": -4, "cam04": 2})
    obs = load_observations(load_rig_config(fixed), time_offsets="fixed")
    assert [c.clock.offset for c in obs.cameras] == [0, 7, -4, 2]
    assert [c.clock.source for c in obs.cameras] == ["reference"] + ["given"] * 3
    assert not any("time offset" in w for w in obs.warnings)


def test_given_offsets_centre_the_search(offset_rig):
    """A rig file's offset is the search's centre: cam02's offset (7) lies inside a window
    of 4 frames about the rig file's 10, outside one about 0 (found at its edge, said)."""
    _, path, _ = offset_rig
    near = _with_offsets(path, "near.toml", {"cam02": 10}, keep=("cam01", "cam02"))
    obs = load_observations(load_rig_config(near), offset_window=4)
    assert obs.cameras[1].clock.offset == pytest.approx(7.0, abs=0.15)
    assert any("cam02" in w and "frame_offset = 10" in w for w in obs.warnings), obs.warnings
    far = _with_offsets(path, "far.toml", {}, keep=("cam01", "cam02"))
    obs = load_observations(load_rig_config(far), offset_window=4)
    assert obs.cameras[1].clock.offset <= 4 + FRACTION_REACH
    assert any("cam02" in w and "edge of the search window" in w for w in obs.warnings)


def test_resample_moves_a_trajectory_by_a_fraction():
    t = np.arange(10, dtype=float)
    a = np.stack([t, 2 * t, np.ones(10)], -1)[:, None, :]          # (T, 1, 3)
    b = resample(a, 0.25)
    assert np.allclose(b[:-1, 0, 0], t[:-1] + 0.25) and np.allclose(b[:-1, 0, 1], 2 * t[:-1] + 0.5)
    assert np.isnan(b[-1, 0, 0]) and b[-1, 0, 2] == 0
    c = resample(a, -1.5)
    assert np.allclose(c[2:, 0, 0], t[2:] - 1.5) and np.isnan(c[:2, 0, 0]).all()


def test_a_camera_at_half_the_frame_rate_is_put_on_the_rig_clock(tmp_path):
    """cam03 films at 30 fps beside 60 fps cameras, 3 frames (of 60 fps) early; cam02 is 5
    late: both found from each input's own frame rate, cam03's frames on every other frame
    of the rig's clock."""
    offsets = (0.0, 5.0, -3.0, 0.0)
    rig = unsynchronised_rig("4cams", offsets, frames=2 * FRAMES, upsample=2, fps=60.0,
                             rates=(1, 1, 2, 1), seed=0, noise_std=4.0)
    path = write_rig(rig, tmp_path)
    for name, det in rig.detections.items():      # the files say each camera's frame rate
        write_keypoints(det, tmp_path / "pose" / f"{name}_json", "openpose", meta=True)
    obs = load_observations(load_rig_config(path))
    clocks = [c.clock for c in obs.cameras]
    assert [c.whole for c in clocks] == [0, 5, -3, 0], clocks
    assert abs(clocks[1].offset - 5.0) < 0.15, clocks
    assert any("cam03" in w and "30 fps" in w for w in obs.warnings), obs.warnings
    seen = np.isfinite(obs.cameras[2].real[..., 0]).any(-1)
    frames = obs.frame_ids[seen]
    assert len(frames) > 0.4 * FRAMES and np.all((frames - 3) % 2 == 0), frames[:10]


def test_the_fractions_std_matches_the_spread_of_its_estimate():
    """The M-estimator's sandwich std of a cost summed over blocks (each block's own
    quadratic about a random centre): over many draws, within 15 % of the spread of the
    minima, and larger for a flatter cost."""
    rng = np.random.default_rng(0)
    grid = np.linspace(-1.5, 1.5, 13)
    minima, stds, flat = [], [], []
    for _ in range(400):
        m = rng.normal(0.2, 0.5, 30)                       # the blocks' own minima
        a = rng.uniform(0.5, 2.0, 30)                      # their curvatures
        Cb = a[:, None] * (grid[None] - m[:, None]) ** 2   # (B, G)
        u, s = _sandwich(grid, Cb)
        minima.append(u)
        stds.append(s)
        flat.append(_sandwich(grid, 0.1 * Cb + 1.0)[1] / s)
    assert np.mean(stds) == pytest.approx(np.std(minima), rel=0.15)
    assert np.allclose(flat, 1.0)      # a scaled cost: the same std
    x, Cb = grid, np.ones((30, 13)) + rng.normal(0, 1e-3, (30, 13))
    assert _sandwich(x, Cb)[1] > 1.0 or not np.isfinite(_sandwich(x, Cb)[0])
