#!/usr/bin/env python
"""Benchmark of the factor-graph refinement (:func:`mirrorgraph.graph.refine_mirror`).

    python bench/bench_graph.py                      # 1000, 10,000 and 54,000 frames + accuracy
    python bench/bench_graph.py --frames 1000 10000  # some sizes only
    python bench/bench_graph.py --seeds 10           # accuracy protocol over 10 seeds
    python bench/bench_graph.py --no-accuracy        # timings only

Scenes: :func:`mirrorgraph.synth.make_scene` (COCO-17, 1920x1080, 4 px detector noise of
mean 0.076 px: MirrorCalib's protocol), the subject's height given (metric scale). The
refinement starts from the true mirror normal tilted by 1 deg (a 2 deg error of the
virtual camera's rotation) with every pair as an inlier, i.e. what the RANSAC
initialisation hands over.

Each size runs in a fresh process (so that the peak resident memory, from
``resource.getrusage``, is that run's); the table gives the wall and CPU time of the
call, its split (graph build / solve / marginals), the linear solves, the peak memory
and its rise over the process before the call. The accuracy protocol compares the
median virtual-camera rotation error over seeds with the Cramer-Rao bound of the
reprojection terms alone (Fisher information at the true joints and mirror, joints
eliminated; the median of the bound's error distribution is taken as 0.83 x its RMS,
the Rayleigh ratio).

Writes ``bench/RESULTS_graph.md`` (machine, command, date, figures) unless ``--no-write``.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from mirrorgraph.graph import RefineOptions  # noqa: E402
from mirrorgraph.pipelines.solve import refine_mirror  # noqa: E402
from mirrorgraph.metrics import mirror_rotation_error_deg as rotation_error_deg  # noqa: E402
from mirrorgraph.synth import make_scene, tilted_normal as tilted  # noqa: E402


def crb_rotation_deg(scene) -> float:
    """RMS virtual-camera rotation error bound of the reprojection terms alone (truth)."""
    from mirrorgraph.graph.builder import build_problem
    from mirrorgraph.graph.optimizer import LevenbergMarquardt, LMParams
    from mirrorgraph.graph.reduction import mirror_reduction
    from mirrorgraph.pipelines.solve import prepare
    from mirrorgraph.graph.result import normal_cov_from_tangent, rotation_std_from_normal_cov
    p = scene.paired()
    opts = RefineOptions(robust_kernel=None, pixel_sigma=float(scene.options["noise_std"]))
    rig = prepare(p, scene.K, scene.normal, p.valid(), None, opts)
    used = rig.views[0].mask
    prob = build_problem(rig, scene.joints3d, used, [(scene.normal, scene.distance)], opts,
                         priors=False)
    red = mirror_reduction(prob, distance_gauge=scene.distance)
    lm = LevenbergMarquardt(prob.reprojection, red, LMParams(max_iterations=1),
                            ordering=prob.point_ordering())
    _, H, _, _ = lm.step(prob.reprojection.linearize(prob.values), prob.values, 0.0)
    basis = np.asarray(prob.values.atOrientedPlane3(prob.plane_keys[0]).normal().basis())
    return rotation_std_from_normal_cov(normal_cov_from_tangent(basis, np.linalg.inv(H)[:2, :2]))


# --------------------------------------------------------------------------- one run
def run_one(frames: int, seed: int, crb: bool) -> dict:
    """Generate a scene, refine it, return the figures (called in a child process)."""
    scene = make_scene(frames=frames, seed=seed, noise_std=4.0, noise_mean=0.076)
    p = scene.paired()
    n0 = tilted(scene.normal, 1.0, np.random.default_rng(1000 + seed))
    opts = RefineOptions(subject_height=scene.subject_height)
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    c0, w0 = time.process_time(), time.perf_counter()
    res = refine_mirror(p, scene.K, n0, p.valid(), options=opts)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    out = {
        "frames": frames, "seed": seed, "wall_s": wall, "cpu_s": cpu,
        "build_s": res.timings["build"], "solve_s": res.timings["solve"],
        "marginals_s": res.timings["marginals"], "iterations": res.iterations,
        "peak_rss_mb": peak, "rss_rise_mb": peak - rss_before,
        "rot_err_deg": rotation_error_deg(res.normal, scene.normal),
        "init_err_deg": rotation_error_deg(n0, scene.normal),
        "rot_std_deg": res.rotation_std_deg,
        "dist_rel_err": res.distance / scene.distance - 1.0,
        "chunked": any(s["name"].startswith("chunk") for s in res.stages),
        "pairs": int(res.inliers.sum()),
    }
    if crb:
        out["crb_deg"] = crb_rotation_deg(scene)
    return out


def child(frames: int, seed: int, crb: bool) -> dict:
    cmd = [sys.executable, __file__, "--child", str(frames), str(seed)] + (["--crb"] if crb else [])
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------- report
from _report import header  # noqa: E402  (one header for every results file)


def table_sizes(rows: list[dict]) -> list[str]:
    L = ["| frames | wall s | CPU s | build s | solve s | marginals s | linear solves | "
         "peak RSS MB | RSS rise MB | ms / frame (CPU) | rot. err deg | std deg | chunked |",
         "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---:|"]
    for r in rows:
        L.append(f"| {r['frames']:,} | {r['wall_s']:.2f} | {r['cpu_s']:.2f} | {r['build_s']:.2f} "
                 f"| {r['solve_s']:.2f} | {r['marginals_s']:.3f} | {r['iterations']} "
                 f"| {r['peak_rss_mb']:.0f} | {r['rss_rise_mb']:.0f} "
                 f"| {1000 * r['cpu_s'] / r['frames']:.2f} | {r['rot_err_deg']:.4f} "
                 f"| {r['rot_std_deg']:.4f} | {'yes' if r['chunked'] else 'no'} |")
    return L


def table_accuracy(rows: list[dict]) -> list[str]:
    L = ["| seed | init err deg | refined err deg | reported std deg | CRB (RMS) deg | "
         "distance rel. err | wall s |", "|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        L.append(f"| {r['seed']} | {r['init_err_deg']:.3f} | {r['rot_err_deg']:.4f} "
                 f"| {r['rot_std_deg']:.4f} | {r.get('crb_deg', float('nan')):.4f} "
                 f"| {100 * r['dist_rel_err']:+.2f} % | {r['wall_s']:.2f} |")
    e = np.array([r["rot_err_deg"] for r in rows])
    s = np.array([r["rot_std_deg"] for r in rows])
    c = np.array([r.get("crb_deg", np.nan) for r in rows])
    d = np.array([r["dist_rel_err"] for r in rows])
    L += ["", f"* median rotation error **{np.median(e):.4f} deg**, RMS {np.sqrt(np.mean(e ** 2)):.4f} deg",
          f"* RMS reported std {np.sqrt(np.mean(s ** 2)):.4f} deg (ratio RMS error / RMS std "
          f"{np.sqrt(np.mean(e ** 2)) / np.sqrt(np.mean(s ** 2)):.2f})",
          f"* Cramer-Rao bound of reprojection alone: RMS {np.sqrt(np.nanmean(c ** 2)):.4f} deg, "
          f"median-equivalent (0.83 x RMS, per scene, then median) {np.nanmedian(0.83 * c):.4f} deg; "
          f"median error / bound (per scene) {np.nanmedian(e / c):.2f}",
          f"* distance within {100 * np.abs(d).max():.1f} % of the truth (max over seeds)",
          f"* median wall time {np.median([r['wall_s'] for r in rows]):.2f} s",
          "",
          "The bound depends on the scene's geometry (make_scene draws the mirror 10-60 deg "
          "off the optical axis at 2.5-4.5 m, so the epipole is often far outside the image "
          "and the epipolar lines nearly parallel): "
          f"{np.nanmin(c):.3f}-{np.nanmax(c):.3f} deg RMS on these seeds. The estimate is "
          "therefore judged against the bound scene by scene (the ratio above), not "
          "against a fixed number of degrees."]
    return L


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, nargs="*", default=[1000, 10000, 54000])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--no-accuracy", action="store_true")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "RESULTS_graph.md")
    ap.add_argument("--child", type=int, nargs=2, help=argparse.SUPPRESS)
    ap.add_argument("--crb", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(run_one(args.child[0], args.child[1], args.crb)))
        return 0

    command = "python bench/bench_graph.py " + " ".join(argv if argv is not None else sys.argv[1:])
    sizes = []
    for T in args.frames:
        r = child(T, 0, False)
        sizes.append(r)
        print(f"{T:>6} frames: wall {r['wall_s']:.2f} s, cpu {r['cpu_s']:.2f} s (build "
              f"{r['build_s']:.2f}, solve {r['solve_s']:.2f}, marginals {r['marginals_s']:.3f}), "
              f"{r['iterations']} solves, peak RSS {r['peak_rss_mb']:.0f} MB, "
              f"err {r['rot_err_deg']:.4f} deg (std {r['rot_std_deg']:.4f})", flush=True)
    acc = []
    if not args.no_accuracy:
        for seed in range(args.seeds):
            r = child(1000, seed, True)
            acc.append(r)
            print(f"seed {seed}: err {r['rot_err_deg']:.4f} deg, std {r['rot_std_deg']:.4f}, "
                  f"CRB {r['crb_deg']:.4f}, distance {100 * r['dist_rel_err']:+.2f} %, "
                  f"wall {r['wall_s']:.2f} s", flush=True)
    lines = ["# Factor-graph refinement benchmark", "",
             *header(cmd=command.strip()),
             "* scenes: `make_scene(frames=T, seed=s, noise_std=4, noise_mean=0.076)` (COCO-17, "
             "1920x1080), subject height given; initial normal = truth tilted by 1 deg (2 deg of "
             "virtual-camera rotation); every pair an inlier. Each run in a fresh process.", ""]
    if sizes:
        lines += ["## Time and memory", ""] + table_sizes(sizes) + [
            "", "Wall time is sensitive to other processes on this 2-core machine (see the "
            "load average above); the CPU time of the process is the steadier figure. Videos "
            "longer than `max_graph_frames` (2000) are solved on a spread subset first, then in "
            "chunks sharing the mirror (`mirrorgraph/graph/chunked.py`), so memory stays "
            "bounded by one chunk and time grows linearly.", ""]
    if acc:
        lines += ["## Accuracy, 1000 frames, 4 px noise (paper's protocol)", ""] \
            + table_accuracy(acc) + [""]
    text = "\n".join(lines) + "\n"
    if not args.no_write:
        args.out.write_text(text)
        print(f"wrote {args.out}")
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
