"""Does ``calibrate``'s rotation std cover its error on short clips, as live calibrates them?

Each scene (``bench_joints.make_truth``: iid, realistic, CMU, low parallax, paper,
fixtures; 1000 frames, the reported subject height) is cut into clips of ``--lengths``
frames (non-overlapping, spread over the scene: ``--clips`` of each length at most) and
each clip calibrated with live's window options (``LiveCalibrator``'s ``_copts``, the
options :func:`mirrorgraph.live.estimator.solve_window` runs ``calibrate`` with). Per
clip: the virtual camera's rotation error (twice the normals' angle, deg), the stated
``rotation_std_deg`` and each of its candidates (:data:`mirrorgraph.graph.uncertainty.
ROBUST_PARTS`), the normal error's Mahalanobis length under the stated ``normal_cov``,
and the distance's error over its ``distance_std``.

``--truth-start``: each clip solved a second time from the true normal (the same pairs
and inliers; only the graph's starting mirror differs): where that solve settles more
than 3 stated stds from the first, the clip's cost has a second mode the first solve's
local uncertainty cannot see (``cost``: the graph's final error of each).

Two references for a std that covers its error:

* ``z = err / rotation_std_deg``: the std is the RMS of the 2-D rotation error
  (``2 sqrt(trace)``), so a calibrated one gives a median 0.67 (one direction holds all
  the variance) to 0.83 (isotropic) and ``P(z > 3)`` 0.27 % to 0.01 %;
* ``m = sqrt(delta^T C^+ delta)`` (the normal's error under the stated covariance
  ``C``): Rayleigh, median 1.18, ``P(m > 3) = 1.1 %``.

    python bench/bench_window_std.py --seeds 0-11 --workers 1

``--scene NAME=VALUE``: a ``make_scene`` argument of the synthetic kinds (the
realistic detector without its per-label bias: ``joint_bias_px=0``).
``--from FILE.json[,FILE.json]``: the report again from saved rows (``--json`` writes them).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402
import bench_joints as bj  # noqa: E402

PARTS = ("marginal", "time", "joint", "two_way", "jack_time", "jack_joint")
LENGTHS = (60, 120, 240, 480, 1000)
KINDS = bj.KINDS


def clip_starts(T: int, length: int, clips: int) -> list[int]:
    """Starts of up to ``clips`` non-overlapping clips of ``length`` frames spread over ``T``."""
    n = min(clips, T // length)
    if n <= 0:
        return []
    return sorted({int(v) for v in np.linspace(0, T - length, n).round()})


def _tangent_error(n: np.ndarray, n_true: np.ndarray) -> np.ndarray:
    """The true normal's offset from ``n`` in the tangent plane at ``n`` (rad, camera frame)."""
    d = n_true * np.sign(n_true @ n) - n
    return d - (d @ n) * n


def solve_from(clip, intrinsics, options, normal: np.ndarray):
    """``calibrate``'s steps (known intrinsics) with the graph started at ``normal``."""
    from mirrorgraph.pipelines import mirror as pm

    opts = options.checked()
    obs = pm.observe(clip, intrinsics, opts)
    init = pm.initialise(obs, opts)
    est = init.estimate
    n = np.asarray(normal, float)
    n = n * (np.sign(n @ est.normal) or 1.0)
    init = replace(init, estimate=replace(est, normal=n))
    run = pm.initial_run(obs, init, opts)
    pm.refine_run(run, opts)
    pm.judge_run(run, obs, init, opts)
    return run


