"""The result of a mirror calibration and its JSON form.

:class:`Calibration` holds what :func:`mirrorgraph.calibrate` found; its
:meth:`Calibration.to_dict` is the schema of ``calibration.json``. Everything in
it is self-consistent: the virtual camera ``(R, t)``, the fundamental matrix and
the epipole are all derived from the one mirror plane ``(normal, distance)``
(see :mod:`mirrorgraph.geometry`). :func:`write_calibration` writes it (atomically,
through :mod:`mirrorgraph.io.calibration`) and :func:`read_calibration` reads it back,
checking every field it needs.

Scale: 2D keypoints alone fix the normal but not the distance. With a metric
prior (``subject_height``) the distance, ``t`` and the 3D joints are in metres
and ``scale`` is ``"subject_height"``; otherwise ``distance`` is ``null``,
``t`` has unit length and ``scale`` is ``"unknown"``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .. import geometry as geo
from .._version import __version__
from ..errors import InputError
from ..intrinsics import Intrinsics, check_camera_matrix, check_distortion, check_size
from ..io._common import load_json, numeric_array
from ..io.calibration import write_json

__all__ = ["Calibration", "read_calibration", "write_calibration"]


#: Version of the ``calibration.json`` schema :meth:`Calibration.to_dict` writes.
SCHEMA_VERSION = 2


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
        lr_fixes: frames whose left/right labels were corrected (the reflection's, or
            either view's over the clip).
        ransac_iterations: samples the robust initialisation drew.
        input: description of the input (source, format, skeleton, joints, the frame
            rate ``fps`` and its ``fps_source``: option, input, video or default) and
            ``reflection_check`` (is the reflection a second person?
            :class:`mirrorgraph.initial.reflection_check.ReflectionCheck`).
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
        """The ``calibration.json`` schema (plain Python types), version
        :data:`SCHEMA_VERSION` (2: ``refinement.scale_source`` describes the metric
        scale, as a rig's ``scale_source`` does; version 1, without ``schema_version``,
        called it ``scale_method`` and wrote the scale's kind as ``scale_source``: both
        are read)."""

        e_px = geo.epipole_pixels(self.epipole)
        return {
            "mirrorgraph_version": __version__,
            "schema_version": SCHEMA_VERSION,
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
            lines.append("mirror distance unknown (no metric scale: give --subject-height "
                         "METRES, CalibrateOptions(subject_height=...) from Python)")
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
            if est.get("estimated") and "std_px" in est:
                lines_used = (est.get("focal_sources") or {}).get("fused", {}).get("with_lines")
                lines.append(f"focal length    {est['focal_px']:.1f} +- {est['std_px']:.1f} px "
                             + ("(estimated from the person, the reflection and the scene's "
                                "lines)" if lines_used and est.get("determined", True) else
                                "(estimated from the person and the reflection)"
                                if est.get("determined", True) else
                                "(not determined by the data: the estimate and its std)"))
            else:
                lines.append(f"focal length    {self.intrinsics.K[0, 0]:.1f} px (a guess: the "
                             "data do not determine it)")
            lines.extend(_focal_sources_lines(est.get("focal_sources")))
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


def _focal_sources_lines(sources: Mapping | None) -> list[str]:
    """The summary's line of the focal length's witnesses (``focal_sources``): the
    person's, the lines' (or why there is none) and the fused estimate."""
    if not sources:
        return []
    p, li, fu = sources.get("person", {}), sources.get("lines", {}), sources.get("fused", {})
    text = f"  sources       person {p.get('f', float('nan')):.0f} +- {p.get('std', float('nan')):.0f} px"
    if "f" in li:
        text += (f", lines {li['f']:.0f} +- {li['std']:.0f} px ({li.get('n_vps', 0)} vanishing "
                 f"points, {li.get('n_segments', 0)} segments)")
        if fu.get("with_lines"):
            text += f", fused {fu.get('f', float('nan')):.0f} +- {fu.get('std', float('nan')):.0f} px"
    else:
        text += f"; lines: none ({li.get('reason', 'not measured')})"
    return [text]


def write_calibration(path: str | os.PathLike, calibration: Calibration) -> None:
    """Write ``calibration.json`` atomically (see :meth:`Calibration.to_dict`)."""
    write_json(path, calibration.to_dict())


def read_calibration(calibration: str | os.PathLike | Mapping | Calibration, *,
                     intrinsics: Intrinsics | None = None) -> Calibration:
    """A :class:`~mirrorgraph.result.mirror.Calibration` from ``calibration.json``.

    The mirror, the intrinsics and the counts are checked (a missing or malformed
    field raises one :class:`~mirrorgraph.errors.InputError` naming the file and
    the field); the reports (``input``, ``refinement``, ``uncertainty``,
    ``sensitivity``, ``warnings``) are taken as written. The normal is kept as
    written where it is a unit vector to 1e-12 (so that numbers derived from it equal
    those of the run in memory), else normalised.

    Args:
        calibration: the file's path, its parsed document, or a
            :class:`~mirrorgraph.result.mirror.Calibration` (returned as it is, with
            ``intrinsics`` replaced where given).
        intrinsics: overrides the intrinsics stored in the file.

    Returns:
        The calibration; ``distance`` is ``None`` where the file has no metric scale.

    Raises:
        InputError: unreadable file or a missing / malformed field.
    """
    if isinstance(calibration, Calibration):
        if intrinsics is None:
            return calibration
        return replace(calibration, intrinsics=intrinsics)
    if isinstance(calibration, (str, os.PathLike)):
        src: str | None = str(calibration)
        obj = load_json(calibration)
    elif isinstance(calibration, Mapping):
        src, obj = None, calibration
    else:
        raise TypeError("calibration must be a path, a dict or a Calibration, "
                        f"got {type(calibration).__name__}")

    def section(key: str) -> Mapping:
        sec = obj.get(key) if isinstance(obj, Mapping) else None
        if not isinstance(sec, Mapping):
            raise InputError("missing or not an object (is this a mirrorgraph "
                             "calibration.json?)", source=src, field=key)
        return sec

    mirror = section("mirror")
    if "normal" not in mirror:
        raise InputError("missing", source=src, field="mirror.normal")
    raw = numeric_array(mirror["normal"], 1, source=src, frame=None, field="mirror.normal")
    if raw.shape != (3,) or not np.isfinite(raw).all() or np.linalg.norm(raw) < 1e-9:
        raise InputError(f"expected a finite non-zero 3-vector, got {mirror['normal']!r}",
                         source=src, field="mirror.normal")
    n = raw if abs(np.linalg.norm(raw) - 1.0) < 1e-12 else raw / np.linalg.norm(raw)
    d = mirror.get("distance")
    if d is not None:
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not np.isfinite(d) or d <= 0:
            raise InputError(f"expected a positive number of metres or null, got {d!r}",
                             source=src, field="mirror.distance")
        d = float(d)
    if intrinsics is None:
        intrinsics = read_intrinsics_section(section("intrinsics"), src)
    n0 = obj.get("initial_normal")
    if n0 is None:
        n0 = n
    else:
        n0 = numeric_array(n0, 1, source=src, frame=None, field="initial_normal")
        if n0.shape != (3,) or not np.isfinite(n0).all() or np.linalg.norm(n0) < 1e-9:
            raise InputError("expected a finite non-zero 3-vector", source=src,
                             field="initial_normal")
        if abs(np.linalg.norm(n0) - 1.0) >= 1e-12:
            n0 = n0 / np.linalg.norm(n0)
    counts = {}
    for key in ("frames_read", "frames_paired", "frames_used", "pairs_total", "pairs_used",
                "lr_fixes", "ransac_iterations"):
        v = obj.get(key) or 0
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v < 0 or v != int(v):
            raise InputError(f"expected a count (a whole number >= 0), got {v!r}",
                             source=src, field=key)
        counts[key] = int(v)
    reports = {}
    for key in ("input", "refinement", "uncertainty", "sensitivity"):
        v = obj.get(key) or {}
        if not isinstance(v, Mapping):
            raise InputError("expected an object", source=src, field=key)
        reports[key] = dict(v)
    ref = reports["refinement"]
    if "schema_version" not in obj and "scale_method" in ref:       # schema 1
        ref["scale_source"] = ref.pop("scale_method")
    warnings = obj.get("warnings") or []
    if not isinstance(warnings, list):
        raise InputError("expected a list of strings", source=src, field="warnings")
    return Calibration(normal=n, distance=d, scale=str(obj.get("scale", "unknown")),
                       estimator=str(obj.get("estimator", "")), intrinsics=intrinsics,
                       initial_normal=n0, refined=bool(obj.get("refined", False)),
                       warnings=[str(w) for w in warnings], **counts, **reports)


def read_intrinsics_section(intr: Mapping, src: str | None) -> Intrinsics:
    """The ``intrinsics`` section of ``calibration.json`` (:meth:`Intrinsics.to_dict`)."""
    if "K" not in intr:
        raise InputError("missing (the 3x3 camera matrix)", source=src, field="intrinsics.K")
    K = check_camera_matrix(numeric_array(intr["K"], 2, source=src, frame=None,
                                          field="intrinsics.K"), src, "intrinsics.K")
    dist = intr.get("dist")
    if dist is not None:
        dist = check_distortion(numeric_array(dist, None, source=src, frame=None,
                                              field="intrinsics.dist"), src)
    size = intr.get("image_size")
    if size is not None:
        if not (isinstance(size, (list, tuple)) and len(size) == 2):
            raise InputError(f"expected [width, height], got {size!r}", source=src,
                             field="intrinsics.image_size")
        size = check_size(size[0], size[1], src, "intrinsics.image_size")
    est = intr.get("estimated")
    if est is not None and not isinstance(est, Mapping):
        raise InputError("expected an object or null", source=src, field="intrinsics.estimated")
    return Intrinsics(K=K, dist=dist, image_size=size, source=str(intr.get("source", "")),
                      approximate=bool(intr.get("approximate", False)),
                      estimated=None if est is None else dict(est))
