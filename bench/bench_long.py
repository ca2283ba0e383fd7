"""Long videos: ``mirrorgraph calibrate`` of 1000 to 16000 frames as a user runs it.

Every scene is ``make_wide_scene(seed, "wide", "iid", frames)``, written as an MMPose
``.json`` (with its image size and frame rate) beside an intrinsics ``.json`` (the camera
matrix); the command is ``python -m mirrorgraph calibrate KEYPOINTS --intrinsics K.json
--subject-height H --out calibration.json --quiet`` in a fresh process. Wall time, CPU
time (the process and every process it waited for: the chunks' workers) and the peak
resident memory of the largest process (``wait4``'s ``ru_maxrss``) are measured. CPU time
is the figure of a shared machine: wall time there also counts the other jobs.

With ``--before DIR`` (a checkout of another commit, e.g. ``git archive HEAD~3 | tar -x
-C DIR``) every scene also runs with DIR's package first on the path, the two trees
alternating, and the table puts them side by side, with the rotation between the two
calibrations' mirror normals. Every run writes the 3D joints too (``--joints3d``), and
a second table scores each tree against the scene's truth: the mirror's rotation and
distance errors beside their stds, the joints' mean and median error, the share more
than 0.3 m off, the worst, the median error/std, and how far the joints of the two
trees lie apart.

With ``--tree NAME=DIR`` (repeatable) more checkouts run beside them, on the frame
counts of ``--tree-frames`` (default every one): an older commit's figures side by side
in the same run (its npz may lack ``joints_std``: its error/std is then left out).

With ``--workers 1,2`` the scenes also run through the library as the command does
(``mg.calibrate`` of the keypoints file, ``write_calibration``) in a fresh process with
``RefineOptions(workers=N)``: the processes that solve the chunks of a long video at
once (this one included); the command has no flag for it.

Run:  python bench/bench_long.py [--frames 1000,4000,16000] [--before DIR] [--repeats 1]
      [--tree NAME=DIR ...] [--tree-frames 1000] [--workers 1,2] [--seed 0] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))


def write_scene(seed: int, frames: int, folder: Path) -> tuple[Path, Path, float, dict]:
    """The scene's keypoints and intrinsics files, the subject's height (metres) and its
    truth (``normal``, ``distance`` m, ``joints3d`` ``(T, J, 3)`` m)."""
    from mirrorgraph.io import write_keypoints
    from mirrorgraph.synth import make_wide_scene

    sc = make_wide_scene(seed, "wide", "iid", frames)
    kp, intr = folder / "keypoints.json", folder / "intrinsics.json"
    write_keypoints(sc.detections, kp, "mmpose", meta=True)
    intr.write_text(json.dumps({"K": np.asarray(sc.K).tolist(),
                                "image_size": list(sc.image_size)}))
    truth = {"normal": np.asarray(sc.normal, float), "distance": float(sc.distance),
             "joints3d": np.asarray(sc.joints3d, float)}
    return kp, intr, float(sc.subject_height), truth


def run_cli(tree: Path, kp: Path, intr: Path, height: float, out: Path) -> dict:
    """One ``calibrate`` (the 3D joints written too) in a fresh process with ``tree``
    first on the path."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    cmd = [sys.executable, "-m", "mirrorgraph", "calibrate", str(kp), "--intrinsics", str(intr),
           "--subject-height", f"{height:.4f}", "--out", str(out),
           "--joints3d", str(out.with_suffix(".npz")), "--quiet"]
    return _measured(cmd, env, tree, out)


_LIBRARY = """
import sys
import mirrorgraph as mg
from mirrorgraph.graph import RefineOptions
kp, intr, height, out, workers = sys.argv[1:]
opts = mg.CalibrateOptions(subject_height=float(height),
                           refine_options=RefineOptions(workers=int(workers)))
run = mg.calibrate(kp, mg.load_intrinsics(intr), opts)
mg.write_calibration(out, run.calibration)
"""


