"""Atomic file writes: a reader sees either the old files or the new ones.

:func:`write_all_or_nothing` is tcamlab's one writer; every report, metrics
file, simulated log and experiment file goes through it (directly or through
:func:`atomic_write_bytes` / :func:`atomic_write_text` for one file).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ..errors import TcamlabError

__all__ = ["atomic_write_bytes", "atomic_write_text", "write_all_or_nothing"]

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


def _stage(final: Path, data: bytes) -> Path:
    """Write data in full to a temporary file next to final, with final's permissions."""
    try:
        mode = final.stat().st_mode & 0o7777
    except FileNotFoundError:
        mode = _default_mode()
    fd, tmp_name = tempfile.mkstemp(dir=final.parent, prefix=f".{final.name}.", suffix=".tmp")
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return tmp


def write_all_or_nothing(target, payload: dict[str, bytes]) -> list[Path]:
    """Write several files into one folder so that a failure leaves none of them half-done.

    Every file is first written in full to a temporary file in ``target``
    (``.NAME.XXXX.tmp``, flushed and fsynced, with the permissions of the file
    it replaces or the umask default); only when all are on disk are they
    renamed over their final names (``os.replace``, atomic on POSIX and
    Windows). If anything fails before the renames, the temporary files are
    removed and no final file is touched. A process killed outright (SIGKILL)
    before the renames leaves at most ``.*.tmp`` files, never a truncated one.

    Parameters
    ----------
    target : path-like
        Folder receiving the files (created with its parents).
    payload : dict of str to bytes
        File name -> content.

    Returns
    -------
    list of pathlib.Path
        The written files, in payload order.

    Raises
    ------
    TcamlabError
        When the file system refuses (permissions, disk full...), naming the
        file; the original ``OSError`` is chained. Other exceptions propagate.
    """
    target = Path(target)
    staged: list[tuple[Path, Path]] = []
    current = target
    try:
        target.mkdir(parents=True, exist_ok=True)
        for name, data in payload.items():
            current = target / name
            staged.append((_stage(current, data), current))
        for tmp, final in staged:
            current = final
            os.replace(tmp, final)
    except BaseException as exc:
        for tmp, _ in staged:
            try:
                tmp.unlink(missing_ok=True)
            except OSError:
                pass
        if isinstance(exc, OSError):
            raise TcamlabError(
                f"cannot write {current}: {exc.strerror or exc}",
                hint="check free disk space and that the output directory is writable",
            ) from exc
        raise
    _fsync_dir(target)
    return [final for _, final in staged]


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write *data* to *path* atomically (see :func:`write_all_or_nothing`) and return the path."""
    target = Path(path)
    return write_all_or_nothing(target.parent, {target.name: data})[0]


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write *text* as UTF-8 atomically (no newline translation)."""
    return atomic_write_bytes(path, text.encode("utf-8"))
