"""Cameras not started together: time offsets found from the people (``mirrorgraph.rigs.clocks``).

Two parts, side by side in one run:

1. **Synthetic** 4-camera rigs with known offsets (``mirrorgraph.synth.rig_clocks``, whole
   and fractional, both signs; 300 frames at 30 fps, 4 px noise): the error of every
   offset found (frames), the share within 0.1 frame, and whether the std covers the error
   (|error| <= 2 std, <= 3 std).
2. **30/60 fps mixes**: the same synthetic 4-camera scene filmed at 60 fps, two cameras at
   30 fps (cam03, cam04), the offsets fractions of a 60 fps frame of either sign (300 or
   ``--mixed-frames`` frames, 4 px noise); calibrated with the offsets searched, beside the
   synchronised all-60 fps rig (the target) and the same offsets at one rate (all 60 fps:
   what the offsets alone cost): every camera's rotation error and the time.
3. **Clock drift** (``clock_drift = true``): a 30 fps rig whose cameras' clocks run fast or
   slow by a few 1e-4 to 1e-3 (600 frames): every rate found and its std.
4. **Pose2Sim's Demo_SinglePerson** (4 real cameras, 100 frames at 60 fps, BlazePose run
   once into a detection cache): the cameras' keypoints renumbered as if started late or
   early by whole frames (up to 15 either way: four fixed scenarios and ``--random``
   more), calibrated with the offsets searched.
   Per scenario (the synchronised demo first, whose truth is 0): every whole offset
   found against the shift applied (the truth), each camera's rotation against the
   synchronised run's with the offsets given (``time_offsets="fixed"``) and against the
   Qualisys calibration (deg), and the time against that synchronised run.

Usage::

    python bench/bench_offsets.py                    # ~20 min on 2 shared cores
    python bench/bench_offsets.py --seeds 6 --mixed-seeds 6 --cache DIR

Writes ``bench/RESULTS_offsets.md``.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import header  # noqa: E402

from mirrorgraph.io import read_keypoints, write_keypoints  # noqa: E402
from mirrorgraph.io.camera_toml import TomlCamera, write_camera_toml  # noqa: E402
from mirrorgraph.io.qualisys import read_qca  # noqa: E402
from mirrorgraph.metrics import rotation_error_deg  # noqa: E402
from mirrorgraph.pipelines.options import CalibrateOptions  # noqa: E402
from mirrorgraph.pipelines.rig import calibrate_rig  # noqa: E402
from mirrorgraph.synth.rig import write_rig  # noqa: E402
from mirrorgraph.synth.rig_clocks import unsynchronised_rig  # noqa: E402

CAMERAS = ("cam01", "cam02", "cam03", "cam04")
#: Whole-frame shifts of the demo's cameras (cam01 is the rig's clock).
SCENARIOS = ((0, 15, -15, 7), (0, -9, 4, -13), (0, 3, -6, 12), (0, -15, 15, -4))


def synthetic(seeds: int, out: Path) -> tuple[list[str], dict]:
    rows, errs, stds = [], [], []
    rng = np.random.default_rng(0)
    for seed in range(seeds):
        offs = [0.0] + list(np.round(rng.uniform(-12, 12, 3), 1))
        rig = unsynchronised_rig("4cams", offs, frames=300, seed=seed, noise_std=4.0)
        path = write_rig(rig, out / f"synth{seed}")
        t = time.perf_counter()
        cal = calibrate_rig(path)
        dt = time.perf_counter() - t
        found = [c.time_offset_frames for c in cal.cameras[1:]]
        sd = [c.time_offset_std for c in cal.cameras[1:]]
        rot = [rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3])
               for c, P in zip(cal.cameras[1:], rig.poses[1:])]
        e = np.array(found) - np.array(offs[1:])
        errs += list(e)
        stds += sd
        rows.append(f"| {seed} | {', '.join(f'{o:+.1f}' for o in offs[1:])} | "
                    f"{', '.join(f'{f:+.2f} ± {s:.2f}' for f, s in zip(found, sd))} | "
                    f"{', '.join(f'{abs(x):.2f}' for x in e)} | "
                    f"{', '.join(f'{r:.2f}' for r in rot)} | {dt:.1f} |")
        print(rows[-1], flush=True)
    errs, stds = np.abs(np.array(errs)), np.array(stds)
    summary = dict(median=float(np.median(errs)), max=float(errs.max()),
                   within=float(np.mean(errs <= 0.1)), cover2=float(np.mean(errs <= 2 * stds)),
                   cover3=float(np.mean(errs <= 3 * stds)), n=len(errs))
    table = ["| seed | true offsets (cam02-04) | found ± std | |error| (frames) | "
             "rotation error (deg) | time (s) |", "|---|---|---|---|---|---|", *rows]
    return table, summary


CAMS = ("cam01", "cam02", "cam03", "cam04")


def _with_lines(path: Path, fps: dict[str, float], head: str = "") -> Path:
    """The rig file ``path`` with each camera's ``fps`` and ``head`` lines at the top."""
    text = path.read_text()
    for cam, f in fps.items():
        text = text.replace(f'name = "{cam}"\n', f'name = "{cam}"\nfps = {f:g}\n', 1)
    path.write_text(head + text)
    return path


