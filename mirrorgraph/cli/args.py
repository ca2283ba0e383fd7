"""What the commands of the command line share: the argument types (a positive
number, a rate in [0, 1], a seed, a human height in metres, an image size, a list
of numbers: each an argparse ``type`` whose error is one line), the options every
command has (``--quiet --verbose --debug``, :func:`add_common`), those of the
calibration several commands have (``--joints``, ``--scale-from``) and the
:class:`~mirrorgraph.pipelines.mirror.CalibrateOptions` of what ``calibrate`` and ``batch``
share (:func:`options_from_args`), and how a run speaks: the summary and its
warnings (:func:`print_result`), steps under ``--verbose``, the solver's progress
bars (:func:`solver_progress`).
"""

from __future__ import annotations

import argparse
import sys
from contextlib import contextmanager

import numpy as np

from ..anthropometry import height_problem
from ..errors import InputError
from ..progress import Progress, SolveProgress

__all__ = ["FLAGS", "add_common", "add_height_sigma", "add_joints", "add_keypoint_offset",
           "add_scale_from", "error_message", "floats", "height", "height_sigma", "image_size",
           "keypoint_offset", "options_from_args", "positive", "print_result", "printer",
           "rate", "report_written", "seed", "solver_progress", "stated_gauge", "staged_names",
           "step", "warn"]


#: The library's argument names -> the flags that give them (with a metavar where the flag
#: takes a value): the library's messages name arguments (``pass intrinsics``), the CLI says
#: them as flags (:meth:`mirrorgraph.errors.InputError.describe`).
FLAGS = {"intrinsics": "--intrinsics FILE", "image_size": "--image-size WxH",
         "camera": "--camera NAME", "fov_deg": "--fov DEG", "skeleton": "--skeleton NAME",
         "estimator": "--estimator NAME", "threshold_px": "--threshold PX",
         "min_confidence": "--min-confidence C", "joints": "--joints NAMES",
         "subject_height": "--subject-height METRES", "scale_from": "--scale-from WHAT",
         "keypoint_offset": "--keypoint-offset METRES",
         "height_sigma": "--height-sigma FRACTION",
         "seed": "--seed N", "fps": "--fps HZ", "video": "--video FILE",
         "render": "--render OUT.mp4", "workers": "--workers N",
         "scheduler": "--scheduler ADDRESS", "joints3d": "--joints3d FILE",
         "save": "--save OUT.rrd", "start": "--start N", "end": "--end N",
         "every": "--every N", "pose_model": "--pose-model FILE.onnx",
         "det_model": "--det-model FILE.onnx"}


def error_message(exc: BaseException) -> str:
    """What ``error: ...`` says of an error: an :class:`InputError`'s arguments as flags."""
    return exc.describe(FLAGS) if isinstance(exc, InputError) else str(exc)


# --------------------------------------------------------------------------- argument types
def image_size(text: str) -> tuple[int, int]:
    from ..intrinsics import parse_image_size
    try:
        return parse_image_size(text)
    except (ValueError, InputError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _number(text: str, cast, kind: str):
    """``cast(text)``, or argparse's one-line error naming what was expected."""
    try:
        return cast(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not {kind}: {text!r}") from None


def positive(text: str) -> float:
    v = _number(text, float, "a number")
    if not np.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return v


def rate(text: str) -> float:
    v = _number(text, float, "a number")
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"must lie in [0, 1], got {text!r}")
    return v


def height(text: str) -> float:
    """``--subject-height``: a human height in metres (centimetres are caught and named)."""
    v = positive(text)
    problem = height_problem(v)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return v


#: ``--keypoint-offset`` above this many metres is taken for centimetres or millimetres.
_MAX_KEYPOINT_OFFSET_M = 0.5


def keypoint_offset(text: str) -> float:
    """``--keypoint-offset``: a keypoint's placement off its anatomical landmark, metres
    (0 allowed; centimetres or millimetres are caught and named)."""
    v = _number(text, float, "a number of metres")
    if not np.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative number of metres, got {text!r}")
    if v > _MAX_KEYPOINT_OFFSET_M:
        raise argparse.ArgumentTypeError(
            f"{text} m is no keypoint placement (at most {_MAX_KEYPOINT_OFFSET_M:g} m): give "
            f"metres, e.g. 0.03 for 3 cm")
    return v


#: ``--height-sigma`` above this is taken for a percentage.
_MAX_HEIGHT_SIGMA = 0.2


def height_sigma(text: str) -> float:
    """``--height-sigma``: the given height's relative std, a fraction (0 allowed; a
    percentage is caught and named)."""
    v = _number(text.strip(), float, "a fraction")
    if not np.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative fraction of the height, "
                                         f"got {text!r}")
    if v > _MAX_HEIGHT_SIGMA:
        raise argparse.ArgumentTypeError(
            f"{text} is no height's relative std (at most {_MAX_HEIGHT_SIGMA:g}): give a "
            f"fraction, e.g. 0.005 for 0.5 %")
    return v


