"""Where the live joints' PA-MPJPE gap to the offline run's comes from: ablations.

Each scene (``bench_joints.make_truth``: the synthetic kinds and the fixtures) is run by the
offline ``mirrorgraph.calibrate`` (the bench's options) and by the live calibrator
(inline, every frame fed as a stream, the lagged frames taken as ``mirrorgraph live``
writes them) under variants that each hand live one thing the offline run has:

* ``lag=L``: each frame given ``L`` frames after it (the fixed-lag smoother's lag);
* ``mirror=offline`` / ``mirror=true``: every window's solve returns the offline
  calibration's normal and distance of all frames (the live options' solve of every frame,
  :func:`mirrorgraph.live.estimator.solve_window`) / the scene's true mirror, the window's
  bone and torso lengths rescaled to that distance;
* ``bones=offline`` / ``bones=true``: the window's mirror, the bone and torso lengths of
  the offline solve of all frames (rescaled to the window's distance) / of the true
  joints (median over the frames);
* ``gate=off``: no view gated on the tracks' prediction (``views_near_track``);
* ``branches=off``: no bone branch along the ray folded in (``frame_prior.bone_branches``);
  ``bw=plain``: the branch weighed by the cost gap alone (``matched=False``, as before
  ``bench/RESULTS_live_gap.md``); ``twostarts=off``: no second start from the tracks'
  prediction (``frame_prior.two_starts``); ``ts=lap``: the two starts weighed as the
  branches are; ``bones=none``: no per-frame bone prior;
* ``fgate=C``, ``restart=N``: the joint filter's gate (squared Mahalanobis distance of
  the innovation) and the rejected measurements in a row that restart a track.

The hooks replace ``mirrorgraph.live.calibrator``'s functions (``solve_window``, the
per-frame ones) in this process only, restored after each run; the library is unchanged. PA-MPJPE is in mm; ``/ off`` is live's over the
offline run's on all the joints each gives, ``/ off, same`` both on the joints both give
(the frames before live's first window left out of the offline run's too).

    python bench/bench_live_gap.py --kinds fixtures,iid,cmu,lowpar --seeds 0-1 \\
        --variants base,lag=15,mirror=offline --json /tmp/gap.json
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_joints as bj  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _undistorted(det, intr):
    """``det`` with its pixels undistorted (what the live calibrator buffers)."""
    from dataclasses import replace

    if not intr.has_distortion:
        return det, intr
    people = []
    for p in det.people:
        p = np.array(p, float)
        ok = np.isfinite(p[..., :2]).all(-1)
        flat = p[..., :2][ok]
        p[..., :2][ok] = intr.undistort_points(flat)
        people.append(p)
    return replace(det, people=people), replace(intr, dist=None)


def _true_lengths(tr, skeleton) -> tuple[dict, dict]:
    """The true joints' bone lengths and torso distances (median over the frames), m."""
    X = tr.joints3d
    bones = {}
    for name, (a, b) in skeleton.bones.items():
        ia, ib = skeleton.index(a), skeleton.index(b)
        bones[name] = float(np.median(np.linalg.norm(X[:, ia] - X[:, ib], axis=-1)))
    return bones, X


def _scaled(d: dict, f: float) -> dict:
    return {k: v * f for k, v in d.items()}


def _hook(variant: dict, full, tr, skeleton):
    """The replacement of ``solve_window`` for ``variant`` (``None``: none)."""
    import mirrorgraph.live.calibrator as lc

    real = lc.solve_window
    mirror, bones = variant.get("mirror"), variant.get("bones")
    if mirror is None and bones in (None, "none"):
        return None
    true_bones, X = _true_lengths(tr, skeleton)

    def true_torso(names):
        out = {}
        for name in names:
            a, b = (skeleton.index(j) for j in name.split("-"))
            out[name] = float(np.median(np.linalg.norm(X[:, a] - X[:, b], axis=-1)))
        return out

    def solve(raw, intr, opts):
        est = real(raw, intr, opts)
        if not est.ok:
            return est
        d0 = float(est.distance)
        if mirror is not None:
            n, d = ((full.normal, float(full.distance)) if mirror == "offline"
                    else (np.asarray(tr.normal, float), float(tr.distance)))
            est.normal, est.distance = np.array(n, float), d
            est.bone_lengths = _scaled(est.bone_lengths, d / d0)
            est.torso_lengths = _scaled(est.torso_lengths, d / d0)
        if bones == "offline":
            f = float(est.distance) / float(full.distance)
            est.bone_lengths = _scaled(full.bone_lengths, f)
            est.torso_lengths = _scaled(full.torso_lengths, f)
        elif bones == "true":
            est.bone_lengths = dict(true_bones)
            est.torso_lengths = true_torso(est.torso_lengths)
        return est

    return solve


