"""``calibrate-rig --people all``: every person the rig sees, in the one graph.

The loop of :func:`solve_everyone`, after the one-person run has solved the rig from its
clearest person (:func:`mirrorgraph.pipelines.rig.calibrate_rig`):

    associate every person across the cameras with the current rig
       (:func:`mirrorgraph.rigs.people.associate_people`)
    -> the observations in the layout of several people side by side
       (:func:`mirrorgraph.skeletons.people_skeleton`, as ``calibrate --people all``:
       each person their own joints, bones and body priors, no prior between two people)
    -> each (person, camera, joint) track's weight in the graph, its effective number of
       independent frames over its frames (:func:`track_weights`)
    -> the one graph built and solved by the one driver (:func:`.solve.build_rig`,
       :func:`.solve.solve_rig`), starting from the current rig
    -> again, until the association changes in at most :data:`STABLE_SHARE` of its
       entries, at most :data:`MAX_ROUNDS` solves.

The person of the one-person run is slot 0, the person ``subject_height`` applies to.

A detector's error on a joint is not independent from frame to frame: it holds a
constant part that changes only as the joint moves in the image (measured on BlazePose
against the Pose2Sim demo's Qualisys rig, 6-15 px per joint; 21-38 px on the demo's
nearly still second person, 4-5x the frame-to-frame scatter). A person standing still
repeats that error in every frame, and the graph, weighing each frame as an independent
observation, lets it pull the cameras as hard as a person who moves. :func:`track_weights`
gives each track the information of its independent frames (Kish's effective sample
size of a mean under correlated errors): frames where the joint stands within
:data:`DETECTOR_BIAS_PX` of each other share one constant error of that size on top of
the ``pixel_sigma`` scatter.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..graph.options import RefineOptions
from ..rigs.observations import RigObservations
from ..rigs.people import PeopleAssociation, associate_people
from .solve import RigSolution, build_rig, solve_rig

__all__ = ["DETECTOR_BIAS_PX", "MAX_ROUNDS", "STABLE_SHARE", "TRACK_WEIGHTS", "EveryoneRun",
           "people_joints", "solve_everyone", "split_solution", "track_weights"]

#: Solves of the graph of every person, at most.
MAX_ROUNDS = 2

#: An association that changes in at most this share of its (camera, frame, person)
#: entries from the previous round's is stable: no further solve.
STABLE_SHARE = 0.01


#: px: a detector's constant error on a joint (the std of each coordinate) while the
#: joint stays in one place of the image, and the distance the joint moves before that
#: error is drawn again (BlazePose against the Pose2Sim demo's Qualisys rig: 6-15 px per
#: joint on the moving subject, docs/accuracy.md).
DETECTOR_BIAS_PX = 10.0

#: Each track weighted by its effective number of independent frames
#: (:func:`track_weights`); ``False``: every observation weighs 1.
TRACK_WEIGHTS = True


def track_weights(real: np.ndarray, pixel_sigma: float, bias_px: float = DETECTOR_BIAS_PX,
                  min_confidence: float = 0.0) -> np.ndarray:
    """Each track's weight: its effective number of independent frames over its frames.

    A track is one joint of one person in one camera, its ``n`` observations ``x_t``
    (px). Its errors are the detector's scatter (std ``pixel_sigma``) plus a constant
    error (std ``bias_px``) shared by the frames where the joint stands in the same
    cell of a ``bias_px`` grid of the image. With ``rho = (bias_px / pixel_sigma)^2``
    and ``n_k`` the frames in cell ``k``, the effective sample size of the track's mean
    (Kish, *Survey Sampling*, 1965, the design effect of clusters) is
    ``n (1 + rho) / (1 + rho sum_k n_k^2 / n)``: ``n`` where every frame stands in its
    own cell (a moving joint), about ``1 + 1 / rho`` where all stand in one (a person
    standing still). The weight is that over ``n``, in ``(0, 1]``: each observation's
    information in the graph (:attr:`mirrorgraph.graph.rig.View.weight`).

    Args:
        real: ``(C, T, K, 3)`` each camera's observations of ``K`` joint columns (every
            person's joints side by side), px and confidence; NaN or confidence at most
            ``min_confidence``: not seen.
        pixel_sigma: the scatter, px; bias_px: the constant error and the cell, px.

    Returns:
        ``(C, K)`` weights (1 where a column is not seen).
    """
    real = np.asarray(real, float)
    C, T, K = real.shape[:3]
    seen = (real[..., 2] > min_confidence) & np.isfinite(real[..., :2]).all(-1)  # (C, T, K)
    c, t, k = np.nonzero(seen)
    out = np.ones((C, K))
    if not len(c):
        return out
    cell = np.floor(real[c, t, k, :2] / float(bias_px)).astype(np.int64)
    track = c * K + k
    keys = np.stack([track, cell[:, 0], cell[:, 1]], 1)
    groups, counts = np.unique(keys, axis=0, return_counts=True)
    sq = np.bincount(groups[:, 0], weights=counts.astype(float) ** 2, minlength=C * K)
    n = np.bincount(track, minlength=C * K).astype(float)
    rho = (float(bias_px) / float(pixel_sigma)) ** 2
    has = n > 0
    w = np.ones(C * K)
    w[has] = (1.0 + rho) / (1.0 + rho * sq[has] / n[has])
    out[:] = np.minimum(w, 1.0).reshape(C, K)
    return out


@dataclass
class EveryoneRun:
    """The graph of every person (:func:`solve_everyone`).

    Attributes:
        observations: the observations in the layout of several people.
        association: the association the solution was solved with.
        solution: the solved rig (joints ``(T, P J, 3)``).
        rounds: per round, ``{"people", "changed", "frames"}``: slots, the share of the
            association's entries changed from the previous round (1 for the first),
            frames each slot is seen by two cameras in.
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
        if run is not None and changed <= STABLE_SHARE:
            rounds.append(dict(people=assoc.count, changed=changed,
                               frames=assoc.frames().tolist(), solved=False))
            break
        say(f"every person: {assoc.count} in the graph (round {r + 1})")
        people_obs = assoc.observations(obs)
        planes = dict(init.planes)
        planes.update(zip(current.mirror_names, current.planes))
        start = replace(init, poses=[np.asarray(p, float) for p in current.poses],
                        planes=planes, K=[np.asarray(k, float) for k in current.intrinsics]
                        if current.intrinsics else init.K)
        rig = build_rig(people_obs, start, people_joints(joints, J, assoc.count),
                        estimate_focal=estimate_focal, focal=options.focal)
        if TRACK_WEIGHTS:
            rig = weighted(rig, people_obs, options.pixel_sigma)
        current = solve_rig(rig, options, height, progress=iteration_progress)
        rounds.append(dict(people=assoc.count, changed=changed,
                           frames=assoc.frames().tolist(), solved=True))
        run = EveryoneRun(people_obs, assoc, current, rounds)
        prev = assoc
        if association is not None:
            break
    return run


