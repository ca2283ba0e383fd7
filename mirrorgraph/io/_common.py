"""Helpers shared by the keypoint readers and writers (private).

Every check raises :class:`~mirrorgraph.errors.InputError` naming the file,
frame and field at fault.

Confidence policy. Each format has a :class:`ScorePolicy`: what its tools write
(the reader modules' docstrings say where that was read). Shared by all:

* a confidence must be finite (except a whole joint written ``NaN, NaN, NaN``
  where the policy allows it: Pose2Sim's OpenPose-style files);
* confidence ``0`` is missing, whatever the coordinates (``0, 0, 0`` usually);
* a negative confidence is missing, whatever the coordinates, where the format
  writes it so (EasyMocap's ``[0, 0, -1]``; SimCC scores ``<= 0``), and refused
  elsewhere;
* confidences above 1 are clipped to 1; above the policy's ``max_confidence``
  (``MAX_CONFIDENCE`` = 1.5 for formats whose scores are heat-map probabilities,
  unbounded for SimCC logits) they are refused.

Everything read as missing or clipped is counted (:class:`Tally`, frozen into
:class:`mirrorgraph.keypoints.ReadNotes`).

Coordinate policy: the x, y of a detected joint (confidence > 0) must be finite
and within ``MAX_COORDINATE`` pixels of the origin; larger values are no image
coordinate of any camera (they come from corrupt files) and are refused.
Image sides are at most ``MAX_IMAGE_SIDE`` pixels.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import InputError
from ..keypoints import ReadNotes
from ..skeleton_guess import guess_skeleton
from ..skeletons import Skeleton, known_counts, skeleton_by_name, skeletons_for_count

#: Confidences up to this value are clipped to 1, above it refused, in formats whose
#: scores are heat-map peaks (OpenPose itself writes up to ~1.41: github.com/CMU-Perceptual-Computing-Lab/openpose/issues/615;
#: Mirrored-Human's annotations up to 1.057).
MAX_CONFIDENCE = 1.5

#: Largest absolute pixel coordinate accepted for a detected joint.
MAX_COORDINATE = 1e6

#: Largest image width or height accepted, pixels.
MAX_IMAGE_SIDE = 1_000_000

_TRAILING_INT = re.compile(r"(\d+)\D*$")


def is_video_input(path: str | os.PathLike) -> bool:
    """Whether a keypoint input is a video file (:func:`mirrorgraph.video.reader.is_video`).
    A keypoint file's ending (``.json``, ``.npz``) or a folder never is one: the video
    package (its detector and tracker, ~0.05 s to import) is not imported to ask."""
    p = Path(path)
    if p.suffix.lower() in (".json", ".npz") or p.is_dir():
        return False
    from ..video.reader import is_video
    return is_video(p)


def load_json(path: str | os.PathLike) -> Any:
    """Parse a JSON file; a missing, unreadable or malformed file is an InputError."""
    try:
        with open(path, "rb") as f:
            return json.loads(f.read().decode("utf-8"))
    except FileNotFoundError:
        raise InputError("no such file", source=path) from None
    except json.JSONDecodeError as e:
        raise InputError(f"malformed JSON: {e.msg} (line {e.lineno}, column {e.colno})",
                         source=path) from None
    except UnicodeDecodeError as e:
        raise InputError(f"not UTF-8 text ({e.reason} at byte {e.start})", source=path) from None
    except ValueError as e:  # e.g. an integer literal longer than Python converts
        raise InputError(f"malformed JSON ({e})", source=path) from None
    except RecursionError:
        raise InputError("malformed JSON: nested too deeply", source=path) from None
    except OSError as e:
        raise InputError(f"cannot read ({e.strerror})", source=path) from None


def dump_json(obj: Any) -> str:
    """Compact JSON text (floats round-trip exactly; NaN refused)."""
    return json.dumps(obj, allow_nan=False, separators=(",", ":"))


def require(obj: dict, key: str, kind: type, *, source: Any, frame: int | None = None,
            field: str | None = None, context: str = "") -> Any:
    """``obj[key]``, checked to be of ``kind`` (a bool is never taken for an int).

    ``field`` names the key in messages (default ``key``); ``context`` is
    appended to them (e.g. ``" in frame entry 3"``).
    """
    field = key if field is None else field
    if key not in obj:
        raise InputError(f"missing{context}", source=source, frame=frame, field=field)
    value = obj[key]
    if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
        raise InputError(f"expected {_JSON_NAMES.get(kind, kind.__name__)}, got "
                         f"{json_type(value)}{context}", source=source, frame=frame, field=field)
    return value


_JSON_NAMES = {list: "a list", dict: "an object", int: "an integer", float: "a number",
               str: "a string", bool: "true/false", type(None): "null"}


def json_type(value: Any) -> str:
    """JSON name of a parsed value's type, for messages."""
    return _JSON_NAMES.get(type(value), type(value).__name__)


