"""Random scenes from the wide ranges: a geometry slice times a detector model.

A *slice* is a geometry preset of :mod:`.geometry` (``"favourable"``, ``"gym"``,
``"wide"``, ``"low_parallax"``); a *noise model* a detector preset of
:mod:`.detector` (``"iid"``, ``"realistic"``). :func:`sample_scene_params`
draws the ``make_scene`` arguments of one scene of a slice and noise model
(the detector's ranges; the geometry's ranges are drawn by ``make_scene``'s
placement itself, which redraws what does not fit), :func:`make_wide_scene`
makes the scene of a seed:

    >>> from mirrorgraph.synth import make_wide_scene
    >>> scene = make_wide_scene(3, slice="gym", noise="realistic", frames=200)
    >>> scene.placement["geometry"], scene.options["lr_swap_views"]
    ('gym', 'both')

The same ``(seed, slice, noise)`` gives the same scene, so benchmarks compare
solvers on identical scenes.
"""

from __future__ import annotations

import numpy as np

from .detector import DETECTORS, sample_detector_params
from .geometry import PRESETS
from .scene import make_scene

__all__ = ["SLICES", "NOISE_MODELS", "sample_scene_params", "make_wide_scene"]

#: The geometry slices (names of :data:`~mirrorgraph.synth.geometry.PRESETS`).
SLICES = tuple(PRESETS)
#: The detector models (names of :data:`~mirrorgraph.synth.detector.DETECTORS`).
NOISE_MODELS = tuple(DETECTORS)

_SALT = 0x5CE7E                    # keeps the draws apart from make_scene's own seed stream


def sample_scene_params(rng: np.random.Generator, slice: str = "wide", noise: str = "iid"
                        ) -> dict:
    """``make_scene`` keyword arguments of one scene of a slice and noise model.

    Args:
        rng: the generator of the draws.
        slice: a geometry preset name (:data:`SLICES`).
        noise: a detector model name (:data:`NOISE_MODELS`).

    Returns:
        ``geometry`` and the detector's arguments (noise, bias, correlation,
        outliers along epipolar lines, left/right swaps) with their ranges drawn.

    Raises:
        ValueError: an unknown slice or noise model.
    """
    if slice not in PRESETS:
        raise ValueError(f"unknown slice {slice!r}; known: {', '.join(SLICES)}")
    return dict(geometry=slice, **sample_detector_params(rng, noise))


def make_wide_scene(seed: int, slice: str = "wide", noise: str = "iid", frames: int = 1000,
                    **overrides):
    """The scene of ``seed`` in a slice and noise model (:func:`sample_scene_params`).

    Args:
        seed: the scene's seed (of the detector draws and of ``make_scene``).
        slice: a geometry preset name.
        noise: a detector model name.
        frames: number of frames.
        overrides: further ``make_scene`` arguments (they win over the drawn ones).

    Returns:
        A :class:`~mirrorgraph.synth.scene.SyntheticScene`.
    """
    params = sample_scene_params(np.random.default_rng([int(seed), _SALT]), slice, noise)
    params.update(overrides)
    return make_scene(frames=frames, seed=seed, **params)
