"""The scene's straight lines as a witness of the focal length, on real footage with a known camera.

Three measurements, side by side in one run, written to ``bench/RESULTS_lines.md``:

1. **Camera clips** (the lines alone): the Pose2Sim demo's 8 distinct camera videos
   (``Demo_SinglePerson`` and ``Demo_MultiPerson``, 4 cameras each, 1080 or 1088 x 1920 at
   60 fps; a motion lab: walls, doors, windows, a walkway; the ``Demo_Batch`` trials are
   copies of these two). :func:`mirrorgraph.video.lines.scene_segments` (the median of
   ``--lines-frames`` frames, no person mask: no detection here) and
   :func:`mirrorgraph.initial.vanishing.focal_from_lines` (principal point at the centre
   with the spread of real cameras, 1 % of the larger side) against Qualisys' focal length;
   on the raw pixels (what a user has) and on the pixels undistorted with Qualisys'
   distortion (what the distortion costs).
2. **Rendered rooms** (:mod:`mirrorgraph.synth.room`): random cameras, the truth exact:
   whether the std is honest (error / std) where the reference is not in question.
3. **Mirror clips** (person, lines, fused): ``bench_agreement.py``'s exact two-camera
   composites (the mirror bisects cameras A and B; the clip's camera f = 840 px,
   1280 x 960; B's undistorted frame fills the mirror, A's person in front), detected with
   BlazePose (the detector every frame with its tiles, as ``bench_agreement.py``) and
   calibrated with :func:`mirrorgraph.calibrate` without intrinsics (the image size, the
   subject's 1.60 m, the clip as ``CalibrateOptions.video``): ``focal_sources`` against
   840 px; the same from the OpenPose annotations of the clip (``bench_agreement.py``'s,
   BODY_25B): the person's evidence from two detectors beside the lines'. Needs the Pose2Sim git history for the OpenPose subjects the composite is
   placed by (``--pose2sim-git``, as ``bench_agreement.py``); ``--no-mirror`` skips it.

Run: ``nice -n 10 python bench/bench_lines.py`` (~10 min on 2 shared cores, detection
cached in ``--work``).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import mirrorgraph as mg  # noqa: E402
from mirrorgraph.graph.options import FocalOptions  # noqa: E402
from mirrorgraph.initial.vanishing import focal_from_lines  # noqa: E402
from mirrorgraph.io.qualisys import read_qca  # noqa: E402
from mirrorgraph.video.lines import scene_segments  # noqa: E402
from results_blocks import machine  # noqa: E402

TRIALS = ("Demo_SinglePerson", "Demo_MultiPerson")
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
TARGET_REL = 0.03
HEIGHT, FPS = 1.60, 30.0


def demo_root() -> Path:
    spec = importlib.util.find_spec("Pose2Sim")
    if spec is None:
        sys.exit("bench_lines needs the pose2sim wheel: pip install --no-deps pose2sim==0.10.49")
    return Path(list(spec.submodule_search_locations)[0])


def camera_rows(frames: int, bootstrap: int) -> list[dict]:
    """Part 1: the lines' focal length of every camera clip, raw and undistorted."""
    rows = []
    for trial in TRIALS:
        cams = read_qca(demo_root() / trial / "calibration" / "Calib.qca.txt")
        for cam in CAMERAS:
            t0 = time.perf_counter()
            scene = scene_segments(demo_root() / trial / "videos" / f"{cam}.mp4", frames=frames)
            t_seg = time.perf_counter() - t0
            K, dist = cams[cam].K, cams[cam].dist
            und = cv2.undistortPoints(scene.segments.reshape(-1, 1, 2), K, dist,
                                      P=K).reshape(-1, 4)
            row = {"clip": f"{trial}/{cam}", "truth": float(K[0, 0]),
                   "pp_off_centre_px": float(np.hypot(K[0, 2] - scene.image_size[0] / 2,
                                                      K[1, 2] - scene.image_size[1] / 2)),
                   "segments_seconds": t_seg}
            for name, seg in (("raw", scene.segments), ("undistorted", und)):
                t0 = time.perf_counter()
                res = focal_from_lines(seg, scene.image_size, bootstrap=bootstrap,
                                       principal_point_sigma_px=0.01 * max(scene.image_size))
                row[name] = {**res.to_dict(), "seconds": time.perf_counter() - t0}
            r = row["raw"]
            print(f"{row['clip']}: truth {row['truth']:.0f}, lines {r.get('f', float('nan')):.0f}"
                  f" +- {r.get('std', float('nan')):.0f} ({r.get('n_vps', 0)} VPs, "
                  f"{r.get('n_segments', 0)} segments); undistorted "
                  f"{row['undistorted'].get('f', float('nan')):.0f}", flush=True)
            rows.append(row)
    return rows


