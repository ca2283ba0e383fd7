"""The ``batch`` command: every recording of a manifest calibrated in parallel with
Dask, a thin layer over :mod:`mirrorgraph.batch` (manifests, tasks, the cluster,
the summary). It prints one line per finished recording on stderr and
:func:`~mirrorgraph.batch.format_summary` on stdout; it exits with 0 when every
recording was calibrated and 2 when any failed (or the manifest itself is bad).
"""

from __future__ import annotations

import argparse
import json
import sys
from ..initial.estimators import DEFAULT_THRESHOLD_PX, ESTIMATORS
from ..intrinsics import DEFAULT_FOV_DEG
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from .args import (add_height_sigma, add_joints, add_keypoint_offset, add_scale_from, height,
                   image_size, options_from_args, positive, rate, seed)
from .commands import HELP

__all__ = ["add_parsers", "cmd_batch"]


def _workers(text: str) -> int:
    """``--workers``: a whole number of processes, at least 1."""
    v = positive(text)
    if v != int(v):
        raise argparse.ArgumentTypeError(f"must be a whole number of workers, got {text!r}")
    return int(v)


def add_parsers(subparsers) -> None:
    """Add the ``batch`` command to ``mirrorgraph``'s sub-command parsers."""
    p = subparsers.add_parser(
        "batch", help=HELP["batch"],
        description="Calibrate every recording of a manifest in parallel with Dask: a CSV "
                    "(keypoints,intrinsics,out,subject_height; paths relative to it) or a "
                    "folder of recording subfolders. One failed recording is reported "
                    "and does not stop the others; a summary table ends the run. Exit "
                    "status 0 if every recording was calibrated, 2 if any failed.")
    p.add_argument("manifest", help="CSV manifest, or folder of recording subfolders")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of an existing Dask scheduler (default: a local cluster)")
    p.add_argument("--workers", type=_workers, metavar="N",
                   help="local worker processes (default: one per core)")
    p.add_argument("--out-dir", metavar="DIR",
                   help="folder for calibrations the manifest gives no 'out' for")
    p.add_argument("--summary", "--report", dest="summary", metavar="FILE.json",
                   help="also write every recording's result as JSON (--report, its former "
                        "name, still works; elsewhere --report names a folder of figures)")
    p.add_argument("--estimator", default="reflective", choices=ESTIMATORS)
    p.add_argument("--threshold", type=positive, default=None, metavar="PX",
                   help="inlier threshold on the epipolar distance in pixels (default "
                        f"{DEFAULT_THRESHOLD_PX:g})")
    p.add_argument("--min-confidence", type=rate, default=DEFAULT_MIN_CONFIDENCE)
    add_joints(p)
    p.add_argument("--subject-height", type=height, metavar="METRES",
                   help="subject height for recordings whose manifest line gives none")
    add_scale_from(p)
    add_keypoint_offset(p)
    add_height_sigma(p)
    p.add_argument("--image-size", type=image_size, metavar="WxH",
                   help="image size for recordings without intrinsics or a size of their own")
    p.add_argument("--fov", type=positive, default=None, metavar="DEG",
                   help="recordings without intrinsics: a horizontal field of view known "
                        "roughly: the focal length held near it (a 10%% prior, in every std) "
                        f"instead of estimated from the person (which starts from "
                        f"{DEFAULT_FOV_DEG:g})")
    p.add_argument("--no-refine", action="store_true", help="skip the factor graph")
    p.add_argument("--seed", type=seed, default=0, help="seed of the RANSAC (default 0)")
    p.add_argument("--quiet", action="store_true", help="print nothing but the summary "
                                                       "and errors")
    p.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    p.set_defaults(func=cmd_batch)


def cmd_batch(args) -> int:
    """Run ``mirrorgraph batch``; 0 if every recording was calibrated, 2 if any failed."""
    from ..batch import (BatchResult, default_workers, format_summary, read_manifest,
                         results_to_json, run_batch)

    from ..io.atomic import check_outputs

    check_outputs([(args.summary, "--summary"), (args.out_dir, "--out-dir")],
                  inputs=[args.manifest], folders=("--out-dir",))
    recordings = read_manifest(args.manifest, out_dir=args.out_dir)
    opts = options_from_args(args)

    def report(res: BatchResult, done: int, total: int) -> None:
        if args.quiet:
            return
        what = f"ok ({res.seconds:.1f} s)" if res.ok else f"FAILED: {res.message}"
        print(f"[{done}/{total}] {res.name}: {what}", file=sys.stderr)

    if not args.quiet:
        where = args.scheduler or f"a local cluster of " \
            f"{args.workers or default_workers(len(recordings))} worker processes"
        print(f"calibrating {len(recordings)} recording{'s' * (len(recordings) != 1)} "
              f"on {where}", file=sys.stderr)
    results = run_batch(recordings, scheduler=args.scheduler, workers=args.workers,
                        options=opts, progress=report)
    print(format_summary(results))
    if args.summary:
        from ..io.atomic import atomic_write_text
        atomic_write_text(args.summary, json.dumps(results_to_json(results), indent=2) + "\n")
    return 0 if all(r.ok for r in results) else 2
