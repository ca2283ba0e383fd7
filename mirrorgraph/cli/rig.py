"""The commands of rigs: ``calibrate-rig`` calibrates every camera and mirror of a
rig file from the people in view (Pose2Sim's ``calibration.toml``, a JSON with the
mirrors, uncertainties and residuals, and on request the 3D joints and figures),
``synth-rig`` writes a synthetic rig with its ground truth: a thin layer over
:mod:`mirrorgraph.rigs` and :func:`mirrorgraph.synth.make_rig`.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ..errors import FailedCameraError, InputError
from ..intrinsics import DEFAULT_FOV_DEG
from ..rigs.config import OFFSET_WINDOW
from ..progress import Progress, SolveProgress
from ..report.backend import INSTALL_HINT
from ..skeletons import SKELETONS
from ..synth.rig import KINDS
from ..synth.rig_files import KEYPOINT_FORMATS
from ..synth.rig_placement import DEFAULT_RIG_GEOMETRY, RIG_PRESETS
from .args import (add_common, add_height_sigma, add_keypoint_offset, add_scale_from, height,
                   positive, print_result, printer, rate, seed, stated_gauge)
from .commands import HELP
from .video import add_video_options, video_options
from .view import add_view_option, check_view_option, view_after_run

__all__ = ["add_parsers", "cmd_calibrate_rig", "cmd_synth_rig", "EXIT_FAILED_CAMERA"]

#: Exit status of ``calibrate-rig --keep-failed`` when a camera failed (the others written).
EXIT_FAILED_CAMERA = 3


def add_parsers(sub) -> None:
    """Add ``calibrate-rig`` and ``synth-rig`` to the CLI's subparsers."""
    p = sub.add_parser(
        "calibrate-rig", help=HELP["calibrate-rig"],
        description="Calibrate every camera and mirror of a rig (cameras synchronised frame "
                    "by frame) from a pose detector's keypoints: Pose2Sim's 'calibrate from "
                    "keypoints'. The first camera of RIG.toml defines the world frame.")
    p.add_argument("rig", help="rig TOML file (cameras, their keypoints and intrinsics, mirrors)")
    p.add_argument("--out", required=True, help="Pose2Sim calibration.toml to write")
    p.add_argument("--json", metavar="FILE",
                   help="also write the JSON with mirrors, uncertainties and residuals "
                        "(default: OUT with .json)")
    p.add_argument("--with-virtual", action="store_true",
                   help="add each mirror's virtual camera per camera to the TOML "
                        "(flipped-image convention)")
    p.add_argument("--subject-height", type=height, metavar="METRES",
                   help="subject's height in metres, e.g. 1.75 (overrides the rig file's "
                        "subject_height)")
    add_scale_from(p)
    add_keypoint_offset(p)
    add_height_sigma(p)
    p.add_argument("--skeleton", help="keypoint layout for cameras whose table names none "
                                      f"({', '.join(SKELETONS)})")
    p.add_argument("--joints", metavar="SET",
                   help="joints to calibrate from: auto (default: every keypoint in direct "
                        "views, limbs through mirrors), limbs (no face, hands or feet), all, "
                        "or comma-separated names; overrides the rig file's joints")
    p.add_argument("--people", choices=("one", "all"), default=None,
                   help="one (default): the person seen longest; all: every person in view, "
                        "associated across the cameras with the rig found from that one, each "
                        "with their own joints and bones in the one graph (--joints3d: .npz "
                        "with a person axis, else one file a person)")
    p.add_argument("--joints3d", metavar="FILE",
                   help="write the 3D joints (world frame): .npz, .csv, or in metres (needs a "
                        "subject height) .trc, .c3d or .bvh")
    p.add_argument("--fps", type=positive, default=None, help="frame rate for --joints3d")
    p.add_argument("--report", metavar="DIR",
                   help="write figures (top view of the rig and every person, residuals "
                        "per view and keypoints kept per camera, per person) into DIR "
                        f"(needs matplotlib: {INSTALL_HINT})")
    p.add_argument("--seed", type=seed, default=0, help="seed of the RANSACs (default 0)")
    p.add_argument("--fov", type=positive, default=None, metavar="DEG",
                   help="cameras without intrinsics: a horizontal field of view you know "
                        "roughly: their focal length is held near it (a 10%% prior, in every "
                        "std) instead of estimated from the people (as calibrate's --fov)")
    p.add_argument("--no-focal", action="store_true",
                   help=f"the same as --fov {DEFAULT_FOV_DEG:g} (kept for scripts that use it)")
    p.add_argument("--fixed-offsets", action="store_true",
                   help="take every camera's frame_offset in the rig file as given (default: "
                        "each camera's time offset is found from the people, to a fraction of "
                        "a frame, about the rig file's frame_offset)")
    p.add_argument("--offset-window", type=lambda t: int(positive(t)), default=OFFSET_WINDOW,
                   metavar="FRAMES",
                   help=f"frames searched either way of a camera's frame_offset (default "
                        f"{OFFSET_WINDOW})")
    p.add_argument("--keep-failed", action="store_true",
                   help="a camera that fits under half of its keypoints fails the run (nothing "
                        "written, exit 2); with this flag the other cameras are written, the "
                        "failed one marked status \"failed\" in the JSON and left out of the "
                        f"TOML, and the exit status is {EXIT_FAILED_CAMERA}")
    add_view_option(p)
    add_video_options(p)
    add_common(p)
    p.set_defaults(func=cmd_calibrate_rig)

    s = sub.add_parser("synth-rig", help=HELP["synth-rig"],
                       description="Write a synthetic multi-camera / multi-mirror rig: per-camera "
                                   "keypoints, Calib.toml (intrinsics), rig.toml, ground truth.")
    s.add_argument("kind", choices=KINDS)
    s.add_argument("--out", required=True, help="folder to write")
    s.add_argument("--frames", type=lambda t: int(positive(t)), default=300)
    s.add_argument("--noise", type=positive, default=4.0, help="pixel noise std (default 4)")
    s.add_argument("--outliers", type=rate, default=0.0, help="fraction of gross errors")
    s.add_argument("--seed", type=seed, default=0)
    s.add_argument("--bystanders", type=seed, default=0, help="other people near the subject")
    s.add_argument("--geometry", default=DEFAULT_RIG_GEOMETRY, choices=tuple(RIG_PRESETS),
                   help="camera-to-mirror distances and focal lengths: favourable (default, the "
                        "rigs of earlier versions), gym (3-8.5 m, focal drawn per camera) or wide "
                        "(2.5-10 m)")
    s.add_argument("--skeleton", default="BODY_25")
    s.add_argument("--format", dest="fmt", default="openpose",
                   choices=KEYPOINT_FORMATS)
    s.add_argument("--no-height", action="store_true",
                   help="leave subject_height out of rig.toml")
    add_common(s)
    s.set_defaults(func=cmd_synth_rig)


