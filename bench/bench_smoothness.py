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
  the prior's per-axis sigma is set against;
* the same over the **ankles**, each fast-limb joint's err/std p99 and the joints with the
  worst scene's highest, the PA-MPJPE over the **oracle**'s (``bench_joints.oracle``),
  the **coverage rule** per kind (:data:`MEDIAN_RANGE`, :data:`P99_MAX`) with each
  value's PA-MPJPE over the first value's on the same scene, and the err/std >= 3 share
  per bin of the truth's acceleration over the sigma (:data:`ACCEL_BINS`: where the
  motion outruns the prior).

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

``--tables A.json B.json`` re-tabulates this script's ``--json`` runs together (the same
values); ``--chain NOISE`` smooths each CMU joint's track alone (iid noise of ``NOISE``
of the height per axis, :func:`chain_smooth`) under the priors of :data:`CHAIN_PRIORS`,
with and without the smoother's bias estimate in the std.

Usage::

    python bench/bench_smoothness.py --values 0.02,0.01,0.005,0.0025 --kinds cmu --seeds 0-9
    python bench/bench_smoothness.py --values 0.01 --scene fps=60 --run-fps 30,60
    python bench/bench_smoothness.py --joints cmu_0.01.json cmu_0.005.json --out T.md
    python bench/bench_smoothness.py --tables real.json rest.json
    python bench/bench_smoothness.py --chain 0.015 --seeds 0-5 --frames 680
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
ANKLES = ("left_ankle", "right_ankle")
#: the joint groups scored apart (the fast limbs), besides every joint
GROUPS = (("wrist", WRISTS), ("ankle", ANKLES))


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
    lag, :func:`bench_joints.replay_live`) on the truth's frames, as
    :func:`_calibrate_joints`; the stream's rate ``fps``."""
    from mirrorgraph.live import LiveOptions

    r = bj.replay_live(tr, LiveOptions.of(subject_height=tr.height_given,
                                          refine_options=ropts, fps=fps))
    return r["X"], np.isfinite(r["X"]).all(-1), r["std_shape"]


def run_one(tr, sigma: float | None, refine: tuple, fps: float,
            method: str = "calibrate", oracle_pa_mm: float | None = None) -> dict:
    """One ``calibrate`` (or with ``method="live"`` one replayed live run, its lines'
    settled joints) of the scene at ``joints_smoothness_sigma = sigma``, told the frame
    rate ``fps``: its figures (``oracle_pa_mm``: the scene's oracle PA-MPJPE, for the
    ratio)."""
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
    out = dict(wall_s=wall)
    groups = [("all", list(range(J)))] + [
        (tag, [tr.names.index(n) for n in names if n in tr.names]) for tag, names in GROUPS]
    groups += [(f"j:{n}", [j]) for j, n in enumerate(tr.names)]
    for tag, cols in groups:
        p = pa[:, cols]
        out[f"pa_{tag}_mm"] = 1e3 * float(np.nanmean(p)) if np.isfinite(p).any() else np.nan
        g = given[:, cols]
        z = (e_shape[:, cols] / sd[:, cols])[g & np.isfinite(sd[:, cols]) & (sd[:, cols] > 0)]
        out[f"z_{tag}_median"] = float(np.median(z)) if z.size else np.nan
        out[f"z_{tag}_p99"] = float(np.percentile(z, 99)) if z.size else np.nan
    # the error / std against the truth's own acceleration there (the norm of its second
    # difference over the run's per-axis sigma at its rate): where the motion outruns the
    # prior, the smoothing's bias, which the std does not hold
    if sigma:
        s_run = float(sigma) * (bj.FPS / fps) ** 2
        f = np.asarray(tr.frame_ids)
        acc = np.full((T, J), np.nan)
        ok = (np.diff(f)[:-1] == 1) & (np.diff(f)[1:] == 1)
        a = np.linalg.norm(tr.joints3d[2:] - 2 * tr.joints3d[1:-1] + tr.joints3d[:-2], axis=-1)
        acc[1:-1][ok] = a[ok] / tr.height / s_run
        z = e_shape / sd
        zok = given & np.isfinite(sd) & (sd > 0) & np.isfinite(acc)
        for lo, hi in ACCEL_BINS:
            m = zok & (acc >= lo) & (acc < hi)
            out[f"acc_{lo:g}"] = dict(n=int(m.sum()), over=int((z[m] >= P99_MAX).sum()),
                                      median=float(np.median(z[m])) if m.any() else np.nan)
    out["oracle_ratio"] = (out["pa_all_mm"] / oracle_pa_mm
                           if oracle_pa_mm and np.isfinite(oracle_pa_mm) else np.nan)
    eg = e[given]
    out["gross"] = float((eg > bj.GROSS_M).mean()) if eg.size else np.nan
    out["worst_m"] = float(eg.max()) if eg.size else np.nan
    return out


