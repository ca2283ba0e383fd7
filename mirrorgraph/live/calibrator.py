"""The live run: one frame of keypoints in, that frame's 3D joints and the current mirror out.

    from mirrorgraph.live import LiveCalibrator, LiveOptions
    live = LiveCalibrator("COCO_17", intrinsics, LiveOptions.of(subject_height=1.75))
    for people in detector_frames:          # (P, J, 3) x, y, confidence per frame
        out = live.update(people)
        out.status, out.joints3d, out.joints_std, out.mirror.normal
    live.close()

**Per frame** (fixed latency, no solver): the detections are checked, undistorted, paired
against the epipole ``e ~ K n`` (:func:`mirrorgraph.initial.pairing.pair_with_epipoles`),
left and right swapped back where the frames so far say the detector confused them
(:class:`~mirrorgraph.initial.body_left_right.BodySwapFilter`), refined with the latest
window's bone lengths (spreads widened by their steps between windows) and torso distances
(``RefineOptions.torso_sigma``) from each joint's rays' midpoint and its track's prediction,
the two and each limb's other branch along its ray folded by the frame's cost
(:mod:`.frame_prior`), the worse view off by more than the threshold once the bones hold
the joint left out (:func:`mirrorgraph.graph.outliers.one_view_outliers`), kept where it
reprojects within the threshold in front of the camera and the mirror, filtered over time
(:mod:`.joint_filter`: a Kalman filter under the joints pass's acceleration prior, outliers
gated; a new window rescales the tracks by the joints' scale change), the face fused with
where the trunk puts it (:func:`.frame_prior.with_head_prior`), and given again
:attr:`LiveOptions.lag_frames` frames later, final (:attr:`LiveFrame.settled`): the joints
pass's graph over the latest frames (:mod:`.window_graph`, solved in the calling thread)
where it solves a joint, else the fixed-lag smoother's. Each joint's std holds the
smoother's covariance (widened for noise that persists in time: :class:`.noise_in_time.NoiseInTime`),
the detector's bias (:func:`.frame_prior.bias_covariance`) and the fused normal's share
(:func:`joints_normal_jacobian`); ``joints_std`` adds the scale's, ``joints_std_shape`` not.

**The mirror** (:mod:`.estimator`): frames holding two people or more are buffered and
calibrated by the offline run: every frame so far each time their number doubles (from
``first_window_frames`` to ``window_frames``), then each later block of ``window_frames``
fused into the mirror of the older ones (:class:`~.estimator.MirrorFusion`), in the calling
thread (``background=False``: deterministic) or in one worker process
(:func:`start_worker`; ``background=True``: the frames flow on, a buffer beyond
``max_buffer_frames`` while the worker is busy is thinned evenly).

**Status**: ``initialising`` until the fused rotation std is at most ``calibrated_std_deg``,
then ``calibrated`` unless the latest window fails the reflection check
(:mod:`mirrorgraph.initial.reflection_check`). Figures: ``bench/RESULTS_live*.md``.
"""

from __future__ import annotations

import copy
import math
import signal
import time
from collections import Counter, deque
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from .. import geometry as geo
from ..errors import InputError
from ..initial.body_left_right import BodySwapFilter
from ..keypoints import RawDetections
from .estimator import MirrorFusion, WindowEstimate, solve_window
from .frame_prior import (bias_covariance, bone_branches, head_layout, refine_starts,
                          triangulate_two_rays, two_starts, view_residuals,
                          views_near_track, with_head_prior)
from .joint_filter import JointFilter
from .noise_in_time import NoiseInTime
from .window_graph import WindowGraph

if TYPE_CHECKING:
    from ..intrinsics import Intrinsics
    from ..skeletons import Skeleton

__all__ = ["LiveOptions", "LiveMirror", "LiveFrame", "LiveCalibrator", "STATUSES",
           "joints_normal_jacobian", "start_worker", "stop_started_workers"]

#: The statuses of a live mirror.
STATUSES = ("initialising", "calibrated")


@dataclass
class LiveOptions:
    """Options of :class:`LiveCalibrator`.

    Attributes:
        calibrate: :class:`~mirrorgraph.pipelines.options.CalibrateOptions` of every
            window's solve (subject height, image size, joints, thresholds, seed, the
            graph's settings); ``None``: the defaults.
        first_window_frames: frames holding two people or more that the first solve
            (the RANSAC and the graph) waits for.
        window_frames: such frames per window. The first block of this many is
            calibrated whole, again each time it has doubled (60, 120, 240, ... frames:
            until then the live mirror *is* the offline calibration of every frame so
            far); every later window of this many is fused into it.
        calibrated_std_deg: the rotation std at which the status becomes ``calibrated``.
        background: solve windows in one worker process (see the module docstring).
        max_buffer_frames: most frames buffered while the worker is busy (thinned evenly
            beyond; at least ``window_frames``).
        fps: the stream's frame rate, Hz, where ``calibrate.fps`` is ``None``: of the
            frame times where the caller gives none and of the acceleration priors (the
            joint filter's and the windows' graphs,
            :meth:`~mirrorgraph.graph.options.PriorOptions.at_frame_rate`).
        bone_prior: refine each frame's joints with the latest window's bone lengths
            (:mod:`.frame_prior`); ``False``: the two rays alone.
        smooth: each joint's track filtered over time (:class:`.joint_filter.JointFilter`:
            the joints pass's acceleration prior ``RefineOptions.joints_smoothness_sigma``
            at the stream's frame rate, ``calibrate.fps`` or ``fps``,
            a Kalman filter over every frame so far, measurements beyond its gate taken
            as outliers); ``False``: each frame on its own.
        lag_frames: each frame is given again, final, this many frames later
            (:attr:`LiveFrame.settled`: its joints smoothed with the frames after it;
            what ``mirrorgraph live`` writes): the output's fixed lag, whatever solves
            it; ``0``: none. At 30 fps the default 9 is 0.30 s (with a window's solve,
            0.015-0.06 s, on the frame that runs it: under 0.5 s).
        window_graph_frames: ``W``: the settled joints are the joints pass's own graph
            (:mod:`.window_graph`: reprojection with the mirror held, every bone at the
            latest window's lengths, the torso, the acceleration prior, one-view outliers
            left out) over the last ``W`` frames that gave joints, from the per-frame
            joints; the joints it does not solve (seen in one view) keep the fixed-lag
            smoother's; every settled joint's std is the smoother's (widened by its
            distance to the graph's point where the graph solved it). ``0``: the
            fixed-lag smoother alone (:class:`.joint_filter.JointFilter`). 20 gives the
            joints of 30 to 0.01 of PA-MPJPE at two thirds of the solve (15: the
            fixtures 1.09 -> 1.10x the offline run's; ``bench/RESULTS_live_graph.md``).
        window_graph_every: ``k``: the window is solved on every ``k``-th update, in
            the calling thread (15-60 ms each on one core), and each solve gives the
            next ``k`` settled frames: frame ``t - lag_frames`` to ``t - lag_frames +
            k - 1`` of the update at ``t``, seen ``lag_frames`` to ``lag_frames - k + 1``
            frames ahead (``k`` is cut to ``lag_frames + 1``).
        can_wait: the source can wait (a file replayed flat out). In the background
            mode the frame that starts the first solve then waits for its mirror, and a
            window due while the worker is busy waits for it instead of thinning the
            buffer: the windows are those of the calling thread's run and every frame
            after the first window has joints. ``False`` for a live feed, whose frames
            cannot wait.
    """

    calibrate: object | None = None
    first_window_frames: int = 60
    window_frames: int = 900
    max_buffer_frames: int = 1800
    calibrated_std_deg: float = 2.0
    background: bool = False
    fps: float = 30.0
    bone_prior: bool = True
    smooth: bool = True
    lag_frames: int = 9
    window_graph_frames: int = 20
    window_graph_every: int = 5
    can_wait: bool = False

    @classmethod
    def of(cls, **kwargs) -> "LiveOptions":
        """Live options with the given ``CalibrateOptions`` fields (``subject_height``,
        ``image_size``, ...) and live fields (``window_frames``, ...) by name."""
        from ..pipelines.options import CalibrateOptions

        mine = {k: kwargs.pop(k) for k in list(kwargs) if k in cls.__dataclass_fields__}
        return cls(calibrate=CalibrateOptions(**kwargs), **mine)


