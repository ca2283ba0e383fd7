"""The metric mirror distance's and the metric scale's error over their stds, two versions of
the code side by side.

With the subject's height the metric distance is ``D = H / S(n, 1)`` (``S`` the stature
measured on the joints triangulated with the mirror ``(n, 1)``,
:mod:`mirrorgraph.pipelines.scale`): its std holds the normal's covariance carried through
the stature, the stature's sampling, the height's prior and the measurement's spread. The
scale (the joints' one factor about the camera against the truth) holds the last two.

Each scene (``bench_joints.py``'s: ``make_wide_scene(seed, "wide", kind, frames)`` for
``iid`` and ``realistic``, its other kinds by ``--kinds``; the generator's population
bodies, the camera matrix given) is calibrated by ``calibrate`` under three settings:

- ``reported``: the height a user reports (``bench_joints.py``'s model: the truth + 1.1 cm
  + 1.9 cm x a normal draw of the scene), the options' defaults;
- ``exact``: the true height, the options' defaults;
- ``stated``: the true height with the bench's own error models stated
  (``keypoint_offset`` 0: the synthetic keypoints lie on the joints; ``height_sigma`` 0.5 %),
  where nothing but the data's and the stature's own terms is left to cover the error.

``--before REV`` is run from ``git archive REV`` in a temporary folder, the working tree as
``after``, each in its own processes (``--workers`` at a time), the same scenes.

Usage::

    python bench/bench_scale_std.py                      # iid and realistic 0-9, ~8 min
    python bench/bench_scale_std.py --full               # seeds 0-19, ~15 min on 2 cores
    python bench/bench_scale_std.py --seeds 13 --kinds iid --no-write

Writes ``bench/RESULTS_scale_std.md`` (machine, command, date, tables) and its JSON.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from _trees import archive, run_worker  # noqa: E402

#: setting -> (height given, RefineOptions fields)
SETTINGS = {"reported": ("reported", {}),
            "exact": ("exact", {}),
            "stated": ("exact", {"keypoint_offset": 0.0, "height_sigma": 0.005})}
KINDS = ("iid", "realistic")


def _seeds(text: str) -> list[int]:
    out = []
    for part in str(text).split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


# ---------------------------------------------------------------- one version's process
def worker(setting: str, kinds: list[str], seeds: list[int], frames: int) -> None:
    """Every scene under ``setting`` with the ``mirrorgraph`` first on ``sys.path``; one
    JSON line a scene on stdout."""
    import bench_joints as bj
    import mirrorgraph as mg
    from mirrorgraph.graph import RefineOptions

    given, fields = SETTINGS[setting]
    for kind in kinds:
        for seed in seeds:
            tr = bj.make_truth(kind, seed, frames, bj.default_fixtures(), "population", given)
            ro = RefineOptions(**fields) if fields else None
            opts = mg.CalibrateOptions(subject_height=tr.height_given, fps=bj.FPS,
                                       refine_options=ro)
            clock = time.perf_counter()
            run = mg.calibrate(tr.detections, tr.intrinsics, opts)
            wall = time.perf_counter() - clock
            cal = run.calibration
            dstd = (cal.uncertainty or {}).get("distance_std")
            X, ok, _, _ = bj.on_truth_frames(run, tr)
            ok = ok & np.isfinite(X).all(-1)
            Xg, Tg = X[ok], tr.joints3d[ok]
            fit = float((Xg * Tg).sum() / (Xg * Xg).sum())
            st = (cal.refinement or {}).get("stature") or {}
            out = dict(kind=kind, seed=seed, setting=setting, wall_s=wall,
                       distance_err=float(cal.distance / tr.distance - 1.0),
                       distance_rel_std=float(dstd / cal.distance) if dstd else None,
                       distance_z=(abs(cal.distance - tr.distance) / dstd if dstd else None),
                       scale_err=1.0 / fit - 1.0,
                       scale_rel_std=getattr(run, "scale_rel_std", None),
                       height_err=tr.height_given / tr.height - 1.0,
                       rotation_std_deg=float(cal.uncertainty.get("rotation_std_deg", np.nan)),
                       parts=st.get("distance_rel_std"))
            print(json.dumps(out), flush=True)


def _run(tree: Path, setting: str, kinds: list[str], seeds: list[int], frames: int,
         nice: int) -> list[dict]:
    return run_worker(tree, "bench_scale_std.py",
                      ["--worker", setting, "--kinds", ",".join(kinds),
                       "--seeds", ",".join(map(str, seeds)), "--frames", str(frames)], nice)


# ---------------------------------------------------------------- figures
def _z(err, std):
    return abs(err) / std if std else float("nan")


def _fmt(x, spec=".2f"):
    return "n/a" if x is None or not np.isfinite(x) else format(x, spec)


def summary(rows: dict, kinds: list[str]) -> list[str]:  # noqa: C901
    """Per setting and kind: the distance's and the scale's err/std, before -> after."""
    lines = ["| setting | kind | scenes | distance std % med | distance err/std med | "
             "distance err/std worst | distance err/std > 3 | scale std % med | "
             "scale err/std worst | scale err/std > 3 |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for setting in SETTINGS:
        for kind in kinds:
            if not any(x["setting"] == setting and x["kind"] == kind for x in rows["after"]):
                continue
            per = {}
            for ver in ("before", "after"):
                r = [x for x in rows[ver] if x["setting"] == setting and x["kind"] == kind]
                dz = np.array([x["distance_z"] or np.nan for x in r])
                ds = np.array([100 * (x["distance_rel_std"] or np.nan) for x in r])
                sz = np.array([_z(x["scale_err"], x["scale_rel_std"]) for x in r])
                ss = np.array([100 * (x["scale_rel_std"] or np.nan) for x in r])
                per[ver] = dict(n=len(r), ds=np.nanmedian(ds) if len(r) else np.nan,
                                dzm=np.nanmedian(dz) if len(r) else np.nan,
                                dzw=np.nanmax(dz) if len(r) else np.nan,
                                dz3=int(np.sum(dz > 3)),
                                ss=np.nanmedian(ss) if len(r) else np.nan,
                                szw=np.nanmax(sz) if len(r) else np.nan,
                                sz3=int(np.sum(sz > 3)))
            b, a = per["before"], per["after"]
            cells = [setting, kind, str(a["n"])]
            for key, spec in (("ds", ".2f"), ("dzm", ".2f"), ("dzw", ".2f"), ("dz3", "d"),
                              ("ss", ".2f"), ("szw", ".2f"), ("sz3", "d")):
                cells.append(f"{_fmt(b[key], spec)} -> {_fmt(a[key], spec)}")
            lines.append("| " + " | ".join(cells) + " |")
    return lines


def per_scene(rows: dict, kinds: list[str], seeds: list[int]) -> list[str]:
    """Every scene: the distance's error and std before -> after under each setting."""
    head = ["scene", "normal's std deg"]
    for s in SETTINGS:
        head += [f"{s}: distance err %", f"{s}: std % before -> after",
                 f"{s}: err/std before -> after", f"{s}: normal's part %"]
    lines = ["| " + " | ".join(head) + " |", "|---" + "|---:" * (len(head) - 1) + "|"]
    idx = {(v, x["setting"], x["kind"], x["seed"]): x for v in rows for x in rows[v]}
    for kind in kinds:
        for seed in seeds:
            a0 = idx.get(("after", "reported", kind, seed))
            cells = [f"{kind} {seed}", _fmt(a0["rotation_std_deg"]) if a0 else "n/a"]
            for s in SETTINGS:
                b, a = idx.get(("before", s, kind, seed)), idx.get(("after", s, kind, seed))
                if a is None or b is None:
                    cells += ["n/a"] * 4
                    continue
                part = (a.get("parts") or {}).get("normal")
                cells += [f"{100 * a['distance_err']:+.2f}",
                          f"{_fmt(100 * (b['distance_rel_std'] or np.nan))} -> "
                          f"{_fmt(100 * (a['distance_rel_std'] or np.nan))}",
                          f"{_fmt(b['distance_z'])} -> {_fmt(a['distance_z'])}",
                          _fmt(None if part is None else 100 * part)]
            lines.append("| " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--full", action="store_true", help="seeds 0-19")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--settings", default=",".join(SETTINGS),
                    help="comma-separated, of " + ", ".join(SETTINGS))
    ap.add_argument("--before", default=None,
                    help="the commit compared against (default: the merge base with main)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--out", default=str(HERE / "RESULTS_scale_std.md"))
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    kinds = [k for k in args.kinds.split(",") if k]
    seeds = _seeds("0-19" if args.full else args.seeds)
    if args.worker:
        worker(args.worker, kinds, seeds, args.frames)
        return 0
    settings = [s for s in args.settings.split(",") if s]
    for s in settings:
        if s not in SETTINGS:
            ap.error(f"--settings: unknown {s!r}; known: {', '.join(SETTINGS)}")
    from _report import header

    before = args.before or subprocess.run(["git", "merge-base", "HEAD", "main"], cwd=ROOT,
                                           capture_output=True, text=True).stdout.strip()
    clock = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="scale_std_") as tmp:
        old = archive(before, Path(tmp))
        trees = {"before": Path(tmp), "after": ROOT}
        jobs = [(v, s) for s in settings for v in trees]
        with ThreadPoolExecutor(max(1, args.workers)) as pool:
            futs = {job: pool.submit(_run, trees[job[0]], job[1], kinds, seeds, args.frames,
                                     args.nice) for job in jobs}
            rows = {"before": [], "after": []}
            for (v, s), fut in futs.items():
                rows[v] += fut.result()
                print(f"{v} {s}: {len(fut.result())} scenes "
                      f"({time.perf_counter() - clock:.0f} s)", flush=True)
    minutes = (time.perf_counter() - clock) / 60
    lines = ["# The metric distance's and scale's error over their stds (`bench/bench_scale_std.py`)",
             "", *header(code=True),
             f"- before: `{old}` (`git archive`); after: the working tree; {minutes:.1f} min "
             f"with {args.workers} workers",
             f"- scenes: `bench_joints.py`'s of each kind (`iid`, `realistic`: "
             f"`make_wide_scene(seed, 'wide', kind, {args.frames})`), kinds "
             f"{', '.join(kinds)}, seeds {seeds[0]}-{seeds[-1]}; population bodies; the camera "
             "matrix given",
             "- settings: `reported` (the user's reported height, defaults), `exact` (the true "
             "height, defaults), `stated` (the true height, `keypoint_offset` 0, "
             "`height_sigma` 0.5 %)",
             "- figures: `distance err/std` the metric mirror distance's |error| over its "
             "`distance_std`; `scale` the joints' one factor about the camera against the "
             "truth over `scale_rel_std`; `> 3` the count of scenes beyond 3; `normal's "
             "part` the distance's relative std from the normal's covariance through the "
             "stature (after only)",
             "", "## Over scenes (before -> after)", "", *summary(rows, kinds),
             "", "## Every scene", "", *per_scene(rows, kinds, seeds), ""]
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        Path(args.out).write_text(text)
        Path(args.out).with_suffix(".json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
