"""Crossed left/right labels in long runs of one view: the mirror and the labels after
``calibrate``, the whole clip's decision beside each frame's and beside another commit.

Synthetic keypoint scenes (:func:`mirrorgraph.synth.sampling.make_wide_scene`, the
``gym`` and ``favourable`` geometries, ``--frames`` frames) with the ``iid`` and the
``realistic`` detector (the latter swaps left and right in 3 % of each view's frames), and
on top of it one view's labels crossed (``make_scene(lr_crossed_view=...)``: a body seen
from behind labelled as facing the camera): none, the person's for the whole clip, the
person's in runs over half the frames, the reflection's in runs over 40 %, the reflection's
for the whole clip (runs of 90 frames on average). Each scene calibrates (the graph, the
truth's intrinsics) with ``left_right="clip"`` (:mod:`mirrorgraph.initial.clip_left_right`)
and ``"frame"`` (the pairing's check of each frame alone), and with ``--before-code DIR``
also under the code in ``DIR`` (e.g. ``git archive <commit> | tar -x -C DIR``; run in a
subprocess on the same detections). Per run: the virtual camera's rotation error and its
reported std (``rotation_std_deg``), and the share of the paired frames whose labels are
crossed in either view after the run (``CalibrationRun.paired`` against the scene's clean
images; crossed labels in both views triangulate a body whose left is its right), or the
refusal.

Prints a table and writes ``bench/RESULTS_left_right_clip.md`` (machine, command, date,
code) unless ``--no-write``; ``--json FILE`` saves the rows, ``--rows FILE`` writes the
report from saved rows, ``--clip-rows FILE`` adds the rows of ``bench/bench_synth_clip.py
--frame-left-right --json FILE`` (BlazePose on the drawn clip) as a second table.

Run:  python bench/bench_left_right_clip.py [--seeds 0 1 2 3] [--frames 400]
      [--before-code /tmp/base]     (~10 s a scene on 2 shared cores, three runs)
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: (name, make_scene arguments) of the crossings.
CROSSINGS = (("none", {}),
             ("person, whole clip", dict(lr_crossed_view="real")),
             ("person, runs over 50 %", dict(lr_crossed_view="real", lr_crossed_fraction=0.5)),
             ("reflection, runs over 40 %", dict(lr_crossed_view="mirror",
                                                 lr_crossed_fraction=0.4)),
             ("reflection, whole clip", dict(lr_crossed_view="mirror")))
DETECTORS = ("iid", "realistic")
SLICES = ("gym", "favourable")


def solve(jobs: list[dict]) -> list[dict]:
    """Calibrate each job's detections (``left_right`` where the code has the option);
    per job the virtual rotation, its std, the paired keypoints, or the refusal."""
    from mirrorgraph.errors import MirrorgraphError
    from mirrorgraph.pipelines.mirror import calibrate
    from mirrorgraph.pipelines.options import CalibrateOptions

    out = []
    for job in jobs:
        kw = dict(job.get("options", {}))
        if job["left_right"]:
            kw["left_right"] = job["left_right"]
        try:
            run = calibrate(job["detections"], job["intrinsics"], CalibrateOptions(**kw))
        except MirrorgraphError as exc:
            out.append({"error": str(exc).splitlines()[0][:90]})
            continue
        c = run.calibration
        out.append({"R": np.asarray(c.virtual_rotation), "normal": np.asarray(c.normal),
                    "std": c.uncertainty.get("rotation_std_deg"),
                    "distance": c.distance, "frames_paired": int(c.frames_paired),
                    "frame_ids": np.asarray(run.paired.frame_ids),
                    "real": np.asarray(run.paired.real), "mirror": np.asarray(run.paired.mirror)})
    return out


def crossed(paired: dict, scene) -> float:
    """The share of the paired frames (both views seen) whose left/right joints lie nearer
    their counterparts' clean images than their own, in either view."""
    flip = scene.skeleton.flip
    sided = np.flatnonzero(flip != np.arange(len(flip)))
    idx = np.searchsorted(scene.frame_ids, paired["frame_ids"])
    wrong = []
    for view, clean in ((paired["real"], scene.real_image), (paired["mirror"], scene.mirror_image)):
        c = clean[idx]
        d = np.linalg.norm(view[:, sided, None, :2]
                           - np.stack([c[:, sided], c[:, flip[sided]]], 2), axis=-1)
        ok = np.isfinite(d).all(-1)
        wrong.append(np.where(ok, d[..., 1], 0).sum(1) < np.where(ok, d[..., 0], 0).sum(1))
    both = (paired["real"][..., 2] > 0).any(1) & (paired["mirror"][..., 2] > 0).any(1)
    return float(np.mean((wrong[0] | wrong[1])[both])) if both.any() else float("nan")


