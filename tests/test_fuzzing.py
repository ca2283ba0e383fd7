"""The plan of the property-based suite (``tests/fuzzing.py``): the number of generated
cases it states, and every planned test present, once, in the fuzz modules."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.fuzzing import EXAMPLES, TOTAL_EXAMPLES

TESTS = Path(__file__).resolve().parent


def test_total_examples_is_recorded():
    """The number of generated cases stated in the module docstring stays true."""
    assert TOTAL_EXAMPLES == sum(EXAMPLES.values()) == 2468


def _planned_tests() -> dict[str, list[str]]:
    """EXAMPLES key -> the test functions decorated with ``@fuzz_settings(key)``, read from
    the source of every ``test_fuzz*.py`` (nothing is imported)."""
    found: dict[str, list[str]] = {}
    for path in sorted(TESTS.rglob("test_fuzz*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.FunctionDef):
                continue
            for dec in node.decorator_list:
                if (isinstance(dec, ast.Call) and isinstance(dec.func, ast.Name)
                        and dec.func.id == "fuzz_settings"):
                    key = dec.args[0].value
                    found.setdefault(key, []).append(
                        f"{path.relative_to(TESTS).as_posix()}::{node.name}")
    return found


def test_every_planned_test_is_there_once():
    """Each entry of EXAMPLES is run by exactly one test, and no test draws on a plan
    that is not there: the stated total is what a run generates."""
    found = _planned_tests()
    assert sorted(found) == sorted(EXAMPLES), (sorted(found), sorted(EXAMPLES))
    for key, tests in found.items():
        assert len(tests) == 1, (key, tests)
    assert all(t.split("/")[-1].startswith("test_fuzz") for ts in found.values() for t in ts)
