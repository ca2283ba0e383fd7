"""The metric mirror distance's error over its std where several people share one mirror
(``calibrate_people``), two versions of the code side by side.

With the scale from one person's stature the metric distance is ``D = H / S(n, 1)``
(:mod:`mirrorgraph.pipelines.scale`): only the mirror's normal and that person's stature
move it. Its std holds the height's prior and the measurement's spread, and (the data's
share) the normal's covariance carried through the stature and the stature's sampling.

Scenes: :func:`mirrorgraph.synth.crowd.make_crowd` (COCO-17, 1920x1080, 70 deg, 4 px
noise, half of the people occluded for a few short intervals, the camera matrix given but
in the ``-focal`` settings), ``--people`` people, two layouts: ``near`` (each person 1-4 m before the mirror, the
generator's default) and ``far`` (2.5-6 m: the people far beyond the mirror's foot point,
where a tilt of the normal turns into a scale); a scene the generator cannot place is
left out. The subject height given is the tallest person's (``height_of="tallest"``);
``tallest ok`` says whether the person whose stature set the scale is the truly tallest
(the track's majority owner).

Settings: ``exact`` (the true height, the options' defaults), ``reported`` (the truth +
1.1 cm + 1.9 cm x a normal draw of the scene, ``bench_joints.py``'s model), ``stated``
(the true height with the bench's own error models stated: ``keypoint_offset`` 0, the
synthetic keypoints lie on the joints; ``height_sigma`` 0.5 %), where nothing but the data's
and the stature's own terms is left to cover the error; ``exact-focal`` and
``stated-focal`` the same without the camera matrix (the focal length estimated).

``--before REV`` (default: ``main``) runs from ``git archive REV`` in a temporary folder,
the working tree as ``after``, each in its own processes (``--workers`` at a time).

``--rigs SEEDS``: also two-camera one-mirror rigs (:func:`mirrorgraph.synth.rig.make_rig`
``"2cams1mirror"``, ``--rig-geometries``), the working tree only: whether the graph's
plane distance std with the scale's share covers the metric distance's error.

Usage::

    python bench/bench_people_std.py                       # 3, 4 people, seeds 0-3, ~6 min
    python bench/bench_people_std.py --seeds 0-9 --settings exact,reported,stated
    python bench/bench_people_std.py --layouts far --seeds 0 --no-write
    python bench/bench_people_std.py --rigs 0-4 --reuse     # the rigs too, people rows kept

Writes ``bench/RESULTS_people_std.md`` (machine, command, date, tables) and its JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from _trees import archive, run_worker  # noqa: E402

#: setting -> (height given, RefineOptions fields, the camera matrix given)
SETTINGS = {"exact": ("exact", {}, True),
            "reported": ("reported", {}, True),
            "stated": ("exact", {"keypoint_offset": 0.0, "height_sigma": 0.005}, True),
            "exact-focal": ("exact", {}, False),
            "stated-focal": ("exact", {"keypoint_offset": 0.0, "height_sigma": 0.005}, False)}
#: layout -> each person's distance from the mirror, m
LAYOUTS = {"near": (1.0, 4.0), "far": (2.5, 6.0)}
#: the reported height's model (bench_joints.py's): bias and spread, m
REPORT_BIAS, REPORT_SPREAD = 0.011, 0.019


def _ints(text: str) -> list[int]:
    out = []
    for part in str(text).split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


# ---------------------------------------------------------------- one version's process
def worker(setting: str, layouts: list[str], people: list[int], seeds: list[int],
           frames: int) -> None:
    """Every scene under ``setting`` with the ``mirrorgraph`` first on ``sys.path``; one
    JSON line a scene on stdout."""
    import bench_multiperson as bm
    from mirrorgraph.graph import RefineOptions
    from mirrorgraph.intrinsics import Intrinsics
    from mirrorgraph.pipelines.options import CalibrateOptions
    from mirrorgraph.pipelines.people import calibrate_people
    from mirrorgraph.synth.crowd import make_crowd

    given, fields, known = SETTINGS[setting]
    for layout in layouts:
        for P in people:
            for seed in seeds:
                row = dict(layout=layout, people=P, seed=seed, setting=setting)
                try:
                    crowd = make_crowd(people=P, frames=frames, seed=seed, occluded_rate=0.5,
                                       person_to_mirror=LAYOUTS[layout])
                except ValueError as exc:
                    print(json.dumps({**row, "skipped": str(exc)}), flush=True)
                    continue
                tallest = int(np.argmax(crowd.heights))
                H = float(crowd.heights[tallest])
                if given == "reported":
                    z = np.random.default_rng(10_000 + seed).standard_normal()
                    H += REPORT_BIAS + REPORT_SPREAD * z
                opts = CalibrateOptions(image_size=crowd.image_size, subject_height=H,
                                        refine_options=RefineOptions(**fields) if fields
                                        else None)
                clock = time.perf_counter()
                run = calibrate_people(crowd.detections,
                                       Intrinsics(K=crowd.K, image_size=crowd.image_size)
                                       if known else None, opts)
                wall = time.perf_counter() - clock
                cal = run.calibration
                owner = bm.identity_figures(crowd, run)["owner"]
                setter = run.height_person
                dstd = (cal.uncertainty or {}).get("distance_std")
                d = cal.distance
                row.update(
                    wall_s=wall, to_mirror_m=[float(x) for x in crowd.person_to_mirror],
                    mirror_distance_m=float(crowd.distance),
                    focal_err=float(cal.intrinsics.K[0, 0] / crowd.K[0, 0] - 1.0),
                    tallest_ok=bool(setter is not None and owner[setter] == tallest),
                    distance_err=None if d is None else float(d / crowd.distance - 1.0),
                    distance_rel_std=None if not d or not dstd else float(dstd / d),
                    distance_z=(None if d is None or not dstd
                                else abs(d - crowd.distance) / dstd),
                    rotation_std_deg=float(cal.uncertainty.get("rotation_std_deg", np.nan)),
                    parts=(cal.uncertainty or {}).get("distance_rel_std"))
                print(json.dumps(row), flush=True)


def rig_worker(setting: str, geometries: list[str], seeds: list[int], frames: int) -> None:
    """Every two-camera one-mirror rig (:func:`mirrorgraph.synth.rig.make_rig`
    ``"2cams1mirror"``) under ``setting``, calibrated from the files a user would have
    (:func:`~mirrorgraph.synth.rig.write_rig`); one JSON line a mirror on stdout."""
    import bench_rig as br
    from mirrorgraph.graph import RefineOptions
    from mirrorgraph.pipelines.options import CalibrateOptions
    from mirrorgraph.pipelines.rig import calibrate_rig
    from mirrorgraph.synth.rig import make_rig, write_rig

    _, fields, _ = SETTINGS[setting]
    for geometry in geometries:
        for seed in seeds:
            rig = make_rig("2cams1mirror", frames=frames, seed=seed, geometry=geometry)
            with tempfile.TemporaryDirectory(prefix="people_std_rig_") as tmp:
                opts = CalibrateOptions(subject_height=rig.subject_height,
                                        refine_options=RefineOptions(**fields) if fields
                                        else None)
                clock = time.perf_counter()
                res = calibrate_rig(write_rig(rig, tmp), opts)
                wall = time.perf_counter() - clock
            ev = br.evaluate(res, rig)
            for m in ev["mirrors"]:
                print(json.dumps(dict(
                    geometry=geometry, seed=seed, setting=setting, mirror=m["name"],
                    wall_s=wall, distance_m=float(abs(next(
                        x.distance for x in res.mirrors if x.name == m["name"]))),
                    err_mm=m["dist_mm"], aligned_mm=m["dist_aligned_mm"],
                    std_mm=m["dist_std_mm"], scale_err=ev["scale_err"],
                    distance_z=abs(m["dist_mm"]) / m["dist_std_mm"])), flush=True)


def _run(tree: Path, setting: str, args, rig: bool = False) -> list[dict]:
    if rig:
        cmd = ["--rig-worker", setting, "--rig-geometries", args.rig_geometries,
               "--rigs", args.rigs, "--frames", str(args.frames)]
    else:
        cmd = ["--worker", setting, "--layouts", args.layouts, "--people", args.people,
               "--seeds", args.seeds, "--frames", str(args.frames)]
    return run_worker(tree, "bench_people_std.py", cmd, args.nice)


# ---------------------------------------------------------------- figures
def _fmt(x, spec=".2f"):
    return "n/a" if x is None or not np.isfinite(x) else format(x, spec)


def _num(x):
    return np.nan if x is None else float(x)


def summary(rows: dict, settings: list[str], layouts: list[str]) -> list[str]:
    """Per setting and layout: the distance's std and err/std, before -> after."""
    lines = ["| setting | layout | scenes | distance std % med | err/std med | err/std worst "
             "| err/std > 3 |", "|---|---|---:|---:|---:|---:|---:|"]
    for setting in settings:
        for layout in layouts:
            per = {}
            for ver in ("before", "after"):
                r = [x for x in rows[ver] if x["setting"] == setting
                     and x["layout"] == layout and "skipped" not in x]
                dz = np.array([_num(x["distance_z"]) for x in r])
                ds = np.array([100 * _num(x["distance_rel_std"]) for x in r])
                ok = len(r) and np.isfinite(dz).any()
                per[ver] = dict(n=len(r), ds=np.nanmedian(ds) if ok else np.nan,
                                dzm=np.nanmedian(dz) if ok else np.nan,
                                dzw=np.nanmax(dz) if ok else np.nan,
                                dz3=int(np.sum(dz > 3)))
            b, a = per["before"], per["after"]
            cells = [setting, layout, str(a["n"])]
            for key, spec in (("ds", ".2f"), ("dzm", ".2f"), ("dzw", ".2f"), ("dz3", "d")):
                cells.append(f"{_fmt(b[key], spec)} -> {_fmt(a[key], spec)}")
            lines.append("| " + " | ".join(cells) + " |")
    return lines


