"""Already paired keypoints in a NumPy ``.npz`` archive.

Arrays (names are the keys of the archive):

* ``real``: ``(T, J, 3)`` float, the person seen directly: x px, y px, confidence.
* ``mirror``: ``(T, J, 3)`` float, the reflection, same layout.
* ``frame_ids``: ``(T,)`` int, optional (default ``0 .. T-1``).
* ``skeleton``: 0-d str, optional (default: from J).
* ``image_size``: ``(2,)`` int ``(width, height)`` px, optional.
* ``fps``: 0-d float, optional.
* ``mirror_flipped``: 0-d bool, optional, default ``False``: ``mirror`` holds the
  detector's own labels of the reflection (as every other format does) and is
  flipped on reading with :attr:`Skeleton.flip`; if ``True`` the labels are
  already those of the real joints.

Missing joints have confidence 0 and ``NaN`` (or any finite) coordinates; any
other non-finite value is refused. This is mirrorgraph's own format, not a
detector's: a negative confidence is refused, confidences in ``(1, 1.5]`` are
clipped to 1 (counted in ``read_notes``), larger ones refused. Rows are sorted
by frame id on reading.
"""

from __future__ import annotations

import os
import re
import warnings
from typing import Any

import numpy as np

from ..errors import InputError
from ..keypoints import PairedKeypoints
from ..skeleton_guess import guess_skeleton
from ..skeletons import Skeleton, known_counts, skeletons_for_count
from ._common import (MAX_IMAGE_SIDE, NPZ_SCORES, Tally, check_frame_ids, clean_keypoints,
                      to_skeleton)
from .atomic import atomic_path

FORMAT = "npz"


def read_paired_npz(path: str | os.PathLike, *,
                    skeleton: Skeleton | str | None = None) -> PairedKeypoints:
    """Read a paired ``.npz`` (see the module docstring) into :class:`PairedKeypoints`."""
    src = str(path)
    arrays = _load_arrays(path, src)
    real, mirror = (_keypoints(arrays, k, src) for k in ("real", "mirror"))
    if real.shape != mirror.shape:
        raise InputError(f"shape {mirror.shape} differs from real {real.shape}",
                         source=src, field="mirror")
    T, J = real.shape[:2]
    if T == 0:
        raise InputError("holds no frames", source=src, field="real")
    skel = _skeleton(arrays, skeleton, J, src)
    ids = _frame_ids(arrays, T, src)
    frame_ids, order = check_frame_ids(ids, source=src)
    tally = Tally()
    real = clean_keypoints(real[order], source=src, frame=None, field="real",
                           policy=NPZ_SCORES, tally=tally, frames=frame_ids)
    mirror = clean_keypoints(mirror[order], source=src, frame=None, field="mirror",
                             policy=NPZ_SCORES, tally=tally, frames=frame_ids)
    if skel is None:
        skel = guess_skeleton(skeletons_for_count(J), np.concatenate([real, mirror]), source=src)
    if not _flag(arrays, "mirror_flipped", src):
        mirror = mirror[:, skel.flip]
    return PairedKeypoints(skeleton=skel, frame_ids=frame_ids, real=real, mirror=mirror,
                           source=src, format=FORMAT, image_size=_image_size(arrays, src),
                           fps=_fps(arrays, src), frames_read=T, read_notes=tally.notes())


def write_paired_npz(paired: PairedKeypoints, path: str | os.PathLike, *,
                     mirror_flipped: bool = False) -> None:
    """Write :class:`PairedKeypoints` to ``path`` atomically (compressed ``.npz``).

    With ``mirror_flipped=False`` the mirror array is stored with the detector's
    labels (``paired.mirror[:, skeleton.flip]``), the inverse of the reader.
    """
    flip = paired.skeleton.flip
    arrays: dict[str, np.ndarray] = {
        "real": np.asarray(paired.real, dtype=float),
        "mirror": np.asarray(paired.mirror if mirror_flipped else paired.mirror[:, flip],
                             dtype=float),
        "frame_ids": np.asarray(paired.frame_ids, dtype=np.int64),
        "skeleton": np.array(paired.skeleton.name),
        "mirror_flipped": np.array(bool(mirror_flipped)),
    }
    if paired.image_size is not None:
        arrays["image_size"] = np.asarray(paired.image_size, dtype=np.int64)
    if paired.fps is not None:
        arrays["fps"] = np.array(float(paired.fps))
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)


