"""Rigs calibrated from every person in view: ``calibrate-rig --people one`` vs ``all``.

Synthetic rigs of 3-5 cameras watching 2-5 people (:func:`mirrorgraph.synth.rig_people.
make_rig_people`: BODY_25, 4 px noise, 2 % outliers, each person hidden from a camera
once for 5-20 frames with probability 0.3, 2 % left/right swaps; one scene of snapshots
2250 frames apart). Per scene, side by side in one run:

* **one**: ``calibrate_rig(people="one")``, the person seen longest;
* **all**: ``calibrate_rig(people="all")``, every person associated and in the one graph;
* **ids**: the identity-knowing bundle adjustment, the best the 2D data allow: the same
  run as ``all`` (the same graph, driver and start) with the association replaced by the
  true one, the detections the detector labelled left/right swapped left out
  (:func:`mirrorgraph.rigs.people.associate_people` patched to return the synthetic
  truth, for this bench only).

Figures: rotation error per camera (deg, median and max over the cameras but the first),
position error (mm) after one least-squares scale for the rig, the wall time, and for
``all`` the association against the truth: detections put with another person
(``wrong``) and identity switches (a slot's person changing between consecutive frames;
not counted on snapshots).

The Pose2Sim demo's ``Demo_MultiPerson`` trial (``--pose2sim``, on by default; BlazePose
on the four videos, read from ``--cache`` or detected in this run): every camera against
the Qualisys calibration for ``one`` and ``all`` (the helpers of ``bench_real.py``), then
diagnoses of why ``all`` is worse there (:data:`P2S_RUNS`; they read the data, they are
not methods): the nearly still second person added to the one-person run's subject with
all of their frames, on keyframes or on one frame; ``all`` without that person; every
person on keyframes; and each person's per-joint offset against the Qualisys rig
(:func:`joint_bias`).

Usage::

    python bench/bench_rig_people.py              # ~15 min on 2 shared cores
    python bench/bench_rig_people.py --pose2sim-only --cache DIR   # ~6 min
    python bench/bench_rig_people.py --quick      # three small scenes, no Pose2Sim
    python bench/bench_rig_people.py --frames 300 # longer scenes
    python bench/bench_rig_people.py --scene 7    # the still person's scene alone, ~3 min
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _report import header  # noqa: E402

import mirrorgraph.pipelines.rig_people as rp  # noqa: E402
from mirrorgraph.pipelines.options import CalibrateOptions  # noqa: E402
from mirrorgraph.pipelines.rig import calibrate_rig  # noqa: E402
from mirrorgraph.rigs.people import PeopleAssociation, candidate_index  # noqa: E402
from mirrorgraph.synth.rig_people import make_rig_people, write_rig_people  # noqa: E402

#: (cameras, people, frames, seed, snapshots[, still people, their constant error px]);
#: the 5-camera 4-person 300-frame scene is the time target's; the last one holds a
#: person standing still with a constant detector error (8 px per camera and joint).
SCENES = [(3, 2, 150, 11, False), (3, 3, 150, 12, False), (4, 3, 150, 13, False),
          (4, 5, 150, 14, False), (5, 4, 300, 15, False), (5, 2, 150, 16, False),
          (4, 3, 60, 17, True), (3, 3, 100, 22, False, 1, 8.0)]
#: The Pose2Sim runs: one, all, all with every observation weighing 1 (no track weights,
#: :data:`mirrorgraph.pipelines.rig_people.TRACK_WEIGHTS`), all after one solve, and
#: diagnoses (not methods): all with
#: the association made under the Qualisys rig instead of the current one; the one-person
#: run's subject in every frame it holds plus the person seen in most frames but the
#: subject's slot (the nearly still one), also with their observations at a fixed weight
#: each (every frame alike otherwise); all without that person; all with every
#: person's joints thinned to keyframes (:func:`keyframes`, 30 px).
P2S_RUNS = ("one", "all", "all, every frame alike", "all, 1 round", "all, Qualisys association",
            "subject + still person", "subject + still person on keyframes 30 px",
            "subject + still person on one frame", "subject + still person at 0.01 a frame",
            "subject + still person at 1e-4 a frame", "all, still person left out",
            "all, keyframes 30 px")

#: Draws of the one-person run's subject with a tenth of the frames left out (the spread
#: of the one-person result itself).
SUBSAMPLE_DRAWS = 8

#: The keyframes' least image motion (px) of the diagnosis ``all, keyframes 30 px``.
KEYFRAME_PX = 30.0


def keyframes(real: np.ndarray, tau: float, min_confidence: float = 0.3) -> np.ndarray:
    """``(T, J)`` bool: the keyframes of one person's joints seen in ``real`` ``(C, T, J, 3)``
    (px, confidence): a joint is kept in a frame where, in some camera, it lies ``tau`` px
    or more from where it was in its last kept frame (its first sight in a camera kept).
    A diagnosis of repeated evidence: a person standing still keeps a few frames."""
    C, T, J, _ = real.shape
    ok = real[..., 2] >= min_confidence
    keep = np.zeros((T, J), bool)
    last = np.full((C, J, 2), np.nan)
    for t in range(T):
        d = np.linalg.norm(real[:, t, :, :2] - last, axis=-1)            # (C, J)
        moved = ok[:, t] & (np.nan_to_num(d, nan=-1.0) >= tau)
        first = ok[:, t] & np.isnan(last[..., 0])
        keep[t] = (moved | first).any(0)
        upd = keep[t][None] & ok[:, t]
        last[upd] = real[:, t, :, :2][upd]
    return keep


def joint_bias(real: np.ndarray, Ks: list[np.ndarray], poses: list[np.ndarray],
               joints: np.ndarray, min_confidence: float = 0.3) -> list[tuple[float, float]]:
    """Per camera ``(bias, scatter)`` px of one person ``real`` ``(C, T, J, 3)`` under a
    rig (``Ks``, camera-to-world ``poses``): each joint of each frame seen by three cameras
    or more triangulated (DLT), its reprojection residual per camera; ``bias`` the median
    over joints of the norm of the joint's mean residual over frames, ``scatter`` the
    median over joints of the mean distance of its residuals from that mean (joints seen
    in more than 5 frames; NaN where none)."""
    Ps = [np.asarray(K) @ np.linalg.inv(T)[:3] for K, T in zip(Ks, poses)]
    C, T = real.shape[:2]
    res: list[dict[int, list[np.ndarray]]] = [{} for _ in range(C)]
    for t in range(T):
        for j in joints:
            x = real[:, t, j]
            ok = np.flatnonzero(x[:, 2] >= min_confidence)
            if len(ok) < 3:
                continue
            A = np.concatenate([[x[c, 0] * Ps[c][2] - Ps[c][0], x[c, 1] * Ps[c][2] - Ps[c][1]]
                                for c in ok])
            X = np.linalg.svd(A)[2][-1]
            for c in ok:
                u = Ps[c] @ X
                res[c].setdefault(int(j), []).append(x[c, :2] - u[:2] / u[2])
    out = []
    for per in res:
        r = [np.array(v) for v in per.values() if len(v) > 5]
        if not r:
            out.append((float("nan"), float("nan")))
            continue
        out.append((float(np.median([np.linalg.norm(v.mean(0)) for v in r])),
                    float(np.median([np.linalg.norm(v - v.mean(0), axis=1).mean() for v in r]))))
    return out


def still_slot(a: PeopleAssociation) -> int | None:
    """The slot seen by two cameras in most frames but slot 0 (``None`` with one slot)."""
    return int(np.argmax(a.frames()[1:])) + 1 if a.count > 1 else None
QUICK = [(3, 2, 80, 11, False), (4, 3, 80, 13, False), (4, 3, 40, 17, True)]
DETECTOR = dict(noise_std=4.0, outlier_rate=0.02, lr_swap_rate=0.02, occlusion_rate=0.3)


def errors(est: list[np.ndarray], true: list[np.ndarray]) -> dict:
    """Rotation (deg) and scale-aligned position (mm) errors of every camera but the first."""
    Ce = np.array([P[:3, 3] for P in est[1:]])
    Ct = np.array([P[:3, 3] for P in true[1:]])
    s = float(np.sum(Ce * Ct) / np.sum(Ce * Ce))
    rot = []
    for P, Q in zip(est[1:], true[1:]):
        R = Q[:3, :3].T @ P[:3, :3]
        rot.append(float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))))
    pos = (1e3 * np.linalg.norm(s * Ce - Ct, axis=1)).tolist()
    return {"rot": rot, "pos": pos}


def true_association(rig, obs) -> PeopleAssociation:
    """The synthetic truth as a :class:`PeopleAssociation` of ``obs``'s candidates (slot 0:
    the true person most often the one-person run's subject)."""
    T, P = len(obs.frame_ids), rig.num_people
    index = []
    votes = np.zeros(P)
    for c, cam in enumerate(obs.cameras):
        own = rig.owner[rig.camera_names[c]]
        ix = np.full((T, P), -1)
        swapped = rig.swapped[rig.camera_names[c]]
        for t, who in enumerate(own):
            keep = ~swapped[who, t]        # the detector's left/right swaps are known too
            ix[t, who[keep]] = np.arange(len(who))[keep]
        sub = candidate_index(cam)
        for t in np.flatnonzero(sub >= 0):
            votes[own[t][sub[t]]] += 1
        index.append(ix)
    order = [int(np.argmax(votes))] + [p for p in range(P) if p != int(np.argmax(votes))]
    return PeopleAssociation(count=P, index=[ix[:, order] for ix in index], people_found=P)