@dataclass
class LiveMirror:
    """The current mirror of a live run (a snapshot).

    Attributes:
        status: ``initialising`` or ``calibrated`` (never while ``doubt`` is said).
        normal: ``(3,)`` unit normal, camera frame; ``None`` before the first window.
        distance: mirror distance (metres with a subject height, else 1).
        rotation_std_deg: the virtual camera's rotation std, deg.
        distance_std: the distance's std (the height's share included); ``None``
            without a subject height (the distance is the unit).
        scale_rel_std: the metric scale's relative std
            (:attr:`~.estimator.MirrorFusion.scale_rel_std`): ``height_sigma`` (the
            subject's height and proportions), the latest window's stature measurement
            spread (:func:`mirrorgraph.stature.measurement_rel_std`) and the windows'
            statures' fused sampling std; shared by every length of every frame and not in
            :attr:`LiveFrame.joints_std_shape`; ``None`` without a subject height.
        focal_px, focal_std_px: the estimated focal length (``None``: given).
        windows, rejected, failed, resets: windows fused, rejected, that failed, restarts.
        scale: ``"subject_height"`` (metres) or ``"unit_distance"``.
        doubt: the reflection check's line where the latest window fused doubted that
            the detection paired as the reflection is one (a second person, or the
            detector too poor to tell); ``None`` otherwise.
    """

    status: str = "initialising"
    normal: np.ndarray | None = None
    distance: float | None = None
    rotation_std_deg: float | None = None
    distance_std: float | None = None
    scale_rel_std: float | None = None
    focal_px: float | None = None
    focal_std_px: float | None = None
    windows: int = 0
    rejected: int = 0
    failed: int = 0
    resets: int = 0
    scale: str = "unit_distance"
    doubt: str | None = None

    def to_dict(self) -> dict:
        """JSON-ready (NaN as ``None``)."""
        return {"status": self.status,
                "normal": None if self.normal is None else [float(v) for v in self.normal],
                "distance": _num(self.distance), "rotation_std_deg": _num(self.rotation_std_deg),
                "distance_std": _num(self.distance_std),
                "scale_rel_std": _num(self.scale_rel_std), "focal_px": _num(self.focal_px),
                "focal_std_px": _num(self.focal_std_px), "windows": self.windows,
                "windows_rejected": self.rejected, "windows_failed": self.failed,
                "resets": self.resets, "scale": self.scale, "doubt": self.doubt}


def _num(v) -> float | None:
    return None if v is None or not np.isfinite(v) else float(v)


def _rounded(values: np.ndarray, ok: list) -> list:
    """``values`` to 6 decimals, ``None`` where not finite or not ``ok``."""
    return [round(v, 6) if k and math.isfinite(v) else None
            for v, k in zip(values.tolist(), ok)]


@dataclass
class LiveFrame:
    """What :meth:`LiveCalibrator.update` returns for one frame.

    Attributes:
        index: 0-based count of frames fed.
        frame_id: the frame's number (the caller's, else ``index``).
        time: seconds (the caller's, else ``frame_id / fps``).
        mirror: :class:`LiveMirror` after this frame.
        joints3d: ``(J, 3)`` real camera frame (metres with a subject height, else
            mirror distances), NaN where not estimated.
        joints_std: ``(J,)`` each joint's position std in the output's unit (metres with
            a subject height): the RMS length of its 3D error (``sqrt`` of its
            covariance's trace) with the metric scale's share,
            ``hypot(joints_std_shape, |X| scale_rel_std)``; NaN where not estimated.
        joints_std_shape: ``(J,)`` the same without the metric scale's share
            (:attr:`LiveMirror.scale_rel_std`, one factor on every length): the rays,
            the mirror's normal and the data's share of the distance, at the
            calibration's scale (the body's shape and relative positions; equal to
            ``joints_std`` without a subject height).
        paired: a person and their reflection were found in this frame.
        skipped: why the frame was skipped (bad input), else ``None``.
        latency_s: wall seconds of this frame's own work (pairing, triangulation; on
            the updates that solve the window's graph, its solve).
        cpu_s: the thread's CPU seconds of the same (the latency without what other
            processes on the machine took from it).
        solve_s: wall seconds spent in a window's solve during this call (in the
            background mode only the waits of a source that can wait, ``can_wait``);
            the window graph's solve for the settled joints is in ``latency_s``.
        settled: the frame :attr:`LiveOptions.lag_frames` back, given again with its
            joints solved with the frames after it (the window's graph, else the
            fixed-lag smoother; the smoother's stds, widened by the two's distance)
            (``None`` while fewer frames came, or without a lag); its ``lag_frames``
            says how late it is.
        lag_frames: frames between this frame and the frame whose update gave it out
            (0: the frame's own update).
    """

    index: int
    frame_id: int
    time: float
    mirror: LiveMirror
    joints3d: np.ndarray
    joints_std: np.ndarray
    joints_std_shape: np.ndarray | None = None
    paired: bool = False
    skipped: str | None = None
    latency_s: float = 0.0
    solve_s: float = 0.0
    cpu_s: float = 0.0
    settled: "LiveFrame | None" = None
    lag_frames: int = 0

    @property
    def status(self) -> str:
        return self.mirror.status

    def to_dict(self) -> dict:
        """The frame's JSON line: NaN written as ``null`` (JSON has no NaN)."""
        ok = np.isfinite(self.joints3d).all(1).tolist()
        shape = self.joints_std if self.joints_std_shape is None else self.joints_std_shape
        return {"frame": self.index, "frame_id": self.frame_id, "time": round(self.time, 6),
                "status": self.mirror.status, "mirror": self.mirror.to_dict(),
                "joints3d": [[round(c, 6) for c in p] if k else None
                             for p, k in zip(self.joints3d.tolist(), ok)],
                "joints_std": _rounded(self.joints_std, ok),
                "joints_std_shape": _rounded(shape, ok),
                "paired": self.paired, "skipped": self.skipped, "lag_frames": self.lag_frames}