def seed(text: str) -> int:
    v = _number(text, int, "an integer")
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}")
    return v


def floats(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


# --------------------------------------------------------------------------- common options
def add_common(p) -> None:
    p.add_argument("--quiet", action="store_true",
                   help="print nothing but errors (warnings stay in the JSON written)")
    p.add_argument("--verbose", action="store_true", help="tell what was detected and done")
    p.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")


def add_joints(p) -> None:
    """``--joints``: the joints :func:`mirrorgraph.calibrate` calibrates from (``calibrate``,
    ``batch``; ``calibrate-rig`` has its own words for its views)."""
    p.add_argument("--joints", help="auto (default: the limbs in the graph, face, hands and "
                                    "feet triangulated afterwards), limbs, all (every keypoint in "
                                    "the graph), or comma-separated joint names (at least 4): the "
                                    "words of calibrate-rig")


def add_scale_from(p) -> None:
    """``--scale-from stature|limbs``: how the subject height becomes a length."""
    from ..graph.options import SCALE_FROM
    p.add_argument("--scale-from", choices=SCALE_FROM, default="stature",
                   help="how the height becomes a length: stature (default: measured on the joints, ankle "
                        "to eyes) or limbs (Winter's limb proportions; for subjects seated or "
                        "bent over most of the video)")


def add_keypoint_offset(p) -> None:
    """``--keypoint-offset METRES``: the keypoints' placement the metric scale's std holds
    (``RefineOptions.keypoint_offset``)."""
    from ..anthropometry import KEYPOINT_OFFSET
    p.add_argument("--keypoint-offset", type=keypoint_offset, default=None, metavar="METRES",
                   help="with --subject-height: how far your keypoints lie from the anatomical "
                        "landmarks, in metres, which the metric scale's std holds (default: "
                        f"{100 * KEYPOINT_OFFSET:g}%% of the height, 3 cm at 1.75 m, video "
                        "detectors against markers after Needham et al. 2021); lower it for "
                        "keypoints on the landmarks (mocap markers projected, synthetic: 0)")


def add_height_sigma(p) -> None:
    """``--height-sigma FRACTION``: the given height's relative std, the height's prior in
    the metric scale's std (``RefineOptions.height_sigma``)."""
    from ..graph.options import GaugeOptions
    p.add_argument("--height-sigma", type=height_sigma, default=None, metavar="FRACTION",
                   help="with --subject-height: the height's relative std, a fraction (default: "
                        f"{GaugeOptions().height_sigma:g}, a height the subject reports: adults "
                        "over-report by ~1.1 cm, spread 1.9 cm); e.g. 0.005 for a height "
                        "measured with a stadiometer")


def stated_gauge(args) -> dict:
    """The :class:`~mirrorgraph.graph.options.GaugeOptions` fields the command line states
    (``--keypoint-offset``, ``--height-sigma``), those not given left out (the options'
    defaults stand)."""
    given = {"keypoint_offset": getattr(args, "keypoint_offset", None),
             "height_sigma": getattr(args, "height_sigma", None)}
    return {k: v for k, v in given.items() if v is not None}


def options_from_args(args):
    """The :class:`~mirrorgraph.pipelines.mirror.CalibrateOptions` of the options ``calibrate``
    and ``batch`` share (``--estimator --threshold --min-confidence --joints
    --no-refine --subject-height --seed --image-size --fov --scale-from
    --keypoint-offset --height-sigma``, and
    ``--sensitivity`` and ``--principal-point`` where the command has them). Without
    intrinsics the focal length is estimated unless ``--fov`` gives one."""
    from ..graph.options import FocalOptions, RefineOptions
    from ..pipelines.mirror import CalibrateOptions

    free = getattr(args, "principal_point", "centre") == "free"
    opts = CalibrateOptions(estimator=args.estimator, min_confidence=args.min_confidence,
                            refine=not args.no_refine, subject_height=args.subject_height,
                            seed=args.seed, image_size=args.image_size,
                            joints=tuple(j.strip() for j in args.joints.split(","))
                            if args.joints else None,
                            refine_options=RefineOptions(
                                scale_from=args.scale_from,
                                **stated_gauge(args),
                                focal=FocalOptions(principal_point=free,
                                                   lines=not getattr(args, "no_lines", False))),
                            sensitivity_priors=getattr(args, "sensitivity", False))
    if args.threshold is not None:
        opts.threshold_px = args.threshold
    if args.fov is not None:                 # a field of view given: kept, not estimated
        opts.fov_deg, opts.estimate_focal = args.fov, False
    return opts


# --------------------------------------------------------------------------- what a run says
def printer(args):
    """``print``, or a function that prints nothing under ``--quiet``."""
    return (lambda *_a, **_k: None) if args.quiet else print


def step(args, name: str) -> None:
    """Name a step on stderr with ``--verbose`` (on a terminal over any open progress line)."""
    if getattr(args, "verbose", False) and not args.quiet:
        clear = "\r" + " " * 80 + "\r" if _isatty(sys.stderr) else ""
        print(f"{clear}... {name}", file=sys.stderr)


def _isatty(stream) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


def warn(args, warnings) -> None:
    """Every warning once on stderr, ``warning: ...``; nothing under ``--quiet`` (the
    warnings stay in the files the run writes)."""
    if getattr(args, "quiet", False):
        return
    for w in dict.fromkeys(warnings):
        print(f"warning: {w}", file=sys.stderr)


def print_result(args, summary: str, warnings) -> None:
    """The summary on stdout and every warning once on stderr, neither under ``--quiet``
    (the summary without its warning lines)."""
    lines = [ln for ln in summary.splitlines() if not ln.startswith("warning: ")]
    printer(args)("\n".join(lines))
    sys.stdout.flush()
    warn(args, warnings)


def report_written(written: dict, out) -> str:
    """``wrote 5 figures and 6 video overlays to DIR, and the overlay video OUT.mp4``."""
    figures = sum(1 for k in written if not k.startswith("overlay_") and k != "video")
    parts = [f"{figures} figure{'s' * (figures != 1)}"]
    overlays = sum(1 for k in written if k.startswith("overlay_"))
    if overlays:
        parts.append(f"{overlays} video overlay{'s' * (overlays != 1)}")
    text = f"wrote {' and '.join(parts)} to {out}"
    if "video" in written:
        text += f", and the overlay video {written['video']}"
    return text


def staged_names(written: dict, folder, render=None) -> dict:
    """The files a report wrote into its staging folder (:meth:`mirrorgraph.io.atomic.
    Staging.folder`), named where they land: ``folder/<name>``, the video at ``render``."""
    from pathlib import Path
    return {k: Path(render) if k == "video" and render else Path(folder) / Path(p).name
            for k, p in written.items()}


@contextmanager
def solver_progress(args):
    """Progress bars of the robust initialisation and of the graph; yields the keyword
    arguments of :func:`mirrorgraph.calibrate` that draw them.

    The initialisation's bar ends with the first step after it, its total shown
    once known (the RANSAC adapts it); the graph's shows the accepted steps and
    the error of the current pass (:class:`~mirrorgraph.progress.SolveProgress`).
    """
    with Progress("robust initialisation", enabled=not args.quiet) as r_bar, \
            Progress("solving the graph", enabled=not args.quiet) as g_bar:
        solve = SolveProgress(g_bar, on_first=r_bar.close)

        def on_step(name: str) -> None:
            if r_bar.started:             # any step after the initialisation ends its bar
                r_bar.close()
            step(args, name)
        yield {"progress": on_step, "iteration_progress": solve,
               "ransac_progress": r_bar.estimate}
        g_bar.close(solve.info or None)
