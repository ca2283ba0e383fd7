"""The README's synthetic clip calibrated by the video path, beside the keypoint file of
the same frames.

For each seed, the README's scene (``mirrorgraph synth --frames 1000 --outliers 0.1
--lr-swaps 0.05 --subject-height 1.75``, the ``gym`` geometry) is drawn as ``clip.mp4``
(its first ``--clip-frames`` frames, :func:`mirrorgraph.synth.video.write_scene_video`),
BlazePose detects it (:func:`mirrorgraph.video.detect.detect_video`, no cache) and
:func:`mirrorgraph.pipelines.mirror.calibrate` runs on the detections and, apart, on
``keypoints_mmpose.json``'s same frames. Per run: the mirror normal's angle to the truth,
the virtual camera's rotation error and its reported std (the sandwich's, ``rotation_std_deg``)
and their ratio, the distance's error (scale from the subject's height), the frames paired.
Per clip: the frames whose reflection is visible
(:func:`~mirrorgraph.synth.video.reflection_visibility` >= ``VISIBLE_FRACTION``), the share
of frames whose person faces the camera, and per view the share of BlazePose's detections
labelled with left and right crossed (the person as a mirror image, the reflection as a
person facing the camera: what :mod:`mirrorgraph.initial.left_right` undoes only where the
detector's labels fit the epipole badly).

``--frame-left-right`` calibrates the clip's detections also with the left/right labels
decided for each frame alone (``left_right="frame"``) beside the whole clip's decision
(:mod:`mirrorgraph.initial.clip_left_right`, the default); ``--cache DIR`` keeps
BlazePose's detections of each clip in ``DIR`` for the next run; ``--before-code DIR``
calibrates the clip's detections also with another commit's tree (a subprocess).

Prints a table and writes ``bench/RESULTS_synth_clip.md`` (machine, command, date) unless
``--no-write``; ``--json FILE`` saves the rows, ``--rows FILE`` writes the report from saved
rows, ``--before FILE`` sets another commit's clip columns beside.

Run:  python bench/bench_synth_clip.py [--seeds 3 4 6 8] [--clip-frames 150]
(BlazePose on 2 shared cores: ~1 min a seed.)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pickle
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

#: The body joints compared between BlazePose and the truth.
_NAMES = ("left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist",
          "right_wrist", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle",
          "right_ankle")


def _swap(name: str) -> str:
    return name.replace("left", "@").replace("right", "left").replace("@", "right")


def crossed_shares(scene, raw, count: int) -> dict:
    """Per view, of the detections nearest its true image (median joint distance, either
    labelling, within 20% of its height), how many and the share labelled with left and
    right crossed: the person labelled as a mirror image, the reflection as a person (a
    mirror image's left is the person's right)."""
    found = [raw.skeleton.index(n) for n in _NAMES]
    same = [scene.skeleton.index(n) for n in _NAMES]
    flipped = [scene.skeleton.index(_swap(n)) for n in _NAMES]
    out = {}
    for view, image, right in (("person", scene.real_image, same),
                               ("reflection", scene.mirror_image, flipped)):
        wrong = flipped if view == "person" else same
        crossed = total = 0
        for t in range(min(count, len(raw.people))):
            best = None
            for p in raw.people[t]:
                d_right = np.nanmedian(np.linalg.norm(p[found, :2] - image[t, right], axis=1))
                d_wrong = np.nanmedian(np.linalg.norm(p[found, :2] - image[t, wrong], axis=1))
                if best is None or min(d_right, d_wrong) < best[0]:
                    best = (min(d_right, d_wrong), d_wrong < d_right)
            if best is not None and best[0] < 0.2 * np.ptp(image[t, :, 1]):
                total += 1
                crossed += bool(best[1])
        out[view] = (crossed / total if total else float("nan"), total)
    return out


def uncrossed(scene, raw, count: int):
    """``raw`` with every detection's left and right put the right way round by the truth
    (the detections matched to a view as :func:`crossed_shares` matches them): what the
    clip gives where left and right are never confused."""
    found = [raw.skeleton.index(n) for n in _NAMES]
    same = [scene.skeleton.index(n) for n in _NAMES]
    flipped = [scene.skeleton.index(_swap(n)) for n in _NAMES]
    people = [p.copy() for p in raw.people]
    for t in range(min(count, len(people))):
        for view, image, right, wrong in (("person", scene.real_image, same, flipped),
                                          ("reflection", scene.mirror_image, flipped, same)):
            best = None
            for k, p in enumerate(people[t]):
                d_right = np.nanmedian(np.linalg.norm(p[found, :2] - image[t, right], axis=1))
                d_wrong = np.nanmedian(np.linalg.norm(p[found, :2] - image[t, wrong], axis=1))
                if best is None or min(d_right, d_wrong) < best[0]:
                    best = (min(d_right, d_wrong), d_wrong < d_right, k)
            if best is not None and best[1] and best[0] < 0.2 * np.ptp(image[t, :, 1]):
                people[t][best[2]] = people[t][best[2]][raw.skeleton.flip]
    return dataclasses.replace(raw, people=people)


def facing_camera(scene, count: int) -> float:
    """The share of the first ``count`` frames whose person faces the camera (the nose
    nearer than the ears' middle)."""
    sk = scene.skeleton
    X = scene.joints3d[:count]
    ears = 0.5 * (X[:, sk.index("left_ear"), 2] + X[:, sk.index("right_ear"), 2])
    return float(np.mean(X[:, sk.index("nose"), 2] < ears))


def crossed_after(run, scene) -> float:
    """The share of the run's paired frames (both views seen) whose body joints (either
    view's) lie nearer their counterparts' true images than their own: labels crossed
    after the run's left/right decisions (the reflection's labels in the person's)."""
    sk = run.paired.skeleton
    found = [sk.index(n) for n in _NAMES]
    same = [scene.skeleton.index(n) for n in _NAMES]
    flipped = [scene.skeleton.index(_swap(n)) for n in _NAMES]
    return _crossed(np.asarray(run.paired.frame_ids), run.paired.real, run.paired.mirror,
                    scene, found, same, flipped)


def _crossed(t, real, mirror, scene, found, same, flipped) -> float:
    wrong = []
    for view, image in ((real, scene.real_image), (mirror, scene.mirror_image)):
        v = view[:, found, :2]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)         # unpaired frames
            d_same = np.nanmedian(np.linalg.norm(v - image[t][:, same], axis=-1), axis=1)
            d_cross = np.nanmedian(np.linalg.norm(v - image[t][:, flipped], axis=-1), axis=1)
        wrong.append(d_cross < d_same)
    both = (real[..., 2] > 0).any(1) & (mirror[..., 2] > 0).any(1)
    return float(np.mean((wrong[0] | wrong[1])[both])) if both.any() else float("nan")


