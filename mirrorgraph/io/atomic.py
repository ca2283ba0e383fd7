"""Atomic file and folder writes: the output is either complete or not there.

Every writer puts its data in a temporary file (or folder) next to the target,
in the same directory so that the final :func:`os.replace` is a rename on one
file system, and renames it over the target only once writing succeeded. On any
exception the temporary is removed and an existing target stays untouched.

Inside :func:`staged_outputs` the renames wait for the end of the block: every
output of a run (:func:`atomic_path`, :func:`atomic_write_text`, ...,
:meth:`Staging.file`, :meth:`Staging.folder`) moves into place together once the
whole block succeeded, and a block that fails leaves every target as it was.

What a target may be (:func:`check_output`, also applied by :func:`atomic_path`):

* a regular file (replaced) or a name not yet taken in an existing folder;
* a symbolic link: written through, the file it points to is replaced and the link
  kept;
* never a folder, a FIFO, a device or a socket (``/dev/null`` included): refused with
  :class:`~mirrorgraph.errors.InputError`, the target untouched;
* ``-`` only where the caller reads it as standard output (``stdout_ok``).
"""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

from ..errors import InputError

__all__ = ["atomic_path", "atomic_write_bytes", "atomic_write_text", "atomic_dir",
           "check_output", "check_outputs", "staged_outputs", "Staging", "STDOUT"]

#: The output name that means standard output where a command allows it.
STDOUT = "-"

# mkstemp/mkdtemp create private (0600/0700) entries; give outputs the usual mode.
_UMASK = os.umask(0o022)
os.umask(_UMASK)

_STAGE: ContextVar["Staging | None"] = ContextVar("mirrorgraph_staging", default=None)


def _at(error: OSError, path: Path) -> OSError:
    """The same kind of OSError, naming ``path`` (its folder when that is missing)."""
    name = path.parent if isinstance(error, FileNotFoundError) else path
    return type(error)(error.errno, error.strerror, str(name))


def _kind(mode: int) -> str | None:
    """``"a FIFO"``, ``"a device"``, ``"a socket"`` for a special file's ``st_mode``."""
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return None


def _target(path: str | os.PathLike, field: str | None = None) -> Path:
    """The file a write to ``path`` replaces: ``path``, or the end of its symbolic links.

    Raises:
        InputError: ``path`` is (or points to) a folder or a special file, or is a
            link that loops.
    """
    path = Path(path)
    target = path
    if path.is_symlink():
        try:
            target = Path(os.path.realpath(path, strict=True)) if path.exists() else \
                Path(os.path.realpath(path))
        except OSError:
            raise InputError("is a symbolic link that loops", source=path, field=field) from None
        if target.is_symlink():                     # realpath gave up: a loop
            raise InputError("is a symbolic link that loops", source=path, field=field)
    try:
        st = os.stat(target)
    except FileNotFoundError:
        return target
    except OSError as e:
        raise InputError(f"cannot be examined ({e.strerror})", source=path, field=field) from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError("is a folder; give a file name", source=path, field=field)
    kind = _kind(st.st_mode)
    if kind is not None:
        raise InputError(f"is {kind}, not a regular file: give a file name (nothing is "
                         "written to special files)", source=path, field=field)
    return target