def association_quality(rig, a: PeopleAssociation, snapshots: bool) -> dict:
    """Detections put with another person than their slot-frame's majority, and identity
    switches (the majority person of a slot changing between consecutive frames)."""
    wrong = held = switches = 0
    T = a.index[0].shape[0]
    major = np.full((a.count, T), -1)
    for p in range(a.count):
        for t in range(T):
            who = [rig.owner[rig.camera_names[c]][t][a.index[c][t, p]]
                   for c in range(len(a.index)) if a.index[c][t, p] >= 0]
            if len(who) >= 2:
                vals, counts = np.unique(who, return_counts=True)
                major[p, t] = vals[np.argmax(counts)]
                held += len(who)
                wrong += len(who) - int(counts.max())
        if not snapshots:
            m = major[p][major[p] >= 0]
            switches += int(np.count_nonzero(np.diff(m) != 0))
    return {"wrong": wrong, "held": held, "switches": None if snapshots else switches}


def run_scene(C: int, P: int, T: int, seed: int, snapshots: bool, still: int = 0,
              bias_px: float = 0.0) -> dict:
    rig = make_rig_people(C, P, frames=T, seed=seed, snapshots=snapshots, still=still,
                          bias_px=bias_px, **DETECTOR)
    row = {"scene": f"{C} cams, {P} people, {T} {'snapshots' if snapshots else 'frames'}"
           + (f", {still} still ({bias_px:g} px constant error)" if still else ""),
           "C": C, "P": P, "T": T, "snapshots": snapshots, "still": still}
    with tempfile.TemporaryDirectory(prefix="bench_rig_people_") as tmp:
        path = write_rig_people(rig, tmp)
        spy: dict = {}
        original = rp.associate_people

        def spying(obs, Ks, poses, **kw):
            spy["a"] = original(obs, Ks, poses, **kw)
            return spy["a"]

        def truth(obs, Ks, poses, **kw):
            return true_association(rig, obs)

        runs = [("one", None), ("all", spying), ("ids", truth)]
        if still:
            runs.append(("flat", None))
        for name, assoc in runs:
            rp.associate_people = assoc or original
            rp.TRACK_WEIGHTS = name != "flat"
            try:
                t0 = time.perf_counter()
                cal = calibrate_rig(path, CalibrateOptions(people="one" if name == "one"
                                                           else "all"))
                row.setdefault("rho", {})[name] = [r.get("rho") for r in
                                                   (cal.refinement.get("people") or {})
                                                   .get("rounds", [])]
                row[name] = errors([np.asarray(c.pose) for c in cal.cameras], rig.poses)
                row[name]["s"] = time.perf_counter() - t0
                row[name]["people"] = cal.num_people
            except Exception as exc:  # noqa: BLE001 - a refused rig is a result
                row[name] = {"failed": f"{type(exc).__name__}: {exc}"}
            finally:
                rp.associate_people, rp.TRACK_WEIGHTS = original, True
        if "a" in spy:
            row["assoc"] = association_quality(rig, spy["a"], snapshots)
    return row


