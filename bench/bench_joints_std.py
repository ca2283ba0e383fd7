"""Each output joint's std against its true error: ``calibrate``'s ``joints_std``.

Calibrates wide scenes (``make_wide_scene(seed, "wide", noise, frames)``, the camera
matrix and the subject's height given) under the iid and the realistic detector, and the
independent generator's scenes (``../shared/fixtures``, their ``joints3d_truth.npz``),
and scores every output joint (the graph's and the completed ones) by its error over its
std, ``|X - X_true| / joints_std`` (:mod:`mirrorgraph.graph.joints_uncertainty`: the
RMS length of the 3D error, so a Gaussian error has an RMS ratio of 1 and a median of
0.67-0.89 by the covariance's shape). Two figures:

* **metric**: the joints in metres against ``joints_std`` (the metric scale's share
  included: the subject's height known to 2 % and the stature's own spread);
* **shape**: the joints rescaled by the one factor that fits them best to the truth
  against ``joints_std_shape`` (the same without the scale's share): whether the std
  holds the body's shape and place at the calibration's scale.

Also each run's time in the joints' uncertainty (``timings["joints_uncertainty"]``) and
the share of joints more than 0.3 m off with their ratio.

Usage::

    python bench/bench_joints_std.py                         # ~10 min on 2 busy cores
    python bench/bench_joints_std.py --seeds 3 --frames 300 --cost --no-write

Writes ``bench/RESULTS_joints_std.md`` (machine, command, date, tables).
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
#: ``../shared/fixtures`` beside the clone (a worktree's clone one level deeper)
FIXTURES = next((p for p in (ROOT.parent / "shared" / "fixtures",
                             ROOT.parents[1] / "shared" / "fixtures") if p.is_dir()),
                ROOT.parent / "shared" / "fixtures")


def score(run, truth: np.ndarray) -> dict:
    """The ratios of one run against ``truth`` ``(T, J, 3)`` (NaN where unknown)."""
    X, ok = run.joints3d, run.valid3d & np.isfinite(truth).all(-1)
    std, shape = run.joints_std, run.joints_std_shape
    ok &= np.isfinite(std)
    err = np.linalg.norm(X - truth, axis=-1)
    f = float(np.sum(truth[ok] * X[ok]) / np.sum(X[ok] ** 2))
    err_shape = np.linalg.norm(f * X - truth, axis=-1)
    comp = run.completed if run.completed is not None else np.zeros_like(ok)
    return {"z": err[ok] / std[ok], "z_shape": err_shape[ok] / (f * shape[ok]),
            "completed": comp[ok], "err": err[ok], "std": std[ok],
            "gross": err[ok] > 0.3, "scale_err": 1.0 / f - 1.0,
            "missing_std": int(np.count_nonzero(run.valid3d & ~np.isfinite(std))),
            "seconds": float(run.timings.get("joints_uncertainty", np.nan)),
            "wall": float(run.timings.get("_wall", np.nan))}


def scene_case(noise: str, seed: int, frames: int) -> dict:
    import mirrorgraph as mg
    from mirrorgraph.synth import make_wide_scene

    sc = make_wide_scene(seed, "wide", noise, frames)
    t = time.perf_counter()
    run = mg.calibrate(sc.detections, mg.Intrinsics(K=sc.K, image_size=sc.image_size),
                       mg.CalibrateOptions(subject_height=sc.subject_height))
    run.timings["_wall"] = time.perf_counter() - t
    out = score(run, np.asarray(sc.joints3d, float))
    out.update(name=f"{noise} {seed}", noise=noise)
    return out


def fixture_case(folder: Path) -> dict:
    import mirrorgraph as mg
    from mirrorgraph.intrinsics import load_intrinsics
    from mirrorgraph.io import read_keypoints

    truth = json.loads((folder / "truth.json").read_text())
    npz = np.load(folder / "joints3d_truth.npz")
    t = time.perf_counter()
    run = mg.calibrate(read_keypoints(folder / "keypoints.json"),
                       load_intrinsics(folder / "camera.json"),
                       mg.CalibrateOptions(subject_height=float(truth["height"])))
    run.timings["_wall"] = time.perf_counter() - t
    ids = np.asarray(run.paired.frame_ids)
    where = {int(f): i for i, f in enumerate(np.asarray(npz["frame_ids"]))}
    true = np.full(run.joints3d.shape, np.nan)
    for i, f in enumerate(ids):
        if int(f) in where:
            true[i] = npz["joints3d"][where[int(f)]]
    out = score(run, true)
    out.update(name=folder.name, noise="fixture")
    return out


def cost_case(frames: int) -> dict:
    """One wide iid scene of ``frames`` frames: the whole call's wall and CPU seconds (this
    process: a long video's chunk workers are not counted) and the joints' uncertainty's."""
    import mirrorgraph as mg
    from mirrorgraph.synth import make_wide_scene

    sc = make_wide_scene(0, "wide", "iid", frames)
    c, t = time.process_time(), time.perf_counter()
    run = mg.calibrate(sc.detections, mg.Intrinsics(K=sc.K, image_size=sc.image_size),
                       mg.CalibrateOptions(subject_height=sc.subject_height))
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    ok = run.valid3d
    return {"frames": frames, "wall": wall, "cpu": cpu,
            "std": float(run.timings.get("joints_uncertainty", np.nan)),
            "covered": f"{int(np.isfinite(run.joints_std[ok]).sum())} / {int(ok.sum())}"}


