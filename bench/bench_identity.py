"""Are the results of a refactoring the same numbers? A gate for moves that should not change the maths.

Runs a fixed set of small cases through the public API (one mirror with and without intrinsics,
the initialisation alone, two rigs, one with a camera's focal length estimated), records every
number each result writes (its JSON) and a digest of the 3D joints, and either saves them
(``--save FILE``) or compares them with a saved file (``--against FILE``): a table of the cases,
"identical" where every number is bit-identical, else the largest relative difference and the
field where it is.

    python bench/bench_identity.py --save /tmp/before.json       # on the old tree
    python bench/bench_identity.py --against /tmp/before.json    # on the new tree

It writes no RESULTS file: its answer is the comparison (under the header of
``bench/_report.py``: date, command, machine, commit), for the commit message.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import mirrorgraph as mg
from _report import header


def _digest(a: np.ndarray | None) -> str | None:
    if a is None:
        return None
    return hashlib.sha256(np.ascontiguousarray(a, dtype=np.float64).tobytes()).hexdigest()[:16]


def _plain(obj):
    """The JSON's numbers, with the run's timings left out (they differ every run)."""
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items() if k not in ("timings", "wall_s", "seconds")}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, float) and not np.isfinite(obj):
        return repr(obj)
    return obj


def single_cases() -> dict:
    from mirrorgraph.synth import make_scene, make_wide_scene

    out = {}
    s = make_scene(frames=300, seed=0)
    run = mg.calibrate(s.detections, s.intrinsics, mg.CalibrateOptions(subject_height=s.subject_height))
    out["single_known"] = {"json": _plain(run.calibration.to_dict()), "joints3d": _digest(run.joints3d)}
    run = mg.calibrate(s.detections, s.intrinsics, mg.CalibrateOptions(refine=False))
    out["single_init_only"] = {"json": _plain(run.calibration.to_dict())}
    w = make_wide_scene(1, frames=300)
    run = mg.calibrate(w.detections, None, mg.CalibrateOptions(subject_height=w.subject_height,
                                                               image_size=w.image_size))
    out["single_focal"] = {"json": _plain(run.calibration.to_dict()), "joints3d": _digest(run.joints3d)}
    return out


def rig_cases(folder: Path) -> dict:
    from mirrorgraph.rigs.config import load_rig_config
    from mirrorgraph.pipelines.rig import calibrate_rig
    from mirrorgraph.synth import make_rig, write_rig

    out = {}
    for kind, seed, drop in (("2cams1mirror", 4, []), ("4cams", 5, [1])):
        r = make_rig(kind, frames=120, seed=seed, geometry="wide")
        write_rig(r, folder / kind)
        cfg = load_rig_config(folder / kind / "rig.toml")
        cams = tuple(dataclasses.replace(c, intrinsics=None, image_size=tuple(r.image_size))
                     if i in drop else c for i, c in enumerate(cfg.cameras))
        cal = calibrate_rig(dataclasses.replace(cfg, cameras=cams),
                            mg.CalibrateOptions(subject_height=r.subject_height, seed=seed))
        text = json.dumps(_plain(cal.to_dict())).replace(str(folder), "<tmp>")
        out[f"rig_{kind}"] = {"json": json.loads(text)}
    return out


def _flatten(obj, prefix=""):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _flatten(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _flatten(v, f"{prefix}[{i}]")
    else:
        yield prefix, obj


def compare(before: dict, after: dict) -> list[tuple[str, str]]:
    rows = []
    for case in sorted(set(before) | set(after)):
        if case not in before or case not in after:
            rows.append((case, "only in " + ("after" if case in after else "before")))
            continue
        a, b = dict(_flatten(before[case])), dict(_flatten(after[case]))
        if a == b:
            rows.append((case, "identical"))
            continue
        missing = sorted(set(a) ^ set(b))
        worst, where = 0.0, ""
        for k in set(a) & set(b):
            x, y = a[k], b[k]
            if x == y:
                continue
            if isinstance(x, (int, float)) and isinstance(y, (int, float)) and not isinstance(x, bool):
                d = abs(x - y) / max(abs(x), abs(y), 1e-300)
            else:
                d = float("inf")
            if d > worst:
                worst, where = d, f"{k}: {x!r} -> {y!r}"
        msg = f"differs: largest relative {worst:.3g} at {where}"
        if missing:
            msg += f"; fields only on one side: {', '.join(missing[:6])}" + (" ..." if len(missing) > 6 else "")
        rows.append((case, msg))
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--save", type=Path, help="write this tree's numbers here")
    g.add_argument("--against", type=Path, help="compare this tree's numbers with a saved file")
    a = p.parse_args(argv)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        res = {**single_cases(), **rig_cases(Path(tmp))}
    print(f"{len(res)} cases in {time.perf_counter() - t0:.0f} s (mirrorgraph at {Path(mg.__file__).parent})")
    if a.save:
        a.save.write_text(json.dumps(res, indent=1, sort_keys=True))
        print(f"saved to {a.save}")
        return 0
    rows = compare(json.loads(a.against.read_text()), json.loads(json.dumps(res)))
    print("\n".join(header(argv=argv, script="bench_identity.py", code=True)) + "\n")
    print("| case | against the saved numbers |\n|---|---|")
    for case, msg in rows:
        print(f"| {case} | {msg} |")
    return 0 if all(m == "identical" for _, m in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