def numeric_array(value: Any, ndim: int | None, *, source: Any, frame: int | None,
                  field: str) -> np.ndarray:
    """A float array of ``ndim`` dims (any if ``None``) from nested lists of JSON numbers.

    Strings, nulls, true/false and ragged lists are refused (no silent coercion).
    """
    try:
        a = np.asarray(value)
    except (ValueError, TypeError):
        raise InputError("expected a rectangular array of numbers", source=source,
                         frame=frame, field=field) from None
    if a.dtype.kind not in "iuf":
        raise InputError(f"expected numbers, got {_describe(a)}", source=source,
                         frame=frame, field=field)
    if holds_bool(value, a.shape):  # NumPy turns [true, 2.5] into [1.0, 2.5]
        raise InputError("expected numbers, got true/false entries", source=source,
                         frame=frame, field=field)
    if ndim is not None and a.ndim != ndim:
        raise InputError(f"expected a {ndim}-D array of numbers, got shape {a.shape}",
                         source=source, frame=frame, field=field)
    return a.astype(float)


def holds_bool(value: Any, shape: tuple[int, ...] | None = None) -> bool:
    """Whether nested lists hold a ``bool`` anywhere (iteratively: no recursion limit).

    ``shape``: the rectangular shape NumPy read ``value`` as; then the leaves are taken
    in one C-level pass (a keypoint file has hundreds of thousands of them).
    """
    if isinstance(value, np.ndarray):
        return value.dtype.kind == "b"
    if shape is not None:
        leaves = np.empty(shape, dtype=object)
        leaves[...] = value
        kinds = set(map(type, leaves.ravel().tolist()))
        return bool in kinds or np.bool_ in kinds
    stack = [value]
    while stack:
        v = stack.pop()
        if isinstance(v, (list, tuple)):
            stack.extend(v)
        elif isinstance(v, (bool, np.bool_)):
            return True
    return False


def _describe(a: np.ndarray) -> str:
    if a.ndim == 0:
        return json_type(a.item())
    return {"U": "text entries", "S": "text entries", "b": "true/false entries"}.get(
        a.dtype.kind, "null or non-numeric entries")


def to_skeleton(skeleton: Skeleton | str | None, *, source: Any) -> Skeleton | None:
    """Resolve a skeleton option given as a name."""
    if skeleton is None or isinstance(skeleton, Skeleton):
        return skeleton
    try:
        return skeleton_by_name(str(skeleton))
    except ValueError as e:
        raise InputError(str(e), source=source, field="skeleton") from None


class JointCount:
    """Checks that every person of every frame has the same number of keypoints.

    The first person seen fixes the count; it must match ``skeleton`` if one is
    given, or else one of the known skeletons. Where several skeletons share the
    count (25: BODY_25 and BODY_25B) the choice waits for all the data:
    :meth:`result` decides from the detections
    (:func:`mirrorgraph.skeleton_guess.guess_skeleton`).
    """

    def __init__(self, skeleton: Skeleton | None, default: Skeleton) -> None:
        self.skeleton = skeleton
        self.default = default
        self.count: int | None = None if skeleton is None else skeleton.num_joints
        self.candidates: tuple[Skeleton, ...] = () if skeleton is None else (skeleton,)

    def check(self, n: int, *, source: Any, frame: int | None, field: str) -> None:
        if self.count is None:
            found = skeletons_for_count(n)
            if not found:
                raise InputError(f"{n} keypoints match no known skeleton ({known_counts()})",
                                 source=source, frame=frame, field=field)
            self.candidates, self.count = found, n
            if len(found) == 1:
                self.skeleton = found[0]
        if n != self.count:
            names = " or ".join(s.name for s in self.candidates)
            raise InputError(f"{n} keypoints, but skeleton {names} has {self.count}",
                             source=source, frame=frame, field=field)

    def result(self, people: Iterable[np.ndarray | None] = (), *, source: Any = None
               ) -> Skeleton:
        """The skeleton found (the format's default if nobody was ever detected).

        Args:
            people: every frame's ``(P_t, J, 3)`` detections (``None`` for none),
                used only where the count is ambiguous.
            source: the file or folder, for the error message.

        Raises:
            InputError: an ambiguous count that the detections do not resolve.
        """
        if self.skeleton is None and len(self.candidates) > 1:
            self.skeleton = guess_skeleton(self.candidates, people, source=source)
        return self.skeleton if self.skeleton is not None else self.default


