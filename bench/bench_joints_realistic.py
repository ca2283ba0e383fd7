"""Where the realistic detector's 3D joints lose against the oracle: by error type and joint group.

The realistic detector (:data:`mirrorgraph.synth.detector.DETECTORS`) adds four kinds of
error to MirrorCalib's iid noise: AR(1) noise correlated from frame to frame, a per-label
bias the two views share (mirrored), keypoints displaced along their epipolar lines and
the whole person's left and right swapped in one view. Each scene of
:func:`mirrorgraph.synth.make_wide_scene` is run through ``calibrate`` (as
``bench/bench_joints.py`` runs it) under variants of its detector, each with one kind
switched off and every other draw the same (the detector's draws come from generators of
their own, so a variant changes only its kind):

* ``realistic``: the preset; ``no bias``, ``no correlation``, ``no epipolar``, ``no
  swaps``: that kind off; ``iid``: all four off (4 px iid noise); ``correlation only``:
  the preset's AR(1) noise alone;

and, on the preset's observations, with the graph given what the oracle has:

* ``true normal``: the joints pass run at the true mirror normal (the graph's own
  distance and bone lengths, which were estimated with its own normal: not a
  consistent set);
* ``true mirror+bones``: the joints pass at the true mirror and the true bone lengths
  (both in the graph's scale: the sum of the graph's bones over the sum of the true
  ones); the face is completed after the graph with the solved mirror, so only its body
  joints' figure measures what the truth gives;
* ``passes``: the joints pass iterated to convergence (the two above iterate too), as
  their control.

Every figure is the run's against the oracle's (each frame triangulated with the TRUE
mirror from the same observations, outliers removed with the truth) on the joints both
give, after each frame's similarity alignment (PA): over all joints and by group (face:
nose, eyes, ears; arms: shoulders, elbows, wrists; legs: hips, knees, ankles). The
``realistic`` run's frames are also split by their distance to the nearest frame the
detector swapped (either view), and its joints by whether an observation was displaced
along its epipolar line.

Usage::

    python bench/bench_joints_realistic.py                 # 6 scenes x 10 runs, ~10-15 min
    python bench/bench_joints_realistic.py --seeds 0-11 --variants realistic,iid

Writes ``--out`` (default ``bench/RESULTS_joints_realistic.md``) unless ``--no-write``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402
import bench_joints as bj  # noqa: E402
from mirrorgraph.metrics import pa_joint_errors  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: a kind switched off without touching the detector's other draws: a correlation and a
#: bias this small take the same generator path as the preset's
OFF = dict(noise_correlation=1e-9, joint_bias_px=1e-12, epipolar_outlier_rate=0.0,
           lr_swap_rate=0.0)
#: variant -> (make_scene overrides, joints-pass hook)
VARIANTS = {
    "realistic": ({}, None),
    "no bias": (dict(joint_bias_px=OFF["joint_bias_px"]), None),
    "no correlation": (dict(noise_correlation=OFF["noise_correlation"]), None),
    "no epipolar": (dict(epipolar_outlier_rate=0.0), None),
    "no swaps": (dict(lr_swap_rate=0.0), None),
    "iid": (dict(OFF), None),
    "correlation only": (dict(OFF, noise_correlation=None), None),
    "passes": ({}, "passes"),
    "true normal": ({}, "normal"),
    "true mirror+bones": ({}, "mirror"),
}
GROUPS = {"face": ("nose", "eye", "ear"), "arms": ("shoulder", "elbow", "wrist"),
          "legs": ("hip", "knee", "ankle")}
#: iterations of the joints pass under a hook (to convergence from a moved start)
HOOK_ITERATIONS = 10


def _install_hook(mode: str | None, tr):
    """Patch the driver's joints-pass stage for ``mode`` (this worker process only);
    returns the function that undoes it (a worker runs further cases)."""
    if mode is None:
        return lambda: None
    from mirrorgraph.factors.mirror_link import plane_to_gtsam
    from mirrorgraph.graph import stages
    from mirrorgraph.graph.problem import extract_planes, snap_virtual_poses

    original = stages._joints_pass_stage
    iterations = stages.JOINTS_PASS_ITERATIONS
    stages.JOINTS_PASS_ITERATIONS = HOOK_ITERATIONS

    def true_length(bone: str, problem) -> float | None:
        sk = problem.rig.skeleton
        for nm, (a, b) in zip(sk.bone_names, sk.bone_index):
            if nm == bone:
                d = np.linalg.norm(tr.joints3d[:, a] - tr.joints3d[:, b], axis=-1)
                return float(np.median(d))
        return None

    def patched(run, lengths, points):
        if mode in ("normal", "mirror"):
            problem, values = run.problem, run.values
            n_g, d_g = extract_planes(problem, values)[0]
            n = np.asarray(tr.normal, float)
            d = d_g
            if mode == "mirror":
                true = {b: true_length(b, problem) for b in lengths}
                common = [b for b in lengths if true[b]]
                s = sum(lengths[b] for b in common) / sum(true[b] for b in common)
                lengths = {b: true[b] * s if true[b] else v for b, v in lengths.items()}
                d = float(tr.distance) * s
            values.update(problem.plane_keys[0], plane_to_gtsam(n, d))
            snap_virtual_poses(problem, values)
        return original(run, lengths, points)

    stages._joints_pass_stage = patched

    def undo() -> None:
        stages._joints_pass_stage = original
        stages.JOINTS_PASS_ITERATIONS = iterations

    return undo


def _truth(seed: int, frames: int, overrides: dict):
    """The bench's truth of ``realistic seed`` under ``overrides``, and its scene."""
    import mirrorgraph.synth as synth

    held = {}
    original = synth.make_wide_scene

    def wide(*a, **kw):
        held["scene"] = original(*a, **{**kw, **overrides})
        return held["scene"]

    synth.make_wide_scene = wide
    try:
        tr = bj._synthetic("realistic", seed, frames, "population")
    finally:
        synth.make_wide_scene = original
    tr.height_given = tr.height
    return tr, held["scene"]


