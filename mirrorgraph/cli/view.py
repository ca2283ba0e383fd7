"""The ``view`` command: a calibration in Rerun's viewer (cameras, mirrors, the 3D motion
and its reflection, the video with its keypoints and epipolar lines), or saved as an
``.rrd`` recording; and ``--view`` of ``calibrate`` / ``calibrate-rig``: a thin layer
over :mod:`mirrorgraph.viewer` (the ``view`` extra).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from ..errors import InputError
from .args import add_common, positive, printer, warn
from .commands import HELP

__all__ = ["add_parsers", "add_view_option", "cmd_view", "check_view_option", "view_after_run"]


def add_parsers(sub) -> None:
    """Add ``view`` to the CLI's subparsers."""
    from ..viewer.recording import INSTALL_HINT

    p = sub.add_parser("view", help=HELP["view"],
                       description="Open a calibration in Rerun's viewer: the real and virtual "
                                   "cameras, the mirror(s), the 3D skeleton over time with its "
                                   "reflection, and with --video the frames with the keypoints "
                                   f"and epipolar lines. Needs the Rerun SDK: {INSTALL_HINT}.")
    p.add_argument("calibration", help="calibration.json of one mirror, or a rig's "
                                       "calibration.toml / JSON from calibrate-rig")
    p.add_argument("--joints3d", metavar="FILE",
                   help="the .npz that --joints3d wrote (default for one mirror: the joints "
                        "kept beside the calibration, c.report.npz)")
    p.add_argument("--video", metavar="FILE",
                   help="the video the keypoints come from (one mirror): frames, keypoints "
                        "and epipolar lines under the camera's image plane")
    p.add_argument("--save", metavar="OUT.rrd",
                   help="write the recording to OUT.rrd instead of opening the viewer "
                        "(open it later with: rerun OUT.rrd)")
    p.add_argument("--fps", type=positive, default=None,
                   help="frame rate of the 'time' timeline (default: the joints file's)")
    p.add_argument("--max-video-frames", type=lambda t: int(positive(t)), default=300,
                   metavar="N", help="at most N video frames, evenly spaced (default 300)")
    add_common(p)
    p.set_defaults(func=cmd_view)


def _check_save(path) -> None:
    if path and Path(path).suffix.lower() != ".rrd":
        raise InputError("must end in .rrd (a Rerun recording)", source=path, field="--save")


def cmd_view(args) -> int:
    from ..viewer.files import view_file

    from ..io.atomic import check_outputs

    _check_save(args.save)
    check_outputs([(args.save, "--save")],
                  inputs=[args.calibration, args.joints3d, args.video])
    out = view_file(args.calibration, joints3d=args.joints3d, video=args.video, save=args.save,
                    fps=args.fps, max_video_frames=args.max_video_frames)
    printer(args)(_written(out, args.save))
    return 0


def _written(out, save) -> str:
    if save:
        return f"wrote {out} (open it with: rerun {out})"
    return f"opened Rerun's viewer on {out}"


def add_view_option(p) -> None:
    """``--view [OUT.rrd]`` of ``calibrate`` and ``calibrate-rig``."""
    p.add_argument("--view", nargs="?", const="", default=None, metavar="OUT.rrd",
                   help="afterwards open the result in Rerun's viewer, or with a file name "
                        "write that recording instead (needs the view extra)")


def has_display() -> bool:
    """Whether a window can open: anywhere but on Linux without ``DISPLAY`` or
    ``WAYLAND_DISPLAY``."""
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY")
                                                        or os.environ.get("WAYLAND_DISPLAY"))


def check_view_option(args) -> None:
    """Fail before the long run: a bad ``--view`` file name, the Rerun SDK missing, or
    the viewer asked for where no window can open (``--view OUT.rrd`` is the way)."""
    if args.view is None:
        return
    if args.view:
        if Path(args.view).suffix.lower() != ".rrd":
            raise InputError("must end in .rrd (a Rerun recording)", source=args.view,
                             field="--view")
    from ..viewer.recording import require_rerun
    require_rerun()
    if not args.view and not has_display():
        raise InputError("Rerun's viewer needs a display (neither DISPLAY nor WAYLAND_DISPLAY "
                         "is set): give --view OUT.rrd to write the recording instead, and "
                         "open it where there is a display with 'rerun OUT.rrd'",
                         field="--view")


def view_after_run(args, scene, video=None) -> str | None:
    """Record ``scene`` as ``--view`` asks; returns the line naming what was written.

    A viewer that does not open after the run (the calibration and its files are
    written by then) is a warning naming the recording, not an error."""
    from ..viewer.recording import record

    try:
        out = record(scene, save=args.view or None, video=video)
    except InputError as exc:
        if args.view:
            raise
        warn(args, [f"{exc.reason}; or give --view OUT.rrd to write the recording"
                    .replace(", or write it to a file instead", "")])
        return None
    return _written(out, args.view)