@dataclass(frozen=True)
class ScorePolicy:
    """How one format writes confidences (see the module docstring).

    Attributes:
        negative_missing: a negative confidence means "missing" (else refused).
        max_confidence: confidences in ``(1, max_confidence]`` are clipped to 1,
            larger ones refused (``inf``: any finite score is accepted).
        nan_missing: a joint whose x and y are NaN and whose confidence is NaN or
            ``<= 0`` is missing (else any NaN is refused).
        zero_nan_missing: NaN coordinates are accepted on joints of confidence 0
            (the ``.npz`` convention).
    """

    negative_missing: bool = False
    max_confidence: float = MAX_CONFIDENCE
    nan_missing: bool = False
    zero_nan_missing: bool = False

    def range_text(self) -> str:
        lo = "(-inf" if self.negative_missing else "[0"
        hi = "inf)" if np.isinf(self.max_confidence) else f"{self.max_confidence:g}]"
        return f"{lo}, {hi}"


#: mirrorgraph's own ``.npz``: confidence in ``[0, 1.5]``, NaN coordinates where 0.
NPZ_SCORES = ScorePolicy(zero_nan_missing=True)


class Tally:
    """Counts of what the cleaning read as missing or clipped, summed over calls.

    Joints: ``zero``, ``negative``, ``nan`` (missing by confidence 0, negative
    confidence, NaN), ``clipped`` (confidence above 1), ``max_confidence`` (largest
    finite one); people: ``no_keypoints``, ``no_joints``; frames: ``empty_frames``.
    :meth:`notes` freezes them into :class:`mirrorgraph.keypoints.ReadNotes`.
    """

    __slots__ = ("zero", "negative", "nan", "clipped", "max_confidence", "no_keypoints",
                 "no_joints", "empty_frames")

    def __init__(self) -> None:
        self.zero = self.negative = self.nan = self.clipped = 0
        self.no_keypoints = self.no_joints = self.empty_frames = 0
        self.max_confidence = -np.inf

    def notes(self) -> ReadNotes:
        top = None if not np.isfinite(self.max_confidence) else float(self.max_confidence)
        return ReadNotes(joints_missing_zero_confidence=self.zero,
                         joints_missing_negative_confidence=self.negative,
                         joints_missing_nan=self.nan, scores_clipped_above_1=self.clipped,
                         max_confidence_read=top, people_without_keypoints=self.no_keypoints,
                         people_without_joints=self.no_joints,
                         frames_without_people=self.empty_frames)


