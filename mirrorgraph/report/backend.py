"""matplotlib for the report, an optional dependency: how to install it
(:data:`INSTALL_HINT`) and :func:`require_matplotlib`, which imports it with the
non-interactive Agg backend or fails with that hint. A module of its own so that
the report package and its figure modules (:mod:`.figures`, :mod:`.rig`) share it
without importing each other; :mod:`mirrorgraph.report` re-exports both names.
"""

from __future__ import annotations

from ..errors import extra_hint, require_extra

__all__ = ["INSTALL_HINT", "require_matplotlib"]

#: How to install the ``plot`` extra, from PyPI or in a clone (as docs/guide/report.md says).
INSTALL_HINT = extra_hint("plot")


def require_matplotlib():
    """Import matplotlib with the Agg backend and return ``matplotlib.pyplot``.

    Raises:
        MissingExtraError: matplotlib is not installed (the message says how to
            install it).
    """
    matplotlib = require_extra("matplotlib", "plot", "the report")
    # Agg unless a notebook (inline backend) or the user chose one already
    backend = str(matplotlib.get_backend()).lower()
    if "inline" not in backend and "ipympl" not in backend and "widget" not in backend:
        matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt
