"""Reading NumPy ``.npz`` archives from untrusted files without ``np.load``.

``np.load`` inflates a member whole before anything is checked, so a small archive whose member
inflates to gigabytes of zeros (a zip bomb), or whose ``.npy`` header declares a terabyte shape,
takes that memory. :func:`read_npz` checks the sizes the zip directory and the ``.npy`` headers
declare before it inflates anything: the archive may inflate to at most :data:`MAX_INFLATION`
times its size on disk (at least :data:`MIN_INFLATED_BYTES`) and at most the memory available;
each member must hold exactly what its header declares, and no pickled objects. zipfile never
inflates past a member's declared size (and checks its CRC there), so the declared sizes bound
what is read.
"""

from __future__ import annotations

import os
import zipfile
import zlib
from pathlib import Path

import numpy as np

from ..errors import InputError, file_reader
from .atomic import memory_limit

#: Most bytes an archive may inflate to per byte on disk. surfsplat writes its archives
#: uncompressed (ratio 1); ``np.savez_compressed`` float arrays shrink by less than 2, and even
#: integer index arrays by less than 10, while zeros deflate 1000 to 1.
MAX_INFLATION = 20
#: Archives that inflate to no more than this many bytes are read whatever their ratio.
MIN_INFLATED_BYTES = 64 << 20
#: Bytes inflated at once while reading a member (the only transient copy).
_CHUNK = 1 << 22


def inflation_limit(path: str | os.PathLike) -> int:
    """Most bytes the ``.npz`` archive at ``path`` may inflate to: :data:`MAX_INFLATION` times its
    size on disk, at least :data:`MIN_INFLATED_BYTES`, at most the memory available now."""
    return min(max(MAX_INFLATION * os.stat(path).st_size, MIN_INFLATED_BYTES), memory_limit())


@file_reader
def npz_names(path: Path, source: str | None = None) -> list[str]:
    """The member names of the ``.npz`` archive at ``path`` (``.npy`` suffix removed), read
    from its zip directory only (nothing inflated); InputError naming the file if it is no zip."""
    source = source or str(path)
    try:
        with zipfile.ZipFile(path) as archive:
            return [_name(info) for info in archive.infolist() if not info.is_dir()]
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise InputError(f"{source}: not a readable .npz archive ({exc})", file=path) from None


@file_reader
def read_npz(path: str | os.PathLike, names=None, source: str | None = None) -> dict[str, np.ndarray]:
    """The members of the ``.npz`` archive at ``path`` as ``{name: array}`` (``names``: only
    these, when present; None: all), checked before anything is inflated (module docstring).

    Raises:
        InputError naming the file (``file``) and, for one member, its name (``element``): not a
        zip archive, corrupt (bad CRC, truncated), inflating past :func:`inflation_limit`, a
        member holding Python objects or not the bytes its ``.npy`` header declares.
    """
    path = Path(path)
    source = source or str(path)
    if not zipfile.is_zipfile(path):
        raise InputError(f"{source}: not an .npz archive (or truncated)", file=path)
    member = None
    try:
        with zipfile.ZipFile(path) as archive:
            infos = [info for info in archive.infolist() if not info.is_dir()
                     and (names is None or _name(info) in names)]
            total = sum(info.file_size for info in infos)
            limit = inflation_limit(path)
            if total > limit:
                raise InputError(
                    f"{source}: the archive inflates to {total:,} bytes ({os.stat(path).st_size:,} on disk), "
                    f"more than the {limit:,} bytes surfsplat inflates for it (at most {MAX_INFLATION} times "
                    f"the file's size or {MIN_INFLATED_BYTES >> 20} MiB, and the memory available); refusing "
                    "to read it (a corrupt file or a zip bomb)", file=path)
            members = {}
            for info in infos:
                member = _name(info)
                members[member] = _read_member(archive, info, source, path)
            return members
    except InputError:
        raise
    except (zipfile.BadZipFile, zlib.error, ValueError, OSError, EOFError, KeyError, NotImplementedError,
            RuntimeError) as exc:
        where = f" (member '{member}')" if member else ""
        raise InputError(f"{source}: not a readable .npz archive{where}: {exc}", file=path, element=member) from None


def _name(info: zipfile.ZipInfo) -> str:
    return info.filename.removesuffix(".npy")


def _read_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, source: str, path: Path) -> np.ndarray:
    """One ``.npy`` member: header checked against the member's declared size, then read in chunks
    straight into the array."""
    name = _name(info)
    with archive.open(info) as stream:
        version = np.lib.format.read_magic(stream)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(stream)
        else:
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(stream)
        if dtype.hasobject:
            raise InputError(f"{source}: member '{name}' holds Python objects (pickle); refused",
                             file=path, element=name)
        count = int(np.prod(shape, dtype=object))
        need = count * dtype.itemsize
        held = info.file_size - stream.tell()
        if need != held:
            raise InputError(f"{source}: member '{name}' declares shape {shape} of {dtype} "
                             f"({need:,} bytes) but holds {held:,} bytes", file=path, element=name)
        array = np.empty(shape, dtype=dtype, order="F" if fortran else "C")
        view = array.reshape(-1, order="A").view(np.uint8).data if need else memoryview(b"")
        done = 0
        while done < need:
            chunk = stream.read(min(_CHUNK, need - done))
            if not chunk:
                raise InputError(f"{source}: member '{name}' is truncated", file=path, element=name)
            view[done:done + len(chunk)] = chunk
            done += len(chunk)
        return array if array.flags.c_contiguous else array.copy(order="C")
