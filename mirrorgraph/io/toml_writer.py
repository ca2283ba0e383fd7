"""A small TOML writer (reading is :mod:`tomllib`, in the standard library).

Only what camera files need: a document is a ``dict`` whose values are
strings, booleans, integers, floats, (nested) lists of those, or ``dict``
tables (written as ``[table]`` / ``[table.sub]`` sections). NumPy arrays and
scalars are accepted and written as the matching TOML arrays and numbers.

Conventions of the output:

* Python ``float`` (and NumPy floating) values are always written as TOML
  floats, with the shortest text that reads back to the same double
  (``repr``); integral values keep a ``.0`` (``1.0``, not ``1``), non-finite
  ones are ``nan``, ``inf`` and ``-inf`` (TOML 1.0 spellings).
* Python ``int`` (and NumPy integer) values are written as TOML integers,
  except in an array that also holds floats, where they are written as floats:
  TOML 1.0 allows mixed arrays, but the older ``toml`` package that Pose2Sim
  and aniposelib read their files with (TOML 0.5) refuses them.
* Strings are TOML basic strings (double quotes) with the escapes TOML
  requires; keys are bare when they can be, quoted otherwise.
* Top-level scalars come first, then each table in insertion order, a blank
  line between tables. Arrays are written on one line: ``[ 1.0, 2.0 ]``.

Arrays of tables (``[[x]]``) are not supported: camera files do not use them.

Example:
    >>> print(dumps({"cam_01": {"name": "cam_01", "size": [1920.0, 1080.0]}}), end="")
    [cam_01]
    name = "cam_01"
    size = [ 1920.0, 1080.0 ]
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .atomic import atomic_write_text

__all__ = ["dumps", "write_toml", "format_value"]

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")
_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n",
            "\f": "\\f", "\r": "\\r"}


def _string(s: str) -> str:
    out = []
    for ch in s:
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _key(k: Any) -> str:
    if not isinstance(k, str):
        raise TypeError(f"TOML keys must be strings, got {type(k).__name__}")
    return k if _BARE_KEY.match(k) else _string(k)


def _float(x: float) -> str:
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    text = repr(float(x))
    if not any(c in text for c in ".eE"):       # repr of an integral float always has
        text += ".0"                            # one of these; kept as a safeguard
    return text


def format_value(value: Any) -> str:
    """The TOML text of one value (not a table).

    Args:
        value: ``str``, ``bool``, ``int``, ``float``, NumPy scalar or array, or a
            (nested) list / tuple of those.

    Returns:
        The value as TOML, e.g. ``[ [ 1.0, 0.0 ], [ 0.0, 1.0 ] ]``.

    Raises:
        TypeError: a value TOML cannot hold here (``None``, a dict inside an
            array, an object).
    """
    if isinstance(value, np.ndarray):
        return format_value(value.tolist())
    if isinstance(value, np.generic):
        return format_value(value.item())
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _float(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, (list, tuple)):
        if not value:
            return "[]"
        items = [v.item() if isinstance(v, np.generic) else v for v in value]
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items)
        if numbers and any(isinstance(v, float) for v in items):
            items = [float(v) for v in items]       # one type per array (see module doc)
        return "[ " + ", ".join(format_value(v) for v in items) + " ]"
    if value is None:
        raise TypeError("TOML has no null value")
    raise TypeError(f"cannot write a {type(value).__name__} as a TOML value")


def _is_table(value: Any) -> bool:
    return isinstance(value, Mapping)


def _emit_table(lines: list[str], path: list[str], table: Mapping[str, Any]) -> None:
    scalars = [(k, v) for k, v in table.items() if not _is_table(v)]
    tables = [(k, v) for k, v in table.items() if _is_table(v)]
    if path and (scalars or not tables):
        if lines:
            lines.append("")
        lines.append("[" + ".".join(_key(p) for p in path) + "]")
    for k, v in scalars:
        if isinstance(v, Sequence) and not isinstance(v, str) and any(_is_table(x) for x in v):
            raise TypeError(f"arrays of tables are not supported (key {k!r})")
        lines.append(f"{_key(k)} = {format_value(v)}")
    for k, v in tables:
        _emit_table(lines, path + [k], v)


def dumps(doc: Mapping[str, Any], *, header: str | None = None) -> str:
    """Serialise ``doc`` as TOML text.

    Args:
        doc: the document (see the module docstring for what values may hold).
        header: optional comment put at the top of the file, one ``#`` line per
            line of text.

    Returns:
        The TOML text, ending with a newline.
    """
    lines: list[str] = []
    if header:
        lines.extend(("# " + line).rstrip() for line in header.splitlines())
        lines.append("")
    body: list[str] = []
    _emit_table(body, [], doc)
    lines.extend(body)
    return "\n".join(lines) + "\n"


def write_toml(path: str | os.PathLike, doc: Mapping[str, Any], *,
               header: str | None = None) -> None:
    """Write ``doc`` (see :func:`dumps`) to ``path`` atomically."""
    atomic_write_text(path, dumps(doc, header=header))
