#!/usr/bin/env python
"""Which body prior moves the mirror, where: each prior alone and all off, across geometries.

    python bench/bench_priors.py                    # 4 scenes a slice, 1000 frames + fixtures
    python bench/bench_priors.py --seeds 2 --frames 600 --out /tmp/priors.md

Scenes: ``bench_stress``'s (``make_wide_scene(seed, geometry, "iid", frames)``, the same
bound ``compare.cramer_rao``) for the slices ``favourable``, ``gym``, ``low_parallax``,
and the independent fixtures (``../shared/fixtures``, skipped when absent). Every
variant refines the same initialisation (``CalibrateOptions(refine=False)``: pairing,
RANSAC) *without* a subject height: with a height the bone lengths stay in the graph
for the gauge, so "bones off" would not be off. Variants: ``full`` (the defaults),
``no priors`` (reprojection alone, the distance held), ``bones only``, ``smoothness
only``, ``all but bones``. Reported: rotation error of the virtual camera over the
scene's bound, and the linear solves.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import mirrorgraph as mg  # noqa: E402
from mirrorgraph.graph import RefineOptions, refine_mirror  # noqa: E402
from mirrorgraph.metrics import mirror_rotation_error_deg  # noqa: E402
from bench_stress import _load_case, machine  # noqa: E402  (bench/bench_stress.py)

OFF = dict(use_bone_length=False, use_symmetry=False, use_anthropometry=False, use_hip=False,
           use_smoothness=False)
VARIANTS = {"full": {}, "no priors": OFF, "bones only": dict(OFF, use_bone_length=True),
            "smoothness only": dict(OFF, use_smoothness=True),
            "all but bones": dict(use_bone_length=False),
            "full, every bone in every frame": dict(bone_bias_limit=None)}
SLICES = ("favourable", "gym", "low_parallax")


def run_case(case: dict) -> dict:
    raw, intr, info, _, stats, bound = _load_case(case)
    run = mg.calibrate(raw, intr, mg.CalibrateOptions(refine=False))
    n_true = np.asarray(info["normal"], float)
    row = {"case": case.get("name") or f"{case['geometry']}/{case['seed']}", "bound": bound,
           "epipole_px": stats.get("epipole_px"),
           "init": mirror_rotation_error_deg(run.calibration.normal, n_true) / bound}
    K = run.calibration.intrinsics.K
    for name, kw in VARIANTS.items():
        t0 = time.process_time()
        res = refine_mirror(run.paired, K, run.calibration.normal, run.candidates,
                            joints=run.joints, options=RefineOptions(**kw))
        row[name] = mirror_rotation_error_deg(res.normal, n_true) / bound
        row[name + " solves"] = res.iterations
        row[name + " cpu"] = time.process_time() - t0
    return row


def table(rows: list[dict]) -> list[str]:
    names = list(VARIANTS)
    out = ["| scene | person-epipole px | init | " + " | ".join(names) + " |",
           "|:---|---:|---:|" + "---:|" * len(names)]
    for r in rows:
        ep = r["epipole_px"]
        out.append(f"| {r['case']} | {ep:.0f} | {r['init']:.2f} | " + " | ".join(
            f"{r[n]:.2f} ({r[n + ' solves']})" for n in names) + " |" if ep is not None else
            f"| {r['case']} | – | {r['init']:.2f} | " + " | ".join(
                f"{r[n]:.2f} ({r[n + ' solves']})" for n in names) + " |")
    return out


def summary(rows: list[dict]) -> list[str]:
    groups: dict[str, list[dict]] = {}
    for r in rows:
        groups.setdefault(r["case"].split("/")[0], []).append(r)
    names = ["init"] + list(VARIANTS)
    out = ["| slice | scenes | " + " | ".join(names) + " |", "|:---|---:|" + "---:|" * len(names)]
    for g, rs in groups.items():
        out.append(f"| {g} | {len(rs)} | " + " | ".join(
            f"{np.median([r[n] for r in rs]):.2f}" for n in names) + " |")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--fixtures", type=Path, default=ROOT.parent / "shared" / "fixtures")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "RESULTS_priors.md")
    args = ap.parse_args()
    t0 = time.perf_counter()
    cases = [dict(kind="synthetic", geometry=g, noise="iid", seed=s, frames=args.frames)
             for g in SLICES for s in range(args.seeds)]
    if args.fixtures.is_dir():
        cases += [dict(kind="fixture", path=str(d), name=f"fixtures/{d.name}")
                  for d in sorted(args.fixtures.glob("scene_*")) if (d / "truth.json").is_file()]
    rows = []
    for i, case in enumerate(cases, 1):
        rows.append(run_case(case))
        print(f"[{i}/{len(cases)}] {rows[-1]['case']}: init {rows[-1]['init']:.2f}, " + ", ".join(
            f"{n} {rows[-1][n]:.2f}" for n in VARIANTS) + " x bound", file=sys.stderr, flush=True)
    lines = ["# Body priors and the mirror across geometries (`bench/bench_priors.py`)", "",
             f"* date: {_dt.datetime.now().isoformat(timespec='seconds')} "
             f"({(time.perf_counter() - t0) / 60:.1f} min)",
             f"* machine: {machine()}",
             f"* command: `python bench/bench_priors.py --seeds {args.seeds} --frames {args.frames}`",
             "* scenes: `make_wide_scene(seed, slice, 'iid', frames)` (4 px iid noise, no outliers "
             "beyond the generator's), the independent fixtures; no subject height (see the "
             "script's docstring); error = rotation error of the virtual camera over the scene's "
             "Cramer-Rao bound; (n) = linear solves.", "",
             "## Median per slice (error / bound)", "", *summary(rows), "",
             "## Every scene", "", *table(rows), ""]
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