def pose2sim_trial(cache: Path | None) -> dict:
    """``Demo_MultiPerson``: ``one`` and ``all`` against Qualisys, per camera."""
    import bench_real as br
    from mirrorgraph.video import VideoOptions, detect_video

    root = br.pose2sim_root()
    trial = "Demo_MultiPerson"
    cams = br.read_cameras(br.calib_path(root, trial))
    true = br.relative_poses(cams)
    out: dict = {}
    with tempfile.TemporaryDirectory(prefix="bench_rig_people_p2s_") as tmp:
        vopts = VideoOptions(cache_dir=cache or Path(tmp) / "cache")
        sizes = {}
        for n in br.CAMERAS:
            det = detect_video(root / trial / "videos" / f"{n}.mp4", vopts)
            sizes[n] = (det.info.width, det.info.height)
        rig = br.write_rig(Path(tmp), root, trial, cams, sizes, None)
        # a second witness: the SinglePerson trial (the same cameras, the same Qualisys
        # file) calibrated from its one subject
        single = "Demo_SinglePerson"
        for n in br.CAMERAS:
            detect_video(root / single / "videos" / f"{n}.mp4", vopts)
        (Path(tmp) / "single").mkdir()
        witness_rig = br.write_rig(Path(tmp) / "single", root, single, cams, sizes, None)
        witness = [np.asarray(c.pose) for c in calibrate_rig(
            witness_rig, CalibrateOptions(people="one", detection=vopts)).cameras]
        out["witness"] = errors(witness, true)["rot"]
        original, rounds = rp.associate_people, rp.MAX_ROUNDS
        layout = PeopleAssociation.observations

        def spying(obs, Ks, poses, **kw):
            a = original(obs, Ks, poses, **kw)
            out["bias"] = _slot_bias(obs, a, true)
            return a

        def qualisys(obs, Ks, poses, **kw):      # a diagnosis: the truth's rig associates
            return original(obs, [c.intrinsics.K for c in obs.cameras], true, **kw)

        def subject_still(obs, Ks, poses, **kw):  # the subject's frames + the still person
            a = original(obs, Ks, poses, **kw)
            s = still_slot(a)
            sub = [candidate_index(c) for c in obs.cameras]
            if s is None:
                return PeopleAssociation(1, [x[:, None] for x in sub], people_found=1)
            return PeopleAssociation(2, [np.stack([x, ix[:, s]], 1)
                                         for x, ix in zip(sub, a.index)], people_found=2)

        def no_still(obs, Ks, poses, **kw):
            a = original(obs, Ks, poses, **kw)
            s = still_slot(a)
            if s is not None:
                for ix in a.index:
                    ix[:, s] = -1
            return a

        def thinning(tau: float, first: int):
            def thinned(self, obs):               # slots >= first on keyframes
                got = layout(self, obs)
                J, P = obs.skeleton.num_joints, self.count
                real = np.stack([c.real.reshape(len(c.real), P, J, 3) for c in got.cameras])
                for p in range(first, P):
                    drop = ~keyframes(real[:, :, p], tau)
                    for c in got.cameras:
                        c.real.reshape(len(c.real), P, J, 3)[:, p][drop] = (np.nan, np.nan, 0)
                return got
            return thinned

        layouts = {"all, keyframes 30 px": thinning(KEYFRAME_PX, 0),
                   "subject + still person on keyframes 30 px": thinning(KEYFRAME_PX, 1),
                   "subject + still person on one frame": thinning(np.inf, 1)}

        patches = {"all": spying, "all, Qualisys association": qualisys,
                   "all, still person left out": no_still}
        patches.update({k: subject_still for k in P2S_RUNS if k.startswith("subject")})
        build = rp.build_rig

        def fixed(w: float):
            def built(people_obs, start, joints, **kw):   # slots >= 1 at weight w
                got = build(people_obs, start, joints, **kw)
                J = people_obs.skeleton.num_joints // 2      # subject_still: two slots
                weight = np.ones(people_obs.skeleton.num_joints)
                weight[J:] = w
                return replace(got, views=tuple(replace(v, weight=weight) if v.mirror is None
                                                else v for v in got.views))
            return built
        builders = {"subject + still person at 0.01 a frame": fixed(0.01),
                    "subject + still person at 1e-4 a frame": fixed(1e-4)}

        for name in P2S_RUNS:
            t0 = time.perf_counter()
            if name == "all, 1 round":
                rp.MAX_ROUNDS = 1
            rp.TRACK_WEIGHTS = name != "all, every frame alike" and name not in builders
            rp.build_rig = builders.get(name, build)
            rp.associate_people = patches.get(name, original)
            PeopleAssociation.observations = layouts.get(name, layout)
            try:
                cal = calibrate_rig(rig, CalibrateOptions(
                    people="one" if name == "one" else "all", detection=vopts))
            except Exception as exc:  # noqa: BLE001
                out[name] = {"failed": f"{type(exc).__name__}: {exc}"}
                continue
            finally:
                rp.associate_people, rp.MAX_ROUNDS = original, rounds
                rp.TRACK_WEIGHTS, rp.build_rig = True, build
                PeopleAssociation.observations = layout
            out[name] = errors([np.asarray(c.pose) for c in cal.cameras], true)
            out[name]["witness"] = errors([np.asarray(c.pose) for c in cal.cameras],
                                          witness)["rot"]
            out[name]["s"] = time.perf_counter() - t0
            out[name]["people"] = cal.num_people
            out[name]["record"] = cal.refinement.get("people")
        # the one-person run's own spread: its subject alone, a tenth of the frames left out
        draws = []
        for d in range(SUBSAMPLE_DRAWS):
            def subject_only(obs, Ks, poses, d=d, **kw):
                sub = [candidate_index(c) for c in obs.cameras]
                keep = np.random.default_rng(d).random(len(sub[0])) >= 0.1
                return PeopleAssociation(1, [np.where(keep, x, -1)[:, None] for x in sub],
                                         people_found=1)
            rp.associate_people, rp.TRACK_WEIGHTS = subject_only, False   # as `one` weighs
            try:
                cal = calibrate_rig(rig, CalibrateOptions(people="all", detection=vopts))
                draws.append(errors([np.asarray(c.pose) for c in cal.cameras], true)["rot"])
            except Exception:  # noqa: BLE001 - a refused draw is left out
                pass
            finally:
                rp.associate_people, rp.TRACK_WEIGHTS = original, True
        out["subsample"] = np.array(draws)
    return out


