"""Atomic file writes: a reader sees either the old file or the new one."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ..errors import TcamlabError

_UMASK: int | None = None


def _default_mode() -> int:
    global _UMASK
    if _UMASK is None:
        current = os.umask(0o022)
        os.umask(current)
        _UMASK = current
    return 0o666 & ~_UMASK


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # not supported (e.g. Windows); best effort only
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write *data* to *path* atomically and return the path.

    Parent directories are created.  The data go to a temporary file in the
    same directory, which is flushed, fsynced and then ``os.replace``-d over
    *path*; on any error the temporary file is removed and an existing file
    at *path* is left untouched.  The new file keeps the permissions of the
    file it replaces (or the umask default for a new file).

    Raises
    ------
    TcamlabError
        When the file system refuses (permissions, disk full...); the
        original ``OSError`` is chained.  Other exceptions propagate as-is.
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            mode = target.stat().st_mode & 0o7777
        except FileNotFoundError:
            mode = _default_mode()
        fd, tmp_name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    except OSError as exc:
        raise TcamlabError(
            f"cannot write {target}: {exc.strerror or exc}",
            hint="check that the output directory is writable",
        ) from exc
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise TcamlabError(
                f"cannot write {target}: {exc.strerror or exc}",
                hint="check free disk space and that the output directory is writable",
            ) from exc
        raise
    _fsync_dir(target.parent)
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write *text* as UTF-8 atomically (no newline translation)."""
    return atomic_write_bytes(path, text.encode("utf-8"))