def joints_normal_jacobian(K: np.ndarray, normal: np.ndarray, distance: float,
                           X: np.ndarray, u: np.ndarray, um: np.ndarray, basis: np.ndarray,
                           *, keep_spread: bool = False) -> np.ndarray:
    """The derivative of joints triangulated with a mirror in the normal's tangent
    directions.

    ``X`` is the maximum-likelihood point of its two rays (the camera's ``K [I | 0]``
    and the mirror's ``K [H | 2 d n]``, :func:`mirrorgraph.geometry.triangulate_mirror`);
    by the implicit function theorem at the Gauss-Newton normal equations,
    ``dX / dt_k = -(J_1^T J_1 + J_2^T J_2)^-1 J_2^T Q dY / dt_k`` with ``J_1``, ``J_2``
    the views' ``2 x 3`` Jacobians in ``X``, ``Q`` the mirror view's in the virtual
    point ``Y = X + 2 (d - n . X) n`` and ``dY / dt_k = 2 (d - n . X) b_k - 2 (b_k . X) n``
    for the unit normal moved along ``b_k`` (Hartley and Zisserman, *Multiple View
    Geometry*, 2nd ed., sec. 5.2 for the first-order propagation).

    Args:
        K: ``(3, 3)`` intrinsics, px; normal: ``(3,)`` unit ``n``; distance: ``d``.
        X: ``(N, 3)`` the points (camera frame, unit of ``d``); u, um: ``(N, 2)`` their
            pixels in the camera and in the mirror (undistorted; only ``X`` enters the
            first-order derivative).
        basis: ``(3, 2)`` tangent directions ``b_k`` of the normal
            (:func:`mirrorgraph.geometry.tangent_basis`).
        keep_spread: hold the points' spread ``sum_i |X_i - mean|^2`` (the body's size,
            the scale a subject height sets) instead of the distance: each derivative
            loses its share along ``X``, ``- X sum_i (X_i - mean) . dX_i / spread``.

    Returns:
        ``(N, 3, 2)`` ``dX_i / dt_k``, the unit of ``d`` per radian.
    """
    n = np.asarray(normal, float).reshape(3)
    X = np.asarray(X, float).reshape(-1, 3)
    H = np.eye(3) - 2.0 * np.outer(n, n)
    off = distance - X @ n                                              # (N,)
    Y = X + 2.0 * off[:, None] * n
    N = len(X)
    q = np.concatenate([X, Y]) @ K.T                                    # both views
    p = q[:, :2] / q[:, 2:3]
    Jv = (K[None, :2, :] - p[:, :, None] * K[None, 2:3, :]) / q[:, 2, None, None]
    J1, Q = Jv[:N], Jv[N:]                                              # (N, 2, 3)
    J2 = Q @ H
    A = J1.transpose(0, 2, 1) @ J1 + J2.transpose(0, 2, 1) @ J2
    dY = (2.0 * off[:, None, None] * basis[None]
          - 2.0 * n[None, :, None] * (X @ basis)[:, None, :])          # (N, 3, 2)
    rhs = J2.transpose(0, 2, 1) @ (Q @ dY)                              # (N, 3, 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        dX = -np.linalg.solve(A, rhs)
    if keep_spread and len(X) >= 2:
        c = X - X.mean(0)
        spread = float(np.sum(c * c))
        if spread > 0:
            dX = dX - X[:, :, None] * (np.einsum("ni,nik->k", c, dX) / spread)[None, None]
    return dX


@contextmanager
def _sigint_ignored():
    """SIGINT ignored for a moment (the main thread only; elsewhere nothing changes)."""
    try:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:                    # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _warm_up() -> None:
    """The worker's imports (GTSAM, SciPy's optimiser, the offline run), done while the
    first window's frames arrive."""
    import scipy.optimize  # noqa: F401

    from ..pipelines import mirror  # noqa: F401


