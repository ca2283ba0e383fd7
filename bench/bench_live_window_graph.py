"""A batch fixed-lag smoother over the joints pass's own graph, against live's per-frame path.

For each frame ``t`` of a scene (``bench_joints.make_truth``: the synthetic kinds and the
fixtures), the offline joints pass's graph (reprojection with the mirror held, every bone,
the torso, the smoothness: :func:`mirrorgraph.graph.stages.joints_pass`, on the window's
calibration graph built as a chunk of a long video is,
:func:`mirrorgraph.graph.chunked._calibrate_chunk`: triangulated with the held mirror,
cleaned, its joints solved with the globals held, then the joints pass) is solved over the
``W`` frames ending at ``t``, given the offline calibration's mirror, bone and torso lengths
(the torso's distances, where the offline pass read them on its own joints, their medians
over its joints: :func:`mirrorgraph.graph.priors.torso_lengths`). The estimate of frame
``t - L`` is taken: a latency of ``L`` frames (``L / 30`` s) plus the solve's time. With
``--every k`` the window is solved at every ``k``-th frame only and each solve gives the
frames ``t - L - k + 1 .. t - L`` (latency ``L`` to ``L + k - 1`` frames). That is what a
``gtsam.BatchFixedLagSmoother`` over these factors computes (it re-solves its window every
update); an incremental one reuses the factorisation, so the CPU here is an upper bound
of its cost at this accuracy.

Live (:mod:`mirrorgraph.live`, inline, ``bench_live_gap.run_variant``) runs beside it: its
default, and with the offline mirror and bones (``mirror=offline+bones=offline``,
``bench/RESULTS_live_gap.md``) at its lag of 5 frames and of 14. Figures
(``bench_live_gap._figures``: :func:`mirrorgraph.metrics.pa_joint_errors`, the gross share
``> bench_joints.GROSS_M``): PA-MPJPE mm, over the offline run's (``/ off``: each on all the
joints it gives; ``same``: both on the joints both give), joints > 0.3 m %, CPU ms a frame
(process time of the method alone: the offline calibration that gives the mirror is not
counted).

    python bench/bench_live_window_graph.py --kinds fixtures --windows 30,60 --lags 0,5,14
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_joints as bj  # noqa: E402
import bench_live_gap as gap  # noqa: E402

LIVE_VARIANTS = ("base", "mirror=offline+bones=offline",
                 "mirror=offline+bones=offline+lag=14")


def _offline(tr):
    """The offline run of ``tr`` (the bench's options) with its driver's rig, options,
    config and solve state (caught from :func:`mirrorgraph.pipelines.solve.solve`)."""
    import mirrorgraph as mg
    import mirrorgraph.pipelines.solve as ps

    caught = {}
    real = ps.solve

    def spy(rig, opts, config, **kw):
        state = real(rig, opts, config, **kw)
        caught.update(rig=rig, opts=opts, config=config, height=kw.get("height"), state=state)
        return state

    ps.solve = spy
    try:
        run = mg.calibrate(tr.detections, tr.intrinsics,
                           mg.CalibrateOptions(subject_height=tr.height_given, fps=bj.FPS))
    finally:
        ps.solve = real
    return run, caught


def window_graph(caught, W: int, lags: list[int], every: int = 1, min_frames: int = 3,
                 torso_from: str = "offline", masks_from: str = "window",
                 iterations: int = 2):
    """The windowed joints pass: per lag ``L`` the ``(T, J, 3)`` joints (graph units, the
    driver's rows; NaN where not given) of the window ending at ``t`` taken at ``t - L``,
    the CPU seconds of all the windows' solves and their number.

    ``torso_from``: ``"offline"`` the offline pass's torso distances held (read on its
    joints where it read them on its own), ``"window"`` as the offline pass does (where it
    read them on its own joints, each window reads them on its own). ``masks_from``:
    ``"window"`` each window cleaned with the held mirror, ``"offline"`` the offline
    run's kept observations (which its whole video decided). ``iterations``: the pass's
    Gauss-Newton steps (the offline pass's ``JOINTS_PASS_ITERATIONS`` is 1, from the
    calibration's solution; a window's torso held from the start moves its joints further
    than one step reaches: scene_900, one window of all frames, 1.10x the offline run's
    PA-MPJPE with 1 step, 0.99x with 2)."""
    from dataclasses import replace

    import mirrorgraph.graph.chunked as ch
    from mirrorgraph.graph import stages
    from mirrorgraph.graph.priors import torso_lengths

    rig, opts, config, st = caught["rig"], caught["opts"], caught["config"], caught["state"]
    if caught["height"] is not None:
        opts = replace(opts, subject_height=float(caught["height"]))
    torso = st.torso_lengths
    if torso is None and torso_from == "offline":   # the offline pass read them on its joints
        torso = torso_lengths(rig, st.points, st.used)
    ctx = ch._Context(opts=opts, config=config, pose=st.poses, body_height=st.body_height,
                      lengths=dict(st.bone_lengths), torso=torso,
                      length_sum=st.prior_info.get("length_sum_gauge", {}).get("sum"),
                      kernel=next((s.get("kernel") for s in reversed(st.stages)
                                   if s.get("kernel")), None))
    plane = (np.asarray(st.planes[0][0], float), float(st.planes[0][1]))
    T, J = rig.num_frames, rig.skeleton.num_joints
    out = {L: np.full((T, J, 3), np.nan) for L in lags}
    real_pass, real_it = ch.joints_pass, stages.JOINTS_PASS_ITERATIONS
    stages.JOINTS_PASS_ITERATIONS = iterations
    # the window's joints alone: no sensitivity to the plane (the chunks' shared step)
    pass_cpu = [0.0]

    def timed_pass(*a, **k):
        c = time.process_time()
        try:
            return stages.joints_pass(*a, **{**k, "sensitivity": False})
        finally:
            pass_cpu[0] += time.process_time() - c

    ch.joints_pass = timed_pass
    cpu = time.process_time()
    solved = 0
    try:
        for t in range(min_frames - 1, T, every):
            a, b = max(0, t - W + 1), t + 1
            start = None
            if masks_from == "offline":        # the offline run's kept observations
                cal = st.calibration_points if st.calibration_points is not None else st.points
                start = (cal[a:b], [np.asarray(m, bool)[a:b] for m in st.view_masks])
            r = ch._calibrate_chunk((rig.subset(slice(a, b)), a, b, plane, start, ctx))
            solved += 1
            if r.joints is None:
                continue
            X = np.where(r.used[..., None], r.joints, np.nan)
            for L in lags:
                for f in range(t - L - every + 1, t - L + 1):
                    if a <= f < b:
                        out[L][f] = X[f - a]
    finally:
        ch.joints_pass, stages.JOINTS_PASS_ITERATIONS = real_pass, real_it
    return out, time.process_time() - cpu, solved, pass_cpu[0]


def run_scene(case) -> dict:
    warnings.filterwarnings("ignore")
    from mirrorgraph.live import LiveCalibrator, LiveOptions
    from mirrorgraph.live.estimator import solve_window

    kind, seed, frames, fixtures, windows, lags, every, live = case
    clock = time.perf_counter()
    tr = bj.make_truth(kind, seed, frames, Path(fixtures))
    run, caught = _offline(tr)
    Xoff, given, rows, keep = bj.on_truth_frames(run, tr)
    Xoff = np.where(given[..., None], Xoff, np.nan)
    scale = float(run.calibration.distance) / float(caught["state"].planes[0][1])
    T = tr.joints3d.shape[0]
    out = dict(kind=kind, seed=seed, name=tr.name, frames=T, methods={})
    for W in windows:
        Xw, cpu, solved, pass_cpu = window_graph(caught, W, lags, every)
        for L in lags:
            X = np.full_like(tr.joints3d, np.nan)
            X[rows[keep]] = Xw[L][keep] * scale
            f = gap._figures(tr, X, Xoff)
            f.update(cpu_ms=cpu / T * 1e3, solve_ms=cpu / max(solved, 1) * 1e3,
                     pass_ms=pass_cpu / max(solved, 1) * 1e3)
            out["methods"][f"graph W={W} L={L}" + (f" k={every}" if every > 1 else "")] = f
    if live:
        copts = LiveCalibrator(tr.detections.skeleton, tr.intrinsics,
                               LiveOptions.of(subject_height=tr.height_given))._copts
        det, intr = gap._undistorted(tr.detections, tr.intrinsics)
        full = solve_window(det, intr, copts)
        for name in LIVE_VARIANTS:
            r = gap.run_variant(tr, gap.parse_variant(name), full)
            f = gap._figures(tr, r["X"], Xoff)
            # on the joints the offline graph solved (not its completed ones), which are
            # the ones a window of the graph gives
            graph = np.isfinite(Xoff).all(-1)
            if run.completed is not None:
                done = np.zeros_like(graph)
                done[rows[keep]] = np.asarray(run.completed, bool)[keep]
                graph &= ~done
            g = gap._figures(tr, np.where(graph[..., None], r["X"], np.nan),
                             np.where(graph[..., None], Xoff, np.nan))
            f.update(pa_graph=g["pa_same"], off_graph=g["off_same"])
            f.update(cpu_ms=r["cpu_s"] / T * 1e3, solve_ms=float("nan"), pass_ms=float("nan"))
            out["methods"]["live " + name] = f
    out["seconds"] = time.perf_counter() - clock
    return out


def table(scenes: list[dict]) -> list[str]:
    methods = list(scenes[0]["methods"])
    for s in scenes[1:]:
        methods += [m for m in s["methods"] if m not in methods]
    lines = ["cells: PA-MPJPE mm / over offline (same joints) / > 0.3 m % / CPU ms a frame"
             " [live: over offline on the offline graph's own joints, not its completed ones]",
             "| method | " + " | ".join(f"{s['kind']} {s['name']}" for s in scenes)
             + " | median / off | median / off, same |",
             "|---|" + "---:|" * (len(scenes) + 2)]
    for m in methods:
        cells, r1, r2 = [], [], []
        for s in scenes:
            f = s["methods"].get(m)
            if f is None:
                cells.append("")
                continue
            cells.append(f"{f['pa']:.1f} / {f['pa'] / f['off']:.3f} "
                         f"({f['pa_same'] / f['off_same']:.3f}) / {f['gross']:.2f} / "
                         f"{f['cpu_ms']:.1f}"
                         + (f" [{f['pa_graph'] / f['off_graph']:.3f}]" if "pa_graph" in f else ""))
            r1.append(f["pa"] / f["off"])
            r2.append(f["pa_same"] / f["off_same"])
        lines.append(f"| {m} | " + " | ".join(cells)
                     + f" | {np.median(r1):.3f} | {np.median(r2):.3f} |")
    lines.append("| offline PA mm | " + " | ".join(
        f"{next(iter(s['methods'].values()))['off']:.1f}" for s in scenes) + " | | |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    bj.add_scene_args(ap, "fixtures", "0-1")
    ap.add_argument("--windows", default="30,60", help="window lengths, or none (live alone)")
    ap.add_argument("--lags", default="0,5,14")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--no-live", action="store_true")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    windows = [int(w) for w in a.windows.split(",")] if a.windows != "none" else []
    lags = [int(v) for v in a.lags.split(",")]
    cases = [(kind, s, a.frames, a.fixtures, windows, lags, a.every, not a.no_live)
             for kind, s in bj.scene_list(a)]
    scenes = []
    for c in cases:
        scenes.append(run_scene(c))
        print(f"# {c[0]} {c[1]}: {scenes[-1]['seconds']:.0f} s", flush=True)
        if a.json:
            Path(a.json).write_text(json.dumps(dict(argv=sys.argv, scenes=scenes), indent=1))
    print("\n".join(table(scenes)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
