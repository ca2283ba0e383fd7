#!/usr/bin/env python
"""The focal length's bias bootstrap (``graph/solve.focal_bias``): replicates, truth, rule.

    python bench/bench_focal_bias.py --scenes 20 --shard 0/2 --json a.json --no-write
    python bench/bench_focal_bias.py --report-only a.json b.json   # RESULTS_focal_bias.md

Every scene is calibrated once from the detections with the image size alone (the
focal length estimated, :func:`mirrorgraph.calibrate`); at the call of
:func:`mirrorgraph.graph.solve.focal_bias` the bootstrap is run with ``--max-replicates``
noisy replicates (seed 0: the first ``R`` of them are what ``bias_replicates = R``
draws) on two truths, the joints the solve returns (the joints pass's) and the
calibration graph's own joints (the ones whose bones hold the focal length), each
solve timed. From that one solve, every variant's focal std
(:func:`~mirrorgraph.graph.marginals.floor_focal` with its bias variance) against the
scene's error, for ``R`` in :data:`REPLICATES` over the disjoint draws of ``R`` of the
replicates, and each rule of :data:`RULES` for the squared bias.

Scenes: ``bench_focal.py``'s issue-23 set (even: ``make_wide_scene``, wide; odd:
``make_scene`` favourable / gym / low parallax / wide, focal 700-2200 px, the CMU take
in every other one; principal points off centre), ``mirrorgraph synth`` scenes (seeds 3
on, focal 1100 px, 300 frames, no subject height: ``tests/pipelines/test_lines.py``'s is
seed 3) and the independent generator's fixtures (``../shared/fixtures``).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for _p in (ROOT, ROOT / "bench"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import mirrorgraph as mg  # noqa: E402
import mirrorgraph.graph.solve as gsolve  # noqa: E402
import mirrorgraph.graph.stages as gstages  # noqa: E402
from _report import emit, record, recorded_header  # noqa: E402
from bench_focal import fixture_scene, honest_scene  # noqa: E402
from mirrorgraph.graph.marginals import floor_focal  # noqa: E402

FIXTURES = ROOT.parent / "shared" / "fixtures"
if not FIXTURES.is_dir():
    FIXTURES = Path("/work/shared/fixtures")


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# ----------------------------------------------------------------- the hook
#: The squared bias from the replicates' mean offset ``b`` and its sampling variance
#: ``s2`` (``s^2 / R``): unbiased (clipped at 0), never under its own sampling variance,
#: and the posterior mean under a flat prior on the bias.
RULES = {"unbiased": lambda b, s2: max(b * b - s2, 0.0),
         "floor": lambda b, s2: max(b * b, s2),
         "posterior": lambda b, s2: b * b + s2}
#: Replicates per bootstrap compared (each over the disjoint draws ``max_r // R``).
REPLICATES = (1, 2, 3, 6)
_CAPTURE: dict = {}


def _capture_joints_pass_stage(orig):
    def wrapped(run, lengths, torso, points):
        if run.config.joints_pass:
            _CAPTURE["calibration_points"] = np.array(points, copy=True)
        return orig(run, lengths, torso, points)
    return wrapped


def _std_with(state, cam: int, model_var: float) -> float:
    """The camera's headline focal std with ``model_var`` px^2 of bias variance
    (:func:`floor_focal` on a shallow copy, as :func:`judge_focal` calls it)."""
    st = dataclasses.replace(state)
    floor = state.scores.prior_floor                # floor_focal takes the floor it finds
    try:
        floor_focal(st, set(), disagreement=False,
                    model_var={cam: model_var} if model_var > 0 else None)
    finally:
        state.scores.prior_floor = floor
    return float(np.asarray(st.intrinsics_std[cam], float)[0])


def _hook(orig, max_r: int, calls: list):
    def wrapped(state, rig, opts, config, height, skip=frozenset(), *, replicates=None, seed=0):
        rec = {"truths": {}}
        cams = [i for i, c in enumerate(rig.cameras) if c.estimate_focal and i not in skip
                and i < len(state.intrinsics)]
        if cams:
            i = cams[0]
            rec["cam"] = i
            rec["focal_px"] = float(np.asarray(state.intrinsics[i])[0, 0])
            rec["std_no_bias_px"] = _std_with(state, i, 0.0)
            # the package's own truth set aside (a field of SolveState where it has one)
            plain = ({"calibration_points": None} if hasattr(state, "calibration_points")
                     else {})
            truths = {"joints": dataclasses.replace(state, **plain)}
            if "calibration_points" in _CAPTURE:
                truths["calibration"] = dataclasses.replace(
                    state, points=_CAPTURE["calibration_points"], **plain)
            for name, st in truths.items():
                t0 = time.perf_counter()
                out = orig(st, rig, opts, config, height, skip, replicates=max_r, seed=seed)
                dt = time.perf_counter() - t0
                if i in out:
                    o = out[i]
                    rec["truths"][name] = {"noiseless_px": o["noiseless_px"],
                                           "replicates": o["replicates"],
                                           "replicate_std_px": o["replicate_std_px"],
                                           "seconds": dt, "solves": max_r + 1}
                else:
                    rec["truths"][name] = {"failed": True, "seconds": dt}
            rec["stds"] = {}
            for name, t in rec["truths"].items():
                if t.get("failed"):
                    continue
                fr, ref, s = np.array(t["replicates"]), t["noiseless_px"], t["replicate_std_px"]
                for R in REPLICATES:
                    for k in range(max_r // R):          # disjoint draws of R replicates
                        b = float(fr[k * R:(k + 1) * R].mean() - ref)
                        s2 = s * s / R
                        for rule, var in RULES.items():
                            rec["stds"][f"{name} R={R} {rule} #{k}"] = _std_with(
                                state, i, var(b, s2))
        calls.append(rec)
        return orig(state, rig, opts, config, height, skip, replicates=replicates, seed=seed)
    return wrapped


# ----------------------------------------------------------------- scenes
def synth_scene(seed: int, frames: int) -> dict:
    """``mirrorgraph synth --seed SEED --focal 1100``: the lines test's generator, no
    subject height given (as the test)."""
    from mirrorgraph.cli import main
    from mirrorgraph.io import read_keypoints
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp) / "scene"
        assert main(["synth", "--out", str(d), "--frames", str(frames), "--seed", str(seed),
                     "--focal", "1100", "--quiet"]) == 0
        K = np.asarray(json.loads((d / "camera.json").read_text())["K"], float)
        det = read_keypoints(d / "keypoints_mmpose.json")
    return {"index": f"synth{seed}", "kind": "synth (lines test)", "detections": det,
            "K": K, "image_size": (1920, 1080), "height": None}


def scene_list(n: int, frames: int, synth: int, fixtures: bool) -> list[tuple[str, object]]:
    out = [("honest", i) for i in range(n)]
    out += [("synth", 3 + k) for k in range(synth)]
    if fixtures and FIXTURES.is_dir():
        out += [("fixture", p.name) for p in sorted(FIXTURES.iterdir()) if p.is_dir()]
    return out


def make(kind: str, key, frames: int) -> dict:
    if kind == "honest":
        return honest_scene(int(key), frames)
    if kind == "synth":
        return synth_scene(int(key), min(frames, 300))
    return fixture_scene(FIXTURES / key)


def run_scene(sc: dict, max_r: int) -> dict:
    calls: list = []
    orig_fb, orig_jp = gsolve.focal_bias, gstages._joints_pass_stage
    gsolve.focal_bias = _hook(orig_fb, max_r, calls)
    gstages._joints_pass_stage = _capture_joints_pass_stage(orig_jp)
    _CAPTURE.clear()
    t0 = time.perf_counter()
    try:
        opts = mg.CalibrateOptions(subject_height=sc.get("height"), image_size=sc["image_size"])
        cal = mg.calibrate(sc["detections"], None, opts).calibration
        err = None
    except Exception as exc:  # noqa: BLE001 - report, do not stop the benchmark
        cal, err = None, f"{type(exc).__name__}: {exc}"
    finally:
        gsolve.focal_bias, gstages._joints_pass_stage = orig_fb, orig_jp
    out = {"index": sc["index"], "kind": sc["kind"], "f_true": float(sc["K"][0, 0]),
           "wall_s": time.perf_counter() - t0, "calls": calls}
    if err:
        out["failed"] = err
        return out
    est = cal.intrinsics.estimated or {}
    out.update(f_out=float(cal.intrinsics.K[0, 0]),
               std_out=float(est.get("std_px", np.nan)),
               determined=bool(est.get("determined", est.get("estimated"))))
    return out


# ----------------------------------------------------------------- report
def first_call(r: dict) -> dict | None:
    """The scene's first call with a bias measured (the calibration's solve)."""
    return next((c for c in r.get("calls", []) if c.get("stds")), None)


def variant_z(rows: list[dict], variant: str) -> tuple[list[float], dict]:
    """|error| / std over every scene and disjoint draw of ``variant`` (``"truth R=n
    rule"``), and per scene the first draw's (seed 0's: what the package reports)."""
    z, first = [], {}
    for r in rows:
        c = first_call(r)
        if c is None:
            continue
        err = abs(c["focal_px"] - r["f_true"])
        k = 0
        while f"{variant} #{k}" in c["stds"]:
            z.append(err / c["stds"][f"{variant} #{k}"])
            if k == 0:
                first[r["index"]] = z[-1]
            k += 1
    return z, first


def solve_seconds(rows: list[dict]) -> np.ndarray:
    """Seconds per bootstrap solve (the joints truth's, per scene)."""
    out = []
    for r in rows:
        c = first_call(r)
        t = c and c["truths"].get("joints")
        if t and not t.get("failed"):
            out.append(t["seconds"] / t["solves"])
    return np.asarray(out, float)


def table_row(label: str, z: list[float], first: dict, secs: str) -> str:
    z = np.asarray(z, float)
    over = [f"{k} ({v:.1f})" for k, v in sorted(first.items(), key=lambda kv: -kv[1]) if v > 3]
    return (f"| {label} | {len(z)} | {np.median(z):.2f} | {np.percentile(z, 90):.2f} | "
            f"{z.max():.2f} | {np.mean(z > 2):.0%} | {np.mean(z > 3):.0%} | "
            f"{', '.join(over) or 'none'} | {secs} |")


def report(data: dict) -> list[str]:
    rows = [r for r in data["rows"] if not r.get("failed")]
    measured = [r for r in rows if first_call(r)]
    secs = solve_seconds(measured)
    L = ["# The focal length's bias bootstrap: replicates and truth (`bench/bench_focal_bias.py`)",
         "", *recorded_header(data["meta"]), ""]
    L += [data["note"], ""] if data.get("note") else []
    kinds = sorted({r["kind"] for r in rows})
    L += [f"{len(data['rows'])} scenes ({', '.join(kinds)}), {data['frames']} frames "
          "(the synth scenes 300), given the image size alone; "
          f"{len(measured)} with a bias measured (the others' focal length called "
          f"undetermined); {len(data['rows']) - len(rows)} failed. Every variant's focal std "
          "(`floor_focal` with its bias variance) from the same solve, against the error "
          "`K[0, 0]` minus the truth. `b`: the replicates' mean minus the noiseless "
          "reference; `s^2`: the replicates' marginal variance over R. Rules for the "
          "squared bias: *unbiased* `max(b^2 - s^2, 0)` (the package before), *floor* "
          "`max(b^2, s^2)` (never under its own sampling variance), *posterior* "
          "`b^2 + s^2` (its mean under a flat prior). Draws: the disjoint groups of R "
          f"of the {data.get('max_replicates', 6)} replicates (seed 0; draw #0 is what "
          "`bias_replicates = R` reports), pooled over scenes.",
          "", f"Seconds per bootstrap solve at this run's load: median {np.median(secs):.1f}, "
          f"largest {secs.max():.1f} (R replicates: R + 1 solves)."]
    nb = {r["index"]: abs(first_call(r)["focal_px"] - r["f_true"])
          / first_call(r)["std_no_bias_px"] for r in measured}
    before = data.get("before_variant", "joints R=1 unbiased")
    after = data.get("after_variant", "calibration R=1 floor")
    L += ["", f"Before (*{before}*) and after (*{after}*) side by side, draw #0 (what the "
          "package reports), per kind of scene: median / largest |error| / std, scenes "
          "beyond 3:", "", "| kind | scenes | before | after |", "|---|---:|---|---|"]
    for kind in sorted({r["kind"].split(" (")[0] for r in measured}) + ["all"]:
        sel = [r for r in measured if kind == "all" or r["kind"].split(" (")[0] == kind]
        cells = []
        for v in (before, after):
            z = np.asarray(list(variant_z(sel, v)[1].values()), float)
            cells.append(f"{np.median(z):.2f} / {z.max():.2f}, {int(np.sum(z > 3))}")
        L.append(f"| {kind} | {len(sel)} | {cells[0]} | {cells[1]} |")
    L += ["", "Every variant (pooled over the disjoint draws):", "",
          "| variant | draws | median err/std | p90 | largest | > 2 | > 3 | "
          "scenes > 3 (draw #0) | bootstrap s (median) |",
          "|---|---:|---:|---:|---:|---:|---:|---|---:|"]
    L.append(table_row("no bias term (`bias_replicates = 0`)", list(nb.values()), nb, "0"))
    names = []
    for r in measured:
        for k in first_call(r)["stds"]:
            v = k.rsplit(" #", 1)[0]
            if v not in names:
                names.append(v)
    for v in names:
        z, first = variant_z(measured, v)
        R = int(v.split("R=")[1].split()[0])
        L.append(table_row(v, z, first, f"{np.median(secs) * (R + 1):.1f}"))
    L += ["", "Per scene (bias px: the replicates' mean minus the noiseless reference, the "
          "first replicate / all of them; spread: the replicates' own std against their "
          "marginal std, px):", "",
          "| scene | kind | f true | f est | error px | std, no bias | joints pass's joints: "
          "bias 1 / all, spread / marginal | calibration's joints: bias 1 / all, spread / "
          "marginal | std before (joints, R=1 unbiased) | std after |",
          "|---|---|---:|---:|---:|---:|---|---|---:|---:|"]
    for r in measured:
        c = first_call(r)
        cell = {}
        for name, t in c["truths"].items():
            if t.get("failed"):
                cell[name] = "failed"
                continue
            e = np.asarray(t["replicates"]) - t["noiseless_px"]
            cell[name] = (f"{e[0]:+.0f} / {e.mean():+.0f}, {e.std(ddof=1):.0f} / "
                          f"{t['replicate_std_px']:.0f}")
        L.append(f"| {r['index']} | {r['kind']} | {r['f_true']:.0f} | {c['focal_px']:.0f} | "
                 f"{c['focal_px'] - r['f_true']:+.0f} | {c['std_no_bias_px']:.0f} | "
                 f"{cell.get('joints', '-')} | {cell.get('calibration', '-')} | "
                 f"{c['stds'].get('joints R=1 unbiased #0', np.nan):.0f} | "
                 f"{c['stds'].get(after + ' #0', np.nan):.0f} |")
    return L


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=16, help="issue 23's scenes 0..N-1")
    ap.add_argument("--synth", type=int, default=3, help="mirrorgraph synth scenes, seeds 3..")
    ap.add_argument("--frames", type=int, default=500)
    ap.add_argument("--max-replicates", type=int, default=6)
    ap.add_argument("--no-fixtures", action="store_true")
    ap.add_argument("--shard", default="0/1", help="I/N: scenes i, i + N, ...")
    ap.add_argument("--json", help="write the data to this file too")
    ap.add_argument("--report-only", nargs="+", metavar="JSON")
    ap.add_argument("--note", default="")
    ap.add_argument("--before", default="joints R=1 unbiased",
                    help="the variant the package reports before (--report-only)")
    ap.add_argument("--after", default="calibration R=1 floor",
                    help="the variant it reports after (--report-only)")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS_focal_bias.md"))
    args = ap.parse_args()
    if args.report_only:
        parts = [json.loads(Path(p).read_text()) for p in args.report_only]
        data = dict(parts[0], rows=[r for p in parts for r in p["rows"]])
        data["note"] = args.note or data.get("note", "")
        data["before_variant"], data["after_variant"] = args.before, args.after
        emit(report(data), None if args.no_write else args.out)
        return 0
    i, n = (int(x) for x in args.shard.split("/"))
    todo = scene_list(args.scenes, args.frames, args.synth, not args.no_fixtures)[i::n]
    data = {"meta": record(code=True), "frames": args.frames, "note": args.note,
            "max_replicates": args.max_replicates, "rows": []}
    for kind, key in todo:
        sc = make(kind, key, args.frames)
        r = run_scene(sc, args.max_replicates)
        data["rows"].append(r)
        c = first_call(r)
        log(f"{kind} {key}: {r['wall_s']:.0f} s, f {r.get('f_out', np.nan):.0f} vs "
            f"{r['f_true']:.0f}" + (f", std joints R=1 "
                                    f"{c['stds'].get('joints R=1 unbiased #0', np.nan):.0f}"
                                    f", calibration R=1 floor "
                                    f"{c['stds'].get('calibration R=1 floor #0', np.nan):.0f}"
                                    if c else " (no bias)"))
        if args.json:
            Path(args.json).write_text(json.dumps(data))
    emit(report(data), None if args.no_write else args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
