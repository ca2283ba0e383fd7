"""A rig's metric scale from one person on snapshots: one body's stature or a mix's.

On snapshots (frames far apart in time) a rig's one-person run keeps each snapshot's own
subject (:mod:`mirrorgraph.rigs.observations`): several people over the video. The scale is
the stature of the body seen in the most snapshots (:func:`mirrorgraph.pipelines.scale.
subject_frames`), whose height is given; before, the stature was measured over every
frame, the median of the mix. Both from one run: the run's scale error against the truth
(the cameras' distances from the first, median), and the mix's, the same joints measured
over every frame (``1 + e_mix = (1 + e) x stature of the body / stature of every frame``,
both on the run's joints).

Scenes: ``make_rig_people(3 cameras, 3 people, 30 snapshots, seed, 4 px noise, 2 %
outliers, 2 % left/right swaps)`` (the scenes of ``tests/pipelines/test_rig_snapshots.py``);
the height given is the true height of the person who is the subject of the most
snapshots (found on a first run without a height, each frame's joints matched to the
nearest true person).

Usage::

    python bench/bench_rig_snapshot_scale.py                 # seeds 1-5, ~5 min
    python bench/bench_rig_snapshot_scale.py --seeds 1-10

Writes ``--out`` (default ``bench/RESULTS_rig_snapshot_scale.md``) unless ``--no-write``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402
from bench_joints import _seeds  # noqa: E402


def _distances(cal) -> np.ndarray:
    return np.array([np.linalg.norm(c.pose[:3, 3]) for c in cal.cameras[1:]])


def scene(seed: int, folder: Path) -> dict:
    from mirrorgraph.pipelines.options import CalibrateOptions
    from mirrorgraph.pipelines.rig import calibrate_rig
    from mirrorgraph.stature import estimate_stature
    from mirrorgraph.synth.rig_people import make_rig_people, write_rig_people

    rig = make_rig_people(3, 3, frames=30, seed=seed, snapshots=True, noise_std=4.0,
                          outlier_rate=0.02, lr_swap_rate=0.02)
    truth = np.array([np.linalg.norm(P[:3, 3]) for P in rig.poses[1:]])
    first = calibrate_rig(write_rig_people(rig, folder / f"{seed}a"),
                          CalibrateOptions(people="one"))
    X = first.joints3d * np.median(truth / _distances(first))
    owner = np.array([np.argmin([np.nanmedian(np.linalg.norm(X[t] - rig.joints3d[p, t], -1))
                                 for p in range(rig.num_people)])
                      for t in range(len(X)) if np.isfinite(X[t]).any()])
    seen = np.bincount(owner, minlength=rig.num_people)
    main = int(seen.argmax())
    cal = calibrate_rig(write_rig_people(rig, folder / f"{seed}b",
                                         subject_height=float(rig.heights[main])),
                        CalibrateOptions(people="one"))
    err = float(np.median(_distances(cal) / truth) - 1.0)
    every = estimate_stature(cal.joints3d, cal.valid, rig.skeleton).height
    body = float(cal.refinement["stature"]["height"])
    rel = float(np.median([c.position_std / np.linalg.norm(c.pose[:3, 3])
                           for c in cal.cameras[1:]]))
    return dict(seed=seed, heights=rig.heights.tolist(), seen=seen.tolist(), main=main,
                err=err, err_mix=(1.0 + err) * body / every - 1.0, std=rel,
                source=cal.scale_source.split("; ")[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1-5")
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent
                                         / "RESULTS_rig_snapshot_scale.md"))
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    if args.nice:
        os.nice(args.nice)
    clock = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        rows = [scene(s, Path(tmp)) for s in _seeds(args.seeds)]
    e = np.array([r["err"] for r in rows])
    m = np.array([r["err_mix"] for r in rows])
    L = ["# A rig's scale from one person on snapshots (`bench/bench_rig_snapshot_scale.py`)",
         "", *_report.header(argv=argv, code=True,
                             note=f"{(time.perf_counter() - clock) / 60:.1f} min"), "",
         "`subject`: snapshots whose subject is each true person (the height given is the "
         "most-seen one's, `given`); `scale %`: the run's error (one body's stature), "
         "`mix %`: the same joints scaled by the stature of every frame (the mix); `std %`: "
         "the cameras' position std over their distance (median); `found`: the run's "
         "`scale_source`.", "",
         "| seed | heights m | subject | given | scale % | mix % | std % | found |",
         "|---:|---|---|---:|---:|---:|---:|---|"]
    for r in rows:
        L.append(f"| {r['seed']} | {', '.join(f'{h:.3f}' for h in r['heights'])} | "
                 f"{', '.join(map(str, r['seen']))} | {r['main']} | {100 * r['err']:+.2f} | "
                 f"{100 * r['err_mix']:+.2f} | {100 * r['std']:.2f} | {r['source']} |")
    L += ["", f"RMS over {len(rows)} scenes: one body {100 * np.sqrt((e ** 2).mean()):.2f} %, "
          f"the mix {100 * np.sqrt((m ** 2).mean()):.2f} %; largest "
          f"{100 * np.abs(e).max():.2f} % against {100 * np.abs(m).max():.2f} %."]
    _report.emit(L, None if args.no_write else args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