def clean_keypoints(kp: np.ndarray, *, source: Any, frame: int | None, field: str,
                    policy: ScorePolicy = NPZ_SCORES, tally: Tally | None = None,
                    frames: np.ndarray | None = None) -> np.ndarray:
    """Validate ``(..., J, 3)`` keypoints and mark missing joints; returns a new array.

    Applies ``policy`` (see the module docstring): non-finite values, confidences
    outside the policy's range and coordinates beyond ``MAX_COORDINATE`` of
    detected joints are refused; joints of confidence ``<= 0`` (``0`` only unless
    ``policy.negative_missing``) and NaN joints (``policy.nan_missing``) get
    confidence 0 and ``NaN`` coordinates; confidences above 1 are clipped to 1.
    What was read as missing or clipped is added to ``tally``. With ``frames``
    (``(T,)`` ids), ``kp`` is ``(T, J, 3)`` and an error names the frame of the
    offending row. Vectorised over all joints.

    Args:
        kp: ``(..., J, 3)`` x px, y px, confidence as read.
        source, frame, field: where ``kp`` came from, for the error message.
        policy: the format's :class:`ScorePolicy`.
        tally: counts to add to, if any.
        frames: ``(T,)`` frame ids of the rows of a ``(T, J, 3)`` ``kp``.

    Returns:
        ``(..., J, 3)`` float: missing joints ``(NaN, NaN, 0)``, confidences in
        ``[0, 1]``.
    """
    kp = np.array(kp, dtype=float)
    conf = kp[..., 2]
    finite = bool(np.isfinite(kp).all())      # the usual case: one check, no masks
    nan_joint = None
    if not finite:
        xy_nan = np.isnan(kp[..., :2])
        bad = ~np.isfinite(kp)
        if policy.nan_missing:
            nan_joint = xy_nan.all(-1) & (np.isnan(conf) | (conf <= 0))
            bad &= ~nan_joint[..., None]
        if policy.zero_nan_missing:
            bad[..., :2] &= ~(xy_nan & (conf == 0)[..., None])
    else:
        bad = None

    def fail(idx: np.ndarray, message: str) -> InputError:
        f = frame
        if frames is not None:
            f, idx = int(frames[idx[0]]), idx[1:]
        where = ", ".join(f"{n} {int(i)}" for n, i in zip(("person", "joint")[-len(idx):], idx))
        return InputError(f"{message} at {where}", source=source, frame=f, field=field)

    if bad is not None and bad.any():
        idx = np.argwhere(bad)[0]
        what = ("x", "y", "confidence")[idx[-1]]
        raise fail(idx[:-1], f"non-finite {what} ({kp[tuple(idx)]})")
    seen = None if nan_joint is None else ~nan_joint   # joints with a finite confidence
    cs = conf if seen is None else conf[seen]
    lo = float(cs.min()) if cs.size else 0.0
    hi = float(cs.max()) if cs.size else 0.0
    if hi > policy.max_confidence or (lo < 0 and not policy.negative_missing):
        with np.errstate(invalid="ignore"):
            out = (conf > policy.max_confidence) | ((conf < 0) & (not policy.negative_missing))
        idx = np.argwhere(out)[0]
        raise fail(idx, f"confidence {conf[tuple(idx)]} outside {policy.range_text()}")
    missing = conf <= 0
    if nan_joint is not None:
        missing |= nan_joint
    if finite and np.abs(kp[..., :2]).max(initial=0.0) <= MAX_COORDINATE:
        far = None
    else:
        with np.errstate(invalid="ignore"):
            far = (np.abs(kp[..., :2]) > MAX_COORDINATE) & ~missing[..., None]
    if far is not None and far.any():
        idx = np.argwhere(far)[0]
        what = ("x", "y")[idx[-1]]
        raise fail(idx[:-1], f"{what} = {kp[tuple(idx)]:g} px is no image coordinate "
                             f"(beyond +-{MAX_COORDINATE:g})")
    if tally is not None:
        if lo <= 0:
            tally.zero += int(np.count_nonzero(cs == 0))
            tally.negative += int(np.count_nonzero(cs < 0))
        if nan_joint is not None:
            tally.nan += int(np.count_nonzero(nan_joint))
        if cs.size:
            tally.max_confidence = max(tally.max_confidence, hi)
            if hi > 1:
                tally.clipped += int(np.count_nonzero(cs > 1))
    if lo <= 0 or nan_joint is not None:
        conf[missing] = 0.0
        kp[missing, :2] = np.nan
    if hi > 1:
        np.minimum(conf, 1.0, out=conf)
    return kp


def drop_empty_people(people: np.ndarray, tally: Tally | None = None) -> np.ndarray:
    """``(P', J, 3)``: the cleaned ``(P, J, 3)`` people with at least one joint seen.

    A person entry whose every joint is missing is no detection to pair (Pose2Sim
    writes such entries for tracked people not seen in a frame); they are counted
    in ``tally.no_joints``.
    """
    seen = (people[..., 2] > 0).any(-1)
    if seen.all():
        return people
    if tally is not None:
        tally.no_joints += int(np.count_nonzero(~seen))
    return people[seen]