def _new_worker():
    """One worker process's pool (spawned, SIGINT ignored), its imports under way.

    A spawned process inherits an ignored SIGINT (and Python then installs no
    KeyboardInterrupt handler in it), so Ctrl-C stops the main process alone: one line,
    no worker traceback; the main process stops the worker (:meth:`LiveCalibrator.close`).
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
    with _sigint_ignored():             # the pool starts its process in submit: no wait
        pool.submit(_warm_up)
    return pool


#: Worker pools started ahead of their calibrator (:func:`start_worker`).
_STARTED: list = []


def start_worker() -> None:
    """Start the background worker (its process and imports: about a second of CPU) ahead
    of its calibrator, for the next :class:`LiveCalibrator` with ``background=True`` to take: a caller that
    reads its input before it can make the calibrator overlaps the two.
    :func:`stop_started_workers` ends any left untaken."""
    _STARTED.append(_new_worker())


def stop_started_workers() -> None:
    """Stop the workers :func:`start_worker` started that no calibrator took, without
    waiting for their imports to end (the interpreter's exit joins them): an error that
    ends the run before its calibrator is made is said at once."""
    while _STARTED:
        _STARTED.pop().shutdown(wait=False, cancel_futures=True)


class LiveCalibrator:
    """A mirror calibrated while the frames arrive, and each frame's 3D joints.

    Args:
        skeleton: the keypoint layout: a :class:`~mirrorgraph.skeletons.Skeleton` or its
            name (``"COCO_17"``, ``"BLAZEPOSE"``, ...).
        intrinsics: :class:`~mirrorgraph.intrinsics.Intrinsics`; ``None``: the focal
            length is estimated from the person (``calibrate.image_size`` needed).
        options: :class:`LiveOptions`.

    Raises:
        InputError: an unknown skeleton, no intrinsics and no image size.
    """

    def __init__(self, skeleton: "Skeleton | str", intrinsics: "Intrinsics | None" = None,
                 options: LiveOptions | None = None):
        from ..intrinsics import intrinsics_from_fov
        from ..joint_sets import mirror_joints
        from ..pipelines.options import CalibrateOptions
        from ..skeletons import skeleton_by_name

        self.options = opts = options or LiveOptions()
        copts = (opts.calibrate or CalibrateOptions()).checked()
        # windows are solved without completion and without their joints' covariance
        # (the frames' joints are triangulated here), their first full solve final (the
        # next window follows it: ``resolve_after_rejection``), and keypoints are
        # undistorted once, here
        self._copts = replace(copts, complete_joints=False, sensitivity_priors=False,
                              fps=copts.fps or opts.fps,
                              refine_options=replace(copts.graph, joints_uncertainty=False,
                                                     resolve_after_rejection=False))
        # the joint filter's acceleration prior at the stream's frame interval (the
        # windows' calibrate takes the graph's at their frame rate itself)
        self._motion = self._copts.graph.at_frame_rate(self._copts.fps)
        self.skeleton = skeleton_by_name(skeleton) if isinstance(skeleton, str) else skeleton
        self.joints = mirror_joints(self.skeleton, copts.joints)
        self._bone_names = list(self.skeleton.bones)
        self._bones = np.array([[self.skeleton.index(a), self.skeleton.index(b)]
                                for a, b in self.skeleton.bones.values()], dtype=np.int64
                               ).reshape(-1, 2)
        self._lengths_of, self._lengths, self._lengths_height = None, None, float("nan")
        self._torso_of, self._torso_for, self._torso = None, None, None
        # each bone's length step between the windows whose lengths the frames held:
        # the sum of its draws of the latest window's relative length variance, their
        # count (:meth:`_note_bone_steps`), and that window's frames
        self._bone_step_sum = np.zeros(len(self._bones))
        self._bone_steps = np.zeros(len(self._bones))
        self._bones_frames = 0
        self.intrinsics = intrinsics
        if intrinsics is None:
            if copts.image_size is None:
                raise InputError("no intrinsics and no image size: give one of them",
                                 fix=("intrinsics", "image_size"))
            self._guess = intrinsics_from_fov(copts.image_size, copts.fov_deg)
            self._window_intr = None
        else:
            self._guess = intrinsics
            self._window_intr = replace(intrinsics, dist=None)     # undistorted here
        self.fusion = MirrorFusion(height_sigma=self._copts.graph.height_sigma,
                                   metric=self._copts.subject_height is not None)
        self._swaps = BodySwapFilter(self.skeleton, copts.min_confidence)
        self._filter: JointFilter | None = None
        # (LiveFrame, its normal and bias shares) awaiting their lag
        self._held: deque = deque()
        # the joints pass's graph over the latest frames (:mod:`.window_graph`), its
        # settled joints by frame number, the settled frames its last solve still covers
        self._graph = (WindowGraph(self.skeleton, self.joints, opts.window_graph_frames)
                       if opts.window_graph_frames > 0 and opts.lag_frames > 0 else None)
        self._graph_joints: dict[int, np.ndarray] = {}
        self._graph_left = 0
        self.graph_solves = 0
        self.graph_failed = 0
        self.graph_seconds = 0.0
        self._last_rays: tuple | None = None   # the latest frame's pixels (both views)
        self._mirror_frames = 0                 # frames of the window the mirror is
        self._frame_normal = np.full(self.skeleton.num_joints, np.nan)
        self._frame_bias = np.zeros(self.skeleton.num_joints)
        # each joint's whitened residual in each view summed over the frames, their count
        self._res_sum = np.zeros((self.skeleton.num_joints, 2, 2))
        self._res_count = np.zeros((self.skeleton.num_joints, 2))
        # the residuals' autocorrelation over time, which widens the filtered joints' std
        self._noise_time = NoiseInTime(self.skeleton.num_joints)
        self._buffer_ids: list[int] = []
        self._buffer_people: list[np.ndarray] = []
        self._future = None
        self._pool = None
        self._last_id: int | None = None
        self.frames = 0
        self._provisional = True                # the first block: re-solved as it grows
        self._next = opts.first_window_frames
        self._job: tuple = ()
        self.skipped: Counter = Counter()
        self.unpaired = 0
        self.with_joints = 0
        self.window_log: list[dict] = []
        self._log_cap = 1000
        self.last_variances: dict = {}
        self._cache: dict = {}                  # what the fused mirror gives every frame
        if opts.background:                     # the worker's start off the first window
            self._executor()

    # ------------------------------------------------------------------ state
    def _cached(self, name: str, make):
        """A figure of the fused mirror, computed once between two windows."""
        if name not in self._cache:
            self._cache[name] = make()
        return self._cache[name]

    def _body_height(self) -> float:
        """The body height the latest window's bone lengths make (the priors' unit, the
        fused mirror's length unit; NaN without them), computed once between two windows."""
        from ..anthropometry import height_from_bone_lengths

        return self._cached("height", lambda: height_from_bone_lengths(
            self.fusion.bone_lengths or {}, self.skeleton))

    @property
    def K(self) -> np.ndarray:
        """The current camera matrix (the fused focal length where it is estimated)."""
        return self._cached("K", self._camera_matrix)

    def _camera_matrix(self) -> np.ndarray:
        K = np.array(self._guess.K, dtype=float)
        f = self.fusion.focal_px
        if self.intrinsics is None and f is not None:
            K[0, 0] = K[1, 1] = f
        return K

    @property
    def mirror(self) -> LiveMirror:
        """The current mirror (:class:`LiveMirror`, a snapshot)."""
        return copy.copy(self._cached("mirror", self._snapshot))

    def _snapshot(self) -> LiveMirror:
        fu = self.fusion
        if fu.normal is None:
            return LiveMirror(failed=fu.failed)
        std = fu.rotation_std_deg
        # a mirror the reflection check doubts is no calibration, however small its std
        # (two people in view and no mirror: their "mirror" fits at a std of 1.2 deg)
        calibrated = std <= self.options.calibrated_std_deg and not fu.doubt
        status = "calibrated" if calibrated else "initialising"
        metric = self._copts.subject_height is not None
        return LiveMirror(status=status, normal=fu.normal.copy(), distance=fu.distance,
                          rotation_std_deg=std,
                          distance_std=fu.distance_std if metric else None,
                          scale_rel_std=fu.scale_rel_std if metric else None,
                          focal_px=fu.focal_px, focal_std_px=fu.focal_std_px,
                          windows=fu.windows, rejected=fu.rejected, failed=fu.failed,
                          resets=fu.resets,
                          scale="subject_height" if metric else "unit_distance",
                          doubt=fu.doubt or None)

    @property
    def counts(self) -> dict:
        """Frames fed, skipped (by reason), without a pair, with joints; window counts;
        the window graph's solves and its failed ones (:mod:`.window_graph`)."""
        return {"frames": self.frames, "skipped": sum(self.skipped.values()),
                "skipped_by_reason": dict(self.skipped), "unpaired": self.unpaired,
                "with_joints": self.with_joints, "windows": self.fusion.windows,
                "windows_rejected": self.fusion.rejected,
                "windows_failed": self.fusion.failed, "resets": self.fusion.resets,
                "buffered": len(self._buffer_ids), "graph_solves": self.graph_solves,
                "graph_failed": self.graph_failed}

    # ------------------------------------------------------------------ input
    def _checked(self, people) -> tuple[np.ndarray | None, tuple[str, str] | None]:
        """The frame as ``(P, J, 3)`` floats, or ``(reason, message)`` why not."""
        J = self.skeleton.num_joints
        try:
            p = np.array(people, dtype=float)
        except (TypeError, ValueError):
            return None, ("not numeric", "the people are not a numeric array")
        if p.ndim == 2:
            p = p[None]
        if p.ndim != 3 or p.shape[-1] != 3:
            return None, ("bad shape", f"shape {p.shape} is not (people, {J}, 3)")
        if p.shape[1] != J:
            return None, ("wrong joint count", f"{p.shape[1]} joints, the skeleton "
                          f"{self.skeleton.name} has {J}")
        conf = p[..., 2]
        bad = ~np.isfinite(conf) | (conf <= 0) | ~np.isfinite(p[..., :2]).all(-1)
        if np.any(np.abs(p[..., :2][~bad]) > 1e6):
            return None, ("coordinates out of range", "coordinates beyond 1e6 px")
        p[..., 2] = np.clip(np.where(np.isfinite(conf), conf, 0.0), 0.0, 1.0)
        p[bad] = (np.nan, np.nan, 0.0)
        return p, None

    def update(self, people: "np.ndarray | list", frame_id: int | None = None,
               time_s: float | None = None) -> LiveFrame:
        """Feed one frame's detections; returns that frame's 3D joints and the mirror.

        Args:
            people: ``(P, J, 3)`` every person the detector found (x px, y px,
                confidence; NaN / 0 where missing), in any order; ``(J, 3)`` for one.
            frame_id: the frame's number (increasing); default: the count of frames fed.
            time_s: the frame's time, seconds; default ``frame_id / fps``.

        Returns:
            :class:`LiveFrame`. A frame that cannot be used (a wrong shape, a frame
            number not after the last one) is skipped with its reason, counted in
            :attr:`counts`.
        """
        clock, cpu = time.perf_counter(), time.thread_time()
        index = self.frames
        self.frames += 1
        fid = index if frame_id is None else int(frame_id)
        t = fid / self.options.fps if time_s is None else float(time_s)
        J = self.skeleton.num_joints
        nan = np.full((J, 3), np.nan)
        solve_s = self._poll()
        self._frame_normal = np.full(J, np.nan)
        self._frame_bias = np.zeros(J)
        p, reason = self._checked(people)
        if reason is None and self._last_id is not None and fid <= self._last_id:
            reason = ("frame number not increasing",
                      f"frame number {fid} not after {self._last_id}")
        if reason is not None:
            self.skipped[reason[0]] += 1
            frame = LiveFrame(index, fid, t, self.mirror, nan, np.full(J, np.nan),
                              np.full(J, np.nan), skipped=f"frame {fid}: {reason[1]}",
                              solve_s=solve_s)
            frame.settled = self._settle(frame)
            frame.latency_s, frame.cpu_s = (time.perf_counter() - clock,
                                            time.thread_time() - cpu)
            return frame
        self._last_id = fid
        if self.intrinsics is not None and self.intrinsics.dist is not None and len(p):
            p[..., :2] = self.intrinsics.undistort_points(p[..., :2])
        joints3d, total, shape, paired = nan, np.full(J, np.nan), np.full(J, np.nan), False
        if self.fusion.normal is not None and len(p) >= 2:
            joints3d, total, shape, paired = self._joints(fid, p)
        if len(p) >= 2:
            self._buffer_ids.append(fid)
            self._buffer_people.append(p)
        if not paired:
            self.unpaired += 1
        if np.isfinite(joints3d).any():
            self.with_joints += 1
        frame = LiveFrame(index, fid, t, None, joints3d, total, shape, paired=paired)
        frame.settled = self._settle(frame)
        frame.latency_s, frame.cpu_s = time.perf_counter() - clock, time.thread_time() - cpu
        frame.solve_s = solve_s + self._schedule()
        frame.mirror = self.mirror                  # a window this frame completed counts
        return frame

    # ------------------------------------------------------------------ per frame
    def _joints(self, fid: int, p: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """The frame's ``(J, 3)`` joints, their stds with and without the metric scale's
        share (``joints_std``, ``joints_std_shape``) and whether a pair was found."""
        from ..initial.pairing import pair_frame_with_epipole

        J = self.skeleton.num_joints
        out, total, shape = np.full((J, 3), np.nan), np.full(J, np.nan), np.full(J, np.nan)
        K = self.K
        n, d = self.fusion.normal, float(self.fusion.distance)
        co = self._copts
        epipole, pairing = self._cached("pairing", self._pairing)
        real, mirror = pair_frame_with_epipole(p, epipole, self.skeleton, self.joints, pairing)
        # the person's left and right as the frames so far say (the detector's
        # confusions in either view, :mod:`mirrorgraph.initial.body_left_right`)
        real, mirror = self._swaps.update(real, mirror, fid)
        seen = ((real[:, 2] >= co.min_confidence) & (mirror[:, 2] >= co.min_confidence)
                & np.isfinite(real[:, :2]).all(1) & np.isfinite(mirror[:, :2]).all(1))
        idx = np.flatnonzero(seen)
        X = triangulate_two_rays(K, n, d, real[idx, :2], mirror[idx, :2])
        good = np.isfinite(X).all(1)
        idx, X = idx[good], X[good]
        if idx.size == 0:
            if self.options.smooth:
                self._filtered(fid, idx, X, np.zeros((0, 3, 3)))
            return out, total, shape, bool(seen.any())
        u, um = real[idx, :2], mirror[idx, :2]
        self._last_rays = (u, um)
        lengths = self._frame_lengths() if self.options.bone_prior else None
        pairs, L, sigma_len = lengths if lengths is not None else (
            self._bones, np.full(len(self._bones), np.nan), np.ones(len(self._bones)))
        # the frame's joints together: both views' reprojection (Huber), the bones'
        # lengths; the worst view off by more than the calibration's inlier threshold
        # once the bones hold the joint (a keypoint displaced along its epipolar line)
        # is left out, the joints pass's rule (at the graph's outlier threshold, twice
        # it, this path's two steps measured no better: PA-MPJPE over the offline run's
        # on the paper protocol 1.08 against 1.04-1.07, the independent generator's
        # 1.07-1.09 against 1.05-1.07)
        gate = co.threshold_px
        # the frame refined again from where the tracks predict it: at small parallax
        # the bones hold a limb on either side of its neighbours along the ray, and the
        # start picks the side; the two folded by the frame's cost at each joint
        starts = [X]
        views = None
        if lengths is not None and self.options.smooth and self._filter is not None:
            Xp, Pp = self._filter.predict(fid)
            Xp, Pp = Xp[idx], Pp[idx]
            have = np.isfinite(Xp).all(1)
            if have.any():
                starts.append(np.where(have[:, None], Xp, X))
                views = views_near_track(K, n, d, Xp, Pp, u, um, self._sigma_px())
        Xs, Cs, keeps, pxs = refine_starts(K, n, d, np.stack(starts), u, um, idx, pairs, L,
                                           self._sigma_px(), sigma_len, iterations=2,
                                           gate_px=gate, views=views)
        X, cov, keep, px = Xs[0], Cs[0], keeps[0], pxs[0]
        if len(starts) > 1:
            X, cov = two_starts(K, n, d, X, cov, Xs[1], Cs[1], u, um, keep, keeps[1], idx,
                                pairs, L, self._sigma_px(), sigma_len, pxA=px, pxB=pxs[1])
        if lengths is not None:
            # a joint the two rays barely place: its bones' other branch along the ray
            X, cov = bone_branches(K, n, d, X, cov, u, um, keep, idx, pairs, L,
                                   self._sigma_px(), sigma_len)
        S = geo.reflect_points(X, n, d)
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(X).all(1) & (X[:, 2] > 0) & (X @ n < d) & (S[:, 2] > 0)
            ok &= (~keep | (px <= gate)).all(1)
            ok &= np.isfinite(cov).all((1, 2))
        bias = self._bias(K, n, d, X[ok], u[ok], um[ok], idx[ok], keep[ok])
        self._noise_time.record(fid, idx[ok], K, n, d, X[ok], u[ok], um[ok], keep[ok], cov[ok])
        idx, X, cov = idx[ok], X[ok], cov[ok]
        widen = np.ones(len(idx))
        if self.options.smooth:
            X, cov = self._filtered(fid, idx, X, cov)
            widen = self._noise_time.factor(fid, idx, cov, 0)
        if self._graph is not None and idx.size:
            views = np.zeros((J, 2), bool)
            views[idx] = keep[ok]
            start = np.full((J, 3), np.nan)
            start[idx] = X
            self._graph.push(fid, real, mirror, views, start)
        if idx.size == 0:
            return out, total, shape, True
        track = (None if self._filter is None or not self.options.smooth
                 else (self._filter.x[:, :3], self._filter.P[:, :3, :3]))
        X, cov = self._head(idx, X, cov, track)
        out[idx] = X
        shape[idx], total[idx] = self._stds(K, n, d, X, cov * widen[:, None, None] + bias)
        self._frame_bias[idx] = np.trace(bias, axis1=1, axis2=2)
        if "normal" in self.last_variances:
            self._frame_normal[idx] = self.last_variances["normal"]
        return out, total, shape, True

    def _bias(self, K, n, d, X, u, um, idx, keep) -> np.ndarray:
        """``(k, 3, 3)`` the detector's bias share of the joints ``X`` (skeleton indices
        ``idx``, views ``keep`` ``(k, 2)``): each joint's residual in each view it keeps,
        whitened, added to its running mean over the frames so far, and
        :func:`.frame_prior.bias_covariance` of the means (0 where NaN)."""
        r, J = view_residuals(K, n, d, X, u, um)
        s = self._sigma_px()
        kept = keep & np.isfinite(r).all(2)
        total = self._res_sum[idx] + np.where(kept[:, :, None], r / s, 0.0)   # idx unique
        count = self._res_count[idx] + kept
        self._res_sum[idx], self._res_count[idx] = total, count
        mean = total / np.maximum(count, 1)[:, :, None]
        C = bias_covariance(J, mean, s)
        return np.where(np.isfinite(C).all((1, 2))[:, None, None], C, 0.0)

    def _stds(self, K, n, d, X, cov) -> tuple[np.ndarray, np.ndarray]:
        """``(k,)`` each joint's std without and with the metric scale's share."""
        var = self._variances(K, n, d, X, None, None, cov)
        self.last_variances = var
        return (np.sqrt(sum(v for k, v in var.items() if k != "scale")),
                np.sqrt(sum(var.values())))

    def _pairing(self) -> tuple:
        """The fused mirror's epipole ``K n`` and the pairing's options."""
        from ..initial.pairing import PairingOptions

        co = self._copts
        return self.K @ self.fusion.normal, PairingOptions(min_confidence=co.min_confidence,
                                                           threshold_px=co.threshold_px)

    def _sigma_px(self) -> float:
        fu = self.fusion
        return fu.noise_px if np.isfinite(fu.noise_px) else self._copts.graph.pixel_sigma

    def _frame_lengths(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """``(pairs, lengths, sigma)``: the distances each frame's joints are held at,
        those the offline joints pass holds (:func:`mirrorgraph.graph.stages.joints_pass`):
        every bone (:meth:`_bone_lengths`) and, where the latest window's pass held the
        torso (``RefineOptions.torso_sigma``), the torso's distances no bone holds
        (:attr:`.estimator.WindowEstimate.torso_lengths`) at ``torso_sigma`` of the
        height; ``(P, 2)`` skeleton joint indices, ``(P,)``, ``(P,)``. ``None`` without
        a window's lengths."""
        bones = self._bone_lengths()
        if bones is None:
            return None
        torso = self.fusion.torso_lengths
        g = self._copts.graph
        if not torso or g.torso_sigma is None or not g.use_bone_length:
            return (self._bones, *bones)
        if self._torso_of is not torso or self._torso_for is not bones:
            sk = self.skeleton
            pairs = np.array([[sk.index(j) for j in name.split("-")] for name in torso],
                             np.int64).reshape(-1, 2)
            L = np.fromiter(torso.values(), float, len(torso))
            sigma = np.full(len(torso), float(g.torso_sigma) * self._lengths_height)
            self._torso = (np.concatenate([self._bones, pairs]),
                           np.concatenate([bones[0], L]), np.concatenate([bones[1], sigma]))
            self._torso_of, self._torso_for = torso, bones
        return self._torso

    def _bone_lengths(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(lengths, sigma)``: the latest window's length of each bone of
        ``self._bones`` (a bone it lacks at its left/right partner's, as the joints pass
        holds it: :func:`mirrorgraph.graph.priors.other_side_lengths`; NaN where neither
        has one) and each one's ``(B,)`` spread about it: the graph's ``bone_sigma`` of
        the height they make (Winter's fractions) and the window's own length error, the
        RMS of the bone's steps between windows (:meth:`_note_bone_steps`; none before
        the second window), in quadrature; ``None`` without a window's lengths."""
        found = self.fusion.bone_lengths
        if not found:
            return None
        if self._lengths_of is not found:
            from ..anthropometry import height_fractions
            from ..graph.priors import other_side_lengths

            held = other_side_lengths(self.skeleton, found)[0]
            L = np.array([held.get(b, np.nan) for b in self._bone_names], float)
            frac = height_fractions(self.skeleton)
            f = np.array([frac.get(b, np.nan) for b in self._bone_names], float)
            both = np.isfinite(L) & np.isfinite(f)
            h = float(L[both].sum() / f[both].sum()) if both.any() else float("nan")
            sigma = self._copts.graph.priors.bone_sigma * h
            own = np.sqrt(self._bone_step_sum / np.maximum(self._bone_steps, 1.0)) * L
            spread = np.hypot(sigma, np.nan_to_num(own))
            self._lengths = (L, spread) if np.isfinite(sigma) and sigma > 0 else None
            self._lengths_of, self._lengths_height = found, h
        return self._lengths

    def _ray_covariance(self, K, n, d, X) -> np.ndarray:
        """``(k, 3, 3)`` the joints ``X`` triangulated from their two rays: the rays'
        covariance at the windows' reprojection noise."""
        eye = np.eye(4)
        views = [geo.camera_projection(K, eye), geo.mirror_projection(K, eye, n, d)]
        ones = np.ones(len(X), bool)
        return geo.triangulation_covariance(views, X, [ones, ones], self._sigma_px())

    def _filtered(self, fid: int, idx: np.ndarray, X: np.ndarray, cov: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """The frame's joints ``X`` ``(k, 3)`` (skeleton indices ``idx``) and their
        covariance filtered with the frames before (:class:`.joint_filter.JointFilter`
        at the joints pass's acceleration prior at the stream's frame rate, a fraction of
        the body's height the windows' bone lengths make, per frame^2 of the stream);
        as given before the first window's bone lengths."""
        h = self._body_height()
        if not np.isfinite(h):
            return X, cov
        g = self._motion
        sigma = float(g.joints_smoothness_sigma * h)
        if self._filter is None:
            self._filter = JointFilter(self.skeleton.num_joints, sigma,
                                       int(g.smoothness_max_gap),
                                       lag=max(int(self.options.lag_frames), 0))
        self._filter.sigma = sigma
        Xf, C, _ = self._filter.step(fid, idx, X, cov)
        return Xf, C

    def _head(self, idx: np.ndarray, X: np.ndarray, cov: np.ndarray, track=None
              ) -> tuple[np.ndarray, np.ndarray]:
        """The face keypoints among the joints ``X`` ``(k, 3)`` (skeleton indices ``idx``)
        fused with where the trunk puts them (:func:`.frame_prior.with_head_prior`, at the
        height the windows' bone lengths make). ``track``: ``((J, 3), (J, 3, 3))`` every
        joint's filtered (or smoothed) point and covariance at the frame, whose trunk
        joints stand in for those the frame does not give (a hip the detector missed
        leaves the face its prior)."""
        h = self._body_height()
        names = self.skeleton.joints
        layout = head_layout(names)
        if track is not None and layout is not None:
            trunk = layout[1]
            given = np.zeros(len(names), bool)
            given[idx] = True
            miss = trunk[~given[trunk]]
            if miss.size and idx.size:
                xs, Ps = track[0][miss], track[1][miss]
                if np.isfinite(xs).all() and np.isfinite(Ps).all():
                    k = len(idx)
                    Xa, Ca = with_head_prior(np.concatenate([X, xs]), np.concatenate([cov, Ps]),
                                             np.concatenate([idx, miss]), names, h)
                    return Xa[:k], Ca[:k]
        return with_head_prior(X, cov, idx, names, h)

    def _settle(self, frame: LiveFrame) -> LiveFrame | None:
        """Hold ``frame``; give back the one :attr:`LiveOptions.lag_frames` back with its
        joints smoothed by the frames after it (``None`` while fewer are held)."""
        lag = int(self.options.lag_frames)
        if lag <= 0:
            return None
        self._held.append((frame, self._frame_normal.copy(), self._frame_bias.copy()))
        if len(self._held) <= lag:
            return None
        if self._graph is not None:
            if self._graph_left <= 0:
                # frames t - lag .. t - lag + k - 1 from the window ending at t
                self._graph_left = max(1, min(int(self.options.window_graph_every), lag + 1))
                self._solve_graph(self._graph_left)
            self._graph_left -= 1
        return self._smoothed_frame(*self._held.popleft(), lag)

    def _solve_graph(self, count: int) -> None:
        """Solve the window's graph (:class:`.window_graph.WindowGraph`) at the current
        mirror and keep its joints of the ``count`` oldest frames held (their settled
        joints); nothing before the first window's bone lengths or where it fails."""
        from ..errors import MirrorgraphError

        self._graph_joints.clear()
        fu = self.fusion
        if fu.normal is None or not fu.bone_lengths or len(self._graph) < 3:
            return
        h = self._body_height()
        g = self._motion
        kernel = g.final_kernel
        if kernel == "auto":
            # the window's pixels are gated per frame, not cleaned as a calibration's:
            # the robust branch of "auto"
            kernel = "geman_mcclure"
        clock = time.perf_counter()
        try:
            sol = self._graph.solve(self.K, fu.normal, float(fu.distance), fu.bone_lengths,
                                    fu.torso_lengths, h, g, kernel=kernel)
        except (MirrorgraphError, RuntimeError, ValueError, np.linalg.LinAlgError):
            sol = None                         # GTSAM's indeterminant system among them
            self.graph_failed += 1
        self.graph_seconds += time.perf_counter() - clock
        if sol is None:
            return
        self.graph_solves += 1
        row = {int(f): i for i, f in enumerate(sol.frame_ids)}
        for k, (fr, _, _) in enumerate(self._held):
            if k >= count:
                break
            i = row.get(int(fr.frame_id))
            if i is not None and fr.skipped is None:
                self._graph_joints[int(fr.frame_id)] = sol.joints[i]

    def _smoothed_frame(self, old: LiveFrame, normal: np.ndarray, bias: np.ndarray,
                        lag: int) -> LiveFrame:
        """``old`` settled: :meth:`_smoother_frame`, and where the window's graph solved
        a joint it gives (:meth:`_solve_graph`) the graph's point, its std the smoother's
        with the two points' distance added in quadrature (``bench/RESULTS_live_graph.md``:
        err / std)."""
        out = self._smoother_frame(old, normal, bias, lag)
        G = self._graph_joints.pop(old.frame_id, None) if self._graph is not None else None
        if G is not None:
            # the graph's joints where it solved one the smoother gives; their std the
            # smoother's and the two points' distance in quadrature: its error is within
            # the smoother's error plus that distance, and where the two disagree (a limb
            # on the other crossing of its bone with its ray) the smoother's std alone
            # left the graph's error at 3.0 stds at the 99th percentile of the worst of
            # 72 scenes (bench/RESULTS_live_graph.md)
            take = np.isfinite(G).all(1) & np.isfinite(out.joints3d).all(1)
            if take.any():
                gap2 = np.sum((G[take] - out.joints3d[take]) ** 2, axis=1)
                out.joints3d = out.joints3d.copy()
                out.joints3d[take] = G[take]
                out.joints_std, out.joints_std_shape = (out.joints_std.copy(),
                                                        out.joints_std_shape.copy())
                out.joints_std[take] = np.sqrt(out.joints_std[take] ** 2 + gap2)
                out.joints_std_shape[take] = np.sqrt(out.joints_std_shape[take] ** 2 + gap2)
        return out

    def _smoother_frame(self, old: LiveFrame, normal: np.ndarray, bias: np.ndarray,
                        lag: int) -> LiveFrame:
        """``old`` with the fixed-lag smoother's joints and stds where it gave joints of
        its own; ``normal`` ``(J,)`` the fused normal's share of each joint's variance at
        the frame's filtered point (first order: the smoothed point is millimetres away),
        NaN where none; ``bias`` ``(J,)`` the detector's bias share (:meth:`_bias`'s
        trace), which the smoother does not average."""
        out = copy.copy(old)
        out.settled, out.lag_frames = None, lag
        sm = (self._filter.smoothed(old.frame_id)
              if self._filter is not None and old.skipped is None else None)
        if sm is None or self.fusion.normal is None:
            return out
        have = np.isfinite(old.joints3d).all(1) & np.isfinite(sm[0]).all(1) \
            & np.isfinite(sm[1]).all((1, 2))
        if not have.any():
            return out
        X, cov = self._head(np.flatnonzero(have), sm[0][have], sm[1][have], sm)
        cov = cov * self._noise_time.factor(old.frame_id, np.flatnonzero(have), sm[1][have],
                                            lag)[:, None, None]
        if np.isfinite(normal[have]).all():
            var = (np.maximum(np.trace(cov, axis1=1, axis2=2), 0.0) + normal[have]
                   + bias[have])
            scale = ((np.linalg.norm(X, axis=1) * self._scale_rel_std()) ** 2
                     if self._copts.subject_height is not None else 0.0)
            shape, total = np.sqrt(var), np.sqrt(var + scale)
        else:
            shape, total = self._stds(self.K, self.fusion.normal,
                                      float(self.fusion.distance), X,
                                      cov + bias[have, None, None] / 3.0 * np.eye(3))
        out.joints3d, out.joints_std, out.joints_std_shape = (
            old.joints3d.copy(), old.joints_std.copy(), old.joints_std_shape.copy())
        out.joints3d[have], out.joints_std[have], out.joints_std_shape[have] = X, total, shape
        return out

    def flush(self) -> list[LiveFrame]:
        """The frames still held for their lag at the end of a stream, each smoothed
        with the frames after it (after :meth:`finish`): with the window's graph, one
        last window solved over them (in the calling thread)."""
        lag = int(self.options.lag_frames)
        if self._graph is not None and self._held:
            self._solve_graph(len(self._held))
        held = list(self._held)
        self._held.clear()
        out = [self._smoothed_frame(fr, normal, bias, lag) for fr, normal, bias in held]
        self._graph_joints.clear()
        self._graph_left = 0
        return out

    def _variances(self, K, n, d, X, u, um, cov=None) -> dict:
        """The shares of each joint's variance (the trace of its covariance, length
        unit squared) of the joints ``X`` triangulated from their rays ``u``, ``um``:
        ``pixels`` (the two rays at the windows' reprojection noise, or ``cov`` where the
        frame's joints were refined with the bones' lengths),
        ``normal`` (the fused normal's covariance through the triangulation, at what
        the windows' gauge holds fixed: the body's size with a subject height, else
        the distance) and ``scale`` (the metric scale's prior, kept apart: see the
        module docstring)."""
        if cov is None:
            cov = self._ray_covariance(K, n, d, X)
        var = {"pixels": np.maximum(np.trace(cov, axis1=1, axis2=2), 0.0)}
        B, C = self._cached("normal_tangent", self._normal_tangent)
        metric = self._copts.subject_height is not None
        if np.all(np.isfinite(C)):
            # with a subject height every window's scale is the subject's stature
            # measured on its joints, so a tilted normal changes the distance with it
            # and the body keeps its size: the spread is held (the distance's own std is
            # that same error seen through the body: not added again); without one the
            # distance is the unit and is held
            J = joints_normal_jacobian(K, n, d, X, u, um, B, keep_spread=metric)  # (N, 3, 2)
            var["normal"] = np.maximum(((J @ C) * J).sum((1, 2)), 0.0)
        if metric:
            var["scale"] = (np.linalg.norm(X, axis=1) * self._scale_rel_std()) ** 2
        return var

    def _scale_rel_std(self) -> float:
        """The fused mirror's metric scale relative std (computed once between windows)."""
        return self._cached("scale_rel_std", lambda: self.fusion.scale_rel_std)

    # ------------------------------------------------------------------ windows
    def _window(self, clear: bool) -> RawDetections:
        raw = RawDetections(self.skeleton, np.asarray(self._buffer_ids, dtype=np.int64),
                            list(self._buffer_people), source=f"live window "
                            f"{self._buffer_ids[0]}-{self._buffer_ids[-1]}",
                            format="live", image_size=self._copts.image_size,
                            fps=self._copts.fps)
        if clear:
            self._buffer_ids, self._buffer_people = [], []
        return raw

    def _schedule(self) -> float:
        """Start a window's solve when one is due (see the module docstring)."""
        n = len(self._buffer_ids)
        busy = self._future is not None
        if busy:
            due = n >= self._next_after_job()
            if self.options.can_wait and due:      # a file: wait, never thin
                waited = self._poll(wait=True)
                return waited + self._schedule()
            if n > max(self.options.max_buffer_frames, self.options.window_frames):
                keep = slice(None, None, 2)                # thin evenly: memory flat
                self._buffer_ids = self._buffer_ids[keep]
                self._buffer_people = self._buffer_people[keep]
            return 0.0
        if self._provisional:
            if n < self._next:
                return 0.0
            block = n >= self.options.window_frames
            job = (self._window(clear=block), True, block)
        else:
            if n < self.options.window_frames:
                return 0.0
            job = (self._window(clear=True), False, False)
        if self.options.background:
            self._future = self._executor().submit(solve_window, job[0], self._window_intr,
                                                   self._copts)
            self._job = job[1:] + (len(job[0].people),)
            if self.options.can_wait and self.fusion.normal is None:
                return self._poll(wait=True)
            return 0.0
        clock = time.perf_counter()
        est = solve_window(job[0], self._window_intr, self._copts)
        self._absorb(est, *job[1:], len(job[0].people))
        return time.perf_counter() - clock

    def _next_after_job(self) -> int:
        """The buffered frames at which the window after the one in flight is due: the
        threshold the window in flight sets once absorbed (:meth:`_absorb`), its solve
        taken to succeed."""
        provisional, block, size = self._job
        if provisional and not block:
            return min(max(self.options.first_window_frames, 2 * size),
                       self.options.window_frames)
        return self.options.window_frames

    def _executor(self):
        """The background worker's pool: one :func:`start_worker` started, else a new one
        (its process starts here)."""
        if self._pool is None:
            self._pool = _STARTED.pop() if _STARTED else _new_worker()
        return self._pool

    def _poll(self, wait: bool = False) -> float:
        if self._future is None or not (wait or self._future.done()):
            return 0.0
        clock = time.perf_counter()
        try:
            est = self._future.result()
        except Exception as exc:  # noqa: BLE001 - a worker's crash is a failed window
            est = WindowEstimate(ok=False, reason=f"worker: {type(exc).__name__}: {exc}")
        self._future = None
        self._absorb(est, *self._job)
        return time.perf_counter() - clock if wait else 0.0

    def _normal_tangent(self) -> tuple[np.ndarray, np.ndarray]:
        """The fused normal's ``(3, 2)`` tangent basis and its ``(2, 2)`` covariance there."""
        B = geo.tangent_basis(self.fusion.normal)
        return B, B.T @ self.fusion.normal_cov @ B

    def _absorb(self, est: WindowEstimate, provisional: bool, block: bool, size: int) -> None:
        before = (None if self.fusion.normal is None else
                  (self.K, self.fusion.normal.copy(), float(self.fusion.distance)))
        bones_before = self.fusion.bone_lengths
        self._cache.clear()
        if provisional:
            # the calibration of every frame so far replaces the one of fewer frames
            what = self.fusion.restart(est)
            self._next = min(max(self.options.first_window_frames, 2 * size),
                             self.options.window_frames)
            if block:          # the first block is done: from now on windows are fused
                self._provisional = self.fusion.normal is None
                self._next = self.options.first_window_frames
        else:
            what = self.fusion.add(est)
        ratio = self._scale_ratio(before)
        if np.isfinite(ratio):
            # the tracks (and the frames awaiting their lag) at the new mirror's scale
            if self._filter is not None:
                self._filter.scale(ratio)
            if self._graph is not None:           # the window's starts and its joints
                self._graph.scale(ratio)
                for G in self._graph_joints.values():
                    G *= ratio
            if provisional and what == "started":
                self.fusion.note_restart_step(math.log(ratio), self._mirror_frames, size)
        if what in ("started", "reset"):
            self._mirror_frames = size
        if what == "reset" and self._graph is not None:
            self._graph.clear()                   # a cut: the frames before are another rig
        if self.fusion.bone_lengths is not bones_before:
            self._note_bone_steps(bones_before if what != "reset" else {},
                                  provisional and what == "started", size)
        if len(self.window_log) < self._log_cap:
            self.window_log.append({"frames": [est.first_frame, est.last_frame],
                                    "size": size, "result": what, "reason": est.reason,
                                    "rotation_std_deg": est.rotation_std_deg,
                                    "seconds": est.seconds, "pairs": est.pairs})

    def _note_bone_steps(self, old: dict, nested: bool, frames: int) -> None:
        """Record how far the new window's bone lengths moved from ``old`` (the lengths
        the frames held), one draw a bone of the new window's relative length variance.

        With each window's length errors independent draws of a variance falling as
        ``1 / frames`` (that of the length measured on its frames), the log step
        ``s`` from a window of ``m`` frames to one of ``n`` is a draw of variance
        ``v_n (n - m) / m`` where the new window holds the old one (the first block's
        re-solves, :meth:`.estimator.MirrorFusion.note_restart_step`'s reasoning) and
        ``v_n (1 + n / m)`` where the two are disjoint (later blocks): ``s^2 m / (n - m)``
        and ``s^2 m / (m + n)`` are draws of ``v_n``. A reset (a cut) starts over."""
        m, n = int(self._bones_frames), int(frames)
        self._bones_frames = n
        if not old or m <= 0 or (nested and n <= m):
            self._bone_step_sum[:] = 0.0
            self._bone_steps[:] = 0.0
            return
        new = self.fusion.bone_lengths
        a = np.array([old.get(b, np.nan) for b in self._bone_names], float)
        c = np.array([new.get(b, np.nan) for b in self._bone_names], float)
        with np.errstate(invalid="ignore", divide="ignore"):
            step = np.log(c / a)
        ok = np.isfinite(step)
        w = m / (n - m) if nested else m / (m + n)
        self._bone_step_sum[ok] += step[ok] ** 2 * w
        self._bone_steps[ok] += 1.0

    def _scale_ratio(self, before: tuple | None) -> float:
        """The joints' size at the current mirror over their size at ``before`` ``(K,
        normal, distance)``: the latest frame's pixels triangulated with both (two rays
        a joint, :func:`.frame_prior.triangulate_two_rays`), the median over the joints of
        their distances from the camera's ratio; NaN without both mirrors or that frame, ``1``
        where the mirror is unchanged. A new window moves the joints' scale by this
        whatever made it (its distance, its normal, the focal length)."""
        fu = self.fusion
        if before is None or fu.normal is None or self._last_rays is None:
            return float("nan")
        K0, n0, d0 = before
        K1, n1, d1 = self.K, fu.normal, float(fu.distance)
        if d1 == d0 and np.array_equal(n1, n0) and np.array_equal(K1, K0):
            return 1.0
        u, um = self._last_rays
        X0 = triangulate_two_rays(K0, n0, d0, u, um)
        X1 = triangulate_two_rays(K1, n1, d1, u, um)
        with np.errstate(invalid="ignore"):
            ok = (np.isfinite(X0).all(1) & np.isfinite(X1).all(1) & (X0[:, 2] > 0)
                  & (X1[:, 2] > 0))
        if not ok.any():
            return float("nan")
        return float(np.median(np.linalg.norm(X1[ok], axis=1) / np.linalg.norm(X0[ok], axis=1)))

    def finish(self) -> LiveMirror:
        """End of the stream: wait for a window in flight, solve what is buffered (the
        whole buffer while the first block is still provisional, else if it holds at
        least half a window), and return the final mirror."""
        self._poll(wait=True)
        n = len(self._buffer_ids)
        if n >= 2 and (self._provisional or n >= self.options.window_frames // 2):
            job = (self._window(clear=True), self._provisional, self._provisional)
            self._absorb(solve_window(job[0], self._window_intr, self._copts), *job[1:],
                         len(job[0].people))
        return self.mirror

    def close(self) -> None:
        """Stop the worker process (if any): joined where no window is in flight (a pool
        left to the interpreter's exit can fail there on its closed pipe), else left to
        end its solve."""
        if self._pool is not None:
            self._pool.shutdown(wait=self._future is None, cancel_futures=True)
            self._pool = None
            self._future = None

    def __enter__(self) -> "LiveCalibrator":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
