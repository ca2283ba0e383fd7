"""The ``live`` command: calibrate while the video streams, 3D joints frame by frame, one
JSON line per frame (a thin layer over :mod:`mirrorgraph.live`).

    mirrorgraph live 0 --image-size 1280x720 --subject-height 1.75 --jsonl out.jsonl
    mirrorgraph live clip.mp4 --intrinsics camera.json --jsonl out.jsonl --view
    mirrorgraph live keypoints.json --intrinsics camera.json --jsonl out.jsonl \\
        --as-fast-as-possible
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import InputError
from ..initial.estimators import DEFAULT_THRESHOLD_PX
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from ..progress import Progress
from .args import (add_common, add_height_sigma, add_joints, add_keypoint_offset, height,
                   image_size, positive, printer, rate, seed, stated_gauge, warn)
from .commands import HELP

__all__ = ["add_parsers", "cmd_live"]


def _lag(text: str) -> int:
    """A lag in frames: a whole number, 0 or more."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number of frames, got {text!r}") \
            from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more frames, got {value}")
    return value


def add_parsers(sub) -> None:
    """Add ``live`` to the CLI's subparsers."""
    p = sub.add_parser(
        "live", help=HELP["live"],
        description="Calibrate the mirror while the frames arrive and write each frame's 3D "
                    "joints and the current mirror as one JSON line (NaN as null). SOURCE: a "
                    "camera index (0), a video file (played at its frame rate; BlazePose, the "
                    "video extra) or any keypoint input calibrate reads (replayed frame by "
                    "frame).")
    p.add_argument("source", help="camera index, video file, or keypoints (MMPose .json, "
                                  "OpenPose / EasyMocap folder, paired .npz)")
    p.add_argument("--jsonl", required=True, metavar="OUT.jsonl",
                   help="JSON-lines file: one line per frame, written as the frames arrive "
                        "(an existing file is replaced; after Ctrl-C it holds every frame "
                        "done, each line complete); '-' writes to standard output")
    p.add_argument("--intrinsics", help="camera intrinsics (as calibrate reads them)")
    p.add_argument("--camera", metavar="NAME",
                   help="camera (section or name) to read from a TOML with several cameras")
    p.add_argument("--image-size", type=image_size, metavar="WxH",
                   help="image size when no intrinsics are given and the source lacks it "
                        "(the focal length is then estimated from the person)")
    p.add_argument("--subject-height", type=height, metavar="METRES",
                   help="subject's standing height in metres: lengths in metres")
    add_keypoint_offset(p)
    add_height_sigma(p)
    p.add_argument("--as-fast-as-possible", action="store_true",
                   help="process a video or keypoint file flat out instead of at its frame rate")
    p.add_argument("--fps", type=positive, default=None,
                   help="frame rate of a keypoint input that carries none (default 30): "
                        "the frame times, and the rate the joints' acceleration prior (stated at 30 fps) "
                        "is taken at")
    p.add_argument("--skeleton", help="keypoint layout when the count is ambiguous")
    p.add_argument("--window", type=lambda t: int(positive(t)), default=900, metavar="N",
                   help="most frames in a window of the mirror's solve (default 900)")
    p.add_argument("--lag", type=_lag, default=None, metavar="FRAMES",
                   help="write each frame's line this many frames after it came, its joints "
                        "solved again with the frames after it: the joints pass's graph over "
                        "the last 20 frames, solved every 5th frame in this thread, else the "
                        "fixed-lag smoother (default 9: 0.30 s at 30 fps; below 4 the graph "
                        "sees fewer frames ahead); 0: each line as its frame comes, filtered "
                        "with the frames before")
    p.add_argument("--window-graph", type=_lag, default=None, metavar="FRAMES",
                   help="frames of the joints pass's graph that solves each line's joints "
                        "again (default 20; 0: the fixed-lag smoother alone)")
    p.add_argument("--calibrated-std", type=positive, default=2.0, metavar="DEG",
                   help="rotation std at which the status becomes 'calibrated' (default 2)")
    solve = p.add_mutually_exclusive_group()
    solve.add_argument("--inline", action="store_true",
                       help="solve the mirror's windows between frames, in this process "
                            "(every line the same from run to run; a file only); by default a "
                            "worker process solves them while the frames flow")
    solve.add_argument("--background", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--threshold", type=positive, default=DEFAULT_THRESHOLD_PX, metavar="PX",
                   help=f"inlier threshold in pixels (default {DEFAULT_THRESHOLD_PX:g})")
    p.add_argument("--min-confidence", type=rate, default=DEFAULT_MIN_CONFIDENCE,
                   help=f"ignore joints below this confidence (default {DEFAULT_MIN_CONFIDENCE:g})")
    add_joints(p)
    p.add_argument("--seed", type=seed, default=0, help="seed of the RANSAC (default 0)")
    p.add_argument("--view", nargs="?", const="", default=None, metavar="OUT.rrd",
                   help="stream to Rerun's live viewer, or with a file name record the stream "
                        "to that .rrd (needs the view extra)")
    add_common(p)
    p.set_defaults(func=cmd_live)


