"""Sections of ``bench/RESULTS.md`` written by other benchmarks than ``compare.py``.

``compare.py`` writes ``RESULTS.md`` whole; another benchmark that belongs in it
(``bench_rig.py``: the rig against aniposelib) keeps its section between two HTML
comments, ``<!-- block:NAME -->`` and ``<!-- /block:NAME -->``. That benchmark
replaces its block (:func:`replace_block`), and ``compare.py`` carries every block
of the old file over to the new one (:func:`keep_blocks`).
"""

from __future__ import annotations

import re
from pathlib import Path

from _report import cpu_model, machine  # noqa: F401  (one header for every results file)

__all__ = ["replace_block", "keep_blocks", "cpu_model", "machine"]

_BLOCK = re.compile(r"<!-- block:(?P<name>[\w-]+) -->\n.*?<!-- /block:(?P=name) -->\n?", re.S)


def _wrap(name: str, body: str) -> str:
    return f"<!-- block:{name} -->\n{body.rstrip()}\n<!-- /block:{name} -->\n"


def replace_block(path: str | Path, name: str, body: str) -> None:
    """Put ``body`` (markdown) in the block ``name`` of ``path``, appended if absent."""
    path = Path(path)
    text = path.read_text() if path.exists() else ""
    block = _wrap(name, body)
    for m in _BLOCK.finditer(text):
        if m.group("name") == name:
            path.write_text(text[:m.start()] + block + text[m.end():])
            return
    path.write_text(text.rstrip("\n") + ("\n\n" if text else "") + block)


def keep_blocks(path: str | Path, new_text: str) -> str:
    """``new_text`` followed by every block of the current ``path`` that it lacks."""
    path = Path(path)
    if not path.exists():
        return new_text
    have = {m.group("name") for m in _BLOCK.finditer(new_text)}
    kept = [m.group(0) for m in _BLOCK.finditer(path.read_text()) if m.group("name") not in have]
    return new_text.rstrip("\n") + "\n\n" + "\n".join(kept) if kept else new_text