def weighted(rig, obs: RigObservations, pixel_sigma: float):
    """``rig`` with each direct view's joint columns weighted by :func:`track_weights`
    of ``obs`` (a camera's direct view is its ``real``)."""
    w = track_weights(np.stack([c.real for c in obs.cameras]), pixel_sigma)
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
                   scale_from: str = "stature"):
    """The solution rescaled so that the stature measured on slot 0's joints (the
    one-person run's subject) is ``height``: :func:`.scale.scale_rig_by_stature` on that
    person, every length of the rig and of every person scaled alike. Returns
    ``(solution, source, stature)`` as it does."""
    from ..stature import LIMB_CHOSEN, stature_rescale

    if scale_from != "stature":
        return sol, LIMB_CHOSEN, None
    points, used = split_solution(sol.points, P), split_solution(sol.used, P)
    factor, source, stature = stature_rescale(points[0], used[0], skeleton, height)
    return (sol if factor is None else sol.scaled(factor)), source, stature


def people_record(run: EveryoneRun) -> dict:
    """The ``refinement["people"]`` record of the result: ``mode`` ``"all"``, ``count``
    (slots of the graph), ``found`` (people associated before their packing into
    slots), ``frames`` (per slot, frames seen by two cameras or more), ``observations``
    (per slot, the joints the graph used), ``rounds`` (:attr:`EveryoneRun.rounds`),
    ``lr_dropped`` and ``switched`` (:class:`~mirrorgraph.rigs.people.PeopleAssociation`)."""
    a = run.association
    used = split_solution(run.solution.used, a.count)
    return {"mode": "all", "count": a.count, "found": a.people_found,
            "frames": a.frames().tolist(),
            "observations": [int(np.count_nonzero(u)) for u in used],
            "rounds": run.rounds, "lr_dropped": a.lr_dropped, "switched": a.switched}