def cmd_live(args) -> int:
    import sys

    from ..io.atomic import check_outputs
    from ..live.calibrator import start_worker, stop_started_workers
    from ..live.sources import is_camera
    from ..live.stream import check_view

    to_stdout = args.jsonl == "-"
    # the summary goes where the JSON lines do not
    say = printer(args) if not to_stdout else \
        (lambda *a, **k: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    if args.camera and not args.intrinsics:
        raise InputError("needs --intrinsics FILE.toml", field="--camera")
    check_view(args.view)
    camera = is_camera(args.source)
    if not camera and not Path(args.source).exists():
        raise InputError("no such file or folder (nor a camera index)", source=args.source)
    check_outputs([(args.jsonl, "--jsonl"), (args.view or None, "--view")],
                  inputs=[None if camera else args.source, args.intrinsics],
                  stdout_ok=("--jsonl",))
    if not args.inline:
        start_worker()              # the worker's start overlaps the input's reading
    try:
        return _run(args, say, camera, to_stdout)
    finally:
        stop_started_workers()      # one the run did not take (it stopped before)


def _run(args, say, camera: bool, to_stdout: bool) -> int:
    """``cmd_live`` once its arguments and outputs are checked."""
    import sys

    from ..intrinsics import load_intrinsics
    from ..live import LiveOptions
    from ..live.sources import open_source
    from ..live.stream import run_live
    from ..graph.options import RefineOptions
    from ..pipelines.options import CalibrateOptions

    intr = load_intrinsics(args.intrinsics, camera=args.camera) if args.intrinsics else None
    source = open_source(args.source, skeleton=args.skeleton, fps=args.fps,
                         realtime=not args.as_fast_as_possible)
    if intr is None and args.image_size is None and source.image_size is None:
        raise InputError("no intrinsics and no image size: give --intrinsics FILE or "
                         "--image-size WxH", source=source.name, field="--image-size")
    copts = CalibrateOptions(min_confidence=args.min_confidence, threshold_px=args.threshold,
                             seed=args.seed, image_size=args.image_size,
                             subject_height=args.subject_height,
                             refine_options=(RefineOptions(**stated_gauge(args))
                                             if stated_gauge(args) else None),
                             joints=tuple(j.strip() for j in args.joints.split(","))
                             if args.joints else None)
    realtime = camera or not args.as_fast_as_possible
    if args.inline and realtime:
        raise InputError("a source played at its frame rate cannot wait for a solve: give "
                         "--as-fast-as-possible with a file", field="--inline")
    opts = LiveOptions(calibrate=copts, window_frames=args.window,
                       calibrated_std_deg=args.calibrated_std, background=not args.inline,
                       can_wait=not realtime,
                       **({} if args.lag is None else {"lag_frames": args.lag}),
                       **({} if args.window_graph is None
                          else {"window_graph_frames": args.window_graph}))
    with Progress(f"live from {source.name}", total=source.total,
                  enabled=not args.quiet) as bar:
        def on_frame(frame) -> None:
            m = frame.mirror
            info = m.status if m.rotation_std_deg is None else \
                f"{m.status}, std {m.rotation_std_deg:.2f} deg"
            bar.update(info=info)
        summary = run_live(source, intr, opts, args.jsonl, view=args.view, on_frame=on_frame)
    where = "standard output" if to_stdout else args.jsonl
    say(summary.describe())
    if summary.interrupted:
        print(f"interrupted after {summary.lines} frames: {where} holds their "
              f"{summary.lines} lines, each complete", file=sys.stderr)
        return 130
    say(f"wrote {summary.lines} lines to {where}")
    if summary.no_mirror is None and summary.mirror.normal is not None and summary.lines \
            and summary.counts["unpaired"] + summary.counts["skipped"] >= summary.lines:
        late = ("; replay the file with --as-fast-as-possible: every frame after the first "
                "window then has its joints") if not camera else ""
        warn(args, [f"the mirror came after the last frame (the first window's solve "
                    f"outlasted the stream): no line of {where} holds 3D joints{late}"])
    if summary.no_mirror is not None:
        raise InputError(f"no mirror found: {summary.no_mirror}",
                         source=None if camera else args.source)
    return 0
