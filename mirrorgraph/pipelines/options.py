"""The options of a calibration run: one object for :func:`~mirrorgraph.calibrate` and
:func:`~mirrorgraph.calibrate_rig`.

A single mirror is the rig of one camera and one mirror, so both front ends take the same
:class:`CalibrateOptions`; the few settings that only one of them reads say so. The
graph's own settings (priors, kernels, schedule, the focal length's priors) stay in
:class:`mirrorgraph.graph.RefineOptions`, held here as ``refine_options``: this object
is what a *run* needs around the graph.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..initial.estimators import DEFAULT_THRESHOLD_PX, ESTIMATORS
from ..graph.options import RefineOptions, one_subject_height
from ..intrinsics import DEFAULT_FOV_DEG
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from ..rigs.config import OFFSET_WINDOW

#: The values of :attr:`CalibrateOptions.time_offsets`.
TIME_OFFSETS = ("search", "fixed")

__all__ = ["CalibrateOptions", "PEOPLE"]

#: The values of :attr:`CalibrateOptions.people` (``None``: the run's default).
PEOPLE = ("one", "all", None)
#: How a single mirror's left/right labels are decided (``left_right``).
LEFT_RIGHT = ("clip", "frame")


@dataclass
class CalibrateOptions:
    """Options of :func:`mirrorgraph.calibrate` and :func:`mirrorgraph.calibrate_rig`.

    Grouped by concern; a setting lives in one place (the graph's in ``refine_options``).

    **Input**

    Attributes:
        skeleton: keypoint layout of an input that does not name its own (a rig: the
            cameras whose table names none); ``None``: recognised from the input.
        joints: the joints the calibration uses (:func:`mirrorgraph.joint_sets.resolve_joints`):
            ``None`` / ``"auto"`` (one mirror: the skeleton's calibration joints, no face,
            hands or feet, as MirrorCalib; a rig: every keypoint in the direct views, the
            limbs through mirrors, or its file's ``joints``), ``"limbs"``, ``"all"``, or
            joint names (a sequence or one comma-separated string; at least 4).
        min_confidence: joints below this detector confidence are ignored (one mirror).
        detection: :class:`mirrorgraph.video.VideoOptions` for inputs that are videos
            (frame range, detector, cache); ``None``: the defaults.
        fps: frame rate of the 3D motion in Hz, given by the user; ``None``: from the
            input, else from ``video``, else :data:`~mirrorgraph.preprocess.DEFAULT_FPS`
            with a warning (:func:`mirrorgraph.preprocess.resolve_fps`; one mirror). The
            graph's acceleration priors, stated at 30 fps, are taken at this rate
            (:meth:`mirrorgraph.graph.options.PriorOptions.at_frame_rate`).
        video: the video the keypoints were detected on, read for its frame rate
            (:func:`~mirrorgraph.preprocess.fps_from_video`; one mirror) and, where the
            focal length is estimated, for the scene's straight lines
            (``FocalOptions.lines``).
        people: ``"all"``: every person in view calibrates and gets their own 3D joints
            (a rig: associated across the cameras after a first solve from the clearest
            person, :mod:`mirrorgraph.pipelines.rig_people`; one mirror: ``calibrate
            --people all`` runs :func:`mirrorgraph.pipelines.people.calibrate_people`);
            ``"one"``: the person seen longest only. ``None``: the run's default
            (``"one"``: :data:`mirrorgraph.pipelines.rig.DEFAULT_PEOPLE`).

    **Time** (a rig's cameras)

    Attributes:
        time_offsets: ``"search"`` (default): every camera's time offset against the
            first camera found from the people, whole frames then a fraction
            (:mod:`mirrorgraph.rigs.clocks`), the rig file's ``frame_offset`` the centre of
            the search and kept unless the people fit another offset significantly better
            (a warning where they put a camera elsewhere), and applied to its keypoints;
            ``"fixed"``: the rig file's ``frame_offset`` as given, no search.
        offset_window: frames searched either way of a camera's given offset.

    **Initialisation**

    Attributes:
        estimator: initial estimator of a single mirror, one of ``reflective``
            (default), ``eightpoint`` (MirrorCalib's Baseline1), ``reflective8`` (the
            paper's 6-unknown eight-point with RANSAC).
        threshold_px: inlier threshold on the epipolar distance, pixels (one mirror;
            a rig's views use ``refine_options.outlier_threshold``).
        seed: seed of every random choice (RANSAC), a non-negative integer.
        left_right: ``"frame"`` (default): the pairing's check of each frame alone
            (one mirror; a rig's cameras keep the pairing's); ``"clip"``: after the
            pairing, which frames of which view carry crossed left/right labels (a body
            seen from behind labelled as facing the camera) is decided over the whole
            clip (:mod:`mirrorgraph.initial.clip_left_right`; with ``people="all"`` each
            person's track apart). ``"clip"`` puts right a view crossed for the whole
            clip (BlazePose on a person seen from behind: 94 -> 3 % of the frames
            crossed, ``bench/RESULTS_left_right_clip.md``), but under a detector whose
            per-label bias follows the labels it crosses runs that were not
            (``bench/RESULTS_joints_full.md``: 4 of 20 realistic scenes, the mirror
            0.78 -> 2.33 deg on one): use it on clips whose person turns their back
            to the camera.

    **Intrinsics** (cameras given without a camera matrix)

    Attributes:
        image_size: ``(width, height)`` in pixels where the input does not carry it
            (one mirror; a rig's file gives each camera's).
        fov_deg: horizontal field of view the focal length's estimate starts from (the
            centre of its weak prior), or with ``estimate_focal=False`` the field of view
            assumed, held by a prior of ``FocalOptions.guess_rel_sigma`` whose spread is in
            every std.
        estimate_focal: estimate the focal length (and the principal point about the
            image centre, :class:`mirrorgraph.graph.options.FocalOptions`) in the factor
            graph, where the bones' constant lengths determine it. Where the data do not
            (a far or square-on mirror, little motion in depth) the estimate is kept with
            its large std and a warning says so. Either way every reported std holds the
            unknown intrinsics.

    **Scale**

    Attributes:
        subject_height: the subject's standing height in metres (the metric prior); the
            one home of this setting (a height in ``refine_options`` is taken when this is
            ``None``, two different ones are refused; a rig file's ``subject_height`` is
            used when neither gives one). Without any, lengths are in units of the mirror
            distance (one mirror) or of the subject's height (a rig).

    **Refinement and output**

    Attributes:
        refine: run the factor-graph refinement after the initialisation (one mirror; a
            rig always does).
        refine_options: :class:`mirrorgraph.graph.RefineOptions` (priors, schedule,
            solver, gauge, the focal length's priors); ``None``: the defaults.
        complete_joints: after the refinement, triangulate with the solved mirror every
            keypoint outside ``joints`` seen in both views
            (:func:`mirrorgraph.completion.complete_mirror_joints`), so that the 3D
            joints hold face and feet too (a rig always completes them).
        sensitivity_priors: also solve the graph again with each body prior's weight
            halved and doubled (``calibration.sensitivity.prior_weights``; eight
            calibrations more: off by default, ``--sensitivity`` on the command line; one
            mirror).
    """

    # input
    skeleton: str | None = None
    joints: str | tuple[str, ...] | None = None
    min_confidence: float = DEFAULT_MIN_CONFIDENCE
    detection: object | None = None
    fps: float | None = None
    video: str | os.PathLike | None = None
    people: str | None = None
    # time (a rig's cameras)
    time_offsets: str = "search"
    offset_window: int = OFFSET_WINDOW
    # initialisation
    estimator: str = "reflective"
    threshold_px: float = DEFAULT_THRESHOLD_PX
    seed: int = 0
    left_right: str = "frame"
    # intrinsics
    image_size: tuple[int, int] | None = None
    fov_deg: float = DEFAULT_FOV_DEG
    estimate_focal: bool = True
    # scale
    subject_height: float | None = None
    # refinement and output
    refine: bool = True
    refine_options: RefineOptions | None = None
    complete_joints: bool = True
    sensitivity_priors: bool = False

    @property
    def graph(self) -> RefineOptions:
        """The graph's settings (``refine_options``, or the defaults)."""
        return self.refine_options or RefineOptions()

    def checked(self, default_height: float | None = None) -> "CalibrateOptions":
        """These options validated, with the one subject height resolved.

        Args:
            default_height: the height where neither this object nor ``refine_options``
                gives one (a rig file's), metres.

        Returns:
            A copy whose ``subject_height`` is the run's one height (or ``None``) and
            whose ``refine_options`` carry it (the gauge's value).

        Raises:
            InputError: an unknown estimator, a seed that is no non-negative integer, a
                field of view outside (0, 180) deg, two different heights or one that is
                no human height; each names its field.
        """
        from dataclasses import replace

        if self.people not in PEOPLE:
            raise InputError(f"must be 'one' or 'all', got {self.people!r}",
                             field="people")
        if self.left_right not in LEFT_RIGHT:
            raise InputError(f"must be one of {', '.join(LEFT_RIGHT)}, got {self.left_right!r}",
                             field="left_right")
        if self.estimator not in ESTIMATORS:
            raise InputError(f"unknown estimator {self.estimator!r}; choose one of "
                             f"{', '.join(ESTIMATORS)}", field="estimator")
        if (isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer))
                or self.seed < 0):
            raise InputError(f"must be a non-negative integer, got {self.seed!r}", field="seed")
        if self.time_offsets not in TIME_OFFSETS:
            raise InputError(f"unknown time_offsets {self.time_offsets!r}; choose one of "
                             f"{', '.join(TIME_OFFSETS)}", field="time_offsets")
        if (isinstance(self.offset_window, bool) or not isinstance(self.offset_window,
                                                                    (int, np.integer))
                or self.offset_window < 1):
            raise InputError(f"must be a positive number of frames, got {self.offset_window!r}",
                             field="offset_window")
        if not 0 < float(self.fov_deg) < 180:
            raise InputError(f"a field of view must lie between 0 and 180 deg, not "
                             f"{self.fov_deg}", field="fov_deg")
        height = one_subject_height(self.subject_height, self.refine_options, "refine_options",
                                    default=default_height)
        graph = self.graph
        if height is not None and graph.subject_height != height:
            graph = replace(graph, subject_height=height)
        return replace(self, subject_height=height,
                       refine_options=graph if self.refine_options is not None
                       or height is not None else None)
