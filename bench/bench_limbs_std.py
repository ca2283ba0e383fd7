"""The limb-proportion scale's std against its error (``scale_from = "limbs"``).

``calibrate`` with ``RefineOptions(scale_from="limbs")`` (the gauge's limb bones and widths
at Winter's fractions of the height, no rescaling by the stature) on ``bench_joints``' wide
iid scenes (``make_wide_scene(seed, 'wide', 'iid', frames)``, population body proportions,
the true height given). Per scene: the metric distance's error, its relative std
(``distance_std / distance``: the graph's, the height's prior ``height_sigma`` and the
measurement's rule :func:`mirrorgraph.stature.measurement_rel_std` with the limbs' prior
:func:`mirrorgraph.stature.limbs_rel_std`), and, from the same run, the std without the
measurement's share (``sqrt(std^2 - m^2)``, ``m`` that rule on the run's stature record:
the height's prior alone), each with the error over it.

Usage::

    python bench/bench_limbs_std.py                   # seeds 0-7, ~2 min
    python bench/bench_limbs_std.py --seeds 0-19 --frames 1000

Writes ``--out`` (default ``bench/RESULTS_limbs_std.md``) unless ``--no-write``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402
from bench_joints import _seeds  # noqa: E402


def scene(seed: int, frames: int) -> dict:
    from mirrorgraph.graph.options import RefineOptions
    from mirrorgraph.pipelines.mirror import CalibrateOptions, calibrate
    from mirrorgraph.stature import measurement_rel_std
    from mirrorgraph.synth.sampling import make_wide_scene

    sc = make_wide_scene(seed, "wide", "iid", frames, body_variation="population")
    run = calibrate(sc.detections, sc.intrinsics,
                    CalibrateOptions(subject_height=sc.subject_height,
                                     refine_options=RefineOptions(scale_from="limbs")))
    c = run.calibration
    err = c.distance / sc.distance - 1.0
    rel = c.uncertainty["distance_std"] / c.distance
    m = measurement_rel_std(c.refinement["stature"], "limbs")
    before = float(np.sqrt(max(rel ** 2 - m ** 2, 0.0)))
    return dict(seed=seed, height=sc.subject_height, err=err, std=rel, m=m,
                std_prior=before, z=abs(err) / rel, z_prior=abs(err) / before)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0-7")
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "RESULTS_limbs_std.md"))
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    if args.nice:
        os.nice(args.nice)
    clock = time.perf_counter()
    rows = [scene(s, args.frames) for s in _seeds(args.seeds)]
    e = np.array([r["err"] for r in rows])
    z = np.array([r["z"] for r in rows])
    zp = np.array([r["z_prior"] for r in rows])
    L = ["# The limbs' scale: its std against its error (`bench/bench_limbs_std.py`)", "",
         *_report.header(argv=argv, code=True,
                         note=f"{(time.perf_counter() - clock) / 60:.1f} min"), "",
         f"Wide iid scenes, population bodies, {args.frames} frames, the true height, "
         "`scale_from = \"limbs\"`. `err`: the metric distance's error; `std`: its relative "
         "std; `measurement`: the limbs' rule (`measurement_rel_std(record, \"limbs\")`); "
         "`std, prior alone`: the std without it (the height's prior and the graph's).", "",
         "| seed | height m | err % | std % | measurement % | err/std | std, prior alone % | "
         "err/std, prior alone |",
         "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        L.append(f"| {r['seed']} | {r['height']:.3f} | {100 * r['err']:+.2f} | "
                 f"{100 * r['std']:.2f} | {100 * r['m']:.2f} | {r['z']:.2f} | "
                 f"{100 * r['std_prior']:.2f} | {r['z_prior']:.2f} |")
    L += ["", f"Over {len(rows)} scenes: error {100 * np.sqrt((e ** 2).mean()):.2f} % RMS, "
          f"{100 * np.abs(e).max():.2f} % largest; err/std median {np.median(z):.2f}, largest "
          f"{z.max():.2f} (the prior alone: {np.median(zp):.2f}, {zp.max():.2f})."]
    _report.emit(L, None if args.no_write else args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
