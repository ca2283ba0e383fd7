"""``calibrate`` from every person before one mirror: each with their own reflection, their
own 3D joints and bone lengths, all in the one graph of the mirror.

The run is :func:`.mirror.calibrate`'s, step for step, on other observations:

    observations (read, undistort; every person paired with their own reflection and
       tracked, :func:`mirrorgraph.initial.people.pair_people`)
    -> initialisation (the reflective RANSAC over every person's pairs)
    -> solve (the one graph: the people side by side in the layout
       :func:`mirrorgraph.skeletons.people_skeleton`, so that each person has their own
       joints, bone lengths, symmetry and proportions, and no prior links two people;
       the mirror, and the focal length where it is estimated, shared)
    -> completion -> scale -> result

**The metric scale.** Everyone's stature is unknown but one: ``subject_height`` applies to
one person, ``height_of`` says which: ``"tallest"`` (the default: the person of the
largest stature measured on the solved joints, ankle to eyes or head top,
:func:`mirrorgraph.stature.estimate_stature`), ``"first"`` (the first person tracked,
:attr:`PeopleRun.people` order), or a person's index. Given a list ``heights`` (metres,
one per person in that order, ``None`` for unknown ones), the scale is the median of their
ratios. The others' statures then follow from the shared mirror: the graph holds every
person in the same unit (the mirror's distance), so one length fixes them all.

The metric distance is then ``D = H / S(n, 1)``, ``S`` the stature of the person whose
height sets the scale (with a list, the person of the median ratio), and its std is one
person's run's (:func:`mirrorgraph.pipelines.scale.distance_rel_parts`, recorded by part as
``uncertainty["distance_rel_std"]``): the mirror normal's covariance carried through that
person's stature (:func:`mirrorgraph.pipelines.scale.normal_scale_rel_std`, on their own
person and reflection), their stature's sampling std, an estimated focal length's relative
std, the height's prior and the measurement's own spread. The joints' scale share
(:attr:`PeopleRun.scale_rel_std`) holds the last two, as one person's run does.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from ..errors import InputError
from ..initial.body_left_right import undo_body_swaps
from ..initial.clip_left_right import clip_left_right_people
from ..initial.people import PeopleOptions, PeoplePairing, pair_people, split_people
from ..intrinsics import Intrinsics
from ..keypoints import PairedKeypoints, RawDetections
from ..graph.joints_uncertainty import position_std, with_scale
from ..stature import estimate_stature, keypoint_offset_fraction, measurement_rel_std
from .mirror import (CalibrationRun, Observations, focal_estimated, initial_run, initialise,
                     judge_run, prepare, refine_run)
from .options import CalibrateOptions
from .scale import distance_rel_parts, normal_scale_rel_std

__all__ = ["PeopleRun", "calibrate_people"]

HEIGHT_OF = ("tallest", "first")


@dataclass
class PeopleRun:
    """A calibration from every person (:func:`calibrate_people`).

    Attributes:
        run: the run of the one graph (:class:`~.mirror.CalibrationRun`; its keypoints and
            joints in the layout of several people).
        pairing: every person with their reflection, tracked.
        joints3d: ``(P, T, J, 3)`` each person's joints (metres with a subject height, else
            in units of the mirror's distance), real camera frame, NaN where not estimated;
            ``None`` without refinement.
        valid3d: ``(P, T, J)`` bool.
        statures: ``(P,)`` each person's stature measured on their joints (the output's
            unit; NaN where the joints do not span ankle to eyes).
        height_person: the person the subject height applies to (``None``: no height, or
            a list of heights).
        joints_std: ``(P, T, J)`` each person's joints' std in the unit of
            :attr:`joints3d` (:attr:`~.mirror.CalibrationRun.joints_std`: with the metric
            scale's share, :attr:`scale_rel_std`); ``None`` without marginals.
        joints_std_shape: ``(P, T, J)`` the same without the metric scale's share.
    """

    run: CalibrationRun
    pairing: PeoplePairing
    joints3d: np.ndarray | None
    valid3d: np.ndarray | None
    statures: np.ndarray
    height_person: int | None = None
    joints_std: np.ndarray | None = None
    joints_std_shape: np.ndarray | None = None

    @property
    def scale_rel_std(self) -> float | None:
        """The metric scale's relative std, shared by every person (one draw for the
        whole run: :attr:`~.mirror.CalibrationRun.scale_rel_std`); 0 without a height."""
        return self.run.scale_rel_std

    @property
    def num_people(self) -> int:
        """``P``."""
        return self.pairing.num_people

    @property
    def calibration(self):
        """The :class:`~mirrorgraph.result.mirror.Calibration`."""
        return self.run.calibration


def _observe_people(keypoints, intrinsics, opts: CalibrateOptions, people: PeopleOptions,
                    step) -> tuple[Observations, PeoplePairing]:
    """Read, undistort (:func:`~.mirror.prepare`), pair every person with their reflection
    and track them."""
    prep = prepare(keypoints, intrinsics, opts, step)
    if isinstance(prep.keypoints, PairedKeypoints):
        raise InputError("every person's pairing needs the detections of every frame, not "
                         "keypoints already paired (one person)", source=prep.keypoints.source)
    step("pairing every person with their reflection")
    clock = time.perf_counter()
    pairing = pair_people(prep.data, prep.joints, prep.pairing, people)
    prep.warnings.extend(pairing.notes)
    paired = pairing.paired
    if opts.left_right == "clip":        # each person's track decided over the clip
        paired, _ = clip_left_right_people(paired, pairing.base, prep.intrinsics.K,
                                           pairing.epipole, prep.joints, prep.pairing)
    # each person's left/right pairs are pairs of the layout's flip: one chain each
    paired, body_swaps = undo_body_swaps(paired, opts.min_confidence)
    pairing = replace(pairing, paired=paired)
    P, J = pairing.num_people, prep.keypoints.skeleton.num_joints
    all_joints = (np.asarray(prep.joints, dtype=int)[None, :] + J * np.arange(P)[:, None]).ravel()
    # the data of every person: the layout of several people side by side, as paired
    obs = Observations.of(prep, paired, time.perf_counter() - clock, body_swaps, data=paired,
                          joints=all_joints)
    return obs, pairing


def _scale_people(points: np.ndarray, valid: np.ndarray, base, height, heights,
                  height_of, keypoint_offset: float | None = None
                  ) -> tuple[float | None, np.ndarray, int | None, str, float, int | None]:
    """The factor that makes the chosen person's stature (or the list's) the given one:
    ``(factor, statures before scaling, person, source, rel_std, setter)``; ``factor``
    ``None`` where no stature can be measured; ``rel_std`` the stature measurement's own
    relative std (:func:`mirrorgraph.stature.measurement_rel_std`) of the chosen person,
    or with a list of heights the median of the measured people's (the detector's keypoint
    offsets are shared by the people, so their number does not shrink it); ``0`` without
    a factor. ``setter``: the person whose stature sets the scale (the chosen one, or with
    a list the person of the median ratio, the lower of two middle ones), ``None`` without
    a factor. ``keypoint_offset``: the keypoints' placement in metres
    (``RefineOptions.keypoint_offset``), each person's fraction of their own height."""
    P = points.shape[0]

    def own(p: int):                                       # person p's height, metres
        if heights is not None:
            return heights[p] if p < len(heights) else None
        return height

    est = [estimate_stature(points[p], valid[p], base,
                            keypoint_offset=keypoint_offset_fraction(keypoint_offset, own(p)))
           for p in range(P)]
    measured = np.array([np.nan if e is None else e.height for e in est])
    if heights is not None:
        given = [p for p, h in enumerate(heights)
                 if h is not None and p < P and np.isfinite(measured[p])]
        if not given:
            return (None, measured, None, "no person of the given heights has a stature",
                    0.0, None)
        ratios = np.array([float(heights[p]) / measured[p] for p in given])
        rel = float(np.median([measurement_rel_std(est[p]) for p in given]))
        setter = given[int(np.argsort(ratios)[(len(ratios) - 1) // 2])]
        return (float(np.median(ratios)), measured, None,
                f"the median of {len(ratios)} people's given heights over their statures",
                rel, setter)
    if not np.isfinite(measured).any():
        return None, measured, None, "no person's joints span ankle to eyes", 0.0, None
    if height_of == "tallest":
        person = int(np.nanargmax(measured))
    elif height_of == "first":
        person = 0
    else:
        person = int(height_of)
    if height is None:
        return None, measured, None, "no height given", 0.0, None
    if person >= P:
        return (None, measured, None, f"person {person} is not among the {P} people tracked",
                0.0, None)
    if not np.isfinite(measured[person]):
        return (None, measured, person,
                f"person {person}'s joints do not span ankle to eyes", 0.0, None)
    return (float(height) / measured[person], measured, person,
            f"person {person}'s stature ({height_of})", measurement_rel_std(est[person]),
            person)


def _check_height_of(height_of, heights) -> None:
    if heights is not None:
        for h in heights:
            if h is not None and not (isinstance(h, (int, float)) and math.isfinite(h)
                                      and h > 0):
                raise InputError(f"every height must be a positive number of metres, got "
                                 f"{h!r}", field="heights")
        return
    if height_of in HEIGHT_OF:
        return
    if isinstance(height_of, bool) or not isinstance(height_of, (int, np.integer)) \
            or height_of < 0:
        raise InputError(f"must be 'tallest', 'first' or a person's index, got "
                         f"{height_of!r}", field="height_of")


def calibrate_people(keypoints: RawDetections | str | os.PathLike,
                     intrinsics: Intrinsics | None = None,
                     options: CalibrateOptions | None = None,
                     people: PeopleOptions | None = None, *, height_of: str | int = "tallest",
                     heights: Sequence[float | None] | None = None,
                     progress: Callable[[str], None] | None = None) -> PeopleRun:
    """Calibrate the mirror from every person before it (the module docstring).

    Args:
        keypoints: a path to any supported keypoint input, or the detections.
        intrinsics: camera intrinsics; ``None``: the focal length estimated (as
            :func:`~.mirror.calibrate`).
        options: :class:`~.options.CalibrateOptions`; ``subject_height`` is one person's
            (``height_of``).
        people: :class:`~mirrorgraph.initial.people.PeopleOptions`.
        height_of: whose height ``subject_height`` is: ``"tallest"``, ``"first"`` or a
            person's index.
        heights: instead, every person's height (metres, ``None``: unknown), in
            :attr:`PeopleRun.people` order.
        progress: optional callback receiving the name of each step.

    Raises:
        InputError: unusable input or options (the message names the field).
        DegenerateGeometryError: the data cannot determine the mirror.
    """
    _check_height_of(height_of, heights)
    opts = (options or CalibrateOptions()).checked()
    height = opts.subject_height
    # the graph runs in units of the mirror's distance: the height is one person's, known
    # only once the statures are measured
    run_opts = replace(opts, subject_height=None,
                       refine_options=replace(opts.graph, subject_height=None))
    step = progress or (lambda _name: None)
    obs, pairing = _observe_people(keypoints, intrinsics, run_opts, people or PeopleOptions(),
                                   step)
    init = initialise(obs, run_opts, step)
    run = initial_run(obs, init, run_opts)
    calib = run.calibration
    calib.input["subject_height"] = height
    calib.input["people"] = {"count": pairing.num_people, "tracks_found": pairing.tracks_found,
                             "pairs_left_out": pairing.pairs_left_out,
                             "height_of": None if heights is not None else height_of,
                             "heights": None if heights is None else list(heights)}
    P = pairing.num_people
    joints3d = valid3d = None
    statures = np.full(P, np.nan)
    person = None
    if opts.refine:
        step("factor-graph refinement")
        refine_run(run, run_opts, estimate_focal=intrinsics is None,
                focal_rel_sigma=None if focal_estimated(run_opts) else
                run_opts.graph.focal.guess_rel_sigma)
        joints3d = split_people(run.joints3d, P)
        valid3d = split_people(run.valid3d, P)
        factor, measured, person, source, rel, setter = _scale_people(
            joints3d, valid3d, pairing.base, height, heights, height_of,
            opts.graph.keypoint_offset)
        statures = measured
        if (height is not None or heights is not None) and factor is not None:
            joints3d = joints3d * factor
            statures = measured * factor
            calib.distance, calib.scale = float(factor), "subject_height"
            calib.refinement["bone_lengths"] = {
                b: v * factor for b, v in calib.refinement["bone_lengths"].items()}
            # the height's prior and the stature measurement's own spread, as one
            # person's scale (mirrorgraph.pipelines.scale.scale_by_stature) holds them
            scale_rel = float(np.hypot(opts.graph.height_sigma, rel))
            parts = _distance_rel_parts(run, pairing, joints3d, valid3d, setter,
                                        height if heights is None else heights[setter],
                                        rel, opts)
            calib.uncertainty["distance_std"] = parts["total"] * float(factor)
            calib.uncertainty["distance_rel_std"] = parts
            calib.refinement["scale_source"] = source
            _scale_joints(run, float(factor), scale_rel)
        elif height is not None or heights is not None:
            calib.warnings.append(f"scale: {source}; the distance stays unknown")
        calib.input["people"]["statures"] = [None if not np.isfinite(s) else float(s)
                                             for s in statures]
        calib.input["people"]["height_person"] = person
    elif height is not None:
        calib.warnings.append("subject_height needs the refinement (it scales the body); "
                              "without it the distance stays unknown")
    judge_run(run, obs, init, opts)
    stds = [None if v is None else split_people(v, P)
            for v in (run.joints_std, run.joints_std_shape)]
    return PeopleRun(run=run, pairing=pairing, joints3d=joints3d, valid3d=valid3d,
                     statures=statures, height_person=person, joints_std=stds[0],
                     joints_std_shape=stds[1])


def _distance_rel_parts(run: CalibrationRun, pairing: PeoplePairing, points: np.ndarray,
                        valid: np.ndarray, setter: int, height: float, measurement: float,
                        opts: CalibrateOptions) -> dict[str, float]:
    """The metric distance's relative std by part (:func:`~.scale.distance_rel_parts`),
    as one person's run states it, from the person whose stature sets the scale: the
    mirror normal's covariance carried through their stature
    (:func:`~.scale.normal_scale_rel_std`, on their own person and reflection), their
    stature's sampling std, an estimated focal length's relative std, the height's prior
    and the measurement's own spread (``measurement``, :func:`_scale_people`'s).

    Args:
        run: the refined run (its keypoints in the layout of several people, undistorted).
        pairing: every person with their reflection (``base``: one person's layout).
        points: ``(P, T, J, 3)`` the joints in the graph's unit; valid: ``(P, T, J)``.
        setter: the person whose stature sets the scale.
        height: their height, metres.
        measurement: the measurement's relative std the scale holds.
        opts: the options (``graph.height_sigma``, ``graph.keypoint_offset``).
    """
    calib = run.calibration
    J = pairing.base.num_joints
    cols = slice(setter * J, (setter + 1) * J)
    paired = replace(run.paired, skeleton=pairing.base, real=run.paired.real[:, cols],
                     mirror=run.paired.mirror[:, cols])
    offset = keypoint_offset_fraction(opts.graph.keypoint_offset, height)
    stature = estimate_stature(points[setter], valid[setter], pairing.base,
                               keypoint_offset=offset)
    normal_cov = np.asarray(calib.uncertainty.get("normal_cov", np.full((3, 3), np.nan)),
                            float)
    K = np.asarray(calib.intrinsics.K, float)
    normal_rel = normal_scale_rel_std(paired, K, calib.normal, 1.0, valid[setter],
                                      normal_cov, offset)
    focal_std = calib.uncertainty.get("focal_std_px")
    focal_rel = float(focal_std) / float(K[0, 0]) if focal_std is not None else 0.0
    parts = distance_rel_parts(normal_rel, stature, opts.graph.height_sigma, focal_rel)
    parts["measurement"] = float(measurement)
    parts["total"] = float(np.sqrt(parts["data"] ** 2 + parts["height"] ** 2
                                   + measurement ** 2))
    return parts


def _scale_joints(run: CalibrationRun, factor: float, scale_rel_std: float) -> None:
    """The run's joints and their uncertainty ``factor`` times larger, the metric scale's
    share (relative std ``scale_rel_std``, one draw for every person) added to each joint's
    covariance as one person's run adds it (:func:`~mirrorgraph.graph.joints_uncertainty.
    with_scale`, ``joints_std^2 = joints_std_shape^2 + (scale_rel_std |X|)^2``), in place."""
    before = np.nan_to_num(run.joints3d)
    run.joints3d = run.joints3d * factor
    if run.joints_cov is None:
        return
    # the shape's covariance: the graph's, without a scale share it may hold already
    shape = np.asarray(run.joints_cov, float)
    if run.scale_rel_std:
        shape = shape - run.scale_rel_std ** 2 * before[..., :, None] * before[..., None, :]
    shape = shape * factor ** 2
    run.joints_std_shape = position_std(shape)
    run.scale_rel_std = float(scale_rel_std)
    run.joints_cov = with_scale(shape, np.nan_to_num(run.joints3d), scale_rel_std)
    run.joints_std = position_std(run.joints_cov)