def _slot_bias(obs, a: PeopleAssociation, true: list[np.ndarray]) -> list[list]:
    """Per slot of ``a``, :func:`joint_bias` per camera under the Qualisys rig."""
    J, P = obs.skeleton.num_joints, a.count
    layout = a.observations(obs)
    real = np.stack([c.real.reshape(len(c.real), P, J, 3) for c in layout.cameras])
    Ks = [c.intrinsics.K for c in obs.cameras]
    joints = np.asarray(obs.skeleton.calibration_joints, int)
    return [joint_bias(real[:, :, p], Ks, true, joints) for p in range(P)]


#: What the runs and columns are, in every results file.
LEGEND = ["`one`: `calibrate_rig(people=\"one\")`; `all`: `people=\"all\"`; `ids`: the same "
          "graph fed the true association (the detector's left/right swaps left out). "
          "Rotation: every camera but the first against the truth; position: after one "
          "least-squares scale for the rig; `vs ids`: the run's median rotation error over "
          "`ids`'; `wrong / held`: detections put with another person than their "
          "slot-frame's majority, of those held; switches: a slot's person changing between "
          "consecutive frames (not on snapshots); `flat`: `all` with every observation "
          "weighing 1 (no track weights), on the scene with a still person. The scene with a "
          "still person is left out of the targets' ratios."]