def before_cell(raw, K, scene, code: str) -> dict:
    """The clip's detections calibrated by the code in ``code`` (another commit's tree, in
    a subprocess: ``bench_left_right_clip.run_before``), as :func:`errors` reports."""
    from bench_left_right_clip import run_before
    from mirrorgraph.metrics import normal_angle_deg, rotation_error_deg

    r = run_before([{"detections": raw, "intrinsics": K,
                     "options": {"subject_height": 1.75, "fps": 30.0}}], code)[0]
    if "error" in r:
        return {"error": r["error"]}
    sk = raw.skeleton
    found = [sk.index(n) for n in _NAMES]
    same = [scene.skeleton.index(n) for n in _NAMES]
    flipped = [scene.skeleton.index(_swap(n)) for n in _NAMES]
    return {"normal_deg": float(normal_angle_deg(r["normal"], scene.normal)),
            "rotation_deg": float(rotation_error_deg(r["R"], scene.virtual_R)),
            "rotation_std_deg": None if r["std"] is None else float(r["std"]),
            "distance_pct": (None if r["distance"] is None else
                             float(100 * (r["distance"] - scene.distance) / scene.distance)),
            "frames_paired": r["frames_paired"],
            "crossed_after": _crossed(r["frame_ids"], r["real"], r["mirror"], scene, found,
                                      same, flipped)}


