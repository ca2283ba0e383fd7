"""What the solve driver returns: :class:`SolveState`, the solved rig, joints and bookkeeping.

One record for every rig and for chunked solves (:func:`~.solve.solve`,
:func:`~.chunked.solve_chunked`): the camera poses and mirror planes (world frame,
graph units: metres with a subject height), the joints, the bone lengths, the
covariances scaled by the a posteriori noise, the reduced system of the last
undamped solve and the joints' scores for the cluster-robust uncertainty
(:mod:`.uncertainty`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from .problem import GraphProblem
from .scores import JointScores

__all__ = ["SolveState"]


@dataclass
class SolveState:
    """What :func:`~.solve.solve` returns (graph units: metres with a subject height).

    Attributes:
        poses: ``(4, 4)`` camera-to-world pose per camera.
        planes: ``(n, d)`` per mirror.
        points: ``(T, J, 3)`` joints (NaN where not estimated); used: ``(T, J)``.
        calibration_points: ``(T, J, 3)`` the calibration graph's own joints where the
            joints pass replaces them in :attr:`points` (the truth of
            :func:`mirrorgraph.graph.solve.focal_bias`); ``None``: :attr:`points`.
        bone_lengths: bone name -> length.
        torso_lengths: the torso's distances the joints pass holds (``"a-b"`` joint
            names -> length, :func:`~.stages.joints_pass`) where read on the
            calibration's joints; ``None``: the joints pass reads them on its own.
        scale: ``"subject_height"`` or ``"unit_distance"``.
        camera_cov: per camera ``(6, 6)`` tangent covariance (zeros for a held pose,
            NaN when not computed), scaled by ``variance_factor``.
        plane_cov: per mirror ``(3, 3)`` tangent covariance ``(v1, v2, d)``, scaled.
        plane_basis: per mirror the ``(3, 2)`` tangent basis of the normal.
        noise_px: the a posteriori pixel sigma; variance_factor: ``(noise / pixel_sigma)^2``.
        view_masks: per view the observations kept.
        joints_masks: per view the observations the output joints rest on where they
            differ from :attr:`view_masks` (a long video's joints pass, which leaves
            out observations the body exposes, :func:`~.stages.joints_pass`; a
            single graph holds them in :attr:`problem`); empty: :attr:`view_masks`.
        rejected: observations dropped as outliers (all views, all stages).
        undetermined: joints dropped because GTSAM found them undetermined.
        prior_info: prior name -> description.
        reprojection_factors: in the final graph(s).
        iterations, final_error, stages, timings: bookkeeping.
        body_height: subject height in graph units (the body priors' length scale).
        information, z_keys, z_values: the reduced system of the last undamped solve.
        scores: every joint's Schur complement and reduced score at the solution, for
            the cluster-robust uncertainty (:mod:`.uncertainty`; ``None`` without
            ``options.marginals``).
        problem: the final graph (``None`` for chunked solves).
        intrinsics: ``(3, 3)`` camera matrix per camera (the estimate where
            :attr:`~.rig.Camera.estimate_focal`, else the given one).
        intrinsics_cov: per camera the ``(d, d)`` covariance of its estimated
            intrinsics ``(f[, cx, cy])``, px^2, scaled by ``variance_factor``
            (``(0, 0)`` where held): the marginals.
        intrinsics_std: per camera the ``(d,)`` standard deviations of its estimated
            intrinsics, px: the larger of the marginal and the cluster-robust figures
            (:func:`~.uncertainty.robust_intrinsics_std`; empty without ``scores``).
        intrinsics_data_std: the same before :func:`~.marginals.floor_focal` puts the
            disagreement of two estimates under them: what the data's own figures say.
        camera_spread, plane_spread: per camera ``(6, 6)`` and per plane ``(3, 3)`` the
            covariance the intrinsics' headline variance adds beyond the marginals
            (:func:`~.marginals.intrinsics_spread`; empty where nothing is estimated):
            the front ends add it to positions and distances.
        focal_undetermined: camera name -> ``{"focal_px", "std_px", "rel_std"}`` for the
            cameras whose focal length the data did not determine; the solution holds
            them at their guess (:func:`mirrorgraph.graph.solve.solve`).
        focal_bias: camera name -> the estimator's bias on its focal length
            (:func:`mirrorgraph.graph.solve.focal_bias`: ``bias_px``, ``bias_var_px2``
            the variance it adds to the data's, ``replicate_std_px``); empty where not
            measured.
    """

    poses: list[np.ndarray]
    planes: list[tuple[np.ndarray, float]]
    points: np.ndarray
    used: np.ndarray
    bone_lengths: dict[str, float]
    scale: str
    camera_cov: list[np.ndarray]
    plane_cov: list[np.ndarray]
    plane_basis: list[np.ndarray]
    noise_px: float
    variance_factor: float
    view_masks: list[np.ndarray]
    rejected: int
    undetermined: int
    prior_info: dict[str, dict]
    reprojection_factors: int
    iterations: int
    final_error: float
    stages: list[dict]
    timings: dict[str, float]
    body_height: float = float("nan")
    information: np.ndarray | None = None
    z_keys: list[tuple[int, int]] = field(default_factory=list)
    z_values: gtsam.Values | None = None
    problem: GraphProblem | None = None
    scores: JointScores | None = None
    intrinsics: list[np.ndarray] = field(default_factory=list)
    intrinsics_cov: list[np.ndarray] = field(default_factory=list)
    intrinsics_std: list[np.ndarray] = field(default_factory=list)
    intrinsics_data_std: list[np.ndarray] = field(default_factory=list)
    camera_spread: list[np.ndarray] = field(default_factory=list)
    plane_spread: list[np.ndarray] = field(default_factory=list)
    focal_undetermined: dict[str, dict] = field(default_factory=dict)
    focal_bias: dict[str, dict] = field(default_factory=dict)
    joints_masks: list[np.ndarray] = field(default_factory=list)
    torso_lengths: dict[str, float] | None = None
    calibration_points: np.ndarray | None = None
