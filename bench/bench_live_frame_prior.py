"""The live run's per-frame joints with and without the bones' lengths (``LiveOptions.bone_prior``).

Each scene is replayed through :class:`mirrorgraph.live.LiveCalibrator` twice in this run,
side by side: the joints triangulated from their two rays alone, and refined with the
latest window's bone lengths (:mod:`mirrorgraph.live.frame_prior`). Against the scene's
true joints, over the frames after the first 10 s: the joints' 3D error (median and RMS,
metres), their error over ``joints_std`` (metres, the scale's share in) and over
``joints_std_shape`` (RMS), and the per-frame CPU time (median, p95).

Usage::

    python bench/bench_live_frame_prior.py            # ~6 min on 2 cores
    python bench/bench_live_frame_prior.py --seeds 0 --no-write

Writes ``bench/RESULTS_live_frame_prior.md`` (machine, command, date, table).
"""

from __future__ import annotations

import argparse
import datetime
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import header  # noqa: E402  (one header for every results file)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FRAMES = 1800
SKIP = 300                      # the first 10 s at 30 fps: the mirror still settling


def run_case(case: tuple[str, int, bool]) -> dict:
    import mirrorgraph as mg
    from mirrorgraph.live import LiveCalibrator, LiveOptions
    from mirrorgraph.synth import make_wide_scene

    noise, seed, prior = case
    sc = make_wide_scene(seed, "wide", noise, FRAMES)
    live = LiveCalibrator(sc.skeleton, mg.Intrinsics(K=sc.K, image_size=sc.image_size),
                          LiveOptions.of(subject_height=sc.subject_height, bone_prior=prior))
    err, z, zs, cpu = [], [], [], []
    try:
        for t, people in enumerate(sc.detections.people):
            f = live.update(people, frame_id=t)
            ok = np.isfinite(f.joints_std)
            if t >= SKIP and ok.any():
                e = np.linalg.norm(f.joints3d[ok] - sc.joints3d[t][ok], axis=1)
                err.append(e)
                z.append(e / f.joints_std[ok])
                zs.append(e / f.joints_std_shape[ok])
                cpu.append(f.cpu_s)
    finally:
        live.close()
    err, z, zs = (np.concatenate(v) for v in (err, z, zs))
    return {"noise": noise, "seed": seed, "prior": prior, "joints": int(err.size),
            "median_m": float(np.median(err)), "rms_m": float(np.sqrt(np.mean(err ** 2))),
            "z_rms": float(np.sqrt(np.mean(z ** 2))), "zs_rms": float(np.sqrt(np.mean(zs ** 2))),
            "cpu_p50_ms": 1e3 * float(np.median(cpu)),
            "cpu_p95_ms": 1e3 * float(np.percentile(cpu, 95))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    started = datetime.datetime.now(datetime.timezone.utc)
    cases = [(n, s, p) for n in ("iid", "realistic") for s in range(args.seeds)
             for p in (False, True)]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(run_case, cases))
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True).stdout.strip()
    cmd = f"python bench/bench_live_frame_prior.py {' '.join(argv or sys.argv[1:])}".rstrip()
    lines = ["# The live per-frame joints with and without the bones (`bench/bench_live_frame_prior.py`)",
             "", *header(started=f"{started:%Y-%m-%d %H:%M} UTC", cmd=cmd, bullet="-"),
             f"- code: `{head}`",
             f"- scenes: `make_wide_scene(seed, 'wide', noise, {FRAMES})` replayed with the "
             "camera matrix and the subject's height, the frames after the first "
             f"{SKIP // 30} s; each cell: rays alone / with the bones",
             "", "| noise | seed | joint error median m | joint error RMS m | error / "
             "joints_std RMS | error / joints_std_shape RMS | CPU ms a frame p50 / p95 |",
             "|---|---:|---|---|---|---|---|"]
    by = {(r["noise"], r["seed"], r["prior"]): r for r in rows}
    for noise in ("iid", "realistic"):
        for s in range(args.seeds):
            a, b = by[(noise, s, False)], by[(noise, s, True)]
            lines.append(
                f"| {noise} | {s} | {a['median_m']:.3f} / {b['median_m']:.3f} | "
                f"{a['rms_m']:.3f} / **{b['rms_m']:.3f}** | {a['z_rms']:.2f} / {b['z_rms']:.2f} | "
                f"{a['zs_rms']:.2f} / {b['zs_rms']:.2f} | {a['cpu_p50_ms']:.2f}, "
                f"{a['cpu_p95_ms']:.2f} / {b['cpu_p50_ms']:.2f}, {b['cpu_p95_ms']:.2f} |")
    for noise in ("iid", "realistic"):
        ra = np.array([by[(noise, s, False)]["rms_m"] for s in range(args.seeds)])
        rb = np.array([by[(noise, s, True)]["rms_m"] for s in range(args.seeds)])
        lines.append("")
        lines.append(f"{noise}: joint error RMS with the bones / without, per scene: "
                     + ", ".join(f"{x:.2f}" for x in rb / ra)
                     + f" (median {np.median(rb / ra):.2f})")
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        (ROOT / "bench" / "RESULTS_live_frame_prior.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