def run_scene(case: tuple) -> list[dict]:
    """Every clip of one scene: ``case = (kind, seed, frames, lengths, clips, fixtures)``."""
    warnings.filterwarnings("ignore")
    from mirrorgraph.errors import MirrorgraphError
    from mirrorgraph.live import LiveCalibrator, LiveOptions
    from mirrorgraph.metrics import mirror_rotation_error_deg
    from mirrorgraph.pipelines.mirror import calibrate

    kind, seed, frames, lengths, clips, fixtures, truth_start, scene = case
    tr = bj.make_truth(kind, seed, frames, Path(fixtures), scene=scene)
    # an ablation's rows apart (the fixtures take no scene argument)
    label = kind + ("".join(f" {k}={v:g}" for k, v in scene) if kind != "fixtures" else "")
    det = tr.detections
    copts = LiveCalibrator(det.skeleton, tr.intrinsics,
                           LiveOptions.of(subject_height=tr.height_given))._copts
    tn = np.asarray(tr.normal, float)
    T = len(det.people)
    rows = []
    for L in lengths:
        for a in clip_starts(T, L, clips if L < T else 1):
            row = dict(kind=label, seed=str(seed), length=int(L), start=int(a))
            t0 = time.perf_counter()
            try:
                clip = replace(det, frame_ids=det.frame_ids[a:a + L],
                               people=list(det.people[a:a + L]))
                run = calibrate(clip, tr.intrinsics, copts)
            except (MirrorgraphError, ValueError, np.linalg.LinAlgError) as exc:
                row["error"] = f"{type(exc).__name__}: {str(exc).splitlines()[0][:120]}"
                rows.append(row)
                continue
            row["seconds"] = time.perf_counter() - t0
            c = run.calibration
            u = c.uncertainty or {}
            p = run.refine_parts or {}
            n = np.asarray(c.normal, float)
            delta = _tangent_error(n, tn)
            row.update(err=mirror_rotation_error_deg(n, tn), delta=delta.tolist(),
                       std=float(u.get("rotation_std_deg", np.nan)),
                       chosen=p.get("chosen"), clusters=int(p.get("clusters", 0) or 0),
                       segments=int(p.get("segments", 0) or 0),
                       bandwidth=float(p.get("bandwidth_frames", np.nan)),
                       pairs=int(c.pairs_used), frames=int(c.frames_used))
            cov = u.get("normal_cov")
            row["m"] = (float(np.sqrt(max(delta @ np.linalg.pinv(np.asarray(cov, float),
                                                                  rcond=1e-10) @ delta, 0.0)))
                        if cov is not None else float("nan"))
            for k in PARTS:
                row[f"{k}_std"] = float(p.get(f"{k}_rotation_std_deg", np.nan))
            if c.distance is not None and u.get("distance_std"):
                row.update(d_err=float(c.distance - tr.distance),
                           d_rel=float(c.distance / tr.distance - 1.0),
                           d_std=float(u["distance_std"]))
            row["cost"] = float((c.refinement or {}).get("final_error", np.nan))
            if truth_start:
                try:
                    alt = solve_from(clip, tr.intrinsics, copts, tn).calibration
                    row.update(alt_err=mirror_rotation_error_deg(alt.normal, tn),
                               alt_std=float((alt.uncertainty or {}).get("rotation_std_deg",
                                                                         np.nan)),
                               alt_cost=float((alt.refinement or {}).get("final_error",
                                                                         np.nan)),
                               sep=mirror_rotation_error_deg(alt.normal, n))
                except (MirrorgraphError, ValueError, np.linalg.LinAlgError) as exc:
                    row["alt_error"] = f"{type(exc).__name__}: {exc}"[:120]
            rows.append(row)
    return rows


def _q(x, p):
    return float(np.quantile(x, p)) if len(x) else float("nan")


def _in_region(r: dict, level: float) -> bool:
    """The truth inside the run's ``level`` region (its chosen figure's clusters:
    :func:`mirrorgraph.graph.uncertainty.region_threshold`)."""
    from mirrorgraph.graph.uncertainty import region_threshold

    return r["m"] ** 2 <= region_threshold(2, r["clusters"] or None, level)