def cmd_calibrate_rig(args) -> int:
    from ..io.atomic import check_outputs, staged_outputs
    from ..io.motion import check_motion_path, write_joints3d
    from ..export import write_rig_toml
    from ..result.rig import write_rig_json
    from ..graph.options import RefineOptions
    from ..pipelines.options import CalibrateOptions
    from ..pipelines.rig import calibrate_rig

    out = Path(args.out)
    if out.is_dir():
        raise InputError("is a folder; give a file name for calibration.toml", source=out,
                         field="--out")
    if out.suffix.lower() != ".toml":
        raise InputError("must end in .toml (Pose2Sim's calibration file)", source=out,
                         field="--out")
    if args.joints3d:
        check_motion_path(args.joints3d, metric=None)   # the scale is known after the solve
    json_path = Path(args.json) if args.json else out.with_suffix(".json")
    check_view_option(args)
    if args.report:
        from ..report import require_matplotlib
        require_matplotlib()          # fail before the long run, with the install hint
    say = printer(args)
    t0 = time.perf_counter()
    from ..rigs.config import load_rig_config
    from ..video.reader import is_video
    config = load_rig_config(args.rig)
    # every output before any work: a failed run leaves the user's files as they were
    inputs = [args.rig] + [c.keypoints for c in config.cameras] + \
        [getattr(c, "intrinsics", None) for c in config.cameras]
    check_outputs([(out, "--out"), (json_path, "--json"), (args.joints3d, "--joints3d"),
                   (args.view or None, "--view"), (args.report, "--report")],
                  inputs=[i for i in inputs if isinstance(i, (str, Path))],
                  folders=("--report",))
    vopts = video_options(args, has_video=any(is_video(c.keypoints) for c in config.cameras))
    bars: dict[str, Progress] = {}

    def frame_progress(camera: str, done: int, total: int) -> None:
        if camera not in bars:
            for b in bars.values():
                b.close()
            bars[camera] = Progress(f"detecting {camera}", enabled=not args.quiet)
        bars[camera].callback(done, total)

    with Progress("solving the rig", enabled=not args.quiet) as bar:
        solve = SolveProgress(bar)

        def status(text: str) -> None:        # a status line ends the open progress line
            if bar.started:
                bar.close(solve.info or None)
            if args.verbose and not args.quiet:
                print(f"... {text}", file=sys.stderr)
        def status_and_bars(text: str) -> None:
            for b in bars.values():
                b.close()
            status(text)
        held = args.fov is not None or args.no_focal      # the focal length near a guess
        opts = CalibrateOptions(subject_height=args.subject_height, skeleton=args.skeleton,
                                joints=args.joints, seed=args.seed, detection=vopts,
                                refine_options=RefineOptions(scale_from=args.scale_from,
                                                             **stated_gauge(args)),
                                estimate_focal=not held, people=args.people,
                                fov_deg=args.fov if args.fov is not None else DEFAULT_FOV_DEG,
                                time_offsets="fixed" if args.fixed_offsets else "search",
                                offset_window=args.offset_window)
        try:
            calib = calibrate_rig(config, opts, progress=status_and_bars,
                                  iteration_progress=solve, frame_progress=frame_progress,
                                  keep_failed=args.keep_failed)
        except FailedCameraError as exc:
            raise FailedCameraError(f"{exc} (nothing written; --keep-failed writes the other "
                                    "cameras)", calibration=exc.calibration,
                                    cameras=exc.cameras) from None
        for b in bars.values():
            b.close()
        bar.close(solve.info or None)
    if args.joints3d:
        check_motion_path(args.joints3d, metric=calib.scale == "subject_height")
    scene = None
    if args.view is not None:
        from ..viewer.scene import scene_from_rig
        scene = scene_from_rig(calib, fps=args.fps)
    written = view_line = None
    with staged_outputs() as stage:              # every file moves into place at the end
        write_rig_toml(calib, out, with_virtual=args.with_virtual)
        write_rig_json(calib, json_path)
        if args.joints3d:
            from ..skeletons import skeleton_by_name
            unit = "m" if calib.scale == "subject_height" else "subject height"
            names = skeleton_by_name(calib.skeleton).joints
            if calib.people_joints3d is not None:       # every person: a person axis
                from ..io.people_motion import write_people_joints3d
                write_people_joints3d(args.joints3d, calib.people_joints3d, calib.people_valid,
                                      calib.frame_ids, names, args.fps or 30.0, unit=unit)
            else:
                write_joints3d(args.joints3d, calib.joints3d, calib.valid, calib.frame_ids,
                               names, args.fps or 30.0, unit=unit, joints_std=calib.joints_std)
        if args.report:
            from ..report.rig import write_rig_report
            written = write_rig_report(calib, stage.folder(args.report),
                                       progress_bar=not args.quiet)
        if args.view:                            # a recording to a file: one more output
            view_line = view_after_run(args, scene)
    failed_lines = {f"camera {c.name} failed: {c.reason}" for c in calib.failed_cameras}
    print_result(args, calib.summary(), [w for w in calib.warnings if w not in failed_lines])
    if view_line:
        say(view_line)
    if written is not None:
        say(f"wrote {len(written)} figure{'s' * (len(written) != 1)} to {args.report}")
    say(f"wrote {out} and {json_path} in {time.perf_counter() - t0:.2f} s")
    if args.view == "":                          # the viewer, once the files are in place
        view_line = view_after_run(args, scene)
        if view_line:
            say(view_line)
    if calib.failed_cameras:                     # one line each, whatever --quiet says
        for c in calib.failed_cameras:
            print(f"error: camera {c.name} failed (marked in {json_path}, left out of {out}): "
                  f"{c.reason}", file=sys.stderr)
        return EXIT_FAILED_CAMERA
    return 0


def cmd_synth_rig(args) -> int:
    from ..synth.rig import make_rig, write_rig

    rig = make_rig(args.kind, frames=args.frames, seed=args.seed, noise_std=args.noise,
                   outlier_rate=args.outliers, skeleton=args.skeleton,
                   bystanders=args.bystanders, geometry=args.geometry)
    path = write_rig(rig, args.out, args.fmt, include_height=not args.no_height)
    if not args.quiet:
        print(f"wrote a {args.frames}-frame {args.kind} rig to {args.out}: {path.name}, "
              "Calib.toml (intrinsics), pose/, ground_truth.json")
    return 0
