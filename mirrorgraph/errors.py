"""Exceptions that the CLI turns into one-line messages.

Every error that user input can cause is a :class:`MirrorgraphError`. It names the
place at fault (file, frame, field) so that the message alone is enough to fix
the input; the command-line interface prints ``error: <message>`` and exits with
a non-zero status instead of showing a traceback.
"""

from __future__ import annotations


class MirrorgraphError(Exception):
    """Base class of every error mirrorgraph raises on purpose."""


class InputError(MirrorgraphError):
    """Input that cannot be used: malformed file, wrong shape, NaN, ...

    Args:
        message: what is wrong, in words a user understands.
        source: the file or folder at fault, if any.
        frame: the frame id at fault, if any.
        field: the JSON key / array name / option at fault, if any.
    """

    def __init__(self, message: str, *, source: str | None = None,
                 frame: int | None = None, field: str | None = None) -> None:
        self.source = None if source is None else str(source)
        self.frame = frame
        self.field = field
        self.reason = message
        where = []
        if self.source is not None:
            where.append(self.source)
        if frame is not None:
            where.append(f"frame {frame}")
        if field is not None:
            where.append(f"field '{field}'")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)


class DegenerateGeometryError(MirrorgraphError):
    """The data cannot determine the mirror (too few pairs, parallel lines, ...)."""