def cost_table(rows: list[dict]) -> list[str]:
    out = ["| frames | calibrate wall s | CPU s (this process) | joints' uncertainty s | share "
           "of wall | joints with a std |", "|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['frames']} | {r['wall']:.1f} | {r['cpu']:.1f} | {r['std']:.2f} | "
                   f"{100 * r['std'] / r['wall']:.0f} % | {r['covered']} |")
    return out


def summary(z: np.ndarray) -> str:
    if not len(z):
        return "- | - | - | -"
    return (f"{np.median(z):.2f} | {np.percentile(z, 90):.2f} | {np.percentile(z, 99):.2f} | "
            f"{100 * np.mean(z > 3):.2f}")


def table(rows: list[dict]) -> list[str]:
    out = ["| scene | joints | metric: median | p90 | p99 | % > 3 | shape: median | p90 | p99 "
           "| % > 3 | completed (shape) median / p99 | scale error | > 0.3 m: % (median ratio) "
           "| std s | calibrate s |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    groups: dict[str, list[dict]] = {}
    for r in rows:
        groups.setdefault(r["noise"], []).append(r)
    for r in rows + [dict(name=f"**all {k}**", **_merge(v)) for k, v in groups.items()]:
        c = r["z_shape"][r["completed"]]
        g = r["gross"]
        comp = (f"{np.median(c):.2f} / {np.percentile(c, 99):.2f}" if len(c) else "-")
        gross = f"{100 * np.mean(g):.2f} ({np.median(r['z'][g]):.2f})" if g.any() else "0"
        scale = f"{100 * r['scale_err']:+.1f} %" if np.isfinite(r["scale_err"]) else "-"
        out.append(f"| {r['name']} | {len(r['z'])} | {summary(r['z'])} | {summary(r['z_shape'])} "
                   f"| {comp} | {scale} | {gross} | {r['seconds']:.2f} | {r['wall']:.1f} |")
    return out


def _merge(rows: list[dict]) -> dict:
    cat = {k: np.concatenate([r[k] for r in rows]) for k in
           ("z", "z_shape", "completed", "err", "std", "gross")}
    cat.update(scale_err=float("nan"), seconds=float(np.median([r["seconds"] for r in rows])),
               wall=float(np.median([r["wall"] for r in rows])), noise="all")
    return cat


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6, help="wide scenes per detector model")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--noise", nargs="+", default=["iid", "realistic"])
    ap.add_argument("--no-fixtures", action="store_true")
    ap.add_argument("--fixtures", type=Path, default=FIXTURES, help="the fixtures' folder")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--cost", type=int, nargs="*", default=[1000, 16000],
                    help="frames of the scenes timed alone (none: no timing)")
    args = ap.parse_args(argv)
    warnings.filterwarnings("ignore")
    started = datetime.datetime.now(datetime.timezone.utc)
    clock = time.perf_counter()
    rows = []
    for noise in args.noise:
        for seed in range(args.seeds):
            try:
                rows.append(scene_case(noise, seed, args.frames))
            except Exception as exc:  # noqa: BLE001 - a failure is a result here
                print(f"{noise} {seed}: {type(exc).__name__}: {exc}", flush=True)
                continue
            print("\n".join(table([rows[-1]])[2:]), flush=True)
    if not args.no_fixtures and args.fixtures.is_dir():
        for folder in sorted(p for p in args.fixtures.iterdir() if (p / "truth.json").is_file()):
            rows.append(fixture_case(folder))
            print("\n".join(table([rows[-1]])[2:]), flush=True)
    lines = table(rows) if rows else []
    costs = [cost_case(f) for f in args.cost]
    if costs:
        lines += ["", "Time (one wide iid scene each, timed alone; wall seconds on the shared "
                  "machine):", ""] + cost_table(costs)
    print("\n".join(lines))
    if args.no_write:
        return 0
    from _report import header

    text = ["# Each joint's std against its error (`calibrate`, `joints_std`)", "",
            *header(started=f"{started:%Y-%m-%d %H:%M} UTC, {time.perf_counter() - clock:.0f} s",
                    argv=argv, script="bench_joints_std.py",
                    note="shared with other jobs (times are noisy)", code=True),
            f"* scenes: `make_wide_scene(seed, 'wide', noise, {args.frames})`, seeds "
            f"0-{args.seeds - 1}, camera matrix and subject height given; the fixtures "
            "(`../shared/fixtures`, their `joints3d_truth.npz`)",
            "* ratio: `|X - X_true| / joints_std` per output joint (graph's and completed); "
            "metric: metres against `joints_std`; shape: the joints rescaled by the one "
            "factor that fits them to the truth against `joints_std_shape`. A Gaussian "
            "error has a median ratio of 0.67 (one long axis) to 0.89 (isotropic), 99 % "
            "under 2.6-1.9. Targets: median in [0.5, 1.5], 99 % under 3.",
            "* scale error: the run's metric scale against the truth's (the one factor); "
            "std s: seconds in the joints' uncertainty; calibrate s: the whole call.", ""]
    text += lines
    (ROOT / "bench" / "RESULTS_joints_std.md").write_text("\n".join(text) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
