"""The joints pass's own graph over the live run's latest frames: its settled joints.

:class:`WindowGraph` holds the last ``W`` frames that gave joints: each joint's pixels in
the real and the mirror view as the per-frame path paired them (after the left/right swap
filter), the views it kept (the per-frame path's one-view outlier rule and its
reprojection gate) and its per-frame joints (the Kalman filter's), the start.
:meth:`WindowGraph.solve` builds the single-mirror rig of those frames with a mirror held
(:func:`mirrorgraph.graph.rig.single_mirror_rig`), the graph from the start joints
(:func:`mirrorgraph.graph.builder.build_problem`: no cleaning, no calibration solve: the
mirror is held and the per-frame path already gated the views) and solves the offline
joints pass on it (:func:`mirrorgraph.graph.stages.joints_pass`: both views'
reprojection, every bone at the given lengths, the torso's distances, the hip, the
acceleration smoothness; then each joint's worse view beyond the outlier threshold left
out and the pass solved again), a few Gauss-Newton steps from the start.

Units: the graph's unit is the mirror distance's (metres with a subject height, else the
distance is 1); the bone lengths, torso distances and ``height`` must be in it. The
priors' sigmas are fractions of ``height`` (``bone_sigma``, ``torso_sigma``,
``joints_smoothness_sigma`` per frame^2 at the options' frame rate:
:meth:`~mirrorgraph.graph.options.PriorOptions.at_frame_rate`), so the graph is the same
in any unit. The pixels' sigma is ``pixel_sigma``, the offline pass's.

A window of ``W`` frames solved every ``k``-th frame and read ``L`` frames back is a batch
fixed-lag smoother over the joints pass's factors (``gtsam.BatchFixedLagSmoother``
re-solves its window the same way); ``bench/RESULTS_live_window_graph.md`` (the graph
given the offline mirror) and ``bench/RESULTS_live_graph.md`` (in the live run).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ["WindowGraph", "WindowSolution", "WINDOW_ITERATIONS"]

#: Gauss-Newton steps of a window's joints pass from the per-frame joints (the offline
#: pass takes one from its calibration's solution; a window's torso held from the start
#: moves the joints further than one step reaches: ``bench/RESULTS_live_window_graph.md``,
#: one window of scene_900's 1000 frames 1.10x the offline PA-MPJPE with 1 step, 0.99x
#: with 2).
WINDOW_ITERATIONS = 2


@dataclass
class WindowSolution:
    """A window's solve.

    Attributes:
        frame_ids: ``(T,)`` the window's frame numbers, increasing.
        joints: ``(T, J, 3)`` the joints pass's joints (camera frame, the mirror
            distance's unit), NaN where the graph did not solve the joint (not seen in
            both views by the per-frame path, or no start).
        iterations: Gauss-Newton steps taken (all the pass's solves).
    """

    frame_ids: np.ndarray
    joints: np.ndarray
    iterations: int = 0


class WindowGraph:
    """The last ``frames`` frames' paired pixels and start joints, and their graph's solve.

    Args:
        skeleton: the keypoint layout (``J`` joints).
        joints: ``(k,)`` skeleton indices the graph estimates (the run's mirror joints).
        frames: ``W``, the frames held (the oldest dropped beyond).
    """

    def __init__(self, skeleton, joints: np.ndarray, frames: int) -> None:
        self.skeleton = skeleton
        self.joints = np.asarray(joints, dtype=np.int64)
        self.frames = int(frames)
        self._rows: deque = deque(maxlen=self.frames)

    def __len__(self) -> int:
        return len(self._rows)

    def push(self, frame_id: int, real: np.ndarray, mirror: np.ndarray, keep: np.ndarray,
             start: np.ndarray) -> None:
        """Hold one frame.

        Args:
            frame_id: the frame's number (after every frame held).
            real, mirror: ``(J, 2)`` undistorted pixels of each joint in the real view
                and its reflection's (paired, the reflection's labels flipped).
            keep: ``(J, 2)`` bool, the views the per-frame path kept of each joint (both
                False where it gave no joint).
            start: ``(J, 3)`` the per-frame path's joints (camera frame, the current
                mirror's unit), NaN where none.
        """
        keep = np.asarray(keep, bool) & np.isfinite(start).all(1)[:, None]
        self._rows.append((int(frame_id), np.asarray(real, float)[:, :2],
                           np.asarray(mirror, float)[:, :2], keep,
                           np.asarray(start, float).copy()))

    def scale(self, ratio: float) -> None:
        """Multiply the held start joints by ``ratio`` (a new mirror's scale over the old:
        the pixels are the mirror's and are kept)."""
        for row in self._rows:
            row[4][...] *= ratio

    def clear(self) -> None:
        """Forget every frame held."""
        self._rows.clear()

    def solve(self, K: np.ndarray, normal: np.ndarray, distance: float,
              lengths: dict[str, float], torso: dict[str, float] | None, height: float,
              options, *, kernel: str | None = "geman_mcclure",
              iterations: int = WINDOW_ITERATIONS) -> WindowSolution | None:
        """The joints pass over the frames held, the mirror and the body held.

        Args:
            K: ``(3, 3)`` intrinsics, px.
            normal: ``(3,)`` the mirror's unit normal (camera frame, away from the
                camera); distance: its distance (the graph's unit).
            lengths: bone name -> length held (the graph's unit); a bone it lacks at its
                left/right partner's (:func:`mirrorgraph.graph.priors.other_side_lengths`).
            torso: ``"a-b"`` joint names -> distance held with ``options.torso_sigma``
                (the graph's unit); ``None`` or ``{}``: no torso term.
            height: the body height of the priors' sigmas, the graph's unit.
            options: :class:`~mirrorgraph.graph.options.RefineOptions` at the stream's
                frame rate (their ``joints_smoothness_sigma``, ``bone_sigma``,
                ``torso_sigma``, ``pixel_sigma``, ``outlier_threshold_px``).
            kernel: the reprojection factors' robust kernel (at
                ``options.final_kernel_scale_px``), ``None``: least squares.
            iterations: Gauss-Newton steps of each of the pass's solves.

        Returns:
            :class:`WindowSolution`; ``None`` with fewer than three frames, no joint seen
            in both views, no bone length, a height that is not a positive number, or
            without ``options.joints_smoothness_sigma``.
        """
        from ..graph.builder import build_problem
        from ..graph.problem import extract_points, snap_virtual_poses
        from ..graph.rig import single_mirror_rig
        from ..graph.stages import joints_pass

        if len(self._rows) < 3 or not lengths or not (np.isfinite(height) and height > 0):
            return None
        ids, real, mirror, keep, start = (np.stack(c) for c in zip(*self._rows))
        est = np.zeros(keep.shape[1], bool)
        est[self.joints] = True
        used = keep.all(-1) & est                  # a joint in both views: the graph's
        if not used.any():
            return None
        plane = (np.asarray(normal, float), float(distance))
        rig = single_mirror_rig(self.skeleton, ids, K, np.nan_to_num(real),
                                np.nan_to_num(mirror), used, plane[0], plane[1], self.joints)
        X0 = np.where(used[..., None], start, 0.0)
        problem = build_problem(rig, X0, used, [plane], options, body_height=float(height),
                                bone_lengths=dict(lengths), final_kernel=kernel)
        snap_virtual_poses(problem, problem.values)
        jp = joints_pass(problem, problem.values, dict(lengths), options,
                         torso=dict(torso or {}), iterations=iterations)
        if jp is None:
            return None
        jproblem, res = jp
        T, J = used.shape
        out = np.full((T, J, 3), np.nan)
        X = extract_points(jproblem, res.values)
        out[jproblem.used] = X[jproblem.used]
        return WindowSolution(frame_ids=ids, joints=out, iterations=int(res.iterations))
