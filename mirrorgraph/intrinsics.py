"""Pinhole intrinsics of the real camera: loading, approximating, undistorting.

Conventions: pixels, origin at the top-left image corner, x right, y down.
``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` maps normalised camera coordinates
``(X/Z, Y/Z, 1)`` to pixels. Distortion coefficients follow OpenCV's order
``(k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tx, ty]]]])``.

Sources:

* :func:`load_intrinsics`: a JSON file
  ``{"K": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "dist": [k1, k2, p1, p2, k3],
  "image_size": [w, h]}`` (``dist`` and ``image_size`` optional), or an OpenCV
  ``FileStorage`` YAML/XML file with ``camera_matrix``, optional
  ``distortion_coefficients``, ``image_width`` and ``image_height`` (what
  OpenCV's calibration sample writes; YAML files start with ``%YAML``), or a
  ``.toml`` camera file of Pose2Sim (``Calib.toml``: ``[cam_01]`` tables with
  ``matrix``, ``distortions``, ``size``) or aniposelib (``calibration.toml``:
  ``[cam_0]`` tables with ``name``, ``matrix``, ``distortions``, ``size``); pick
  the camera with ``camera=`` (section key or name) when the file holds several.
* :func:`intrinsics_from_fov`: a guess from the image size and a horizontal
  field of view, flagged ``approximate``.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .errors import InputError
from .io._common import MAX_IMAGE_SIDE, json_type, load_json, numeric_array
from .io.camera_toml import read_camera_toml, select_camera

#: Horizontal field of view assumed when no intrinsics are given, degrees. A
#: typical webcam or phone main camera has a horizontal FOV of 55-70 degrees.
DEFAULT_FOV_DEG = 60.0

#: Largest absolute value of an entry of K (focal lengths, principal point, skew), pixels:
#: a 1,000,000 px wide image seen through a 0.6 deg field of view has fx ~ 1e8.
MAX_K_ENTRY = 1e8

#: Lengths OpenCV accepts for distortion coefficient vectors.
DIST_LENGTHS = (4, 5, 8, 12, 14)

_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)


@dataclass
class Intrinsics:
    """Camera matrix, distortion and image size of one camera.

    Attributes:
        K: ``(3, 3)`` float camera matrix, pixels.
        dist: ``(k,)`` float OpenCV distortion coefficients, or ``None`` (none).
        image_size: ``(width, height)`` pixels, if known.
        source: where the values came from (file name or a description).
        approximate: ``True`` when guessed (e.g. from a field of view).
        estimated: where ``K`` was estimated from the data (the focal length from the
            person and the reflection, :mod:`mirrorgraph.graph`), the estimate's record
            (``focal_px``, ``std_px``, ...; ``RefinementResult.focal``); else ``None``.
    """

    K: np.ndarray
    dist: np.ndarray | None = None
    image_size: tuple[int, int] | None = None
    source: str = ""
    approximate: bool = False
    estimated: dict | None = None

    def __post_init__(self) -> None:
        self.K = np.asarray(self.K, dtype=float)
        if self.K.shape != (3, 3):
            raise ValueError(f"K must be 3x3, got shape {self.K.shape}")
        if self.dist is not None:
            self.dist = np.asarray(self.dist, dtype=float).ravel()
        if self.image_size is not None:
            self.image_size = (int(self.image_size[0]), int(self.image_size[1]))

    @property
    def fx(self) -> float:
        """Focal length along x, pixels."""
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        """Focal length along y, pixels."""
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        """Principal point x, pixels."""
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        """Principal point y, pixels."""
        return float(self.K[1, 2])

    @property
    def has_distortion(self) -> bool:
        """Whether any distortion coefficient is non-zero."""
        return self.dist is not None and bool(np.any(self.dist != 0))

    def undistort_points(self, points: np.ndarray) -> np.ndarray:
        """Remove lens distortion from pixel coordinates.

        Args:
            points: ``(..., 2)`` distorted pixel coordinates; rows with a NaN stay NaN.

        Returns:
            ``(..., 2)`` float: where an ideal pinhole camera with the same ``K``
            would image the same rays. A copy of ``points`` without distortion.
        """
        pts = np.array(points, dtype=float)
        if pts.shape[-1:] != (2,):
            raise ValueError(f"points must have shape (..., 2), got {pts.shape}")
        if not self.has_distortion:
            return pts
        flat = pts.reshape(-1, 2)
        ok = np.isfinite(flat).all(axis=1)
        flat[~ok] = np.nan
        if ok.any():
            src = np.ascontiguousarray(flat[ok]).reshape(-1, 1, 2)
            flat[ok] = _cv_undistort(src, self.K, self.dist).reshape(-1, 2)
        return flat.reshape(pts.shape)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form: ``K``, ``dist``, ``image_size``, ``source``, ``approximate``
        (and ``estimated`` where ``K`` was estimated)."""
        out = {"K": self.K.tolist(),
               "dist": None if self.dist is None else self.dist.tolist(),
               "image_size": None if self.image_size is None else list(self.image_size),
               "source": self.source, "approximate": self.approximate}
        if self.estimated is not None:
            out["estimated"] = dict(self.estimated)
        return out