def frame_from_name(path: Path) -> int:
    """The frame number in a file name: the last run of digits in its stem.

    ``video_000000000012_keypoints.json`` -> 12, ``000012.json`` -> 12.
    """
    m = _TRAILING_INT.search(path.stem)
    if m is None:
        raise InputError("file name holds no frame number", source=path)
    return int(m.group(1))


def check_frame_ids(frame_ids: Iterable[int], *, source: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(frame_ids sorted, order)``; refuses an empty list, duplicates and ids
    that do not fit a 64-bit integer."""
    listed = [int(i) for i in frame_ids]
    for i in listed:
        if not -2**63 <= i < 2**63:
            raise InputError("frame id out of range (64-bit integers)", source=source,
                             frame=i)
    ids = np.asarray(listed, dtype=np.int64)
    if ids.size == 0:
        raise InputError("holds no frames", source=source)
    order = np.argsort(ids, kind="stable")
    ids = ids[order]
    dup = np.flatnonzero(np.diff(ids) == 0)
    if dup.size:
        raise InputError("duplicate frame id", source=source, frame=int(ids[dup[0]]))
    return ids, order


def json_folder(path: Path) -> list[Path]:
    """The ``*.json`` files of a folder, sorted by name; InputError if there are none."""
    try:
        names = [e.name for e in os.scandir(path)
                 if e.name.lower().endswith(".json") and e.is_file()]
    except OSError as e:
        raise InputError(f"cannot list folder ({e.strerror})", source=path) from None
    if not names:
        raise InputError("folder holds no JSON files", source=path)
    return [path / n for n in sorted(names)]


def missing_mask(people: np.ndarray) -> np.ndarray:
    """``(..., J)`` bool: joints a writer must write as missing."""
    return (people[..., 2] <= 0) | ~np.isfinite(people[..., :2]).all(-1)


def zero_missing(people: np.ndarray) -> np.ndarray:
    """Copy with missing joints set to ``0, 0, 0`` (how detectors write them)."""
    out = np.array(people, dtype=float)
    out[missing_mask(out)] = 0.0
    return out


def bbox_of(person: np.ndarray) -> list[float]:
    """``[x1, y1, x2, y2]`` of the visible joints of a ``(J, 3)`` person (zeros if none)."""
    seen = person[~missing_mask(person), :2]
    if seen.size == 0:
        return [0.0, 0.0, 0.0, 0.0]
    return [*map(float, seen.min(0)), *map(float, seen.max(0))]


def check_writable_ids(frame_ids: np.ndarray) -> None:
    """Folder formats encode frame ids in file names: they must be >= 0."""
    if np.any(np.asarray(frame_ids) < 0):
        raise ValueError("frame ids written into file names must be >= 0")


def frame_files(folder: Path) -> tuple[np.ndarray, list[Path]]:
    """``(frame_ids, files)`` of a per-frame JSON folder, sorted by frame number.

    Only file names are listed here; the files are parsed one at a time later.
    """
    files = json_folder(folder)
    frame_ids, order = check_frame_ids([frame_from_name(f) for f in files], source=folder)
    return frame_ids, [files[i] for i in order]


def iter_frame_documents(folder: Path, files: list[Path], frame_ids: np.ndarray,
                         expected: str, key: str, progress: "ProgressCallback | None" = None
                         ) -> Iterator[tuple[int, Path, dict]]:
    """Stream a per-frame JSON folder: ``(frame id, file, parsed dict)`` one file at a time.

    Reports ``progress(done, total)`` per file and refuses a file that is not of
    the folder's format (no ``key``) with :func:`mixed_folder`'s error.
    """
    for i, (t, file) in enumerate(zip(frame_ids.tolist(), files)):
        if progress is not None:
            progress(i + 1, len(files))
        obj = load_json(file)
        if not isinstance(obj, dict) or key not in obj:
            raise mixed_folder(folder, file, expected, key)
        yield t, file, obj


def mixed_folder(folder: Path, file: Path, expected: str, key: str) -> InputError:
    """The error for a file of another format among per-frame files."""
    return InputError(f"not an {expected} frame file (no '{key}'); folder {folder} mixes "
                      "formats or holds other JSON files", source=file, field=key)


#: ``progress(done, total)``: called once per file read by the folder readers.
ProgressCallback = Callable[[int, int], None]