def room_rows(n: int, bootstrap: int) -> list[dict]:
    """Part 3: rendered rooms (:mod:`mirrorgraph.synth.room`) with random cameras: focal
    700-2200 px (log-uniform), landscape or portrait 1920 x 1080, turned 45 deg either way,
    looking 5-25 deg down, rolled up to 5 deg, placed anywhere in the room's front, the
    principal point off the centre by 1 % of the larger side (a standard deviation per
    coordinate: the prior's spread), 3 grey levels of image noise."""
    from mirrorgraph.synth.room import render_room, rotation_ypr
    from mirrorgraph.video.lines import image_segments
    rows = []
    for seed in range(n):
        rng = np.random.default_rng(1000 + seed)
        size = (1920, 1080) if rng.random() < 0.5 else (1080, 1920)
        f = float(np.exp(rng.uniform(np.log(700), np.log(2200))))
        off = rng.normal(0.0, 0.01, 2) * max(size)
        K = np.array([[f, 0, size[0] / 2 + off[0]], [0, f, size[1] / 2 + off[1]], [0, 0, 1]])
        R = rotation_ypr(rng.uniform(-45, 45), rng.uniform(5, 25), rng.uniform(-5, 5))
        C = (rng.uniform(-2, 2), rng.uniform(-0.5, 0.5), rng.uniform(-1.5, 2))
        img = render_room(K, R, size, C, noise=3.0, seed=seed)
        res = focal_from_lines(image_segments(img), size, bootstrap=bootstrap, seed=seed,
                               principal_point_sigma_px=0.01 * max(size))
        rows.append({"seed": seed, "truth": f, **res.to_dict()})
    return rows


def mirror_rows(pairs: list[str], frames: int, work: Path, git: Path) -> list[dict]:
    """Part 2: ``calibrate`` without intrinsics on the two-camera mirror composites."""
    import bench_agreement as ba
    from mirrorgraph.video import VideoOptions, detect_video
    from mirrorgraph.video.track import TrackerOptions
    trial = ba.demo_trial()
    quals = read_qca(trial / "calibration" / "Calib.qca.txt")
    cams = sorted({c for p in pairs for c in p.split("-")})
    args = argparse.Namespace(openpose=None, pose2sim_git=git)
    op_root = ba.openpose_folders(args, cams, work)
    subjects = {c: {t: s for t, s in ba.openpose_subject(op_root / c).items() if t < frames}
                for c in cams}
    rows = []
    for p in pairs:
        A, B = p.split("-")
        clip = ba.PairClip(A, B, quals[A], quals[B], subjects[A], subjects[B])
        video = work / f"pair_{A}_{B}_{clip.size[0]}x{clip.size[1]}.mp4"
        ba.write_clip(video, clip, trial, frames)
        t0 = time.perf_counter()
        det = detect_video(video, VideoOptions(end=frames, tracker=TrackerOptions(
            detect_every=1, tiles_every=1))).to_raw()
        t_det = time.perf_counter() - t0
        row = {"clip": clip.name, "truth": float(clip.F), "detect_seconds": t_det}
        folder = work / f"ann_pair_{A}_{B}_{clip.size[0]}x{clip.size[1]}"
        ba.write_keypoints(ba.annotations(clip, subjects[A], subjects[B]), folder, "openpose",
                           meta=True)
        ann = ba.read_annotations(folder)
        for tag, lines, keypoints in (("with lines", True, det), ("person alone", False, det),
                                      ("OpenPose with lines", True, ann)):
            opts = mg.CalibrateOptions(
                image_size=clip.size, subject_height=HEIGHT, fps=FPS, video=video,
                refine_options=mg.RefineOptions(focal=FocalOptions(lines=lines)))
            t0 = time.perf_counter()
            try:
                run = mg.calibrate(keypoints, None, opts)
                est = run.calibration.intrinsics.estimated or {}
                row[tag] = {"sources": est.get("focal_sources"),
                            "focal": float(run.calibration.intrinsics.K[0, 0]),
                            "std": float(est.get("std_px", float("nan"))),
                            "normal": run.calibration.normal.tolist(),
                            "warnings": list(run.calibration.warnings)}
            except (mg.InputError, mg.DegenerateGeometryError) as exc:
                row[tag] = {"refused": str(exc)[:300]}
            row[tag]["seconds"] = time.perf_counter() - t0
        row["normal_truth"] = clip.truth["normal"]
        s = row["with lines"].get("sources") or {}
        print(f"{clip.name}: truth {clip.F:.0f}; {json.dumps(s)}", flush=True)
        rows.append(row)
    return rows


