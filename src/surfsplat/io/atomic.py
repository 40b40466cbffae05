"""Safe file access.

Writing: a failed or interrupted write never leaves a partial file nor touches an existing one: the
data go to a temporary file beside the target, which then replaces it (:func:`atomic_path`).

Reading: :func:`check_readable` accepts only regular files (a FIFO would block forever, a device such as
``/dev/zero`` never ends, a folder is no file), and :func:`memory_limit` bounds what a reader may
allocate from a file's header before it has seen the data."""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from pathlib import Path

from ..errors import InputError, file_reader


@file_reader
def check_writable(path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """``path`` as a Path after checking, before any work, that it can be written: its folder exists,
    it is not a folder, and it does not exist unless ``overwrite`` (InputError naming it)."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"{path}: folder {folder} does not exist")
    if path.is_dir():
        raise InputError(f"{path}: is a folder")
    if path.exists() and not overwrite:
        raise InputError(f"{path}: exists; use --force to overwrite it")
    return path


@file_reader
def check_readable(path: str | os.PathLike) -> Path:
    """``path`` as a Path after checking, before opening it, that it is an existing regular file
    (symbolic links followed): InputError naming it for a missing file, a folder, a FIFO, a socket or
    a device."""
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise InputError(f"{path}: is a directory, not a file")
    if not stat.S_ISREG(mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
                else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")
        raise InputError(f"{path}: is {kind}, not a regular file; surfsplat reads only regular files")
    return path


def memory_limit() -> int:
    """The most bytes a reader may allocate for one file: the memory available now (``MemAvailable``
    of /proc/meminfo, or free physical pages), at least 64 MiB; 2**40 where neither is known."""
    try:
        with open("/proc/meminfo", "rb") as stream:
            for line in stream:
                if line.startswith(b"MemAvailable:"):
                    return max(int(line.split()[1]) * 1024, 1 << 26)
    except (OSError, ValueError, IndexError):
        pass
    try:
        return max(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"), 1 << 26)
    except (ValueError, OSError, AttributeError):
        return 1 << 40


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, overwrite: bool = False):
    """Yield a temporary path beside ``path`` to write; on success it replaces ``path`` (atomically on
    one file system), on any error it is removed and ``path`` is left as it was."""
    path = check_writable(path, overwrite=overwrite)
    try:
        handle, temp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp",
                                        dir=path.parent if str(path.parent) else ".")
    except OSError as exc:
        raise InputError(f"{path}: cannot write in its folder: {exc.strerror or exc}") from exc
    os.close(handle)
    try:
        try:
            yield Path(temp)
        except OSError as exc:  # disk full, file size limit, ...: the old file stays as it was
            raise InputError(f"{path}: cannot write: {exc.strerror or exc}") from exc
        if not overwrite and path.exists():
            raise InputError(f"{path}: exists; use --force to overwrite it")
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temp, 0o666 & ~umask)   # mkstemp made it private; a new file gets the usual mode
        os.replace(temp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temp)


def write_atomically(path: str | os.PathLike, data: bytes, *, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` through :func:`atomic_path`."""
    with atomic_path(path, overwrite=overwrite) as temp:
        temp.write_bytes(data)
    return Path(path)
