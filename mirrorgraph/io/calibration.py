"""Reading and writing JSON documents such as the calibration file.

Only the mechanics live here: conversion of NumPy values to plain JSON types and
atomic writing. The calibration's schema, reader and writer are
:mod:`mirrorgraph.result.mirror`'s.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import PurePath
from typing import Any

import numpy as np

from ..errors import InputError
from ._common import load_json
from .atomic import atomic_write_text


def to_jsonable(obj: Any) -> Any:
    """Recursively turn ``obj`` into plain JSON types.

    NumPy arrays become (nested) lists, NumPy scalars Python scalars, tuples
    lists, paths strings; non-finite floats (NaN, +-inf) become ``None``. Dict
    keys keep their insertion order (NumPy scalar keys become Python scalars).
    Anything else is returned unchanged (``json.dumps`` then decides).
    """
    if isinstance(obj, dict):
        return {_key(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind == "f":
            out = obj.astype(object)
            out[~np.isfinite(obj)] = None
            return out.tolist()
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return to_jsonable(obj.item())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, PurePath):
        return str(obj)
    return obj


def _key(k: Any) -> Any:
    return k.item() if isinstance(k, np.generic) else k


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Write ``obj`` (after :func:`to_jsonable`) as indented JSON, atomically."""
    text = json.dumps(to_jsonable(obj), indent=2, allow_nan=False, ensure_ascii=False)
    atomic_write_text(path, text + "\n")


#: The counts of a single mirror's calibration.json, and the largest one read (a billion
#: frames: over a year of video at 30 frames/s).
COUNT_FIELDS = ("frames_read", "frames_paired", "frames_used", "pairs_total", "pairs_used",
                "lr_fixes", "ransac_iterations")
MAX_COUNT = 10**9
#: The geometry of a calibration JSON (a single mirror's and a rig's): no number in it
#: beyond :data:`MAX_NUMBER` (lengths in metres or subject heights, pixels: all far below;
#: the reports' weights and figures are not bounded).
GEOMETRY_FIELDS = ("mirror", "intrinsics", "virtual_camera", "fundamental_matrix",
                   "epipole_px", "initial_normal", "cameras", "mirrors")
MAX_NUMBER = 1e12


def read_calibration_document(path: str | os.PathLike, newest: int) -> dict:
    """A calibration JSON (a single mirror's or a rig's), parsed, if its schema is one
    that a reader of schemas 1 to ``newest`` reads.

    A single mirror's ``calibration.json`` carries ``schema_version`` (schema 1, of the
    first versions, has none but carries ``mirrorgraph_version``); a rig's JSON carries
    ``mirrorgraph_version``.

    Raises:
        InputError: not a JSON object, a ``schema_version`` that is no whole number
            >= 1 or is newer than ``newest``, or neither field (not mirrorgraph's); a NaN
            or an infinity anywhere, a number beyond :data:`MAX_NUMBER` in the geometry
            (:data:`GEOMETRY_FIELDS`); a count (:data:`COUNT_FIELDS`) beyond
            :data:`MAX_COUNT`.
    """
    doc = load_json(path)
    if not isinstance(doc, dict):
        raise InputError("not a calibration written by mirrorgraph (expected a JSON object)",
                         source=path)
    if "schema_version" in doc:
        v = doc["schema_version"]
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise InputError(f"expected a schema version (a whole number >= 1), got {v!r}",
                             source=path, field="schema_version")
        if v > newest:
            raise InputError(f"schema {v} is newer than this mirrorgraph reads (1 to "
                             f"{newest}): upgrade mirrorgraph", source=path,
                             field="schema_version")
    elif "mirrorgraph_version" not in doc:
        raise InputError("neither schema_version nor mirrorgraph_version: not a calibration "
                         "written by mirrorgraph", source=path)
    for key in COUNT_FIELDS:
        v = doc.get(key)
        if v is not None and not isinstance(v, bool) and isinstance(v, (int, float)) \
                and not 0 <= v <= MAX_COUNT:
            raise InputError(f"{v!r} is not a count of frames or pairs (0 to {MAX_COUNT:.0e})",
                             source=path, field=key)
    where = _unreadable_number(doc, bounded=False)
    for key in GEOMETRY_FIELDS:
        if where is None and key in doc:
            where = _unreadable_number(doc[key], key)
    if where is not None:
        raise InputError(f"NaN, an infinity or a number beyond {MAX_NUMBER:g}, which "
                         "mirrorgraph never writes (an unknown figure is null)", source=path,
                         field=where)
    return doc


def _unreadable_number(obj: Any, where: str = "", bounded: bool = True) -> str | None:
    """The key path of the first NaN or infinity (or, ``bounded``, number beyond
    :data:`MAX_NUMBER`) in a parsed JSON document, or ``None``."""
    if isinstance(obj, (int, float)) and not isinstance(obj, bool):
        ok = math.isfinite(obj) and (not bounded or abs(obj) <= MAX_NUMBER)
        return None if ok else (where or "(the document)")
    if isinstance(obj, dict):
        items = ((f"{where}.{k}" if where else str(k), v) for k, v in obj.items())
    elif isinstance(obj, list):
        items = ((f"{where}[{i}]", v) for i, v in enumerate(obj))
    else:
        return None
    for key, v in items:
        found = _unreadable_number(v, key, bounded)
        if found is not None:
            return found
    return None


def read_json(path: str | os.PathLike) -> Any:
    """Parse a JSON file; InputError naming the file if missing or malformed."""
    return load_json(path)


