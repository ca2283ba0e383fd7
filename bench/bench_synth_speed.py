"""How long the synthetic scene generator takes: ``make_scene(frames=1000)`` (was the
timed test ``tests/synth/test_synth.py::test_speed``, < 1 s; a timing on a shared
machine is a measurement, not a test).

Every repeat builds the same scene (seed 1, the default geometry and detector) in this
process, the first one also paying the imports and first calls (reported apart).
Prints the figures and writes ``bench/RESULTS_synth_speed.md`` (machine, command,
date) unless ``--no-write``.

Run:  python bench/bench_synth_speed.py [--repeats 9] [--frames 1000]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

#: What the timed test asked of a 1000-frame scene, seconds of wall time.
TARGET_S = 1.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()

    t0, c0 = time.perf_counter(), time.process_time()
    from mirrorgraph.synth import make_scene
    make_scene(frames=args.frames, seed=1)
    first = (time.perf_counter() - t0, time.process_time() - c0)
    wall, cpu = [], []
    for _ in range(args.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        make_scene(frames=args.frames, seed=1)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    text = (f"| frames | repeats | wall s, median (min-max) | CPU s, median (min-max) | "
            f"target |\n|---:|---:|---:|---:|---:|\n"
            f"| {args.frames} | {args.repeats} | {statistics.median(wall):.3f} "
            f"({min(wall):.3f}-{max(wall):.3f}) | {statistics.median(cpu):.3f} "
            f"({min(cpu):.3f}-{max(cpu):.3f}) | < {TARGET_S:g} s wall |\n\n"
            f"The first call, with the imports: {first[0]:.3f} s wall, {first[1]:.3f} s CPU.\n")
    print(text)
    if args.no_write:
        return
    from _report import header
    doc = ["# Synthetic scene generator speed (`bench/bench_synth_speed.py`)", "",
           *header(),
           f"* what: `mirrorgraph.synth.make_scene(frames={args.frames}, seed=1)` in one "
           "process, timed after a first call (imports, first calls); wall from "
           "`time.perf_counter`, CPU from `time.process_time`", "", text]
    (ROOT / "bench" / "RESULTS_synth_speed.md").write_text("\n".join(doc))
    print(f"wrote {ROOT / 'bench' / 'RESULTS_synth_speed.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
