"""Camera files of Pose2Sim (``Calib.toml``) and aniposelib (``calibration.toml``).

Both tools keep a multi-camera calibration as one TOML table per camera and a
``[metadata]`` table::

    [cam_01]                      # Pose2Sim: cam_01, cam_02, ...; aniposelib: cam_0, cam_1, ...
    name = "cam_01"
    size = [ 1920.0, 1080.0 ]     # [width, height] px (Pose2Sim floats, aniposelib integers)
    matrix = [ [ fx, 0.0, cx ], [ 0.0, fy, cy ], [ 0.0, 0.0, 1.0 ] ]
    distortions = [ k1, k2, p1, p2 ]          # OpenCV order (aniposelib: 5 values)
    rotation = [ rx, ry, rz ]     # Rodrigues vector of the world -> camera rotation
    translation = [ tx, ty, tz ]  # world -> camera translation, metres
    fisheye = false               # Pose2Sim only

    [metadata]
    adjusted = false
    error = 0.0

A camera maps a world point ``X`` to ``X_cam = R X + t`` (``R`` from the
Rodrigues vector) and to the pixel ``K dist(pi(X_cam))`` with OpenCV's
distortion model: an ordinary right-handed pinhole camera. Pose2Sim
(``common.retrieve_calib_params`` / ``computeP``) and aniposelib
(``CameraGroup.load``, ``Camera.load_dict``) read exactly these keys; Pose2Sim
takes every table but ``metadata`` (and its board tables) as a camera, in file
order, aniposelib in sorted key order. The writers here write the keys in the
order those tools write them.

:func:`read_camera_toml` reads either flavour (any table holding a ``matrix``
is a camera); :func:`select_camera` picks one by section key or ``name``.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .toml_writer import write_toml

__all__ = ["TomlCamera", "STYLES", "camera_document", "write_camera_toml", "read_camera_toml",
           "select_camera", "rotation_to_rodrigues", "rodrigues_to_rotation"]

#: Supported flavours: ``"pose2sim"`` (``Calib.toml``) and ``"anipose"`` (aniposelib).
STYLES = ("pose2sim", "anipose")

#: Tables of a Pose2Sim calibration that are not cameras.
_NOT_CAMERAS = ("metadata", "capture_volume", "charuco", "checkerboard")


def rotation_to_rodrigues(R: np.ndarray) -> np.ndarray:
    """``(3,)`` Rodrigues (axis-angle) vector of a ``(3, 3)`` rotation matrix.

    Uses a quaternion conversion, accurate to machine precision also near a
    half-turn (the virtual camera of a mirror facing the camera is close to
    one), where the textbook ``arccos((trace R - 1) / 2)`` formula loses
    precision.
    """
    from scipy.spatial.transform import Rotation    # 0.3-0.8 s to import: at first use

    return Rotation.from_matrix(np.asarray(R, dtype=float)).as_rotvec()


def rodrigues_to_rotation(rvec: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation matrix of a ``(3,)`` Rodrigues vector."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(rvec, dtype=float).reshape(3)).as_matrix()


@dataclass
class TomlCamera:
    """One camera of a Pose2Sim / aniposelib calibration.

    Attributes:
        key: section key (``cam_01``, ``cam_0``, ...).
        name: the camera's ``name``.
        matrix: ``(3, 3)`` camera matrix ``K``, pixels.
        distortions: ``(k,)`` OpenCV distortion coefficients.
        size: ``(width, height)`` px, or ``None`` if the file has none.
        rotation: ``(3,)`` Rodrigues vector of the world -> camera rotation.
        translation: ``(3,)`` world -> camera translation (metres).
        fisheye: Pose2Sim's ``fisheye`` flag (OpenCV fisheye model if true).
        extra: other keys of the section, as read.
    """

    key: str
    name: str
    matrix: np.ndarray
    distortions: np.ndarray
    size: tuple[int, int] | None = None
    rotation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    fisheye: bool = False
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def R(self) -> np.ndarray:
        """``(3, 3)`` world -> camera rotation."""
        return rodrigues_to_rotation(self.rotation)

    @property
    def projection_matrix(self) -> np.ndarray:
        """``(3, 4)`` ``K [R | t]`` (pixels of undistorted points)."""
        return np.asarray(self.matrix, float) @ np.hstack(
            [self.R, np.asarray(self.translation, float).reshape(3, 1)])


def _floats(a: Any) -> list:
    return np.asarray(a, dtype=float).tolist()


def camera_document(cameras: Sequence[TomlCamera], style: str, *,
                    error: float = 0.0) -> dict[str, Any]:
    """The TOML document (a dict) of ``cameras`` in the ``style`` of one tool.

    Args:
        cameras: the cameras, in order; their ``key`` is the section name.
        style: ``"pose2sim"`` (``size`` as floats, a ``fisheye`` flag) or
            ``"anipose"`` (``size`` as integers).
        error: the ``[metadata] error`` value (the tools store their
            calibration's reprojection error there).

    Returns:
        ``{key: {name, size, matrix, distortions, rotation, translation[, fisheye]},
        ..., "metadata": {"adjusted": False, "error": error}}``.
    """
    if style not in STYLES:
        raise InputError(f"unknown camera file style {style!r}; known: {', '.join(STYLES)}",
                         field="style")
    doc: dict[str, Any] = {}
    for cam in cameras:
        if cam.key in doc or cam.key == "metadata":
            raise ValueError(f"duplicate or reserved camera key {cam.key!r}")
        if cam.size is None:
            raise ValueError(f"camera {cam.key!r} has no image size")
        w, h = (int(v) for v in cam.size)
        section: dict[str, Any] = {
            "name": str(cam.name),
            "size": [float(w), float(h)] if style == "pose2sim" else [w, h],
            "matrix": _floats(cam.matrix),
            "distortions": _floats(np.ravel(cam.distortions)),
            "rotation": _floats(np.ravel(cam.rotation)),
            "translation": _floats(np.ravel(cam.translation)),
        }
        if style == "pose2sim":
            section["fisheye"] = bool(cam.fisheye)
        doc[cam.key] = section
    doc["metadata"] = {"adjusted": False, "error": float(error)}
    return doc


def write_camera_toml(path: str | os.PathLike, cameras: Sequence[TomlCamera], style: str, *,
                      error: float = 0.0, header: str | None = None) -> None:
    """Write a Pose2Sim / aniposelib calibration file atomically.

    Args:
        path: output ``.toml`` file.
        cameras: the cameras, in order.
        style: ``"pose2sim"`` or ``"anipose"`` (see :func:`camera_document`).
        error: the ``[metadata] error`` value.
        header: comment lines put at the top of the file (``#``-prefixed; both
            tools' TOML readers ignore comments).
    """
    write_toml(path, camera_document(cameras, style, error=error), header=header)


# --------------------------------------------------------------------------- reading
def read_camera_toml(path: str | os.PathLike) -> dict[str, TomlCamera]:
    """Read the cameras of a Pose2Sim or aniposelib calibration file.

    Every top-level table holding a ``matrix`` is a camera (``metadata`` and
    Pose2Sim's board tables never are). ``distortions`` (default: none),
    ``size``, ``rotation`` and ``translation`` (default: zero) are optional so
    that intrinsics-only files can be read too.

    Returns:
        ``{section key: TomlCamera}`` in file order.

    Raises:
        InputError: naming the file and ``section.field``: missing file,
            malformed TOML, no camera table, values of the wrong shape or type,
            non-finite numbers.
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except FileNotFoundError:
        raise InputError("no such file", source=path) from None
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"malformed TOML ({e})", source=path) from None
    except UnicodeDecodeError:
        raise InputError("malformed TOML (not UTF-8 text)", source=path) from None
    cams: dict[str, TomlCamera] = {}
    for key, sec in doc.items():
        if key in _NOT_CAMERAS or not isinstance(sec, dict) or "matrix" not in sec:
            continue
        cams[key] = _read_section(path, key, sec)
    if not cams:
        raise InputError("no camera table (a [section] with a 'matrix') in the file",
                         source=path)
    return cams


def _array(path: Path, key: str, sec: dict, name: str, shape: tuple[int, ...] | None,
           default: Any = None) -> np.ndarray | None:
    field_name = f"{key}.{name}"
    if name not in sec:
        return default
    value = sec[name]
    try:
        a = np.asarray(value)
    except (ValueError, TypeError):
        a = None
    if a is None or a.dtype.kind not in "iuf":
        raise InputError(f"expected numbers, got {value!r}", source=path, field=field_name)
    a = a.astype(float)
    if shape is not None and a.shape != shape:
        want = "x".join(map(str, shape))
        raise InputError(f"expected {want} numbers, got shape {a.shape}", source=path,
                         field=field_name)
    if shape is None and a.ndim != 1:
        raise InputError(f"expected a list of numbers, got shape {a.shape}", source=path,
                         field=field_name)
    if not np.isfinite(a).all():
        raise InputError("non-finite values", source=path, field=field_name)
    return a


def _read_section(path: Path, key: str, sec: dict) -> TomlCamera:
    K = _array(path, key, sec, "matrix", (3, 3))
    dist = _array(path, key, sec, "distortions", None, default=np.zeros(0))
    size_a = _array(path, key, sec, "size", (2,))
    size = None
    if size_a is not None:
        if not all(v > 0 and float(v).is_integer() for v in size_a):
            raise InputError(f"expected [width, height], two positive whole numbers, got "
                             f"{sec['size']!r}", source=path, field=f"{key}.size")
        size = (int(size_a[0]), int(size_a[1]))
    rvec = _array(path, key, sec, "rotation", (3,), default=np.zeros(3))
    tvec = _array(path, key, sec, "translation", (3,), default=np.zeros(3))
    name = sec.get("name", key)
    if not isinstance(name, (str, int)) or isinstance(name, bool):
        raise InputError(f"expected a string, got {name!r}", source=path, field=f"{key}.name")
    fisheye = sec.get("fisheye", False)
    if not isinstance(fisheye, bool):
        raise InputError(f"expected true or false, got {fisheye!r}", source=path,
                         field=f"{key}.fisheye")
    known = {"name", "size", "matrix", "distortions", "rotation", "translation", "fisheye"}
    return TomlCamera(key=key, name=str(name), matrix=K, distortions=dist, size=size,
                      rotation=rvec, translation=tvec, fisheye=fisheye,
                      extra={k: v for k, v in sec.items() if k not in known})


def select_camera(cameras: dict[str, TomlCamera], camera: str | int | None, *,
                  source: Any = None) -> TomlCamera:
    """Pick one camera by section key or ``name``.

    Args:
        cameras: from :func:`read_camera_toml`.
        camera: a section key (``"cam_01"``), a ``name``, or ``None`` when the file
            holds a single camera.
        source: the file, for error messages.

    Raises:
        InputError: ``camera`` is ``None`` and the file holds several cameras, or
            it matches none (or several names); the message lists the cameras.
    """
    listing = ", ".join(k if c.name == k else f"{k} (name {c.name!r})"
                        for k, c in cameras.items())
    if camera is None:
        if len(cameras) == 1:
            return next(iter(cameras.values()))
        raise InputError(f"holds {len(cameras)} cameras: choose one of {listing}",
                         source=source, field="camera")
    wanted = str(camera)
    if wanted in cameras:
        return cameras[wanted]
    by_name = [c for c in cameras.values() if c.name == wanted]
    if len(by_name) == 1:
        return by_name[0]
    what = "several cameras are named" if by_name else "no camera section or name"
    raise InputError(f"{what} {wanted!r}; cameras: {listing}", source=source, field="camera")

