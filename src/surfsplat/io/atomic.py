"""Writing files so that a failed or interrupted write never leaves a partial file nor touches an
existing one: the data go to a temporary file beside the target, which then replaces it."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from ..errors import InputError


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


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, overwrite: bool = False):
    """Yield a temporary path beside ``path`` to write; on success it replaces ``path`` (atomically on
    one file system), on any error it is removed and ``path`` is left as it was."""
    path = check_writable(path, overwrite=overwrite)
    handle, temp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent if str(path.parent) else ".")
    os.close(handle)
    try:
        yield Path(temp)
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
