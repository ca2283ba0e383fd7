"""The package's docstrings, read from the source (nothing is imported).

A module docstring fits on one screen (at most :data:`MAX_MODULE_LINES` lines): what the
module does, its frames and units, its reference, and where its measurements live
(bench/RESULTS_*.md, docs/). The documentation (module, class and function docstrings,
and the ``#:`` comments that document a constant) says what the code is and does, in the
present tense: no issue reference such as ``#24`` or ``issue 17``, and none of the
phrases that tell the code's history (:data:`HISTORY`: "as before", "counted twice
before", "the old signature", "does now", "previously", "fell from", "this session", a
measurement told in the past tense, ...). How the code got its form lives in git, measured figures in bench/.
"""

from __future__ import annotations

import ast
import functools
import re
from collections.abc import Iterator
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "mirrorgraph"
MAX_MODULE_LINES = 40
ISSUE_REFERENCE = re.compile(r"#\d+|\bissues? \d+", re.IGNORECASE)


def _words(*patterns: str) -> re.Pattern:
    """One pattern of ``patterns``, a space in them matching any run of whitespace (a
    phrase may wrap onto the next line of a docstring)."""
    return re.compile("|".join(p.replace(" ", r"\s+") for p in patterns), re.IGNORECASE)


#: Phrases that tell the code's history rather than what it is. Not the bare words
#: "before" or "was": "before the pairing" is an order of steps, "where ``K`` was
#: estimated" a state of the data; the phrases below are the forms history takes.
HISTORY = _words(
    r"\bas before\b",                                   # "keeps every output as before"
    r"\b(?:twice|once) before\b",                       # "counted twice before"
    r"\bbefore (?:it|they|this|that|these|we) (?:was|were|had)\b",  # "before they were swapped"
    r"\bbefore the (?:fix|change|refactor\w*|rewrite)\b",
    r"\b(?:was|were|has been|have been) (?:renamed|rewritten|introduced)\b",
    r"\bno longer\b", r"\bnow\b", r"\bpreviously\b", r"\bformerly\b", r"\bused to be\b",
    r"\bany ?more\b", r"\buntil now\b", r"\bregressed\b",
    r"\b(?:the|an?) (?:old|new) (?:signature|code|behaviou?r|version|default|api"
    r"|implementation|form|name|path)s?\b",             # "the keywords of the old signature"
    r"\bthis (?:fix|change|commit|refactor\w*)\b",
    r"\b(?:commit|revision) [0-9a-f]{7,40}\b",
    r"\bsince (?:commit|version|v?\d+\.\d+)\b",
    r"\b(?:was|were) (?:about |~|only |still )?[-+]?\d",  # a figure told as a story
    r"\b(?:fell|rose|dropped|grew|shrank) from\b",     # "the solves fell from 12 to 7"
    r"\bwent [-+~]?\d[\d.]* ?->",                       # "the median went 0.42 -> 0.50"
    r"\bearlier versions? of\b", r"\bthe scenes of earlier versions\b",
    r"\b(?:this|last|previous|earlier|an earlier|a later|another) session\b",
)

#: Present-tense text that a :data:`HISTORY` phrase matches, allowed where it stands:
#: (file under the package's parent, the phrase with the match).
ALLOWED = {
    ("mirrorgraph/video/track.py", "crop no longer holds a person"),  # a track's end
}

#: History found in files that other work had open when the check was written:
#: (file, the matched text). Each entry is a failure that stays to be rewritten;
#: :func:`test_every_pending_entry_is_still_there` fails once it is gone, so that its
#: entry goes too. Empty when every docstring is in the present tense.
PENDING: set[tuple[str, str]] = set()


@functools.cache
def _trees() -> list[tuple[Path, ast.Module]]:
    return [(p, ast.parse(p.read_text(), filename=str(p))) for p in sorted(PACKAGE.rglob("*.py"))]


def _documentation() -> Iterator[tuple[str, int, str, str]]:
    """Every piece of documentation: ``(file, first line, owner, text)``.

    The docstrings of modules, classes and functions (their raw text, so that a line
    counted in it is a line of the file) and the ``#:`` comment blocks above constants.
    """
    for path, tree in _trees():
        rel = str(path.relative_to(PACKAGE.parent))
        for node in ast.walk(tree):
            if not isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef
                              | ast.AsyncFunctionDef) or not node.body:
                continue
            first = node.body[0]
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str)):
                yield rel, first.lineno, getattr(node, "name", "<module>"), first.value.value
        block: list[str] = []
        for number, line in enumerate(path.read_text().splitlines() + [""], start=1):
            if line.lstrip().startswith("#:"):
                block.append(line.lstrip()[2:])
                continue
            if block:
                yield rel, number - len(block), "#:", "\n".join(block)
                block = []


def _found(pattern: re.Pattern, allowed=frozenset()) -> list[tuple[str, int, str, str]]:
    """``(file, line, owner, matched text)`` of every match of ``pattern`` not allowed."""
    hits = []
    for rel, line, owner, text in _documentation():
        flat = " ".join(text.split())
        for m in pattern.finditer(text):
            said = " ".join(m.group(0).split())
            if any(f == rel and phrase in flat and said in phrase for f, phrase in allowed):
                continue
            hits.append((rel, line + text.count("\n", 0, m.start()), owner, said))
    return hits


def _listed(hits) -> str:
    return "\n".join(f"{rel}:{line}: {owner}: {said!r}" for rel, line, owner, said in hits)


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
    found = _found(ISSUE_REFERENCE)
    assert not found, "documentation citing issue numbers:\n" + _listed(found)


def test_no_docstring_tells_the_code_s_history():
    found = [h for h in _found(HISTORY, ALLOWED) if (h[0], h[3]) not in PENDING]
    assert not found, ("documentation telling the code's history (say what the code is and "
                       "does; figures by reference to bench/):\n" + _listed(found))


def test_every_pending_entry_is_still_there():
    """An entry of :data:`PENDING` rewritten leaves the list."""
    there = {(h[0], h[3]) for h in _found(HISTORY, ALLOWED)}
    gone = sorted(PENDING - there)
    assert not gone, f"rewritten: remove from PENDING {gone}"


def test_the_checks_can_fail():
    """The patterns catch the forms they are meant to, and let ordinary text through."""
    for text in ("fixed in #24", "see issue 17", "(#33, point 2)", "Issue 5", "issues 3 and 4"):
        assert ISSUE_REFERENCE.search(text), text
    for text in ("17 joints", "an issue with 2 views", "RESULTS_live.md", "colour #ff0000"):
        assert not ISSUE_REFERENCE.search(text), text
    for text in ("frames counted twice before", "the names before they were swapped",
                 "0 (default) keeps every output as before", "the keywords of the old\n"
                 "    signature", "as ``estimate_focal=False`` does now", "it previously held",
                 "its error was 6.5 %", "were about 3 px", "the new default", "this change",
                 "fixed at commit 0123abcd", "no longer drops frames", "it used to be slower",
                 "the solves fell from 12-14 to 7-9", "the median went 0.42 -> 0.50",
                 "the scenes of earlier versions", "measured this session"):
        assert HISTORY.search(text), text
    for text in ("before the pairing", "the frame before", "before refinement", "one of the two "
                 "was", "where ``K`` was estimated", "how many observations were dropped",
                 "a fixed camera", "no more than 3 px", "the new masks", "old tangent -> new",
                 "the known width", "snow", "was estimated (std 2 px)", "nowhere",
                 "the fall from the ledge", "from 12 to 7 px", "120 -> 30 fps",
                 "a capture session's files"):
        assert not HISTORY.search(text), text

