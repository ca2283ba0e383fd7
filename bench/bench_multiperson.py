"""Every person before one mirror against the one-person run, on synthetic gym scenes.

Scenes: :func:`mirrorgraph.synth.crowd.make_crowd` (3-5 people 1-4 m before one mirror,
4 px noise, half of the people briefly occluded in one view or both). Each scene is
calibrated twice from the same detections, with the camera matrix given and without it
(the focal length estimated): ``calibrate`` (one pair a frame) and
``calibrate_people`` (every person with their own reflection, tracked, in one graph).
Figures: the mirror's rotation error (the virtual camera's, deg), the focal length's
error (%), the pairs the graph used, the people found, identity switches (a track whose
person detection changes owner from one of its frames to the next, summed over tracks),
pairs of a wrong reflection, each person's PA-MPJPE (mm; the track matched to the true
person who owns most of its frames) and the wall time; with ``--oracle`` also the same
graph from the true pairs (identities known: the best the pairing can give it).

    python bench/bench_multiperson.py                       # 3, 4, 5 people, 2 seeds
    python bench/bench_multiperson.py --people 3,5 --seeds 0-5 --frames 600
    python bench/bench_multiperson.py --people 5 --seeds 2,4 --camera unknown --oracle
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402  (the header every results file shares)

from mirrorgraph.intrinsics import Intrinsics
from mirrorgraph.keypoints import PairedKeypoints
from mirrorgraph.metrics import mirror_rotation_error_deg, pa_mpjpe
from mirrorgraph.pipelines.mirror import calibrate
from mirrorgraph.pipelines.options import CalibrateOptions
from mirrorgraph.pipelines.people import calibrate_people
from mirrorgraph.skeletons import people_skeleton
from mirrorgraph.synth.crowd import make_crowd

HERE = Path(__file__).resolve().parent


def _range(spec: str) -> list[int]:
    out = []
    for part in spec.split(","):
        a, _, b = part.partition("-")
        out.extend(range(int(a), int(b or a) + 1))
    return out


def identity_figures(crowd, people_run) -> dict:
    """Identity switches, wrong pairs, and each track's true person (majority)."""
    det = people_run.pairing.detections                           # (T, P, 2)
    switches = wrong = 0
    owner = []
    for k in range(det.shape[1]):
        own = []
        for t in range(det.shape[0]):
            a, b = det[t, k]
            if a < 0:
                continue
            oa, ob = crowd.truth_person[t][a], crowd.truth_person[t][b]
            if oa != ob or crowd.truth_reflection[t][a] or not crowd.truth_reflection[t][b]:
                wrong += 1
            own.append(oa)
        own = np.array(own, dtype=int)
        switches += int(np.count_nonzero(own[1:] != own[:-1]))
        owner.append(int(np.bincount(own).argmax()) if len(own) else -1)
    return {"switches": switches, "wrong_pairs": wrong, "owner": owner}


def person_errors(crowd, people_run, owner) -> list[float]:
    """PA-MPJPE (mm) of every true person's limb joints (the calibration joints): the
    joints of the track that follows them longest."""
    out = []
    for p in range(crowd.num_people):
        tracks = [k for k, o in enumerate(owner) if o == p]
        if not tracks or people_run.joints3d is None:
            out.append(float("nan"))
            continue
        counts = [int(people_run.valid3d[k].any(-1).sum()) for k in tracks]
        k = tracks[int(np.argmax(counts))]
        limbs = np.zeros(crowd.skeleton.num_joints, dtype=bool)
        limbs[crowd.skeleton.calibration_joints] = True
        out.append(1000.0 * pa_mpjpe(people_run.joints3d[k], crowd.joints3d[p],
                                     people_run.valid3d[k] & limbs))
    return out


