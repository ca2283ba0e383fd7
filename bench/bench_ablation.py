"""Ablation of the factor graph on scenes with a realistic detector, end to end.

Each scene: ``mirrorgraph.synth.make_scene`` with BODY_25 (so the hip prior
applies), 1000 frames, 4 px noise correlated from frame to frame (AR(1) 0.8),
a constant per-joint bias of 3 px (std), 10% outliers and 10% left/right
confusions on the reflection; the subject's height is given. Every variant runs
the whole pipeline from the detections (pairing, RANSAC, graph): the
initialisation alone, the full graph, and the full graph with each prior
switched off. Metrics as MirrorCalib defines them: rotation error of the
virtual camera (deg), translation error after scaling to the true norm (mm),
PA-MPJPE of the 3D joints (mm), plus the error of the metric distance.

It also times the pipeline on the paper's protocol (1000 frames, COCO-17,
white 4 px noise) with the split init / build / solve / marginals.

Run:  python bench/bench_ablation.py [--seeds 8] [--out bench/RESULTS_ablation.md]
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import mirrorgraph as mg  # noqa: E402
from mirrorgraph.graph import RefineOptions  # noqa: E402
from mirrorgraph.metrics import pa_mpjpe, rotation_error_deg, translation_error  # noqa: E402
from mirrorgraph.synth import make_scene  # noqa: E402

REALISTIC = dict(frames=1000, skeleton="BODY_25", noise_std=4.0, noise_correlation=0.8,
                 joint_bias_px=3.0, outlier_rate=0.10, lr_swap_rate=0.10)

VARIANTS: dict[str, RefineOptions | None] = {
    "initialisation only": None,
    "full graph": RefineOptions(),
    "- bone length": RefineOptions(use_bone_length=False),
    "- symmetry": RefineOptions(use_symmetry=False),
    "- anthropometry": RefineOptions(use_anthropometry=False),
    "- hip colinearity": RefineOptions(use_hip=False),
    "+ smoothness (0.8 h)": RefineOptions(use_smoothness=True),
    "every bone, every frame": RefineOptions(bone_bias_limit=None),
    "reprojection only": RefineOptions(use_bone_length=False, use_symmetry=False,
                                       use_anthropometry=False, use_hip=False),
}


def run_variant(scene, ropts):
    opts = mg.CalibrateOptions(subject_height=scene.subject_height, refine=ropts is not None,
                               refine_options=ropts)
    t0 = time.perf_counter()
    run = mg.calibrate(scene.detections, scene.intrinsics, opts)
    wall = time.perf_counter() - t0
    c = run.calibration
    rot = rotation_error_deg(c.virtual_rotation, scene.virtual_R)
    trans = 1000 * translation_error(c.virtual_translation, scene.virtual_t)
    if run.joints3d is not None:
        mpjpe = 1000 * pa_mpjpe(run.joints3d, scene.joints3d, run.valid3d)
        dist = 100 * (c.distance - scene.distance) / scene.distance
    else:
        mpjpe = dist = float("nan")
    return rot, trans, mpjpe, dist, wall


def ablation(seeds: int) -> list[str]:
    rows = {k: [] for k in VARIANTS}
    for seed in range(seeds):
        scene = make_scene(seed=seed, **REALISTIC)
        for name, ropts in VARIANTS.items():
            rows[name].append(run_variant(scene, ropts))
            r = rows[name][-1]
            print(f"seed {seed} {name:22s} rot {r[0]:.4f} deg  trans {r[1]:6.1f} mm  "
                  f"PA-MPJPE {r[2]:6.1f} mm  dist {r[3]:+.2f} %  {r[4]:.2f} s", flush=True)
    lines = ["| variant | rotation deg (median) | rotation deg (IQR) | translation mm (median) "
             "| PA-MPJPE mm (median) | distance error % (median abs) | wall s (median) |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for name, vals in rows.items():
        a = np.array(vals)
        q1, q3 = np.percentile(a[:, 0], [25, 75])
        lines.append(f"| {name} | {np.median(a[:, 0]):.4f} | {q1:.4f}-{q3:.4f} | "
                     f"{np.median(a[:, 1]):.1f} | {np.nanmedian(a[:, 2]):.1f} | "
                     f"{np.nanmedian(np.abs(a[:, 3])):.2f} | {np.median(a[:, 4]):.2f} |")
    return lines


def timing(repeats: int = 3) -> list[str]:
    scene = make_scene(frames=1000, seed=0)
    splits = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run = mg.calibrate(scene.detections, scene.intrinsics,
                           mg.CalibrateOptions(subject_height=scene.subject_height))
        total = time.perf_counter() - t0
        splits.append({**run.timings, "end to end": total})
    keys = list(splits[0])
    med = {k: float(np.median([s.get(k, np.nan) for s in splits])) for k in keys}
    print("timing (median of", repeats, "):", {k: round(v, 3) for k, v in med.items()})
    return ["| " + " | ".join(keys) + " |", "|" + "---:|" * len(keys),
            "| " + " | ".join(f"{med[k]:.3f}" for k in keys) + " |"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "RESULTS_ablation.md")
    args = ap.parse_args()
    t_lines = timing()
    a_lines = ablation(args.seeds)
    load = os.getloadavg()
    text = "\n".join([
        "# Ablation of the factor graph, and end-to-end time",
        "",
        f"* date: {_dt.datetime.now().isoformat(timespec='seconds')}",
        f"* machine: {platform.platform()}, {os.cpu_count()} CPUs, Python "
        f"{platform.python_version()}; load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}",
        f"* command: `python bench/bench_ablation.py --seeds {args.seeds}`",
        "",
        "## End to end, 1000 frames x 12 joints (paper's protocol, COCO-17), seconds",
        "",
        "Pairing and RANSAC (`initialisation`), graph `build`, `solve` and `marginals`, and the "
        "whole `mirrorgraph.calibrate` call; median of 3 runs.",
        "",
        *t_lines,
        "",
        "## Ablation on a realistic detector",
        "",
        f"Scenes: `make_scene(seed=0..{args.seeds - 1}, {', '.join(f'{k}={v!r}' for k, v in REALISTIC.items())})`, "
        "subject height given. Every variant runs the whole pipeline from the raw detections.",
        "",
        *a_lines,
        "",
    ])
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
