"""A griffe extension for the API page: the library's docstrings cross-reference in Sphinx's
roles (``:class:`~.config.RigConfig```), which Markdown does not know; each is read as the
plain code span Sphinx would show (``RigConfig``) before the docstring is parsed.

Loaded by mkdocs.yml (mkdocstrings' ``extensions`` option); not part of the package.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const):`([^`]+)`")


def _shown(target: str) -> str:
    """What Sphinx shows for a role's target: the last name after ``~``, no leading dot."""
    if target.startswith("~"):
        return target.lstrip("~.").rsplit(".", 1)[-1]
    return target.lstrip(".")


class SphinxRoles(griffe.Extension):
    """Rewrite Sphinx roles as Markdown code spans in every docstring."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _ROLE.sub(lambda m: f"`{_shown(m.group(1))}`",
                                            obj.docstring.value)
