"""``mirrorgraph live --as-fast-as-possible`` on a keypoint file, whole process: frames/s.

A synthetic scene (``mirrorgraph synth --frames N``, MMPose keypoints, its camera and the
subject's height) is replayed flat out by ``mirrorgraph live`` in a fresh process, with
the windows solved in the worker process (the default) and inline (``--inline``), each
``--repeats`` times; for each run:

* **wall s** and **frames/s**: the whole process, start-up and the last window included
  (as ``time`` measures it), and **CPU s**: user + system of the process and its worker
  (``resource.getrusage(RUSAGE_CHILDREN)``);
* **main thread CPU s** and **asleep s**: the ``live`` process's main thread's time on a
  CPU and its time asleep (the wall less that and its time runnable but waiting for a
  CPU, ``/proc/PID/schedstat``, read once the process has exited): asleep is the waits
  for the worker's windows (with the worker's own waits for a CPU on a loaded machine);
* **PA-MPJPE mm**: the lines' joints against the scene's true joints
  (:func:`mirrorgraph.metrics.pa_mpjpe`, each frame aligned by Procrustes): the worker's
  lines differ from the inline run's (a frame gets the mirror solved by then);
* **without joints**: the JSON lines after the first one that carries a mirror with no 3D
  joint (the target: none), and the lines written;
* **where an inline run's CPU goes**, in process: the start-up's imports, the windows'
  imports (GTSAM, SciPy, the offline run), the reading, the per-frame path, the windows'
  solves and the JSON lines;
* ``--before PATH``: the same runs with the package of another tree (its
  ``mirrorgraph/`` first on ``PYTHONPATH``), side by side, interleaved run by run;
* ``--refine NAME=VALUE`` (repeatable): a :class:`~mirrorgraph.graph.RefineOptions` field
  every run sets (its windows' graph; the whole-process runs take it as the field's
  default, which ``mirrorgraph live`` has no flag for);
* ``--graph-off``: this tree again with the window graph off (``--window-graph 0``, the
  fixed-lag smoother alone), side by side;
* **latency**: a frame's line comes ``lag_frames`` frames after the frame (the window
  graph's or the smoother's solve over the frames after it) plus its own path's time: the
  lag at the stream's frame rate plus the per-frame path's 99th percentile
  (``LiveFrame.cpu_s``, the window graph's solve included on the updates that run it,
  one in ``window_graph_every``), against the target
  (:data:`TARGET_LATENCY_S` at :data:`STREAM_FPS`); the whole process keeps up where its
  frames/s exceeds the stream's.

Each tree's modules are byte-compiled first (one untimed run writes their
``__pycache__``, as installing a package does; ``PYTHONDONTWRITEBYTECODE`` is not passed
on), so that start-up is an installed package's, not the compiler's.

Usage::

    python bench/bench_live_speed.py                       # 1000 frames, 3 repeats
    python bench/bench_live_speed.py --before ../main --repeats 5
    python bench/bench_live_speed.py --refine torso_sigma=0.02 --append

Writes ``--out`` (default ``bench/RESULTS_live_speed.md``; with ``--append`` a section
added below the ones there) unless ``--no-write``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import header, now  # noqa: E402

from mirrorgraph.metrics import pa_mpjpe  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TARGET_FPS = 200.0
#: The latency target of a live stream (s) and the stream's frame rate it holds at.
TARGET_LATENCY_S = 0.5
STREAM_FPS = 30.0

#: A fresh process running ``mirrorgraph live`` with ``RefineOptions`` defaults of its
#: own (``argv[1]``, JSON): the ``--refine`` fields, which the command has no flag for.
LAUNCH = """
import json, sys
from mirrorgraph.graph import options
refine = json.loads(sys.argv[1])
init = options.RefineOptions.__init__
def patched(self, *args, **kw):
    init(self, *args, **{**refine, **kw})
