"""One mirror two ways: ``calibrate`` (the single mirror's run) and ``calibrate_rig`` on the rig of
one camera and one mirror, on the same wide random scenes (issue #25: the single mirror as the
one-camera rig all the way up).

Each scene (:func:`mirrorgraph.synth.make_wide_scene`, the camera matrix given, the subject's
height given) is written as MMPose keypoints with a one-camera rig file beside it, calibrated by
both runs; the table gives each run's mirror rotation error against the truth, its reported std
and its distance error, and the two runs' difference. It shows what moving the single mirror onto
the rig's run would change.

    python bench/bench_one_camera_rig.py [--seeds 20] [--frames 300] [--no-write]

Writes ``bench/RESULTS_one_camera_rig.md`` (machine, command, date).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _report import header  # noqa: E402

import mirrorgraph as mg  # noqa: E402
from mirrorgraph.metrics import mirror_rotation_error_deg, normal_angle_deg  # noqa: E402
from mirrorgraph.synth import make_wide_scene, write_scene  # noqa: E402

RIG = """subject_height = {h}
[[cameras]]
name = "camera"
keypoints = "keypoints_mmpose.json"
intrinsics = "camera.json"
mirrors = ["mirror"]
[[mirrors]]
name = "mirror"
"""


def one(seed: int, frames: int) -> dict:
    s = make_wide_scene(seed, frames=frames)
    out = {"seed": seed}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        write_scene(s, tmp, formats=("mmpose",))
        (tmp / "rig.toml").write_text(RIG.format(h=s.subject_height))
        t0 = time.perf_counter()
        cal = mg.calibrate(tmp / "keypoints_mmpose.json", mg.load_intrinsics(tmp / "camera.json"),
                           mg.CalibrateOptions(subject_height=s.subject_height)).calibration
        t1 = time.perf_counter()
        out["mirror"] = {"err": mirror_rotation_error_deg(cal.normal, s.normal),
                         "std": cal.uncertainty["rotation_std_deg"],
                         "d_err": cal.distance / s.distance - 1, "s": t1 - t0, "n": cal.normal}
        try:
            rig = mg.calibrate_rig(tmp / "rig.toml")
            m = rig.mirrors[0]
            out["rig"] = {"err": mirror_rotation_error_deg(m.normal, s.normal),
                          "std": m.rotation_std_deg, "d_err": m.distance / s.distance - 1,
                          "s": time.perf_counter() - t1, "n": m.normal}
        except mg.MirrorgraphError as exc:
            out["rig"] = {"failed": str(exc)}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--no-write", action="store_true")
    a = p.parse_args(argv)
    rows = []
    head = ("| seed | calibrate: error / std (deg) | distance error | calibrate_rig: error / std "
            "(deg) | distance error | between the two (deg) | time (s) one / rig |\n"
            "|---:|---|---:|---|---:|---:|---|")
    lines = [head]
    for seed in range(a.seeds):
        r = one(seed, a.frames)
        rows.append(r)
        m, g = r["mirror"], r["rig"]
        if "failed" in g:
            line = (f"| {seed} | {m['err']:.3f} / {m['std']:.3f} | {100 * m['d_err']:+.1f} % | "
                    f"failed: {g['failed'][:80]} | | | {m['s']:.1f} / - |")
        else:
            line = (f"| {seed} | {m['err']:.3f} / {m['std']:.3f} | {100 * m['d_err']:+.1f} % | "
                    f"{g['err']:.3f} / {g['std']:.3f} | {100 * g['d_err']:+.1f} % | "
                    f"{2 * normal_angle_deg(m['n'], g['n']):.3f} | {m['s']:.1f} / {g['s']:.1f} |")
        lines.append(line)
        print(line, flush=True)
    ok = [r for r in rows if "failed" not in r["rig"]]
    med = lambda k, w: float(np.median([r[w][k] for r in ok]))  # noqa: E731
    summary = (f"{len(ok)} of {len(rows)} scenes calibrated by both. Median rotation error: "
               f"calibrate {med('err', 'mirror'):.3f} deg, calibrate_rig {med('err', 'rig'):.3f} deg; "
               f"median |distance error|: {100 * float(np.median([abs(r['mirror']['d_err']) for r in ok])):.2f} % "
               f"and {100 * float(np.median([abs(r['rig']['d_err']) for r in ok])):.2f} %; "
               f"median error / std {float(np.median([r['mirror']['err'] / r['mirror']['std'] for r in ok])):.2f} "
               f"and {float(np.median([r['rig']['err'] / r['rig']['std'] for r in ok])):.2f}.")
    print(summary)
    if not a.no_write:
        text = ("# One mirror two ways: `calibrate` and `calibrate_rig` on the one-camera rig\n\n"
                + "\n".join(header(cmd=f"python bench/bench_one_camera_rig.py --seeds {a.seeds} "
                                       f"--frames {a.frames}")) + "\n"
                f"* scenes: `make_wide_scene(seed, frames={a.frames})` (the wide slice, iid detector "
                "noise), camera matrix and subject height given\n\n"
                + "\n".join(lines) + f"\n\n{summary}\n")
        Path(__file__).with_name("RESULTS_one_camera_rig.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