def run_case(case: tuple) -> dict:
    import warnings
    warnings.filterwarnings("ignore")
    from mirrorgraph.metrics import normal_angle_deg

    seed, frames, variant = case
    overrides, hook = VARIANTS[variant]
    clock = time.perf_counter()
    tr, sc = _truth(seed, frames, {k: v for k, v in overrides.items() if v is not None})
    orc = bj.oracle(tr)
    Xo, oko = orc["_X"], orc["_ok"]
    import mirrorgraph as mg

    undo = _install_hook(hook, tr)
    try:
        run = mg.calibrate(tr.detections, tr.intrinsics,
                           mg.CalibrateOptions(subject_height=tr.height_given, fps=bj.FPS))
    finally:
        undo()
    T = tr.joints3d.shape[0]
    X, given, _, _ = bj.on_truth_frames(run, tr)
    given &= np.isfinite(X).all(-1)
    both = given & oko
    e_run = pa_joint_errors(X, tr.joints3d, both)
    e_orc = pa_joint_errors(Xo, tr.joints3d, both)
    body = np.array([not any(k in n for k in GROUPS["face"]) for n in tr.names])
    e_run_b = pa_joint_errors(X, tr.joints3d, both & body)
    e_orc_b = pa_joint_errors(Xo, tr.joints3d, both & body)
    out = dict(seed=seed, variant=variant,
               normal_err_deg=float(normal_angle_deg(np.asarray(run.calibration.normal),
                                                     tr.normal)),
               run_mm=1e3 * float(np.nanmean(e_run)), oracle_mm=1e3 * float(np.nanmean(e_orc)),
               body_run_mm=1e3 * float(np.nanmean(e_run_b)),
               body_oracle_mm=1e3 * float(np.nanmean(e_orc_b)),
               seconds=time.perf_counter() - clock)
    for g, keys in GROUPS.items():
        cols = [j for j, n in enumerate(tr.names) if any(k in n for k in keys)]
        out[f"{g}_run_mm"] = 1e3 * float(np.nanmean(e_run[:, cols]))
        out[f"{g}_oracle_mm"] = 1e3 * float(np.nanmean(e_orc[:, cols]))
    if variant == "realistic":
        swapped = np.asarray(sc.lr_swapped, bool) | np.asarray(sc.lr_swapped_real, bool)
        idx = np.flatnonzero(swapped)
        t = np.arange(T)
        dist = (np.min(np.abs(t[:, None] - idx[None]), 1) if idx.size
                else np.full(T, 10 ** 6))
        bins = {"0": dist == 0, "1-3": (dist >= 1) & (dist <= 3),
                "4-10": (dist >= 4) & (dist <= 10), "more": dist > 10}
        out["by_swap"] = {k: [int(m.sum()), 1e3 * float(np.nanmean(e_run[m])),
                              1e3 * float(np.nanmean(e_orc[m]))] for k, m in bins.items()}
        epi = (np.asarray(sc.epipolar_outlier_mask_real, bool)
               | np.asarray(sc.epipolar_outlier_mask_mirror, bool))
        # the oracle leaves the displaced observations out: the run's own error on
        # them (aligned on every joint it gives) against its error on the others
        e_all = pa_joint_errors(X, tr.joints3d, given)
        out["by_epipolar"] = {k: [int((given & m).sum()), 1e3 * float(np.nanmean(e_all[m]))]
                              for k, m in (("displaced", epi), ("clean", ~epi))}
    return out


def _fmt(v, f=".1f"):
    return "n/a" if v is None or not np.isfinite(v) else format(v, f)


