#!/usr/bin/env python
"""The estimated focal length's error / std on long videos, solved in chunks.

    python bench/bench_focal_long.py --frames 1000,4000 --scenes 12 [--before DIR] [--no-write]

Above ``RefineOptions.max_graph_frames`` (2000) frames a one-mirror video is solved in
chunks that hold the focal length a spread subset estimated (:mod:`mirrorgraph.graph.chunked`).
Each scene (``bench_focal.py``'s issue-23 set: ``make_wide_scene`` and ``make_scene``
variants, principal points off centre) is calibrated from its detections with the image
size alone (:func:`mirrorgraph.calibrate`, no camera matrix), the subject's height given,
in a fresh process per tree; the table gives the focal length's error, its std and
error / std per scene and frame count. With ``--before DIR`` (a checkout of another
commit, e.g. ``git archive HEAD~1 | tar -x -C DIR``) that tree runs beside this one.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from _report import emit, header  # noqa: E402

ONE = r"""
import json, os, sys
for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(v, "1")
sys.path.insert(0, sys.argv[3])
import numpy as np
import mirrorgraph as mg
from bench_focal import honest_scene
sc = honest_scene(int(sys.argv[1]), int(sys.argv[2]))
opts = mg.CalibrateOptions(subject_height=sc.get("height"), image_size=sc["image_size"])
cal = mg.calibrate(sc["detections"], None, opts).calibration
est = cal.intrinsics.estimated or {}
f, ft = float(cal.intrinsics.K[0, 0]), float(sc["K"][0, 0])
print(json.dumps({"kind": sc["kind"], "f_true": ft, "f": f,
                  "std": float(est.get("std_px", np.nan)),
                  "determined": bool(est.get("determined", False))}))
"""


def run(tree: Path, seed: int, frames: int) -> dict:
    """One scene in a fresh process on ``tree``'s package: run in ``tree`` (``python -c``
    puts the working directory first on the path) with its bench scripts."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", ONE, str(seed), str(frames), str(tree / "bench")],
                         env=env, cwd=tree, capture_output=True, text=True)
    if out.returncode:
        return {"failed": (out.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", default="1000,4000")
    ap.add_argument("--scenes", type=int, default=12, help="issue 23's scenes 0..N-1")
    ap.add_argument("--before", type=Path, default=None, help="another tree, run beside")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS_focal_long.md"))
    a = ap.parse_args()
    frames = [int(x) for x in a.frames.split(",")]
    trees = ([("before", a.before)] if a.before else []) + [("after", ROOT)]
    rows, z = [], {(n, T): [] for n, _ in trees for T in frames}
    for seed in range(a.scenes):
        for T in frames:
            cells = []
            for name, tree in trees:
                r = run(tree, seed, T)
                if "failed" in r:
                    cells.append("failed: " + r["failed"][:60])
                    continue
                e = (r["f"] - r["f_true"]) / r["f_true"]
                zz = (r["f"] - r["f_true"]) / r["std"]
                if r["determined"]:
                    z[(name, T)].append(abs(zz))
                cells.append("%+.2f %% / %.2f %% / %+.2f%s" % (
                    100 * e, 100 * r["std"] / r["f_true"], zz, "" if r["determined"] else " (u)"))
                kind = r["kind"]
            line = "| %d | %s | %d | %s |" % (seed, kind, T, " | ".join(cells))
            print(line, flush=True)
            rows.append(line)
    names = [n for n, _ in trees]
    lines = ["# The focal length's error / std on long videos (`bench/bench_focal_long.py`)", "",
             *header(code=True), "",
             "Cells: the focal length's error / its std (both of the true focal length) / error over "
             "std; `(u)`: called undetermined (the std its prior's or the disagreement's, "
             "left out of the summary). Above 2000 frames the video is solved in chunks.", "",
             "| scene | kind | frames | " + " | ".join(names) + " |",
             "|---:|---|---:|" + "---:|" * len(names), *rows, "",
             "Determined scenes: |error| / std median, largest, count beyond 3:", ""]
    for T in frames:
        for n in names:
            v = np.asarray(z[(n, T)])
            if v.size:
                lines.append("- %s, %d frames (%d scenes): %.2f, %.2f, %d" % (
                    n, T, v.size, float(np.median(v)), float(v.max()), int((v > 3).sum())))
    emit(lines, None if a.no_write else a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