def run_library(tree: Path, kp: Path, intr: Path, height: float, out: Path, workers: int) -> dict:
    """``mg.calibrate`` of the keypoints file with ``workers`` in a fresh process."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    cmd = [sys.executable, "-c", _LIBRARY, str(kp), str(intr), f"{height:.4f}", str(out),
           str(workers)]
    return _measured(cmd, env, tree, out)


def _measured(cmd: list[str], env: dict, tree: Path, out: Path) -> dict:
    """Run ``cmd``; its wall time, CPU time (with the processes it waited for), peak memory
    of its largest process and the mirror normal it wrote to ``out``."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=str(tree), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise RuntimeError(f"{cmd[:4]} exited {code} in {tree}:\n{err[-2000:]}")
    cal = json.loads(out.read_text())
    res = dict(wall=wall, cpu=ru.ru_utime + ru.ru_stime, rss_mb=ru.ru_maxrss / 1024.0,
               normal=np.asarray(cal["mirror"]["normal"], float),
               distance=float(cal["mirror"]["distance"]),
               rotation_std_deg=float(cal["uncertainty"]["rotation_std_deg"]),
               distance_std=float(cal["uncertainty"]["distance_std"]))
    npz = out.with_suffix(".npz")
    if npz.exists():
        with np.load(npz) as z:
            res.update(joints3d=np.asarray(z["joints3d"], float),
                       valid=np.asarray(z["valid"], bool),
                       joints_std=np.asarray(z["joints_std"], float) if "joints_std" in z.files
                       else np.full(np.shape(z["valid"]), np.nan))
    return res


def accuracy(r: dict, truth: dict) -> dict:
    """The mirror's and the joints' errors of one run against the scene's truth."""
    out = dict(rot_err=_angle_deg(r["normal"], truth["normal"]),
               dist_err_mm=1e3 * abs(r["distance"] - truth["distance"]),
               rot_std=r["rotation_std_deg"], dist_std_mm=1e3 * r["distance_std"])
    if "joints3d" in r:
        ok = r["valid"]
        err = np.linalg.norm(r["joints3d"] - truth["joints3d"], axis=-1)[ok]
        ratio = err / r["joints_std"][ok]           # NaN: a tree without joints_std
        out.update(mpjpe_mm=1e3 * float(np.mean(err)), median_mm=1e3 * float(np.median(err)),
                   gross_pct=100.0 * float(np.mean(err > 0.3)), worst_m=float(np.max(err)),
                   err_std=float(np.median(ratio)), joints=int(np.count_nonzero(ok)))
    return out


