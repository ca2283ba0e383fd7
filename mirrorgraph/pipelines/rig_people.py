"""``calibrate-rig --people all``: every person the rig sees, in the one graph.

The loop of :func:`solve_everyone`, after the one-person run has solved the rig from its
clearest person (:func:`mirrorgraph.pipelines.rig.calibrate_rig`):

    associate every person across the cameras with the current rig
       (:func:`mirrorgraph.rigs.people.associate_people`)
    -> the observations in the layout of several people side by side
       (:func:`mirrorgraph.skeletons.people_skeleton`, as ``calibrate --people all``:
       each person their own joints, bones and body priors, no prior between two people)
    -> from the second round on, each (person, camera, joint) track's weight in the graph:
       its effective number of independent frames over its frames (:func:`track_weights`),
       with each person's constant detector error in each camera measured under the last
       round's rig (:func:`bias_ratio`)
    -> the one graph built and solved by the one driver (:func:`.solve.build_rig`,
       :func:`.solve.solve_rig`), starting from the current rig
    -> again, until the association changes in at most :data:`STABLE_SHARE` of its
       entries and no constant error is measured (:data:`RHO_NEGLIGIBLE`), at most
       :data:`MAX_ROUNDS` solves.

The person of the one-person run is slot 0, the person ``subject_height`` applies to.

A detector's error on a joint is not independent from frame to frame: it holds a
constant part that changes only as the joint moves in the image (measured on BlazePose
against the Pose2Sim demo's Qualisys rig, 6-15 px per joint; 21-38 px on the demo's
nearly still second person, 4-5x the frame-to-frame scatter). A person standing still
repeats that error in every frame, and the graph, weighing each frame as an independent
observation, lets it pull the cameras as hard as a person who moves. :func:`track_weights`
gives each track the information of its independent frames (Kish's effective sample
size of a mean under correlated errors): frames where the joint stands in one
:data:`DETECTOR_BIAS_PX` cell of the image share one constant error, whose size against
the scatter is measured per person and camera from the residuals' correlation in
consecutive frames (:func:`bias_ratio`; about 0 for independent errors, where every
frame weighs 1).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..graph.options import RefineOptions
from ..rigs.observations import RigObservations
from ..rigs.people import PeopleAssociation, associate_people
from .solve import RigSolution, build_rig, solve_rig

__all__ = ["DETECTOR_BIAS_PX", "MAX_ROUNDS", "RHO_NEGLIGIBLE", "STABLE_SHARE", "TRACK_WEIGHTS",
           "EveryoneRun", "bias_ratio", "people_joints", "people_views", "solve_everyone",
           "split_solution", "track_weights"]

#: Solves of the graph of every person, at most.
MAX_ROUNDS = 2

#: An association that changes in at most this share of its (camera, frame, person)
#: entries from the previous round's is stable: no further solve.
STABLE_SHARE = 0.01


#: px: the distance a joint moves in the image before a detector's constant error on it
#: is drawn again (the cell of :func:`track_weights`; BlazePose's constant error against
#: the Pose2Sim demo's Qualisys rig is 6-15 px per joint, docs/accuracy.md).
DETECTOR_BIAS_PX = 10.0

#: Each track weighted by its effective number of independent frames
#: (:func:`track_weights`) from the second round on; ``False``: every observation
#: weighs 1.
TRACK_WEIGHTS = True

#: A person's constant error in a camera whose variance is at most this share of the
#: scatter's (:func:`bias_ratio`) weighs nothing: that person's observations in that
#: camera weigh 1, and where all do, no further round is solved for the weights.
RHO_NEGLIGIBLE = 0.05


#: Rows each side of a frame in the running median of a joint's position that places it
#: in a cell (:func:`track_weights`): the detector's scatter alone does not move a joint
#: from one cell to the next.
SMOOTH_ROWS = 4


def _smoothed(real: np.ndarray, frame_ids: np.ndarray) -> np.ndarray:
    """``real`` ``(C, T, K, 3)`` with each seen position replaced by the median of its
    track's positions within :data:`SMOOTH_ROWS` rows that lie within that many times
    :data:`~mirrorgraph.rigs.tracking.TRACK_MAX_GAP` frames of it."""
    from numpy.lib.stride_tricks import sliding_window_view

    from ..rigs.tracking import TRACK_MAX_GAP

    h = SMOOTH_ROWS
    out = np.array(real, float)
    ids = np.asarray(frame_ids, float)
    near = np.abs(sliding_window_view(np.pad(ids, h, constant_values=np.inf), 2 * h + 1)
                  - ids[:, None]) <= h * TRACK_MAX_GAP                           # (T, W)
    for c in range(out.shape[0]):
        for a in range(0, out.shape[2], 32):                      # bounded temporaries
            xy = out[c, :, a:a + 32, :2]
            xy = np.where(out[c, :, a:a + 32, 2:] > 0, xy, np.nan)
            win = sliding_window_view(np.pad(xy, ((h, h), (0, 0), (0, 0)),
                                             constant_values=np.nan), 2 * h + 1, axis=0)
            win = np.where(near[:, None, None, :], win, np.nan)
            with np.errstate(all="ignore"):
                finite = np.isfinite(win).any(-1)
                med = np.nanmedian(np.where(finite[..., None], win, 0.0), -1)
            out[c, :, a:a + 32, :2] = np.where(np.isfinite(xy), med, xy)
    return out


def _cells(real: np.ndarray, cell_px: float):
    """The seen observations of ``real`` ``(C, T, K, 3)`` and their groups: ``(c, t, k)``
    index arrays, each observation's group (one track, one ``cell_px`` cell of the
    image) and each group's size."""
    seen = (real[..., 2] > 0) & np.isfinite(real[..., :2]).all(-1)
    c, t, k = np.nonzero(seen)
    cell = np.floor(real[c, t, k, :2] / float(cell_px)).astype(np.int64)
    keys = np.stack([c * real.shape[2] + k, cell[:, 0], cell[:, 1]], 1)
    _, group, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    return (c, t, k), group.ravel(), counts


