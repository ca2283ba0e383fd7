"""Cameras not started together: every camera's time offset found from the people, against
synthetic rigs with known offsets (whole and fractional, both signs) and a synchronised
one that must stay synchronised."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.io import write_keypoints
from mirrorgraph.metrics import rotation_error_deg
from mirrorgraph.pipelines.rig import calibrate_rig
from mirrorgraph.rigs.clocks import (FRACTION_REACH, ClockEstimate, _sandwich, on_rig_clock,
                                     resample, rig_rates)
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
    assert any("cam03 30" in w and "60 fps clock" in w for w in obs.warnings), obs.warnings
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


def _with_rates(path, fps: dict[str, float], name: str = "rates.toml", head: str = ""):
    """A copy of a synthetic rig file with each camera's ``fps`` (and ``head`` lines at the
    top)."""
    text = path.read_text()
    for cam, f in fps.items():
        text = text.replace(f'name = "{cam}"\n', f'name = "{cam}"\nfps = {f}\n', 1)
    new = path.parent / name
    new.write_text(head + text)
    return new


def test_rig_rates_put_every_camera_on_the_finest_whole_multiple_of_the_reference():
    assert rig_rates([60.0, 60.0, 30.0]) == ([1.0, 1.0, 2.0], 1, 60.0)
    assert rig_rates([30.0, 60.0, 60.0]) == ([2.0, 1.0, 1.0], 2, 60.0)
    rates, unit, fps = rig_rates([30.0, 25.0, 29.97, 30.0001])
    assert unit == 1 and fps == 30.0 and rates[0] == 1.0 and rates[3] == 1.0
    assert rates[1] == pytest.approx(1.2) and rates[2] == pytest.approx(30 / 29.97)
    assert rig_rates([None, 60.0]) == ([1.0, 1.0], 1, None)
    assert rig_rates([30.0, None]) == ([1.0, 1.0], 1, 30.0)


def test_a_slower_camera_is_placed_at_the_instants_of_the_rig_frames():
    """A 30 fps camera (2 rig frames a frame) whose frame g shows rig frame 2 g - 1.3: each
    frame at the rig frame nearest, the keypoints there interpolated; a trajectory linear in
    time is exact. A 25 fps camera on a 30 fps clock (1.2 rig frames a frame) likewise."""
    for rate, offset in ((2.0, 1.3), (2.0, -0.6), (1.2, 0.4), (1.0, -2.25)):
        g = np.arange(40)
        truth = lambda t: np.stack([3 * t + 1, -2 * t, np.ones_like(t)], -1)[:, None]  # noqa: E731
        a = truth(rate * g - offset)                         # (T, 1, 3): x, y = f(rig time)
        a[17, 0, :2] = np.nan                                # one frame unseen
        a[17, 0, 2] = 0
        clock = ClockEstimate(offset=offset, std=0.0, source="search")
        rows, b = on_rig_clock(a, g, rate, clock)
        assert np.all(np.diff(rows) > 0)
        assert np.all(np.abs(rows - (rate * g[-1] - offset)) <= rate * g[-1] + 1)
        ok = b[:, 0, 2] > 0
        assert ok.sum() >= len(g) - 4
        assert np.allclose(b[ok, 0, :2], truth(rows[ok].astype(float))[:, 0, :2])
        assert np.isnan(b[~ok, 0, 0]).all()


def test_a_clock_rate_places_the_frames_by_it():
    """A camera whose clock runs 1 + 1e-3 fast: its frame g at rig instant (g - o) / rate."""
    g = np.arange(0, 2000, 1)
    rate = 1 + 1e-3
    truth = lambda t: np.stack([0.5 * t, np.zeros_like(t), np.ones_like(t)], -1)[:, None]  # noqa: E731
    a = truth((g - 3.0) / rate)
    rows, b = on_rig_clock(a, g, 1.0, ClockEstimate(offset=3.0, std=0, source="search",
                                                    rate=rate))
    ok = b[:, 0, 2] > 0
    assert np.allclose(b[ok, 0, 0], 0.5 * rows[ok])
    assert len(rows) == len(g) - 2         # two frames fall on one rig frame: the nearest


def test_the_rig_file_names_a_frame_rate_and_the_clock_drift(tmp_path):
    rig = unsynchronised_rig("4cams", (0, 0, 0, 0), frames=10, seed=0)
    path = write_rig(rig, tmp_path)
    cfg = load_rig_config(_with_rates(path, {"cam02": 30, "cam03": 29.97},
                                      head="clock_drift = true\n"))
    assert [c.fps for c in cfg.cameras] == [None, 30.0, 29.97, None]
    assert cfg.clock_drift is True and load_rig_config(path).clock_drift is False
    for bad in ("0", "-30", '"fast"', "true"):
        with pytest.raises(InputError, match="cameras.1..fps"):
            load_rig_config(_with_rates(path, {"cam02": bad}, name="bad.toml"))
    with pytest.raises(InputError, match="clock_drift"):
        load_rig_config(_with_rates(path, {}, name="bad.toml", head="clock_drift = 1\n"))


#: A 60 fps rig: cam02 at 60 fps late by a fraction, cam03 and cam04 at 30 fps, one early
#: and one late by fractions (rig frames, 60 fps).
MIXED = (0.0, 4.6, -3.3, 2.7)


@pytest.fixture(scope="module")
def mixed_rig(tmp_path_factory):
    rig = unsynchronised_rig("4cams", MIXED, frames=2 * FRAMES, fps=60.0, rates=(1, 1, 2, 2),
                             seed=0, noise_std=4.0)
    out = tmp_path_factory.mktemp("mixed")
    path = _with_rates(write_rig(rig, out), {"cam01": 60, "cam02": 60, "cam03": 30,
                                             "cam04": 30})
    return rig, path, calibrate_rig(path)


def test_a_30_and_60_fps_rig_finds_fractional_offsets_of_either_sign(mixed_rig):
    """Two 30 fps cameras beside 60 fps ones, offsets fractions of a 60 fps frame either
    way: each found within a quarter of a 60 fps frame (4 ms) with a std that covers it,
    in frames and in seconds, and every camera where it is."""
    rig, _, cal = mixed_rig
    found = np.array([c.time_offset_frames for c in cal.cameras])
    std = np.array([c.time_offset_std for c in cal.cameras])
    err = np.abs(found - np.array(MIXED))
    assert err.max() < 0.25, (found, std)
    assert np.all(err[1:] < 3 * std[1:] + 0.02), (found, std)
    secs = np.array([c.time_offset_s for c in cal.cameras])
    assert np.allclose(secs, found / 60.0)
    assert [c.fps for c in cal.cameras] == [60.0, 60.0, 30.0, 30.0]
    for c, P in zip(cal.cameras[1:], rig.poses[1:]):
        assert rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3]) < 0.6
    doc = {c["name"]: c for c in cal.to_dict()["cameras"]}
    assert doc["cam03"]["time_offset_s"] == pytest.approx(MIXED[2] / 60, abs=0.15 / 60)
    assert doc["cam03"]["fps"] == 30.0
    line = next(ln for ln in cal.summary().splitlines() if ln.startswith("camera cam03"))
    assert " ms)" in line, line


def test_a_30_fps_reference_beside_60_fps_cameras_keeps_every_60_fps_frame(tmp_path):
    """The first camera films at 30 fps, the others at 60: the rig's clock is 60 fps (each
    60 fps frame its own row), the offsets in the first camera's frames (half of the 60 fps
    ones) and seconds."""
    offsets = (0.0, 3.0, -5.4, 1.6)                      # 60 fps frames
    rig = unsynchronised_rig("4cams", offsets, frames=2 * FRAMES, fps=60.0,
                             rates=(2, 1, 1, 1), seed=0, noise_std=4.0)
    path = _with_rates(write_rig(rig, tmp_path), {"cam01": 30, "cam02": 60, "cam03": 60,
                                                  "cam04": 60})
    obs = load_observations(load_rig_config(path))
    assert obs.fps == 60.0
    seen = [np.isfinite(c.real[..., 0]).any(-1).sum() for c in obs.cameras]
    assert seen[1] > 1.5 * seen[0], seen                 # 60 fps frames not merged in pairs
    ref = [c.clock.reference_frames[0] for c in obs.cameras]
    assert np.allclose(ref, np.array(offsets) / 2, atol=0.1), ref
    assert np.allclose([c.clock.seconds[0] for c in obs.cameras], np.array(offsets) / 60,
                       atol=0.2 / 60)


def test_a_mixed_rig_is_calibrated_as_well_as_the_same_rig_at_one_rate(mixed_rig, tmp_path):
    """The same scene and offsets filmed by four 60 fps cameras: the mixed rig's rotations
    within 0.1 deg of that rig's (cam03 and cam04 have half its frames)."""
    rig, _, cal = mixed_rig
    same = unsynchronised_rig("4cams", MIXED, frames=2 * FRAMES, fps=60.0, seed=0,
                              noise_std=4.0)
    base = calibrate_rig(write_rig(same, tmp_path))
    for c, b, P in zip(cal.cameras[1:], base.cameras[1:], rig.poses[1:]):
        mixed = rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3])
        one_rate = rotation_error_deg(b.pose[:3, :3], np.asarray(P)[:3, :3])
        assert mixed < one_rate + 0.1, (c.name, mixed, one_rate)