def _fmt(v, d=0):
    return "-" if v is None or not np.isfinite(v) else f"{v:.{d}f}"


def report(cam_rows, room_rows_, mir_rows, seconds, started, argv, args) -> str:
    cmd = "python bench/bench_lines.py " + " ".join(argv if argv is not None else sys.argv[1:])
    rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True).stdout.strip()
    L = ["# The scene's straight lines as a witness of the focal length", "",
         f"- date: {started:%Y-%m-%d %H:%M} UTC; run time {seconds / 60:.1f} min",
         f"- machine: {machine()}",
         f"- command: `{cmd.strip()}` (mirrorgraph at `{rev}`)",
         f"- target: the lines alone within {100 * TARGET_REL:.0f} % on clips with man-made "
         "structure, their std honest (error/std about 1, under 2)", "",
         "## 1. Camera clips: the lines alone against Qualisys", "",
         f"Median background of {args.lines_frames} frames, no person mask, principal point "
         "assumed at the centre (+- 1 % of the larger side in the bootstrap; the true one "
         "lies the distance in the table off it), "
         f"{args.bootstrap} bootstrap draws of the edges.", "",
         "| clip | Qualisys f | lines f +- std (raw pixels) | error | error/std | VPs | "
         "segments | undistorted f +- std | error | error/std | pp off centre |",
         "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    errs, zs = [], []
    for r in cam_rows:
        cells = [r["clip"], _fmt(r["truth"])]
        for name in ("raw", "undistorted"):
            x = r[name]
            if "f" in x:
                e = (x["f"] - r["truth"]) / r["truth"]
                z = (x["f"] - r["truth"]) / x["std"]
                cells += [f"{x['f']:.0f} +- {x['std']:.0f}", f"{100 * e:+.1f} %", f"{z:+.2f}"]
                if name == "raw":
                    errs.append(abs(e))
                    zs.append(abs(z))
                    cells += [str(x["n_vps"]), str(x["n_segments"])]
            else:
                cells += [f"none: {x['reason']}", "-", "-"] + (["-", "-"] if name == "raw" else [])
        cells.append(f"{r['pp_off_centre_px']:.0f} px")
        L.append("| " + " | ".join(cells) + " |")
    if errs:
        L += ["", f"Raw pixels: {len(errs)} of {len(cam_rows)} clips with an estimate; |error| "
              f"median {100 * np.median(errs):.1f} %, max {100 * np.max(errs):.1f} % "
              f"({sum(e <= TARGET_REL for e in errs)} within {100 * TARGET_REL:.0f} %); "
              f"|error|/std median {np.median(zs):.2f}, max {np.max(zs):.2f} "
              f"({sum(z <= 2 for z in zs)} within 2 std)."]
    L += ["", f"## 2. Rendered rooms: the std's honesty ({len(room_rows_)} random cameras)", ""]
    ok = [r for r in room_rows_ if "f" in r]
    if ok:
        e = np.array([(r["f"] - r["truth"]) / r["truth"] for r in ok])
        z = np.array([(r["f"] - r["truth"]) / r["std"] for r in ok])
        what = room_rows.__doc__.split(": ", 1)[1].replace("\n    ", " ").strip()
        L += [what[0].upper() + what[1:] + f" {args.bootstrap} bootstrap draws.", "",
              "| rooms with an estimate | abs error median | abs error max | within 3 % | "
              "abs error/std median | within 2 std | within 3 std |",
              "|---:|---:|---:|---:|---:|---:|---:|",
              f"| {len(ok)} of {len(room_rows_)} | {100 * np.median(abs(e)):.2f} % | "
              f"{100 * np.max(abs(e)):.2f} % | {np.mean(abs(e) <= 0.03):.0%} | "
              f"{np.median(abs(z)):.2f} | {np.mean(abs(z) <= 2):.0%} | "
              f"{np.mean(abs(z) <= 3):.0%} |"]
        none = [r["reason"] for r in room_rows_ if "f" not in r]
        if none:
            L += ["", "Without an estimate: " + "; ".join(sorted(set(none)))]
    L += ["", "## 3. Mirror clips: person, lines and fused (`focal_sources`)", ""]
    if not mir_rows:
        L.append("Not run (`--no-mirror`).")
    else:
        L += ["`mirrorgraph.calibrate` without intrinsics on the two-camera composites (truth "
              "f = 840 px); `person alone`: the same with `FocalOptions(lines=False)`.", "",
              "| clip | keypoints | person f +- std | lines f +- std | fused f +- std | person, "
              "lines, fused error | agreement (person - lines) / std | normal error fused / "
              "person alone | disagreement warned |",
              "|---|---|---:|---:|---:|---:|---:|---:|---|"]
        rows = [(r, det, r[tag], r["person alone"] if tag == "with lines" else {})
                for r in mir_rows for det, tag in (("BlazePose", "with lines"),
                                                  ("OpenPose", "OpenPose with lines"))]
        for r, det, w, a in rows:
            s = w.get("sources")
            if not s:
                L.append(f"| {r['clip']} | {det} | refused: "
                         f"{w.get('refused', a.get('refused', '?'))} | | | | | | |")
                continue
            t = r["truth"]
            p, li, fu = s["person"], s["lines"], s["fused"]
            lt = f"{li['f']:.0f} +- {li['std']:.0f}" if "f" in li else f"none: {li['reason']}"
            le = f"{100 * (li['f'] - t) / t:+.1f} %" if "f" in li else "-"
            ang = [float(np.degrees(np.arccos(min(1.0, abs(np.dot(x["normal"], r["normal_truth"]))))))
                   if "normal" in x else float("nan") for x in (w, a or {})]
            warned = any("disagree" in x for x in w.get("warnings", []))
            L.append(f"| {r['clip']} | {det} | {p['f']:.0f} +- {p['std']:.0f} | {lt} | "
                     f"{fu['f']:.0f} +- {fu['std']:.0f} | {100 * (p['f'] - t) / t:+.1f} %, {le}, "
                     f"{100 * (fu['f'] - t) / t:+.1f} % | "
                     f"{_fmt(s.get('agreement_sigma'), 2)} | {ang[0]:.2f} / {_fmt(ang[1], 2)} deg | "
                     f"{'yes' if warned else 'no'} |")
    return "\n".join(L) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lines-frames", type=int, default=31)
    ap.add_argument("--bootstrap", type=int, default=200)
    ap.add_argument("--frames", type=int, default=100, help="frames of each mirror clip")
    ap.add_argument("--rooms", type=int, default=40, help="rendered rooms of part 2")
    ap.add_argument("--pairs", nargs="*", default=["cam01-cam04", "cam02-cam03", "cam01-cam03",
                                                    "cam02-cam04"])
    ap.add_argument("--no-mirror", action="store_true", help="part 1 only")
    ap.add_argument("--pose2sim-git", type=Path,
                    default=Path("/work/.mirror/perfanalytics+pose2sim/repo"))
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "bench_agreement")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    started = datetime.datetime.now(datetime.timezone.utc)
    t0 = time.perf_counter()
    args.work.mkdir(parents=True, exist_ok=True)
    rooms = room_rows(args.rooms, args.bootstrap)
    cam_rows = camera_rows(args.lines_frames, args.bootstrap)
    mir_rows = [] if args.no_mirror else mirror_rows(args.pairs, args.frames, args.work,
                                                     args.pose2sim_git)
    text = report(cam_rows, rooms, mir_rows, time.perf_counter() - t0, started, argv, args)
    print(text)
    if not args.no_write:
        (ROOT / "bench" / "RESULTS_lines.md").write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