def measure(result: dict, scene) -> dict:
    from mirrorgraph.metrics import rotation_error_deg

    if "error" in result:
        return {"error": result["error"]}
    return {"rotation_deg": float(rotation_error_deg(result["R"], scene.virtual_R)),
            "std_deg": None if result["std"] is None else float(result["std"]),
            "crossed": crossed(result, scene)}


def run_before(jobs: list[dict], code: str) -> list[dict]:
    """:func:`solve` in a subprocess whose ``mirrorgraph`` is the one in ``code``."""
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "jobs.pkl", Path(tmp) / "out.pkl"
        src.write_bytes(pickle.dumps([dict(j, left_right=None) for j in jobs]))
        env = dict(os.environ, PYTHONPATH=str(Path(code).resolve()))
        subprocess.run([sys.executable, __file__, "--solve", str(src), str(dst)], env=env,
                       check=True)
        return pickle.loads(dst.read_bytes())


def _summary(cells: list[dict]) -> list[str]:
    ok = [c for c in cells if "error" not in c]
    refused = len(cells) - len(ok)
    if not ok:
        return ["", "", "", "", f"{refused}/{len(cells)}"]
    rot = np.array([c["rotation_deg"] for c in ok])
    std = np.array([np.nan if c["std_deg"] is None else c["std_deg"] for c in ok])
    wrong = np.array([c["crossed"] for c in ok])
    return [f"{np.median(rot):.2f}", f"{rot.max():.2f}", f"{np.nanmedian(std):.2f}",
            f"{100 * np.nanmean(wrong):.1f} (max {100 * np.nanmax(wrong):.0f})",
            f"{refused}/{len(cells)}"]


def table(rows: list[dict], modes: list[str]) -> list[str]:
    cols = ["rotation err median (deg)", "max", "rotation std median (deg)",
            "frames crossed after (%)", "refused"]
    head = ["detector", "crossed labels"] + [f"{m}: {c}" for m in modes for c in cols]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for det in DETECTORS:
        for name, _ in CROSSINGS:
            sel = [r for r in rows if r["detector"] == det and r["crossing"] == name]
            if not sel:
                continue
            cells = [det, name]
            for m in modes:
                cells += _summary([r[m] for r in sel])
            out.append("| " + " | ".join(cells) + " |")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    ap.add_argument("--frames", type=int, default=400)
    ap.add_argument("--before-code", metavar="DIR",
                    help="a tree of another commit whose calibrate runs beside")
    ap.add_argument("--json", metavar="FILE", help="save the rows")
    ap.add_argument("--rows", metavar="FILE", help="write the report from saved rows")
    ap.add_argument("--clip-rows", metavar="FILE",
                    help="saved rows of bench_synth_clip.py --frame-left-right, a second table")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--solve", nargs=2, metavar=("JOBS", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.solve:                        # the subprocess of --before-code: its own code
        jobs = pickle.loads(Path(args.solve[0]).read_bytes())
        Path(args.solve[1]).write_bytes(pickle.dumps(solve(jobs)))
        return
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "bench"))
    from mirrorgraph.synth.sampling import make_wide_scene

    rows = json.loads(Path(args.rows).read_text()) if args.rows else []
    before = args.before_code or any("before" in r for r in rows)
    modes = (["before"] if before else []) + ["frame", "clip"]
    for det in DETECTORS if not args.rows else ():
        for name, kw in CROSSINGS:
            for sl in SLICES:
                for seed in args.seeds:
                    scene = make_wide_scene(seed, slice=sl, noise=det, frames=args.frames,
                                            **kw)
                    job = {"detections": scene.detections, "intrinsics": scene.intrinsics}
                    row = {"detector": det, "crossing": name, "slice": sl, "seed": seed}
                    for mode in ("frame", "clip"):
                        row[mode] = measure(solve([dict(job, left_right=mode)])[0], scene)
                    if args.before_code:
                        row["before"] = measure(run_before([job], args.before_code)[0], scene)
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    lines = table(rows, modes)
    print("\n".join(lines))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    if not args.no_write:
        from _report import header
        text = ["# Crossed left/right labels in long runs of one view "
                "(`bench/bench_left_right_clip.py`)", "", *header(code=True), "", *lines, ""]
        if args.clip_rows:
            from bench_synth_clip import table as clip_table
            text += ["## BlazePose on the drawn clip (`bench/bench_synth_clip.py "
                     "--frame-left-right`)", "",
                     *clip_table(json.loads(Path(args.clip_rows).read_text())), ""]
        (ROOT / "bench" / "RESULTS_left_right_clip.md").write_text("\n".join(text))


if __name__ == "__main__":
    main()
