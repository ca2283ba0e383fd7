"""The joints pass's acceleration prior against real motion: wrists, frame rate, coverage.

``RefineOptions.joints_smoothness_sigma`` is the std of each joint's second difference
per frame^2 at 30 fps (``REFERENCE_FPS``), a fraction of the subject's height; the run
takes it at its frame rate (``RefineOptions.at_frame_rate``). ``bench/bench_joints.py --refine``
scores it over every joint; this script runs the same ``calibrate`` (its
:func:`bench_joints.make_truth` scenes, the height as a user reports it) at several
values side by side on each scene and scores what a tight prior hurts first:

* **PA-MPJPE** (mm) over every joint and over the **wrists** alone (each frame's
  similarity alignment on all its joints, :func:`mirrorgraph.metrics.pa_joint_errors`);
* the wrists' **error / std** (median, p99): the error left once the run's metric scale
  is fitted to the truth (live: each frame's) over the std without the scale's share
  (``joints_std_shape``, RMS length), as ``bench_joints.py``'s ``shape err/std`` over
  every joint (also given);
* the truth's own **acceleration** (the norm of its second difference over consecutive
  frames, fraction of the height per frame^2; median and p99, wrists and all joints): what
  the prior's per-axis sigma is set against.

Over the scenes: the median and the worst scene (max) of each figure per value.
``--scene fps=60`` plays the same take at another frame rate; each run is told the
scene's rate, or with ``--run-fps 30,60`` each rate in turn (a 60 fps scene told 30 fps
gets the prior per frame number, ``(60/30)^2`` times looser in h/s^2: the code before
``at_frame_rate``). ``--method live`` scores the live run's lines instead (each frame
settled after ``lag_frames``).

``--joints A.json B.json ...`` instead tabulates ``bench_joints.py --json`` runs made at
several ``--refine joints_smoothness_sigma=...`` (every kind, every joint: PA-MPJPE,
its ratio to the oracle's, the > 0.3 m share, the worst joint, the shape error / std) per
value per kind.

Usage::

    python bench/bench_smoothness.py --values 0.02,0.01,0.005,0.0025 --kinds cmu --seeds 0-9
    python bench/bench_smoothness.py --values 0.01 --scene fps=60 --run-fps 30,60
    python bench/bench_smoothness.py --joints cmu_0.01.json cmu_0.005.json --out T.md
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402
import bench_joints as bj  # noqa: E402

WRISTS = ("left_wrist", "right_wrist")


def _accel(tr) -> tuple[np.ndarray, np.ndarray]:
    """The truth's acceleration norms, fraction of the height per frame^2: ``(all, wrists)``
    over the triples of consecutive frames."""
    X = np.asarray(tr.joints3d, float)
    f = np.asarray(tr.frame_ids)
    ok = (np.diff(f)[:-1] == 1) & (np.diff(f)[1:] == 1)
    a = np.linalg.norm(X[2:] - 2 * X[1:-1] + X[:-2], axis=-1)[ok] / tr.height   # (M, J)
    w = [tr.names.index(n) for n in WRISTS if n in tr.names]
    return a[np.isfinite(a)], a[:, w][np.isfinite(a[:, w])]


def _calibrate_joints(tr, ropts, fps: float):
    """``calibrate``'s joints on the truth's frames: ``X (T, J, 3)``, ``given (T, J)``,
    the RMS shape std ``(T, J)``."""
    import mirrorgraph as mg

    opts = mg.CalibrateOptions(subject_height=tr.height_given, fps=fps, refine_options=ropts)
    run = mg.calibrate(tr.detections, tr.intrinsics, opts)
    T, J = tr.joints3d.shape[:2]
    X, given, rows, keep = bj.on_truth_frames(run, tr)
    given &= np.isfinite(X).all(-1)
    sd = np.full((T, J), np.nan)
    if getattr(run, "joints_std_shape", None) is not None:
        sd[rows[keep]] = bj._rms_length(np.asarray(run.joints_std_shape, float))[keep]
    return X, given, sd


def _live_joints(tr, ropts, fps: float):
    """The live run's joints (each frame as its JSON line carries it: settled after the
    lag) on the truth's frames, as :func:`_calibrate_joints`; the stream's rate ``fps``."""
    from mirrorgraph.live import LiveCalibrator, LiveOptions

    det = tr.detections
    live = LiveCalibrator(det.skeleton, tr.intrinsics,
                          LiveOptions.of(subject_height=tr.height_given, refine_options=ropts,
                                         fps=fps))
    T, J = tr.joints3d.shape[:2]
    X, sd = np.full((T, J, 3), np.nan), np.full((T, J), np.nan)
    where = {int(f): i for i, f in enumerate(tr.frame_ids)}

    def take(f) -> None:
        t = where.get(int(f.frame_id))
        if t is not None:
            X[t] = f.joints3d
            if f.joints_std_shape is not None:
                sd[t] = f.joints_std_shape

    try:
        for k, people in enumerate(det.people):
            f = live.update(people, frame_id=int(det.frame_ids[k]))
            if f.settled is not None:
                take(f.settled)
        live.finish()
        for f in live.flush():
            take(f)
    finally:
        live.close()
    return X, np.isfinite(X).all(-1), sd


def run_one(tr, sigma: float | None, refine: tuple, fps: float,
            method: str = "calibrate") -> dict:
    """One ``calibrate`` (or with ``method="live"`` one replayed live run, its lines'
    settled joints) of the scene at ``joints_smoothness_sigma = sigma``, told the frame
    rate ``fps``: its figures."""
    from mirrorgraph.metrics import pa_joint_errors

    ropts = bj._refine_options(None, None, tuple(refine) + (("joints_smoothness_sigma", sigma),))
    clock = time.perf_counter()
    X, given, sd = (_live_joints if method == "live" else _calibrate_joints)(tr, ropts, fps)
    wall = time.perf_counter() - clock
    T, J = tr.joints3d.shape[:2]
    pa = pa_joint_errors(X, tr.joints3d, given)
    Xz = np.where(given[..., None], X, 0.0)
    # the metric scale fitted to the truth: over the run (calibrate's one scale), or each
    # frame's (live's changes from window to window, as tests/live score it)
    axes = (1, 2) if method == "live" else (0, 1, 2)
    fit = ((Xz * tr.joints3d).sum(axes, keepdims=True)
           / np.maximum((Xz * Xz).sum(axes, keepdims=True), 1e-12))
    e_shape = np.linalg.norm(fit * Xz - tr.joints3d, axis=-1)
    e = np.linalg.norm(Xz - tr.joints3d, axis=-1)
    w = [tr.names.index(n) for n in WRISTS if n in tr.names]
    out = dict(wall_s=wall)
    for tag, cols in (("all", list(range(J))), ("wrist", w)):
        p = pa[:, cols]
        out[f"pa_{tag}_mm"] = 1e3 * float(np.nanmean(p)) if np.isfinite(p).any() else np.nan
        g = given[:, cols]
        z = (e_shape[:, cols] / sd[:, cols])[g & np.isfinite(sd[:, cols]) & (sd[:, cols] > 0)]
        out[f"z_{tag}_median"] = float(np.median(z)) if z.size else np.nan
        out[f"z_{tag}_p99"] = float(np.percentile(z, 99)) if z.size else np.nan
    eg = e[given]
    out["gross"] = float((eg > bj.GROSS_M).mean()) if eg.size else np.nan
    out["worst_m"] = float(eg.max()) if eg.size else np.nan
    return out


FIGS = (("pa_all_mm", "PA all mm", ".1f"), ("pa_wrist_mm", "PA wrists mm", ".1f"),
        ("z_all_median", "err/std all med", ".2f"), ("z_all_p99", "err/std all p99", ".2f"),
        ("z_wrist_median", "err/std wrists med", ".2f"),
        ("z_wrist_p99", "err/std wrists p99", ".2f"),
        ("gross", ">0.3 m %", ".2f"), ("worst_m", "worst m", ".2f"))


def table(rows: list[dict], values: list, kinds: list[str]) -> list[str]:
    """Per kind and value: the median and the worst scene (max) of each figure."""
    head = "| kind | sigma | scenes | " + " | ".join(f"{t} (med / max)" for _, t, _ in FIGS) + " |"
    L = [head, "|" + "---|" * (3 + len(FIGS))]
    for k in kinds:
        for v in values:
            rs = [r["runs"][str(v)] for r in rows if r["kind"] == k]
            if not rs:
                continue
            cells = []
            for key, _, spec in FIGS:
                a = np.array([r[key] for r in rs], float)
                if key == "gross":
                    a = 100 * a
                a = a[np.isfinite(a)]
                cells.append(f"{np.median(a):{spec}} / {a.max():{spec}}" if a.size else "n/a")
            L.append(f"| {k} | {v} | {len(rs)} | " + " | ".join(cells) + " |")
    return L


def accel_table(rows: list[dict], kinds: list[str]) -> list[str]:
    L = ["| kind | accel all med | accel all p99 | accel wrists med | accel wrists p99 |",
         "|---|---|---|---|---|"]
    for k in kinds:
        rs = [r for r in rows if r["kind"] == k]
        if rs:
            m = {key: np.median([r["accel"][key] for r in rs])
                 for key in ("all_med", "all_p99", "wrist_med", "wrist_p99")}
            L.append(f"| {k} | {m['all_med']:.4f} | {m['all_p99']:.4f} | "
                     f"{m['wrist_med']:.4f} | {m['wrist_p99']:.4f} |")
    return L


JOINTS_FIGS = (("pa_mpjpe_mm", "PA-MPJPE mm", ".1f"), ("oracle_ratio", "/ oracle", ".2f"),
               ("gross", "> 0.3 m %", ".2f"), ("worst_m", "worst m", ".2f"),
               ("z_shape_median", "shape err/std med", ".2f"),
               ("z_shape_p99", "shape err/std p99", ".2f"))


def joints_table(paths: list[str], method: str = "calibrate") -> list[str]:
    """``bench_joints.py --json`` runs side by side: per kind, per value of
    ``joints_smoothness_sigma`` (the run's ``--refine``), the median and the worst scene
    (max) of each figure over the ``method`` runs (``calibrate`` or ``live``)."""
    runs = []
    for p in paths:
        d = json.loads(Path(p).read_text())
        runs.append((d["meta"].get("refine", {}).get("joints_smoothness_sigma", "default"), d))
    kinds = list(dict.fromkeys(sc["kind"] for _, d in runs for sc in d["scenes"]))
    L = ["| kind | sigma | scenes | " + " | ".join(f"{t} (med / max)" for _, t, _ in JOINTS_FIGS)
         + " |", "|" + "---|" * (3 + len(JOINTS_FIGS))]
    for k in kinds:
        for v, d in sorted(runs, key=lambda r: -float(r[0]) if _num(r[0]) else 0):
            rs = [sc[method] for sc in d["scenes"]
                  if sc["kind"] == k and "error" not in sc.get(method, {"error": 1})]
            if not rs:
                continue
            cells = []
            for key, _, spec in JOINTS_FIGS:
                a = np.array([np.nan if r.get(key) is None else r[key] for r in rs], float)
                a = 100 * a if key == "gross" else a
                a = a[np.isfinite(a)]
                cells.append(f"{np.median(a):{spec}} / {a.max():{spec}}" if a.size else "n/a")
            L.append(f"| {k} | {v} | {len(rs)} | " + " | ".join(cells) + " |")
    return L


def _num(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--values", default="0.02,0.01,0.005,0.0025",
                    help="joints_smoothness_sigma values, comma-separated ('none': no pass)")
    ap.add_argument("--kinds", default="cmu", help=f"comma-separated, of {', '.join(bj.KINDS)}")
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--scene", action="append", default=[], type=bj._refine_pair,
                    help="a make_scene argument (repeatable), e.g. fps=60")
    ap.add_argument("--run-fps", default="scene",
                    help="frame rates told the runs, comma-separated (default: the scene's)")
    ap.add_argument("--refine", action="append", default=[], type=bj._refine_pair,
                    help="a further RefineOptions field (repeatable)")
    ap.add_argument("--fixtures", type=Path, default=bj.default_fixtures())
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--out", default=None, help="markdown (default: print only)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--joints", nargs="+", default=None,
                    help="bench_joints.py --json files: tabulate them per value per kind, exit")
    ap.add_argument("--method", default="calibrate",
                    help="calibrate or live: the runs' (with --joints: the files' to tabulate)")
    args = ap.parse_args(argv)
    if args.joints:
        text = "\n".join(joints_table(args.joints, args.method))
        print(text)
        if args.out:
            Path(args.out).write_text(text + "\n")
        return 0
    os.nice(args.nice)
    sigmas = [None if v.strip().lower() == "none" else float(v) for v in args.values.split(",")]
    rates = [None if r.strip() == "scene" else float(r) for r in args.run_fps.split(",")]
    # (label, sigma, rate told the run; None: the scene's)
    configs = [(str(v) if len(rates) == 1 else
                f"{v} @ " + ("scene" if r is None else f"{r:g} fps"), v, r)
               for v in sigmas for r in rates]
    values = [c[0] for c in configs]
    kinds = [k.strip() for k in args.kinds.split(",")]
    started = _dt.datetime.now(_dt.timezone.utc)
    clock = time.perf_counter()
    rows = []
    for k in kinds:
        seeds = ([p.name for p in bj.fixture_dirs(args.fixtures)] if k == "fixtures"
                 else bj._seeds(args.seeds))
        for s in seeds:
            tr = bj.make_truth(k, s, args.frames, args.fixtures, scene=tuple(args.scene))
            a_all, a_w = _accel(tr)
            row = dict(kind=k, seed=s, accel=dict(
                all_med=float(np.median(a_all)), all_p99=float(np.percentile(a_all, 99)),
                wrist_med=float(np.median(a_w)), wrist_p99=float(np.percentile(a_w, 99))),
                runs={})
            for label, v, rate in configs:
                fps = rate or tr.detections.fps or bj.FPS
                row["runs"][label] = r = run_one(tr, v, tuple(args.refine), fps, args.method)
                r["run_fps"] = float(fps)
                print(f"{k} {s} sigma {label}: PA {r['pa_all_mm']:.1f} mm, wrists "
                      f"{r['pa_wrist_mm']:.1f} mm, err/std wrists p99 {r['z_wrist_p99']:.2f} "
                      f"({r['wall_s']:.0f} s)", file=sys.stderr, flush=True)
            rows.append(row)
    meta = dict(date=f"{started:%Y-%m-%d %H:%M} UTC", code=bj.code_version(),
                command="python bench/bench_smoothness.py " + shlex.join(argv),
                machine=_report.machine(), minutes=(time.perf_counter() - clock) / 60.0)
    L = ["# The joints pass's acceleration prior (`bench/bench_smoothness.py`)", "",
         f"- date: {meta['date']}; code `{meta['code']}`",
         f"- machine: {meta['machine']}; {meta['minutes']:.1f} min",
         f"- command: `{meta['command']}`", "",
         *table(rows, values, kinds), "",
         "The truth's acceleration (norm of the second difference, fraction of the height "
         "per frame^2; median over the scenes):", "", *accel_table(rows, kinds), ""]
    text = "\n".join(L)
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    if args.json:
        Path(args.json).write_text(json.dumps(dict(meta=meta, scenes=rows), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