def run_variant(tr, variant: dict, full) -> dict:
    """One live run of ``tr`` under ``variant``: its ``(T, J, 3)`` joints and CPU seconds
    (:func:`bench_joints.replay_live` with the variant's hooks in place)."""
    import mirrorgraph.live.calibrator as lc
    from mirrorgraph.live import LiveOptions
    from mirrorgraph.skeletons import skeleton_by_name

    det = tr.detections
    opts = LiveOptions.of(subject_height=tr.height_given,
                          lag_frames=int(variant.get("lag", 5)),
                          bone_prior=variant.get("bones") != "none")
    # the calibrator's own skeleton (LiveCalibrator.skeleton)
    skeleton = (skeleton_by_name(det.skeleton) if isinstance(det.skeleton, str)
                else det.skeleton)
    saved = (lc.solve_window, lc.views_near_track, lc.JointFilter, lc.bone_branches,
             lc.two_starts)
    try:
        if variant.get("branches") == "off":
            lc.bone_branches = lambda K, n, d, X, cov, *a, **k: (X, cov)
        if variant.get("bw") == "plain":       # the branch's weight without the Laplace tail
            lc.bone_branches = functools.partial(saved[3], matched=False)
        if variant.get("ts") == "lap":         # two_starts weighed as bone_branches
            lc.two_starts = functools.partial(saved[4], matched=True)
        if variant.get("twostarts") == "off":
            lc.two_starts = lambda K, n, d, X, cov, *a, **k: (X, cov)
        hook = _hook(variant, full, tr, skeleton)
        if hook is not None:
            lc.solve_window = hook
        if variant.get("gate") == "off":
            lc.views_near_track = lambda *a, **k: None
        if "fgate" in variant or "restart" in variant:
            kw = {}
            if "fgate" in variant:
                kw["gate_chi2"] = float(variant["fgate"])
            if "restart" in variant:
                kw["restart_after"] = int(variant["restart"])
            lc.JointFilter = functools.partial(saved[2], **kw)
        r = bj.replay_live(tr, opts)
    finally:
        (lc.solve_window, lc.views_near_track, lc.JointFilter, lc.bone_branches,
         lc.two_starts) = saved
    return dict(X=r["X"], cpu_s=r["cpu_s"])


def _figures(tr, X, Xoff) -> dict:
    from mirrorgraph.metrics import pa_joint_errors

    given = np.isfinite(X).all(-1)
    goff = np.isfinite(Xoff).all(-1)
    e = pa_joint_errors(X, tr.joints3d, given)
    eo = pa_joint_errors(Xoff, tr.joints3d, goff)
    both = given & goff
    es = pa_joint_errors(X, tr.joints3d, both)
    eos = pa_joint_errors(Xoff, tr.joints3d, both)
    m = lambda a: float(np.nanmean(a)) * 1e3  # noqa: E731
    err = np.linalg.norm(np.where(given[..., None], X, 0) - tr.joints3d, axis=-1)[given]
    per_joint = {tr.names[j]: [m(es[:, j]), m(eos[:, j])] for j in range(len(tr.names))
                 if np.isfinite(es[:, j]).any()}
    return dict(pa=m(e), off=m(eo), pa_same=m(es), off_same=m(eos),
                gross=float((err > bj.GROSS_M).mean()) * 100 if err.size else float("nan"),
                given=float(given.mean()) * 100, per_joint=per_joint)


