"""Atomic file writing: a temporary file in the target folder, then ``os.replace``.

Every writer in :mod:`quadnodes.io` goes through :func:`write_atomic`, so a file
at the target path is either the complete new content or whatever was there
before: a failure part-way (a full disk, an OCCT error, Ctrl-C) leaves the old
file untouched and removes the temporary file.

The temporary file has a short hidden name, ``.qn-XXXXXXXX.tmp``, whatever the
target's name, so any file name the file system allows (up to 255 bytes) can be
written. A process killed part-way cannot remove its temporary file; such
leftovers (that name pattern, older than :data:`STALE_SECONDS`) are removed by the
next write into the same folder (once per folder and process).
"""

from __future__ import annotations

import os
import re
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from ..errors import ExportError

__all__ = ["write_atomic", "write_text_atomic", "write_bytes_atomic", "remove_stale_temporaries",
           "STALE_SECONDS"]

_MODE: int | None = None

#: A temporary file older than this (seconds) is a leftover of a killed write.
STALE_SECONDS = 600.0
_TMP_PREFIX, _TMP_SUFFIX = ".qn-", ".tmp"
_TMP_RE = re.compile(r"\.qn-[A-Za-z0-9_]{8}\.tmp\Z")  # mkstemp's 8 random characters
_SWEPT: set[str] = set()


def remove_stale_temporaries(folder: str | os.PathLike[str], *, older_than: float = STALE_SECONDS) -> list[Path]:
    """Delete temporary files of killed writes (``.qn-XXXXXXXX.tmp``) older than ``older_than`` seconds.

    Files of other names, and recent temporary files (a write in progress in
    another process), are left alone. Errors (a missing or unreadable folder, a
    file removed meanwhile) are ignored: this is housekeeping.

    Returns
    -------
    list of Path
        The files removed.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> old = d / ".qn-abcd1234.tmp"; _ = old.write_text("half a file")
    >>> os.utime(old, (0, 0))                       # modified in 1970
    >>> [p.name for p in remove_stale_temporaries(d)], old.exists()
    (['.qn-abcd1234.tmp'], False)
    """
    removed: list[Path] = []
    limit = time.time() - older_than
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        if not _TMP_RE.match(e.name):
            continue
        try:
            if e.is_file(follow_symlinks=False) and e.stat(follow_symlinks=False).st_mtime < limit:
                os.unlink(e.path)
                removed.append(Path(e.path))
        except OSError:
            continue
    return removed


def _file_mode() -> int:
    """``0o666`` minus the process umask: the mode ``open(path, "w")`` would give.

    ``mkstemp`` creates files readable by the owner only; the final file should
    get the same permissions as any other file the user writes.
    """
    global _MODE
    if _MODE is None:
        mask = os.umask(0o022)
        os.umask(mask)
        _MODE = 0o666 & ~mask
    return _MODE


def _fsync(path: str) -> None:
    with open(path, "rb+") as f:
        os.fsync(f.fileno())


def write_atomic(path: str | os.PathLike[str], write: Callable[[str], None]) -> Path:
    """Write a file atomically through a callback.

    Parameters
    ----------
    path : str or path-like
        Final location. Its folder must exist.
    write : callable
        ``write(tmp_path)`` writes the complete content to ``tmp_path`` (a file
        that already exists, empty, in the same folder as ``path``).

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    ExportError
        If the temporary file cannot be created (missing or unwritable folder),
        ``write`` raises, or the final rename fails. The message names ``path``;
        the original exception is chained. Nothing is left behind: no temporary
        file, and an existing file at ``path`` is unchanged.
        An :class:`ExportError` raised by ``write`` is passed on as it is.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = tempfile.mkdtemp()
    >>> p = write_atomic(pathlib.Path(d) / "a.txt", lambda tmp: pathlib.Path(tmp).write_text("hi"))
    >>> p.read_text()
    'hi'
    """
    target = Path(os.fspath(path))
    folder = target.parent
    key = os.path.abspath(folder)
    if key not in _SWEPT:
        _SWEPT.add(key)
        remove_stale_temporaries(folder)
    try:
        fd, tmp = tempfile.mkstemp(prefix=_TMP_PREFIX, suffix=_TMP_SUFFIX, dir=folder)
    except OSError as exc:  # said of the folder: the temporary file's name means nothing to the user
        where = str(folder)
        if not folder.exists():
            why = f"the folder {where!r} does not exist"
        elif not folder.is_dir():
            why = f"{where!r} is not a folder"
        else:
            why = f"cannot create a file in the folder {where!r} ({exc.strerror or exc})"
        raise ExportError(f"cannot write {str(target)!r}: {why}") from exc
    os.close(fd)
    try:
        os.chmod(tmp, _file_mode())
        write(tmp)
        _fsync(tmp)
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, ExportError) or not isinstance(exc, Exception):
            raise  # our own error (already names the panel / file), or Ctrl-C
        raise ExportError(f"writing {str(target)!r} failed: {type(exc).__name__}: {exc}") from exc
    return target


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; see :func:`write_atomic`.

    Raises
    ------
    ExportError
        As :func:`write_atomic`.
    """

    def _write(tmp: str) -> None:
        with open(tmp, "wb") as f:
            f.write(data)

    return write_atomic(path, _write)


def write_text_atomic(path: str | os.PathLike[str], text: str, *, encoding: str = "utf-8") -> Path:
    r"""Write ``text`` to ``path`` atomically with ``\n`` line endings; see :func:`write_atomic`.

    Raises
    ------
    ExportError
        As :func:`write_atomic`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = write_text_atomic(pathlib.Path(tempfile.mkdtemp()) / "b.txt", "x\n")
    >>> p.read_bytes()
    b'x\n'
    """

    def _write(tmp: str) -> None:
        with open(tmp, "w", encoding=encoding, newline="\n") as f:
            f.write(text)

    return write_atomic(path, _write)