def _f(v, fmt="{:.3f}"):
    return "-" if v is None else fmt.format(v)


def table(rows: list[dict]) -> list[str]:
    lines = ["| scene | run | people | rot median (deg) | rot max (deg) | pos median (mm) | "
             "time (s) | vs ids (rot median) | wrong / held | switches |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ids = r.get("ids", {})
        for name in ("one", "all", "ids", "flat"):
            if name not in r:
                continue
            e = r.get(name, {})
            if "failed" in e:
                lines.append(f"| {r['scene']} | {name} | - | failed: {e['failed'][:80]} |"
                             " | | | | | |")
                continue
            rm = float(np.median(e["rot"]))
            ratio = (rm / float(np.median(ids["rot"])) if "rot" in ids else None)
            a = r.get("assoc", {}) if name == "all" else {}
            lines.append(
                f"| {r['scene']} | {name} | {e['people']} | {rm:.3f} | {max(e['rot']):.3f} | "
                f"{float(np.median(e['pos'])):.1f} | {e['s']:.1f} | {_f(ratio, '{:.2f}')} | "
                + (f"{a['wrong']} / {a['held']} | {_f(a['switches'], '{}')} |" if a
                   else "| |"))
    return lines


def targets(rows: list[dict]) -> list[str]:
    ok = [r for r in rows if all("rot" in r.get(k, {}) for k in ("one", "all", "ids"))
          and not r.get("still")]
    still = [r for r in rows if r.get("still") and all("rot" in r.get(k, {})
                                                       for k in ("one", "all", "flat"))]
    ratios = [np.median(r["all"]["rot"]) / np.median(r["ids"]["rot"]) for r in ok]
    pos_ratios = [np.median(r["all"]["pos"]) / np.median(r["ids"]["pos"]) for r in ok]
    better = [np.median(r["all"]["rot"]) < np.median(r["one"]["rot"]) for r in ok if r["P"] >= 3]
    timing = [r["all"]["s"] / r["one"]["s"] for r in ok if (r["C"], r["P"], r["T"]) == (5, 4, 300)]
    lines = [f"* rotation within 1.1x of the identity-knowing BA (median over scenes of the "
             f"per-scene median ratio): {np.median(ratios):.2f}x "
             f"(per scene {', '.join(f'{x:.2f}' for x in ratios)})" if ratios else
             "* no scene ran all three",
             f"* position, the same ratio: {np.median(pos_ratios):.2f}x" if pos_ratios else "",
             f"* better than one person on every scene with >= 3 people: "
             f"{sum(better)} of {len(better)}",
             f"* 5 cameras, 4 people, 300 frames: every person {timing[0]:.2f}x the one-person "
             "run's time (target 3x)" if timing else "* (the 300-frame scene did not run)"]
    for r in still:
        one, every, flat = (np.array(r[k]["rot"]) for k in ("one", "all", "flat"))
        lines.append(f"* {r['scene']}: every camera no worse than one person: "
                     f"{'yes' if (every <= one).all() else 'no'} (all {every.round(3).tolist()}, "
                     f"one {one.round(3).tolist()}); every camera better than every frame "
                     f"alike (`flat`, {flat.round(3).tolist()}): "
                     f"{'yes' if (every < flat).all() else 'no'}; largest rho per round "
                     f"{[None if x is None else round(float(np.max(x)), 2) for x in r['rho']['all']]}")
    return [x for x in lines if x]


def p2s_lines(p2s: dict) -> list[str]:
    if not p2s:
        return []
    lines = ["", "## Pose2Sim Demo_MultiPerson (two people, BlazePose) against Qualisys", "",
             "| run | people | " + " | ".join(f"cam0{i} rot (deg)" for i in (2, 3, 4))
             + " | " + " | ".join(f"cam0{i} pos (mm)" for i in (2, 3, 4))
             + " | rot vs SinglePerson `one`, cam02 / 03 / 04 (deg) | time (s) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name in P2S_RUNS:
        e = p2s.get(name, {})
        if "failed" in e:
            lines.append(f"| {name} | failed: {e['failed'][:100]} | | | | | | | | |")
            continue
        lines.append(f"| {name} | {e['people']} | "
                     + " | ".join(f"{x:.2f}" for x in e["rot"]) + " | "
                     + " | ".join(f"{x:.0f}" for x in e["pos"]) + " | "
                     + " / ".join(f"{x:.2f}" for x in e.get("witness", [])) + f" | {e['s']:.1f} |")
    if p2s.get("witness"):
        lines += ["", "The second witness, Demo_SinglePerson calibrated from its one subject "
                  "(`one`; the same cameras and Qualisys file), against Qualisys: "
                  + " / ".join(f"{x:.2f}" for x in p2s["witness"]) + " deg (cam02 / 03 / 04)."]
    sub = p2s.get("subsample")
    if sub is not None and len(sub):
        lines += ["", f"The one-person run's own spread: its subject alone (`people=\"all\"` "
                  f"with the association replaced by the subject's detections), a random tenth "
                  f"of the frames left out, {len(sub)} draws (rotation, deg):", "",
                  "| | cam02 | cam03 | cam04 |", "|---|---|---|---|"]
        for label, f in (("min", np.min), ("median", np.median), ("max", np.max)):
            lines.append(f"| {label} | " + " | ".join(f"{x:.2f}" for x in f(sub, 0)) + " |")
    if p2s.get("bias"):
        lines += ["", "Each slot of `all`'s last association against the Qualisys rig "
                  "(`joint_bias`: per camera, the median over joints of the norm of a joint's "
                  "mean reprojection residual over the frames, and the median scatter about "
                  "that mean, px):", "",
                  "| slot | " + " | ".join(f"cam0{i} bias / scatter (px)" for i in (1, 2, 3, 4))
                  + " |", "|---|---|---|---|---|"]
        for p, row in enumerate(p2s["bias"]):
            lines.append(f"| {p} | " + " | ".join(f"{b:.1f} / {s:.1f}" for b, s in row) + " |")
    for name in P2S_RUNS[1:]:
        if "record" in p2s.get(name, {}):
            rec = p2s[name]["record"] or {}
            lines += ["", f"`{name}`: {rec.get('count')} slots, frames seen by two cameras per "
                          f"slot {rec.get('frames')}, rounds {len(rec.get('rounds', []))}, "
                          f"detections taken from their track by the geometry "
                          f"{rec.get('switched')}"]
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="three small scenes, no Pose2Sim")
    ap.add_argument("--frames", type=int, default=None, help="frames of every scene")
    ap.add_argument("--no-pose2sim", action="store_true", help="skip Demo_MultiPerson")
    ap.add_argument("--cache", type=Path, default=None, help="detection cache folder")
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument("--scene", type=int, action="append", default=None,
                    help="only this scene of SCENES (0-based; repeatable), written to "
                         "RESULTS_rig_people_scenes.md")
    ap.add_argument("--pose2sim-only", action="store_true",
                    help="only Demo_MultiPerson, written to RESULTS_rig_people_pose2sim.md")
    args = ap.parse_args()
    started = time.strftime("%Y-%m-%dT%H:%M:%S")
    if args.pose2sim_only:
        text = "\n".join(["# Rigs from every person: Pose2Sim Demo_MultiPerson "
                          "(`bench/bench_rig_people.py --pose2sim-only`)", "",
                          *header(started=started), *p2s_lines(pose2sim_trial(args.cache))])
        print(text)
        if not args.no_write:
            (Path(__file__).parent / "RESULTS_rig_people_pose2sim.md").write_text(text + "\n")
        return
    scenes = QUICK if args.quick else SCENES
    if args.scene:
        scenes = [SCENES[i] for i in args.scene]
        args.no_pose2sim = True
    if args.frames:
        scenes = [(C, P, args.frames, s, snap) for C, P, _, s, snap in scenes]
    rows = []
    for sc in scenes:
        print(f"scene {sc}", flush=True)
        rows.append(run_scene(*sc))
        print("\n".join(table(rows[-1:])[2:]), flush=True)
    p2s = {} if args.quick or args.no_pose2sim else pose2sim_trial(args.cache)
    lines = ["# Rigs from every person in view (`bench/bench_rig_people.py`)", "",
             *header(started=started), "", "Synthetic rigs (detector: "
             + ", ".join(f"{k} {v}" for k, v in DETECTOR.items()) + "):", "", *LEGEND, "",
             *table(rows), "", "Targets:", "", *targets(rows), *p2s_lines(p2s)]
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write and not args.quick:
        name = "RESULTS_rig_people_scenes.md" if args.scene else "RESULTS_rig_people.md"
        (Path(__file__).parent / name).write_text(text)


if __name__ == "__main__":
    main()
