#!/usr/bin/env python
"""Which body prior earns its place: each one off (or on), on iid noise and on a realistic detector.

    python bench/bench_ablation.py                    # 4 slices x 2 noise models x 4 seeds
    python bench/bench_ablation.py --seeds 2 --frames 600 --out /tmp/ablation.md

Scenes: ``make_wide_scene(seed, slice, noise, frames, skeleton="BODY_25")`` for the
geometry slices ``favourable``, ``gym``, ``wide``, ``low_parallax`` and the detector
models ``iid`` (4 px Gaussian) and ``realistic`` (AR(1) noise of correlation
0.90-0.97, a per-label bias of 2-4 px, 5 % outliers along the epipolar lines, 3 %
left/right swaps in each view: :mod:`mirrorgraph.synth.detector`); BODY_25 so that
the hip prior applies. Each scene is initialised once (``calibrate(refine=False)``:
pairing, left/right fixes, RANSAC) and every variant refines that initialisation
(``refine_mirror``) *without* a subject height (with a height the bone lengths stay
in the graph for the gauge, so "bones off" would not be off).

Variants: ``full`` (the defaults: bones where their length is measured without bias,
symmetry, anthropometry, hip; no smoothness in the calibration graph; the joints
pass), each of bones / symmetry / anthropometry / hip off, the smoothness of 0.8 h
*on* in the calibration graph, every bone in every frame (``bone_bias_limit=None``),
reprojection only (every prior off), and no joints pass.

Metrics (medians over the scenes of a noise model): rotation error of the virtual
camera over the scene's Cramer-Rao bound (:func:`mirrorgraph.metrics.cramer_rao_mirror`,
iid 4 px, reprojection only: the realistic detector's bias is not in it, so errors
there are many bounds), PA-MPJPE of the refined joints against the truth (mm, after a
per-frame similarity alignment, so without the metric scale), CPU seconds of the
refinement and its linear solves; then the error per slice.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np
from scipy.stats import wilcoxon

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

OFF = dict(use_bone_length=False, use_symmetry=False, use_anthropometry=False, use_hip=False)
VARIANTS = {
    "full": {},
    "- bones": dict(use_bone_length=False),
    "- symmetry": dict(use_symmetry=False),
    "- anthropometry": dict(use_anthropometry=False),
    "- hip": dict(use_hip=False),
    "+ smoothness 0.8 h": dict(use_smoothness=True),
    "every bone, every frame": dict(bone_bias_limit=None),
    "reprojection only": OFF,
    "no joints pass": dict(joints_smoothness_sigma=None),
}
SLICES = ("favourable", "gym", "wide", "low_parallax")
NOISE = ("iid", "realistic")


def run_scene(case: tuple[str, str, int, int]) -> list[dict]:
    import warnings
    warnings.filterwarnings("ignore")
    import mirrorgraph as mg
    from mirrorgraph.graph import RefineOptions
    from mirrorgraph.pipelines.solve import refine_mirror
    from mirrorgraph.metrics import cramer_rao_mirror, mirror_rotation_error_deg, pa_mpjpe
    from mirrorgraph.synth import make_wide_scene

    slice_, noise, seed, frames = case
    sc = make_wide_scene(seed, slice_, noise, frames, skeleton="BODY_25")
    calib = np.zeros(sc.skeleton.num_joints, bool)
    calib[sc.skeleton.calibration_joints] = True
    seen = ~sc.missing_real & ~sc.missing_mirror & calib[None]
    bound = cramer_rao_mirror(sc.K, sc.normal, sc.distance, sc.joints3d[seen], 4.0)["rot_rms_deg"]
    run = mg.calibrate(sc.detections, sc.intrinsics, mg.CalibrateOptions(refine=False))
    K = run.calibration.intrinsics.K
    rows = [dict(slice=slice_, noise=noise, seed=seed, variant="initialisation",
                 err=mirror_rotation_error_deg(run.calibration.normal, sc.normal) / bound)]
    for name, kw in VARIANTS.items():
        t0 = time.process_time()
        try:
            r = refine_mirror(run.paired, K, run.calibration.normal, run.candidates,
                              joints=run.joints, options=RefineOptions(**kw))
        except Exception as exc:  # noqa: BLE001 - a crash is a result here
            rows.append(dict(slice=slice_, noise=noise, seed=seed, variant=name,
                             err=np.nan, mpjpe=np.nan, cpu=np.nan, solves=np.nan,
                             error=f"{type(exc).__name__}: {exc}"))
            continue
        cpu = time.process_time() - t0
        rows.append(dict(slice=slice_, noise=noise, seed=seed, variant=name,
                         err=mirror_rotation_error_deg(r.normal, sc.normal) / bound,
                         mpjpe=1000 * pa_mpjpe(r.joints3d, sc.joints3d, r.valid & calib[None]),
                         cpu=cpu, solves=r.iterations))
    return rows


def tables(rows: list[dict]) -> list[str]:
    names = ["initialisation"] + list(VARIANTS)
    out = ["| variant | " + " | ".join(f"{n}: err / bound, PA-MPJPE mm, CPU s, solves"
                                      for n in NOISE) + " |",
           "|:---|" + "---:|" * len(NOISE)]
    for name in names:
        cells = []
        for noise in NOISE:
            R = [r for r in rows if r["variant"] == name and r["noise"] == noise]
            if not R:
                cells.append("–")
                continue
            err = np.nanmedian([r["err"] for r in R])
            if name == "initialisation":
                cells.append(f"{err:.2f}")
                continue
            crashed = sum("error" in r for r in R)
            cells.append(f"{err:.2f}, {np.nanmedian([r['mpjpe'] for r in R]):.1f}, "
                         f"{np.nanmedian([r['cpu'] for r in R]):.2f}, "
                         f"{np.nanmedian([r['solves'] for r in R]):.0f}"
                         + (f" ({crashed} crashed)" if crashed else ""))
        out.append(f"| {name} | " + " | ".join(cells) + " |")
    out += ["", "Median error / bound per slice:", ""]
    cols = [(s, n) for n in NOISE for s in SLICES]
    out += ["| variant | " + " | ".join(f"{s} {n}" for s, n in cols) + " |",
            "|:---|" + "---:|" * len(cols)]
    for name in names:
        out.append(f"| {name} | " + " | ".join(
            f"{np.nanmedian([r['err'] for r in rows if r['variant'] == name and r['slice'] == s and r['noise'] == n]):.2f}"
            for s, n in cols) + " |")
    out += ["", "Each variant against the full graph, scene by scene (the same initialisation and "
            "detections): scenes where it is better / worse than the full graph, RMS error / "
            "bound of the two, and the two-sided Wilcoxon signed-rank p-value (a small p: the "
            "difference is not chance).", ""]
    out += ["| variant | " + " | ".join(f"{n}: better / worse, RMS full -> variant, p"
                                      for n in NOISE) + " |",
            "|:---|" + "---:|" * len(NOISE)]
    for name in names:
        if name == "full":
            continue
        cells = []
        for noise in NOISE:
            full = {(r["slice"], r["seed"]): r["err"] for r in rows
                    if r["variant"] == "full" and r["noise"] == noise}
            pairs = np.array([(full[(r["slice"], r["seed"])], r["err"]) for r in rows
                              if r["variant"] == name and r["noise"] == noise
                              and (r["slice"], r["seed"]) in full], dtype=float)
            pairs = pairs[np.isfinite(pairs).all(1)] if len(pairs) else pairs
            if len(pairs) < 6:
                cells.append("–")
                continue
            f, v = pairs[:, 0], pairs[:, 1]
            p = wilcoxon(v, f).pvalue if np.any(v != f) else 1.0
            cells.append(f"{int((v < f).sum())} / {int((v > f).sum())}, "
                         f"{np.sqrt(np.mean(f ** 2)):.2f} -> {np.sqrt(np.mean(v ** 2)):.2f}, "
                         f"{p:.3f}")
        out.append(f"| {name} | " + " | ".join(cells) + " |")
    return out


def main() -> None:
    from _report import header, now
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "RESULTS_ablation.md")
    ap.add_argument("--replot", type=Path, default=None, metavar="RESULTS.json",
                    help="only rewrite the tables of --out (its header kept) from a run's JSON")
    args = ap.parse_args()
    if args.replot:
        rows = json.loads(args.replot.read_text())
        head = []
        for line in args.out.read_text().splitlines():
            if line.startswith("| "):
                break
            head.append(line)
        args.out.write_text("\n".join(head + tables(rows) + [""]))
        print(f"wrote {args.out} from {args.replot}")
        return
    t0 = time.perf_counter()
    cases = [(s, n, seed, args.frames) for n in NOISE for s in SLICES for seed in range(args.seeds)]
    with Pool(args.workers) as pool:
        rows = []
        for i, part in enumerate(pool.imap(run_scene, cases), 1):
            rows += part
            print(f"[{i}/{len(cases)}] {part[0]['slice']}/{part[0]['noise']}/{part[0]['seed']}: "
                  + ", ".join(f"{r['variant']} {r['err']:.2f}" for r in part), flush=True)
    lines = ["# Ablation of the body priors (`bench/bench_ablation.py`)", "",
             *header(started=f"{now()} ({(time.perf_counter() - t0) / 60:.1f} min)",
                     cmd=f"python bench/bench_ablation.py --seeds {args.seeds} --frames "
                         f"{args.frames} --workers {args.workers}",
                     note=f"{args.workers} scenes at a time: CPU times are the steadier figure"),
             f"* scenes: `make_wide_scene(seed, slice, noise, {args.frames}, skeleton='BODY_25')`, "
             f"seeds 0-{args.seeds - 1}, slices {', '.join(SLICES)}; every variant refines the same "
             "initialisation, no subject height (see the script's docstring).", "",
             *tables(rows), ""]
    args.out.write_text("\n".join(lines))
    args.out.with_suffix(".json").write_text(json.dumps(rows))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
