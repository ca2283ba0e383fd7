"""End-to-end scaling: 1k, 10k and 54k frames (a 30-minute video at 30 fps).

For each length: a synthetic scene written as an OpenPose folder (one JSON file a
frame, as OpenPose writes it), then, in a fresh process, the whole
``mirrorgraph.calibrate`` from that folder: reading (streamed, file by file),
pairing, RANSAC (on a spread subset of frames), the factor graph (chunked above
2000 frames) and the marginals. Prints the split and the peak resident memory,
and writes ``bench/RESULTS_scale.md``.

Run:  python bench/bench_scale.py [--frames 1000 10000 54000]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _tree_pss_mb() -> float:
    """Proportional set size of this process and its children (``/proc``), MB: what the
    solve's worker processes hold counts too, shared pages once."""
    def tree(pid: int) -> list[int]:
        out = [pid]
        try:
            with open(f"/proc/{pid}/task/{pid}/children") as f:
                for c in f.read().split():
                    out += tree(int(c))
        except OSError:
            pass
        return out
    total = 0.0
    for pid in tree(os.getpid()):
        try:
            with open(f"/proc/{pid}/smaps_rollup") as f:
                total += next(int(line.split()[1]) for line in f if line.startswith("Pss:")) / 1024
        except (OSError, StopIteration):
            pass
    return total


def child(folder: str, camera: str, height: float, workers: int | None) -> None:
    import threading

    import mirrorgraph as mg
    from mirrorgraph.graph import RefineOptions
    from mirrorgraph.io import read_keypoints

    peak = [0.0]
    stop = threading.Event()

    def sample() -> None:
        while not stop.wait(0.2):
            peak[0] = max(peak[0], _tree_pss_mb())

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    t0 = time.perf_counter()
    data = read_keypoints(folder)
    t_read = time.perf_counter() - t0
    run = mg.calibrate(data, mg.load_intrinsics(camera),
                       mg.CalibrateOptions(subject_height=height,
                                           refine_options=RefineOptions(workers=workers)))
    total = time.perf_counter() - t0
    stop.set()
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"read": t_read, **run.timings, "total": total, "peak_mb": peak_mb,
                      "tree_pss_mb": max(peak[0], _tree_pss_mb()),
                      "normal": run.calibration.normal.tolist()}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, nargs="*", default=[1000, 10000, 54000])
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "RESULTS_scale.md")
    ap.add_argument("--workers", default="1,auto",
                    help="worker processes of a long video's chunks, each compared in the same "
                         "run (comma-separated; auto = RefineOptions' default)")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child[0], args.child[1], float(args.child[2]),
              None if args.child[3] == "auto" else int(args.child[3]))
        return
    from mirrorgraph.metrics import rotation_error_deg
    from mirrorgraph.geometry import virtual_camera_from_mirror
    from mirrorgraph.synth import make_scene, write_scene

    rows = []
    for T in args.frames:
        scene = make_scene(frames=T, seed=0)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            paths = write_scene(scene, tmp, formats=("openpose",))
            t_write = time.perf_counter() - t0
            for w in args.workers.split(","):
                out = subprocess.run([sys.executable, __file__, "--child", str(paths["openpose"]),
                                      str(paths["camera"]), str(scene.subject_height), w],
                                     capture_output=True, text=True, check=True)
                r = json.loads(out.stdout.strip().splitlines()[-1])
                r["frames"], r["write"], r["workers"] = T, t_write, w
                r["rot_err"] = rotation_error_deg(virtual_camera_from_mirror(r["normal"], 1)[0],
                                                  scene.virtual_R)
                rows.append(r)
                print({k: (round(v, 3) if isinstance(v, float) else v) for k, v in r.items()
                       if k != "normal"}, flush=True)
    keys = ["read", "pairing", "initialisation", "build", "solve", "marginals", "total"]
    lines = ["| frames | workers | " + " | ".join(f"{k} s" for k in keys) + " | ms / frame "
             "| peak memory MB (process tree PSS) | rotation error deg |",
             "|---:|---:|" + "---:|" * (len(keys) + 3)]
    for r in rows:
        lines.append(f"| {r['frames']:,} | {r['workers']} | "
                     + " | ".join(f"{r.get(k, float('nan')):.2f}" for k in keys)
                     + f" | {1000 * r['total'] / r['frames']:.2f} | {r['tree_pss_mb']:.0f} | "
                     f"{r['rot_err']:.4f} |")
    from _report import header
    text = "\n".join([
        "# End-to-end scaling (`bench/bench_scale.py`)", "",
        *header(cmd=f"python bench/bench_scale.py --frames {' '.join(map(str, args.frames))} "
                    f"--workers {args.workers}"),
        "* input: an OpenPose folder (one JSON file a frame) of `make_scene(frames=T, seed=0)`, "
        "COCO-17, 4 px noise; reading and the whole `calibrate` in a fresh process, subject "
        "height given; `workers`: `RefineOptions.workers` (videos over 2000 frames are solved "
        "in chunks, that many at a time; auto = the cores, at most 4); memory: the peak "
        "proportional set size of the process and its workers, sampled every 0.2 s.", "",
        *lines, ""])
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