def _rotations(cal, rig) -> list[float]:
    return [rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3])
            for c, P in zip(cal.cameras[1:], rig.poses[1:])]


def mixed(seeds: int, frames: int, out: Path) -> tuple[list[str], dict]:
    """30/60 fps mixes beside the synchronised all-60 rig and the same offsets at 60 fps."""
    rows, errs, stds, gaps, gaps_same, ratios, missed = [], [], [], [], [], [], []
    rng = np.random.default_rng(2)
    for seed in range(seeds):
        offs = [0.0] + list(np.round(rng.uniform(-8, 8, 3), 1))
        runs = {}
        for label, o, rates in (("sync", (0, 0, 0, 0), (1, 1, 1, 1)),
                                ("same", offs, (1, 1, 1, 1)), ("mixed", offs, (1, 1, 2, 2))):
            rig = unsynchronised_rig("4cams", o, frames=frames, fps=60.0, rates=rates,
                                     seed=seed, noise_std=4.0)
            path = _with_lines(write_rig(rig, out / f"mixed{seed}{label}"),
                               {n: 60.0 / r for n, r in zip(CAMS, rates)})
            t = time.process_time()
            cal = calibrate_rig(path, CalibrateOptions(time_offsets="fixed") if label == "sync"
                                else None)
            runs[label] = (cal, _rotations(cal, rig), time.process_time() - t)
        cal, rot, cpu = runs["mixed"]
        found = [c.time_offset_frames for c in cal.cameras[1:]]
        sd = [c.time_offset_std for c in cal.cameras[1:]]
        e = np.array(found) - np.array(offs[1:])
        if np.abs(e).max() < 0.5:             # every offset found: its errors counted
            errs += list(np.abs(e))
            stds += sd
        else:
            missed.append(seed)
        gaps.append(max(np.array(rot) - np.array(runs["sync"][1])))
        gaps_same.append(max(np.array(rot) - np.array(runs["same"][1])))
        ratios.append(cpu / runs["sync"][2])
        rows.append(f"| {seed} | {', '.join(f'{o:+.1f}' for o in offs[1:])} | "
                    f"{', '.join(f'{f:+.2f} ± {s:.2f}' for f, s in zip(found, sd))} | "
                    f"{', '.join(f'{r:.2f}' for r in rot)} | "
                    f"{', '.join(f'{r:.2f}' for r in runs['same'][1])} | "
                    f"{', '.join(f'{r:.2f}' for r in runs['sync'][1])} | "
                    f"{cpu:.1f} ({cpu / runs['sync'][2]:.1f}x) |")
        print(rows[-1], flush=True)
    errs, stds = np.array(errs), np.array(stds)
    table = ["| seed | true offsets (cam02-04, 60 fps frames) | found ± std | rotation error "
             "30/60 mix (deg) | same offsets, all 60 fps | synchronised, all 60 fps | "
             "CPU (s, vs synchronised with the offsets given) |", "|---|---|---|---|---|---|---|",
             *rows]
    return table, dict(n=len(errs), median=float(np.median(errs)) if len(errs) else np.nan,
                       max=float(errs.max()) if len(errs) else np.nan,
                       cover3=float(np.mean(errs <= 3 * stds)) if len(errs) else np.nan,
                       gap=float(max(gaps)), gap_same=float(max(gaps_same)),
                       ratio=(min(ratios), max(ratios)), missed=missed, seeds=seeds)


