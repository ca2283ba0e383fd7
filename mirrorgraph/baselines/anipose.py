"""aniposelib's bundle adjustment on a mirror, as a multi-camera user would run it.

aniposelib (the calibration library of Anipose) knows ordinary, right-handed
cameras. The mirror view is a *left-handed* virtual camera, but flipping the
image horizontally makes it right-handed again:

    a reflection seen at ``u' = (x', y')`` is seen in the flipped image at
    ``(W - x', y')``; the camera that takes the flipped image has the
    intrinsics ``K_f`` (``cx -> W - cx``, skew ``s -> -s``) and camera
    coordinates ``F X_v`` with ``F = diag(-1, 1, 1)``. With
    ``X_v = D (R X + t)`` (:mod:`mirrorgraph.geometry`, ``D = F``) its
    extrinsics are ``F D (R X + t) = R X + t``: exactly the package's
    ``(R, t)``, a proper rotation.

So :func:`calibrate_anipose` builds a :class:`aniposelib.cameras.CameraGroup`
of the real camera (``K``, identity pose) and the flipped-image camera
(``K_f``, an initial ``(R, t)``), gives it every joint pair as a point seen by
both, runs ``CameraGroup.bundle_adjust_iter`` and reads the relative pose of
the second camera back as the virtual camera ``(R, t)`` (no further
conversion: the flip is already undone by construction).

Choices (options of :class:`AniposeOptions`):

* **Initial pose** (aniposelib needs one; with a mirror there is no board):
  ``"essential"`` (default) is what a user without a board does: OpenCV's
  five-point essential matrix with RANSAC (``cv2.findEssentialMat`` with its
  default 1 px threshold and 0.999 confidence, on normalised coordinates) and
  ``cv2.recoverPose`` on the flipped pairs. ``"reflective"`` starts from
  mirrorgraph's own initial estimate (then the result measures what bundle
  adjustment adds to it); ``"identity"`` starts at ``R = I`` and a unit
  sideways baseline; ``initial_pose=(R, t)`` gives the start explicitly.
* **Intrinsics** are known (as for every method in the comparison), so only the
  extrinsics are adjusted (``only_extrinsics=True``); aniposelib's own default
  would also adjust the focal length and one distortion coefficient.
* Everything else is aniposelib's default (six robust iterations, 1000 sampled
  points, ``ftol=1e-4``). Its sampling uses NumPy's global generator; it is
  seeded with ``seed`` and restored afterwards.
* The pose is not forced to be a reflection: ``R`` need not equal
  ``D (I - 2 n n^T)``; the normal reported is ``D t / |t|``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .. import geometry as geo
from ..errors import DegenerateGeometryError
from ..initial.estimators import estimate_mirror
from . import require, triangulate_virtual

INITS = ("essential", "reflective", "identity")


def flip_points(u: np.ndarray, width: float) -> np.ndarray:
    """Pixels ``(..., 2)`` in the horizontally flipped image: ``x -> W - x``."""
    out = np.array(u, dtype=float, copy=True)
    out[..., 0] = width - out[..., 0]
    return out


def flipped_intrinsics(K: np.ndarray, width: float) -> np.ndarray:
    """``K_f`` of the camera that takes the flipped image: ``cx -> W - cx``, ``s -> -s``."""
    Kf = np.array(K, dtype=float, copy=True)
    Kf[0, 2] = width - Kf[0, 2]
    Kf[0, 1] = -Kf[0, 1]
    return Kf


@dataclass
class AniposeOptions:
    """Options of :func:`calibrate_anipose` (aniposelib's defaults where not said)."""

    init: str = "essential"
    initial_pose: tuple | None = None
    only_extrinsics: bool = True
    essential_threshold_px: float = 1.0
    n_iters: int = 6
    start_mu: float = 15.0
    end_mu: float = 1.0
    max_nfev: int = 200
    ftol: float = 1e-4
    n_samp_iter: int = 200
    n_samp_full: int = 1000
    error_threshold: float = 0.3
    seed: int = 0
    verbose: bool = False


@dataclass
class AniposeResult:
    """What :func:`calibrate_anipose` returns.

    Attributes:
        rotation: ``(3, 3)`` virtual-camera rotation ``R`` (``X_v = D (R X + t)``).
        translation: ``(3,)`` ``t``, unit length (bundle adjustment fixes no scale).
        normal: ``(3,)`` ``D t``, the mirror normal the translation implies.
        initial_rotation, initial_translation: the start given to aniposelib.
        error: aniposelib's final median reprojection error, px.
        joints3d: ``(T, J, 3)`` the pairs triangulated with the result (unit ``|t|``).
        camera_group: the adjusted :class:`aniposelib.cameras.CameraGroup`.
        timings: seconds per stage.
    """

    rotation: np.ndarray
    translation: np.ndarray
    normal: np.ndarray
    initial_rotation: np.ndarray
    initial_translation: np.ndarray
    error: float
    joints3d: np.ndarray
    camera_group: object = None
    timings: dict = field(default_factory=dict)


def _initial_pose(kind: str, K, Kf, u, um_flipped, um, threshold_px, seed):
    cv2 = require("cv2", "the aniposelib baseline")
    if kind == "identity":
        return np.eye(3), np.array([-1.0, 0.0, 0.0])
    if kind == "reflective":
        est = estimate_mirror(u, um, K, seed=seed)
        R, t = geo.virtual_camera_from_mirror(est.normal, 0.5)
        return R, t
    if kind != "essential":
        raise ValueError(f"unknown init {kind!r}; choose one of {', '.join(INITS)}")
    x0 = (np.linalg.solve(K, geo.to_homogeneous(u).T).T)[:, :2]
    x1 = (np.linalg.solve(Kf, geo.to_homogeneous(um_flipped).T).T)[:, :2]
    cv2.setRNGSeed(int(seed))
    E, mask = cv2.findEssentialMat(x0, x1, np.eye(3), method=cv2.RANSAC, prob=0.999,
                                   threshold=threshold_px / K[0, 0])
    if E is None or E.shape[0] < 3:
        raise DegenerateGeometryError("OpenCV found no essential matrix for the flipped views")
    E = E[:3]
    _, R, t, _ = cv2.recoverPose(E, x0, x1, np.eye(3), mask=mask)
    return R, t.ravel()


def calibrate_anipose(real: np.ndarray, mirror: np.ndarray, K: np.ndarray,
                      image_size: tuple[int, int], *, valid: np.ndarray | None = None,
                      joints: np.ndarray | None = None,
                      options: AniposeOptions | None = None) -> AniposeResult:
    """Calibrate the virtual camera with aniposelib's ``bundle_adjust_iter``.

    Args:
        real: ``(T, J, 2|3)`` direct-view pixels (undistorted).
        mirror: ``(T, J, 2|3)`` mirror-view pixels, real-joint labels (as for
            every method: the reflection's labels flipped).
        K: ``(3, 3)`` intrinsics; image_size: ``(width, height)``.
        valid: ``(T, J)`` bool pairs to use (default: finite in both views).
        joints: joint indices used (default: all given).
        options: :class:`AniposeOptions`.

    Raises:
        BenchDependencyError: aniposelib is not installed.
        DegenerateGeometryError: too few pairs or no initial pose.
    """
    opts = options or AniposeOptions()
    cameras = require("aniposelib.cameras", "the aniposelib baseline")
    cv2 = require("cv2", "the aniposelib baseline")
    K = np.asarray(K, float)
    W = float(image_size[0])
    real = np.asarray(real, float)[..., :2]
    mirror = np.asarray(mirror, float)[..., :2]
    T, J = real.shape[:2]
    ok = np.isfinite(real).all(-1) & np.isfinite(mirror).all(-1)
    if valid is not None:
        ok &= np.asarray(valid, bool)
    if joints is not None:
        sel = np.zeros(J, bool)
        sel[np.asarray(joints, int)] = True
        ok &= sel[None, :]
    u, um = real[ok], mirror[ok]
    if len(u) < 8:
        raise DegenerateGeometryError(f"aniposelib baseline needs 8 pairs, got {len(u)}")
    Kf = flipped_intrinsics(K, W)
    umf = flip_points(um, W)
    timings = {}
    t0 = time.perf_counter()
    if opts.initial_pose is not None:
        R0, t0_vec = (np.asarray(opts.initial_pose[0], float),
                      np.asarray(opts.initial_pose[1], float).reshape(3))
    else:
        R0, t0_vec = _initial_pose(opts.init, K, Kf, u, umf, um, opts.essential_threshold_px,
                                   opts.seed)
    timings["initial"] = time.perf_counter() - t0

    size = (int(image_size[0]), int(image_size[1]))
    cam_real = cameras.Camera(matrix=K, dist=np.zeros(5), size=size, rvec=np.zeros(3),
                              tvec=np.zeros(3), name="real")
    cam_virt = cameras.Camera(matrix=Kf, dist=np.zeros(5), size=size,
                              rvec=cv2.Rodrigues(np.asarray(R0, float))[0].ravel(),
                              tvec=np.asarray(t0_vec, float), name="mirror_flipped")
    group = cameras.CameraGroup([cam_real, cam_virt])
    p2ds = np.stack([u, umf]).astype(np.float64)          # (2, N, 2)
    state = np.random.get_state()
    np.random.seed(opts.seed)
    t0 = time.perf_counter()
    try:
        error = group.bundle_adjust_iter(
            p2ds, n_iters=opts.n_iters, start_mu=opts.start_mu, end_mu=opts.end_mu,
            max_nfev=opts.max_nfev, ftol=opts.ftol, n_samp_iter=opts.n_samp_iter,
            n_samp_full=opts.n_samp_full, error_threshold=opts.error_threshold,
            only_extrinsics=opts.only_extrinsics, verbose=opts.verbose)
    finally:
        np.random.set_state(state)
    timings["bundle_adjust"] = time.perf_counter() - t0

    R_r = cv2.Rodrigues(group.cameras[0].get_rotation())[0]
    t_r = group.cameras[0].get_translation()
    R_v = cv2.Rodrigues(group.cameras[1].get_rotation())[0]
    t_v = group.cameras[1].get_translation()
    R = R_v @ R_r.T                                       # relative to the real camera
    t = t_v - R @ t_r
    norm = np.linalg.norm(t)
    if not np.isfinite(norm) or norm < 1e-12:
        raise DegenerateGeometryError("aniposelib returned a zero baseline")
    t = t / norm
    n = geo.D_FLIP @ t
    X = np.full((T, J, 3), np.nan)
    X[ok] = triangulate_virtual(K, R, t, u, um)
    return AniposeResult(rotation=R, translation=t, normal=n, initial_rotation=np.asarray(R0),
                         initial_translation=np.asarray(t0_vec) / np.linalg.norm(t0_vec),
                         error=float(error), joints3d=X, camera_group=group, timings=timings)


def calibrate_anipose_paired(paired, K: np.ndarray, *, min_confidence: float = 0.0,
                             joints: np.ndarray | None = None,
                             options: AniposeOptions | None = None) -> AniposeResult:
    """:func:`calibrate_anipose` on a :class:`~mirrorgraph.keypoints.PairedKeypoints`."""
    if paired.image_size is None:
        raise ValueError("the aniposelib baseline needs the image width (paired.image_size)")
    joints = paired.skeleton.calibration_joints if joints is None else joints
    return calibrate_anipose(paired.real, paired.mirror, K, paired.image_size,
                             valid=paired.valid(min_confidence), joints=joints,
                             options=options)
