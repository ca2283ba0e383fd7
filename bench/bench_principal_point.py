"""What ``--principal-point free`` does against a principal point off the image centre.

Without intrinsics the focal length is estimated from the person and the reflection; the
principal point is a variable of the graph too, held about the image centre by a prior:
the spread of real cameras (1 % of the larger side, ``centre``, the default) or a loose
one (5 % of the width, ``free``). Each scene (``make_wide_scene(seed, 'gym', 'iid',
frames)``) is calibrated as drawn (its principal point within a few pixels of the
centre) and with every keypoint shifted by ``--offset DX,DY`` px, which is the same scene
seen by a camera whose principal point is that far off the centre. Reported: the
principal point's error and its reported std, the virtual camera's rotation error and
std, the focal length's error.

Run:  python bench/bench_principal_point.py [--seeds 3] [--frames 1000] [--offset 60,-40]
Writes ``bench/RESULTS_principal_point.md`` (header, table) unless ``--no-write``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from _report import header  # noqa: E402


def run_case(seed: int, frames: int, offset: np.ndarray, free: bool) -> dict:
    import mirrorgraph as mg
    from mirrorgraph.graph.options import FocalOptions, RefineOptions
    from mirrorgraph.keypoints import RawDetections
    from mirrorgraph.metrics import mirror_rotation_error_deg
    from mirrorgraph.synth import make_wide_scene

    sc = make_wide_scene(seed, "gym", "iid", frames)
    people = []
    for p in sc.detections.people:
        q = np.array(p, float)
        q[..., :2] += offset
        people.append(q)
    raw = RawDetections(sc.skeleton, sc.detections.frame_ids, people,
                        image_size=sc.image_size, fps=30.0)
    opts = mg.CalibrateOptions(image_size=sc.image_size, subject_height=sc.subject_height,
                               refine_options=RefineOptions(
                                   focal=FocalOptions(principal_point=free)))
    cal = mg.calibrate(raw, None, opts).calibration
    K, u = cal.intrinsics.K, cal.uncertainty
    true_pp = sc.K[:2, 2] + offset
    return dict(seed=seed, offset=offset.tolist(), free=free,
                pp_err=(K[:2, 2] - true_pp).tolist(),
                pp_std=list(u.get("principal_point_std_px") or [np.nan, np.nan]),
                focal_err_pct=100 * (K[0, 0] / sc.K[0, 0] - 1),
                rot_err=mirror_rotation_error_deg(cal.normal, sc.normal),
                rot_std=float(u["rotation_std_deg"]))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--offset", default="60,-40", help="DX,DY px of the shifted scenes")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    shift = np.array([float(v) for v in args.offset.split(",")])
    rows = []
    for seed in range(args.seeds):
        for offset in (np.zeros(2), shift):
            for free in (False, True):
                r = run_case(seed, args.frames, offset, free)
                rows.append(r)
                print(r, flush=True)
    table = ["| seed | principal point off the centre (px) | mode | principal point error (px) "
             "| its std (px) | error / std | focal error | rotation error (deg) | rotation std "
             "(deg) |", "|---:|---|---|---|---|---|---:|---:|---:|"]
    for r in rows:
        e, s = np.array(r["pp_err"]), np.array(r["pp_std"])
        table.append(f"| {r['seed']} | {r['offset'][0]:+.0f}, {r['offset'][1]:+.0f} | "
                     f"{'free' if r['free'] else 'centre'} | {e[0]:+.1f}, {e[1]:+.1f} | "
                     f"{s[0]:.1f}, {s[1]:.1f} | {abs(e[0]) / s[0]:.1f}, {abs(e[1]) / s[1]:.1f} | "
                     f"{r['focal_err_pct']:+.1f} % | {r['rot_err']:.2f} | {r['rot_std']:.2f} |")
    text = "\n".join(["# The principal point without intrinsics (`bench/bench_principal_point.py`)",
                      "", *header(argv=argv), "", *table, ""])
    print(text)
    if not args.no_write:
        (ROOT / "bench" / "RESULTS_principal_point.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
