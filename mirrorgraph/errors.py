"""Exceptions that the CLI turns into one-line messages.

Every error that user input can cause is a :class:`MirrorgraphError`. It names the
place at fault (file, frame, field) so that the message alone is enough to fix
the input; the command-line interface prints ``error: <message>`` and exits with
a non-zero status instead of showing a traceback.

:class:`InputError` is also a :class:`ValueError` (SciPy's and NumPy's convention
for an argument that cannot be used), so that ``except ValueError`` catches a bad
argument whichever function refused it. The library names the argument or field
at fault (``field="intrinsics"``), never a command-line flag: the CLI says which
flag gives it.

:class:`MissingExtraError` is also an :class:`ImportError`: an optional dependency (an
"extra" of the package) is not installed. :func:`require_extra` imports one or raises
it with the install hint; every optional import of the library goes through it.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from types import ModuleType


class MirrorgraphError(Exception):
    """Base class of every error mirrorgraph raises on purpose."""


class InputError(MirrorgraphError, ValueError):
    """Input that cannot be used: malformed file, wrong shape, NaN, unknown name, ...

    Args:
        message: what is wrong, in words a user understands.
        source: the file or folder at fault, if any.
        frame: the frame id at fault, if any.
        field: the JSON key / array name / argument at fault, if any.
        fix: the arguments that would make the input usable, as their names
            (``"intrinsics"``) or a name and a value (``"skeleton=BODY_25"``): the
            message ends in ``pass intrinsics or image_size``, and a front end that
            calls them otherwise says so with :meth:`describe` (the CLI: flags).
    """

    def __init__(self, message: str, *, source: str | None = None,
                 frame: int | None = None, field: str | None = None,
                 fix: tuple[str, ...] = ()) -> None:
        self.source = None if source is None else str(source)
        self.frame = frame
        self.field = field
        self.reason = message
        self.fix = tuple(fix)
        super().__init__(self.describe())

    def describe(self, names: Mapping[str, str] | None = None) -> str:
        """The message, with every argument it names (``field``, ``fix``) spelled as
        ``names`` maps them (an argument it does not map keeps its name).

        Args:
            names: argument name -> what a front end calls it, e.g. ``{"image_size":
                "--image-size WxH"}``; in ``field 'x'`` only its first word is used,
                and only where no ``source`` is named (a field of a file is the file's).
        """
        names = names or {}
        where = []
        if self.source is not None:
            where.append(self.source)
        if self.frame is not None:
            where.append(f"frame {self.frame}")
        if self.field is not None:
            field = names.get(self.field, self.field) if self.source is None else self.field
            where.append(f"field '{field.split(' ')[0]}'")
        message = self.reason
        if self.fix:
            spelled = []
            for arg in self.fix:
                name, _, value = arg.partition("=")
                if name in names:
                    spelled.append(names[name].split(" ")[0] + (f" {value}" if value else
                                   "".join(" " + w for w in names[name].split(" ")[1:])))
                else:
                    spelled.append(arg)
            message += f"; pass {' or '.join(spelled)}"
        return f"{', '.join(where)}: {message}" if where else message


class DegenerateGeometryError(MirrorgraphError):
    """The data cannot determine the mirror (too few pairs, parallel lines, ...)."""


class FailedCameraError(DegenerateGeometryError):
    """A rig camera fits under half of its keypoints: the rig is not written.

    Attributes:
        calibration: the :class:`~mirrorgraph.result.rig.RigCalibration` with every
            failed camera marked (``status = "failed"``, ``reason``), for a caller that
            keeps the others.
        cameras: the failed cameras' names.
    """

    def __init__(self, message: str, *, calibration=None, cameras: tuple[str, ...] = ()):
        super().__init__(message)
        self.calibration = calibration
        self.cameras = tuple(cameras)


class MissingExtraError(MirrorgraphError, ImportError):
    """An optional dependency (an extra of the package: ``plot``, ``view``, ``batch``,
    ``c3d``, ``video``, ...) is not installed; the message says how to install it.

    A :class:`MirrorgraphError`, so that the CLI prints its one line (exit status 2); and
    an :class:`ImportError` (not an :class:`InputError`: nothing is wrong with the
    input), so that ``except ImportError``, the usual guard of an optional feature,
    catches it as it catches the failed import itself.

    Attributes:
        name: the module that could not be imported (:class:`ImportError`'s).
        extra: the extra that installs it.
    """

    def __init__(self, message: str, *, module: str | None = None,
                 extra: str | None = None) -> None:
        super().__init__(message, name=module)
        self.extra = extra


def extra_hint(extra: str) -> str:
    """How to install the extra ``extra``, from PyPI or in a clone."""
    return f"pip install 'mirrorgraph[{extra}]' (in a clone: pip install -e '.[{extra}]')"


def require_extra(module: str, extra: str | None, purpose: str, *, what: str | None = None,
                  hint: str | None = None) -> ModuleType:
    """Import the optional ``module`` and return it, or raise :class:`MissingExtraError`:
    ``"{purpose} needs {what}: {hint}"``.

    Args:
        module: what to import, e.g. ``"dask.distributed"``.
        extra: the package's extra that installs it (``"batch"``), or ``None`` (then
            ``hint`` says how).
        purpose: what needs it, the message's subject (``"mirrorgraph batch"``).
        what: how the message names the dependency (default ``module``).
        hint: how to install it (default :func:`extra_hint` of ``extra``).

    Raises:
        MissingExtraError: ``module`` cannot be imported.
    """
    try:
        __import__(module)               # as an import statement does (and what patches it)
    except ImportError:
        hint = hint or extra_hint(str(extra))
        raise MissingExtraError(f"{purpose} needs {what or module}: {hint}", module=module,
                                extra=extra) from None
    return sys.modules[module]
