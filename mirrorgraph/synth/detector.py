"""Detector models of the synthetic scenes beyond MirrorCalib's Gaussian noise.

:func:`mirrorgraph.synth.make_scene` simulates a pose detector (its module
docstring has the model). This module adds the errors of real detectors that
are hardest for a mirror calibration, and names two detector presets:

* outliers along the epipolar line (:func:`displace_along_epipolar_lines`): a
  keypoint moved along the line through itself, its partner in the other view
  and the epipole (e.g. a knee detected a little up or down the leg when the
  leg points at the epipole). The pair still satisfies ``u'^T [e]_x u = 0``, so
  its epipolar (Sampson) residual stays at the noise level and no epipolar
  RANSAC can reject it, but the depth triangulated from it is wrong;
* left/right swaps in both views (``make_scene(lr_swap_views="both")``): the
  detector also confuses the real person's left and right;
* a per-joint bias that follows the detector's *label* in both views
  (``make_scene(joint_bias_shared=True)``): label ``j`` is off by ``b_j`` on the
  person and by ``b_j`` mirrored horizontally on the reflection (which looks
  mirrored), as ``bench/compare.py``'s bias sweep models it, instead of one
  independent offset per view;
* frame-to-frame correlated noise (AR(1), ``noise_correlation``) and the
  per-joint bias (``joint_bias_px``) are ``make_scene``'s own.

:data:`DETECTORS` holds two presets, drawn by :func:`sample_detector_params`:

``"iid"``
    MirrorCalib's protocol: Gaussian noise of 4 px (mean 0.076 px), nothing else.
``"realistic"``
    4 px AR(1) noise with a frame-to-frame correlation of 0.90-0.97, a
    per-label bias of 2-4 px (std per coordinate), 5 % of the observations
    displaced 15-100 px along their epipolar lines, and 3 % of the frames of
    each view with left and right swapped.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DETECTORS", "sample_detector_params", "displace_along_epipolar_lines",
           "EPIPOLAR_OUTLIER_PX"]

#: Length of a displacement along the epipolar line, px (uniform, either direction).
EPIPOLAR_OUTLIER_PX = (15.0, 100.0)

#: Detector presets: name -> make_scene keyword arguments, ``(low, high)`` ranges
#: drawn uniformly by :func:`sample_detector_params`.
DETECTORS: dict[str, dict] = {
    "iid": dict(noise_std=4.0, noise_mean=0.076),
    "realistic": dict(noise_std=4.0, noise_mean=0.076, noise_correlation=(0.90, 0.97),
                      joint_bias_px=(2.0, 4.0), joint_bias_shared=True,
                      epipolar_outlier_rate=0.05, lr_swap_rate=0.03, lr_swap_views="both"),
}


def sample_detector_params(rng: np.random.Generator, model: str = "iid") -> dict:
    """``make_scene`` keyword arguments of a detector preset, its ranges drawn from ``rng``.

    Args:
        rng: the generator to draw from.
        model: a name of :data:`DETECTORS`.

    Raises:
        ValueError: an unknown model.
    """
    if model not in DETECTORS:
        raise ValueError(f"unknown detector model {model!r}; known: {', '.join(DETECTORS)}")
    return {k: float(rng.uniform(*v)) if isinstance(v, tuple) else v
            for k, v in DETECTORS[model].items()}


def displace_along_epipolar_lines(rng: np.random.Generator, xy: np.ndarray, conf: np.ndarray,
                                  clean: np.ndarray, clean_image: np.ndarray,
                                  candidates: np.ndarray, rate: float, K: np.ndarray,
                                  n: np.ndarray, size: tuple[int, int],
                                  dist: np.ndarray | None = None,
                                  distort=None) -> np.ndarray:
    """Move a fraction of the observations along their epipolar lines, in place.

    Each candidate observation is chosen with probability ``rate`` and moved by
    15-100 px (:data:`EPIPOLAR_OUTLIER_PX`, either direction; the other one if
    the first leaves the image) along the line through its noise-free pinhole
    point and its partner's in the other view (the line through the epipole);
    its detector noise is kept and it gets an outlier's confidence
    (``0.3 + 0.7 Beta(2, 2)``).

    Args:
        rng: the generator of the choices.
        xy: ``(2, T, J, 2)`` observed pixels (view 0 the person, view 1 the
            reflection in real-joint labels), in the image (distorted where
            ``dist`` is given); modified.
        conf: ``(2, T, J)`` confidences; modified.
        clean: ``(2, T, J, 2)`` noise-free pinhole pixels ``pi(K X)``, ``pi(K S(X))``.
        clean_image: ``(2, T, J, 2)`` the same as the camera images them
            (``clean`` distorted by ``dist``; ``clean`` without).
        candidates: ``(2, T, J)`` observations that may be moved (detected, not
            already an outlier).
        rate: probability of each candidate.
        K: ``(3, 3)``; n: ``(3,)`` the mirror normal (for pairs whose two points
            coincide, the line through the epipole).
        size: ``(width, height)`` px.
        dist: OpenCV distortion coefficients, or ``None``.
        distort: ``distort(K, dist, pts)`` (pinhole to image pixels), with ``dist``.

    Returns:
        ``(2, T, J)`` bool: the observations moved.
    """
    sel = candidates & (rng.random(candidates.shape) < rate)
    k = int(sel.sum())
    if k == 0:
        return sel
    p = clean[sel]                                          # (k, 2) pinhole pixels
    direction = clean[::-1][sel] - p                        # to the partner in the other view
    e = np.asarray(K, float) @ np.asarray(n, float)         # homogeneous epipole
    short = np.linalg.norm(direction, axis=1) < 1.0
    direction[short] = e[:2] - e[2] * p[short]              # toward the epipole
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
    step = rng.uniform(*EPIPOLAR_OUTLIER_PX, k) * rng.choice([-1.0, 1.0], k)
    moved = p + step[:, None] * direction
    w, h = size
    outside = ((moved < 0.0) | (moved > np.array([w - 1.0, h - 1.0]))).any(1)
    moved[outside] = p[outside] - step[outside, None] * direction[outside]
    image = moved if dist is None else distort(K, dist, moved)
    xy[sel] = image + (xy[sel] - clean_image[sel])          # keep the detector noise
    np.clip(xy[..., 0], 0.0, w - 1.0, out=xy[..., 0])
    np.clip(xy[..., 1], 0.0, h - 1.0, out=xy[..., 1])
    conf[sel] = 0.3 + 0.7 * rng.beta(2.0, 2.0, k)
    return sel