def track_weights(real: np.ndarray, rho, cell_px: float = DETECTOR_BIAS_PX,
                  frame_ids: np.ndarray | None = None) -> np.ndarray:
    """Each track's weight: its effective number of independent frames over its frames.

    A track is one joint of one person in one camera, its ``n`` observations (px). Its
    errors are the detector's scatter plus a constant error shared by the frames where
    the joint stands in the same cell of a ``cell_px`` grid of the image (its position
    the running median of :func:`_smoothed` where ``frame_ids`` are given), ``rho`` the
    ratio of the two variances (:func:`bias_ratio`). With ``n_k`` the frames in cell
    ``k``, the effective sample size of the track's mean (Kish, *Survey Sampling*, 1965,
    the design effect of clusters) is ``n (1 + rho) / (1 + rho sum_k n_k^2 / n)``: ``n``
    where every frame stands in its own cell (a moving joint) or ``rho`` is 0, about
    ``1 + 1 / rho`` where all stand in one (a person standing still). The weight is
    that over ``n``, in ``(0, 1]``: each observation's information in the graph
    (:attr:`mirrorgraph.graph.rig.View.weight`).

    Args:
        real: ``(C, T, K, 3)`` each camera's observations of ``K`` joint columns (every
            person's joints side by side), px and confidence (NaN or 0: not seen).
        rho: the constant error's variance over the scatter's, one number or ``(C, K)``
            per column of each camera; cell_px: the cell, px.
        frame_ids: ``(T,)``, the rows' frames.

    Returns:
        ``(C, K)`` weights (1 where a column is not seen).
    """
    real = np.asarray(real, float) if frame_ids is None else _smoothed(real, frame_ids)
    C, _, K = real.shape[:3]
    out = np.ones(C * K)
    rho = np.broadcast_to(np.asarray(rho, float), (C, K)).ravel()
    (c, _, k), group, counts = _cells(real, cell_px)
    if not len(c) or not (rho > 0).any():
        return out.reshape(C, K)
    track = c * K + k
    first = np.zeros(len(counts), np.int64)
    first[group] = track                                    # each group's track
    sq = np.bincount(first, weights=counts.astype(float) ** 2, minlength=C * K)
    n = np.bincount(track, minlength=C * K).astype(float)
    has = n > 0
    out[has] = (1.0 + rho[has]) / (1.0 + rho[has] * sq[has] / n[has])
    return np.minimum(out, 1.0).reshape(C, K)


