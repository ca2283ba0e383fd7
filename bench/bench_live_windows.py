"""Live's joints against the offline run's, mirror by mirror: which window's calibration
served which frames, how far off it was, and what the joints did under it.

Each scene (``bench_joints.make_truth``) is run by the offline ``mirrorgraph.calibrate``
(the bench's options, every frame) and by the live calibrator (inline, every frame fed as
a stream, the lagged frames taken as ``mirrorgraph live`` writes them). Live's frames are
grouped by the mirror that served them (an epoch: the first block's calibration of the
frames so far, re-solved at 60, 120, 240, 480, 900 frames, then the fused one); each
epoch's row gives that mirror's normal error (degrees) and distance error (%), its
window's ``rotation_std_deg``, live's and the offline run's PA-MPJPE on the epoch's
frames (on the joints both give) and live's joints more than 0.3 m off once each frame's
scale is fitted (``bench_joints.score``'s ``gross_scaled``).

``--segments a-b,...``: the window solve (:func:`mirrorgraph.live.estimator.solve_window`,
the live options; the same calibration ``mirrorgraph.calibrate`` gives those frames) of
those frames alone: how well the scene's frames place the mirror by themselves.
``--resolve-every N``: a second live run whose first block is re-solved every ``N``
frames instead of each time the frames double (a bench-only hook on
``LiveCalibrator._absorb``; the library unchanged).

    python bench/bench_live_windows.py --kinds realistic --seeds 13 \\
        --segments 0-60,60-120,0-240,240-480 --resolve-every 60
"""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_joints as bj  # noqa: E402


def _angle(n, tn) -> float:
    return float(np.degrees(np.arccos(min(1.0, abs(float(np.asarray(n, float) @ tn))))))


def run_live(tr, resolve_every: int = 0) -> dict:
    """Live's ``(T, J, 3)`` joints, each frame's mirror and status, the window log
    (:func:`bench_joints.replay_live`, the first block re-solved every ``resolve_every``
    frames where it is positive)."""
    import mirrorgraph.live.calibrator as lc
    from mirrorgraph.live import LiveOptions

    real = lc.LiveCalibrator._absorb

    def absorb(self, est, provisional, block, size):
        real(self, est, provisional, block, size)
        if provisional and not block:
            self._next = min(size + resolve_every, self.options.window_frames)

    if resolve_every > 0:
        lc.LiveCalibrator._absorb = absorb
    try:
        r = bj.replay_live(tr, LiveOptions.of(subject_height=tr.height_given))
    finally:
        lc.LiveCalibrator._absorb = real
    return dict(X=r["X"], normal=r["normal"], dist=r["distance"], rot_std=r["rotation_std_deg"],
                status=r["status"], windows=r["windows"])