def run_scene(case) -> dict:
    import warnings
    warnings.filterwarnings("ignore")
    import mirrorgraph as mg
    from mirrorgraph.live import LiveCalibrator, LiveOptions
    from mirrorgraph.live.estimator import solve_window

    kind, seed, frames, fixtures, variants = case
    clock = time.perf_counter()
    tr = bj.make_truth(kind, seed, frames, Path(fixtures))
    # the offline run (the bench's options) and its joints on the truth's frames
    run = mg.calibrate(tr.detections, tr.intrinsics,
                       mg.CalibrateOptions(subject_height=tr.height_given, fps=bj.FPS))
    Xoff, given, rows, keep = bj.on_truth_frames(run, tr)
    Xoff = np.where(given[..., None], Xoff, np.nan)
    # the live options' solve of every frame: the offline mirror and bones live can hold
    copts = LiveCalibrator(tr.detections.skeleton, tr.intrinsics,
                           LiveOptions.of(subject_height=tr.height_given))._copts
    det, intr = _undistorted(tr.detections, tr.intrinsics)
    full = solve_window(det, intr, copts)
    out = dict(kind=kind, seed=seed, name=tr.name, variants={})
    for name in variants:
        v = parse_variant(name)
        r = run_variant(tr, v, full)
        f = _figures(tr, r["X"], Xoff)
        f["cpu_s"] = r["cpu_s"]
        out["variants"][name] = f
    out["seconds"] = time.perf_counter() - clock
    return out


def parse_variant(name: str) -> dict:
    out = {}
    for part in name.split("+"):
        if part == "base":
            continue
        k, _, v = part.partition("=")
        out[k] = int(v) if k == "lag" else v
    return out


def table(scenes: list[dict], variants: list[str]) -> list[str]:
    lines = ["| variant | " + " | ".join(s["name"] for s in scenes)
             + " | median / off | median / off, same |",
             "|---|" + "---:|" * (len(scenes) + 2)]
    for v in variants:
        cells, r1, r2 = [], [], []
        for s in scenes:
            f = s["variants"][v]
            cells.append(f"{f['pa']:.1f} ({f['pa'] / f['off']:.2f}; "
                         f"{f['pa_same'] / f['off_same']:.2f})")
            r1.append(f["pa"] / f["off"])
            r2.append(f["pa_same"] / f["off_same"])
        lines.append(f"| {v} | " + " | ".join(cells)
                     + f" | {np.median(r1):.3f} | {np.median(r2):.3f} |")
    lines.append("| offline PA mm | " + " | ".join(
        f"{s['variants'][variants[0]]['off']:.1f}" for s in scenes) + " | | |")
    return lines


def per_joint(scenes: list[dict], variants: list[str]) -> list[str]:
    lines = []
    for s in scenes:
        if s["kind"] != "fixtures":
            continue
        names = list(s["variants"][variants[0]]["per_joint"])
        lines += [f"\n{s['name']}: per joint PA mm on the joints both give (live / offline)",
                  "| joint | " + " | ".join(variants) + " | offline |",
                  "|---|" + "---:|" * (len(variants) + 1)]
        for j in names:
            row = [f"{s['variants'][v]['per_joint'][j][0]:.1f}" for v in variants]
            lines.append(f"| {j} | " + " | ".join(row)
                         + f" | {s['variants'][variants[0]]['per_joint'][j][1]:.1f} |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    bj.add_scene_args(ap, "fixtures,iid,cmu,lowpar", "0-1")
    ap.add_argument("--variants", default="base,lag=15,lag=30,lag=60,mirror=offline")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    variants = a.variants.split(",")
    cases = [(kind, s, a.frames, a.fixtures, variants) for kind, s in bj.scene_list(a)]
    if a.workers > 1:
        with ProcessPoolExecutor(a.workers) as ex:
            scenes = list(ex.map(run_scene, cases))
    else:
        scenes = [run_scene(c) for c in cases]
    if a.json:
        Path(a.json).write_text(json.dumps(dict(argv=sys.argv, scenes=scenes), indent=1))
    print("\n".join(table(scenes, variants) + per_joint(scenes, variants)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
