"""The result of a mirror calibration and its JSON form.

:class:`Calibration` holds what :func:`mirrorgraph.calibrate` found; its
:meth:`Calibration.to_dict` is the schema of ``calibration.json``. Everything in
it is self-consistent: the virtual camera ``(R, t)``, the fundamental matrix and
the epipole are all derived from the one mirror plane ``(normal, distance)``
(see :mod:`mirrorgraph.geometry`).

Scale: 2D keypoints alone fix the normal but not the distance. With a metric
prior (``subject_height``) the distance, ``t`` and the 3D joints are in metres
and ``scale`` is ``"subject_height"``; otherwise ``distance`` is ``null``,
``t`` has unit length and ``scale`` is ``"unknown"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import geometry as geo
from ._version import __version__
from .intrinsics import Intrinsics


@dataclass
class Calibration:
    """A calibrated mirror (real camera frame).

    Attributes:
        normal: ``(3,)`` unit mirror normal, pointing away from the camera.
        distance: camera-to-mirror distance in metres, or ``None`` if the scale
            is unknown.
        scale: ``"subject_height"`` or ``"unknown"``.
        estimator: initial estimator used (``reflective``, ``eightpoint``, ``reflective8``).
        intrinsics: the camera intrinsics used.
        initial_normal: ``(3,)`` normal of the initial estimate (before refinement).
        refined: whether the factor-graph refinement ran.
        frames_read, frames_paired, frames_used: frames in the input, with a
            person/reflection pair, with at least one inlier pair.
        pairs_total, pairs_used: joint/reflection pairs considered, inliers kept.
        lr_fixes: frames whose reflection's left/right labels were corrected.
        ransac_iterations: samples the robust initialisation drew.
        input: description of the input (source, format, skeleton, joints, the frame
            rate ``fps`` and its ``fps_source``: option, input, video or default) and
            ``reflection_check`` (is the reflection a second person?
            :class:`mirrorgraph.pipeline.ReflectionCheck`).
        refinement: refinement report (priors, weights, residuals, timings; under
            ``completion`` the keypoints outside the graph triangulated with the solved
            mirror, :class:`mirrorgraph.completion.Completion`), or empty.
        uncertainty: the mirror's covariance and rotation std (the cluster-robust
            figure, the marginals beside it), or empty.
        sensitivity: what the calibration rests on
            (:mod:`mirrorgraph.graph.sensitivity`), or empty.
        warnings: doubts about the result, in words.
    """

    normal: np.ndarray
    distance: float | None
    scale: str
    estimator: str
    intrinsics: Intrinsics
    initial_normal: np.ndarray
    refined: bool = False
    frames_read: int = 0
    frames_paired: int = 0
    frames_used: int = 0
    pairs_total: int = 0
    pairs_used: int = 0
    lr_fixes: int = 0
    ransac_iterations: int = 0
    input: dict[str, Any] = field(default_factory=dict)
    refinement: dict[str, Any] = field(default_factory=dict)
    uncertainty: dict[str, Any] = field(default_factory=dict)
    sensitivity: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    # ---------------------------------------------------------------- derived
    @property
    def virtual_rotation(self) -> np.ndarray:
        """``(3, 3)`` rotation ``R = D (I - 2 n n^T)`` of the virtual camera."""
        return geo.virtual_camera_from_mirror(self.normal, 1.0)[0]

    @property
    def virtual_translation(self) -> np.ndarray:
        """``(3,)`` ``t = 2 d D n`` in metres, or the unit vector ``D n`` if scale is unknown."""
        if self.distance is None:
            return geo.D_FLIP @ self.normal
        return geo.virtual_camera_from_mirror(self.normal, self.distance)[1]

    @property
    def epipole(self) -> np.ndarray:
        """``(3,)`` homogeneous epipole ``K n`` in pixels, unit norm."""
        return geo.epipole_from_normal(self.intrinsics.K, self.normal)

    @property
    def fundamental(self) -> np.ndarray:
        """``(3, 3)`` reflective fundamental matrix ``[K n]_x`` (unit norm, pixels)."""
        return geo.fundamental_from_epipole(self.epipole)

    @property
    def inlier_ratio(self) -> float:
        return self.pairs_used / self.pairs_total if self.pairs_total else 0.0

    def to_dict(self) -> dict[str, Any]:
        """The ``calibration.json`` schema (plain Python types)."""

        e_px = geo.epipole_pixels(self.epipole)
        return {
            "mirrorgraph_version": __version__,
            "mirror": {
                "normal": self.normal.tolist(),
                "distance": self.distance,
                "frame": "real camera (x right, y down, z forward); normal points away "
                         "from the camera; plane n.X = distance",
            },
            "scale": self.scale,
            "virtual_camera": {
                "R": self.virtual_rotation.tolist(),
                "t": self.virtual_translation.tolist(),
                "D": geo.D_FLIP.tolist(),
                "convention": "X_virtual = D (R X + t); pixels = pi(K X_virtual)",
            },
            "fundamental_matrix": self.fundamental.tolist(),
            "epipole_px": None if e_px is None else e_px.tolist(),
            "epipole_homogeneous": self.epipole.tolist(),
            "estimator": self.estimator,
            "refined": self.refined,
            "initial_normal": np.asarray(self.initial_normal).tolist(),
            "frames_read": self.frames_read,
            "frames_paired": self.frames_paired,
            "frames_used": self.frames_used,
            "pairs_total": self.pairs_total,
            "pairs_used": self.pairs_used,
            "inlier_ratio": self.inlier_ratio,
            "lr_fixes": self.lr_fixes,
            "ransac_iterations": self.ransac_iterations,
            "intrinsics": self.intrinsics.to_dict(),
            "input": self.input,
            "refinement": self.refinement,
            "uncertainty": self.uncertainty,
            "sensitivity": self.sensitivity,
            "warnings": list(self.warnings),
        }

    def summary(self) -> str:
        """A few lines for people."""
        n = self.normal
        lines = [f"mirror normal   [{n[0]:+.5f}, {n[1]:+.5f}, {n[2]:+.5f}]  (real camera frame)"]
        if self.distance is None:
            lines.append("mirror distance unknown (no metric prior: pass --subject-height)")
        else:
            lines.append(f"mirror distance {self.distance:.4f} m  (scale from {self.scale})")
        e_px = geo.epipole_pixels(self.epipole)
        lines.append("epipole         " + ("at infinity" if e_px is None
                                           else f"({e_px[0]:.1f}, {e_px[1]:.1f}) px"))
        lines.append(f"pairs           {self.pairs_used} inliers of {self.pairs_total} "
                     f"({100 * self.inlier_ratio:.1f}%) in {self.frames_used} frames "
                     f"of {self.frames_read}; left/right fixes {self.lr_fixes}")
        est = self.intrinsics.estimated
        if est:
            if est.get("estimated"):
                lines.append(f"focal length    {est['focal_px']:.1f} +- {est['std_px']:.1f} px "
                             "(estimated from the person and the reflection)")
            else:
                lines.append(f"focal length    {self.intrinsics.K[0, 0]:.1f} px (a guess: the "
                             "data do not determine it)")
        lines.append(f"estimator       {self.estimator}" + (" + factor graph" if self.refined else ""))
        completion = self.refinement.get("completion")
        if completion:
            lines.append(f"3D joints       {completion['joints_completed']} keypoints outside the "
                         "graph triangulated with the solved mirror")
        if self.uncertainty:
            u = self.uncertainty
            line = f"uncertainty     rotation std {u.get('rotation_std_deg', float('nan')):.4f} deg"
            if u.get("rotation_90_deg") is not None:
                line += f", 90 % region up to {u['rotation_90_deg']:.4f} deg"
            lines.append(line)
        for w in self.warnings:
            lines.append(f"warning: {w}")
        return "\n".join(lines)


def write_calibration(path, calibration: Calibration) -> None:
    """Write ``calibration.json`` atomically (see :meth:`Calibration.to_dict`)."""
    from .io.calibration import write_json

    write_json(path, calibration.to_dict())