def oracle_paired(crowd) -> tuple[PairedKeypoints, tuple[str, ...]]:
    """Every person with their reflection by the truth (identities known), side by side as
    :func:`~mirrorgraph.initial.people.pair_people` lays them out, and the joints to use."""
    T, J, P = len(crowd.frame_ids), crowd.skeleton.num_joints, crowd.num_people
    R = np.full((T, P, J, 3), np.nan)
    R[..., 2] = 0.0
    M = R.copy()
    for t in range(T):
        for det, p, refl in zip(crowd.detections.people[t], crowd.truth_person[t],
                                crowd.truth_reflection[t]):
            if refl:
                M[t, p] = det[crowd.skeleton.flip]
            else:
                R[t, p] = det
    sk = people_skeleton(crowd.skeleton, P)
    joints = (crowd.skeleton.calibration_joints[None] + J * np.arange(P)[:, None]).ravel()
    paired = PairedKeypoints(skeleton=sk, frame_ids=crowd.frame_ids, real=R.reshape(T, -1, 3),
                             mirror=M.reshape(T, -1, 3), image_size=crowd.image_size)
    return paired, tuple(sk.joints[j] for j in joints)


def run_scene(people: int, seed: int, frames: int, known: bool, oracle: bool = False) -> dict:
    crowd = make_crowd(people=people, frames=frames, seed=seed, occluded_rate=0.5)
    intr = Intrinsics(K=crowd.K, image_size=crowd.image_size) if known else None
    opts = CalibrateOptions(image_size=crowd.image_size)
    row = {"people": people, "seed": seed, "frames": frames, "known_K": known,
           "to_mirror_m": [round(float(x), 2) for x in crowd.person_to_mirror],
           "mirror_distance_m": float(crowd.distance)}
    clock = time.perf_counter()
    one = calibrate(crowd.detections, intr, opts).calibration
    row["one"] = {"rot_deg": mirror_rotation_error_deg(one.normal, crowd.normal),
                  "focal_pct": 100.0 * (one.intrinsics.K[0, 0] / crowd.K[0, 0] - 1.0),
                  "pairs": int(one.pairs_used), "seconds": time.perf_counter() - clock}
    if oracle:
        clock = time.perf_counter()
        paired, joints = oracle_paired(crowd)
        cal = calibrate(paired, intr, replace(opts, joints=joints)).calibration
        row["oracle"] = {"rot_deg": mirror_rotation_error_deg(cal.normal, crowd.normal),
                         "focal_pct": 100.0 * (cal.intrinsics.K[0, 0] / crowd.K[0, 0] - 1.0),
                         "pairs": int(cal.pairs_used), "seconds": time.perf_counter() - clock}
    clock = time.perf_counter()
    run = calibrate_people(crowd.detections, intr, opts)
    seconds = time.perf_counter() - clock
    cal = run.calibration
    ident = identity_figures(crowd, run)
    row["all"] = {"rot_deg": mirror_rotation_error_deg(cal.normal, crowd.normal),
                  "focal_pct": 100.0 * (cal.intrinsics.K[0, 0] / crowd.K[0, 0] - 1.0),
                  "pairs": int(cal.pairs_used), "seconds": seconds,
                  "people_found": run.num_people, "tracks_found": run.pairing.tracks_found,
                  "switches": ident["switches"], "wrong_pairs": ident["wrong_pairs"],
                  "pa_mpjpe_mm": person_errors(crowd, run, ident["owner"])}
    return row