def _joints_moved(folder: Path) -> float:
    """Median distance, mm, between the two trees' joints where both give one."""
    with np.load(folder / "before.npz") as b, np.load(folder / "after.npz") as a:
        ok = b["valid"] & a["valid"]
        return 1e3 * float(np.median(np.linalg.norm(a["joints3d"][ok] - b["joints3d"][ok],
                                                    axis=-1)))


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = abs(float(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return float(np.degrees(np.arccos(min(1.0, c))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", default="1000,4000,16000")
    ap.add_argument("--before", type=Path, default=None,
                    help="a checkout of the commit to compare with")
    ap.add_argument("--tree", action="append", default=[], metavar="NAME=DIR",
                    help="another checkout run beside the two (repeatable)")
    ap.add_argument("--tree-frames", default="",
                    help="the frame counts the --tree checkouts run on (default: every one)")
    ap.add_argument("--repeats", type=int, default=1, help="runs of each tree (the fastest kept)")
    ap.add_argument("--workers", default="",
                    help="also run the library with these RefineOptions.workers (e.g. 1,2)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    from _report import header, now

    started = now()
    extra = [(n, Path(d).resolve()) for n, d in (t.split("=", 1) for t in args.tree)]
    extra_frames = {int(f) for f in args.tree_frames.split(",") if f.strip()}
    trees = (extra + ([("before", args.before.resolve())] if args.before else [])
             + [("after", ROOT)])
    workers = [int(w) for w in args.workers.split(",") if w.strip()]
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_long_") as tmp:
        for frames in [int(f) for f in args.frames.split(",")]:
            folder = Path(tmp) / str(frames)
            folder.mkdir()
            kp, intr, height, truth = write_scene(args.seed, frames, folder)
            best: dict[str, dict] = {}
            for _ in range(args.repeats):
                for name, tree in trees:
                    if (name, tree) in extra and extra_frames and frames not in extra_frames:
                        continue
                    r = run_cli(tree, kp, intr, height, folder / f"{name}.json")
                    if name not in best or r["cpu"] < best[name]["cpu"]:
                        best[name] = r
                    print(f"{frames:6d} {name:6s} wall {r['wall']:6.1f} s  CPU {r['cpu']:6.1f} s"
                          f"  peak {r['rss_mb']:6.0f} MB", flush=True)
                for w in workers:
                    r = run_library(ROOT, kp, intr, height, folder / f"w{w}.json", w)
                    key = f"after, workers={w}"
                    if key not in best or r["cpu"] < best[key]["cpu"]:
                        best[key] = r
                    print(f"{frames:6d} {key} wall {r['wall']:6.1f} s  CPU {r['cpu']:6.1f} s"
                          f"  peak {r['rss_mb']:6.0f} MB", flush=True)
            for r in best.values():
                r["acc"] = accuracy(r, truth)
                r.pop("joints3d", None), r.pop("valid", None), r.pop("joints_std", None)
            both = ("before" in best and "after" in best
                    and "mpjpe_mm" in best["before"]["acc"] and "mpjpe_mm" in best["after"]["acc"])
            if both:
                best["after"]["acc"]["moved_mm"] = _joints_moved(folder)
            rows.append((frames, best))
    names = [n for n, _ in trees] + [f"after, workers={w}" for w in workers]
    head = "| frames | " + " | ".join(f"{n}: wall s | {n}: CPU s | {n}: peak MB" for n in names)
    head += " | mirror before-after, deg |" if args.before else " |"
    sep = "|---:" * (1 + 3 * len(names) + (1 if args.before else 0)) + "|"
    lines = [head, sep]
    for frames, best in rows:
        cells = [f"{best[n]['wall']:.1f} | {best[n]['cpu']:.1f} | {best[n]['rss_mb']:.0f}"
                 if n in best else "- | - | -" for n in names]
        diff = (f" | {_angle_deg(best['before']['normal'], best['after']['normal']):.4f}"
                if args.before else "")
        lines.append(f"| {frames} | " + " | ".join(cells) + diff + " |")
    acc = ["| frames | tree | mirror rotation error, deg | its std, deg | distance error, mm "
           "| its std, mm | joints: mean error, mm | median, mm | > 0.3 m, % | worst, m "
           "| median error/std | joints | joints moved before-after, median mm |",
           "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for frames, best in rows:
        for n in names:
            if n not in best:
                continue
            a = best[n]["acc"]
            j = (f"{a['mpjpe_mm']:.1f} | {a['median_mm']:.1f} | {a['gross_pct']:.2f} | "
                 f"{a['worst_m']:.2f} | {a['err_std']:.2f} | {a['joints']}"
                 if "mpjpe_mm" in a else " | ".join(["-"] * 6))
            moved = f"{a['moved_mm']:.3f}" if "moved_mm" in a else "-"
            acc.append(f"| {frames} | {n} | {a['rot_err']:.4f} | {a['rot_std']:.4f} | "
                       f"{a['dist_err_mm']:.1f} | {a['dist_std_mm']:.1f} | {j} | {moved} |")
    text = "\n".join(lines) + "\n\nAccuracy against the scene's truth (the same runs):\n\n" \
        + "\n".join(acc)
    print(text)
    if args.no_write:
        return
    doc = ["# Long videos: `calibrate` of 1000-16000 frames (`bench/bench_long.py`)", "",
           *header(started=started,
                   note=f"{args.repeats} run(s) of each tree, the least CPU kept"),
           "* what: `make_wide_scene(%d, 'wide', 'iid', frames)` written as MMPose .json and "
           "intrinsics .json; `python -m mirrorgraph calibrate KEYPOINTS --intrinsics K.json "
           "--subject-height H --out OUT --joints3d OUT.npz --quiet` in a fresh process; CPU is "
           "the process's and "
           "its workers'; peak is the largest process's resident memory; `after, workers=N`: "
           "`mg.calibrate` of the same files with `RefineOptions(workers=N)` in a fresh "
           "process" % args.seed, "",
           text, ""]
    (ROOT / "bench" / "RESULTS_long.md").write_text("\n".join(doc))
    print(f"wrote {ROOT / 'bench' / 'RESULTS_long.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