def drift(frames: int, out: Path) -> tuple[list[str], dict]:
    """A 30 fps rig whose clocks drift, calibrated with ``clock_drift = true``."""
    offs, rates = (0.0, 2.4, -3.7, 1.1), (1.0, 1 + 1e-3, 1 - 5e-4, 1 + 2e-4)
    rig = unsynchronised_rig("4cams", offs, frames=frames, drifts=rates, seed=0,
                             noise_std=4.0)
    path = _with_lines(write_rig(rig, out / "drift"), {},
                       head="clock_drift = true\n")
    t = time.process_time()
    cal = calibrate_rig(path)
    cpu = time.process_time() - t
    rows = []
    for c, o, r in zip(cal.cameras[1:], offs[1:], rates[1:]):
        rows.append(f"| {c.name} | {o:+.1f} | {c.time_offset_frames:+.2f} ± "
                    f"{c.time_offset_std:.2f} | {(r - 1) * 1e4:+.1f} | "
                    f"{(c.clock_rate - 1) * 1e4:+.1f} ± {c.clock_rate_std * 1e4:.1f} |")
    table = ["| camera | true offset (frames) | found ± std | true rate - 1 (1e-4) | "
             "found - 1 ± std (1e-4; 0 where not significant) |", "|---|---|---|---|---|", *rows]
    return table, dict(cpu=cpu, frames=frames)


def _demo_root() -> Path:
    return Path(list(importlib.util.find_spec("Pose2Sim").submodule_search_locations)[0]) \
        / "Demo_SinglePerson"


def _demo_rig(folder: Path, detections: dict, shifts) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    lines = []
    for n, s in zip(CAMERAS, shifts):
        d = detections[n]
        write_keypoints(replace(d, frame_ids=np.asarray(d.frame_ids) + int(s)),
                        folder / f"{n}.json", "mmpose")
        lines += ["[[cameras]]", f'name = "{n}"', f'keypoints = "{n}.json"',
                  f'intrinsics = "{folder.parent / "Calib.toml"}"', f'intrinsics_section = "{n}"']
    (folder / "rig.toml").write_text("\n".join(lines) + "\n")
    return folder / "rig.toml"


def _qualisys_errors(cal, truth) -> list[float]:
    """Every camera's rotation relative to the first against the Qualisys calibration (deg)."""
    return [rotation_error_deg(c.pose[:3, :3], T[:3, :3])
            for c, T in zip(cal.cameras[1:], truth[1:])]


def _random_scenarios(n: int) -> tuple[tuple[int, ...], ...]:
    """``n`` more shifts of cam02-04, each uniform in -15..15 (seeded)."""
    rng = np.random.default_rng(1)
    return tuple((0, *map(int, rng.integers(-15, 16, 3))) for _ in range(n))