def errors(run, scene) -> dict:
    from mirrorgraph.metrics import normal_angle_deg, rotation_error_deg

    c = run.calibration
    rot = rotation_error_deg(c.virtual_rotation, scene.virtual_R)
    std = c.uncertainty.get("rotation_std_deg")
    return {"normal_deg": float(normal_angle_deg(c.normal, scene.normal)),
            "rotation_deg": float(rot), "rotation_std_deg": None if std is None else float(std),
            "distance_pct": (None if c.distance is None else
                             float(100 * (c.distance - scene.distance) / scene.distance)),
            "frames_paired": int(c.frames_paired), "crossed_after": crossed_after(run, scene)}


def one_seed(seed: int, clip_frames: int, tmp: Path, uncross: bool = False,
             frame_left_right: bool = False, cache: Path | None = None,
             before_code: str | None = None) -> dict:
    from mirrorgraph.errors import MirrorgraphError
    from mirrorgraph.intrinsics import load_intrinsics
    from mirrorgraph.io import read_keypoints
    from mirrorgraph.pipelines.mirror import CalibrateOptions, calibrate
    from mirrorgraph.synth import make_scene, write_scene
    from mirrorgraph.synth.video import VISIBLE_FRACTION, reflection_visibility, write_scene_video
    from mirrorgraph.video.detect import VideoOptions, detect_video

    scene = make_scene(frames=1000, seed=seed, geometry="gym", outlier_rate=0.1,
                       lr_swap_rate=0.05, subject_height=1.75)
    folder = tmp / f"seed{seed}"
    paths = write_scene(scene, folder, formats=("mmpose",))
    clip, _ = write_scene_video(scene, folder / "clip.mp4", clip_frames)
    K = load_intrinsics(paths["camera"])
    row = {"seed": seed, "clip_frames": clip_frames,
           "visible": int((reflection_visibility(scene, clip_frames) >= VISIBLE_FRACTION).sum())}
    cached = None if cache is None else cache / f"seed{seed}_{clip_frames}.pkl"
    if cached is not None and cached.exists():
        raw = pickle.loads(cached.read_bytes())
    else:
        raw = detect_video(clip, VideoOptions(cache=False)).to_raw()
        if cached is not None:
            cached.parent.mkdir(parents=True, exist_ok=True)
            cached.write_bytes(pickle.dumps(raw))
    row["facing"] = facing_camera(scene, clip_frames)
    row["crossed"] = crossed_shares(scene, raw, clip_frames)
    keys = read_keypoints(paths["mmpose"])
    keys = dataclasses.replace(keys, frame_ids=keys.frame_ids[:clip_frames],
                               people=keys.people[:clip_frames])
    runs = [("clip", raw, "clip"), ("keypoints", keys, "clip")]
    if uncross:
        runs.append(("clip_uncrossed", uncrossed(scene, raw, clip_frames), "clip"))
    if frame_left_right:
        runs.append(("clip_frame", raw, "frame"))
    if before_code:
        row["clip_code_before"] = before_cell(raw, K, scene, before_code)
    for name, data, left_right in runs:
        opts = CalibrateOptions(subject_height=1.75, left_right=left_right)
        opts.fps = 30.0
        try:
            row[name] = errors(calibrate(data, K, opts), scene)
        except MirrorgraphError as exc:
            row[name] = {"error": str(exc).splitlines()[0][:80]}
    return row


def _cell(r: dict) -> list[str]:
    if "error" in r:
        return [f"refused: {r['error'].split('clip.mp4: ')[-1]}", "", "", "", "", "", ""]
    std = r["rotation_std_deg"]
    ratio = "" if not std else f"{r['rotation_deg'] / std:.1f}"
    dist = "" if r["distance_pct"] is None else f"{r['distance_pct']:+.1f}"
    crossed = r.get("crossed_after")
    return [f"{r['normal_deg']:.2f}", f"{r['rotation_deg']:.2f}",
            "" if std is None else f"{std:.2f}", ratio,
            "" if crossed is None else f"{100 * crossed:.0f}%", dist, str(r["frames_paired"])]


