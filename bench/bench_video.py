"""Detection on real clips, before and after: people a frame, tracks a clip, frames/s.

Runs :func:`mirrorgraph.video.detect_video` (BlazePose, its defaults, no cache) on
each clip twice in this one run, with two versions of the ``mirrorgraph``
package side by side, clip by clip (so that both see the same load on the
machine):

* **before**: the package of a git revision (``--before``, default ``main``),
  extracted with ``git archive`` into a temporary folder;
* **after**: the package this script sits next to (the working tree).

Each run is a subprocess of this script (``--worker``) with its own
``PYTHONPATH``; it returns every frame's keypoints, track ids and the detection
time, and the figures are computed here, the same way for both:

* **people a frame**: the share of frames whose number of people lies in the
  clip's expected range: the subjects, plus up to the bystanders that are in view
  (counted by eye on the frames: Demo_SinglePerson cam01 has one person standing
  at the back, cam02 one person and an anatomical skeleton model; cam03, cam04
  none), and the mean number a frame;
* **duplicates**: frames holding two poses of one person by the criteria of
  :func:`mirrorgraph.video.nms.pose_nms` (object keypoint similarity above 0.5,
  left/right swaps included, box IoU above 0.7, or 85 % of one's keypoints on the
  other's body): the "after" code applies them, so its count is 0 by construction;
  the "people a frame" figure, against the counts by eye, is the independent one;
* **tracks**: track ids over the clip (the subjects' count is the ideal);
* **frames/s**: frames over the detection's wall time (decoding included, model
  loading and the one-time import of ``scipy.sparse`` not), under whatever else the machine runs (the load average is
  written); **CPU ms a frame**: the process's CPU time (all threads) a frame, which
  other jobs change far less: on an idle machine the wall time a frame is about
  that (the models' runtime measured no faster with 2 threads than with 1).

Clips (100 frames each unless ``--frames``): the eight Demo_SinglePerson and
Demo_MultiPerson videos of the ``pose2sim`` wheel (1080 x 1920, 60 fps; one or
two subjects); ``mirror1080``: Demo_SinglePerson cam01 composited into a
1920 x 1080 mirror scene (:class:`mirrorgraph.synth.mirror_clip.MirrorComposite`:
the person at half scale and a flipped 0.4x, 0.6x as bright copy: one person and
one reflection, plus the bystander and theirs); ``planar``: the tests' planar
mirror clip (:class:`mirrorgraph.synth.mirror_clip.PlanarMirrorClip`, 840 x 960).

Usage::

    python bench/bench_video.py                       # ~15 min on 2 cores
    python bench/bench_video.py --clips mirror1080 --frames 60 --no-write

Writes ``bench/RESULTS_video.md`` (machine, command, date, table), or ``--out FILE``.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: clip -> (subjects, bystanders in view at most)
DEMO_PEOPLE = {"cam01": 1, "cam02": 2, "cam03": 0, "cam04": 0}


def _demo_root() -> Path:
    spec = importlib.util.find_spec("Pose2Sim")
    if spec is None:
        sys.exit("pose2sim is not installed (pip install --no-deps pose2sim==0.10.49)")
    return Path(list(spec.submodule_search_locations)[0])


def _write_clip(path: Path, frames, fps: float) -> Path:
    import cv2
    h, w = frames[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for f in frames:
        out.write(np.ascontiguousarray(f[..., ::-1]))
    out.release()
    return path


def _read(path: Path, n: int):
    import cv2
    cap = cv2.VideoCapture(str(path))
    out = []
    while len(out) < n:
        ok, bgr = cap.read()
        if not ok:
            break
        out.append(np.ascontiguousarray(bgr[..., ::-1]))
    cap.release()
    return out


def clips(names: list[str], frames: int, folder: Path) -> list[tuple[str, Path, int, int]]:
    """``(name, video, subjects, most people)`` of the clips asked for (composites
    written into ``folder``)."""
    demo = _demo_root()
    out = []
    for name in names:
        if name == "mirror1080":
            from mirrorgraph.synth.mirror_clip import MirrorComposite
            comp = MirrorComposite()
            src = _read(demo / "Demo_SinglePerson" / "videos" / "cam01.mp4", frames)
            out.append((name, _write_clip(folder / "mirror1080.mp4",
                                          [comp.compose(f) for f in src], 30.0), 2, 4))
        elif name == "planar":
            import cv2
            from mirrorgraph.io.qualisys import read_qca
            from mirrorgraph.synth.mirror_clip import PlanarMirrorClip
            trial = demo / "Demo_SinglePerson"
            K = np.diag([0.5, 0.5, 1.0]) @ read_qca(
                trial / "calibration" / "Calib.qca.txt")["cam01"].K
            a = np.radians(70)
            clip = PlanarMirrorClip(K=K, normal=np.array([np.sin(a), 0.0, np.cos(a)]),
                                    distance=1.6, depth=2.9, width=840, split=420)
            src = _read(trial / "videos" / "cam01.mp4", frames)
            out.append((name, _write_clip(folder / "planar.mp4", [clip.compose(
                cv2.resize(f, (540, 960), interpolation=cv2.INTER_AREA)) for f in src], 30.0),
                2, 2 + DEMO_PEOPLE["cam01"]))
        else:
            trial, cam = name.split("/")
            subjects = 2 if trial == "Demo_MultiPerson" else 1
            video = demo / trial / "videos" / f"{cam}.mp4"
            out.append((name, video, subjects, subjects + DEMO_PEOPLE[cam]))
    return out


def worker(video: str, frames: int, out: str) -> None:
    """Detect one clip with the ``mirrorgraph`` on ``sys.path``; save what was found."""
    import mirrorgraph
    from mirrorgraph.video import VideoOptions, detect_video
    from mirrorgraph.video.blazepose import BlazePoseModels
    BlazePoseModels()                                   # model loading out of the timing
    import scipy.sparse  # noqa: F401  (imported by the first letterbox: 0.2 s, 2 ms a frame of 100)
    t0, c0 = time.perf_counter(), time.process_time()
    det = detect_video(video, VideoOptions(end=frames, cache=False))      # its defaults
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    counts = np.array([len(p) for p in det.people])
    J = det.skeleton.num_joints
    np.savez(out, counts=counts, seconds=seconds, cpu=cpu,
             keypoints=np.concatenate(det.people) if counts.sum() else np.zeros((0, J, 3)),
             track_ids=np.concatenate(det.track_ids) if counts.sum() else np.zeros(0, int),
             package=str(Path(mirrorgraph.__file__).parent),
             stats=json.dumps(det.stats))


def _run(package_root: Path, video: Path, frames: int, tmp: Path, tag: str) -> dict:
    out = tmp / f"{tag}.npz"
    env = dict(os.environ, PYTHONPATH=str(package_root))
    subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker", str(video),
                    str(frames), str(out)], check=True, env=env, cwd=str(tmp))
    with np.load(out, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def figures(res: dict, lo: int, hi: int) -> dict:
    """People a frame, duplicates, tracks and speed of one run (see the module docstring)."""
    from mirrorgraph.skeletons import BLAZEPOSE
    from mirrorgraph.video.nms import pose_nms
    counts = res["counts"]
    people = np.split(res["keypoints"], np.cumsum(counts)[:-1])
    dup = 0
    for kp in people:
        if len(kp) >= 2:
            seen = np.isfinite(kp[..., :2]).all(-1)
            xy = np.where(seen[..., None], kp[..., :2], np.nanmean(kp[..., :2], axis=1,
                                                                   keepdims=True))
            dup += len(pose_nms(xy, np.where(seen, kp[..., 2], 0.0), flip=BLAZEPOSE.flip)) \
                < len(kp)
    T = len(counts)
    return {"frames": T, "in_range": float(np.mean((counts >= lo) & (counts <= hi))),
            "mean": float(counts.mean()), "max": int(counts.max()) if T else 0,
            "dup_frames": dup, "tracks": len(np.unique(res["track_ids"])),
            "fps": T / float(res["seconds"]), "cpu_ms": 1000 * float(res["cpu"]) / T,
            "stats": json.loads(str(res["stats"]))}


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], check=True, capture_output=True,
                          text=True).stdout.strip()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", default="main", help="git revision of the 'before' package")
    ap.add_argument("--clips", nargs="+", default=[
        "mirror1080", "planar", *(f"{t}/cam0{i}" for t in ("Demo_SinglePerson",
                                                            "Demo_MultiPerson")
                                  for i in range(1, 5))])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "RESULTS_video.md",
                    help="the results file (default bench/RESULTS_video.md)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))                       # this tree's mirrorgraph for the figures
    before_rev = _git("rev-parse", "--short", args.before)
    after_rev = _git("rev-parse", "--short", "HEAD")
    dirty = bool(_git("status", "--porcelain", "--", "mirrorgraph"))
    rows, loads = [], []
    started = datetime.datetime.now(datetime.timezone.utc)
    with tempfile.TemporaryDirectory(prefix="bench_video_") as t:
        tmp = Path(t)
        old = tmp / "before"
        old.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", before_rev, "mirrorgraph"],
                                 check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
        for name, video, lo, hi in clips(args.clips, args.frames, tmp):
            got = {}
            for side, root in (("before", old), ("after", ROOT)):
                got[side] = figures(_run(root, video, args.frames, tmp, side), lo, hi)
            rows.append((name, lo, hi, got))
            b, a = got["before"], got["after"]
            print(f"{name:28s} people {lo}-{hi}: in range {b['in_range']:6.1%} -> "
                  f"{a['in_range']:6.1%}, mean {b['mean']:.2f} -> {a['mean']:.2f}, dup frames "
                  f"{b['dup_frames']} -> {a['dup_frames']}, tracks {b['tracks']} -> "
                  f"{a['tracks']}, {b['fps']:.1f} -> {a['fps']:.1f} frames/s, CPU "
                  f"{b['cpu_ms']:.0f} -> {a['cpu_ms']:.0f} ms a frame (load "
                  f"{os.getloadavg()[0]:.1f})", flush=True)
            loads.append(os.getloadavg()[0])
    lines = [
        "# Video detection: people a frame, tracks, speed (before / after)", "",
        f"- date: {started:%Y-%m-%d %H:%M} UTC",
        f"- machine: {platform.machine()}, {_cpu()}, {os.cpu_count()} cores visible, "
        f"Python {platform.python_version()}, {platform.system()} (shared with other jobs: "
        "frames/s are of one run under that load, before and after side by side; load "
        f"average {min(loads):.1f}-{max(loads):.1f} during the run)",
        f"- command: `python bench/bench_video.py {' '.join(argv or sys.argv[1:])}`".replace(
            "  ", " "),
        f"- before: `{before_rev}` ({args.before}); after: `{after_rev}`"
        + (" + uncommitted changes" if dirty else ""),
        f"- {args.frames} frames a clip, BlazePose with each version's default options "
        "(its LiteRT threads included), no cache", "",
        "| clip | people (subjects-most) | in range | mean a frame | max | frames with "
        "duplicates | tracks | frames/s | CPU ms a frame | detector runs | landmark runs |",
        "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, lo, hi, got in rows:
        b, a = got["before"], got["after"]
        lines.append(
            f"| {name} | {lo}-{hi} | {b['in_range']:.0%} / **{a['in_range']:.0%}** | "
            f"{b['mean']:.2f} / {a['mean']:.2f} | {b['max']} / {a['max']} | "
            f"{b['dup_frames']} / {a['dup_frames']} | {b['tracks']} / {a['tracks']} | "
            f"{b['fps']:.1f} / **{a['fps']:.1f}** | {b['cpu_ms']:.0f} / {a['cpu_ms']:.0f} | "
            f"{b['stats'].get('detector_runs', '')} / "
            f"{a['stats'].get('detector_runs', '')} | {b['stats'].get('landmark_runs', '')} / "
            f"{a['stats'].get('landmark_runs', '')} |")
    lines += ["", "Each cell: before / after. See the docstring of `bench/bench_video.py` for "
              "what each figure is."]
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        args.out.write_text(text)
    return 0


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--worker":
        worker(sys.argv[2], int(sys.argv[3]), sys.argv[4])
        sys.exit(0)
    sys.exit(main())