def _frame_scaled_errors(X, truth) -> tuple[np.ndarray, np.ndarray]:
    """``(T, J)`` each joint's error once its frame's scale is fitted, and where given."""
    g = np.isfinite(X).all(-1)
    Xz = np.where(g[..., None], X, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = (Xz * truth).sum((1, 2)) / (Xz * Xz).sum((1, 2))
    return np.linalg.norm(Xz * np.nan_to_num(f)[:, None, None] - truth, axis=-1), g


def epochs(tr, lv: dict, Xoff: np.ndarray) -> list[dict]:
    """One row per run of frames served by one mirror (and one for the frames before)."""
    from mirrorgraph.metrics import pa_joint_errors

    truth, X = tr.joints3d, lv["X"]
    tn = np.asarray(tr.normal, float)
    pl = pa_joint_errors(X, truth, np.isfinite(X).all(-1))
    po = pa_joint_errors(Xoff, truth, np.isfinite(Xoff).all(-1))
    e, g = _frame_scaled_errors(X, truth)
    key = np.where(np.isfinite(lv["dist"]), lv["dist"], -1.0)
    cuts = np.flatnonzero(np.r_[True, key[1:] != key[:-1], True])
    rows = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        both = np.isfinite(pl[a:b]) & np.isfinite(po[a:b])
        gg = g[a:b]
        rows.append(dict(
            frames=(int(a), int(b - 1)), has=bool(np.isfinite(lv["dist"][a])),
            angle=_angle(lv["normal"][a], tn) if np.isfinite(lv["dist"][a]) else None,
            dist_err=(float(lv["dist"][a] / tr.distance - 1.0) * 100
                      if np.isfinite(lv["dist"][a]) else None),
            rot_std=float(lv["rot_std"][a]) if np.isfinite(lv["rot_std"][a]) else None,
            status=str(lv["status"][a]),
            live=float(pl[a:b][both].mean() * 1e3) if both.any() else None,
            off=float(po[a:b][both].mean() * 1e3) if both.any() else None,
            gross=int((e[a:b][gg] > bj.GROSS_M).sum()), given=int(gg.sum())))
    return rows


def summary(tr, X, Xoff) -> dict:
    from mirrorgraph.metrics import pa_joint_errors

    pl = pa_joint_errors(X, tr.joints3d, np.isfinite(X).all(-1))
    po = pa_joint_errors(Xoff, tr.joints3d, np.isfinite(Xoff).all(-1))
    e, g = _frame_scaled_errors(X, tr.joints3d)
    return dict(live=float(np.nanmean(pl) * 1e3), off=float(np.nanmean(po) * 1e3),
                gross=float((e[g] > bj.GROSS_M).mean() * 100))


def segments(tr, spec: str) -> list[str]:
    from mirrorgraph.live import LiveCalibrator, LiveOptions
    from mirrorgraph.live.estimator import solve_window

    det = tr.detections
    tn = np.asarray(tr.normal, float)
    copts = LiveCalibrator(det.skeleton, tr.intrinsics,
                           LiveOptions.of(subject_height=tr.height_given))._copts
    lines = ["| frames | normal error deg | distance error % | rotation_std_deg | pairs |",
             "|---|---:|---:|---:|---:|"]
    for part in spec.split(","):
        a, b = (int(v) for v in part.split("-"))
        est = solve_window(replace(det, frame_ids=det.frame_ids[a:b],
                                   people=list(det.people[a:b])), tr.intrinsics, copts)
        if not est.ok:
            lines.append(f"| {a}-{b - 1} | failed: {est.reason} | | | |")
            continue
        lines.append(f"| {a}-{b - 1} | {_angle(est.normal, tn):.2f} | "
                     f"{(est.distance / tr.distance - 1) * 100:+.1f} | "
                     f"{est.rotation_std_deg:.1f} | {est.pairs} |")
    return lines


def main(argv=None) -> int:
    warnings.filterwarnings("ignore")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    bj.add_scene_args(ap, "realistic", "13")
    ap.add_argument("--segments", default=None)
    ap.add_argument("--resolve-every", type=int, default=0)
    a = ap.parse_args(argv)
    import mirrorgraph as mg

    out = []
    for kind, seed in bj.scene_list(a):
        tr = bj.make_truth(kind, seed, a.frames, Path(a.fixtures))
        run = mg.calibrate(tr.detections, tr.intrinsics,
                           mg.CalibrateOptions(subject_height=tr.height_given, fps=bj.FPS))
        Xoff, given, _, _ = bj.on_truth_frames(run, tr)
        Xoff = np.where(given[..., None], Xoff, np.nan)
        lv = run_live(tr)
        s = summary(tr, lv["X"], Xoff)
        start = len(out)
        out += [f"\n### {tr.name}: live PA {s['live']:.1f} mm, offline {s['off']:.1f} mm "
                f"({s['live'] / s['off']:.2f}x), > 0.3 m with each frame's scale fitted "
                f"{s['gross']:.2f} %; offline mirror "
                f"{_angle(run.calibration.normal, np.asarray(tr.normal, float)):.2f} deg, "
                f"distance {(run.calibration.distance / tr.distance - 1) * 100:+.1f} %\n",
                "| live's mirror serves frames | normal error deg | distance error % "
                "| rotation_std_deg | status | live PA mm | offline PA mm | live / offline "
                "| > 0.3 m, frame's scale fitted |",
                "|---|---:|---:|---:|---|---:|---:|---:|---:|"]
        for r in epochs(tr, lv, Xoff):
            f = (lambda v, p: "" if v is None else format(v, p))  # noqa: E731
            ratio = (r["live"] / r["off"]) if r["live"] and r["off"] else None
            out.append(f"| {r['frames'][0]}-{r['frames'][1]} | {f(r['angle'], '.2f')} | "
                       f"{f(r['dist_err'], '+.1f')} | {f(r['rot_std'], '.1f')} | "
                       f"{r['status'] if r['has'] else 'no mirror yet'} | "
                       f"{f(r['live'], '.1f')} | {f(r['off'], '.1f')} | {f(ratio, '.2f')} | "
                       f"{r['gross']} ({100 * r['gross'] / max(r['given'], 1):.2f} %) |")
        if a.resolve_every > 0:
            lv2 = run_live(tr, a.resolve_every)
            s2 = summary(tr, lv2["X"], Xoff)
            out.append(f"\nfirst block re-solved every {a.resolve_every} frames "
                       f"({len(lv2['windows'])} windows against {len(lv['windows'])}): "
                       f"live PA {s2['live']:.1f} mm ({s2['live'] / s2['off']:.2f}x), "
                       f"> 0.3 m frame-scaled {s2['gross']:.2f} %")
        if a.segments:
            out += [f"\n{tr.name}: the window solve of these frames alone\n"]
            out += segments(tr, a.segments)
        print("\n".join(out[start:]), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
