"""What holds a joint in depth at low parallax: the joints pass with its held lengths, the true ones, the torso term.

Where a joint's two rays meet at a few degrees (the person near the line through the
camera and the mirror) its depth is the body's: the joints pass
(:func:`mirrorgraph.graph.stages.joints_pass`) holds every bone at a length and the
motion smooth. Each scene is calibrated as ``bench/bench_joints.py`` runs it (its
:func:`run_calibrate`: the camera matrix and a reported height given, its scoring) four
times:

* ``held``: as the package runs it (the lengths the joints pass is given);
* ``held + torso``: with the torso term (``RefineOptions.torso_sigma`` 0.02);
* ``true lengths``: the joints pass given every bone's true length (the scene's median,
  times the scale of the ``held`` run's joints pass against the truth), the rest as is;
* ``true lengths + torso``: both.

Per scene and variant: the share of the joints more than 0.3 m off (metric, and with
the run's scale fitted to the truth), more than 1 m, the worst, PA-MPJPE, err/std p99;
for ``held`` the bones the joints pass got no length for and each held length's error
(the same scale fitted). Over the scenes: the median and the worst.

Usage::

    python bench/bench_low_parallax_depth.py                      # lowpar 0-9, iid 9, cmu 0-4
    python bench/bench_low_parallax_depth.py --scenes lowpar:6,iid:9 --no-write
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

import _report  # noqa: E402
import bench_joints as bj  # noqa: E402

VARIANTS = (("held", False, None), ("held + torso", False, 0.02),
            ("true lengths", True, None), ("true lengths + torso", True, 0.02))
DEFAULT_SCENES = "lowpar:0-9,iid:9,cmu:0-4"


def _scenes(text: str) -> list[tuple[str, int]]:
    out = []
    for part in text.split(","):
        kind, seeds = part.split(":")
        out += [(kind, s) for s in bj._seeds(seeds)]
    return out


def run_scene(kind: str, seed: int, frames: int) -> dict:
    """The four variants of one scene (module docstring)."""
    import mirrorgraph.graph.stages as stages
    from mirrorgraph.graph import RefineOptions
    from mirrorgraph.graph.bones import bone_table
    from mirrorgraph.graph.problem import extract_points

    tr = bj.make_truth(kind, seed, frames, bj.default_fixtures())
    truth = tr.joints3d
    original_pass, original_options = stages.joints_pass, bj._refine_options
    held: dict = {}
    out = {"scene": f"{kind} {seed}"}
    for name, true_lengths, torso in VARIANTS:
        def patched(problem, values, lengths, opts, sensitivity=False,
                    true_lengths=true_lengths):
            names, pairs = bone_table(problem.rig)
            true = {b: float(np.median(np.linalg.norm(truth[:, i] - truth[:, j], axis=-1)))
                    for b, (i, j) in zip(names, pairs)}
            if true_lengths:
                lengths = {b: v * held["scale"] for b, v in true.items()}
            res = original_pass(problem, values, lengths, opts, sensitivity)
            if not true_lengths:
                P = extract_points(res[0], res[1].values)
                ok = np.isfinite(P).all(-1)
                s = float((P[ok] * truth[ok]).sum() / (truth[ok] * truth[ok]).sum())
                held.update(scale=s, missing=[b for b in names if b not in lengths],
                            errors={b: 100.0 * (lengths[b] / s / true[b] - 1.0)
                                    for b in names if b in lengths})
            return res

        stages.joints_pass = patched
        bj._refine_options = lambda _k, torso=torso: RefineOptions(torso_sigma=torso)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = bj.run_calibrate(tr)
        finally:
            stages.joints_pass, bj._refine_options = original_pass, original_options
        out[name] = {k: r.get(k) for k in ("gross", "gross_shape", "far", "worst_m",
                                           "pa_mpjpe_mm", "z_p99")}
    out["missing"] = held.get("missing", [])
    out["length_errors"] = held.get("errors", {})
    return out


def _f(v, spec: str) -> str:
    return "n/a" if v is None or not np.isfinite(v) else format(v, spec)


def tables(rows: list[dict]) -> list[str]:
    L = ["## Per scene", "",
         "`> 0.3 m` metric / with the run's scale fitted, `> 1 m`, worst (m), PA-MPJPE (mm), "
         "err/std p99; `held`'s bones without a length and its held lengths' largest "
         "errors (%, the scale fitted).", "",
         "| scene | variant | > 0.3 m % | > 0.3 m, scale out % | > 1 m % | worst m | PA mm "
         "| err/std p99 |", "|---|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        for name, *_ in VARIANTS:
            v = r[name]
            L.append(f"| {r['scene']} | {name} | {_f(100 * v['gross'], '.2f')} | "
                     f"{_f(100 * v['gross_shape'], '.2f')} | {_f(100 * v['far'], '.2f')} | "
                     f"{_f(v['worst_m'], '.2f')} | {_f(v['pa_mpjpe_mm'], '.1f')} | "
                     f"{_f(v['z_p99'], '.2f')} |")
    L += ["", "| scene | bones without a length | held lengths' largest errors % |",
          "|---|---|---|"]
    for r in rows:
        worst = sorted(r["length_errors"].items(), key=lambda kv: -abs(kv[1]))[:4]
        L.append(f"| {r['scene']} | {', '.join(r['missing']) or '-'} | "
                 + ", ".join(f"{b} {e:+.1f}" for b, e in worst) + " |")
    L += ["", "## Over the scenes: median / worst", "",
          "| variant | > 0.3 m % | > 0.3 m, scale out % | > 1 m % | worst m | PA mm |",
          "|---|---:|---:|---:|---:|---:|"]
    for name, *_ in VARIANTS:
        cells = []
        for key, scale, spec in (("gross", 100, ".2f"), ("gross_shape", 100, ".2f"),
                                 ("far", 100, ".2f"), ("worst_m", 1, ".2f"),
                                 ("pa_mpjpe_mm", 1, ".1f")):
            v = np.array([r[name][key] for r in rows], float) * scale
            cells.append(f"{_f(np.median(v), spec)} / {_f(np.max(v), spec)}")
        L.append(f"| {name} | " + " | ".join(cells) + " |")
    return L


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=DEFAULT_SCENES,
                    help=f"kind:seeds,... (default {DEFAULT_SCENES})")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--out", default=str(HERE / "RESULTS_low_parallax_depth.md"))
    ap.add_argument("--json", default=None)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    clock = time.perf_counter()
    rows = []
    for kind, seed in _scenes(args.scenes):
        r = run_scene(kind, seed, args.frames)
        rows.append(r)
        print(f"{r['scene']}: " + ", ".join(
            f"{n} {100 * r[n]['gross']:.2f} %" for n, *_ in VARIANTS), flush=True)
    L = ["# What holds a joint in depth at low parallax (`bench/bench_low_parallax_depth.py`)",
         "", f"- date: {_report.now()}; code `{bj.code_version()}`",
         f"- machine: {_report.machine()}; {(time.perf_counter() - clock) / 60:.1f} min",
         f"- command: `{_report.command(argv, 'bench_low_parallax_depth.py')}`",
         f"- scenes: `bench/bench_joints.py`'s ({args.frames} frames, the reported height); "
         "variants: the module docstring", "", *tables(rows)]
    text = "\n".join(L) + "\n"
    print(text)
    if not args.no_write:
        Path(args.out).write_text(text)
        if args.json:
            Path(args.json).write_text(json.dumps(rows, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
