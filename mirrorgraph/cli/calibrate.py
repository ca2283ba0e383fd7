"""The ``calibrate`` command: one mirror video's keypoints (or the video itself,
detected first, :mod:`.video`) to ``calibration.json``, with the run its report is
drawn from beside it (``c.report.npz``, :mod:`mirrorgraph.report.store`), and on
request the 3D joints (``--joints3d``) and the report's figures (``--report``): a
thin layer over :func:`mirrorgraph.calibrate`.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..initial.estimators import DEFAULT_THRESHOLD_PX, ESTIMATORS
from ..intrinsics import DEFAULT_FOV_DEG
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from ..preprocess import DEFAULT_FPS, DEFAULT_FPS_WARNING
from ..progress import Progress
from ..report.backend import INSTALL_HINT
from ..skeletons import SKELETONS
from .args import (add_common, add_height_sigma, add_joints, add_keypoint_offset,
                   add_scale_from, height, image_size, options_from_args, positive,
                   print_result, printer, rate, report_written, seed, solver_progress,
                   staged_names, step, warn)
from .commands import HELP
from .video import (add_video_options, check_video, describe, detect_with_progress,
                    video_options)
from .view import add_view_option, check_view_option, view_after_run

__all__ = ["add_parsers", "cmd_calibrate"]


def add_parsers(sub) -> None:
    """Add ``calibrate`` to the CLI's subparsers."""
    p = sub.add_parser("calibrate", help=HELP["calibrate"],
                       description="Calibrate the mirror's virtual camera from a pose "
                                   "detector's keypoints of a person and their reflection.")
    p.add_argument("keypoints", help="MMPose .json, OpenPose or EasyMocap folder, paired .npz, "
                                     "or a video file (detected, or read from the cache)")
    p.add_argument("--out", required=True, help="calibration JSON to write")
    p.add_argument("--intrinsics", help="camera intrinsics: JSON {K, image_size, dist}, "
                                        "OpenCV YAML (camera_matrix, distortion_coefficients), "
                                        "or a Pose2Sim / aniposelib calibration TOML")
    p.add_argument("--camera", metavar="NAME",
                   help="camera (section or name) to read from a TOML with several cameras")
    p.add_argument("--image-size", type=image_size, metavar="WxH",
                   help="image size when no intrinsics are given and the input lacks it; "
                        "the focal length and the principal point are then estimated from "
                        "the person and the reflection (square pixels; the principal point "
                        "about the image centre, with the spread of real cameras)")
    p.add_argument("--fov", type=positive, default=None, metavar="DEG",
                   help="without intrinsics: a horizontal field of view you know roughly: "
                        "the focal length is held near it (a 10%% prior, in every std) instead "
                        f"of estimated from the person (which starts from {DEFAULT_FOV_DEG:g})")
    p.add_argument("--principal-point", choices=("centre", "free"), default="centre",
                   help="without intrinsics: the principal point about the image centre "
                        "with the spread of real cameras, 1%% of the larger side (default), or "
                        "a loose prior, 5%% of the width (free: the person and the reflection "
                        "estimate it, well on some scenes, badly on others: "
                        "docs/guide/unknown-intrinsics.md)")
    p.add_argument("--no-lines", action="store_true",
                   help="without intrinsics, on a video: leave the scene's straight lines out "
                        "(by default their vanishing points are a second witness of the focal "
                        "length beside the person's, reported apart in focal_sources)")
    p.add_argument("--skeleton", help="keypoint layout when the count is ambiguous "
                                      f"({', '.join(SKELETONS)})")
    p.add_argument("--estimator", default="reflective", choices=ESTIMATORS,
                   help="initial estimator: ours (reflective, default), MirrorCalib's "
                        "Baseline1 (eightpoint) or its 6-unknown eight-point (reflective8)")
    p.add_argument("--threshold", type=positive, default=None, metavar="PX",
                   help="inlier threshold on the epipolar distance in pixels (default "
                        f"{DEFAULT_THRESHOLD_PX:g})")
    p.add_argument("--min-confidence", type=rate, default=DEFAULT_MIN_CONFIDENCE,
                   help="ignore joints below this detector confidence (default "
                        f"{DEFAULT_MIN_CONFIDENCE:g})")
    add_joints(p)
    p.add_argument("--subject-height", type=height, metavar="METRES",
                   help="subject's standing height in metres, e.g. 1.75: gives the metric scale")
    add_scale_from(p)
    add_keypoint_offset(p)
    add_height_sigma(p)
    p.add_argument("--people", choices=("one", "all"), default="one",
                   help="one: a person and their reflection a frame (default); all: every "
                        "person before the mirror paired with their own reflection and "
                        "tracked, each with their own joints and bones in the one graph "
                        "(--joints3d: .npz with a person axis, else one file a person)")
    p.add_argument("--height-of", type=_height_of, default="tallest", metavar="WHO",
                   help="with --people all: whose height --subject-height is: tallest "
                        "(default), first (the first person tracked) or a person's number")
    p.add_argument("--no-refine", action="store_true",
                   help="keep the robust initialisation, skip the factor graph")
    p.add_argument("--sensitivity", action="store_true",
                   help="also solve again with each body prior's weight halved and doubled "
                        "(calibration.json's sensitivity.prior_weights; eight calibrations more)")
    p.add_argument("--joints3d", metavar="FILE",
                   help="write the refined 3D joints: .npz (T, J, 3) with names and a validity "
                        "mask, .csv, or in metres (needs --subject-height) OpenSim .trc, C3D "
                        ".c3d or BVH .bvh")
    p.add_argument("--fps", type=positive, default=None,
                   help="frame rate of the 3D motion; the joints' acceleration prior, stated at "
                        "30 fps, is taken at it (default: the input's, else --video's, "
                        f"else {DEFAULT_FPS:g} with a warning)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the RANSAC (default 0)")
    p.add_argument("--report", metavar="DIR",
                   help="write the report's figures (PNG) into DIR (needs matplotlib: "
                        f"{INSTALL_HINT})")
    p.add_argument("--video", metavar="FILE",
                   help="the video the keypoints come from: its frame rate, its straight "
                        "lines where the focal length is estimated, and with --report the "
                        "overlay on sampled frames")
    p.add_argument("--render", metavar="OUT.mp4",
                   help="with --report and --video: write the whole overlay video")
    add_view_option(p)
    add_video_options(p)
    add_common(p)
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args) -> int:
    from ..intrinsics import load_intrinsics
    from ..io import read_keypoints
    from ..io._common import is_video_input
    from ..io.atomic import check_outputs, staged_outputs
    from ..io.motion import check_motion_path, write_joints3d
    from ..pipelines.mirror import calibrate
    from ..report.store import report_data_path, write_calibration_and_run

    say = printer(args)
    if Path(args.out).is_dir():
        raise InputError("is a folder; give a file name for the calibration JSON",
                         source=args.out, field="--out")
    if args.render and not (args.report and args.video):
        raise InputError("needs --report DIR and --video FILE", field="--render")
    if args.report:
        from ..report import require_matplotlib
        require_matplotlib()          # fail before the long run, with the install hint
    if args.video:
        check_video(args.video, "--video")
    if args.render and Path(args.render).suffix.lower() not in (".mp4", ".webm"):
        raise InputError("must end in .mp4 or .webm", source=args.render, field="--render")
    if args.joints3d and args.no_refine:
        raise InputError("needs the refinement: drop --no-refine", field="--joints3d")
    if args.joints3d:
        check_motion_path(args.joints3d, metric=bool(args.subject_height))
    if args.view is not None and args.no_refine:
        raise InputError("needs the refinement's 3D joints: drop --no-refine", field="--view")
    check_view_option(args)
    # every output before any work: a failed run leaves the user's files as they were
    check_outputs([(args.out, "--out"), (report_data_path(args.out), "--out"),
                   (args.joints3d, "--joints3d"), (args.view or None, "--view"),
                   (args.report, "--report"), (args.render, "--render")],
                  inputs=[args.keypoints, args.intrinsics, args.video],
                  folders=("--report",))
    if args.sensitivity and args.no_refine:
        raise InputError("needs the refinement: drop --no-refine", field="--sensitivity")
    if args.camera and not args.intrinsics:
        raise InputError("needs --intrinsics FILE.toml", field="--camera")
    if args.principal_point == "free" and (args.intrinsics or args.fov is not None
                                           or args.no_refine):
        raise InputError("estimates the principal point with the focal length: not with "
                         "--intrinsics, --fov or --no-refine", field="--principal-point")
    from_video = is_video_input(args.keypoints)
    vopts = video_options(args, has_video=from_video)
    if from_video:
        check_video(args.keypoints, "keypoints")
    intr = load_intrinsics(args.intrinsics, camera=args.camera) if args.intrinsics else None
    t0 = time.perf_counter()
    if from_video:
        det = detect_with_progress(args.keypoints, vopts, quiet=args.quiet)
        say(describe(det))
        data = det.to_raw()
        if args.video is None:
            args.video = args.keypoints          # its frame rate, and the report's overlay
    else:
        with Progress("reading frames", enabled=not args.quiet) as bar:
            data = read_keypoints(args.keypoints, skeleton=args.skeleton, progress=bar.callback)
    _verbose_input(args, data)
    opts = options_from_args(args)
    opts.fps, opts.video = args.fps, args.video           # the frame rate of the 3D motion
    people = None
    with solver_progress(args) as callbacks:
        if args.people == "all":
            from ..pipelines.people import calibrate_people
            people = calibrate_people(data, intr, opts, height_of=args.height_of,
                                      progress=callbacks["progress"])
            run = people.run
        else:
            run = calibrate(data, intr, opts, **callbacks)
    calib = run.calibration
    if args.joints3d and run.fps_source == "default":
        calib.warnings.append(DEFAULT_FPS_WARNING)
    if args.joints3d and run.joints3d is None:
        raise InputError("needs the refinement: drop --no-refine", field="--joints3d")
    scene = None
    if args.view is not None:
        from ..viewer.scene import scene_from_calibration
        scene = scene_from_calibration(calib, joints3d=run.joints3d, valid=run.valid3d,
                                       frame_ids=run.paired.frame_ids,
                                       joint_names=run.paired.skeleton.joints, fps=run.fps,
                                       keypoints=(run.paired.real, run.paired.mirror))
    report_line = view_line = None
    with staged_outputs() as stage:              # every file moves into place at the end
        write_calibration_and_run(args.out, run)     # with the run its report draws from
        if args.joints3d:
            unit = "m" if calib.distance is not None else "mirror distance"
            if people is not None:
                from ..io.people_motion import write_people_joints3d
                write_people_joints3d(args.joints3d, people.joints3d, people.valid3d,
                                      run.paired.frame_ids, people.pairing.base.joints,
                                      run.fps, unit=unit, joints_std=people.joints_std,
                                      joints_std_shape=(people.joints_std_shape
                                                        if unit == "m" else None),
                                      scale_rel_std=(people.scale_rel_std
                                                     if unit == "m" else None))
            else:
                write_joints3d(args.joints3d, run.joints3d, run.valid3d, run.paired.frame_ids,
                               run.paired.skeleton.joints, run.fps, unit=unit,
                               joints_std=run.joints_std,
                               joints_std_shape=(run.joints_std_shape if unit == "m"
                                                 else None),
                               scale_rel_std=run.scale_rel_std if unit == "m" else None)
        if args.report:
            from ..report import make_report
            written = make_report(run, stage.folder(args.report), video=args.video,
                                  render=stage.file(args.render) if args.render else None,
                                  progress=lambda s: step(args, s),
                                  progress_bar=not args.quiet,
                                  warn=lambda line: warn(args, [stage.as_targets(line)]))
            report_line = report_written(staged_names(written, args.report, args.render),
                                         args.report)
        if args.view:                            # a recording to a file: one more output
            view_line = view_after_run(args, scene, video=args.video)
    print_result(args, calib.summary(), calib.warnings)
    if args.verbose and not args.quiet:
        print("timings: " + ", ".join(f"{k} {v:.2f} s" for k, v in run.timings.items()),
              file=sys.stderr)
    if report_line:
        say(report_line)
    if view_line:
        say(view_line)
    files = " and ".join(str(f) for f in (args.out, args.joints3d) if f)
    say(f"wrote {files} in {time.perf_counter() - t0:.2f} s")
    if args.view == "":                          # the viewer, once the files are in place
        view_line = view_after_run(args, scene, video=args.video)
        if view_line:
            say(view_line)
    return 0


def _height_of(text: str):
    """``--height-of``: ``tallest``, ``first`` or a person's number."""
    import argparse
    if text in ("tallest", "first"):
        return text
    if text.isdigit():
        return int(text)
    raise argparse.ArgumentTypeError(f"must be tallest, first or a person's number, not "
                                     f"{text!r}")


def _verbose_input(args, data) -> None:
    if not getattr(args, "verbose", False):
        return
    from ..keypoints import RawDetections
    if isinstance(data, RawDetections):
        counts = np.bincount([len(p) for p in data.people])
        per = ", ".join(f"{n} people: {c}" for n, c in enumerate(counts) if c)
        print(f"input: {data.format}, skeleton {data.skeleton.name}, {len(data)} frames "
              f"({per})", file=sys.stderr)
    else:
        print(f"input: {data.format} (paired), skeleton {data.skeleton.name}, "
              f"{len(data)} frames", file=sys.stderr)
    notes = data.read_notes.summary()
    if notes:
        print(f"input: {notes}", file=sys.stderr)