def check_output(path: str | os.PathLike, *, field: str | None = None,
                 inputs: Iterable[str | os.PathLike | None] = (), folder: bool = False,
                 stdout_ok: bool = False) -> None:
    """Refuse, before any work, an output a run could not write or should not replace.

    A file output needs an existing folder it can write into and must not be a folder, a
    special file (:func:`_target`), a read-only file or one of ``inputs`` (the same file
    by :func:`os.path.samefile`, links and hard links included). A ``folder`` output may
    not exist yet (its parents are created) but must not be a file. ``-`` is standard
    output where ``stdout_ok``, else refused.

    Args:
        path: the output as the user gave it.
        field: the option that gives it (``--joints3d``), named in the message.
        inputs: the run's input files and folders (``None`` entries ignored).
        folder: the output is a folder (``--report DIR``).
        stdout_ok: ``-`` means standard output.

    Raises:
        InputError: one line naming the path and what is wrong with it.
    """
    text = os.fspath(path)
    if text == STDOUT:
        if stdout_ok:
            return
        raise InputError("standard output ('-') is not an output of this option; give a "
                         "file name", field=field)
    if not text:
        raise InputError("an empty file name", field=field)
    p = Path(text)
    if folder:
        if p.exists() and not p.is_dir():
            raise InputError("is a file; give a folder", source=p, field=field)
        probe = p
        while not probe.exists():                 # the folder it will be made in
            probe = probe.parent
        if not probe.is_dir():
            raise InputError(f"{probe} is a file, not a folder", source=p, field=field)
        if not os.access(probe, os.W_OK | os.X_OK):
            raise InputError(f"cannot write into {probe} (permission denied)", source=p,
                             field=field)
    else:
        target = _target(p, field)
        parent = target.parent
        if not parent.exists():
            raise InputError(f"no such folder: {parent}", source=p, field=field)
        if not parent.is_dir():
            raise InputError(f"{parent} is not a folder", source=p, field=field)
        if not os.access(parent, os.W_OK | os.X_OK):
            raise InputError(f"cannot write into {parent} (permission denied)", source=p,
                             field=field)
        if target.exists() and not os.access(target, os.W_OK):
            raise InputError("is read-only; give another name or make it writable",
                             source=p, field=field)
    for inp in inputs:
        if inp is None or os.fspath(inp) in ("", STDOUT):
            continue
        try:
            same = os.path.samefile(p, inp)
        except OSError:
            continue
        if same:
            raise InputError(f"is the input {os.fspath(inp)}; give another name (the input "
                             "would be overwritten)", source=p, field=field)


def check_outputs(outputs: Iterable[tuple[str | os.PathLike | None, str]], *,
                  inputs: Iterable[str | os.PathLike | None] = (),
                  folders: Iterable[str] = (), stdout_ok: Iterable[str] = ()) -> None:
    """:func:`check_output` of every ``(path, field)`` given (``None`` paths skipped),
    and no two outputs naming the same file.

    Args:
        outputs: ``(path, field)`` pairs, e.g. ``(args.out, "--out")``.
        inputs: the run's inputs (no output may be one of them).
        folders: the fields whose output is a folder.
        stdout_ok: the fields where ``-`` means standard output.
    """
    inputs = [i for i in inputs if i is not None]
    folders, stdout_ok = set(folders), set(stdout_ok)
    seen: dict[str, str] = {}
    for path, field in outputs:
        if path is None:
            continue
        check_output(path, field=field, inputs=inputs, folder=field in folders,
                     stdout_ok=field in stdout_ok)
        if os.fspath(path) == STDOUT:
            continue
        key = os.path.realpath(path)
        if key in seen:
            raise InputError(f"is also the output of {seen[key]}; give two names",
                             source=path, field=field)
        seen[key] = field


