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


def read_calibration_document(path: str | os.PathLike, newest: int) -> dict:
    """A calibration JSON (a single mirror's or a rig's), parsed, if its schema is one
    that a reader of schemas 1 to ``newest`` reads.

    A single mirror's ``calibration.json`` carries ``schema_version`` (schema 1, of the
    first versions, has none but carries ``mirrorgraph_version``); a rig's JSON carries
    ``mirrorgraph_version``.

    Raises:
        InputError: not a JSON object, a ``schema_version`` that is no whole number
            >= 1 or is newer than ``newest``, or neither field (not mirrorgraph's).
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
    return doc


def read_json(path: str | os.PathLike) -> Any:
    """Parse a JSON file; InputError naming the file if missing or malformed."""
    return load_json(path)