def _load_arrays(path: str | os.PathLike, src: str) -> dict[str, np.ndarray]:
    """Every array of the archive; InputError for anything that is not a readable one.

    A damaged archive makes NumPy and ``zipfile`` fail in many ways (``BadZipFile``,
    ``ValueError``, ``EOFError``, ``NotImplementedError`` for a garbled compression
    method, ``tokenize.TokenError`` or ``SyntaxError`` for a garbled array header, ...)
    and warn while parsing a header; all of it means "not a readable .npz".
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # open the file here: np.load leaves its own handle open when the zip is corrupt
            with open(path, "rb") as fh:
                z = np.load(fh, allow_pickle=False)
                if not isinstance(z, np.lib.npyio.NpzFile):
                    raise InputError("not an .npz archive (a single .npy array)", source=src)
                with z:
                    return {k: _member(z, k, src) for k in z.files}
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError("no such file", source=src) from None
    except Exception as e:  # noqa: BLE001 - see the docstring
        raise InputError(f"not a readable .npz archive ({_reason(e)})", source=src) from None


def _member(z: Any, key: str, src: str) -> np.ndarray:
    try:
        return z[key]
    except Exception as e:  # noqa: BLE001 - as in _load_arrays
        raise InputError(f"unreadable array ({_reason(e)})", source=src, field=key) from None


def _reason(e: Exception) -> str:
    """One line: the exception's type and text, without object addresses."""
    text = _ADDRESS.sub("...", " ".join(str(e).split()))
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


_ADDRESS = re.compile(r"<[^<>]* at 0x[0-9a-fA-F]+>")


def _keypoints(arrays: dict, key: str, src: str) -> np.ndarray:
    if key not in arrays:
        raise InputError("missing", source=src, field=key)
    a = arrays[key]
    if a.dtype.kind not in "iuf" or a.ndim != 3 or a.shape[2] != 3:
        raise InputError(f"expected a (T, J, 3) float array, got {a.dtype} {a.shape}",
                         source=src, field=key)
    return a.astype(float)


def _skeleton(arrays: dict, option: Skeleton | str | None, J: int, src: str) -> Skeleton | None:
    """The layout named by the option or the file, or the one of ``J`` keypoints;
    ``None`` where several layouts have ``J`` (see :func:`guess_skeleton`)."""
    skel = to_skeleton(option, source=src)
    if "skeleton" in arrays:
        a = arrays["skeleton"]
        if a.dtype.kind != "U" or a.ndim != 0:
            raise InputError(f"expected a string, got {a.dtype} {a.shape}", source=src,
                             field="skeleton")
        stored = to_skeleton(str(a[()]), source=src)
        if skel is not None and skel.name != stored.name:
            raise InputError(f"file says {stored.name}, option says {skel.name}", source=src,
                             field="skeleton")
        skel = stored
    if skel is None:
        found = skeletons_for_count(J)
        if not found:
            raise InputError(f"{J} keypoints match no known skeleton ({known_counts()})",
                             source=src, field="real")
        if len(found) > 1:
            return None          # ambiguous: decided from the cleaned keypoints
        skel = found[0]
    if skel.num_joints != J:
        raise InputError(f"{J} keypoints, but skeleton {skel.name} has {skel.num_joints}",
                         source=src, field="real")
    return skel


def _frame_ids(arrays: dict, T: int, src: str) -> np.ndarray:
    if "frame_ids" not in arrays:
        return np.arange(T)
    a = arrays["frame_ids"]
    if a.dtype.kind not in "iu" or a.shape != (T,):
        raise InputError(f"expected ({T},) integers, got {a.dtype} {a.shape}", source=src,
                         field="frame_ids")
    return a


def _flag(arrays: dict, key: str, src: str) -> bool:
    if key not in arrays:
        return False
    a = arrays[key]
    if a.ndim != 0 or a.dtype.kind not in "biu" or a[()] not in (0, 1):
        raise InputError(f"expected a scalar bool, got {a.dtype} {a.shape}", source=src,
                         field=key)
    return bool(a[()])


def _image_size(arrays: dict, src: str) -> tuple[int, int] | None:
    if "image_size" not in arrays:
        return None
    a = arrays["image_size"]
    ok = (a.shape == (2,) and a.dtype.kind in "iuf" and np.isfinite(a).all()
          and (a > 0).all() and (a <= MAX_IMAGE_SIDE).all() and (a == np.round(a)).all())
    if not ok:
        raise InputError(f"expected (width, height) positive integers up to {MAX_IMAGE_SIDE}, "
                         f"got {a!r}", source=src, field="image_size")
    return int(a[0]), int(a[1])


def _fps(arrays: dict, src: str) -> float | None:
    if "fps" not in arrays:
        return None
    a = arrays["fps"]
    if a.size != 1 or a.dtype.kind not in "iuf" or not np.isfinite(a).all() or a.item() <= 0:
        raise InputError(f"expected a positive number, got {a!r}", source=src, field="fps")
    return float(a.item())