class Staging:
    """The outputs of a run, written to temporaries and moved into place together.

    Made by :func:`staged_outputs`; :func:`atomic_path` registers its temporaries here
    while a staging is active. :meth:`commit` renames every temporary over its target
    (an existing target is kept aside until every rename succeeded and put back if one
    fails); :meth:`discard` deletes them and leaves every target as it was.
    """

    def __init__(self) -> None:
        self._files: list[tuple[Path, Path]] = []      # (temporary, target)
        self._folders: list[tuple[Path, Path]] = []    # (temporary folder, target folder)

    def add(self, tmp: Path, target: Path) -> None:
        """Move the written file ``tmp`` to ``target`` at :meth:`commit`."""
        self._files.append((Path(tmp), Path(target)))

    def file(self, path: str | os.PathLike) -> Path:
        """A temporary beside ``path`` (same suffix) that replaces it at :meth:`commit`;
        the caller writes it (by any means: a video writer, a recording)."""
        target = _target(path)
        tmp = _mkstemp(target)
        self.add(tmp, target)
        return tmp

    def folder(self, path: str | os.PathLike) -> Path:
        """An empty temporary folder whose files go into the folder ``path`` (made if
        missing, its other files kept) at :meth:`commit`."""
        path = Path(path)
        probe = path.parent if str(path.parent) else Path(".")
        while not probe.exists():
            probe = probe.parent
        try:
            tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=probe))
        except OSError as e:
            raise _at(e, path) from None
        os.chmod(tmp, 0o777 & ~_UMASK)
        self._folders.append((tmp, path))
        return tmp

    def as_targets(self, text: str) -> str:
        """``text`` (a message about a staged output) with every temporary's name
        replaced by its target's, as the user gave it."""
        for tmp, target in [*self._files, *self._folders]:
            text = text.replace(str(tmp), str(target)).replace(tmp.name, target.name)
        return text

    def commit(self) -> None:
        """Move every output into place; on a failure put back what was there."""
        moves = list(self._files)
        for tmp, folder in self._folders:
            folder.mkdir(parents=True, exist_ok=True)
            moves += [(f, folder / f.name) for f in sorted(tmp.iterdir()) if f.is_file()]
        kept: list[tuple[Path, Path | None]] = []      # (target, its old content or None)
        try:
            for tmp, target in moves:
                kept.append((target, _aside(target) if target.exists() else None))
                os.replace(tmp, target)
        except BaseException:
            for target, aside in reversed(kept):
                if aside is not None:
                    os.replace(aside, target)
                    aside.unlink(missing_ok=True)  # rename between hard links of one file
                else:                              # does nothing: the link stays
                    target.unlink(missing_ok=True)
            self.discard()
            raise
        for _, aside in kept:
            if aside is not None:
                aside.unlink(missing_ok=True)
        self.discard()

    def discard(self) -> None:
        """Delete every temporary; the targets stay as they were."""
        for tmp, _ in self._files:
            tmp.unlink(missing_ok=True)
        for tmp, _ in self._folders:
            shutil.rmtree(tmp, ignore_errors=True)
        self._files, self._folders = [], []


@contextmanager
def staged_outputs() -> Iterator[Staging]:
    """Every output written in the block moves into place only when the block succeeds.

    Example:
        >>> with staged_outputs() as stage:              # doctest: +SKIP
        ...     write_json("c.json", doc)               # waits for the end of the block
        ...     figures = make_report(run, stage.folder("report"))
    """
    stage = Staging()
    token = _STAGE.set(stage)
    try:
        yield stage
    except BaseException:
        _STAGE.reset(token)
        stage.discard()
        raise
    _STAGE.reset(token)
    stage.commit()


def _aside(target: Path) -> Path:
    """A copy of the existing ``target`` beside it (a hard link where the file system
    has them), put back by :meth:`Staging.commit` if a later rename fails."""
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent)
    os.close(fd)
    aside = Path(name)
    try:
        os.unlink(aside)
        os.link(target, aside)
    except OSError:
        shutil.copy2(target, aside)
    return aside


def _mkstemp(target: Path) -> Path:
    parent = target.parent if str(target.parent) else Path(".")
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".tmp{target.suffix}",
                                        dir=parent)
    except OSError as e:  # name the target, not the temporary, e.g. a missing folder
        raise _at(e, target) from None
    os.close(fd)
    tmp = Path(tmp_name)
    os.chmod(tmp, 0o666 & ~_UMASK)
    return tmp


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary file path that replaces ``path`` when the block succeeds.

    The temporary lives in the directory of the target and keeps its suffix (so
    that e.g. ``np.savez`` does not append ``.npz``). The caller writes to it;
    on normal exit it is renamed over the target (or, inside :func:`staged_outputs`,
    at the end of the staging), on an exception it is deleted and the exception
    propagates. A symbolic link is written through (its target replaced, the link
    kept); a folder or a special file is refused (:class:`InputError`).

    Example:
        >>> with atomic_path("out.npz") as tmp:          # doctest: +SKIP
        ...     with open(tmp, "wb") as f:
        ...         np.savez(f, a=a)
    """
    target = _target(path)
    tmp = _mkstemp(target)
    try:
        yield tmp
        stage = _STAGE.get()
        if stage is not None:
            stage.add(tmp, target)
        else:
            os.replace(tmp, target)
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