def bias_ratio(real: np.ndarray, frame_ids: np.ndarray, Ks, poses, columns: np.ndarray,
               limit_px: float, people: int = 1) -> np.ndarray:
    """The constant error's variance over the scatter's (``rho`` of :func:`track_weights`)
    per camera and person, measured on the residuals of a rig.

    Every joint column of ``columns`` seen by three cameras or more (two in a rig of two)
    is triangulated with the rig, frame by frame (:func:`~mirrorgraph.geometry.triangulate`)
    and reprojected; residuals over ``limit_px`` (the graph's outliers) are left out. A
    joint moves far less than a cell from one frame to the next, so the correlation
    ``c`` of the residuals of one track in consecutive frames (rows at most
    :data:`~mirrorgraph.rigs.tracking.TRACK_MAX_GAP` frames apart, pooled over the
    tracks of one person in one camera) is the constant error's share of the variance,
    ``rho = c / (1 - c)``; 0 without such pairs or where ``c <= 0`` (independent errors).

    Args:
        real: ``(C, T, K, 3)`` as :func:`track_weights`; frame_ids: ``(T,)``.
        Ks: ``(3, 3)`` per camera; poses: ``(4, 4)`` camera-to-world per camera.
        columns: ``(K,)`` bool, the columns to measure (the graph's joints).
        limit_px: residuals over this are outliers.
        people: ``P``, the columns being ``P`` people's joints side by side.

    Returns:
        ``(C, P)`` ``rho`` of each person in each camera.
    """
    from ..geometry import camera_projection, triangulate
    from ..rigs.tracking import TRACK_MAX_GAP

    real = np.asarray(real, float)
    C = real.shape[0]
    seen = ((real[..., 2] > 0) & np.isfinite(real[..., :2]).all(-1)
            & np.asarray(columns, bool)[None, None])
    Ps = [camera_projection(K, T) for K, T in zip(Ks, poses)]
    X, ok = triangulate(Ps, [r[..., :2] for r in real], list(seen), min_views=min(3, C))
    res = np.zeros(real.shape[:3] + (2,))
    for i, P in enumerate(Ps):
        y = np.where(ok[..., None], X, 0.0) @ P[:, :3].T + P[:, 3]
        y[..., 2] = np.where(ok, y[..., 2], 1.0)
        res[i] = np.nan_to_num(y[..., :2] / y[..., 2:3] - real[i, ..., :2])
    keep = seen & ok[None] & (np.linalg.norm(res, axis=-1) <= limit_px)
    step = np.diff(np.asarray(frame_ids, np.int64)) <= TRACK_MAX_GAP            # (T - 1,)
    pair = keep[:, :-1] & keep[:, 1:] & step[None, :, None]                     # (C, T-1, K)
    K = real.shape[2]
    who = np.broadcast_to(np.arange(C)[:, None, None] * people
                          + (np.arange(K) // (K // people))[None, None], pair.shape)[pair]
    a, b = res[:, :-1][pair], res[:, 1:][pair]
    n = C * people
    ab = np.bincount(who, np.sum(a * b, 1), minlength=n)
    aa = np.bincount(who, np.sum(a * a, 1), minlength=n)
    bb = np.bincount(who, np.sum(b * b, 1), minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = ab / np.sqrt(aa * bb)
    c = np.where(np.isfinite(c), c, 0.0)
    return np.where((c > 0) & (c < 1), c / np.maximum(1.0 - c, 1e-12), 0.0).reshape(C, people)


@dataclass
class EveryoneRun:
    """The graph of every person (:func:`solve_everyone`).

    Attributes:
        observations: the observations in the layout of several people.
        association: the association the solution was solved with.
        solution: the solved rig (joints ``(T, P J, 3)``).
        rounds: per round, ``{"people", "changed", "frames", "rho", "solved"}``: slots,
            the share of the association's entries changed from the previous round (1
            for the first), frames each slot is seen by two cameras in, ``(C, P)`` each
            person's constant error in each camera (:func:`bias_ratio`, 0 where
            negligible and in the first round), whether the round was solved.
    """

    observations: RigObservations
    association: PeopleAssociation
    solution: RigSolution
    rounds: list[dict] = field(default_factory=list)

    @property
    def count(self) -> int:
        """``P``."""
        return self.association.count


def people_joints(joints: tuple[np.ndarray, np.ndarray], J: int, P: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The ``(direct, through mirrors)`` joint indices of one person in the layout of ``P``
    people: the direct ones for every person, those through mirrors for slot 0 (only the
    subject's reflections are associated)."""
    direct = (np.asarray(joints[0], int)[None, :] + J * np.arange(P)[:, None]).ravel()
    return direct, np.asarray(joints[1], int)


def solve_everyone(obs: RigObservations, init, sol: RigSolution,
                   joints: tuple[np.ndarray, np.ndarray], options: RefineOptions,
                   height: float, *, estimate_focal: bool = True,
                   association: PeopleAssociation | None = None,
                   progress: Callable[[str], None] | None = None,
                   iteration_progress=None) -> EveryoneRun | None:
    """Solve the rig from every person (the module docstring).

    Args:
        obs: the one-person run's observations (every camera's candidates per frame).
        init: its :class:`~mirrorgraph.initial.rig.InitialRig` (mirrors, focal guesses).
        sol: its solution, before completion and scale: the rig the first association
            reads.
        joints: ``(direct, through mirrors)`` joint indices of one person.
        options: the graph's settings; height: the gauge (``solve_rig``'s).
        estimate_focal: as :func:`.solve.build_rig`.
        association: a given association (the true one of a synthetic rig: the
            identity-knowing bundle adjustment); solved once, never re-associated.
        progress: called with a short description of each round.
        iteration_progress: ``(iteration, error)`` of each solve.

    Returns:
        :class:`EveryoneRun`; ``None`` where no person is seen by two cameras at once.
    """
    say = progress or (lambda s: None)
    J = obs.skeleton.num_joints
    current, prev, rounds = sol, None, []
    run = None
    for r in range(MAX_ROUNDS):
        if association is not None:
            assoc = association
        else:
            Ks = current.intrinsics or [c.intrinsics.K for c in obs.cameras]
            assoc = associate_people(obs, Ks, current.poses)
        if not assoc.people_found:
            break                                   # no one seen by two cameras
        changed = assoc.changed(prev)
        people_obs = assoc.observations(obs)
        direct = people_joints(joints, J, assoc.count)
        rho = np.zeros((len(obs.cameras), assoc.count))
        if TRACK_WEIGHTS and run is not None:       # measured under every person's rig
            columns = np.zeros(J * assoc.count, bool)
            columns[direct[0]] = True
            rho = bias_ratio(np.stack([c.real for c in people_obs.cameras]),
                             people_obs.frame_ids,
                             current.intrinsics or [c.intrinsics.K for c in obs.cameras],
                             current.poses, columns, options.outlier_threshold, assoc.count)
        rho = np.where(rho > RHO_NEGLIGIBLE, rho, 0.0)
        if run is not None and changed <= STABLE_SHARE and not rho.any():
            rounds.append(dict(people=assoc.count, changed=changed,
                               frames=assoc.frames().tolist(), rho=rho.round(3).tolist(),
                               solved=False))
            break
        say(f"every person: {assoc.count} in the graph (round {r + 1})")
        planes = dict(init.planes)
        planes.update(zip(current.mirror_names, current.planes))
        start = replace(init, poses=[np.asarray(p, float) for p in current.poses],
                        planes=planes, K=[np.asarray(k, float) for k in current.intrinsics]
                        if current.intrinsics else init.K)
        rig = build_rig(people_obs, start, direct,
                        estimate_focal=estimate_focal, focal=options.focal)
        if rho.any():
            rig = weighted(rig, people_obs, np.repeat(rho, J, axis=1))
        current = solve_rig(rig, options, height, progress=iteration_progress)
        rounds.append(dict(people=assoc.count, changed=changed,
                           frames=assoc.frames().tolist(), rho=rho.round(3).tolist(),
                           solved=True))
        run = EveryoneRun(people_obs, assoc, current, rounds)
        prev = assoc
    return run


def weighted(rig, obs: RigObservations, rho: np.ndarray):
    """``rig`` with each direct view's joint columns weighted by :func:`track_weights`
    of ``obs`` (a camera's direct view is its ``real``) at ``rho`` ``(C, K)``."""
    w = track_weights(np.stack([c.real for c in obs.cameras]), rho, frame_ids=obs.frame_ids)
    index = {c.name: i for i, c in enumerate(obs.cameras)}
    return replace(rig, views=tuple(
        replace(v, weight=w[index[v.camera]]) if v.mirror is None else v for v in rig.views))


def split_solution(values: np.ndarray | None, P: int) -> np.ndarray | None:
    """``(T, P J, ...)`` to ``(P, T, J, ...)``."""
    if values is None:
        return None
    v = np.asarray(values)
    T, PJ = v.shape[:2]
    return np.moveaxis(v.reshape(T, P, PJ // P, *v.shape[2:]), 1, 0)


def scale_everyone(sol: RigSolution, skeleton, P: int, height: float,
                   scale_from: str = "stature", keypoint_offset: float | None = None):
    """The solution rescaled so that the stature measured on slot 0's joints (the
    one-person run's subject) is ``height``: :func:`.scale.scale_rig_by_stature` on that
    person, every length of the rig and of every person scaled alike (``keypoint_offset``
    as there; ``None``: the literature's). Returns ``(solution, source, stature)`` as it
    does."""
    from ..anthropometry import KEYPOINT_OFFSET
    from ..stature import LIMB_CHOSEN, stature_rescale
    from .scale import limbs_stature

    o = KEYPOINT_OFFSET if keypoint_offset is None else keypoint_offset
    points, used = split_solution(sol.points, P), split_solution(sol.used, P)
    if scale_from != "stature":
        return sol, LIMB_CHOSEN, limbs_stature(points[0], used[0], skeleton, o)
    factor, source, stature = stature_rescale(points[0], used[0], skeleton, height, o)
    return (sol if factor is None else sol.scaled(factor)), source, stature


def people_record(run: EveryoneRun) -> dict:
    """The ``refinement["people"]`` record of the result: ``mode`` ``"all"``, ``count``
    (slots of the graph), ``found`` (people associated before their packing into
    slots), ``frames`` (per slot, frames seen by two cameras or more), ``observations``
    (per slot, the joints the graph used), ``views`` (:func:`people_views`), ``rounds``
    (:attr:`EveryoneRun.rounds`), ``lr_dropped`` and ``switched``
    (:class:`~mirrorgraph.rigs.people.PeopleAssociation`)."""
    a = run.association
    used = split_solution(run.solution.used, a.count)
    return {"mode": "all", "count": a.count, "found": a.people_found,
            "frames": a.frames().tolist(),
            "observations": [int(np.count_nonzero(u)) for u in used],
            "views": people_views(run.solution, a.count),
            "rounds": run.rounds, "lr_dropped": a.lr_dropped, "switched": a.switched}


def people_views(sol: RigSolution, P: int) -> list[dict]:
    """Per slot, the views it offered keypoints to: view name -> ``{"rms_px",
    "observations", "offered"}`` as the rig's ``refinement["views"]``, of that person's
    joints alone (:attr:`.solve.RigSolution.view_joint_tally`); every table empty where
    the tally is missing."""
    if sol.view_joint_tally is None:
        return [{} for _ in range(P)]
    V, PJ = sol.view_joint_tally.shape[:2]
    per = sol.view_joint_tally.reshape(V, P, PJ // P, 3).sum(2)          # (V, P, 3)
    out = []
    for p in range(P):
        views = {}
        for name, (sq, kept, offered) in zip(sol.view_names, per[:, p]):
            if offered > 0:
                views[name] = {"rms_px": float(np.sqrt(sq / kept)) if kept else float("nan"),
                               "observations": int(kept), "offered": int(offered)}
        out.append(views)
    return out