def per_scene(rows: dict, settings: list[str]) -> list[str]:
    """Every scene: the distance's error, std and err/std before -> after per setting."""
    head = ["scene", "to mirror (m)", "normal's std deg", "tallest ok"]
    for s in settings:
        head += [f"{s}: err %", f"{s}: std % before -> after",
                 f"{s}: err/std before -> after", f"{s}: normal's part %"]
    lines = ["| " + " | ".join(head) + " |", "|---|---|---:|---" + "|---:" * (len(head) - 4) + "|"]
    idx = {(v, x["setting"], x["layout"], x["people"], x["seed"]): x
           for v in ("before", "after") for x in rows[v]}
    scenes = sorted({(x["layout"], x["people"], x["seed"]) for x in rows["after"]
                     if "skipped" not in x})
    for lay, P, seed in scenes:
        a0 = idx[("after", settings[0], lay, P, seed)]
        cells = [f"{lay} {P}p {seed}", ", ".join(f"{x:.1f}" for x in a0["to_mirror_m"]),
                 _fmt(a0["rotation_std_deg"]), "yes" if a0["tallest_ok"] else "no"]
        for s in settings:
            b, a = idx.get(("before", s, lay, P, seed)), idx.get(("after", s, lay, P, seed))
            if a is None or b is None or "skipped" in a or "skipped" in b:
                cells += ["n/a"] * 4
                continue
            part = (a.get("parts") or {}).get("normal")
            cells += [_fmt(100 * _num(a["distance_err"]), "+.2f"),
                      f"{_fmt(100 * _num(b['distance_rel_std']))} -> "
                      f"{_fmt(100 * _num(a['distance_rel_std']))}",
                      f"{_fmt(_num(b['distance_z']))} -> {_fmt(_num(a['distance_z']))}",
                      _fmt(None if part is None else 100 * part)]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def rig_section(rigs: list[dict], settings: list[str]) -> list[str]:
    """The rigs' mirror distance: err/std over scenes per setting, then every scene."""
    lines = ["| setting | rigs | distance std % med | err/std med | err/std worst | "
             "err/std > 3 |", "|---|---:|---:|---:|---:|---:|"]
    for s in settings:
        r = [x for x in rigs if x["setting"] == s]
        if not r:
            continue
        z = np.array([x["distance_z"] for x in r])
        rel = np.array([100 * x["std_mm"] / 1e3 / x["distance_m"] for x in r])
        lines.append(f"| {s} | {len(r)} | {np.median(rel):.2f} | {np.median(z):.2f} | "
                     f"{z.max():.2f} | {int(np.sum(z > 3))} |")
    lines += ["", "| rig | setting | distance m | err mm | std mm | err/std | "
              "scale-aligned err mm | scale err % |", "|---|---|---:|---:|---:|---:|---:|---:|"]
    for x in sorted(rigs, key=lambda x: (x["geometry"], x["seed"], x["setting"])):
        lines.append(f"| {x['geometry']} {x['seed']} | {x['setting']} | {x['distance_m']:.2f} | "
                     f"{x['err_mm']:+.1f} | {x['std_mm']:.1f} | {x['distance_z']:.2f} | "
                     f"{x['aligned_mm']:+.1f} | {100 * x['scale_err']:+.2f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layouts", default="near,far")
    ap.add_argument("--people", default="3,4")
    ap.add_argument("--seeds", default="0-3")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--settings", default="exact,stated",
                    help="comma-separated, of " + ", ".join(SETTINGS))
    ap.add_argument("--before", default="main", help="the commit compared against")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--out", default=str(HERE / "RESULTS_people_std.md"))
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--rigs", default="",
                    help="seeds of two-camera one-mirror rigs to measure too (after only)")
    ap.add_argument("--rig-geometries", default="favourable,gym,wide")
    ap.add_argument("--rig-settings", default="exact,stated",
                    help="the settings the rigs run under (their own code is not compared)")
    ap.add_argument("--reuse", action="store_true",
                    help="take the rows of each (version, setting) the JSON beside --out "
                         "holds; run only the others")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--rig-worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    layouts = [x for x in args.layouts.split(",") if x]
    if args.worker:
        worker(args.worker, layouts, _ints(args.people), _ints(args.seeds), args.frames)
        return 0
    if args.rig_worker:
        rig_worker(args.rig_worker, [g for g in args.rig_geometries.split(",") if g],
                   _ints(args.rigs), args.frames)
        return 0
    settings = [s for s in args.settings.split(",") if s]
    for s in settings:
        if s not in SETTINGS:
            ap.error(f"--settings: unknown {s!r}; known: {', '.join(SETTINGS)}")
    for s in args.rig_settings.split(","):
        if s and SETTINGS.get(s, ("", {}, False))[::2] != ("exact", True):
            ap.error(f"--rig-settings: {s!r}; the rigs run with the true height: "
                     + ", ".join(k for k, v in SETTINGS.items() if v[::2] == ("exact", True)))
    for lay in layouts:
        if lay not in LAYOUTS:
            ap.error(f"--layouts: unknown {lay!r}; known: {', '.join(LAYOUTS)}")
    import _report
    from _report import header

    clock = time.perf_counter()
    rows = {"before": [], "after": [], "rigs": []}
    json_path = Path(args.out).with_suffix(".json")
    if args.reuse and json_path.exists():
        old_rows = json.loads(json_path.read_text())
        for key in rows:
            rows[key] = [x for x in old_rows.get(key, []) if x["setting"] in settings
                         or key == "rigs"]
    have = {(v, x["setting"]) for v in rows for x in rows[v]}
    with tempfile.TemporaryDirectory(prefix="people_std_") as tmp:
        old = archive(args.before, Path(tmp))
        trees = {"before": Path(tmp), "after": ROOT}
        jobs = [(v, s) for s in settings for v in trees if (v, s) not in have]
        if args.rigs:
            jobs += [("rigs", s) for s in args.rig_settings.split(",")
                     if s and ("rigs", s) not in have]
        with ThreadPoolExecutor(max(1, args.workers)) as pool:
            futs = {job: pool.submit(_run, trees.get(job[0], ROOT), job[1], args,
                                     job[0] == "rigs") for job in jobs}
            for (v, s), fut in futs.items():
                rows[v] += fut.result()
                print(f"{v} {s}: {len(fut.result())} rows "
                      f"({time.perf_counter() - clock:.0f} s)", flush=True)
    minutes = (time.perf_counter() - clock) / 60
    reused = sorted({f"{v} {s}" for v, s in have})
    if reused and args.reuse:
        earlier = json.loads(json_path.read_text()).get("meta", {})
        reused.append(f"that run: {earlier.get('command', '?')} at {earlier.get('date', '?')}, "
                      f"code {earlier.get('code', '?')}")
    meta = {"command": f"`{_report.command(argv, 'bench_people_std.py')}`", "date": _report.now(),
            "code": _report.code_state()}
    lines = ["# The mirror distance's error over its std, several people "
             "(`bench/bench_people_std.py`)", "", *header(code=True),
             f"- before: `{old}` (`git archive {args.before}`); after: the working tree; "
             f"{minutes:.1f} min with {args.workers} workers"
             + (f" (rows reused from the JSON of an earlier run of the same code: "
                f"{', '.join(reused)})" if reused else ""),
             f"- scenes: `make_crowd(people, {args.frames} frames, seed, occluded_rate=0.5, "
             f"person_to_mirror)`, people {args.people}, seeds {args.seeds}, layouts "
             + ", ".join(f"`{k}` {LAYOUTS[k][0]:g}-{LAYOUTS[k][1]:g} m" for k in layouts)
             + "; the camera matrix given (but in `-focal`); `calibrate_people` with the "
             "tallest person's height",
             "- settings: `exact` (the true height, defaults), `reported` (the truth + 1.1 cm "
             "+ 1.9 cm x a normal draw), `stated` (the true height, `keypoint_offset` 0, "
             "`height_sigma` 0.5 %); `-focal`: the same without the camera matrix (the focal "
             "length estimated, its relative std in the data's share)",
             "- figures: `err/std` the metric mirror distance's |error| over its "
             "`distance_std`; `> 3` the count of scenes beyond 3; `normal's part` the "
             "distance's relative std from the normal's covariance through the stature "
             "(after only); `tallest ok` the person whose stature set the scale is the truly "
             "tallest",
             "", "## Over scenes (before -> after)", "", *summary(rows, settings, layouts),
             "", "## Every scene", "", *per_scene(rows, settings), ""]
    if rows["rigs"]:
        lines += ["## Multi-camera rigs: the mirror distance (after)", "",
                  f"`make_rig('2cams1mirror', {args.frames} frames, seed, geometry)` (two "
                  "cameras, one mirror, BODY_25, 4 px noise; geometries "
                  f"{args.rig_geometries}, seeds {args.rigs}), written as a user's files and "
                  "calibrated by `calibrate_rig` with the true height; the distance's std the "
                  "graph's plane marginal with the scale's share (`height_sigma` and the "
                  "stature measurement); `scale-aligned` the error after one scale factor over "
                  "the camera centres (`bench_rig.py`'s).", "",
                  *rig_section(rows["rigs"], list(SETTINGS)), ""]
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        Path(args.out).write_text(text)
        json_path.write_text(json.dumps({**rows, "meta": (earlier if reused and args.reuse
                                                          else meta)}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