def table(rows: list[dict], before: dict[int, dict] | None = None) -> list[str]:
    before = before or {}
    cols = ["normal err (deg)", "rotation err (deg)", "rotation std (deg)", "err / std",
            "frames labelled crossed after", "distance err (%)", "frames paired"]
    head = ["seed", "reflection visible", "person faces the camera",
            "person labelled crossed", "reflection labelled crossed"]
    head += [f"clip, face always drawn: {c}" for c in cols[:5]] if before else []
    code_before = any("clip_code_before" in r for r in rows)
    head += [f"clip, another commit: {c}" for c in cols[:5]] if code_before else []
    frame = any("clip_frame" in r for r in rows)
    head += [f"clip, left/right each frame alone: {c}" for c in cols[:5]] if frame else []
    head += [f"clip: {c}" for c in cols]
    uncross = any("clip_uncrossed" in r for r in rows)
    head += [f"clip, left/right by the truth: {c}" for c in cols[:5]] if uncross else []
    head += [f"keypoints: {c}" for c in cols]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def share(pair):
        return "" if not pair[1] else f"{100 * pair[0]:.0f}% of {pair[1]}"

    for r in rows:
        cells = [str(r["seed"]), f"{r['visible']}/{r['clip_frames']}",
                 f"{100 * r['facing']:.0f}%", share(r["crossed"]["person"]),
                 share(r["crossed"]["reflection"])]
        if before:
            cells += _cell(before[r["seed"]]["clip"])[:5] if r["seed"] in before else [""] * 5
        if code_before:
            cells += (_cell(r["clip_code_before"])[:5] if "clip_code_before" in r
                      else [""] * 5)
        if frame:
            cells += _cell(r["clip_frame"])[:5] if "clip_frame" in r else [""] * 5
        cells += _cell(r["clip"])
        if uncross:
            cells += _cell(r["clip_uncrossed"])[:5] if "clip_uncrossed" in r else [""] * 5
        out.append("| " + " | ".join(cells + _cell(r["keypoints"])) + " |")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[3, 4, 6, 8])
    ap.add_argument("--clip-frames", type=int, default=150)
    ap.add_argument("--uncross", action="store_true",
                    help="also calibrate the clip's detections with left and right put the "
                         "right way round by the truth")
    ap.add_argument("--frame-left-right", action="store_true",
                    help="also calibrate the clip's detections with left/right decided for "
                         "each frame alone (left_right='frame') beside the whole clip's")
    ap.add_argument("--cache", metavar="DIR",
                    help="keep BlazePose's detections of each seed's clip in DIR and read "
                         "them from there on the next run")
    ap.add_argument("--before-code", metavar="DIR",
                    help="also calibrate the clip's detections with the code of another "
                         "commit's tree (e.g. git archive <commit> | tar -x -C DIR)")
    ap.add_argument("--json", metavar="FILE", help="save the rows")
    ap.add_argument("--rows", metavar="FILE", help="write the report from saved rows")
    ap.add_argument("--before", metavar="FILE",
                    help="saved rows of another commit, whose clip columns stand beside")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    rows = json.loads(Path(args.rows).read_text()) if args.rows else []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in [] if args.rows else args.seeds:
            rows.append(one_seed(seed, args.clip_frames, Path(tmp), args.uncross,
                                 args.frame_left_right,
                                 Path(args.cache) if args.cache else None,
                                 args.before_code))
            print(json.dumps(rows[-1]), flush=True)
    before = ({r["seed"]: r for r in json.loads(Path(args.before).read_text())}
              if args.before else None)
    lines = table(rows, before)
    print("\n".join(lines))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    if not args.no_write:
        from _report import header
        text = ["# The synthetic clip through the video path vs the keypoint file "
                "(`bench/bench_synth_clip.py`)", "", *header(code=True), "", *lines, ""]
        (ROOT / "bench" / "RESULTS_synth_clip.md").write_text("\n".join(text))


if __name__ == "__main__":
    main()
