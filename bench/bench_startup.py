"""How long the command line takes to start: ``import mirrorgraph`` and a fresh
``mirrorgraph calibrate`` against the same call in a running process.

A user runs the command, so a fresh process pays the interpreter's start and every
import before the first frame is read. Measured here, side by side in one run, with
the repeats interleaved (the machine is shared and its load moves):

* ``python -c pass``: the interpreter alone;
* ``python -c "import mirrorgraph"``: wall and CPU of the whole process, and what
  ``python -X importtime`` reports for the package (its cumulative microseconds,
  from a second process);
* ``mirrorgraph --help`` in a fresh process (the parser and every command's options);
* ``python -c "import numpy, cv2, gtsam, scipy.optimize"``: what ``calibrate`` needs from other
  packages, the floor of its start;
* ``mirrorgraph calibrate`` of a synthetic 1000-frame scene (MMPose JSON, the
  camera's intrinsics, the subject's height), in a fresh process and the very same
  ``main(argv)`` in a running process that has already run it once (its imports
  done): the difference is what starting costs a user. The fresh processes run as
  Python runs by default, keeping the compiled modules in ``__pycache__`` (written by
  an untimed first run); and once more from a copy of the package without them and
  with ``PYTHONDONTWRITEBYTECODE=1`` (as some sandboxes and containers set it), where
  every start compiles the package's modules again.

Each source tree given (``--tree LABEL=PATH``, default this checkout) is measured
with ``PYTHONPATH=PATH`` and the same interpreter; the running process is one
server per tree (``--serve``), started once. Prints the table and writes
``bench/RESULTS_startup.md`` (machine, command, date) unless ``--no-write``.

Run:  python bench/bench_startup.py [--repeats 7] [--frames 1000]
          [--tree before=/tmp/main-tree --tree after=.]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
THIS = str(Path(__file__).resolve())

#: What ``calibrate`` cannot start without (OpenCV's geometry, the graph GTSAM's, the
#: epipole's robust fit SciPy's ``least_squares``): the floor of a fresh process's start.
JOB_IMPORTS = "numpy, cv2, gtsam, scipy.optimize"
JOB_ROW = f"python -c \"import {JOB_IMPORTS}\""

#: Packages whose import a command pays for only where it needs them.
HEAVY = ("gtsam", "scipy", "scipy.special", "scipy.optimize", "scipy.spatial", "cv2",
         "matplotlib", "dask", "mirrorgraph.video", "mirrorgraph.synth", "mirrorgraph.batch",
         "mirrorgraph.viewer")


def serve() -> None:
    """The running process: ``main(argv)`` for every JSON argv read on stdin, answering
    one JSON line ``{"wall": s, "cpu": s, "status": int}`` each."""
    import contextlib
    import io

    from mirrorgraph.cli import main
    for line in sys.stdin:
        argv = json.loads(line)
        sink = io.StringIO()
        c0, t0 = time.process_time(), time.perf_counter()
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            status = main(argv)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        print(json.dumps({"wall": wall, "cpu": cpu, "status": status}), flush=True)


def heavy_modules() -> None:
    """Print which :data:`HEAVY` packages ``main(argv)`` (argv as JSON in ``sys.argv[2]``)
    imported; ``[]`` runs nothing but ``import mirrorgraph``."""
    import contextlib
    import io

    argv = json.loads(sys.argv[2])
    import mirrorgraph
    if argv:
        from mirrorgraph.cli import main
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            main(argv)
    print(json.dumps({"file": mirrorgraph.__file__,
                      "heavy": [m for m in HEAVY if m in sys.modules]}))


#: Where the measured processes run: not in a source tree, whose ``mirrorgraph`` the
#: current directory (first on ``sys.path`` under ``-c`` and ``-m``) would put before
#: ``PYTHONPATH``'s. Set by :func:`main`.
CWD: Path = Path(tempfile.gettempdir())


def timed(cmd: list[str], env: dict) -> tuple[float, float]:
    """Wall and CPU (user + system, threads included) seconds of one fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=CWD, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        raise SystemExit(f"{shlex.join(cmd)} failed: {proc.stderr.decode()[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def importtime_ms(env: dict) -> float:
    """The package's cumulative import time as ``python -X importtime`` reports it, ms."""
    proc = subprocess.run([sys.executable, "-X", "importtime", "-c", "import mirrorgraph"],
                          env=env, cwd=CWD, capture_output=True, text=True, check=True)
    for line in proc.stderr.splitlines():
        m = re.match(r"import time:\s+\d+ \|\s+(\d+) \| mirrorgraph$", line)
        if m:
            return int(m.group(1)) / 1000
    raise SystemExit("no 'mirrorgraph' line in -X importtime's output")


def git_commit(path: Path) -> str:
    proc = subprocess.run(["git", "-C", str(path), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True)
    dirty = subprocess.run(["git", "-C", str(path), "status", "--porcelain", "mirrorgraph"],
                           capture_output=True, text=True).stdout.strip()
    if proc.returncode:
        return "not a git checkout"
    return proc.stdout.strip() + (" with uncommitted changes" if dirty else "")


def med(xs: list[float]) -> str:
    return f"{statistics.median(xs):.3f} ({min(xs):.3f}-{max(xs):.3f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--tree", action="append", metavar="LABEL=PATH",
                    help="a source tree to measure (repeatable; default: this checkout)")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--heavy", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.serve:
        return serve()
    if args.heavy is not None:
        return heavy_modules()

    trees = {}
    for spec in args.tree or [f"this checkout={ROOT}"]:
        label, _, path = spec.rpartition("=")
        trees[label or path] = Path(path).resolve()
    # as a user runs it: Python keeps the compiled modules (__pycache__); and apart, a tree
    # copied without them and PYTHONDONTWRITEBYTECODE=1 (every start compiles the package)
    env0 = {k: v for k, v in os.environ.items()
            if k not in ("PYTHONPATH", "PYTHONDONTWRITEBYTECODE")}
    envs = {label: {**env0, "PYTHONPATH": str(path)} for label, path in trees.items()}
    py = sys.executable
    work = Path(tempfile.mkdtemp(prefix="bench_startup_"))
    global CWD
    CWD = work
    nocache = {}
    for k, (label, path) in enumerate(trees.items()):
        copy = work / f"nocache_{k}"
        shutil.copytree(path / "mirrorgraph", copy / "mirrorgraph",
                        ignore=shutil.ignore_patterns("__pycache__"))
        nocache[label] = {**env0, "PYTHONPATH": str(copy), "PYTHONDONTWRITEBYTECODE": "1"}
    first = next(iter(envs.values()))
    subprocess.run([py, "-m", "mirrorgraph", "synth", "--out", str(work / "scene"),
                    "--frames", str(args.frames), "--seed", "3", "--formats", "mmpose",
                    "--quiet"], env=first, cwd=work, check=True)
    scene = work / "scene"
    calib = ["calibrate", str(scene / "keypoints_mmpose.json"), "--intrinsics",
             str(scene / "camera.json"), "--subject-height", "1.75", "--quiet"]

    servers = {}
    for label, env in envs.items():
        servers[label] = subprocess.Popen([py, THIS, "--serve"], env=env, cwd=work,
                                          text=True, stdin=subprocess.PIPE,
                                          stdout=subprocess.PIPE)

    def in_process(label: str, argv: list[str]) -> tuple[float, float]:
        srv = servers[label]
        srv.stdin.write(json.dumps(argv) + "\n")
        srv.stdin.flush()
        ans = json.loads(srv.stdout.readline())
        if ans["status"]:
            raise SystemExit(f"{label}: main({argv}) returned {ans['status']}")
        return ans["wall"], ans["cpu"]

    for k, label in enumerate(trees):         # the running process runs it once first,
        in_process(label, calib + ["--out", str(work / f"warm_{k}.json")])
        timed([py, "-m", "mirrorgraph", *calib, "--out", str(work / f"warm_{k}.json")],
              envs[label])                     # and a fresh one, which writes __pycache__

    rows: dict[tuple[str, str], list[tuple[float, float]]] = {}
    imptime: dict[str, list[float]] = {label: [] for label in trees}
    load0 = os.getloadavg()
    t_start = time.perf_counter()
    for r in range(args.repeats):
        order = list(trees) if r % 2 == 0 else list(reversed(trees))
        for label in order:
            env = envs[label]
            out = str(work / f"c_{r}.json")
            steps = [
                ("python -c pass", lambda: timed([py, "-c", "pass"], env)),
                ("import mirrorgraph", lambda: timed([py, "-c", "import mirrorgraph"], env)),
                (JOB_ROW,
                 lambda: timed([py, "-c", f"import {JOB_IMPORTS}"], env)),
                ("mirrorgraph --help", lambda: timed([py, "-m", "mirrorgraph", "--help"], env)),
                ("calibrate, fresh process",
                 lambda: timed([py, "-m", "mirrorgraph", *calib, "--out", out], env)),
                ("calibrate, fresh process, no bytecode cache",
                 lambda: timed([py, "-m", "mirrorgraph", *calib, "--out", out],
                               nocache[label])),
                ("calibrate, running process", lambda: in_process(label, calib + ["--out", out])),
            ]
            if r % 2:
                steps.reverse()
            for name, run in steps:
                rows.setdefault((label, name), []).append(run())
            imptime[label].append(importtime_ms(env))
        print(f"repeat {r + 1}/{args.repeats} done", file=sys.stderr)
    elapsed = time.perf_counter() - t_start
    for srv in servers.values():
        srv.stdin.close()
        srv.wait(timeout=60)

    heavy = {}
    for label, env in envs.items():
        heavy[label] = {}
        for what, argv in (("import mirrorgraph", []), ("mirrorgraph --help", ["--help"]),
                           ("calibrate", calib + ["--out", str(work / "h.json")])):
            ans = json.loads(subprocess.run(
                [py, THIS, "--heavy", json.dumps(argv)], env=env, cwd=work,
                capture_output=True, text=True, check=True).stdout)
            if not Path(ans["file"]).resolve().is_relative_to(trees[label]):
                raise SystemExit(f"{label}: imported {ans['file']}, not {trees[label]}'s")
            heavy[label][what] = ans["heavy"]

    lines = ["| tree | what | wall s, median (min-max) | CPU s, median (min-max) |",
             "|---|---|---:|---:|"]
    for (label, name), vals in rows.items():
        lines.append(f"| {label} | {name} | {med([v[0] for v in vals])} | "
                     f"{med([v[1] for v in vals])} |")
    summary = []
    for label in trees:
        fresh = rows[(label, "calibrate, fresh process")]
        cold = rows[(label, "calibrate, fresh process, no bytecode cache")]
        warm = rows[(label, "calibrate, running process")]
        d_wall = [f[0] - w[0] for f, w in zip(fresh, warm)]
        d_cpu = [f[1] - w[1] for f, w in zip(fresh, warm)]
        c_wall = [f[0] - w[0] for f, w in zip(cold, warm)]
        c_cpu = [f[1] - w[1] for f, w in zip(cold, warm)]
        imp = [v[0] for v in rows[(label, "import mirrorgraph")]]
        bare = [v[0] for v in rows[(label, "python -c pass")]]
        summary.append(
            f"* **{label}** (`{trees[label]}`, {git_commit(trees[label])}): "
            f"`import mirrorgraph` {statistics.median(imp):.3f} s wall for the whole process "
            f"({statistics.median([a - b for a, b in zip(imp, bare)]):.3f} s above "
            f"`python -c pass`); `-X importtime` {statistics.median(imptime[label]):.0f} ms "
            f"cumulative for the package (median; it inflates what it measures). "
            f"`{JOB_ROW}` (what calibrate needs from other packages): "
            f"{statistics.median(v[1] for v in rows[(label, JOB_ROW)]):.3f} s CPU. "
            f"A fresh `calibrate` of {args.frames} frames costs "
            f"{statistics.median(d_wall):.3f} s wall ({statistics.median(d_cpu):.3f} s CPU) "
            f"more than the same call in a running process (median of the paired "
            f"differences; range {min(d_wall):.3f}-{max(d_wall):.3f} s wall); without the "
            f"bytecode cache {statistics.median(c_wall):.3f} s wall "
            f"({statistics.median(c_cpu):.3f} s CPU).")
        for what, mods in heavy[label].items():
            summary.append(f"  - {what} imports: {', '.join(mods) if mods else 'none of them'}")
    text = "\n".join(lines) + "\n\n" + "\n".join(summary) + "\n"
    print(text)
    if args.no_write:
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from _report import header
    cmd = "python bench/bench_startup.py " + shlex.join(sys.argv[1:])
    doc = ["# Start-up of the command line (`bench/bench_startup.py`)", "",
           *header(cmd=cmd, note=f"at the start {load0[0]:.2f} (1 min); {elapsed:.0f} s of "
                                 "measuring"),
           f"* {args.repeats} repeats, interleaved (every measure of every tree once a "
           "repeat, the order reversed every other repeat); wall from `time.perf_counter`, "
           "CPU as user + system of the process and its threads (`getrusage` of the child; "
           "`time.process_time` in the running process). The machine is shared: the CPU "
           "times are the steadier figure.",
           f"* the scene: `mirrorgraph synth --frames {args.frames} --seed 3 --formats mmpose`; "
           f"the call: `mirrorgraph {' '.join(calib[:1])} keypoints_mmpose.json --intrinsics "
           "camera.json --subject-height 1.75 --quiet --out c.json`; the running process "
           "ran it once before the timed calls (imports done).",
           f"* packages whose import is counted (in `sys.modules` after the call): "
           f"{', '.join(HEAVY)}",
           "", text]
    (ROOT / "bench" / "RESULTS_startup.md").write_text("\n".join(doc))
    print(f"wrote {ROOT / 'bench' / 'RESULTS_startup.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
