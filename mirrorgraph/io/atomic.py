"""Atomic file and folder writes: the output is either complete or not there.

Every writer puts its data in a temporary file (or folder) next to the target,
in the same directory so that the final :func:`os.replace` is a rename on one
file system, and renames it over the target only once writing succeeded. On any
exception the temporary is removed and an existing target stays untouched.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

# mkstemp/mkdtemp create private (0600/0700) entries; give outputs the usual mode.
_UMASK = os.umask(0o022)
os.umask(_UMASK)


def _at(error: OSError, path: Path) -> OSError:
    """The same kind of OSError, naming ``path`` (its folder when that is missing)."""
    name = path.parent if isinstance(error, FileNotFoundError) else path
    return type(error)(error.errno, error.strerror, str(name))


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary file path that replaces ``path`` when the block succeeds.

    The temporary lives in the directory of ``path`` and keeps its suffix (so
    that e.g. ``np.savez`` does not append ``.npz``). The caller writes to it;
    on normal exit it is renamed over ``path``, on an exception it is deleted
    and the exception propagates.

    Example:
        >>> with atomic_path("out.npz") as tmp:          # doctest: +SKIP
        ...     with open(tmp, "wb") as f:
        ...         np.savez(f, a=a)
    """
    path = Path(path)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}",
                                        dir=path.parent if str(path.parent) else ".")
    except OSError as e:  # name the target, not the temporary, e.g. a missing folder
        raise _at(e, path) from None
    os.close(fd)
    tmp = Path(tmp_name)
    os.chmod(tmp, 0o666 & ~_UMASK)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (fsync'd before the rename)."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


@contextmanager
def atomic_dir(path: str | os.PathLike) -> Iterator[Path]:
    """Yield an empty temporary folder that replaces the folder ``path`` on success.

    The temporary is a sibling of ``path``. On success an existing ``path`` is
    first moved aside, the new folder renamed into place and the old one
    deleted; between the two renames ``path`` briefly does not exist. On an
    exception the temporary folder is deleted and ``path`` is untouched.

    Raises:
        FileExistsError: ``path`` exists and is not a folder.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise FileExistsError(f"{path} exists and is not a folder")
    parent = path.parent if str(path.parent) else Path(".")
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent))
    except OSError as e:
        raise _at(e, path) from None
    os.chmod(tmp, 0o777 & ~_UMASK)
    try:
        yield tmp
        if not path.exists():
            os.replace(tmp, path)
            return
        old = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".old", dir=parent))
        os.replace(path, old / "d")
        try:
            os.replace(tmp, path)
        except BaseException:
            os.replace(old / "d", path)
            raise
        finally:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