options.RefineOptions.__init__ = patched
from mirrorgraph.cli import main
sys.exit(main(sys.argv[2:]))
"""


def _env(tree: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1")
    env.pop("PYTHONDONTWRITEBYTECODE", None)     # start-up as an installed package's
    return env


def make_scene(folder: Path, frames: int, seed: int) -> Path:
    subprocess.run([sys.executable, "-m", "mirrorgraph", "synth", "--out", str(folder),
                    "--frames", str(frames), "--seed", str(seed), "--formats", "mmpose",
                    "--subject-height", "1.75", "--quiet"], check=True, env=_env(ROOT))
    return folder


def _main_thread(pid: int) -> tuple[float, float]:
    """``(on a CPU, runnable and waiting for one)`` seconds of process ``pid``'s main
    thread (``/proc/PID/schedstat``; an exited process's until it is reaped)."""
    try:
        on, queued = Path(f"/proc/{pid}/schedstat").read_text().split()[:2]
    except (OSError, ValueError):
        return float("nan"), float("nan")
    return int(on) * 1e-9, int(queued) * 1e-9


def run_once(tree: Path, scene: Path, inline: bool, jsonl: Path, refine: dict,
             extra: tuple = ()) -> dict:
    """One fresh ``mirrorgraph live`` process (``extra``: more of its arguments): wall,
    CPU, and its lines' joints."""
    args = ["live", str(scene / "keypoints_mmpose.json"),
            "--intrinsics", str(scene / "camera.json"), "--subject-height", "1.75",
            "--as-fast-as-possible", "--jsonl", str(jsonl), "--quiet",
            *extra] + ["--inline"] * inline
    cmd = ([sys.executable, "-c", LAUNCH, json.dumps(refine)] if refine
           else [sys.executable, "-m", "mirrorgraph"]) + args
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    clock = time.perf_counter()
    # run from the tree: ``python -m`` puts the working directory first on the path
    proc = subprocess.Popen(cmd, env=_env(tree), stdout=subprocess.DEVNULL, cwd=tree)
    os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOWAIT)     # exited, not reaped yet
    wall = time.perf_counter() - clock
    main_cpu, main_queued = _main_thread(proc.pid)
    if proc.wait() != 0:
        raise subprocess.CalledProcessError(proc.returncode, cmd)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = [json.loads(x) for x in jsonl.read_text().splitlines()]
    first = next((i for i, ln in enumerate(lines) if ln["mirror"]["normal"] is not None), None)
    missing = (sum(1 for ln in lines[first + 1:]
                   if not any(p is not None for p in ln["joints3d"]))
               if first is not None else len(lines))
    truth = np.load(scene / "ground_truth_joints3d.npz")["joints3d"]
    X = np.full(truth.shape, np.nan)
    for ln in lines:
        for j, p in enumerate(ln["joints3d"]):
            if p is not None:
                X[ln["frame"], j] = p
    return dict(wall=wall, cpu=cpu, main_cpu=main_cpu,
                pa_mm=1e3 * pa_mpjpe(X, truth, np.isfinite(X).all(-1)),
                main_asleep=max(wall - main_cpu - main_queued, 0.0), lines=len(lines),
                missing=missing,
                first_mirror=None if first is None else lines[first]["frame"])


#: One in-process live run (windows inline) and where its CPU goes: the start-up's
#: imports (the interpreter, NumPy, OpenCV, the live modules), the windows' imports (GTSAM,
#: SciPy, the offline run), the input's reading, each frame's own path
#: (:attr:`mirrorgraph.live.LiveFrame.cpu_s`), the windows' solves (the rest of each
#: update's thread CPU) and the JSON lines (``mirrorgraph live``'s encoding).
BREAKDOWN = """
import time
import json, sys
import numpy as np
from mirrorgraph.graph import RefineOptions
from mirrorgraph.cli import main
from mirrorgraph.intrinsics import load_intrinsics
from mirrorgraph.live import LiveCalibrator, LiveOptions
from mirrorgraph.live.sources import open_source
from mirrorgraph.live.stream import run_live
t = {"start": time.process_time()}
c = time.process_time()
import scipy.optimize
import mirrorgraph.pipelines.mirror
t["solve_imports"] = time.process_time() - c
scene = sys.argv[1]
refine = json.loads(sys.argv[2])
live_opts = json.loads(sys.argv[3])
c = time.process_time()
src = open_source(scene + "/keypoints_mmpose.json", skeleton=None, fps=None)
intr = load_intrinsics(scene + "/camera.json")
t["read"] = time.process_time() - c
live = LiveCalibrator(src.skeleton, intr, LiveOptions.of(
    subject_height=1.75, can_wait=True, refine_options=RefineOptions(**refine), **live_opts))
out, total = [], 0.0
for f in src.frames:
    c = time.thread_time()
    out.append(live.update(f.people, frame_id=f.frame_id, time_s=f.time))
    total += time.thread_time() - c
t["per_frame"] = float(sum(f.cpu_s for f in out))
t["windows"] = total - t["per_frame"]
paired = [f.cpu_s for f in out if f.paired]
t["paired_ms"] = 1e3 * float(np.median(paired))
t["paired_p99_ms"] = 1e3 * float(np.percentile(paired, 99))
t["paired_max_ms"] = 1e3 * float(np.max(paired))
t["lag_frames"] = live.options.lag_frames
t["graph_s"] = live.graph_seconds
t["graph_solves"] = live.graph_solves
c = time.process_time()
for f in out:
    if f.settled is not None:
        json.dumps(f.settled.to_dict(), allow_nan=False)
t["json"] = time.process_time() - c
print(json.dumps(t))
"""

