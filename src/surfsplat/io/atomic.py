"""Safe file access.

Writing: outputs are replaced, as image and point-cloud tools do, and atomically: the data go to a
temporary file (or folder) beside the target, which then replaces it (:func:`atomic_path`), so a
failed or interrupted write never leaves a partial file and never touches the existing one, and a
reader sees either the old file or the new one. Every writer of surfsplat goes through it.

Reading: :func:`check_readable` accepts only regular files (a FIFO would block forever, a device such as
``/dev/zero`` never ends, a folder is no file), and :func:`memory_limit` bounds what a reader may
allocate from a file's header before it has seen the data."""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
from pathlib import Path

from ..errors import InputError, file_reader


@file_reader
def check_writable(path: str | os.PathLike, *, overwrite: bool = True, directory: bool = False) -> Path:
    """``path`` as a Path after checking, before any work, that it can be written: its folder exists,
    and it is not a folder (with ``directory``: not a file). An existing output is refused only with
    ``overwrite=False``. InputError naming the path."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"{path}: folder {folder} does not exist")
    if directory and path.exists() and not path.is_dir():
        raise InputError(f"{path}: exists and is not a folder")
    if not directory and path.is_dir():
        raise InputError(f"{path}: is a folder")
    if path.exists() and not overwrite:
        raise InputError(f"{path}: exists (not replaced: overwrite=False)")
    return path


def same_file(path: str | os.PathLike, other: str | os.PathLike) -> bool:
    """Whether ``path`` and ``other`` are the same existing file or folder: the same device and inode,
    so a hard link or a symbolic link (followed) to ``other`` counts as ``other``."""
    try:
        return os.path.samefile(path, other)
    except (OSError, ValueError):   # one of them does not exist (yet), or a name NUL cannot be
        return False


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
def atomic_path(path: str | os.PathLike, *, overwrite: bool = True, directory: bool = False):
    """Yield a temporary path beside ``path`` to write (a new empty folder with ``directory``); when
    the block succeeds it replaces ``path``, on any error it is removed and ``path`` is left as it was.

    A file is replaced by one ``os.replace`` (atomic on one file system: a reader sees the old file
    or the new one). A folder cannot be replaced in one step: the old one is renamed aside, the new
    one renamed in, then the old one deleted. ``overwrite=False`` refuses an existing ``path``; a
    symbolic link at ``path`` is itself replaced (the file it points to is not written). Refusing
    the caller's own inputs is the caller's business (:func:`same_file`). OSError while writing a
    file (disk full, file size limit) -> InputError naming ``path``."""
    target = check_writable(path, overwrite=overwrite, directory=directory)
    folder = target.parent if str(target.parent) else Path(".")
    try:
        if directory:
            temp = tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=folder)
        else:
            handle, temp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
            os.close(handle)
    except OSError as exc:
        raise InputError(f"{target}: cannot write in its folder: {exc.strerror or exc}") from exc
    try:
        try:
            yield Path(temp)
        except OSError as exc:  # disk full, file size limit, ...: the old file stays as it was
            if directory:   # a folder's builder reads inputs too: its errors are its own to word
                raise
            raise InputError(f"{target}: cannot write: {exc.strerror or exc}") from exc
        if not overwrite and target.exists():
            raise InputError(f"{target}: exists (not replaced: overwrite=False)")
        if directory:
            _replace_folder(Path(temp), target)
        else:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(temp, 0o666 & ~umask)   # mkstemp made it private; a new file gets the usual mode
            os.replace(temp, target)
    finally:
        if directory:
            shutil.rmtree(temp, ignore_errors=True)
        else:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temp)


def _replace_folder(temp: Path, path: Path) -> None:
    """Rename the finished folder ``temp`` to ``path``, an old ``path`` first renamed aside and deleted
    after (a crash in between leaves it under a hidden ``.NAME.*.old`` name, never half deleted)."""
    if not (path.exists() or path.is_symlink()):
        os.rename(temp, path)
        return
    old = temp.with_name(temp.name + ".old")
    os.rename(path, old)
    try:
        os.rename(temp, path)
    except OSError:
        os.rename(old, path)
        raise
    if old.is_dir() and not old.is_symlink():
        shutil.rmtree(old, ignore_errors=True)
    else:
        old.unlink()


def write_atomically(path: str | os.PathLike, data: bytes, *, overwrite: bool = True) -> Path:
    """Write ``data`` to ``path`` through :func:`atomic_path`."""
    with atomic_path(path, overwrite=overwrite) as temp:
        temp.write_bytes(data)
    return Path(path)
