"""Camera files for Pose2Sim and aniposelib: a mirror calibration as a two-camera rig, a rig
with every camera and (optionally) every view through a mirror.

The real camera and the mirror's virtual camera are written as two ordinary cameras of a
Pose2Sim ``Calib.toml`` or an aniposelib ``calibration.toml``
(:mod:`mirrorgraph.io.camera_toml`), so that those tools triangulate the person from the
direct view and the reflection and get mirrorgraph's own 3D joints back.

The flip: a mirror view is a left-handed camera, ``u = pi(K D (R X + t))`` with
``D = diag(-1, 1, 1)``, ``R = D (I - 2 n n^T)``, ``t = 2 d D n``
(:mod:`mirrorgraph.geometry`). Mirroring the image, ``u' = W - u`` (``W`` the image width
in pixels), makes it an ordinary right-handed camera with the same ``R``, ``t`` and

    K' = [[fx, -s, W - cx], [0, fy, cy], [0, 0, 1]],

and lens distortion with ``p2, s1, s2, tauY`` negated (:func:`flip_distortion`); the flip
is exact on the raw (distorted) pixels. The mirror camera's keypoints are the
reflection's with ``x -> W - x`` and left/right labels swapped
(:func:`flip_mirror_keypoints`); the real view is the first camera.

World frame: ``world="camera"`` (default) is the real camera frame (x right, y down,
z forward; the real camera ``R = I, t = 0``); ``world="z_up"`` is ``(x, z, -y)`` of it,
what Pose2Sim's OpenSim steps assume. Translations in metres with a metric scale, else in
units of the mirror distance (:func:`export_calibration` warns).

The derivation of ``K'`` and of the distortion's signs, and what users do with their
keypoints: ``docs/internals.md`` and ``docs/guide/exports.md``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import geometry as geo
from ._version import __version__
from .result.mirror import Calibration, read_calibration
from .errors import InputError
from .intrinsics import check_size
from .io.camera_toml import TomlCamera, rotation_to_rodrigues, write_camera_toml
from .skeletons import Skeleton, skeleton_by_name

if TYPE_CHECKING:
    from .result.rig import RigCalibration

__all__ = ["FORMATS", "WORLD_FRAMES", "camera_sections", "export_calibration",
           "export_cameras", "flip_camera_matrix", "flip_distortion", "flip_mirror_keypoints",
           "flipped_mirror_camera", "rig_cameras", "world_rotation", "write_rig_toml"]

#: Export formats: ``--to`` values and the camera-file style each writes.
FORMATS = {"pose2sim": "pose2sim", "anipose": "anipose", "aniposelib": "anipose"}

#: ``world=`` choices and the rotation ``A`` with ``X_world = A X_camera``.
WORLD_FRAMES = {
    "camera": np.eye(3),
    "z_up": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}

#: Distortion coefficient indices (OpenCV order) that change sign under ``x -> -x``:
#: ``p2``, ``s1``, ``s2``, ``tauY``.
FLIPPED_DISTORTION_TERMS = (3, 8, 9, 13)

_KEYS = {"pose2sim": (("cam_01", "cam_01"), ("cam_02", "cam_02")),
         "anipose": (("cam_0", "real"), ("cam_1", "mirror"))}


def camera_sections(fmt: str) -> tuple[tuple[str, str], tuple[str, str]]:
    """``((section, name) of the real camera, (section, name) of the mirror camera)`` as
    :func:`export_calibration` writes them for ``fmt``.

    Example:
        >>> camera_sections("pose2sim")
        (('cam_01', 'cam_01'), ('cam_02', 'cam_02'))
        >>> camera_sections("anipose")
        (('cam_0', 'real'), ('cam_1', 'mirror'))
    """
    style = FORMATS.get(str(fmt).lower())
    if style is None:
        raise InputError(f"unknown export format {fmt!r}; choose one of {', '.join(FORMATS)}",
                         field="fmt")
    return _KEYS[style]

_HEADER = """\
Written by mirrorgraph {version} from {source}.
Two cameras: {real} = the real camera, {mirror} = the mirror's virtual camera as the camera
that sees the HORIZONTALLY FLIPPED image (x -> {W} - x); both are ordinary right-handed
OpenCV cameras. World frame: {world}.
Translation unit: {unit}.
Keypoints for {real}: the person as detected, unchanged.
Keypoints for {mirror}: the reflection with x -> {W} - x (y and confidence unchanged) AND
left/right labels swapped (the detector's right_wrist of the reflection -> left_wrist),
or the reflection detected on the horizontally flipped video, labels as they come.
"""


# --------------------------------------------------------------------------- flips
def flip_camera_matrix(K: np.ndarray, width: float) -> np.ndarray:
    """Camera matrix of the horizontally flipped image, ``K' = F K D``.

    Args:
        K: ``(3, 3)`` camera matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``.
        width: image width ``W`` in pixels (the flip is ``u' = W - u``).

    Returns:
        ``(3, 3)`` ``[[fx, -s, W - cx], [0, fy, cy], [0, 0, 1]]``.
    """
    K = np.asarray(K, dtype=float)
    F = np.array([[-1.0, 0.0, float(width)], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return F @ K @ geo.D_FLIP


def flip_distortion(dist: np.ndarray | None) -> np.ndarray:
    """OpenCV distortion coefficients of the horizontally flipped image.

    Negates the terms odd in ``x``: ``p2`` (index 3), ``s1``, ``s2`` (8, 9) and
    ``tauY`` (13), where present (see the module docstring for the derivation).

    Args:
        dist: ``(k,)`` coefficients in OpenCV order, or ``None`` (no distortion).

    Returns:
        ``(k,)`` float coefficients (``(0,)`` for ``None``).
    """
    d = np.zeros(0) if dist is None else np.array(dist, dtype=float).ravel()
    for i in FLIPPED_DISTORTION_TERMS:
        if i < d.size:
            d[i] = -d[i]
    return d


def flipped_mirror_camera(key: str, name: str, K: np.ndarray, dist: np.ndarray | None,
                          size: tuple[int, int], R: np.ndarray, t: np.ndarray) -> TomlCamera:
    """The camera file's section of a mirror's virtual camera, in the flipped image.

    The one construction of :func:`export_cameras` (one camera and its mirror) and of
    :func:`mirrorgraph.export.rig_cameras` (every camera and mirror of a
    rig): the virtual camera of the horizontally flipped image (a proper rotation, see
    the module docstring), ``K' = F K D`` (:func:`flip_camera_matrix`) and the flipped
    distortion (:func:`flip_distortion`).

    Args:
        key, name: the section's key and ``name``.
        K: ``(3, 3)`` the real camera's matrix; dist: its OpenCV coefficients or ``None``.
        size: ``(W, H)`` px (``W`` fixes the flip).
        R, t: ``(3, 3)``, ``(3,)``: world -> virtual camera of the flipped image.

    Returns:
        The :class:`~mirrorgraph.io.camera_toml.TomlCamera` (4 zero coefficients for
        a lens without distortion).
    """
    d = flip_distortion(dist)
    return TomlCamera(key=key, name=name, matrix=flip_camera_matrix(K, size[0]),
                      distortions=d if d.size else np.zeros(4), size=size,
                      rotation=rotation_to_rodrigues(np.asarray(R, float)),
                      translation=np.asarray(t, float).copy())


def flip_mirror_keypoints(keypoints: np.ndarray, image_width: float,
                          skeleton: Skeleton | str | np.ndarray) -> np.ndarray:
    """The reflection's keypoints as the flipped mirror camera sees them.

    Applies the recipe of the module docstring: ``x -> W - x`` and the
    left/right labels swapped, so that the keypoints can be given to Pose2Sim or
    aniposelib as the views of the exported mirror camera.

    Args:
        keypoints: ``(..., J, 2)`` or ``(..., J, 3)`` (x, y[, confidence]) of the
            reflection, in the detector's labels, raw pixels (with distortion).
        image_width: ``W``, pixels.
        skeleton: the layout (a :class:`~mirrorgraph.skeletons.Skeleton` or its
            name), or the ``(J,)`` left/right permutation itself.

    Returns:
        New ``(..., J, 2|3)`` array: entry ``j`` holds the detector's joint
        ``flip[j]`` with ``x`` mirrored. Missing joints (NaN, or confidence
        ``<= 0``, e.g. OpenPose's ``0, 0, 0``) are moved but left as they were.
    """
    kp = np.array(keypoints, dtype=float)
    if kp.ndim < 2 or kp.shape[-1] not in (2, 3):
        raise ValueError(f"keypoints must have shape (..., J, 2|3), got {kp.shape}")
    if isinstance(skeleton, str):
        skeleton = skeleton_by_name(skeleton)
    perm = skeleton.flip if isinstance(skeleton, Skeleton) else np.asarray(skeleton, dtype=int)
    if perm.shape != (kp.shape[-2],):
        raise ValueError(f"{kp.shape[-2]} joints, but the left/right map has {perm.shape}")
    out = kp[..., perm, :].copy()
    seen = np.isfinite(out[..., 0])
    if out.shape[-1] == 3:
        seen &= out[..., 2] > 0
    out[..., 0] = np.where(seen, float(image_width) - out[..., 0], out[..., 0])
    return out


def world_rotation(world: str) -> np.ndarray:
    """``(3, 3)`` rotation ``A`` of ``X_world = A X_camera`` for a ``world=`` choice."""
    if world not in WORLD_FRAMES:
        raise InputError(f"unknown world frame {world!r}; choose one of "
                         f"{', '.join(WORLD_FRAMES)}", field="world")
    return WORLD_FRAMES[world].copy()


# --------------------------------------------------------------------------- input
# --------------------------------------------------------------------------- export
def _style_distortion(d: np.ndarray, style: str, warnings: list[str]) -> np.ndarray:
    """Coefficient vector in the length each tool writes (values unchanged)."""
    # Pose2Sim writes (k1, k2, p1, p2), aniposelib (k1, k2, p1, p2, k3): shorter vectors
    # are padded with zeros, longer ones cut when the extra terms are zero and otherwise
    # kept whole (both tools undistort with OpenCV, which takes 4, 5, 8, 12 or 14).
    n = 4 if style == "pose2sim" else 5
    if d.size <= n or not np.any(d[n:]):
        return np.pad(d[:n], (0, n - d[:n].size))
    if style == "pose2sim":
        return d
    warnings.append(f"the lens has {d.size} distortion coefficients; aniposelib's "
                    "undistortion uses OpenCV (all of them) but its own projection only the "
                    "first 5 (k1, k2, p1, p2, k3)")
    return d


def _as_rig(calibration) -> tuple["RigCalibration", str | None, bool]:
    """``(rig, source path or None, whether it is a single mirror)`` of any calibration:
    a single mirror's (object, parsed ``calibration.json`` or its path) as the rig of one
    camera and one mirror (:meth:`~mirrorgraph.result.rig.RigCalibration.from_mirror`),
    a rig's as it is (object, parsed rig JSON or its path)."""
    from .io._common import load_json
    from .result.rig import RigCalibration, is_rig_document, read_rig_calibration

    source = str(calibration) if isinstance(calibration, (str, os.PathLike)) else None
    if isinstance(calibration, RigCalibration):
        return calibration, source, False
    obj = load_json(calibration) if source is not None else calibration
    if is_rig_document(obj):
        rig = read_rig_calibration(obj if source is None else calibration)
        return rig, source, False
    return RigCalibration.from_mirror(read_calibration(
        calibration if source is not None else obj)), source, True


def rig_cameras(rig: "RigCalibration", style: str = "pose2sim", *, world: str = "camera",
                with_virtual: bool = True, keys: tuple | None = None,
                image_size: tuple[int, int] | None = None,
                warnings: list[str] | None = None) -> list[TomlCamera]:
    """The cameras of a camera file for any calibration seen as a rig: every real camera
    (a failed one left out, :attr:`~mirrorgraph.result.rig.RigCamera.status`), then (``with_virtual``) every camera's view through every mirror it sees as the camera
    of the horizontally flipped image (:func:`flipped_mirror_camera`, extrinsics
    :func:`mirrorgraph.result.rig.virtual_extrinsics`). The one construction behind
    :func:`export_cameras` and :func:`mirrorgraph.export.write_rig_toml`.

    Args:
        rig: the calibration (a single mirror: :meth:`RigCalibration.from_mirror`).
        style: ``"pose2sim"`` or ``"anipose"``: section keys and distortion lengths.
        world: a :data:`WORLD_FRAMES` name: the world is the first camera's frame rotated.
        with_virtual: also the mirror views.
        keys: ``((key, name) of the first camera, (key, name) of its first mirror view)``
            (a single mirror's :func:`camera_sections`); default: the names, keys
            ``<camera>`` / ``<camera>_<mirror>`` (Pose2Sim) or ``cam_<i>`` (aniposelib).
        image_size: ``(W, H)`` px for cameras without one.
        warnings: appended to (distortion terms a tool ignores).

    Raises:
        InputError: a camera without an image size (the flip and the file need it).
    """
    from .result.rig import virtual_extrinsics

    warnings = [] if warnings is None else warnings
    At = world_rotation(world).T                # world -> first camera: X_cam = A^T X_world
    views = [(c, None) for c in rig.cameras if c.status != "failed"]
    if with_virtual:
        views += [(rig.camera(cname), m) for m in rig.mirrors for cname in m.seen_by
                  if rig.camera(cname).status != "failed"]
    out = []
    for i, (c, m) in enumerate(views):
        size = c.intrinsics.image_size if image_size is None else image_size
        if size is None:
            raise InputError(f"camera {c.name} has no image size, needed to write it (and to "
                             "flip its mirror views, u -> W - u)", field="image_size")
        name = c.name if m is None else f"{c.name}_{m.name}"
        if keys is not None:
            key, name = keys[0] if m is None else keys[1]
        else:
            key = f"cam_{i}" if style == "anipose" else name
        dist = None if c.intrinsics.dist is None else np.asarray(c.intrinsics.dist, float)
        if m is None:
            cam = TomlCamera(key=key, name=name, matrix=c.intrinsics.K.copy(),
                             distortions=_style_distortion(
                                 np.zeros(0) if dist is None else dist.copy(), style, warnings),
                             size=size, rotation=rotation_to_rodrigues(c.R @ At),
                             translation=c.t + 0.0)
        else:
            R, t = virtual_extrinsics(c.pose, m.normal, m.distance)
            cam = flipped_mirror_camera(key, name, c.intrinsics.K, dist, size, R @ At, t)
            cam.distortions = _style_distortion(cam.distortions, style, [])
        out.append(cam)
    return out


def _export(calibration, fmt, world, image_size):
    style = FORMATS.get(str(fmt).lower())
    if style is None:
        raise InputError(f"unknown export format {fmt!r}; choose one of "
                         f"{', '.join(FORMATS)}", field="format")
    world_rotation(world)
    rig, source, single = _as_rig(calibration)
    if image_size is None and any(c.intrinsics.image_size is None for c in rig.cameras):
        raise InputError("the image size is needed to flip the mirror view (u -> W - u) but "
                         "the calibration has none: give image_size=(W, H)",
                         source=source, field="intrinsics.image_size")
    size = None if image_size is None else check_size(image_size[0], image_size[1], source,
                                                       "image_size")
    warnings: list[str] = []
    metric = rig.scale == "subject_height"
    if not metric:
        unit = "the mirror distance (d = 1)" if single else "the subject's height"
        warnings.append(f"the calibration has no metric scale: translations are in units of "
                        f"{unit}, not metres; calibrate with a subject height for metres")
    if any(c.intrinsics.approximate for c in rig.cameras):
        warnings.append("the intrinsics are approximate (a field-of-view guess, or a focal "
                        "length the data do not determine): "
                        + ("both cameras are" if single else "the cameras without a camera "
                           "matrix are") + " approximate, and so is what the tools triangulate")
    cameras = rig_cameras(rig, style, world=world, keys=_KEYS[style] if single else None,
                          image_size=size, warnings=warnings)
    return cameras, warnings, style, metric, source, single


def export_cameras(calibration: Calibration | Mapping | str | os.PathLike, fmt: str, *,
                   world: str = "camera", image_size: tuple[int, int] | None = None
                   ) -> tuple[list[TomlCamera], list[str]]:
    """The real and the flipped mirror camera, ready for :func:`export_calibration`.

    Args:
        calibration: a ``calibration.json`` path, its parsed dict, or a
            :class:`~mirrorgraph.result.mirror.Calibration`.
        fmt: ``"pose2sim"`` or ``"anipose"`` (alias ``"aniposelib"``): section
            keys, names and distortion vector lengths follow that tool.
        world: ``"camera"`` (world = real camera frame) or ``"z_up"`` (see the
            module docstring).
        image_size: ``(width, height)`` px, overriding the calibration's
            ``intrinsics.image_size`` (the width fixes the flip).

    Returns:
        ``([real, mirror], warnings)``: the two cameras (Rodrigues rotation,
        translation in metres or mirror-distance units) and doubts in words.

    Raises:
        InputError: unknown ``fmt`` or ``world``, malformed calibration (naming the
            file and field), or no image size.
    """
    cameras, warnings, *_ = _export(calibration, fmt, world, image_size)
    return cameras, warnings


def export_calibration(calibration: Calibration | Mapping | str | os.PathLike, fmt: str,
                       out_path: str | os.PathLike, *, world: str = "camera",
                       image_size: tuple[int, int] | None = None) -> list[str]:
    """Write the real and the (flipped) mirror camera as a Pose2Sim or aniposelib file.

    The file is a Pose2Sim ``Calib.toml`` (``fmt="pose2sim"``: sections
    ``[cam_01]`` real, ``[cam_02]`` mirror, ``size`` as floats, ``fisheye =
    false``) or an aniposelib ``calibration.toml`` (``fmt="anipose"``: ``[cam_0]``
    named ``"real"``, ``[cam_1]`` named ``"mirror"``, 5 distortion
    coefficients), each ending with ``[metadata] adjusted = false, error = 0.0``,
    with a comment header that states the keypoint recipe. Written atomically.

    The mirror camera is the camera of the horizontally flipped image: rotation
    ``R = D (I - 2 n n^T)``, translation ``t = 2 d D n`` and camera matrix
    ``K' = [[fx, -s, W - cx], [0, fy, cy], [0, 0, 1]]``, distortion with
    ``p2, s1, s2, tauY`` negated (module docstring). Give it the reflection's
    keypoints through :func:`flip_mirror_keypoints`.

    Args:
        calibration: a ``calibration.json`` path, its parsed dict, or a
            :class:`~mirrorgraph.result.mirror.Calibration`.
        fmt: ``"pose2sim"`` or ``"anipose"`` (alias ``"aniposelib"``).
        out_path: the ``.toml`` file to write.
        world: ``"camera"`` (default; triangulation gives mirrorgraph's
            ``joints3d``) or ``"z_up"`` (X right, Y depth, Z up: for Pose2Sim's
            OpenSim steps).
        image_size: ``(width, height)`` px if the calibration has none.

    Returns:
        Warnings in words (no metric scale, approximate intrinsics, ...), to be
        shown to the user; empty when there is nothing to say.

    Raises:
        InputError: see :func:`export_cameras`.

    Example:
        >>> warnings = export_calibration("calibration.json", "pose2sim",
        ...                               "Calib.toml")        # doctest: +SKIP
    """

    cameras, warnings, style, metric, source, single = _export(calibration, fmt, world,
                                                               image_size)
    where = {"camera": "the real camera frame (x right, y down, z forward)",
             "z_up": "X right, Y forward (depth), Z up (camera (x, z, -y))"}[world]
    name = Path(source).name if source else "a calibration in memory"
    if single:
        real, mirror = cameras
        header = _HEADER.format(
            version=__version__, source=name, real=real.key, mirror=mirror.key,
            W=f"{real.size[0]:d}", world=where,
            unit="metres" if metric else "mirror distance (scale unknown)")
    else:
        header = _rig_header(name, cameras[0].name, where, metric)
    write_camera_toml(out_path, cameras, style, header=header)
    return warnings


def _rig_header(source: str, first: str, world: str, metric: bool) -> str:
    """The comment header of a rig's camera file."""
    unit = "metres" if metric else "subject heights (no subject height given: NOT metres)"
    return (f"Written by mirrorgraph {__version__} from {source}: every camera, then every\n"
            "camera's view through a mirror, section <camera>_<mirror> (aniposelib: cam_<i>),\n"
            "as the camera of the HORIZONTALLY FLIPPED image (u -> W - u): give it the\n"
            "reflection's keypoints flipped the same way, left/right labels swapped.\n"
            f"World frame: {world} of camera {first}. Translation unit: {unit}.")


def write_rig_toml(calib: "RigCalibration", path: str | os.PathLike, *,
                   with_virtual: bool = False) -> None:
    """Write Pose2Sim's ``calibration.toml`` of a rig (atomically): one section per camera
    named after it, ``name``, ``size``, ``matrix``, ``distortions`` (as given),
    ``rotation`` (Rodrigues) and ``translation`` of the world-to-camera transform, the
    first camera's frame the world (:func:`rig_cameras`). With ``with_virtual`` every
    camera's view through a mirror follows as the camera of the horizontally flipped
    image, section ``<camera>_<mirror>``. Translations in metres with a subject height,
    else in subject heights (the header says which); ``[metadata] error`` the cameras'
    mean reprojection RMS.

    Raises:
        InputError: a camera without an image size (Pose2Sim needs it).
    """
    cams = rig_cameras(calib, "pose2sim", with_virtual=with_virtual)
    rms = [c.reprojection_rms_px for c in calib.cameras
           if np.isfinite(c.reprojection_rms_px) and c.status != "failed"]
    unit = ("metres" if calib.scale == "subject_height"
            else "subject heights (no subject height given: NOT metres)")
    header = (f"Calibrated by mirrorgraph from the people in view ({calib.source}).\n"
              f"World frame: camera {calib.cameras[0].name}. Translation unit: {unit}.")
    if with_virtual:
        header += ("\nSections <camera>_<mirror> are virtual cameras of the horizontally "
                   "flipped image (u -> W - u); give them the reflection's keypoints flipped "
                   "the same way, left/right labels swapped.")
    write_camera_toml(path, cams, "pose2sim", error=float(np.mean(rms)) if rms else 0.0,
                      header=header)