def demo(out: Path, cache: Path, extra: int = 0) -> tuple[list[str], dict]:
    from mirrorgraph.video import VideoOptions
    root = _demo_root()
    cams = read_qca(root / "calibration" / "Calib.qca.txt")
    write_camera_toml(out / "Calib.toml",
                      [TomlCamera(key=n, name=n, matrix=cams[n].K, distortions=cams[n].dist,
                                  size=cams[n].size) for n in CAMERAS], "pose2sim")
    first = np.linalg.inv(cams[CAMERAS[0]].pose)
    truth = [first @ cams[n].pose for n in CAMERAS]
    det = {n: read_keypoints(root / "videos" / f"{n}.mp4", video=VideoOptions(cache_dir=cache))
           for n in CAMERAS}
    sync = _demo_rig(out / "sync", det, (0, 0, 0, 0))
    t, c = time.perf_counter(), time.process_time()
    base = calibrate_rig(sync, CalibrateOptions(time_offsets="fixed"))
    t_fixed, c_fixed = time.perf_counter() - t, time.process_time() - c
    q_base = _qualisys_errors(base, truth)
    print(f"synchronised, offsets given: {t_fixed:.1f} s, vs Qualisys "
          f"{', '.join(f'{r:.2f}' for r in q_base)} deg", flush=True)
    # cam02 at offsets -1 and -2 (its frames renumbered 1 and 2 later, the offsets given):
    # how far that moves it from the Qualisys calibration
    early = []
    for k in (1, 2):
        cal = calibrate_rig(_demo_rig(out / f"early{k}", det, (0, k, 0, 0)),
                            CalibrateOptions(time_offsets="fixed"))
        early.append(_qualisys_errors(cal, truth)[0])
    rows, exact, worst, ratios, cpus, moved = [], 0, 0.0, [], [], 0
    scenarios = SCENARIOS + _random_scenarios(extra)
    for shifts in ((0, 0, 0, 0),) + scenarios:
        path = sync if not any(shifts) else \
            _demo_rig(out / ("shift" + "_".join(map(str, shifts))), det, shifts)
        t, c = time.perf_counter(), time.process_time()
        try:
            cal = calibrate_rig(path)
        except Exception as exc:          # a refusal is a result here
            rows.append(f"| {shifts[1:]} | refused: {str(exc)[:120]} | | | | | |")
            continue
        dt, dc = time.perf_counter() - t, time.process_time() - c
        ratios.append(dt / t_fixed)
        cpus.append(dc)
        found = [c.time_offset_frames for c in cal.cameras]
        std = [c.time_offset_std for c in cal.cameras]
        ok = [round(f) == s for f, s in zip(found[1:], shifts[1:])]
        exact += all(ok)
        if not any(shifts):
            moved = sum(f != 0 for f in found[1:])
        rot = [rotation_error_deg(c.pose[:3, :3], b.pose[:3, :3])
               for c, b in zip(cal.cameras[1:], base.cameras[1:])]
        worst = max(worst, max(rot))
        label = "synchronised" if not any(shifts) else ", ".join(f"{s:+d}" for s in shifts[1:])
        rows.append(f"| {label} | "
                    f"{', '.join(f'{f:+.2f} ± {d:.2f}' for f, d in zip(found[1:], std[1:]))} | "
                    f"{'yes' if all(ok) else 'NO'} | {', '.join(f'{r:.2f}' for r in rot)} | "
                    f"{', '.join(f'{r:.2f}' for r in _qualisys_errors(cal, truth))} | "
                    f"{dt:.1f} ({dt / t_fixed:.1f}x) | {dc:.1f} |")
        print(rows[-1], flush=True)
    t, c = time.perf_counter(), time.process_time()    # again: the machine's load drifts
    calibrate_rig(sync, CalibrateOptions(time_offsets="fixed"))
    t_again, c_again = time.perf_counter() - t, time.process_time() - c
    c_ref = 0.5 * (c_fixed + c_again)
    table = [f"Synchronised run with the offsets given (`time_offsets=\"fixed\"`): {t_fixed:.1f} s "
             f"before the runs below, {t_again:.1f} s after (the wall ratios use the first); "
             f"CPU {c_fixed:.1f} and {c_again:.1f} s (the CPU ratios use their mean, "
             f"{c_ref:.1f} s: CPU time is what the shared machine's load leaves alone); "
             f"its rotations against the Qualisys calibration "
             f"{', '.join(f'{r:.2f}' for r in q_base)} deg (cam02-04); with cam02 at offset -1 "
             f"or -2 instead (given): cam02 {early[0]:.2f} or {early[1]:.2f} deg off Qualisys.",
             "", "| shifts applied (cam02-04, frames; the truth) | offsets found ± std (frames) | "
             "every whole offset = the truth | rotation vs synchronised run (deg) | "
             "rotation vs Qualisys (deg) | wall time (s, vs offsets given) | CPU (s) |",
             "|---|---|---|---|---|---|---|", *rows]
    return table, dict(exact=exact, scenarios=len(scenarios) + 1, worst_deg=worst,
                       worst_ratio=max(ratios) if ratios else float("nan"),
                       cpu_ratios=(min(cpus) / c_ref, max(cpus) / c_ref) if cpus else
                       (float("nan"),) * 2, moved=moved)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4, help="synthetic rigs (default 4)")
    ap.add_argument("--cache", type=Path, default=None,
                    help="detection cache folder to reuse (default: a fresh one)")
    ap.add_argument("--random", type=int, default=3,
                    help="random demo shifts within +-15 frames beside the four fixed "
                         "(default 3)")
    ap.add_argument("--mixed-seeds", type=int, default=4,
                    help="30/60 fps mixes (default 4; each three calibrations)")
    ap.add_argument("--mixed-frames", type=int, default=300,
                    help="frames of the 30/60 fps mixes at 60 fps (default 300)")
    ap.add_argument("--drift-frames", type=int, default=600,
                    help="frames of the drifting rig at 30 fps (default 600)")
    ap.add_argument("--no-demo", action="store_true")
    ap.add_argument("--only-rates", action="store_true",
                    help="the 30/60 fps mixes and the drift only")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    started = time.strftime("%Y-%m-%dT%H:%M:%S")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        syn_table, syn = ([], None) if args.only_rates else synthetic(args.seeds, out)
        mix_table, mix = mixed(args.mixed_seeds, args.mixed_frames, out)
        drift_table, dri = drift(args.drift_frames, out)
        demo_table, dem = ([], None) if args.no_demo or args.only_rates else \
            demo(out, args.cache or out / "cache", args.random)
    lines = ["# Time offsets from the people (`bench/bench_offsets.py`)", "",
             *header(started=started), ""]
    if syn is not None:
        lines += ["## Synthetic 4-camera rigs, known offsets (300 frames, 30 fps, 4 px noise)", "",
                  f"{syn['n']} offsets: median |error| {syn['median']:.3f} frames, largest "
                  f"{syn['max']:.3f}; within 0.1 frame {100 * syn['within']:.0f} %; "
                  f"|error| <= 2 std {100 * syn['cover2']:.0f} %, <= 3 std "
                  f"{100 * syn['cover3']:.0f} %.", "", *syn_table, ""]
    lines += [f"## 30/60 fps mixes ({args.mixed_frames} frames at 60 fps, cam03 and cam04 at "
              "30 fps, 4 px noise)", "",
              f"Every offset within half a frame in {mix['seeds'] - len(mix['missed'])} of "
              f"{mix['seeds']} rigs (not in seeds {mix['missed'] or 'none'}: the people do "
              "not fix them, each kept as given with a std of frames); the "
              f"{mix['n']} offsets of those (60 fps frames): median |error| "
              f"{mix['median']:.3f}, largest {mix['max']:.3f}; |error| <= 3 std "
              f"{100 * mix['cover3']:.0f} %. "
              f"Rotation errors: the mix at most {mix['gap']:.2f} deg above the synchronised "
              f"all-60 fps rig's, at most {mix['gap_same']:+.2f} deg against the same offsets "
              f"at 60 fps (what the offsets' search costs, not the rates); CPU time "
              f"{mix['ratio'][0]:.1f}-{mix['ratio'][1]:.1f}x the synchronised all-60 fps run's "
              "with the offsets given (`time_offsets=\"fixed\"`).", "", *mix_table, "",
              f"## Clock drift ({dri['frames']} frames at 30 fps, `clock_drift = true`, "
              f"4 px noise; CPU {dri['cpu']:.1f} s)", "", *drift_table, ""]
    if dem is not None:
        lines += ["## Pose2Sim Demo_SinglePerson, cameras renumbered by whole frames", "",
                  f"Synchronised demo: {dem['moved']} of 3 cameras moved by the search. "
                  f"Every whole offset equal to the truth in {dem['exact']} of "
                  f"{dem['scenarios']} runs (the synchronised one included); "
                  f"largest rotation against the synchronised run {dem['worst_deg']:.2f} deg; "
                  f"CPU time {dem['cpu_ratios'][0]:.1f}-{dem['cpu_ratios'][1]:.1f}x the "
                  f"synchronised run with the offsets given (wall time at most "
                  f"{dem['worst_ratio']:.1f}x, the machine shared).", "", *demo_table, ""]
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        (Path(__file__).resolve().parent / "RESULTS_offsets.md").write_text(text)


if __name__ == "__main__":
    main()