def test_a_drifting_clock_is_measured_where_the_rig_file_asks(tmp_path):
    """cam02's clock runs 0.3 % fast, cam03's 0.2 % slow (0.9 and 0.6 frames over the
    clip): with ``clock_drift = true`` each rate is found within 3 stds (its std under
    1e-3) and applied, the offsets at the rig's frame 0 within 3 stds; cam04's steady
    clock stays at 1. Without it the rates are 1 and cam02's offset is the clip's mean."""
    offsets, drifts = (0, 3.3, -2.6, 1.4), (1, 1.003, 0.998, 1.0)
    rig = unsynchronised_rig("4cams", offsets, frames=3 * FRAMES, drifts=drifts, seed=0,
                             noise_std=4.0)
    path = write_rig(rig, tmp_path)
    obs = load_observations(load_rig_config(_with_rates(path, {}, head="clock_drift = true\n")))
    clocks = [c.clock for c in obs.cameras]
    for c, o, d in zip(clocks[1:3], offsets[1:3], drifts[1:3]):
        assert c.rate_std < 1e-3 and abs(c.rate - d) < 3 * c.rate_std and c.rate != 1, c
        assert abs(c.offset - o) < 3 * c.std + 0.05, c
    assert clocks[3].rate == 1.0 and np.isfinite(clocks[3].rate_std), clocks[3]
    assert "not significant" in clocks[3].note
    plain = load_observations(load_rig_config(path))
    assert [c.clock.rate for c in plain.cameras] == [1.0] * 4
    middle = offsets[1] + (drifts[1] - 1) * 0.5 * 3 * FRAMES     # the clip's mean offset
    assert abs(plain.cameras[1].clock.offset - middle) < 0.2, plain.cameras[1].clock


def test_a_rig_of_two_cameras_at_60_and_30_fps_finds_the_fraction(tmp_path):
    """Two cameras (no third to triangulate from), the second at 30 fps 2.6 frames (of 60
    fps) early: the pair's fraction on the slower camera's own samples."""
    rig = unsynchronised_rig("4cams", (0, -2.6, 0, 0), frames=2 * FRAMES, fps=60.0,
                             rates=(1, 2, 1, 1), seed=0, noise_std=4.0)
    path = _with_rates(write_rig(rig, tmp_path), {"cam01": 60, "cam02": 30})
    two = _with_offsets(path, "two.toml", {}, keep=("cam01", "cam02"))
    clock = load_observations(load_rig_config(two)).cameras[1].clock
    assert abs(clock.offset + 2.6) < 0.15 and abs(clock.offset + 2.6) < 3 * clock.std, clock