def _cv_undistort(src: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Iterative undistortion to convergence (OpenCV's default stops after 5 steps)."""
    if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4.x
        return cv2.undistortPointsIter(src, K, dist, None, K, _CRITERIA)
    return cv2.undistortPoints(src, K, dist, P=K, criteria=_CRITERIA)


def load_intrinsics(path: str | os.PathLike, camera: str | int | None = None) -> Intrinsics:
    """Read intrinsics from a JSON, OpenCV YAML/XML or TOML file (see the module docstring).

    Args:
        path: the file. A ``.toml`` suffix selects the Pose2Sim / aniposelib
            camera-file reader.
        camera: for TOML files, the camera to read: its section key
            (``"cam_01"``, ``"cam_0"``) or its ``name``. May be left out when
            the file holds one camera. Only the intrinsics (``matrix``,
            ``distortions``, ``size``) are read; the extrinsics are ignored.
            Note that the mirror camera of a file written by
            :func:`mirrorgraph.export.export_calibration` is the *flipped*
            virtual camera (mirrored principal point and tangential terms),
            not the real camera's intrinsics.

    Raises:
        InputError: naming the file and field: missing file, malformed content,
            no or non-3x3 ``K``, non-finite values, last row of ``K`` not
            ``[0, 0, 1]``, ``fx`` or ``fy`` not positive, entries of ``K`` beyond
            ``MAX_K_ENTRY``, singular ``K``, a
            distortion vector of a length OpenCV does not know, image size not
            two positive integers; for TOML also a missing or ambiguous
            ``camera`` (the message lists the cameras of the file) and
            Pose2Sim's ``fisheye = true`` (a lens model mirrorgraph does not use).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("no such file", source=path)
    if path.suffix.lower() == ".toml":
        return _load_toml(path, camera)
    if camera is not None:
        raise InputError("camera= selects a camera of a .toml file; this is not one",
                         source=path, field="camera")
    with open(path, "rb") as f:
        head = f.read(64).lstrip()
    if head.startswith(b"%YAML") or head.startswith(b"<?xml") or \
            path.suffix.lower() in (".yml", ".yaml", ".xml"):
        K, dist, size, key = _read_opencv(path)
    else:
        K, dist, size, key = _read_json(path)
    return Intrinsics(K=check_camera_matrix(K, path, key), dist=check_distortion(dist, path),
                      image_size=size, source=str(path))


def _load_toml(path: Path, camera: str | int | None) -> Intrinsics:
    cam = select_camera(read_camera_toml(path), camera, source=path)
    if cam.fisheye:
        raise InputError("fisheye = true: the OpenCV fisheye lens model is not supported "
                         "(mirrorgraph undistorts with the standard model)", source=path,
                         field=f"{cam.key}.fisheye")
    dist = cam.distortions if cam.distortions.size else None
    if dist is not None and len(dist) not in DIST_LENGTHS:
        raise InputError(f"{len(dist)} distortion coefficients; OpenCV takes "
                         f"{', '.join(map(str, DIST_LENGTHS))}", source=path,
                         field=f"{cam.key}.distortions")
    size = None if cam.size is None else check_size(*cam.size, path, f"{cam.key}.size")
    return Intrinsics(K=check_camera_matrix(cam.matrix, path, f"{cam.key}.matrix"),
                      dist=check_distortion(dist, path), image_size=size,
                      source=f"{path} [{cam.key}]")


def _read_json(path: Path) -> tuple[np.ndarray, np.ndarray | None, tuple[int, int] | None, str]:
    obj = load_json(path)
    if not isinstance(obj, dict):
        raise InputError(f"expected a JSON object, got {json_type(obj)}", source=path)
    if "K" not in obj:
        raise InputError("missing (the 3x3 camera matrix)", source=path, field="K")
    K = numeric_array(obj["K"], 2, source=path, frame=None, field="K")
    dist = obj.get("dist")
    if dist is not None:
        dist = numeric_array(dist, None, source=path, frame=None, field="dist")
    size = obj.get("image_size")
    if size is not None:
        if not (isinstance(size, list) and len(size) == 2):
            raise InputError(f"expected [width, height], got {size!r}", source=path,
                             field="image_size")
        size = check_size(size[0], size[1], path, "image_size")
    return K, dist, size, "K"


def _read_opencv(path: Path) -> tuple[np.ndarray, np.ndarray | None, tuple[int, int] | None, str]:
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as e:
        raise InputError(f"malformed OpenCV YAML/XML ({_cv_message(e)})", source=path) from None
    if not fs.isOpened():
        raise InputError("cannot open as OpenCV YAML/XML", source=path)
    try:
        K = _node_matrix(fs, "camera_matrix", path)
        if K is None:
            raise InputError("missing (the 3x3 camera matrix)", source=path,
                             field="camera_matrix")
        dist = _node_matrix(fs, "distortion_coefficients", path)
        w, h = (_node_int(fs, k, path) for k in ("image_width", "image_height"))
    except (cv2.error, SystemError) as e:  # e.g. a top level that is no map
        raise InputError(f"malformed OpenCV YAML/XML ({_cv_message(e)})", source=path) from None
    except UnicodeDecodeError as e:  # a text node that is not UTF-8
        raise InputError(f"not UTF-8 text ({e.reason})", source=path) from None
    finally:
        fs.release()
    if (w is None) != (h is None):
        raise InputError("image_width and image_height must be given together", source=path,
                         field="image_width" if w is None else "image_height")
    size = None if w is None else check_size(w, h, path, "image_width")
    return K, dist, size, "camera_matrix"


def _node_matrix(fs: Any, key: str, path: Path) -> np.ndarray | None:
    """An ``!!opencv-matrix`` / ``!!opencv-nd-matrix`` or a plain list of numbers.

    The matrix is read here from its ``rows``/``cols`` (or ``sizes``), ``dt`` and ``data``
    rather than with ``FileNode.mat()``, which corrupts memory (and may crash the
    process) on a matrix whose ``cols`` is missing (OpenCV 5.0.0).
    """
    node = fs.getNode(key)
    if node.empty() or node.isNone():
        return None

    def fail(message: str) -> InputError:
        return InputError(message, source=path, field=key)

    try:
        if node.isSeq():
            return _node_numbers(node, fail, "expected a list of numbers")
        if not node.isMap():
            raise fail("expected an !!opencv-matrix or a list of numbers")
        data = node.getNode("data")
        if data.empty() or not data.isSeq():
            raise fail("not an OpenCV matrix: no 'data' list")
        values = _node_numbers(data, fail, "not an OpenCV matrix: 'data' holds no numbers")
        sizes = node.getNode("sizes")
        if not sizes.empty():
            if not sizes.isSeq() or not all(sizes.at(i).isInt() for i in range(sizes.size())):
                raise fail("not an OpenCV matrix: 'sizes' is no list of integers")
            shape = tuple(int(sizes.at(i).real()) for i in range(sizes.size()))
        else:
            shape = tuple(_node_child_int(node, k, fail) for k in ("rows", "cols"))
        dt = node.getNode("dt")
        m = _DT.match(dt.string()) if dt.isString() else None
        if m is None:
            raise fail("not an OpenCV matrix: no 'dt' (a type such as d or f)")
        if m.group(1) not in ("", "1"):
            raise fail(f"not a single-channel OpenCV matrix (dt {dt.string()!r})")
    except (cv2.error, SystemError) as e:
        raise fail(f"not an OpenCV matrix ({_cv_message(e)})") from None
    if any(n < 0 for n in shape) or math.prod(shape) != len(values):
        raise fail(f"not an OpenCV matrix: 'data' holds {len(values)} numbers for "
                   f"shape {shape}")
    return values.reshape(shape)


_DT = re.compile(r"^(\d*)([ucwsifdh])$")


def _node_numbers(node: Any, fail: Any, message: str) -> np.ndarray:
    items = [node.at(i) for i in range(node.size())]
    if not all(v.isInt() or v.isReal() for v in items):
        raise fail(message)
    return np.array([v.real() for v in items], dtype=float)


def _node_child_int(node: Any, key: str, fail: Any) -> int:
    child = node.getNode(key)
    if child.empty() or not child.isInt():
        raise fail(f"not an OpenCV matrix: no '{key}' (an integer)")
    return int(child.real())


def _node_int(fs: Any, key: str, path: Path) -> int | None:
    node = fs.getNode(key)
    if node.empty() or node.isNone():
        return None
    if not node.isInt():
        raise InputError("expected an integer", source=path, field=key)
    return int(node.real())


def _cv_message(e: Exception) -> str:
    """The gist of an OpenCV error: the text after ``error: (-code:kind)``."""
    text = " ".join(str(e.__cause__ or e).split())
    m = re.search(r"error: \([^)]*\) (.*)$", text)
    return m.group(1) if m else text or type(e).__name__


def check_camera_matrix(K: np.ndarray, path: Path, key: str) -> np.ndarray:
    def fail(message: str) -> InputError:
        return InputError(message, source=path, field=key)

    if K.shape != (3, 3):
        raise fail(f"expected a 3x3 matrix, got shape {K.shape}")
    if not np.isfinite(K).all():
        raise fail("non-finite values")
    if not np.allclose(K[2], [0.0, 0.0, 1.0], rtol=0.0, atol=1e-9):
        raise fail(f"last row must be [0, 0, 1], got {K[2].tolist()}")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise fail(f"focal lengths must be positive, got fx={K[0, 0]}, fy={K[1, 1]}")
    if np.abs(K[:2]).max() > MAX_K_ENTRY:
        raise fail(f"values beyond {MAX_K_ENTRY:g} px (fx={K[0, 0]:g}, fy={K[1, 1]:g}) are "
                   "no camera's")
    # determinant of K with its rows divided by fx, fy (no overflow for huge fx, fy)
    with np.errstate(all="ignore"):
        det = np.linalg.det(K / np.array([[K[0, 0]], [K[1, 1]], [1.0]]))
    if not np.isfinite(det) or abs(det) <= 1e-9:
        raise fail("singular camera matrix")
    return K


def check_distortion(dist: np.ndarray | None, path: Path) -> np.ndarray | None:
    if dist is None:
        return None
    dist = dist.ravel()
    if len(dist) not in DIST_LENGTHS:
        raise InputError(f"{len(dist)} distortion coefficients; OpenCV takes "
                         f"{', '.join(map(str, DIST_LENGTHS))}", source=path, field="dist")
    if not np.isfinite(dist).all():
        raise InputError("non-finite values", source=path, field="dist")
    return dist


def check_size(w: Any, h: Any, source: Any, field: str) -> tuple[int, int]:
    ok = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool)
             and 0 < v <= MAX_IMAGE_SIDE for v in (w, h))
    if not ok:
        raise InputError(f"image size must be two positive integers up to {MAX_IMAGE_SIDE}, "
                         f"got {w!r} x {h!r}", source=source, field=field)
    return int(w), int(h)


_SIZE = re.compile(r"^\s*(\d+)\s*[xX,]\s*(\d+)\s*$")


def parse_image_size(value: str | tuple[int, int] | list[int]) -> tuple[int, int]:
    """``"1920x1080"`` (or ``(1920, 1080)``) -> ``(1920, 1080)``; InputError otherwise."""
    if isinstance(value, str):
        m = _SIZE.match(value)
        if m is None:
            raise InputError(f"image size {value!r} is not WIDTHxHEIGHT, e.g. 1920x1080",
                             field="image_size")
        value = (int(m.group(1)), int(m.group(2)))
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise InputError(f"image size {value!r} is not (width, height)", field="image_size")
    return check_size(value[0], value[1], None, "image_size")


def intrinsics_from_fov(image_size: str | tuple[int, int],
                        fov_deg: float = DEFAULT_FOV_DEG) -> Intrinsics:
    """Approximate intrinsics from the image size and a horizontal field of view.

    Square pixels, no skew, no distortion, principal point at the image centre
    ``(w / 2, h / 2)``; ``fx = fy = (w / 2) / tan(fov / 2)``.

    Args:
        image_size: ``(width, height)`` pixels or ``"WIDTHxHEIGHT"``.
        fov_deg: horizontal field of view in degrees, in ``(0, 180)``.
    """
    w, h = parse_image_size(image_size)
    if not (math.isfinite(fov_deg) and 0.0 < fov_deg < 180.0):
        raise InputError(f"field of view {fov_deg} deg is not in (0, 180)", field="fov_deg")
    f = 0.5 * w / math.tan(math.radians(fov_deg) / 2.0)
    K = np.array([[f, 0.0, w / 2.0], [0.0, f, h / 2.0], [0.0, 0.0, 1.0]])
    return Intrinsics(K=K, dist=None, image_size=(w, h), approximate=True,
                      source=f"approximate: {fov_deg:g} deg horizontal field of view")


def estimated_intrinsics(guess: Intrinsics, K: np.ndarray, focal: dict, fov_deg: float,
                         warnings: list[str], camera: str | None = None,
                         user_guess: bool = False) -> Intrinsics:
    """The intrinsics of a run whose focal length (and principal point) were estimated,
    with its warnings.

    The estimate is always kept with its standard deviation (the priors about the guess
    hold the spread of real cameras; nothing is replaced by a guess held exact).

    Args:
        guess: the field-of-view guess the estimate started from.
        K: ``(3, 3)`` the refinement's camera matrix.
        focal: the refinement's record (:attr:`mirrorgraph.graph.RefinementResult.focal`).
        fov_deg: the guess's horizontal field of view, degrees.
        warnings: the run's warnings, appended to.
        camera: the camera's name (a rig's), for the warning.
        user_guess: the guess is the user's (``--fov``): its prior is narrow
            (``FocalOptions.guess_rel_sigma``).

    Returns:
        :class:`Intrinsics` with ``estimated`` set; ``approximate`` where the data do not
        determine the focal length (``focal["determined"]`` false) or the user's guess
        holds it.
    """
    w = guess.image_size[0] if guess.image_size else 2.0 * float(K[0, 2])
    who = "" if camera is None else f"camera {camera}: "
    f, std = float(focal["focal_px"]), float(focal.get("std_px", float("nan")))
    fov = math.degrees(2.0 * math.atan(0.5 * w / f))
    determined = bool(focal.get("determined", focal.get("estimated")))
    prior = focal.get("principal_point_prior_px")
    pp = ("estimated about the image centre with the spread of real cameras "
          f"(+- {prior[2]:.0f} px a coordinate)" if prior else
          "estimated (a loose prior about the centre)") if focal.get(
              "principal_point_estimated") else "assumed at the centre"
    if user_guess:
        warnings.append(
            who + f"no intrinsics: the focal length is held near the {fov_deg:g} deg field "
            f"of view given (+- {100 * focal.get('focal_prior_std_px', 0) / max(f, 1e-9):.0f}% "
            f"spread), {f:.0f} +- {std:.0f} px, the principal point {pp}; their spread is in "
            "every standard deviation; pass --intrinsics FILE if you have them")
    elif not determined:
        und = focal.get("undetermined", {})
        why = []
        if und.get("at_range_end"):
            why.append(f"a {und.get('fov_deg', fov):.0f} deg field of view, at the end of the "
                       "cameras searched")
        if und.get("data_open") is False and und.get("search_px"):
            why.append(f"the bones hold it to {100 * und.get('data_rel_std', 0.0):.0f}%, but the "
                       f"initial search over every bone puts it at {und['search_px']:.0f} px: "
                       "that disagreement is its std")
        if und.get("low_parallax"):
            why.append(f"a joint's two rays meet at a median {und.get('parallax_deg', float('nan')):.0f} "
                       "deg, where the bones that determine it are measured with a bias")
        warnings.append(
            who + f"the focal length is not determined by the data: {f:.0f} +- {std:.0f} px "
            f"({100 * std / f:.0f}%)" + (f" ({'; '.join(why)})" if why else "")
            + ": too little change of the person's depth and pose, a mirror seen nearly "
            "square-on, or joints whose two rays meet at a small angle; the estimate is kept "
            f"(the {fov_deg:g} deg guess is its prior's centre) and its standard deviation is "
            "in the normal's and the distance's; pass --intrinsics FILE")
    elif focal.get("poorly_determined"):
        warnings.append(
            who + f"the focal length is poorly determined ({f:.0f} +- {std:.0f} px, "
            f"{100 * std / f:.0f}%): little change of the person's depth and pose, or "
            "joints whose two rays meet at a small angle; the normal and distance "
            "inherit its error (in their standard deviations); pass --intrinsics FILE if "
            "you have them")
    source = ((f"near the {fov_deg:g} deg field of view given" if user_guess else
               "estimated from the person and the reflection")
              + f": focal {f:.1f} +- {std:.1f} px ({fov:.1f} deg horizontal field of view"
              + ("" if determined or user_guess else ", not determined by the data")
              + f"), square pixels, principal point {pp}")
    return Intrinsics(K=np.asarray(K, float), dist=guess.dist, image_size=guess.image_size,
                      source=source, approximate=bool(user_guess or not determined),
                      estimated=dict(focal))
