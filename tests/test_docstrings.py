"""The package's docstrings, read from the source (nothing is imported).

A module docstring fits on one screen (at most :data:`MAX_MODULE_LINES` lines): what the
module does, its frames and units, its reference, and where its measurements live
(bench/RESULTS_*.md, docs/). No docstring (module, class or function) carries an issue
reference such as ``#24`` or ``issue 17``: how the code got its form lives in git.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "mirrorgraph"
MAX_MODULE_LINES = 40
ISSUE_REFERENCE = re.compile(r"#\d+|\bissues? \d+", re.IGNORECASE)


def _trees() -> list[tuple[Path, ast.Module]]:
    return [(p, ast.parse(p.read_text(), filename=str(p))) for p in sorted(PACKAGE.rglob("*.py"))]


def test_the_package_is_found():
    assert len(_trees()) > 50


def test_no_module_docstring_is_over_one_screen():
    long = []
    for path, tree in _trees():
        doc = ast.get_docstring(tree)
        if doc is not None and len(doc.splitlines()) > MAX_MODULE_LINES:
            long.append(f"{path.relative_to(PACKAGE.parent)}: {len(doc.splitlines())} lines")
    assert not long, f"module docstrings over {MAX_MODULE_LINES} lines:\n" + "\n".join(long)


def test_no_docstring_cites_an_issue_number():
    found = []
    for path, tree in _trees():
        for node in ast.walk(tree):
            if not isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            doc = ast.get_docstring(node)
            if doc is None:
                continue
            for match in ISSUE_REFERENCE.finditer(doc):
                name = getattr(node, "name", "<module>")
                found.append(f"{path.relative_to(PACKAGE.parent)}:{name}: {match.group(0)!r}")
    assert not found, "docstrings citing issue numbers:\n" + "\n".join(found)


def test_the_checks_can_fail():
    """The pattern catches the forms it is meant to, and lets ordinary text through."""
    for text in ("fixed in #24", "see issue 17", "(#33, point 2)", "Issue 5", "issues 3 and 4"):
        assert ISSUE_REFERENCE.search(text), text
    for text in ("17 joints", "an issue with 2 views", "RESULTS_live.md", "colour #ff0000"):
        assert not ISSUE_REFERENCE.search(text), text
