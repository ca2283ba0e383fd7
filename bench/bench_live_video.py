"""The live video path end to end: ``mirrorgraph live clip.mp4`` as a user runs it.

Each run is the command in a fresh process (``python -m mirrorgraph live ...``), so the
figures are what a user gets, start-up included in the wall time (not in frames/s, which
is the command's own count over its stream). Three runs a clip:

* **at the frame rate** (the default: the video played at its own rate, the mirror's
  windows solved in a worker process): frames processed per second of video, frames
  dropped because the detector was slower than the stream, per-frame latency of the
  3D step (pairing and triangulation), time into the stream at which the status became
  ``calibrated``, the final mirror normal's error against the clip's truth;
* **flat out** (``--as-fast-as-possible``, windows solved inline): the throughput, and
  the CPU time a frame (start-up, detection, the 3D step and the windows' solves over
  the frames: the figure other jobs on the machine change least);
* **offline** (``mirrorgraph calibrate clip.mp4 --no-cache``): the batch calibration
  of the same video, whose error the live run's is compared with.

Clips (600 frames at 30 fps each: the 100 frames of a Pose2Sim demo video played
forward and back three times, so that the person keeps moving without a cut):

* ``planar70``: Demo_SinglePerson cam01 (one person and a bystander) at 540 x 960 in
  an 840 x 960 clip with the reflection of the scene in a mirror 70 deg off the
  optical axis, 1.6 m away (:class:`mirrorgraph.synth.mirror_clip.PlanarMirrorClip`:
  the scene as a flat cut-out at 2.9 m, so every pixel and its reflection lie exactly
  on a line through the epipole ``K n``; the normal is the truth, the cut-out's
  reflection is not that of a 3D body: the graph is pulled off by it, see
  ``tests/video/test_video.py``). Intrinsics given (Qualisys' camera 1, halved).
* ``planar2p``: Demo_MultiPerson cam04 (two people) the same way: two people and
  two reflections to pair frame by frame.
* ``nomirror2``: Demo_MultiPerson cam04 at 540 x 960 in the same 840 x 960 canvas with
  nothing right of the split: two people and **no mirror**. The right answer is no
  calibration: a live run must not report ``calibrated``, nor the offline run a
  mirror without saying it may be a second person.
* ``mirror1080``: Demo_SinglePerson cam01 composited into a 1920 x 1080 scene
  (:class:`mirrorgraph.synth.mirror_clip.MirrorComposite`: the person at half scale
  and a flipped copy as the reflection): one person and one reflection at 1080p, the
  issue's speed case. The copy is not a planar mirror's image, so only its speed is
  reported (image size only, no truth).
* ``demo60``: Demo_SinglePerson cam01 as shipped (1080 x 1920, 60 fps, no mirror):
  a real video at its own rate; nothing to calibrate, so only its speed.

Usage::

    python bench/bench_live_video.py              # ~5 min on 2 idle cores
    python bench/bench_live_video.py --clips planar70 --no-write

Writes ``bench/RESULTS_live_video.md`` (machine, command, date, load, table).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
import _report  # noqa: E402  (the machine line every results file shares)

from bench_video import _demo_root, _git, _read, _write_clip  # noqa: E402

#: clip -> (trial, camera, mirror angle deg, distance m, cut-out depth m) for the planar ones
PLANAR = {"planar70": ("Demo_SinglePerson", "cam01", 70.0, 1.6, 2.9),
          "planar2p": ("Demo_MultiPerson", "cam04", 70.0, 1.6, 2.9),
          "nomirror2": ("Demo_MultiPerson", "cam04", None, None, None)}
CLIPS = ("planar70", "planar2p", "nomirror2", "mirror1080", "demo60")
REPEATS = 3                      # forward and back, three times: 600 frames from 100


def _pingpong(frames: list) -> list:
    return (frames + frames[::-1]) * REPEATS


def make_clip(name: str, folder: Path) -> dict:
    """Write clip ``name`` into ``folder``; its path, fps, truth and intrinsics file."""
    import cv2
    demo = _demo_root()
    if name in PLANAR:
        from mirrorgraph.io.qualisys import read_qca
        from mirrorgraph.synth.mirror_clip import PlanarMirrorClip
        trial, cam, angle, dist, depth = PLANAR[name]
        K = np.diag([0.5, 0.5, 1.0]) @ read_qca(
            demo / trial / "calibration" / "Calib.qca.txt")[cam].K
        src = [cv2.resize(f, (540, 960), interpolation=cv2.INTER_AREA)
               for f in _read(demo / trial / "videos" / f"{cam}.mp4", 100)]
        if angle is None:                   # no mirror: the frame's left part, black beside
            n = None
            frames = [np.zeros((960, 840, 3), np.uint8) for _ in src]
            for canvas, f in zip(frames, src):
                canvas[:, :420] = f[:, :420]
        else:
            a = np.radians(angle)
            n = np.array([np.sin(a), 0.0, np.cos(a)])
            clip = PlanarMirrorClip(K=K, normal=n, distance=dist, depth=depth, width=840,
                                    split=420)
            frames = [clip.compose(f) for f in src]
        video = _write_clip(folder / f"{name}.mp4", _pingpong(frames), 30.0)
        camfile = folder / f"{name}_camera.json"
        camfile.write_text(json.dumps({"K": K.tolist(), "image_size": [840, 960]}))
        return {"video": video, "fps": 30.0, "normal": n, "intrinsics": camfile,
                "size": "840x960"}
    if name == "mirror1080":
        from mirrorgraph.synth.mirror_clip import MirrorComposite
        comp = MirrorComposite()
        src = _read(demo / "Demo_SinglePerson" / "videos" / "cam01.mp4", 100)
        video = _write_clip(folder / "mirror1080.mp4",
                            _pingpong([comp.compose(f) for f in src]), 30.0)
        return {"video": video, "fps": 30.0, "normal": None, "intrinsics": None,
                "size": "1920x1080"}
    if name == "demo60":
        return {"video": demo / "Demo_SinglePerson" / "videos" / "cam01.mp4", "fps": 60.0,
                "normal": None, "intrinsics": None, "size": "1080x1920"}
    raise SystemExit(f"unknown clip {name!r}: one of {', '.join(CLIPS)}")


def _angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    c = abs(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(min(1.0, c))))


def _command(args: list[str], check: bool = True) -> tuple[str, float, float, int, str]:
    """Run ``python -m mirrorgraph ARGS`` in a fresh process: stdout, wall s, CPU s, exit
    code and the last line of stderr (``check``: raise where it fails)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    clock = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "mirrorgraph", *args], capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    wall = time.perf_counter() - clock
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if check and proc.returncode != 0:
        raise RuntimeError(f"mirrorgraph {' '.join(args)} failed: {proc.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    last = (proc.stderr.strip().splitlines() or [""])[-1]
    return proc.stdout, wall, cpu, proc.returncode, last


def _camera_args(clip: dict) -> list[str]:
    if clip["intrinsics"] is not None:
        return ["--intrinsics", str(clip["intrinsics"])]
    return ["--image-size", clip["size"]]


def live_run(clip: dict, folder: Path, tag: str, flat_out: bool) -> dict:
    """One ``mirrorgraph live`` run; the figures of its JSON lines and its summary."""
    out = folder / f"{clip['video'].stem}_{tag}.jsonl"
    args = ["live", str(clip["video"]), "--jsonl", str(out), "--subject-height", "1.6",
            *_camera_args(clip)]
    if flat_out:
        args.append("--as-fast-as-possible")
    stdout, wall, cpu, _, _ = _command(args)
    lines = [json.loads(s) for s in out.read_text().splitlines()]
    m = re.search(r"(\d+) frames in ([\d.]+) s", stdout)
    frames, seconds = int(m.group(1)), float(m.group(2))
    dropped = re.search(r"(\d+) video frames dropped", stdout)
    lat = re.search(r"latency median ([\d.]+) ms, p95 ([\d.]+) ms, p99 ([\d.]+) ms", stdout)
    calibrated = next((ln["time"] for ln in lines if ln["status"] == "calibrated"), None)
    last = lines[-1]["mirror"]
    err = (_angle(last["normal"], clip["normal"])
           if clip["normal"] is not None and last["normal"] is not None else None)
    with_joints = float(np.mean([any(p is not None for p in ln["joints3d"]) for ln in lines]))
    return {"frames": frames, "seconds": seconds, "fps": frames / seconds,
            "dropped": int(dropped.group(1)) if dropped else 0, "wall": wall, "cpu": cpu,
            "latency": tuple(float(x) for x in lat.groups()) if lat else None,
            "calibrated_at": calibrated, "status": last["status"], "error": err,
            "std": last["rotation_std_deg"], "with_joints": with_joints}


def offline_run(clip: dict, folder: Path) -> dict:
    """``mirrorgraph calibrate`` of the same video (no cache): its error, std, the
    reflection check's verdict, or the line it refused with."""
    out = folder / f"{clip['video'].stem}_offline.json"
    _, wall, cpu, rc, err = _command(["calibrate", str(clip["video"]), "--out", str(out),
                                      "--subject-height", "1.6", "--no-cache", "--quiet",
                                      *_camera_args(clip)], check=False)
    if rc != 0:
        return {"wall": wall, "cpu": cpu, "refused": err, "error": None, "std": None,
                "initial_error": None, "check": None}
    c = json.loads(out.read_text())
    truth = clip["normal"]
    return {"wall": wall, "cpu": cpu, "refused": None,
            "error": None if truth is None else _angle(c["mirror"]["normal"], truth),
            "std": (c.get("uncertainty") or {}).get("rotation_std_deg"),
            "initial_error": None if truth is None else _angle(c["initial_normal"], truth),
            "check": ((c.get("input") or {}).get("reflection_check") or {}).get("verdict")}


def _f(v, spec=".2f") -> str:
    return "-" if v is None else format(v, spec)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clips", nargs="+", default=list(CLIPS), choices=CLIPS)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    started = datetime.datetime.now(datetime.timezone.utc)
    rows, loads = [], []
    with tempfile.TemporaryDirectory(prefix="bench_live_video_") as t:
        folder = Path(t)
        for name in args.clips:
            clip = make_clip(name, folder)
            row = {"clip": name, "size": clip["size"], "fps_video": clip["fps"]}
            row["realtime"] = live_run(clip, folder, "rt", flat_out=False)
            loads.append(os.getloadavg()[0])
            row["flat"] = live_run(clip, folder, "flat", flat_out=True)
            loads.append(os.getloadavg()[0])
            row["offline"] = (offline_run(clip, folder) if clip["intrinsics"] is not None
                              else None)
            loads.append(os.getloadavg()[0])
            rows.append(row)
            rt, fl, off = row["realtime"], row["flat"], row["offline"]
            print(f"{name:11s} at frame rate {rt['fps']:.1f} frames/s ({rt['dropped']} of "
                  f"{rt['frames'] + rt['dropped']} dropped), flat out {fl['fps']:.1f} frames/s, "
                  f"calibrated at {_f(rt['calibrated_at'], '.1f')} s, error live "
                  f"{_f(rt['error'])} / flat {_f(fl['error'])} / offline "
                  f"{_f(off and off['error'])} deg, offline {off and (off['refused'] or off['check'])} (load {os.getloadavg()[0]:.1f})",
                  flush=True)
    head = _git("rev-parse", "--short", "HEAD")
    dirty = bool(_git("status", "--porcelain", "--", "mirrorgraph"))
    lines = [
        "# The live video path end to end (`bench/bench_live_video.py`)", "",
        f"- date: {started:%Y-%m-%d %H:%M} UTC",
        f"- machine: {_report.machine()}; load average {min(loads):.1f}-{max(loads):.1f} "
        "during the run (the machine is shared: frames/s are of this run under that load)",
        f"- command: `python bench/bench_live_video.py {' '.join(argv or sys.argv[1:])}`"
        .rstrip(" `") + "`",
        f"- code: `{head}`" + (" + uncommitted changes" if dirty else ""),
        "- each run the command in a fresh process; subject height 1.6 m; 600 frames a clip "
        "(demo60: the 100 frames as shipped); the clips are described in the script's "
        "docstring", "",
        "## Speed", "",
        "| clip | size | video fps | at frame rate: frames/s processed | dropped | 3D step "
        "ms p50 / p95 / p99 | wall s / CPU s (fresh process) | flat out: frames/s | "
        "wall s / CPU s | flat out: CPU ms a frame |",
        "|---|---|---:|---:|---:|---|---|---:|---|---:|"]
    for r in rows:
        rt, fl = r["realtime"], r["flat"]
        lat = " / ".join(f"{x:.2f}" for x in rt["latency"]) if rt["latency"] else "-"
        lines.append(
            f"| {r['clip']} | {r['size']} | {r['fps_video']:.0f} | **{rt['fps']:.1f}** | "
            f"{rt['dropped']} of {rt['frames'] + rt['dropped']} | {lat} | "
            f"{rt['wall']:.1f} / {rt['cpu']:.1f} | **{fl['fps']:.1f}** | "
            f"{fl['wall']:.1f} / {fl['cpu']:.1f} | {1e3 * fl['cpu'] / fl['frames']:.0f} |")
    lines += ["", "## The mirror, live and offline (clips with intrinsics)", "",
              "Error: the angle between the normal found and the clip's (`-`: no mirror in "
              "the clip). Offline: the reflection check's verdict (`ok`, `doubtful`: a "
              "warning, `second_person`: refused), or the line it refused with.", "",
              "| clip | calibrated at s (at frame rate) | live final error deg / std (at "
              "frame rate) | live final error / std (flat out) | offline error deg / std | "
              "offline initial estimate error deg | offline reflection check | offline "
              "wall s / CPU s |",
              "|---|---:|---|---|---|---:|---|---|"]
    for r in rows:
        if r["offline"] is None:
            continue
        rt, fl, off = r["realtime"], r["flat"], r["offline"]
        lines.append(
            f"| {r['clip']} | {_f(rt['calibrated_at'], '.1f')} | {_f(rt['error'])} / "
            f"{_f(rt['std'])} ({rt['status']}) | {_f(fl['error'])} / {_f(fl['std'])} "
            f"({fl['status']}) | "
            f"{_f(off['error'])} / {_f(off['std'])} | {_f(off['initial_error'])} | "
            f"{off['refused'] or off['check']} | {off['wall']:.1f} / {off['cpu']:.1f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        (ROOT / "bench" / "RESULTS_live_video.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