#: The breakdown's columns: key, heading.
PARTS = [("paired_ms", "per-frame path, ms a paired frame"),
         ("paired_p99_ms", "its p99 ms"), ("paired_max_ms", "its max ms"),
         ("per_frame", "per-frame path s"),
         ("windows", "windows' solves s"), ("start", "start-up s"),
         ("solve_imports", "the windows' imports s"), ("read", "reading s"),
         ("json", "JSON lines s"), ("graph_s", "window graph's solves s (wall, in the "
                                              "per-frame path)"),
         ("graph_solves", "its solves")]


def breakdown(tree: Path, scene: Path, refine: dict, live: dict | None = None) -> dict:
    """Where an inline run's CPU goes (:data:`BREAKDOWN`; ``live``: LiveOptions fields),
    seconds (the frame's ms)."""
    res = subprocess.run([sys.executable, "-c", BREAKDOWN, str(scene), json.dumps(refine),
                          json.dumps(live or {})],
                         check=True,
                         env=_env(tree), capture_output=True, text=True, cwd=tree)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--before", type=Path, default=None,
                    help="another tree whose package is measured beside this one")
    ap.add_argument("--nice", type=int, default=0,
                    help="niceness of the runs (default 0: a speed bench runs at the "
                         "machine's normal priority; its CPU time is the steadier figure)")
    ap.add_argument("--refine", action="append", default=[], metavar="NAME=VALUE",
                    help="a RefineOptions field every run sets (repeatable), e.g. "
                         "torso_sigma=0.02 joints_bone_lengths=integrated")
    ap.add_argument("--graph-off", action="store_true",
                    help="also this tree with the window graph off (--window-graph 0: the "
                         "fixed-lag smoother alone), side by side")
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS_live_speed.md"))
    ap.add_argument("--append", action="store_true",
                    help="add the report as a section below the ones --out holds")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    refine = _refine(ap, args.refine)
    if args.nice:
        os.nice(args.nice)
    # (name, tree, the command's extra arguments, the in-process run's LiveOptions)
    trees = ([("before", args.before.resolve(), (), {})] if args.before else []) + [
        ("this", ROOT, (), {})] + ([("this, graph off", ROOT, ("--window-graph", "0"),
                                     {"window_graph_frames": 0})] if args.graph_off else [])
    rows = []
    parts: dict[str, list] = {}
    loads = []
    with tempfile.TemporaryDirectory() as tmp:
        scene = make_scene(Path(tmp) / "scene", args.frames, args.seed)
        for _, tree, _, _ in trees:                # untimed: each tree's bytecode written
            run_once(tree, scene, True, Path(tmp) / "out.jsonl", refine)
        for r in range(args.repeats):              # interleaved: the load hits both alike
            for name, tree, extra, _ in trees:
                for inline in (False, True):
                    loads.append(os.getloadavg()[0])
                    out = run_once(tree, scene, inline, Path(tmp) / "out.jsonl", refine, extra)
                    out.update(code=name, mode="inline" if inline else "background", rep=r)
                    rows.append(out)
                    print(f"{name} {out['mode']}: {out['wall']:.2f} s wall "
                          f"({args.frames / out['wall']:.0f} frames/s), {out['cpu']:.2f} s CPU, "
                          f"main thread {out['main_cpu']:.2f} s CPU {out['main_asleep']:.2f} s "
                          f"asleep, PA-MPJPE {out['pa_mm']:.1f} mm, "
                          f"{out['missing']} lines without joints after the first mirror",
                          file=sys.stderr, flush=True)
            for name, tree, _, live in trees:
                parts.setdefault(name, []).append(breakdown(tree, scene, refine, live))
    title = "# `mirrorgraph live --as-fast-as-possible`, whole process (`bench/bench_live_speed.py`)"
    old = (Path(args.out).read_text().rstrip("\n") if args.append and Path(args.out).exists()
           else "")
    L = [old, "", f"## {now()[:16].replace('T', ' ')}" + (
        ": " + ", ".join(f"`{k}={v}`" for k, v in refine.items()) if refine else "")] if old \
        else [title]
    L += ["", *header(argv=argv), "* graph options set (`--refine`): " + (
        ", ".join(f"`{k}={v}`" for k, v in refine.items()) if refine else "none (the defaults)"),
         f"* input: `mirrorgraph synth --frames {args.frames} --seed "
         f"{args.seed}` (MMPose keypoints, 30 fps, the camera and the subject's height given); "
         f"each run a fresh process, its modules byte-compiled beforehand (an untimed run "
         f"per tree); medians of {args.repeats} runs (min, max), the trees interleaved; "
         f"1-min load average at the runs' starts {min(loads):.1f} to {max(loads):.1f}", "",
         "| code | mode | wall s | frames/s | CPU s | CPU-time frames/s | main thread CPU s | "
         "main thread asleep s | PA-MPJPE mm | lines | lines without joints after the first "
         "mirror | first mirror at frame |",
         "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, *_ in trees:
        for mode in ("background", "inline"):
            sel = [r for r in rows if r["code"] == name and r["mode"] == mode]
            w = np.array([r["wall"] for r in sel])
            c = np.array([r["cpu"] for r in sel])
            fps = args.frames / w
            L.append(f"| {name} | {mode} | {np.median(w):.2f} ({w.min():.2f}, {w.max():.2f}) | "
                     f"{np.median(fps):.0f} ({fps.min():.0f}, {fps.max():.0f}) | "
                     f"{np.median(c):.2f} | {args.frames / np.median(c):.0f} | "
                     f"{np.median([r['main_cpu'] for r in sel]):.2f} | "
                     f"{np.median([r['main_asleep'] for r in sel]):.2f} | "
                     f"{np.median([r['pa_mm'] for r in sel]):.1f} | {sel[0]['lines']} | "
                     f"{max(r['missing'] for r in sel)} | {sel[0]['first_mirror']} |")
    L += ["", "CPU-time frames/s: frames / CPU s of the process and its worker (user + "
          "system), the measure the machine's load disturbs least.",
          "", "Where an inline run's CPU goes (in process, a fresh one each repeat; the "
          "per-frame path `LiveFrame.cpu_s`, each frame's own work; the windows' solves the "
          "rest of each update's thread CPU; start-up: the interpreter and the imports of "
          "NumPy, OpenCV and the live modules; the windows' imports: GTSAM, SciPy, the "
          "offline run), medians over the repeats:", "",
          "| code | " + " | ".join(h for _, h in PARTS) + " |",
          "|---|" + "---:|" * len(PARTS)]
    for name, *_ in trees:
        med = [np.median([p[k] for p in parts[name]]) for k, _ in PARTS]
        L.append(f"| {name} | " + " | ".join(f"{v:.2f}" for v in med) + " |")
    L += ["", f"Latency at {STREAM_FPS:.0f} fps (a frame's line after the frame: the lag's "
          "frames at the stream's rate plus the per-frame path's p99, medians over the "
          f"repeats; target <= {TARGET_LATENCY_S} s):", ""]
    for name, *_ in trees:
        lag = int(parts[name][0]["lag_frames"])
        p99 = float(np.median([p["paired_p99_ms"] for p in parts[name]])) / 1e3
        worst = float(np.max([p["paired_max_ms"] for p in parts[name]])) / 1e3
        total = lag / STREAM_FPS + p99
        L.append(f"* {name}: {lag} frames / {STREAM_FPS:.0f} fps + {1e3 * p99:.1f} ms = "
                 f"{total:.3f} s (the slowest frame's path {1e3 * worst:.1f} ms): "
                 + ("holds" if total <= TARGET_LATENCY_S else "over the target"))
    L += ["", f"Target: >= {TARGET_FPS:.0f} frames/s whole process in both modes, no line "
          "without joints after the first mirror."]
    text = "\n".join(L) + "\n"
    print(text)
    if not args.no_write:
        Path(args.out).write_text(text)
    return 0


def _refine(ap: argparse.ArgumentParser, items: list[str]) -> dict:
    """``--refine NAME=VALUE`` items as RefineOptions fields (values read as JSON, else
    as text); an unknown field refused by name."""
    from mirrorgraph.graph import RefineOptions

    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in RefineOptions.__dataclass_fields__:
            ap.error(f"--refine {item!r}: not NAME=VALUE of a RefineOptions field")
        try:
            out[name] = json.loads(value)
        except json.JSONDecodeError:
            out[name] = value
    RefineOptions(**out)
    return out


if __name__ == "__main__":
    sys.exit(main())
