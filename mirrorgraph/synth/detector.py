"""Detector models of the synthetic scenes beyond MirrorCalib's Gaussian noise.

:func:`mirrorgraph.synth.make_scene` simulates a pose detector (its module
docstring has the model; :func:`observe_keypoints` and :func:`bystander_keypoints`
here). This module adds the errors of real detectors that
are hardest for a mirror calibration, and names two detector presets:

* outliers along the epipolar line (:func:`displace_along_epipolar_lines`): a
  keypoint moved along the line through itself, its partner in the other view
  and the epipole (e.g. a knee detected a little up or down the leg when the
  leg points at the epipole). The pair still satisfies ``u'^T [e]_x u = 0``, so
  its epipolar (Sampson) residual stays at the noise level and no epipolar
  RANSAC can reject it, but the depth triangulated from it is wrong;
* left/right swaps in both views (``make_scene(lr_swap_views="both")``): the
  detector also confuses the real person's left and right;
* crossed labels in long runs of one view (``make_scene(lr_crossed_view=...)``,
  :func:`crossed_runs`): a body seen from behind labelled as one facing the camera,
  frame after frame while the person turns their back to it, or the whole clip;
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

from .camera import Z_MIN, project

__all__ = ["DETECTORS", "correlated_noise", "crossed_runs", "sample_detector_params",
           "displace_along_epipolar_lines",
           "EPIPOLAR_OUTLIER_PX", "bystander_keypoints", "observe_keypoints"]

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


def crossed_runs(rng: np.random.Generator, frames: int, fraction: float,
                 mean_run: float) -> np.ndarray:
    """``(frames,)`` bool: the frames of a view whose labels a detector crosses in runs.

    A two-state Markov chain over the frames whose crossed runs last ``mean_run``
    frames on average (geometric lengths) and whose stationary share of crossed frames
    is ``fraction``; it starts in its stationary distribution. ``fraction = 1`` crosses
    every frame, ``0`` none.

    Args:
        rng: the generator of the runs.
        frames: ``T``.
        fraction: the share of crossed frames, in ``[0, 1]``.
        mean_run: the mean length of a crossed run, frames (``>= 1``).
    """
    if fraction >= 1.0:
        return np.ones(frames, bool)
    if fraction <= 0.0:
        return np.zeros(frames, bool)
    leave = 1.0 / max(float(mean_run), 1.0)                  # crossed -> straight
    enter = min(leave * fraction / (1.0 - fraction), 1.0)    # straight -> crossed
    u = rng.random(frames)
    out = np.empty(frames, bool)
    state = bool(u[0] < fraction)
    for t in range(frames):                 # a scalar recursion of T steps, once a scene
        if t:
            state = (u[t] >= leave) if state else (u[t] < enter)
        out[t] = state
    return out


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


def _confidences(rng: np.random.Generator, outlier: np.ndarray) -> np.ndarray:
    conf = rng.beta(4.0, 1.2, outlier.shape)
    k = int(outlier.sum())
    if k:
        conf[outlier] = rng.beta(2.0, 2.0, k)
    conf *= 0.7
    conf += 0.3
    return conf


def correlated_noise(rng: np.random.Generator, shape: tuple[int, ...], rho: float
                      ) -> np.ndarray:
    """Unit-variance AR(1) noise along axis 1 (frames): ``e_t = rho e_(t-1) + sqrt(1-rho^2) w_t``."""
    # lazy: importing scipy.signal costs ~0.35 s, and this module is loaded by
    # `import mirrorgraph.synth` and `mirrorgraph --help`
    from scipy.signal import lfilter

    w = rng.standard_normal(shape)
    w[:, 0] /= np.sqrt(1.0 - rho ** 2)          # start in the stationary distribution
    return lfilter([np.sqrt(1.0 - rho ** 2)], [1.0, -rho], w, axis=1)


def observe_keypoints(rng: np.random.Generator, clean: np.ndarray, size: tuple[int, int],
             noise_mean: float, noise_std: float, outlier_rate: float, missing_rate: float,
             single_person_rate: float, noise_correlation: float = 0.0,
             joint_bias_px: float = 0.0, rng_detector: np.random.Generator | None = None,
             bias_flip: np.ndarray | None = None):
    """Noisy detections ``(V, T, J, 3)`` of clean points ``(V, T, J, 2)``.

    With ``bias_flip`` (the skeleton's left/right map; ``V = 2``, view 1 the
    reflection in real-joint labels) the per-joint bias follows the detector's
    label: label ``j`` is off by ``b_j`` on the person and by ``b_j`` mirrored
    horizontally on the reflection, whose real joint ``k`` the detector labels
    ``flip[k]``.
    """
    V, T, J, _ = clean.shape
    if noise_correlation > 0 or joint_bias_px > 0:
        xy = clean + noise_mean
        if noise_std > 0:
            xy = xy + noise_std * correlated_noise(rng_detector, clean.shape, noise_correlation)
        if joint_bias_px > 0 and bias_flip is None:
            xy = xy + rng_detector.normal(0.0, joint_bias_px, (V, 1, J, 2))
        elif joint_bias_px > 0:
            b = rng_detector.normal(0.0, joint_bias_px, (J, 2))
            xy = xy + np.stack([b, b[bias_flip] * np.array([-1.0, 1.0])])[:, None]
    elif noise_std > 0:
        xy = rng.normal(noise_mean, noise_std, clean.shape)
        xy += clean
    else:
        xy = clean + noise_mean
    outl = rng.random((V, T, J)) < outlier_rate if outlier_rate > 0 \
        else np.zeros((V, T, J), bool)
    k = int(outl.sum())
    if k:
        ang = rng.uniform(0.0, 2 * np.pi, k)
        rad = rng.uniform(30.0, 150.0, k)
        xy[outl] = clean[outl] + np.stack([np.cos(ang), np.sin(ang)], -1) * rad[:, None]
    w, h = size
    np.clip(xy[..., 0], 0.0, w - 1.0, out=xy[..., 0])
    np.clip(xy[..., 1], 0.0, h - 1.0, out=xy[..., 1])
    conf = _confidences(rng, outl)
    p_person = missing_rate / 5.0
    p_joint = max(0.0, (missing_rate - p_person) / (1.0 - p_person)) if p_person < 1 else 1.0
    drop = rng.random((V, T)) < p_person if p_person > 0 else np.zeros((V, T), bool)
    if single_person_rate > 0:
        single = np.flatnonzero(rng.random(T) < single_person_rate)
        drop[rng.integers(0, V, len(single)), single] = True
    miss = rng.random((V, T, J)) < p_joint if p_joint > 0 else np.zeros((V, T, J), bool)
    detected = ~drop & ~miss.all(-1)
    miss |= ~detected[..., None]
    outl &= ~miss
    obs = np.empty(xy.shape[:-1] + (3,))
    obs[..., :2] = xy
    obs[..., 2] = conf
    del xy, conf
    obs[miss] = (np.nan, np.nan, 0.0)
    return obs, miss, outl, detected


def bystander_keypoints(rng: np.random.Generator, poses: np.ndarray, frames: np.ndarray,
                K: np.ndarray, size: tuple[int, int], margin: float, R_cw: np.ndarray,
                noise_mean: float, noise_std: float, missing_rate: float) -> np.ndarray:
    """Keypoints ``(E, J, 3)`` of unrelated people, whole inside the image."""
    E, J = len(frames), poses.shape[1]
    if E == 0:
        return np.zeros((0, J, 3))
    w, h = size
    T = poses.shape[0]
    p = poses[rng.integers(0, T, E)]                    # (E, J, 3) units of height, copy
    p[..., [0, 2]] -= p[..., [0, 2]].mean(1, keepdims=True)
    height = rng.uniform(1.50, 1.95, E)
    yaw = rng.uniform(-np.pi, np.pi, E)
    c, s = np.cos(yaw), np.sin(yaw)
    Ry = np.zeros((E, 3, 3))
    Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2] = c, s, 1.0, -s, c
    Rb = R_cw @ Ry                                       # (E, 3, 3) body -> camera
    X = np.einsum("eij,ekj->eki", Rb, p) * height[:, None, None]
    depth = rng.uniform(3.0, 9.0, E)
    X = X + np.stack([np.zeros(E), 0.9 * height, depth], -1)[:, None, :]
    X[..., 2] = np.maximum(X[..., 2], Z_MIN)
    uv = project(K, X)
    lo, hi = uv.min(1), uv.max(1)                        # (E, 2) bounding boxes
    box = np.maximum(hi - lo, 1e-6)
    avail = np.array([w - 2 * margin, h - 2 * margin])
    frac = rng.uniform(0.35, 0.8, E)
    scale = np.minimum(np.minimum(1.0, avail[1] * frac / box[:, 1]), avail[0] / box[:, 0])
    uv = (uv - lo[:, None]) * scale[:, None, None]
    box = box * scale[:, None]
    corner = margin + rng.random((E, 2)) * np.maximum(avail - box, 0.0)
    uv = uv + corner[:, None]
    xy = uv + rng.normal(noise_mean, noise_std, uv.shape) if noise_std > 0 else uv + noise_mean
    xy[..., 0] = np.clip(xy[..., 0], 0.0, w - 1.0)
    xy[..., 1] = np.clip(xy[..., 1], 0.0, h - 1.0)
    conf = _confidences(rng, np.zeros((E, J), bool))
    miss = rng.random((E, J)) < missing_rate
    miss[miss.all(1), 0] = False                         # keep at least one joint
    out = np.concatenate([xy, conf[..., None]], -1)
    out[miss] = (np.nan, np.nan, 0.0)
    return out
