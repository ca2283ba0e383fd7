"""The scene's straight lines as the focal length's second witness, beside the person's.

Where ``calibrate`` estimates the focal length of a video (no intrinsics, no ``--fov``),
:func:`lines_witness` measures it from the room (:mod:`mirrorgraph.video.lines`: the
median background of frames over the video, the people's boxes masked;
:mod:`mirrorgraph.initial.vanishing`: the vanishing points of orthogonal directions).
The pipeline solves the graph once with the person alone, then, where the lines give an
estimate, once more with the lines' Gaussian joined to the guess's prior on the focal
length (:func:`fuse_gaussians`: the product of the two factors); :func:`focal_sources`
is the record of the three (``person``, ``lines``, ``fused``) and
:func:`disagreement_warning` says when person and lines disagree.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from typing import TYPE_CHECKING

from ..errors import InputError
from ..graph.options import FocalOptions, RefineOptions

if TYPE_CHECKING:
    from ..initial.vanishing import LinesFocal

__all__ = ["lines_witness", "fuse_gaussians", "focal_sources", "disagreement_warning",
           "video_of", "searched_near", "DISAGREEMENT_SIGMA", "SEARCH_SIGMAS",
           "SEARCH_MIN_REL"]

#: Person and lines disagree where their focal lengths lie more than this many combined
#: standard deviations apart.
DISAGREEMENT_SIGMA = 2.0

#: The fused solve's initial search of the focal length spans the fused prior's mean
#: this many of its standard deviations either way, and at least :data:`SEARCH_MIN_REL`
#: of it (within the options' range): an estimate within a few per cent of the
#: prior's mean lies inside the span, away from its ends (where
#: :func:`~mirrorgraph.graph.solve.undetermined_focal` calls it undetermined).
SEARCH_SIGMAS = 5.0
SEARCH_MIN_REL = 0.25


def video_of(keypoints, video: str | os.PathLike | None) -> Path | None:
    """The video whose frames show the scene: the input itself where it is a video file,
    else ``video`` (``CalibrateOptions.video``), else ``None``."""
    from ..video.reader import is_video
    if isinstance(keypoints, (str, os.PathLike)) and is_video(keypoints):
        return Path(keypoints)
    return Path(video) if video is not None and is_video(video) else None


def lines_witness(video: Path | None, people: list[np.ndarray] | None,
                  image_size: tuple[int, int] | None, focal: FocalOptions,
                  seed: int = 0) -> LinesFocal:
    """The focal length the scene's lines give (:func:`~mirrorgraph.initial.vanishing.
    focal_from_lines`), or a :class:`~mirrorgraph.initial.vanishing.LinesFocal` with the
    reason there is none: switched off, no video, a video of another size than the
    keypoints', too few lines.

    Args:
        video: the video (``None``: the input is keypoints without one).
        people: per frame ``(P, J, 3)`` keypoints of every detection, for the mask.
        image_size: the keypoints' ``(width, height)`` px.
        focal: ``lines``, ``lines_frames``, ``search_fov_deg``, ``principal_point_rel_sigma``.
        seed: RANSAC's and the bootstrap's seed.
    """
    from ..initial.vanishing import LinesFocal, focal_from_lines
    from ..video.lines import scene_segments
    if not focal.lines:
        return LinesFocal(None, None, 0, reason="switched off (--no-lines)")
    if video is None:
        return LinesFocal(None, None, 0, reason="the input is no video (keypoints only: "
                                                "give the video to use the scene's lines)")
    try:
        scene = scene_segments(video, people, frames=focal.lines_frames)
    except InputError as exc:
        return LinesFocal(None, None, 0, reason=f"the video cannot be read: {exc}")
    if scene.frames == 0:
        return LinesFocal(None, None, 0, reason="no frame of the video could be read")
    if image_size is not None and tuple(image_size) != tuple(scene.image_size):
        return LinesFocal(None, None, 0, reason=(
            f"the video is {scene.image_size[0]}x{scene.image_size[1]}, the keypoints' "
            f"image {image_size[0]}x{image_size[1]}"))
    return focal_from_lines(scene.segments, scene.image_size,
                            fov_range_deg=focal.search_fov_deg,
                            principal_point_sigma_px=(focal.principal_point_rel_sigma
                                                      * max(scene.image_size)),
                            seed=seed)


def searched_near(options: RefineOptions, f: float, std: float, K: np.ndarray
                  ) -> RefineOptions:
    """``options`` whose focal search (:attr:`~mirrorgraph.graph.options.FocalOptions.
    search_fov_deg`) spans ``f +- max(SEARCH_SIGMAS std, SEARCH_MIN_REL f)`` (within its
    own range) for the
    image of ``K``: the start of the fused solve among the focal lengths its prior
    allows, not at the person's own best, whose bones may hold the solve in a minimum
    the prior does not reach."""
    half_width = float(K[0, 2])
    lo_deg, hi_deg = options.focal.search_fov_deg

    def fov(x):
        return float(np.degrees(2.0 * np.arctan(half_width / max(x, 1e-9))))

    rel = max(SEARCH_SIGMAS * std / f, SEARCH_MIN_REL)
    span = (max(lo_deg, fov(f * (1.0 + rel))), min(hi_deg, fov(f * max(1.0 - rel, 1e-3))))
    if span[0] >= span[1]:
        return options
    return replace(options, focal=replace(options.focal, search_fov_deg=span))


def fuse_gaussians(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    """``(mean, std)`` of the product of two Gaussians ``(mean, std)``: two priors on one
    variable are this one."""
    wa, wb = 1.0 / a[1] ** 2, 1.0 / b[1] ** 2
    return (wa * a[0] + wb * b[0]) / (wa + wb), math.sqrt(1.0 / (wa + wb))


def focal_sources(person: dict, lines: LinesFocal, fused: dict | None) -> dict:
    """The ``focal_sources`` record: ``person`` (the graph's estimate without the lines:
    ``f``, ``std``, ``determined``), ``lines`` (``f``, ``std``, ``n_segments``, ``n_vps``,
    ... or ``reason``), ``fused`` (the graph's estimate with both; the person's where the
    lines give none) and ``agreement_sigma`` (person minus lines over their combined
    std, where both are)."""
    rec = {"person": {"f": float(person["focal_px"]), "std": float(person["std_px"]),
                      "determined": bool(person.get("determined", True))},
           "lines": lines.to_dict()}
    src = fused if fused is not None else person
    rec["fused"] = {"f": float(src["focal_px"]), "std": float(src["std_px"]),
                    "with_lines": fused is not None}
    if lines.usable:
        rec["agreement_sigma"] = float(
            (rec["person"]["f"] - lines.focal_px)
            / math.hypot(rec["person"]["std"], lines.std_px))
    return rec


def disagreement_warning(sources: dict) -> str | None:
    """A warning where person and lines lie more than :data:`DISAGREEMENT_SIGMA` combined
    standard deviations apart (``None`` where they agree or one is missing)."""
    z = sources.get("agreement_sigma")
    if z is None or abs(z) <= DISAGREEMENT_SIGMA:
        return None
    p, li = sources["person"], sources["lines"]
    return (f"the focal length from the person ({p['f']:.0f} +- {p['std']:.0f} px) and from "
            f"the scene's lines ({li['f']:.0f} +- {li['std']:.0f} px) disagree by "
            f"{abs(z):.1f} combined std: a detector whose joints are biased, lens distortion "
            "bending the lines, or lines not at right angles; the fused estimate "
            f"({sources['fused']['f']:.0f} +- {sources['fused']['std']:.0f} px) leans on the "
            "tighter; see intrinsics.estimated.focal_sources, or pass --intrinsics FILE")