def tables(rows: list[dict], variants: list[str]) -> list[str]:
    med = lambda xs: float(np.median(xs)) if len(xs) else float("nan")  # noqa: E731
    L = ["## By detector error and by what the graph is given", "",
         "Median over scenes of each figure (mm: the mean aligned joint error on the joints "
         "both give; ratio: the run's over the oracle's, each scene's, then the median):", "",
         "| variant | scenes | oracle mm | run mm | run / oracle | body joints: run / oracle "
         "| face | arms | legs | normal error deg |",
         "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for v in variants:
        rs = [r for r in rows if r["variant"] == v]
        if not rs:
            continue
        ratio = lambda a, b: med([r[a] / r[b] for r in rs])  # noqa: E731
        L.append(f"| {v} | {len(rs)} | {_fmt(med([r['oracle_mm'] for r in rs]))} | "
                 f"{_fmt(med([r['run_mm'] for r in rs]))} | {_fmt(ratio('run_mm', 'oracle_mm'), '.2f')} | "
                 f"{_fmt(ratio('body_run_mm', 'body_oracle_mm'), '.2f')} | "
                 + " | ".join(_fmt(ratio(f'{g}_run_mm', f'{g}_oracle_mm'), '.2f') for g in GROUPS)
                 + f" | {_fmt(med([r['normal_err_deg'] for r in rs]), '.3f')} |")
    L += ["", "Per group, mm (run / oracle), median over scenes:", "",
          "| variant | face | arms | legs |", "|---|---:|---:|---:|"]
    for v in variants:
        rs = [r for r in rows if r["variant"] == v]
        if rs:
            L.append(f"| {v} | " + " | ".join(
                f"{_fmt(med([r[f'{g}_run_mm'] for r in rs]))} / "
                f"{_fmt(med([r[f'{g}_oracle_mm'] for r in rs]))}" for g in GROUPS) + " |")
    real = [r for r in rows if r["variant"] == "realistic" and "by_swap" in r]
    if real:
        L += ["", "The `realistic` runs' frames by their distance to the nearest frame the "
              "detector swapped (either view), and their joints by an observation displaced "
              "along its epipolar line (all scenes pooled; mm: mean aligned error):", "",
              "| frames | run mm | oracle mm | run / oracle |", "|---|---:|---:|---:|"]
        for k in real[0]["by_swap"]:
            n = sum(r["by_swap"][k][0] for r in real)
            a = np.nansum([r["by_swap"][k][0] * r["by_swap"][k][1] for r in real]) / max(n, 1)
            b = np.nansum([r["by_swap"][k][0] * r["by_swap"][k][2] for r in real]) / max(n, 1)
            L.append(f"| {k} from a swap ({n} frames) | {a:.1f} | {b:.1f} | {a / b:.2f} |")
        for k in real[0]["by_epipolar"]:
            n = sum(r["by_epipolar"][k][0] for r in real)
            a = np.nansum([r["by_epipolar"][k][0] * r["by_epipolar"][k][1] for r in real]) / max(n, 1)
            L.append(f"| joints {k} ({n}; aligned on every joint the run gives) | {a:.1f} "
                     "| (left out) | - |")
    L += ["", "## Per scene", "", "| seed | variant | oracle mm | run mm | run / oracle | "
          "body run / oracle | normal error deg |", "|---:|---|---:|---:|---:|---:|---:|"]
    for r in sorted(rows, key=lambda r: (r["seed"], variants.index(r["variant"]))):
        L.append(f"| {r['seed']} | {r['variant']} | {r['oracle_mm']:.1f} | {r['run_mm']:.1f} | "
                 f"{r['run_mm'] / r['oracle_mm']:.2f} | "
                 f"{r['body_run_mm'] / r['body_oracle_mm']:.2f} | {r['normal_err_deg']:.3f} |")
    return L


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-5")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS_joints_realistic.md"))
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    variants = [v for v in args.variants.split(",") if v]
    for v in variants:
        if v not in VARIANTS:
            ap.error(f"--variants: unknown {v!r}; known: {', '.join(VARIANTS)}")
    os.nice(10)
    cases = [(s, args.frames, v) for s in bj._seeds(args.seeds) for v in variants]
    clock = time.perf_counter()
    rows = []
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        for r in pool.map(run_case, cases):
            rows.append(r)
            print(f"realistic {r['seed']} {r['variant']}: run {r['run_mm']:.1f} mm, oracle "
                  f"{r['oracle_mm']:.1f} mm ({r['seconds']:.0f} s)", file=sys.stderr, flush=True)
    L = ["# The realistic detector's 3D joints against the oracle, by cause "
         "(`bench/bench_joints_realistic.py`)", "",
         f"- date: {_report.now()}; code `{bj.code_version()}`",
         f"- machine: {_report.machine()}; {(time.perf_counter() - clock) / 60:.1f} min with "
         f"{args.workers} workers",
         f"- command: `{_report.command(argv, 'bench_joints_realistic.py')}`",
         f"- scenes: `make_wide_scene(seed, 'wide', 'realistic', {args.frames})`, bodies with "
         "the adult spread, the true height given; variants: the script's docstring", ""]
    L += tables(rows, variants)
    _report.emit(L, None if args.no_write else args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