def render(rows: list[dict], meta: dict) -> str:
    """The report of ``rows``; its header the run's own (``meta``: :func:`_report.record`)."""
    lines = ["# Every person before one mirror (bench_multiperson)", "",
             *_report.recorded_header(meta, note="the machine shared: the times are wall "
                                                 "seconds under that load, compare them "
                                                 "within a row"), "",
             "Scenes: `mirrorgraph.synth.crowd.make_crowd` (COCO-17, 1920x1080, 70 deg, 4 px "
             "noise, half of the people occluded in one view or both for 5-40 frames, one "
             "to three times). *one*: `calibrate` (one pair a frame); *all*: "
             "`calibrate_people` (every person with their own reflection, tracked, in the "
             "one graph). rot: the virtual camera's rotation error; focal: the estimated "
             "focal length's error (camera matrix not given); pairs: pairs the graph used; "
             "switches: identity switches within tracks; wrong: pairs of a person with "
             "another's reflection (or a reflection taken for a person); PA-MPJPE of each "
             "true person's limb joints (the 12 calibration joints, mm).", ""]
    for known in (True, False):
        sub = [r for r in rows if r["known_K"] == known]
        if not sub:
            continue
        header = ("| people | seed | to mirror (m) | rot one | rot all | "
                  + ("" if known else "focal one | focal all | ")
                  + "pairs one | pairs all | found / tracks | switches | wrong | "
                  "PA-MPJPE (mm) | s one | s all |")
        lines += [f"## Camera matrix {'given' if known else 'not given (focal estimated)'}",
                  "", header, "|" + "---|" * (header.count("|") - 1)]
        for r in sub:
            o, a = r["one"], r["all"]
            lines.append(
                f"| {r['people']} | {r['seed']} | {', '.join(f'{x:.1f}' for x in r['to_mirror_m'])} "
                f"| {o['rot_deg']:.3f} | {a['rot_deg']:.3f} | "
                + ("" if known else f"{o['focal_pct']:+.2f} % | {a['focal_pct']:+.2f} % | ")
                + f"{o['pairs']} | {a['pairs']} | {a['people_found']} / {a['tracks_found']} | "
                f"{a['switches']} | {a['wrong_pairs']} | "
                f"{', '.join(f'{x:.0f}' for x in a['pa_mpjpe_mm'])} | "
                f"{o['seconds']:.1f} | {a['seconds']:.1f} |")
        one = np.array([r["one"]["rot_deg"] for r in sub])
        al = np.array([r["all"]["rot_deg"] for r in sub])
        lines += ["", f"Median rotation error: one {np.median(one):.3f} deg, all "
                  f"{np.median(al):.3f} deg; all better on {int(np.sum(al < one))} of "
                  f"{len(sub)} scenes."]
        if not known:
            for p in sorted({r["people"] for r in sub}):
                fo = [abs(r["one"]["focal_pct"]) for r in sub if r["people"] == p]
                fa = [abs(r["all"]["focal_pct"]) for r in sub if r["people"] == p]
                lines.append(f"{p} people: median |focal error| one {np.median(fo):.2f} %, "
                             f"all {np.median(fa):.2f} %.")
        lines.append("")
    orc = [r for r in rows if "oracle" in r]
    if orc:
        lines += ["## Identities known", "",
                  "*oracle*: the same graph from every person paired with their reflection by "
                  "the truth (`calibrate` on the people side by side), the best the pairing "
                  "can give it.", "",
                  "| people | seed | camera | rot oracle | rot all | focal oracle | focal all |",
                  "|---|---|---|---|---|---|---|"]
        for r in orc:
            o, a = r["oracle"], r["all"]
            lines.append(f"| {r['people']} | {r['seed']} | "
                         f"{'given' if r['known_K'] else 'estimated'} | {o['rot_deg']:.3f} | "
                         f"{a['rot_deg']:.3f} | {o['focal_pct']:+.2f} % | "
                         f"{a['focal_pct']:+.2f} % |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", default="3,4,5")
    ap.add_argument("--seeds", default="0-1")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--camera", choices=("both", "known", "unknown"), default="both")
    ap.add_argument("--out", default=str(HERE / "RESULTS_multiperson.md"))
    ap.add_argument("--oracle", action="store_true",
                    help="also the graph from the true pairs (identities known)")
    ap.add_argument("--report-only", action="store_true",
                    help="render --out from its .json beside it, run nothing")
    args = ap.parse_args(argv)
    if args.report_only:
        data = json.loads(Path(args.out).with_suffix(".json").read_text())
        Path(args.out).write_text(render(data["rows"], data))
        print(Path(args.out).read_text())
        return 0
    modes = {"both": (True, False), "known": (True,), "unknown": (False,)}[args.camera]
    rows = []
    for known in modes:
        for p in _range(args.people):
            for s in _range(args.seeds):
                row = run_scene(p, s, args.frames, known, args.oracle)
                rows.append(row)
                print(json.dumps({k: row[k] for k in ("people", "seed", "known_K")}),
                      f"rot one {row['one']['rot_deg']:.3f} all {row['all']['rot_deg']:.3f}",
                      f"focal one {row['one']['focal_pct']:+.2f} all "
                      f"{row['all']['focal_pct']:+.2f}",
                      f"switches {row['all']['switches']}", flush=True)
    meta = _report.record(argv=argv, script="bench_multiperson.py")
    Path(args.out).with_suffix(".json").write_text(json.dumps({"rows": rows, **meta}, indent=1))
    text = render(rows, meta)
    Path(args.out).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
