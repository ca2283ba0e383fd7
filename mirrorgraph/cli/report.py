"""The commands that read a calibration: ``report`` draws its figures (and video
overlays) from the run kept beside it or from its keypoints calibrated again
(:mod:`mirrorgraph.report`), ``export`` writes its real and virtual camera for
Pose2Sim or aniposelib (:mod:`mirrorgraph.export`).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from ..export import FORMATS, WORLD_FRAMES
from .args import (add_common, printer, report_written, solver_progress, staged_names, step,
                   warn)
from .commands import HELP

__all__ = ["add_parsers", "check_schema", "cmd_export", "cmd_report"]


def add_parsers(sub) -> None:
    """Add ``export`` and ``report`` to the CLI's subparsers."""
    _add_export(sub)
    _add_report(sub)


# --------------------------------------------------------------------------- report
def _add_report(sub) -> None:
    p = sub.add_parser("report", help=HELP["report"],
                       description="Write PNG figures of a calibration and, with --video, "
                                   "overlays on the video (needs the plot extra). The figures "
                                   "are those of 'calibrate --report': drawn from the run "
                                   "'calibrate' kept beside the calibration (CALIBRATION with "
                                   ".report.npz), or, without it, from the keypoints calibrated "
                                   "again with the options the calibration records.")
    p.add_argument("calibration", help="calibration.json written by 'mirrorgraph calibrate', or "
                                       "a rig's JSON written by 'calibrate-rig'")
    p.add_argument("keypoints", nargs="?", default=None,
                   help="the keypoints the calibration was made from (read only without a "
                        "usable .report.npz beside the calibration, or with --recompute; "
                        "default: the input calibration.json records)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder to write the figures into")
    p.add_argument("--recompute", action="store_true",
                   help="calibrate the keypoints again even where the run is stored (the "
                        "ones given, else the input calibration.json records)")
    p.add_argument("--skeleton", help="keypoint layout when the count is ambiguous")
    p.add_argument("--video", metavar="FILE",
                   help="draw joints, reflections and epipolar lines on sampled frames")
    p.add_argument("--render", metavar="OUT.mp4",
                   help="write the whole overlay video (needs --video): .mp4 (H.264 where "
                        "OpenCV has it, else mp4v, which browsers do not play) or .webm (VP9)")
    p.add_argument("--frames", type=int, default=6, help="video frames to sample (default 6)")
    add_common(p)
    p.set_defaults(func=cmd_report)


def check_schema(path) -> dict:
    """The calibration JSON at ``path``, parsed, if this version reads its schema
    (:func:`mirrorgraph.io.calibration.read_calibration_document`)."""
    from ..io.calibration import read_calibration_document
    from ..result.mirror import SCHEMA_VERSION

    return read_calibration_document(path, SCHEMA_VERSION)


def _rig_document(path):
    """The rig JSON at ``path`` as a :class:`~mirrorgraph.result.rig.RigCalibration`, or
    ``None`` where it is a single mirror's ``calibration.json``."""
    from ..result.rig import is_rig_document, read_rig_calibration

    return read_rig_calibration(path) if is_rig_document(check_schema(path)) else None


def cmd_report(args) -> int:
    from ..io.atomic import check_outputs, staged_outputs
    from ..report import load_run, make_report, require_matplotlib
    from .video import check_video

    require_matplotlib()
    rig = _rig_document(args.calibration)
    check_outputs([(args.out, "--out"), (args.render, "--render")],
                  inputs=[args.calibration, args.keypoints, args.video], folders=("--out",))
    if rig is not None:             # a rig's JSON: its figures (the JSON holds no 3D joints)
        from ..report.rig import write_rig_report

        if args.keypoints or args.video or args.render or args.recompute:
            raise InputError("a rig's report is drawn from its JSON alone: no keypoints, "
                             "--video, --render or --recompute", field="calibration")
        with staged_outputs() as stage:
            out = write_rig_report(rig, stage.folder(args.out), progress_bar=not args.quiet)
        printer(args)(report_written({p.stem: p for p in out}, args.out))
        return 0
    if args.render and not args.video:
        raise InputError("needs --video FILE to draw on", field="--render")
    if args.render and Path(args.render).suffix.lower() not in (".mp4", ".webm"):
        raise InputError("must end in .mp4 or .webm", source=args.render, field="--render")
    if args.frames < 1:
        raise InputError(f"must be a positive number of frames, got {args.frames}",
                         field="--frames")
    if args.video:
        check_video(args.video, "--video")
    say = printer(args)
    with solver_progress(args) as callbacks:
        loaded = load_run(args.calibration, args.keypoints,
                          report_data=None if args.recompute else "auto",
                          skeleton=args.skeleton, **callbacks)
    warn(args, loaded.warnings)
    note = ""
    if loaded.origin == "stored" and args.keypoints is not None:
        note = f" ({args.keypoints} not read; --recompute calibrates it again)"
    say(loaded.message + note)
    with staged_outputs() as stage:              # every file moves into place at the end
        out = make_report(loaded.run, stage.folder(args.out), video=args.video,
                          render=stage.file(args.render) if args.render else None,
                          max_frames=args.frames, progress=lambda s: step(args, s),
                          progress_bar=not args.quiet,
                          warn=lambda line: warn(args, [stage.as_targets(line)]))
    say(report_written(staged_names(out, args.out, args.render), args.out))
    return 0


# --------------------------------------------------------------------------- export
def _add_export(sub) -> None:
    p = sub.add_parser("export", help=HELP["export"],
                       description="Write the real camera and the mirror's virtual camera as two "
                                   "ordinary cameras of a Pose2Sim Calib.toml or an aniposelib "
                                   "calibration.toml. The virtual camera is the one that sees the "
                                   "horizontally flipped image (u -> W - u): give those tools the "
                                   "reflection's keypoints with x -> W - x and left/right labels "
                                   "swapped (docs/guide/exports.md).")
    p.add_argument("calibration", help="calibration.json written by 'mirrorgraph calibrate', or "
                                       "a rig's JSON written by 'calibrate-rig' (every camera "
                                       "and every view through a mirror)")
    # the file styles, without the API's alias "aniposelib"
    p.add_argument("--to", required=True, choices=tuple(dict.fromkeys(FORMATS.values())),
                   dest="fmt")
    p.add_argument("out", help="TOML file to write")
    p.add_argument("--world", default="camera", choices=tuple(WORLD_FRAMES),
                   help="world frame: the real camera's (default) or X right, Y depth, Z up")
    add_common(p)
    p.set_defaults(func=cmd_export)


def cmd_export(args) -> int:
    from ..export import camera_sections, export_calibration
    from ..io.atomic import check_output

    check_schema(args.calibration)
    check_output(args.out, field="out", inputs=[args.calibration])
    warnings = export_calibration(args.calibration, args.fmt, args.out, world=args.world)
    warn(args, warnings)
    if _rig_document(args.calibration) is not None:
        printer(args)(f"wrote {args.out} ({args.fmt}): every camera of the rig, then each "
                      "camera's view through a mirror as the camera of the flipped image (give "
                      "it the reflection's keypoints with x -> W - x and left/right swapped)")
        return 0
    (k_real, n_real), (k_mirror, n_mirror) = camera_sections(args.fmt)
    named = lambda key, name: f"[{key}]" + (f" '{name}'" if name != key else "")  # noqa: E731
    printer(args)(f"wrote {args.out} ({args.fmt}): {named(k_real, n_real)} the real camera, "
                  f"{named(k_mirror, n_mirror)} the mirror's virtual camera (flipped image: give "
                  "it the reflection's keypoints with x -> W - x and left/right swapped)")
    return 0
