"""The mirror of a live run: windows of frames solved by the offline run, fused.

A window (the next frames holding two people or more) is calibrated by the run
``calibrate`` makes (:func:`mirrorgraph.pipelines.mirror.calibrate`); :func:`solve_window`
returns what the fusion needs of it (:class:`WindowEstimate`).

:class:`MirrorFusion` carries the older windows as a Gaussian on the mirror: the frames
are independent given the mirror, so marginalising a window's joints leaves its
information on the plane, and the information of disjoint windows adds (a fixed-lag
smoother whose lag is one window). A detector's bias that every window shares does not
average out, so the normal's covariance has two parts:

* **independent**: the windows' normals weighted by their marginal information (as one
  graph over every frame weighs them), with the sandwich covariance of that weighted mean,
  each window's ``max(marginal_w, time_w)`` in it (it shrinks like 1 / windows);
* **shared**: the mean over windows of ``headline_w - max(marginal_w, time_w)`` (its PSD
  part; it does not shrink), ``headline_w`` the window's robust figure
  (:func:`mirrorgraph.graph.uncertainty.robust_normal_cov`).

The focal length, where estimated, is fused by its windows' information. The **distance**
is the frame-weighted median of the windows' distances (with a subject height each is the
one at which the stature measured on the window's joints is the height); its data std is
the larger of the windows' own, combined, and their spread (from the median absolute
deviation, from three windows on); the subject's height is a shared relative part. The
metric scale's relative std (:attr:`MirrorFusion.scale_rel_std`) holds the height's prior,
the latest window's measured stature spread (a detector's distortion: more frames do not
average it out) and the windows' statures' sampling std fused by its information
(:attr:`mirrorgraph.stature.StatureEstimate.sampling_rel_std`: it shrinks with the
frames), from three windows on their distances' spread, or the first block's restart
steps (:meth:`MirrorFusion.note_restart_step`), the largest (a detector's error that
drifts with the motion over longer than a window is seen between windows only). The
per-frame bone prior holds the latest window's bone lengths and torso distances
(other fusions of the scale: ``bench/RESULTS_live_scale.md``).

While the first block grows each solve replaces the fused mirror
(:meth:`MirrorFusion.restart`); later blocks are fused (:meth:`MirrorFusion.add`). A window
beyond :data:`REJECT_CHI2` (squared Mahalanobis distance, both covariances) is rejected;
:data:`RESET_AFTER` rejected windows in a row that agree restart the fusion from them (the
camera or the mirror moved). Figures: ``bench/RESULTS_live.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .. import geometry as geo

__all__ = ["WindowEstimate", "MirrorFusion", "solve_window", "REJECT_CHI2", "RESET_AFTER"]

#: A window whose normal lies beyond this squared Mahalanobis distance from the fused
#: one (2 degrees of freedom, both covariances) is rejected: chi-square 0.9999.
REJECT_CHI2 = 18.4
#: Rejected windows in a row (agreeing with each other) that restart the fusion.
RESET_AFTER = 3


@dataclass
class WindowEstimate:
    """One window's calibration, what the fusion needs of it.

    Attributes:
        ok: the window calibrated; ``reason`` says why not otherwise.
        normal: ``(3,)`` unit normal (camera frame, away from the camera).
        distance: mirror distance (metres with a subject height, else 1).
        cov_marginal: ``(3, 3)`` the graph's marginal covariance of the normal (its
            inverse weighs the window, as one graph over every frame weighs them).
        cov_indep: ``(3, 3)`` the normal's covariance that averages over windows (the
            larger of the marginals and the time-series sandwich).
        cov_shared: ``(3, 3)`` the window's headline covariance beyond it (a bias every
            window shares; PSD part).
        rotation_std_deg: the window's own headline std (as ``calibrate`` reports it).
        distance_std: the distance's std without the height's share.
        focal_px, focal_std_px: the estimated focal length and its std (``None`` where
            the intrinsics were given).
        noise_px: the reprojection noise the window's solve found, pixels.
        frames, pairs: frames and pairs the window's graph used.
        first_frame, last_frame: frame ids the window spans.
        seconds: wall time of the solve.
        check: the window's reflection check's verdict (``ok``, ``doubtful``,
            ``too_few_frames``; :func:`~mirrorgraph.initial.reflection_check.check_reflection`:
            is the detection paired as the reflection a second person?), ``""`` where
            none ran (keypoints given as pairs).
        check_text: the check's one line where it is doubtful.
        scale_side: the stature measurement's spread in the window's calibration
            (:func:`mirrorgraph.stature.measurement_rel_std`: the legs apart and the
            segments' disagreement about the height).
        scale_sampling: the window's stature's relative std from its frames
            (:attr:`mirrorgraph.stature.StatureEstimate.sampling_rel_std`; NaN where not
            measured).
        bone_lengths: bone name -> length the window's graph held (the unit of
            ``distance``), for the per-frame prior (:mod:`.frame_prior`).
        torso_lengths: the torso's distances the window's joints pass held nearly rigid
            (``RefineOptions.torso_sigma``, :mod:`mirrorgraph.factors.torso`): ``"a-b"``
            (the two joints' names) -> the median over the window's frames of the
            distance on its joints (the unit of ``distance``); empty where the pass had
            no torso term.
    """

    ok: bool
    reason: str = ""
    normal: np.ndarray | None = None
    distance: float = float("nan")
    cov_marginal: np.ndarray | None = None
    cov_indep: np.ndarray | None = None
    cov_shared: np.ndarray | None = None
    rotation_std_deg: float = float("nan")
    distance_std: float = float("nan")
    focal_px: float | None = None
    focal_std_px: float | None = None
    noise_px: float = float("nan")
    frames: int = 0
    pairs: int = 0
    first_frame: int = -1
    last_frame: int = -1
    seconds: float = 0.0
    check: str = ""
    check_text: str = ""
    scale_side: float = 0.0
    scale_sampling: float = float("nan")
    bone_lengths: dict = field(default_factory=dict)
    torso_lengths: dict = field(default_factory=dict)


def _torso_lengths(run) -> dict:
    """The torso's distances a window's joints pass held (its record's pairs,
    :func:`mirrorgraph.graph.priors.add_torso`), each the median over the window's frames
    of the distance on its output joints: the unit of its bone lengths (the record's
    lengths are the graph's unit, before the metric scale's rescaling); empty without a
    torso term."""
    from ..graph.bones import median_bone_lengths

    record = (((run.calibration.refinement or {}).get("priors") or {}).get("joints_pass")
              or {}).get("torso") or {}
    names = list(record.get("lengths") or {})
    if not names or run.joints3d is None or run.valid3d is None:
        return {}
    sk = run.paired.skeleton
    pairs = np.array([[sk.index(j) for j in name.split("-")] for name in names], int)
    used = np.asarray(run.valid3d, bool)
    L = median_bone_lengths(run.joints3d, pairs, used[:, pairs[:, 0]] & used[:, pairs[:, 1]])
    return {name: float(v) for name, v in zip(names, L) if np.isfinite(v) and v > 0}


def _psd(C: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    return (V * np.maximum(w, 0.0)) @ V.T


def solve_window(raw, intrinsics, options) -> WindowEstimate:
    """Calibrate one window with the offline run; never raises for the data's sake.

    Args:
        raw: :class:`~mirrorgraph.keypoints.RawDetections` of the window (undistorted).
        intrinsics: :class:`~mirrorgraph.intrinsics.Intrinsics`, or ``None`` (the focal
            length estimated from ``options.image_size``).
        options: :class:`~mirrorgraph.pipelines.options.CalibrateOptions`.

    Returns:
        :class:`WindowEstimate` (``ok`` False with the reason where the window does not
        determine the mirror: too few pairs, no reflection, a second person).
    """
    from ..errors import MirrorgraphError
    from ..graph.sandwich import covariance_max
    from ..initial.reflection_check import ReflectionCheck
    from ..pipelines.mirror import calibrate
    from ..stature import measurement_rel_std

    clock = time.perf_counter()
    ids = np.asarray(raw.frame_ids)
    span = dict(first_frame=int(ids[0]) if len(ids) else -1,
                last_frame=int(ids[-1]) if len(ids) else -1)
    try:
        run = calibrate(raw, intrinsics, options)
    except (MirrorgraphError, ValueError, np.linalg.LinAlgError) as exc:
        return WindowEstimate(ok=False, reason=str(exc).splitlines()[0][:200], **span,
                              seconds=time.perf_counter() - clock)
    cal = run.calibration
    unc = cal.uncertainty or {}
    parts = run.refine_parts or {}
    marginal = np.asarray(unc.get("marginal_normal_cov") or np.full((3, 3), np.nan), float)
    if not np.all(np.isfinite(marginal)):
        return WindowEstimate(ok=False, reason="the window's marginals are undetermined",
                              **span, seconds=time.perf_counter() - clock)
    t_cov = np.asarray(parts.get("time_normal_cov", marginal), float)
    j_cov = np.asarray(parts.get("joint_normal_cov", t_cov), float)
    if not np.all(np.isfinite(t_cov)):
        t_cov = marginal
    indep = covariance_max(marginal, t_cov)
    # the headline (the largest of the marginals, the time series, the joint-pair
    # clusters, both, and the jackknifes) beyond the part that averages out: what a
    # detector's bias shared by every window adds (measured: the joint-pair clusters
    # alone left the realistic detector's live error at 1.7-2.4 times the live std)
    head = np.asarray(unc.get("normal_cov") or j_cov, float)
    if not np.all(np.isfinite(head)):
        head = j_cov
    shared = _psd(head - indep) if np.all(np.isfinite(head)) else np.zeros((3, 3))
    d = float(cal.distance) if cal.distance is not None else 1.0
    d_std = unc.get("distance_std")
    # the scale's parts out of the window's own: the height's prior and the stature's
    # measured spread, one factor on every window alike, and the stature's sampling
    # std, which the fusion takes by its information (:attr:`MirrorFusion.scale_sampling`)
    stature = (cal.refinement or {}).get("stature")
    side = measurement_rel_std(stature)
    sampling = (stature or {}).get("sampling_rel_std")
    own = float(sampling) if sampling is not None and np.isfinite(sampling) else 0.0
    hs = (float(np.sqrt(options.graph.height_sigma ** 2 + side ** 2 + own ** 2))
          if cal.distance is not None else 0.0)
    d_var = (float(d_std) ** 2 - (hs * d) ** 2) if d_std is not None else 0.0
    focal = cal.intrinsics.estimated or None
    priors = (cal.refinement or {}).get("priors", {}).get("reprojection", {})
    record = cal.input.get("reflection_check")
    check = ReflectionCheck.from_dict(record) if record else None
    return WindowEstimate(
        ok=True, normal=np.asarray(cal.normal, float), distance=d, cov_marginal=marginal,
        cov_indep=indep,
        cov_shared=shared, rotation_std_deg=float(unc.get("rotation_std_deg", np.nan)),
        distance_std=float(np.sqrt(max(d_var, 1e-12 * d * d))),
        focal_px=float(cal.intrinsics.K[0, 0]) if focal else None,
        focal_std_px=float(unc.get("focal_std_px", np.nan)) if focal else None,
        noise_px=float(priors.get("a_posteriori_sigma_px") or options.graph.pixel_sigma),
        frames=int(cal.frames_used), pairs=int(cal.pairs_used), **span,
        seconds=time.perf_counter() - clock,
        check=check.verdict if check is not None else "", scale_side=side,
        scale_sampling=float(sampling) if sampling is not None else float("nan"),
        bone_lengths=dict((cal.refinement or {}).get("bone_lengths") or {}),
        torso_lengths=_torso_lengths(run),
        check_text=check.describe() if check is not None and check.verdict == "doubtful"
        else "")


def _tangent(C: np.ndarray, B: np.ndarray) -> np.ndarray:
    return B.T @ C @ B


@dataclass
class MirrorFusion:
    """The fused mirror of the windows so far (see the module docstring).

    In the tangent basis of the current normal: ``info`` = sum of the windows' marginal
    information ``W_w`` (the weights: one graph over every frame weighs each pixel
    alike, and the marginal information is what it gives each window), ``meat`` = sum
    of ``W_w V_w W_w`` with ``V_w`` the window's independent covariance, so that the
    fused normal's independent covariance is the sandwich ``info^-1 meat info^-1``;
    ``shared_sum`` the sum of the windows' shared covariances (their mean is added).

    Attributes:
        height_sigma: the metric scale's relative std (shared by every window).
        metric: lengths in metres (a subject height), else mirror distances.
        normal: ``(3,)`` fused normal, or ``None`` before the first window.
        distance, distance_info: fused distance and its information.
        focal_px, focal_info: fused focal length and its information (``None``: held).
        noise_px: the latest window's reprojection noise (pixels).
        windows, rejected, failed, resets: counts.
        doubt: the reflection check's line of the latest window fused (or started
            from) where it doubted that the "reflection" is one (a second person
            paired as the reflection), ``""`` where it did not.
        scale_side: the latest fused window's stature measurement spread
            (:attr:`WindowEstimate.scale_side`).
        scale_sampling: the fused windows' statures' sampling std (relative), ``1 /
            sqrt(sum_w 1 / s_w^2)`` over their :attr:`WindowEstimate.scale_sampling`; NaN
            where none was measured.
        bone_lengths: the latest fused window's bone lengths (the per-frame prior).
        torso_lengths: that window's torso distances (:attr:`WindowEstimate.torso_lengths`).
    """

    height_sigma: float = 0.02
    metric: bool = False
    normal: np.ndarray | None = None
    info: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    meat: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    shared_sum: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    distance: float = 1.0
    distance_info: float = 0.0
    distances: list = field(default_factory=list)   # (distance, frames) of the windows
    focal_px: float | None = None
    focal_info: float = 0.0
    noise_px: float = float("nan")
    windows: int = 0
    rejected: int = 0
    failed: int = 0
    resets: int = 0
    last_reason: str = ""
    doubt: str = ""
    scale_side: float = 0.0
    scale_sampling: float = float("nan")
    sampling_info: float = 0.0
    bone_lengths: dict = field(default_factory=dict)
    torso_lengths: dict = field(default_factory=dict)
    step_var_sum: float = 0.0
    steps: int = 0
    _pending: list = field(default_factory=list)

    @property
    def basis(self) -> np.ndarray:
        return geo.tangent_basis(self.normal)

    @property
    def normal_cov(self) -> np.ndarray:
        """``(3, 3)`` the fused normal's covariance: independent + shared parts."""
        if self.normal is None or self.windows == 0:
            return np.full((3, 3), np.nan)
        B = self.basis
        inv = np.linalg.inv(self.info)
        indep = B @ (inv @ self.meat @ inv) @ B.T
        return indep + self.shared_sum / self.windows

    @property
    def rotation_std_deg(self) -> float:
        """The virtual camera's rotation std, deg (twice the normal's angle)."""
        from ..graph.result import rotation_std_from_normal_cov

        C = self.normal_cov
        return float(rotation_std_from_normal_cov(C)) if np.all(np.isfinite(C)) else float("nan")

    #: windows whose distances the median keeps (the oldest dropped beyond: 8 h of
    #: 900-frame windows at 30 fps; memory flat)
    MAX_DISTANCES = 1000

    @property
    def distance_spread_std(self) -> float:
        """The std of the windows' median distance from their spread: ``1.2533 * 1.4826
        MAD / sqrt(n)`` over the ``n >= 3`` windows' distances (the median's standard
        error, the MAD scaled to a normal's std; NaN with fewer windows). With a subject
        height each window's distance is its scale (the stature measured on its joints
        is the height), so this spread is the windows' scale draws seen together."""
        if len(self.distances) < 3:
            return float("nan")
        d = np.array([x for x, _ in self.distances])
        mad = 1.4826 * np.median(np.abs(d - np.median(d)))
        return float(1.2533 * mad / np.sqrt(len(d)))

    def note_restart_step(self, log_ratio: float, old_frames: int, new_frames: int) -> None:
        """Record how far a restart of the first block moved the joints' scale.

        ``log_ratio``: the log of the new window's joints' size over the old one's, on the
        same rays (:meth:`LiveCalibrator <mirrorgraph.live.calibrator.LiveCalibrator>`
        measures it on the latest frame's); ``old_frames``, ``new_frames``: the two
        windows' frames, the old ones among the new. The new window is the old one and
        a block of ``n - m`` new frames, so the step is ``(n - m) / n`` times the
        difference of the two blocks' scale errors; with blocks whose errors are
        independent draws, each of a variance falling as ``1 / frames`` or not falling
        at all (a detector's error that drifts with the motion), ``step^2 m / (n - m)``
        is an unbiased draw of the new window's scale variance for ``n = 2 m``, and
        about one otherwise (``m / (n - m)`` exactly under the first). An error that
        persists over longer than the windows (a drift correlated over hundreds of
        frames) moves the windows less than it is off: the draws then understate it
        (``tests/live/test_live.py``: an AR(1) drift, median error / std 1.2). Ignored
        where not finite or ``new_frames <= old_frames``."""
        m, n = int(old_frames), int(new_frames)
        if not (np.isfinite(log_ratio) and 0 < m < n):
            return
        self.step_var_sum += float(log_ratio) ** 2 * m / (n - m)
        self.steps += 1

    @property
    def scale_step_std(self) -> float:
        """The joints' scale std from the first block's restarts (relative): the RMS of
        their draws (:meth:`note_restart_step`); NaN before the first. A window's own
        sampling std (batch means within its frames) does not see a detector's error
        that drifts over longer than the window; two windows' blocks apart do."""
        return float(np.sqrt(self.step_var_sum / self.steps)) if self.steps else float("nan")

    @property
    def distance_data_std(self) -> float:
        """The distance's std without the height's share: the windows' own (combined by
        information) or their spread (:attr:`distance_spread_std`), the larger."""
        if self.distance_info <= 0:
            return float("nan")
        return float(np.sqrt(max(1.0 / self.distance_info,
                                 np.nan_to_num(self.distance_spread_std) ** 2)))

    @property
    def distance_std(self) -> float:
        """The distance's std: with a subject height the windows' own and the metric
        scale's share (:attr:`scale_rel_std`, which holds the windows' spread), else
        :attr:`distance_data_std`."""
        if self.distance_info <= 0:
            return float("nan")
        if not self.metric:
            return self.distance_data_std
        return float(np.hypot(np.sqrt(1.0 / self.distance_info),
                              self.scale_rel_std * self.distance))

    @property
    def scale_rel_std(self) -> float:
        """The metric scale's relative std: the height's prior, the latest fused window's
        measured stature spread (:attr:`WindowEstimate.scale_side`) and the windows'
        sampling: their fused within-window std (:attr:`scale_sampling`), from three
        windows on their distances' spread (:attr:`distance_spread_std` over the
        distance), or the first block's restart steps (:attr:`scale_step_std`), the
        largest (``0`` where none was measured). A window's own sampling
        std sees only what varies within its frames; a detector's error that drifts
        with the motion over longer than a window is seen between windows."""
        sampling = self.scale_sampling if np.isfinite(self.scale_sampling) else 0.0
        spread = self.distance_spread_std / self.distance if self.metric else float("nan")
        sampling = max(sampling, np.nan_to_num(spread), np.nan_to_num(self.scale_step_std))
        return float(np.sqrt(self.height_sigma ** 2 + self.scale_side ** 2 + sampling ** 2))

    def _median_distance(self) -> float:
        d = np.array([x for x, _ in self.distances])
        w = np.array([max(k, 1) for _, k in self.distances], float)
        order = np.argsort(d)
        c = np.cumsum(w[order])
        i = int(np.searchsorted(c, 0.5 * c[-1]))
        if len(d) % 2 == 0 and abs(c[i] - 0.5 * c[-1]) < 1e-9 and i + 1 < len(d):
            return float(0.5 * (d[order][i] + d[order][i + 1]))     # an even split
        return float(d[order][i])

    @property
    def focal_std_px(self) -> float | None:
        return None if self.focal_px is None else float(np.sqrt(1.0 / self.focal_info))

    def _start(self, w: WindowEstimate) -> None:
        self.normal = w.normal / np.linalg.norm(w.normal)
        self.info = np.zeros((2, 2))
        self.meat = np.zeros((2, 2))
        self.shared_sum = np.zeros((3, 3))
        self.windows = 0
        self.distance_info, self.focal_px, self.focal_info = 0.0, None, 0.0
        self.distances = []
        self.scale_sampling, self.sampling_info = float("nan"), 0.0
        self._fuse(w)

    def restart(self, w: WindowEstimate) -> str:
        """Replace the fused mirror by one window's (the calibration of every frame so
        far, while the first block grows); a failed window leaves it as it is. Returns
        ``"started"`` or ``"failed"``."""
        if not w.ok or not self._usable(w):
            self.failed += 1
            self.last_reason = w.reason or "the window's covariance is singular"
            return "failed"
        self._start(w)
        return "started"

    @staticmethod
    def _usable(w: WindowEstimate) -> bool:
        try:
            B = geo.tangent_basis(w.normal)
            np.linalg.cholesky(_tangent(w.cov_marginal, B))
            np.linalg.cholesky(_tangent(w.cov_indep, B))
        except np.linalg.LinAlgError:
            return False
        return True

    def _mahalanobis2(self, w: WindowEstimate) -> float:
        B = self.basis
        n_w = w.normal if w.normal @ self.normal >= 0 else -w.normal
        r = B.T @ (n_w - self.normal)
        C = _tangent(self.normal_cov, B) + _tangent(w.cov_indep + w.cov_shared, B)
        return float(r @ np.linalg.solve(C, r))

    def add(self, w: WindowEstimate) -> str:
        """Fuse one window. Returns ``"fused"``, ``"started"``, ``"rejected"``,
        ``"reset"`` or ``"failed"``."""
        if not w.ok:
            self.failed += 1
            self.last_reason = w.reason
            return "failed"
        if not self._usable(w):
            self.failed += 1
            self.last_reason = "the window's covariance is singular"
            return "failed"
        if self.normal is None:
            self._start(w)
            return "started"
        if self._mahalanobis2(w) > REJECT_CHI2:
            self.rejected += 1
            self._pending.append(w)
            if len(self._pending) >= RESET_AFTER and self._agree(self._pending[-RESET_AFTER:]):
                recent = self._pending[-RESET_AFTER:]
                self._pending.clear()
                self.resets += 1
                self.step_var_sum, self.steps = 0.0, 0       # another scene
                self._start(recent[0])
                for other in recent[1:]:
                    self._fuse(other)
                return "reset"
            return "rejected"
        self._pending.clear()
        self._fuse(w)
        return "fused"

    @staticmethod
    def _agree(ws: list[WindowEstimate]) -> bool:
        probe = MirrorFusion()
        probe._start(ws[0])
        return all(probe._mahalanobis2(w) <= REJECT_CHI2 for w in ws[1:])

    def _fuse(self, w: WindowEstimate) -> None:
        B = self.basis
        n_w = w.normal if w.normal @ self.normal >= 0 else -w.normal
        W = np.linalg.inv(_tangent(w.cov_marginal, B))
        V = _tangent(w.cov_indep, B)
        r = B.T @ (n_w - self.normal)
        info = self.info + W
        x = np.linalg.solve(info, W @ r)
        n_new = self.normal + B @ x
        n_new /= np.linalg.norm(n_new)
        R = geo.tangent_basis(n_new).T @ B               # old tangent -> new (2 x 2)
        self.info = R @ info @ R.T
        self.meat = R @ (self.meat + W @ V @ W) @ R.T
        self.normal = n_new
        self.shared_sum = self.shared_sum + w.cov_shared
        self.windows += 1
        self.distance_info += 1.0 / w.distance_std ** 2
        self.distances.append((float(w.distance), int(w.frames)))
        del self.distances[:-self.MAX_DISTANCES]
        self.distance = self._median_distance()
        if w.focal_px is not None and np.isfinite(w.focal_std_px or np.nan):
            fw = 1.0 / w.focal_std_px ** 2
            f0 = self.focal_px if self.focal_px is not None else 0.0
            self.focal_px = (f0 * self.focal_info + w.focal_px * fw) / (self.focal_info + fw)
            self.focal_info += fw
        if np.isfinite(w.noise_px):
            self.noise_px = w.noise_px
        self.doubt = w.check_text
        self.scale_side = w.scale_side
        if np.isfinite(w.scale_sampling) and w.scale_sampling > 0:
            self.sampling_info += 1.0 / w.scale_sampling ** 2
            self.scale_sampling = float(1.0 / np.sqrt(self.sampling_info))
        if w.bone_lengths:
            self.bone_lengths = w.bone_lengths
            self.torso_lengths = w.torso_lengths