FIGS = (("pa_all_mm", "PA all mm", ".1f"), ("oracle_ratio", "/ oracle", ".2f"),
        ("pa_wrist_mm", "PA wrists mm", ".1f"), ("pa_ankle_mm", "PA ankles mm", ".1f"),
        ("z_all_median", "err/std all med", ".2f"), ("z_all_p99", "err/std all p99", ".2f"),
        ("z_wrist_median", "err/std wrists med", ".2f"),
        ("z_wrist_p99", "err/std wrists p99", ".2f"),
        ("z_ankle_p99", "err/std ankles p99", ".2f"),
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
                a = np.array([r.get(key, np.nan) for r in rs], float)
                if key == "gross":
                    a = 100 * a
                a = a[np.isfinite(a)]
                cells.append(f"{np.median(a):{spec}} / {a.max():{spec}}" if a.size else "n/a")
            L.append(f"| {k} | {v} | {len(rs)} | " + " | ".join(cells) + " |")
    return L


#: the truth's acceleration bins (its second difference's norm over the per-axis sigma;
#: a Gaussian's norm of per-axis sigma 1 has median 1.54, p99 3.37)
ACCEL_BINS = ((0.0, 1.5), (1.5, 3.0), (3.0, 6.0), (6.0, np.inf))


def accel_bins_table(rows: list[dict], values: list, kinds: list[str]) -> list[str]:
    """Per kind and value, pooled over the scenes' joint-frames: per bin of the truth's
    acceleration over the sigma, the joint-frames' share, their share with shape err/std
    at or over ``P99_MAX``, and the bin's share of all those."""
    L = ["| kind | sigma | " + " | ".join(
        f"accel/sigma {lo:g}-{hi:g}: share, err/std >= {P99_MAX:g} %" for lo, hi in ACCEL_BINS)
        + f" | err/std >= {P99_MAX:g} at accel/sigma >= 3: share of them |",
        "|---|---|" + "---:|" * (len(ACCEL_BINS) + 1)]
    for k in kinds:
        for v in values:
            rs = [r["runs"][str(v)] for r in rows if r["kind"] == k and str(v) in r["runs"]]
            bins = [[r[f"acc_{lo:g}"] for r in rs if f"acc_{lo:g}" in r] for lo, _ in ACCEL_BINS]
            n = np.array([sum(b["n"] for b in bb) for bb in bins], float)
            o = np.array([sum(b["over"] for b in bb) for bb in bins], float)
            if not n.sum():
                continue
            cells = [f"{100 * n[i] / n.sum():.1f} %, {100 * o[i] / max(n[i], 1):.2f}"
                     for i in range(len(ACCEL_BINS))]
            L.append(f"| {k} | {v} | " + " | ".join(cells)
                     + f" | {100 * o[2:].sum() / max(o.sum(), 1):.0f} % of {int(o.sum())} |")
    return L


#: the coverage rule the package's joints' stds are held to (``bench_joints.py``'s
#: targets): per kind, the median of the scenes' shape err/std medians in this range and
#: every scene's shape err/std 99th percentile under ``P99_MAX``
MEDIAN_RANGE, P99_MAX = (0.5, 1.5), 3.0


def coverage_table(rows: list[dict], values: list, kinds: list[str]) -> list[str]:
    """Per kind and value: the coverage rule (the median of the scenes' shape err/std
    medians, the worst scene's p99, the scenes over ``P99_MAX``) and the PA-MPJPE against
    the first value's on the same scene (median and range of the per-scene ratios)."""
    L = [f"| kind | sigma | scenes | shape err/std med (median of scenes) | p99 (median / worst "
         f"scene) | scenes p99 >= {P99_MAX:g} | rule | PA / {values[0]}'s (median, min-max) |",
         "|---|---|---:|---:|---:|---:|---|---:|"]
    for k in kinds:
        for v in values:
            rs = [(r["runs"][str(values[0])], r["runs"][str(v)]) for r in rows
                  if r["kind"] == k and str(v) in r["runs"]]
            if not rs:
                continue
            med = np.array([b["z_all_median"] for _, b in rs], float)
            p99 = np.array([b["z_all_p99"] for _, b in rs], float)
            ratio = np.array([b["pa_all_mm"] / a["pa_all_mm"] for a, b in rs], float)
            m = float(np.nanmedian(med))
            ok = MEDIAN_RANGE[0] <= m <= MEDIAN_RANGE[1] and np.nanmax(p99) < P99_MAX
            L.append(f"| {k} | {v} | {len(rs)} | {m:.2f} | {np.nanmedian(p99):.2f} / "
                     f"{np.nanmax(p99):.2f} | {int((p99 >= P99_MAX).sum())} | "
                     f"{'met' if ok else '**not met**'} | {np.nanmedian(ratio):.3f} "
                     f"({np.nanmin(ratio):.3f}-{np.nanmax(ratio):.3f}) |")
    return L


def joint_table(rows: list[dict], values: list, kinds: list[str], top: int = 3) -> list[str]:
    """Per kind and value: each fast limb joint's shape err/std p99 (median of the scenes /
    worst scene), and the ``top`` joints with the highest worst-scene p99."""
    limbs = [n for _, names in GROUPS for n in names]
    L = ["| kind | sigma | " + " | ".join(f"{n} p99 (med / max)" for n in limbs)
         + f" | top {top} joints by worst-scene p99 |", "|---|---|" + "---:|" * len(limbs) + "---|"]
    for k in kinds:
        for v in values:
            rs = [r["runs"][str(v)] for r in rows if r["kind"] == k and str(v) in r["runs"]]
            if not rs:
                continue
            names = [key[4:-4] for key in rs[0] if key.startswith("z_j:") and key.endswith("_p99")]

            def p99(n):
                a = np.array([r.get(f"z_j:{n}_p99", np.nan) for r in rs], float)
                return a[np.isfinite(a)]
            cells = [(f"{np.median(a):.2f} / {a.max():.2f}" if (a := p99(n)).size else "n/a")
                     for n in limbs]
            worst = sorted(((p99(n).max(), n) for n in names if p99(n).size), reverse=True)[:top]
            L.append(f"| {k} | {v} | " + " | ".join(cells) + " | "
                     + ", ".join(f"{n} {w:.2f}" for w, n in worst) + " |")
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


def chain_smooth(y: np.ndarray, sigma_frame: float, sigma_acc: float,
                 huber: float | None = None, iterations: int = 15
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One joint's track ``y`` ``(T, 3)`` (consecutive frames, iid per-axis noise
    ``sigma_frame``) smoothed by a second-difference prior of per-axis ``sigma_acc``:
    the posterior mean ``(T, 3)``, its per-axis variance ``(T,)`` and the smoother's bias
    estimated at the solution ``(T, 3)``.

    The posterior mean is ``x = S y``, ``S = (I + lambda D^T D)^-1``, ``lambda =
    sigma_frame^2 / sigma_acc^2``; its bias on a motion ``m`` is ``(S - I) m = -lambda S
    D^T D m``, which the posterior variance holds only for a motion as smooth as the
    prior says. At the solution ``x - y = -lambda D^T D x``, so ``S (x - y)`` is the bias
    with the estimate for the motion (the posterior covariance times the prior's
    gradient there). ``huber``: the prior's norm under a Huber loss at ``huber`` sigmas
    (iteratively reweighted; the variance of the last weights)."""
    from scipy.linalg import solveh_banded

    T = len(y)
    w = np.ones(T - 2)
    c = np.array([1.0, -2.0, 1.0])
    for _ in range(iterations if huber else 1):
        ab = np.zeros((3, T))                  # upper banded form of I / sf^2 + D^T W D / sa^2
        ab[2] = 1.0 / sigma_frame ** 2
        for a in range(3):
            ab[2, a:T - 2 + a] += w * c[a] ** 2 / sigma_acc ** 2
        for a in range(2):
            ab[1, 1 + a:T - 1 + a] += w * c[a] * c[a + 1] / sigma_acc ** 2
        ab[0, 2:] += w * c[0] * c[2] / sigma_acc ** 2
        x = solveh_banded(ab, y / sigma_frame ** 2)
        if huber:
            r = np.linalg.norm(x[:-2] - 2 * x[1:-1] + x[2:], axis=1) / sigma_acc
            w = np.where(r > huber, huber / np.maximum(r, 1e-12), 1.0)
    var = np.diag(solveh_banded(ab, np.eye(T))).copy()
    return x, var, solveh_banded(ab, (x - y) / sigma_frame ** 2)


#: the chain's priors: (label, per-axis sigma, Huber threshold in sigmas or None, the bias
#: estimate added to the variance)
CHAIN_PRIORS = (("0.01", 0.01, None, False), ("0.007", 0.007, None, False),
                ("0.005", 0.005, None, False), ("0.005 Huber 2", 0.005, 2.0, False),
                ("0.01 + bias^2", 0.01, None, True), ("0.007 + bias^2", 0.007, None, True),
                ("0.005 + bias^2", 0.005, None, True), ("0.0035 + bias^2", 0.0035, None, True))


def chain_table(seeds: list[int], frames: int, noise: float, fixtures: Path) -> list[str]:
    """The CMU take's true joints, each joint's track alone with iid per-axis noise of
    ``noise`` (fraction of the height) smoothed by each of :data:`CHAIN_PRIORS`: the
    mean error (mm) and the error / std (RMS length) median and p99 (median of the
    scenes / worst scene), every joint, the wrists, the ankles; pooled over ``seeds``
    (each its own noise draw)."""
    res: dict = {}
    names: list = []
    for s in seeds:
        tr = bj.make_truth("cmu", s, frames, fixtures)
        X, h, names = tr.joints3d, tr.height, tr.names
        Y = X + np.random.default_rng([s, 31]).normal(0.0, noise * h, X.shape)
        for label, sa, hub, with_bias in CHAIN_PRIORS:
            E, Z = np.zeros(X.shape[:2]), np.zeros(X.shape[:2])
            for j in range(X.shape[1]):
                x, var, b = chain_smooth(Y[:, j], noise * h, sa * h, hub)
                E[:, j] = np.linalg.norm(x - X[:, j], axis=1)
                v = var + ((b ** 2).sum(1) / 3 if with_bias else 0.0)
                Z[:, j] = E[:, j] / np.sqrt(3 * v)
            res.setdefault(label, []).append((E, Z))
    groups = [("all", list(range(len(names))))] + [
        (tag, [names.index(n) for n in ns if n in names]) for tag, ns in GROUPS]
    L = ["| prior | " + " | ".join(f"{g}: err mm, err/std med, p99 (med / max)" for g, _ in groups)
         + " |", "|---|" + "---|" * len(groups)]
    for label, rs in res.items():
        cells = []
        for _, cols in groups:
            e = np.concatenate([E[:, cols].ravel() for E, _ in rs])
            zm = np.median(np.concatenate([Z[:, cols].ravel() for _, Z in rs]))
            p = [np.percentile(Z[:, cols], 99) for _, Z in rs]
            cells.append(f"{1e3 * e.mean():.1f}, {zm:.2f}, {np.median(p):.2f} / {max(p):.2f}")
        L.append(f"| {label} | " + " | ".join(cells) + " |")
    return L


def _tables(rows: list[dict], values: list, kinds: list[str]) -> list[str]:
    return [*table(rows, values, kinds), "",
            "The coverage rule (shape err/std median of the scenes' in "
            f"[{MEDIAN_RANGE[0]:g}, {MEDIAN_RANGE[1]:g}], every scene's p99 < {P99_MAX:g}):",
            "", *coverage_table(rows, values, kinds), "",
            "The shape err/std against the truth's acceleration (pooled joint-frames):", "",
            *accel_bins_table(rows, values, kinds), "",
            "The fast limbs' shape err/std p99, per joint:", "",
            *joint_table(rows, values, kinds), "",
            "The truth's acceleration (norm of the second difference, fraction of the height "
            "per frame^2; median over the scenes):", "", *accel_table(rows, kinds), ""]


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--values", default="0.02,0.01,0.005,0.0025",
                    help="joints_smoothness_sigma values, comma-separated ('none': no pass)")
    bj.add_scene_args(ap, "cmu", "0-9")
    ap.add_argument("--scene", action="append", default=[], type=bj._refine_pair,
                    help="a make_scene argument (repeatable), e.g. fps=60")
    ap.add_argument("--run-fps", default="scene",
                    help="frame rates told the runs, comma-separated (default: the scene's)")
    ap.add_argument("--refine", action="append", default=[], type=bj._refine_pair,
                    help="a further RefineOptions field (repeatable)")
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--out", default=None, help="markdown (default: print only)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--joints", nargs="+", default=None,
                    help="bench_joints.py --json files: tabulate them per value per kind, exit")
    ap.add_argument("--method", default="calibrate",
                    help="calibrate or live: the runs' (with --joints: the files' to tabulate)")
    ap.add_argument("--tables", nargs="+", default=None,
                    help="this script's --json files (same values): their scenes' tables, exit")
    ap.add_argument("--chain", type=float, default=None, metavar="NOISE",
                    help="the smoothing alone on the CMU take's joints with iid noise of "
                         "NOISE (fraction of the height, per axis): the priors of "
                         "CHAIN_PRIORS over --seeds, --frames; exit")
    args = ap.parse_args(argv)
    if args.chain is not None:
        os.nice(args.nice)
        text = "\n".join(chain_table(bj._seeds(args.seeds), args.frames, args.chain,
                                     args.fixtures))
        print(text)
        if args.out:
            Path(args.out).write_text(text + "\n")
        return 0
    if args.joints:
        text = "\n".join(joints_table(args.joints, args.method))
        print(text)
        if args.out:
            Path(args.out).write_text(text + "\n")
        return 0
    if args.tables:
        rows = [sc for p in args.tables for sc in json.loads(Path(p).read_text())["scenes"]]
        values = list(rows[0]["runs"])
        kinds = list(dict.fromkeys(r["kind"] for r in rows))
        text = "\n".join(_tables(rows, values, kinds))
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
    for k, s in bj.scene_list(args):
        tr = bj.make_truth(k, s, args.frames, args.fixtures, scene=tuple(args.scene))
        a_all, a_w = _accel(tr)
        orc = bj.oracle(tr)["pa_mpjpe_mm"]
        row = dict(kind=k, seed=s, accel=dict(
            all_med=float(np.median(a_all)), all_p99=float(np.percentile(a_all, 99)),
            wrist_med=float(np.median(a_w)), wrist_p99=float(np.percentile(a_w, 99))),
            oracle_pa_mm=float(orc), runs={})
        for label, v, rate in configs:
            fps = rate or tr.detections.fps or bj.FPS
            row["runs"][label] = r = run_one(tr, v, tuple(args.refine), fps, args.method,
                                             orc)
            r["run_fps"] = float(fps)
            print(f"{k} {s} sigma {label}: PA {r['pa_all_mm']:.1f} mm, wrists "
                  f"{r['pa_wrist_mm']:.1f} mm, err/std wrists p99 {r['z_wrist_p99']:.2f} "
                  f"({r['wall_s']:.0f} s)", file=sys.stderr, flush=True)
        rows.append(row)
        if args.json:   # each scene as it is done
            Path(args.json).write_text(json.dumps(dict(meta=dict(partial=True),
                                                       scenes=rows), indent=1))
    meta = dict(date=f"{started:%Y-%m-%d %H:%M} UTC", code=bj.code_version(),
                command="python bench/bench_smoothness.py " + shlex.join(argv),
                machine=_report.machine(), minutes=(time.perf_counter() - clock) / 60.0)
    L = ["# The joints pass's acceleration prior (`bench/bench_smoothness.py`)", "",
         f"- date: {meta['date']}; code `{meta['code']}`",
         f"- machine: {meta['machine']}; {meta['minutes']:.1f} min",
         f"- command: `{meta['command']}`", "", *_tables(rows, values, kinds)]
    text = "\n".join(L)
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    if args.json:
        Path(args.json).write_text(json.dumps(dict(meta=meta, scenes=rows), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