def summarise(rows: list[dict], kinds, lengths) -> list[str]:
    out = ["| kind | frames | clips (failed) | rot err deg med / p90 | stated std deg med "
           "| z = err/std med / p90 / p99 | z > 3 | z > 2 | m med / p90 | m > 3 "
           "| region 90 % / 99 % covers | distance err/std med / p90 | distance > 3 "
           "| std chosen |",
           "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for kind in kinds:
        for L in lengths:
            R = [r for r in rows if r["kind"] == kind and r["length"] == L]
            if not R:
                continue
            ok = [r for r in R if "err" in r and np.isfinite(r["std"]) and r["std"] > 0]
            fail = len(R) - len(ok)
            if not ok:
                out.append(f"| {kind} | {L} | 0 ({fail}) | | | | | | | | | | | |")
                continue
            err = np.array([r["err"] for r in ok])
            std = np.array([r["std"] for r in ok])
            z = err / std
            m = np.array([r["m"] for r in ok])
            dz = np.array([abs(r["d_err"]) / r["d_std"] for r in ok if "d_err" in r])
            ch: dict[str, int] = {}
            for r in ok:
                ch[r["chosen"]] = ch.get(r["chosen"], 0) + 1
            chs = ", ".join(f"{k} {v}" for k, v in sorted(ch.items(), key=lambda kv: -kv[1]))
            reg = (f"{np.mean([_in_region(r, .9) for r in ok]):.1%} / "
                   f"{np.mean([_in_region(r, .99) for r in ok]):.1%}")
            dist = (f"{np.median(dz):.2f} / {_q(dz, .9):.2f} | {np.mean(dz > 3):.1%}"
                    if len(dz) else " | ")
            out.append(
                f"| {kind} | {L} | {len(ok)} ({fail}) | {np.median(err):.2f} / {_q(err, .9):.2f} "
                f"| {np.median(std):.2f} | {np.median(z):.2f} / {_q(z, .9):.2f} / {_q(z, .99):.2f} "
                f"| {np.mean(z > 3):.1%} | {np.mean(z > 2):.1%} "
                f"| {np.median(m):.2f} / {_q(m, .9):.2f} | {np.mean(m > 3):.1%} | {reg} "
                f"| {dist} | {chs} |")
    return out


def modes(rows: list[dict], kinds, lengths) -> list[str]:
    """The clips solved again from the truth (``--truth-start``): how many settle in a
    second mode, and how many of the clips whose error exceeds 3 stds that explains."""
    out = ["| kind | frames | clips | second mode: truth start > 3 stds away | "
           "of them, the first mode's cost lower | z > 3 | z > 3 in a second mode "
           "| z > 3, the scene's own error (within half of it of the whole clip's) "
           "| z > 3 where the truth start ends at the same solution: seed@start err / std |",
           "|---|---:|---:|---:|---:|---:|---:|---:|---|"]
    whole = {(r["kind"], r["seed"]): np.asarray(r["delta"]) for r in rows
             if "delta" in r and r["length"] == max(lengths)}

    def persistent(r):
        w = whole.get((r["kind"], r["seed"]))
        d = np.asarray(r["delta"])
        return w is not None and np.linalg.norm(d - w) < 0.5 * np.linalg.norm(d)

    for kind in kinds:
        for L in lengths:
            R = [r for r in rows if r["kind"] == kind and r["length"] == L and "sep" in r
                 and np.isfinite(r["std"]) and r["std"] > 0]
            if not R:
                continue
            two = [r for r in R if r["sep"] > 3 * r["std"]]
            lower = sum(r["cost"] <= r["alt_cost"] for r in two)
            bad = [r for r in R if r["err"] > 3 * r["std"]]
            bad2 = [r for r in bad if r["sep"] > 3 * r["std"]]
            same = ", ".join(f"{r['seed']}@{r['start']}: {r['err']:.2f} / {r['std']:.2f}"
                             for r in bad if r["sep"] <= 3 * r["std"])
            pers = sum(persistent(r) for r in bad if r["sep"] <= 3 * r["std"])
            out.append(f"| {kind} | {L} | {len(R)} | {len(two)} ({len(two) / len(R):.1%}) | "
                       f"{lower} | {len(bad)} ({len(bad) / len(R):.1%}) | {len(bad2)} | "
                       f"{pers} | {same} |")
    return out


#: The joint-pair clusters of the COCO skeleton's mirror joints (every kind here).
JOINT_CLUSTERS = 6


def _t_factor(clusters: int) -> float:
    """``sqrt(nu / (nu - 2))``, ``nu = G - 1``: the RMS of a t variate with the degrees of
    freedom of a variance estimated from ``G`` clusters, over its scale."""
    nu = clusters - 1.0
    return float(np.sqrt(nu / (nu - 2.0))) if nu > 2 else float("nan")


def what_if_t(rows: list[dict], kinds, lengths) -> list[str]:
    """A what-if from the saved rows (the library unchanged): each clustered candidate's
    std times :func:`_t_factor` (joint pairs: ``G = JOINT_CLUSTERS``; the time jackknife:
    its segments), the headline the largest (the chosen one's widening kept)."""
    out = ["| kind | frames | now: z med / z > 3 | t-predictive: z med / z > 3 "
           "| std / now, median |", "|---|---:|---:|---:|---:|"]
    for kind in kinds:
        for L in lengths:
            R = [r for r in rows if r["kind"] == kind and r["length"] == L and "err" in r
                 and np.isfinite(r["std"]) and r["std"] > 0]
            if not R:
                continue
            new = []
            for r in R:
                g = _t_factor(JOINT_CLUSTERS)
                cands = {"marginal": 1.0, "time": 1.0, "joint": g, "two_way": g,
                         "jack_joint": g, "jack_time": _t_factor(r["segments"])}
                old = max(r[f"{k}_std"] for k in cands if np.isfinite(r[f"{k}_std"]))
                s = max(r[f"{k}_std"] * f for k, f in cands.items()
                        if np.isfinite(r[f"{k}_std"] * f))
                new.append(r["std"] * s / old)
            err = np.array([r["err"] for r in R])
            z0, z1 = err / np.array([r["std"] for r in R]), err / np.array(new)
            ratio = np.median(np.array(new) / np.array([r["std"] for r in R]))
            out.append(f"| {kind} | {L} | {np.median(z0):.2f} / {np.mean(z0 > 3):.1%} | "
                       f"{np.median(z1):.2f} / {np.mean(z1 > 3):.1%} | {ratio:.2f} |")
    return out


def main(argv=None) -> int:
    warnings.filterwarnings("ignore")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--seeds", default="0-11", help="synthetic kinds' seeds")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--lengths", default=",".join(map(str, LENGTHS)))
    ap.add_argument("--clips", type=int, default=6, help="clips of each length a scene, at most")
    ap.add_argument("--fixtures", default=str(bj.default_fixtures()))
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--scene", action="append", default=[], metavar="NAME=VALUE",
                    help="a make_scene argument of the synthetic kinds (a detector ablation: "
                         "joint_bias_px=0)")
    ap.add_argument("--truth-start", action="store_true",
                    help="also solve each clip from the true normal (a second mode?)")
    ap.add_argument("--json", default="bench/RESULTS_window_std.json")
    ap.add_argument("--out", default="bench/RESULTS_window_std.md")
    ap.add_argument("--from", dest="src", default=None, help="saved rows: the report only")
    a = ap.parse_args(argv)
    kinds = a.kinds.split(",")
    lengths = [int(v) for v in a.lengths.split(",")]
    scene = tuple((k, float(v)) for k, v in (x.split("=", 1) for x in a.scene))
    metas = []
    if a.src:
        # several runs: a later run's clip (kind, seed, length, start) replaces an earlier's
        merged: dict = {}
        for path in a.src.split(","):
            saved = json.loads(Path(path).read_text())
            metas.append(saved["meta"])
            for r in saved["rows"]:
                merged[(r["kind"], r["seed"], r["length"], r["start"])] = r
        rows = list(merged.values())
    else:
        meta = _report.record(code=True)
        cases = []
        for kind in kinds:
            seeds = ([p.name for p in bj.fixture_dirs(Path(a.fixtures))] if kind == "fixtures"
                     else bj._seeds(a.seeds))
            cases += [(kind, s, a.frames, lengths, a.clips, a.fixtures, a.truth_start, scene)
                      for s in seeds]
        rows = []
        t0 = time.time()
        if a.workers > 1:
            from concurrent.futures import ProcessPoolExecutor
            with ProcessPoolExecutor(a.workers) as ex:
                for k, part in enumerate(ex.map(run_scene, cases)):
                    rows += part
                    print(f"[{k + 1}/{len(cases)}] {time.time() - t0:.0f} s", flush=True)
        else:
            for k, case in enumerate(cases):
                rows += run_scene(case)
                print(f"[{k + 1}/{len(cases)}] {case[0]} {case[1]} {time.time() - t0:.0f} s",
                      flush=True)
        meta["minutes"] = (time.time() - t0) / 60
        metas.append(meta)
        if a.json:
            Path(a.json).write_text(json.dumps(dict(meta=meta, rows=rows)))
    kinds = sorted({r["kind"] for r in rows}, key=lambda k: (
        KINDS.index(k.split()[0]) if k.split()[0] in KINDS else len(KINDS), k))
    head = []
    for meta in metas:
        head += [*_report.recorded_header(meta), ""]
    lines = ["# Rotation std on short clips (`bench/bench_window_std.py`)", "", *head,
             *summarise(rows, kinds, sorted({r["length"] for r in rows}))]
    lines += ["", *what_if_t(rows, kinds, sorted({r["length"] for r in rows}))]
    if any("sep" in r for r in rows):
        lines += ["", *modes(rows, kinds, sorted({r["length"] for r in rows}))]
    _report.emit(lines, a.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
