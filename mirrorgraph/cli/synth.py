"""The commands of synthetic data: ``synth`` writes a synthetic mirror scene with its
ground truth in every input format (:mod:`mirrorgraph.synth`), and ``demo`` runs the
whole pipeline on such a scene and compares the calibration with the truth.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..synth.body import SUPPORTED_SKELETONS
from ..synth.geometry import PRESETS
from ..synth.writer import FORMATS as SCENE_FORMATS
from ..progress import Progress
from .args import (add_common, floats, image_size, positive, print_result, printer, rate, seed,
                   solver_progress, warn)
from .commands import HELP

__all__ = ["add_parsers", "cmd_demo", "cmd_synth"]


def add_parsers(sub) -> None:
    """Add ``synth`` and ``demo`` to the CLI's subparsers."""
    _add_synth(sub)
    _add_demo(sub)


# --------------------------------------------------------------------------- synth
def _add_synth(sub) -> None:
    p = sub.add_parser("synth", help=HELP["synth"],
                       description="Write a synthetic scene: a person exercising between "
                                   "the camera and a mirror, keypoints in every input "
                                   "format, camera.json and ground_truth.json.")
    p.add_argument("--out", required=True, help="folder to write")
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--skeleton", default="COCO_17", choices=SUPPORTED_SKELETONS)
    p.add_argument("--image-size", type=image_size, default=(1920, 1080), metavar="WxH")
    p.add_argument("--geometry", default="gym", choices=tuple(PRESETS),
                   help="scene geometry: gym (default: a typical gym or studio, mirror "
                        "3.5-8 m away, person 0.8-2.5 m in front of it), wide (mirror 2.5-10 m, "
                        "person 0.5-3.5 m, focal 700-2200 px, camera height and tilt varied), "
                        "low_parallax (the person near the camera-mirror line) or favourable "
                        "(the person far from the epipole: the scenes of earlier versions)")
    focal = p.add_mutually_exclusive_group()
    focal.add_argument("--fov", type=positive, default=None, metavar="DEG",
                       help="horizontal field of view (default: the geometry's focal range; "
                            "60 for favourable)")
    focal.add_argument("--focal", type=positive, default=None, metavar="PX",
                       help="focal length in pixels")
    p.add_argument("--mirror-angle", type=float, default=None, metavar="DEG",
                   help="angle of the mirror normal to the optical axis (default: the geometry's)")
    p.add_argument("--mirror-distance", type=positive, default=None, metavar="METRES")
    p.add_argument("--subject-height", type=positive, default=None, metavar="METRES")
    p.add_argument("--noise", type=float, default=4.0, metavar="PX",
                   help="detector noise std in pixels (default 4, as MirrorCalib)")
    p.add_argument("--noise-mean", type=float, default=0.076, metavar="PX")
    p.add_argument("--noise-correlation", type=rate, default=0.0, metavar="RHO",
                   help="frame-to-frame correlation of the detector noise (AR(1), < 1)")
    p.add_argument("--joint-bias", type=float, default=0.0, metavar="PX",
                   help="std of a constant per-joint offset of the detector, pixels")
    p.add_argument("--outliers", type=rate, default=0.0, help="outlier rate")
    p.add_argument("--lr-swaps", type=rate, default=0.0,
                   help="rate of frames whose reflection has left/right swapped")
    p.add_argument("--lr-swap-views", default="mirror", choices=("mirror", "both"),
                   help="swap left/right on the reflection only (default) or in both views")
    p.add_argument("--epipolar-outliers", type=rate, default=0.0, metavar="RATE",
                   help="rate of keypoints displaced along their epipolar line (small "
                        "epipolar residual, wrong depth)")
    p.add_argument("--shared-bias", action="store_true",
                   help="with --joint-bias: the same per-joint offset on the person and, "
                        "mirrored, on the reflection (one detector's habit)")
    p.add_argument("--missing", type=rate, default=0.0, help="rate of missing joints")
    p.add_argument("--extra-people", type=rate, default=0.0,
                   help="rate of frames with an extra person")
    p.add_argument("--single", type=rate, default=0.0,
                   help="rate of frames with only one of the two people detected")
    p.add_argument("--distortion", type=floats, default=None, metavar="k1,k2,p1,p2,k3")
    p.add_argument("--motion", default=None, metavar="FILE.bvh",
                   help="real motion capture (BVH, e.g. the CMU take shipped as "
                        "mirrorgraph/data/cmu_01_01.bvh) instead "
                        "of the procedural exercise motion; resampled to 30 fps")
    p.add_argument("--formats", default=",".join(SCENE_FORMATS),
                   help="comma-separated formats to write")
    p.add_argument("--video-frames", type=lambda t: int(positive(t)) if t != "0" else 0,
                   default=150, metavar="N",
                   help="also write clip.mp4: the first N frames drawn as a video (the person "
                        "and the reflection as simple bodies a pose detector finds), to try "
                        "'calibrate clip.mp4' and 'live clip.mp4' on (default 150; 0: none)")
    add_common(p)
    p.set_defaults(func=cmd_synth)


def cmd_synth(args) -> int:
    from ..synth import make_scene, write_scene

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
    say = printer(args)
    if args.video_frames:
        from ..synth.video import hidden_reflection_note, write_scene_video

        count = min(args.video_frames, args.frames)
        with Progress("drawing clip.mp4", total=count, enabled=not args.quiet) as bar:
            # for mirrorgraph's own reader: the codec need not be one browsers play
            paths["video"], _ = write_scene_video(scene, Path(args.out) / "clip.mp4", count,
                                                  progress=bar.update)
        hidden = hidden_reflection_note(scene, count)
        if hidden:
            warn(args, [f"clip.mp4 of seed {args.seed}: {hidden}, where a pose detector "
                        "finds the person alone (the keypoint files hold the whole scene; "
                        "another --seed or --geometry favourable draws both)"])
    say(f"wrote a {args.frames}-frame {args.skeleton} {args.geometry} scene to {args.out}:")
    for name, path in paths.items():
        say(f"  {name:18s} {path}")
    return 0


# --------------------------------------------------------------------------- demo
def _add_demo(sub) -> None:
    p = sub.add_parser("demo", help=HELP["demo"],
                       description="Synthesise a 1000-frame scene with known mirror (seed 7, "
                                   "MirrorCalib's noise), write it as MMPose keypoints, "
                                   "calibrate from the file and compare with the truth.")
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--seed", type=seed, default=7)
    p.add_argument("--keep", metavar="DIR", help="keep the scene and results in DIR")
    add_common(p)
    p.set_defaults(func=cmd_demo)


def cmd_demo(args) -> int:
    from ..intrinsics import load_intrinsics
    from ..metrics import normal_angle_deg, rotation_error_deg, translation_error
    from ..pipelines.mirror import CalibrateOptions, calibrate
    from ..report.store import write_calibration_and_run
    from ..synth import make_scene, write_scene

    say = printer(args)
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
        with solver_progress(args) as callbacks:
            run = calibrate(paths["mmpose"], load_intrinsics(paths["camera"]),
                            CalibrateOptions(subject_height=scene.subject_height), **callbacks)
        elapsed = time.perf_counter() - t0
        if args.keep:
            write_calibration_and_run(root / "calibration.json", run)
    c = run.calibration
    R_true, t_true = scene.virtual_R, scene.virtual_t
    say("")
    print_result(args, c.summary(), c.warnings)
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
