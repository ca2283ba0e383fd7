"""Command-line interface: a thin layer over the Python API.

    mirrorgraph calibrate KEYPOINTS|VIDEO [--intrinsics FILE] --out calibration.json
    mirrorgraph detect VIDEO --out keypoints.json [--format openpose] [--every N ...]
    mirrorgraph synth --out DIR [--frames N --noise PX --outliers R ...]
    mirrorgraph demo
    mirrorgraph export calibration.json --to pose2sim|anipose OUT.toml
    mirrorgraph report calibration.json [KEYPOINTS] --out DIR
    mirrorgraph batch MANIFEST [--scheduler ADDRESS] [--workers N] [--out-dir DIR] [--report FILE.json]
    mirrorgraph calibrate-rig RIG.toml --out calibration.toml [--with-virtual]
    mirrorgraph synth-rig KIND --out DIR

Every error that input can cause ends in one line ``error: ...`` on stderr and
exit status 2 (1 for an unexpected internal error; ``--debug`` shows its
traceback). No output file is written by a failed run.

What a run says: its summary on stdout, each warning once on stderr (also under
``--quiet``), progress bars on stderr only when it is a terminal
(:mod:`mirrorgraph.progress`), and a last line naming what was written.
``calibrate --out c.json`` also keeps the run its figures are drawn from in
``c.report.npz`` (named in ``c.json``, see :mod:`mirrorgraph.report.store`), so
that ``report`` later draws the very figures ``calibrate --report`` draws.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ._version import __version__
from .errors import InputError, MirrorgraphError
from .keypoints import DEFAULT_MIN_CONFIDENCE
from .anthropometry import height_problem
from .progress import Progress, SolveProgress

EXIT_INPUT = 2
EXIT_INTERNAL = 1


# --------------------------------------------------------------------------- parsing helpers
def _image_size(text: str) -> tuple[int, int]:
    from .intrinsics import parse_image_size
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


def _positive(text: str) -> float:
    v = _number(text, float, "a number")
    if not np.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return v


def _rate(text: str) -> float:
    v = _number(text, float, "a number")
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"must lie in [0, 1], got {text!r}")
    return v


def _height(text: str) -> float:
    """``--subject-height``: a human height in metres (centimetres are caught and named)."""
    v = _positive(text)
    problem = height_problem(v)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return v


def _seed(text: str) -> int:
    v = _number(text, int, "an integer")
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}")
    return v


def _floats(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


def _install_hint() -> str:
    from .report import INSTALL_HINT
    return INSTALL_HINT


# --------------------------------------------------------------------------- calibrate
def _add_calibrate(sub) -> None:
    p = sub.add_parser("calibrate", help="calibrate the mirror from 2D keypoints",
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
    p.add_argument("--image-size", type=_image_size, metavar="WxH",
                   help="image size when no intrinsics are given and the input lacks it; "
                        "the focal length is then estimated from the person and the "
                        "reflection (square pixels, principal point at the image centre)")
    p.add_argument("--fov", type=_positive, default=None, metavar="DEG",
                   help="without intrinsics: keep this horizontal field of view instead of "
                        "estimating the focal length (the estimate starts from 60)")
    p.add_argument("--principal-point", choices=("centre", "free"), default="centre",
                   help="without intrinsics: the principal point at the image centre "
                        "(default) or estimated with the focal length")
    p.add_argument("--skeleton", help="keypoint layout when the count is ambiguous "
                                      "(COCO_17, BODY_25, BODY_25B, COCO_18, HALPE_26, BLAZEPOSE)")
    p.add_argument("--estimator", default="reflective",
                   choices=("reflective", "eightpoint", "reflective8"),
                   help="initial estimator: ours (reflective, default), MirrorCalib's "
                        "Baseline1 (eightpoint) or its 6-unknown eight-point (reflective8)")
    p.add_argument("--threshold", type=_positive, default=None, metavar="PX",
                   help="inlier threshold on the epipolar distance in pixels (default 10)")
    p.add_argument("--min-confidence", type=_rate, default=DEFAULT_MIN_CONFIDENCE,
                   help="ignore joints below this detector confidence (default "
                        f"{DEFAULT_MIN_CONFIDENCE:g})")
    p.add_argument("--joints", help="auto (default: the limbs in the graph, face, hands and "
                                    "feet triangulated afterwards), limbs, all (every keypoint in "
                                    "the graph), or comma-separated joint names (at least 4): the "
                                    "words of calibrate-rig")
    p.add_argument("--subject-height", type=_height, metavar="METRES",
                   help="subject's standing height in metres, e.g. 1.75: gives the metric scale")
    p.add_argument("--scale-from", choices=("stature", "limbs"), default="stature",
                   help="how the height becomes a length: stature (default: measured on the joints, ankle "
                        "to eyes) or limbs (Winter's limb proportions; for subjects seated or "
                        "bent over most of the video)")
    p.add_argument("--no-refine", action="store_true",
                   help="keep the robust initialisation, skip the factor graph")
    p.add_argument("--sensitivity", action="store_true",
                   help="also solve again with each body prior's weight halved and doubled "
                        "(calibration.json's sensitivity.prior_weights; eight calibrations more)")
    p.add_argument("--joints3d", metavar="FILE",
                   help="write the refined 3D joints: .npz (T, J, 3) with names and a validity "
                        "mask, .csv, or OpenSim .trc (metres, needs --subject-height)")
    p.add_argument("--fps", type=_positive, default=None,
                   help="frame rate of the 3D motion (default: the input's, else --video's, "
                        "else 30 with a warning)")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the RANSAC (default 0)")
    p.add_argument("--report", metavar="DIR",
                   help="write the report's figures (PNG) into DIR (needs matplotlib: "
                        f"{_install_hint()})")
    p.add_argument("--video", metavar="FILE",
                   help="the video the keypoints come from: its frame rate, and with "
                        "--report the overlay on sampled frames")
    p.add_argument("--render", metavar="OUT.mp4",
                   help="with --report and --video: write the whole overlay video")
    from .cli_video import add_video_options
    add_video_options(p)
    _add_common(p)
    p.set_defaults(func=_cmd_calibrate)


def _cmd_calibrate(args) -> int:
    from .intrinsics import load_intrinsics
    from .io import read_keypoints
    from .io.motion import write_joints3d
    from .graph.options import FocalOptions, RefineOptions
    from .pipeline import CalibrateOptions, calibrate

    say = _say(args)
    if Path(args.out).is_dir():
        raise InputError("is a folder; give a file name for the calibration JSON",
                         source=args.out, field="--out")
    if args.render and not (args.report and args.video):
        raise InputError("needs --report DIR and --video FILE", field="--render")
    if args.report:
        from .report import require_matplotlib
        require_matplotlib()          # fail before the long run, with the install hint
    if args.video and not Path(args.video).is_file():
        raise InputError("no such video file", source=args.video, field="--video")
    if args.render and Path(args.render).suffix.lower() != ".mp4":
        raise InputError("must end in .mp4", source=args.render, field="--render")
    if args.joints3d and args.no_refine:
        raise InputError("needs the refinement: drop --no-refine", field="--joints3d")
    if args.joints3d and Path(args.joints3d).suffix.lower() not in (".npz", ".csv", ".trc"):
        raise InputError("must end in .npz, .csv or .trc", source=args.joints3d,
                         field="--joints3d")
    if args.joints3d and Path(args.joints3d).suffix.lower() == ".trc" and not args.subject_height:
        raise InputError("OpenSim .trc needs metres: add --subject-height", field="--joints3d")
    if args.sensitivity and args.no_refine:
        raise InputError("needs the refinement: drop --no-refine", field="--sensitivity")
    if args.camera and not args.intrinsics:
        raise InputError("needs --intrinsics FILE.toml", field="--camera")
    if args.principal_point == "free" and (args.intrinsics or args.fov is not None
                                           or args.no_refine):
        raise InputError("estimates the principal point with the focal length: not with "
                         "--intrinsics, --fov or --no-refine", field="--principal-point")
    from .cli_video import describe, detect_with_progress, video_options
    from .video.reader import is_video
    from_video = is_video(args.keypoints)
    vopts = video_options(args, has_video=from_video)
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
    opts = CalibrateOptions(estimator=args.estimator, min_confidence=args.min_confidence,
                            refine=not args.no_refine, subject_height=args.subject_height,
                            seed=args.seed, image_size=args.image_size,
                            joints=tuple(j.strip() for j in args.joints.split(","))
                            if args.joints else None,
                            refine_options=RefineOptions(
                                scale_from=args.scale_from,
                                focal=FocalOptions(principal_point=args.principal_point == "free")),
                            sensitivity_priors=args.sensitivity)
    if args.threshold is not None:
        opts.threshold_px = args.threshold
    if args.fov is not None:                 # a field of view given: kept, not estimated
        opts.fov_deg, opts.estimate_focal = args.fov, False
    opts.fps, opts.video = args.fps, args.video           # the frame rate of the 3D motion
    with _solver_progress(args) as callbacks:
        run = calibrate(data, intr, opts, **callbacks)
    calib = run.calibration
    if args.joints3d and run.fps_source == "default":
        from .pipeline import DEFAULT_FPS_WARNING
        calib.warnings.append(DEFAULT_FPS_WARNING)
    _write_calibration_and_run(args.out, run)
    if args.joints3d:
        if run.joints3d is None:
            raise InputError("needs the refinement: drop --no-refine", field="--joints3d")
        write_joints3d(args.joints3d, run.joints3d, run.valid3d, run.paired.frame_ids,
                       run.paired.skeleton.joints, run.fps,
                       unit="m" if calib.distance is not None else "mirror distance")
    report_line = None
    if args.report:
        from .report import make_report
        written = make_report(run, args.report, video=args.video, render=args.render,
                              progress=lambda s: _step(args, s), progress_bar=not args.quiet)
        report_line = _report_written(written, args.report)
    _print_result(args, calib.summary(), calib.warnings)
    if args.verbose and not args.quiet:
        print("timings: " + ", ".join(f"{k} {v:.2f} s" for k, v in run.timings.items()),
              file=sys.stderr)
    if report_line:
        say(report_line)
    say(f"wrote {args.out} in {time.perf_counter() - t0:.2f} s")
    return 0


def _write_calibration_and_run(out: str | Path, run) -> None:
    """The calibration JSON and, beside it, the run its report draws from
    (:func:`mirrorgraph.report.store.write_calibration_and_run`)."""
    from .report.store import write_calibration_and_run
    write_calibration_and_run(out, run)


@contextmanager
def _solver_progress(args):
    """Progress bars of the robust initialisation and of the graph; yields the keyword
    arguments of :func:`mirrorgraph.calibrate` that draw them.

    The initialisation's bar ends with the first step after it, its total shown
    once known (the RANSAC adapts it); the graph's shows the accepted steps and
    the error of the current pass (:class:`~mirrorgraph.progress.SolveProgress`).
    """
    with Progress("robust initialisation", enabled=not args.quiet) as r_bar, \
            Progress("solving the graph", enabled=not args.quiet) as g_bar:
        solve = SolveProgress(g_bar, on_first=r_bar.close)

        def step(name: str) -> None:
            if r_bar.started:             # any step after the initialisation ends its bar
                r_bar.close()
            _step(args, name)
        yield {"progress": step, "iteration_progress": solve,
               "ransac_progress": r_bar.estimate}
        g_bar.close(solve.info or None)


def _report_written(written: dict, out) -> str:
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


def _print_result(args, summary: str, warnings) -> None:
    """The summary on stdout (unless ``--quiet``, and without its warning lines), then
    every warning once on stderr (also under ``--quiet``)."""
    lines = [ln for ln in summary.splitlines() if not ln.startswith("warning: ")]
    _say(args)("\n".join(lines))
    sys.stdout.flush()
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)


def _verbose_input(args, data) -> None:
    if not getattr(args, "verbose", False):
        return
    from .keypoints import RawDetections
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


# --------------------------------------------------------------------------- synth
def _add_synth(sub) -> None:
    from .synth.geometry import PRESETS as PRESET_NAMES

    p = sub.add_parser("synth", help="write a synthetic mirror scene with ground truth",
                       description="Write a synthetic scene: a person exercising between "
                                   "the camera and a mirror, keypoints in every input "
                                   "format, camera.json and ground_truth.json.")
    p.add_argument("--out", required=True, help="folder to write")
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--seed", type=_seed, default=0)
    p.add_argument("--skeleton", default="COCO_17", choices=("COCO_17", "BODY_25", "COCO_18", "BODY_25B", "HALPE_26"))
    p.add_argument("--image-size", type=_image_size, default=(1920, 1080), metavar="WxH")
    p.add_argument("--geometry", default="gym", choices=tuple(PRESET_NAMES),
                   help="scene geometry: gym (default: a typical gym or studio, mirror "
                        "3.5-8 m away, person 0.8-2.5 m in front of it), wide (mirror 2.5-10 m, "
                        "person 0.5-3.5 m, focal 700-2200 px, camera height and tilt varied), "
                        "low_parallax (the person near the camera-mirror line) or favourable "
                        "(the person far from the epipole: the scenes of earlier versions)")
    focal = p.add_mutually_exclusive_group()
    focal.add_argument("--fov", type=_positive, default=None, metavar="DEG",
                       help="horizontal field of view (default: the geometry's focal range; "
                            "60 for favourable)")
    focal.add_argument("--focal", type=_positive, default=None, metavar="PX",
                       help="focal length in pixels")
    p.add_argument("--mirror-angle", type=float, default=None, metavar="DEG",
                   help="angle of the mirror normal to the optical axis (default: the geometry's)")
    p.add_argument("--mirror-distance", type=_positive, default=None, metavar="METRES")
    p.add_argument("--subject-height", type=_positive, default=None, metavar="METRES")
    p.add_argument("--noise", type=float, default=4.0, metavar="PX",
                   help="detector noise std in pixels (default 4, as MirrorCalib)")
    p.add_argument("--noise-mean", type=float, default=0.076, metavar="PX")
    p.add_argument("--noise-correlation", type=_rate, default=0.0, metavar="RHO",
                   help="frame-to-frame correlation of the detector noise (AR(1), < 1)")
    p.add_argument("--joint-bias", type=float, default=0.0, metavar="PX",
                   help="std of a constant per-joint offset of the detector, pixels")
    p.add_argument("--outliers", type=_rate, default=0.0, help="outlier rate")
    p.add_argument("--lr-swaps", type=_rate, default=0.0,
                   help="rate of frames whose reflection has left/right swapped")
    p.add_argument("--lr-swap-views", default="mirror", choices=("mirror", "both"),
                   help="swap left/right on the reflection only (default) or in both views")
    p.add_argument("--epipolar-outliers", type=_rate, default=0.0, metavar="RATE",
                   help="rate of keypoints displaced along their epipolar line (small "
                        "epipolar residual, wrong depth)")
    p.add_argument("--shared-bias", action="store_true",
                   help="with --joint-bias: the same per-joint offset on the person and, "
                        "mirrored, on the reflection (one detector's habit)")
    p.add_argument("--missing", type=_rate, default=0.0, help="rate of missing joints")
    p.add_argument("--extra-people", type=_rate, default=0.0,
                   help="rate of frames with an extra person")
    p.add_argument("--single", type=_rate, default=0.0,
                   help="rate of frames with only one of the two people detected")
    p.add_argument("--distortion", type=_floats, default=None, metavar="k1,k2,p1,p2,k3")
    p.add_argument("--motion", default=None, metavar="FILE.bvh",
                   help="real motion capture (BVH, e.g. the CMU take shipped as "
                        "mirrorgraph/data/cmu_01_01.bvh) instead "
                        "of the procedural exercise motion; resampled to 30 fps")
    p.add_argument("--formats", default="mmpose,openpose,easymocap,npz",
                   help="comma-separated formats to write")
    _add_common(p)
    p.set_defaults(func=_cmd_synth)


def _cmd_synth(args) -> int:
    from .synth import make_scene, write_scene

    if args.frames < 1:
        raise InputError("must be at least 1", field="--frames")
    if args.noise_correlation >= 1.0:
        raise InputError("must be below 1", field="--noise-correlation")
    if args.distortion is not None and len(args.distortion) != 5:
        raise InputError("needs 5 coefficients k1,k2,p1,p2,k3", field="--distortion")
    scene = make_scene(frames=args.frames, seed=args.seed, skeleton=args.skeleton,
                       image_size=args.image_size, fov_deg=args.fov, focal_px=args.focal,
                       geometry=args.geometry, lr_swap_views=args.lr_swap_views,
                       epipolar_outlier_rate=args.epipolar_outliers,
                       joint_bias_shared=args.shared_bias,
                       mirror_angle_deg=args.mirror_angle, mirror_distance=args.mirror_distance,
                       subject_height=args.subject_height, noise_mean=args.noise_mean,
                       noise_std=args.noise, outlier_rate=args.outliers,
                       lr_swap_rate=args.lr_swaps, missing_rate=args.missing,
                       extra_person_rate=args.extra_people, single_person_rate=args.single,
                       distortion=None if args.distortion is None else np.array(args.distortion),
                       motion=args.motion, noise_correlation=args.noise_correlation,
                       joint_bias_px=args.joint_bias)
    paths = write_scene(scene, args.out, formats=tuple(f.strip() for f in args.formats.split(",")))
    say = _say(args)
    say(f"wrote a {args.frames}-frame {args.skeleton} {args.geometry} scene to {args.out}:")
    for name, path in paths.items():
        say(f"  {name:18s} {path}")
    return 0


# --------------------------------------------------------------------------- demo
def _add_demo(sub) -> None:
    p = sub.add_parser("demo", help="run the whole pipeline on an embedded synthetic scene",
                       description="Synthesise a 1000-frame scene with known mirror (seed 7, "
                                   "MirrorCalib's noise), write it as MMPose keypoints, "
                                   "calibrate from the file and compare with the truth.")
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--seed", type=_seed, default=7)
    p.add_argument("--keep", metavar="DIR", help="keep the scene and results in DIR")
    _add_common(p)
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args) -> int:
    from .intrinsics import load_intrinsics
    from .metrics import normal_angle_deg, rotation_error_deg, translation_error
    from .pipeline import CalibrateOptions, calibrate
    from .synth import make_scene, write_scene

    say = _say(args)
    scene = make_scene(frames=args.frames, seed=args.seed, outlier_rate=0.05,
                       lr_swap_rate=0.05, missing_rate=0.02, single_person_rate=0.05,
                       extra_person_rate=0.02)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep) if args.keep else Path(tmp)
        paths = write_scene(scene, root, formats=("mmpose",))
        where = (f"-> {paths['mmpose']}" if args.keep else
                 "(in a temporary folder, deleted at the end; --keep DIR keeps it)")
        say(f"scene: {args.frames} frames, COCO-17, 1920x1080, noise 4 px, 5% outliers, "
            f"5% left/right swaps, subject {scene.subject_height:.2f} m {where}")
        t0 = time.perf_counter()
        with _solver_progress(args) as callbacks:
            run = calibrate(paths["mmpose"], load_intrinsics(paths["camera"]),
                            CalibrateOptions(subject_height=scene.subject_height), **callbacks)
        elapsed = time.perf_counter() - t0
        if args.keep:
            _write_calibration_and_run(root / "calibration.json", run)
    c = run.calibration
    R_true, t_true = scene.virtual_R, scene.virtual_t
    say("")
    _print_result(args, c.summary(), c.warnings)
    say("")
    say(f"{'':18s}{'estimate':>34s}{'ground truth':>34s}")
    fmt = lambda v: "[" + ", ".join(f"{x:+.4f}" for x in v) + "]"  # noqa: E731
    say(f"{'normal':18s}{fmt(c.normal):>34s}{fmt(scene.normal):>34s}")
    say(f"{'distance (m)':18s}{c.distance or float('nan'):>34.4f}{scene.distance:>34.4f}")
    say("")
    say(f"normal angle error        {normal_angle_deg(c.normal, scene.normal):.4f} deg "
        f"(initial estimate {normal_angle_deg(c.initial_normal, scene.normal):.4f} deg)")
    say(f"virtual camera rotation   {rotation_error_deg(c.virtual_rotation, R_true):.4f} deg "
        "(MirrorCalib on real video: 1.82 deg)")
    say(f"virtual camera translation {1000 * translation_error(c.virtual_translation, t_true):.1f} mm"
        " after scaling to the true norm (MirrorCalib: 69.5 mm)")
    if c.distance is not None:
        say(f"distance error            {100 * abs(c.distance - scene.distance) / scene.distance:.2f} %"
            " (scale from the subject's height)")
    say(f"time                      {elapsed:.2f} s")
    if args.keep:
        say(f"kept the scene and calibration.json in {root} (mirrorgraph report "
            f"{root / 'calibration.json'} --out DIR draws its figures)")
    return 0


# --------------------------------------------------------------------------- report
def _add_report(sub) -> None:
    p = sub.add_parser("report", help="figures of a calibration: epipole, residuals, 3D view, "
                                      "bone lengths, uncertainty",
                       description="Write PNG figures of a calibration and, with --video, "
                                   "overlays on the video (needs the plot extra). The figures "
                                   "are those of 'calibrate --report': drawn from the run "
                                   "'calibrate' kept beside the calibration (CALIBRATION with "
                                   ".report.npz), or, without it, from the keypoints calibrated "
                                   "again with the options the calibration records.")
    p.add_argument("calibration", help="calibration.json written by 'mirrorgraph calibrate'")
    p.add_argument("keypoints", nargs="?", default=None,
                   help="the keypoints the calibration was made from (needed only without "
                        "the .report.npz beside the calibration, or with --recompute)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder to write the figures into")
    p.add_argument("--recompute", action="store_true",
                   help="calibrate the keypoints again even where the run is stored")
    p.add_argument("--skeleton", help="keypoint layout when the count is ambiguous")
    p.add_argument("--video", metavar="FILE",
                   help="draw joints, reflections and epipolar lines on sampled frames")
    p.add_argument("--render", metavar="OUT.mp4", help="write the whole overlay video (needs --video)")
    p.add_argument("--frames", type=int, default=6, help="video frames to sample (default 6)")
    _add_common(p)
    p.set_defaults(func=_cmd_report)


def _cmd_report(args) -> int:
    from .report import load_run, make_report, require_matplotlib

    require_matplotlib()
    if args.recompute and args.keypoints is None:
        raise InputError("needs the keypoints the calibration was made from", field="--recompute")
    say = _say(args)
    with _solver_progress(args) as callbacks:
        loaded = load_run(args.calibration, args.keypoints,
                          report_data=None if args.recompute else "auto",
                          skeleton=args.skeleton, **callbacks)
    for w in loaded.warnings:
        print(f"warning: {w}", file=sys.stderr)
    note = ""
    if loaded.origin == "stored" and args.keypoints is not None:
        note = f" ({args.keypoints} not read; --recompute calibrates it again)"
    say(loaded.message + note)
    out = make_report(loaded.run, args.out, video=args.video, render=args.render,
                      max_frames=args.frames, progress=lambda s: _step(args, s),
                      progress_bar=not args.quiet)
    say(_report_written(out, args.out))
    return 0


# --------------------------------------------------------------------------- export
def _add_export(sub) -> None:
    p = sub.add_parser("export", help="write the real and virtual camera for Pose2Sim / aniposelib",
                       description="Write the real camera and the mirror's virtual camera as two "
                                   "ordinary cameras of a Pose2Sim Calib.toml or an aniposelib "
                                   "calibration.toml. The virtual camera is the one that sees the "
                                   "horizontally flipped image (u -> W - u): give those tools the "
                                   "reflection's keypoints with x -> W - x and left/right labels "
                                   "swapped (see the README).")
    p.add_argument("calibration", help="calibration.json written by 'mirrorgraph calibrate'")
    p.add_argument("--to", required=True, choices=("pose2sim", "anipose"), dest="fmt")
    p.add_argument("out", help="TOML file to write")
    p.add_argument("--world", default="camera", choices=("camera", "z_up"),
                   help="world frame: the real camera's (default) or X right, Y depth, Z up")
    _add_common(p)
    p.set_defaults(func=_cmd_export)


def _cmd_export(args) -> int:
    from .export import camera_sections, export_calibration

    warnings = export_calibration(args.calibration, args.fmt, args.out, world=args.world)
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)
    (k_real, n_real), (k_mirror, n_mirror) = camera_sections(args.fmt)
    named = lambda key, name: f"[{key}]" + (f" '{name}'" if name != key else "")  # noqa: E731
    _say(args)(f"wrote {args.out} ({args.fmt}): {named(k_real, n_real)} the real camera, "
               f"{named(k_mirror, n_mirror)} the mirror's virtual camera (flipped image: give "
               "it the reflection's keypoints with x -> W - x and left/right swapped)")
    return 0


# --------------------------------------------------------------------------- common
def _add_common(p) -> None:
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--verbose", action="store_true", help="tell what was detected and done")
    p.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")


def _say(args):
    return (lambda *_a, **_k: None) if args.quiet else print


def _step(args, name: str) -> None:
    """Name a step on stderr with ``--verbose`` (on a terminal over any open progress line)."""
    if getattr(args, "verbose", False) and not args.quiet:
        clear = "\r" + " " * 80 + "\r" if _isatty(sys.stderr) else ""
        print(f"{clear}... {name}", file=sys.stderr)


def _isatty(stream) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors, like every other error of the CLI."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(EXIT_INPUT, f"error: {self.prog}: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="mirrorgraph",
        description="Calibrate a planar mirror's virtual camera from the people in the "
                    "video, and turn mirror videos into 3D motion.")
    parser.add_argument("--version", action="version", version=f"mirrorgraph {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_calibrate(sub)
    _add_synth(sub)
    _add_demo(sub)
    _add_export(sub)
    _add_report(sub)
    from .batch import add_batch_parser
    add_batch_parser(sub)
    from .cli_rig import add_rig_parsers
    add_rig_parsers(sub, _add_common, _positive, _seed, _rate)
    from .cli_video import add_detect_parser
    add_detect_parser(sub, _add_common)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``mirrorgraph`` command; returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:          # --help, --version, or a usage error
        return exc.code if isinstance(exc.code, int) else EXIT_INPUT
    try:
        return int(args.func(args) or 0)
    except MirrorgraphError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except FileNotFoundError as exc:
        print(f"error: {exc.filename}: no such file or folder", file=sys.stderr)
        return EXIT_INPUT
    except (PermissionError, IsADirectoryError, NotADirectoryError) as exc:
        print(f"error: {exc.filename}: {exc.strerror}", file=sys.stderr)
        return EXIT_INPUT
    except BrokenPipeError:  # e.g. `mirrorgraph ... | head`: the reader left
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - last line of defence of the CLI
        if getattr(args, "debug", False):
            raise
        print(f"internal error: {type(exc).__name__}: {exc} (rerun with --debug and "
              "please report it)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
