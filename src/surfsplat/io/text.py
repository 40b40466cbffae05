"""Point clouds as text: ``.xyz``, ``.pts``, ``.csv``, ``.txt``.

One point per line; values separated by commas (when the first data line has a comma), by
semicolons (likewise), else by whitespace. Lines starting with ``#`` or ``//`` before the data
are comments, except that the last such line, or a first line of words, can be a header:

- **With a header row** of names (``x,y,z,red,green,blue``; CloudCompare's ``//X,Y,Z,R,G,B``
  also works): the columns are read by name as
  :meth:`SplatCloud.from_dict <surfsplat.cloud.SplatCloud.from_dict>` reads them: ``x y z``,
  ``nx ny nz`` (``normal_x ...``), ``red green blue`` or ``r g b``, ``radius``, ``ux .. vz``;
  other columns are ignored.
- **Without one**, by the number of columns, in the order ``x y z [nx ny nz] [r g b]``:
  3: ``x y z``; 4: ``x y z intensity`` (ignored); 6: ``x y z`` then normals when those three
  columns are unit vectors (every finite row within 1e-2 of length 1), else colors; 7:
  ``x y z intensity r g b`` (Leica PTS); 9: ``x y z nx ny nz r g b``. Other counts are an
  error.
- **PTS**: a first line holding a single integer (the point count) is skipped (several scans
  concatenated, each with its count line, are not supported).

Colors are 0..255 integers or floats in [0, 1] (decided by their largest value, see
:func:`surfsplat.cloud.unit_colors`). Parsing is vectorized (``numpy.loadtxt``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError, file_reader

#: Extensions read as point text (lower case).
TEXT_EXTENSIONS = (".xyz", ".pts", ".csv", ".txt")

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^[+-]?(nan|inf)$", re.IGNORECASE)


@file_reader
def read_text(path: Path) -> SplatCloud:
    """Read a point text file (see the module docstring) as an unvalidated SplatCloud.

    Raises InputError naming the file: unreadable or empty file, rows of differing lengths or
    non-numeric values, an unsupported column count, a header without x, y, z.
    """
    source = str(path)
    try:
        with open(path, "r", encoding="utf-8", errors="strict") as stream:
            head = [stream.readline() for _ in range(64)]
    except UnicodeDecodeError as exc:
        raise InputError(f"{source}: not a text point file (not UTF-8 text: {exc.reason})") from exc
    except OSError as exc:
        raise InputError(f"{source}: cannot read: {exc.strerror or exc}") from exc
    skip, header = 0, None
    lines = iter(enumerate(head))
    first_data = None
    for index, line in lines:
        text = line.strip()
        if not line:
            break
        if not text:
            continue
        if text.startswith("#") or text.startswith("//"):
            words = _split(text.lstrip("#/").strip())
            if words and not all(_NUMBER.match(w) for w in words):
                header = words  # a commented header (CloudCompare, many exporters)
            skip = index + 1
            continue
        words = _split(text)
        if not all(_NUMBER.match(w) for w in words):
            if header is not None or index > skip:
                raise InputError(f"{source}: line {index + 1}: not numbers: {text[:80]!r}", row=index)
            header = words
            skip = index + 1
            continue
        if len(words) == 1 and path.suffix.lower() == ".pts" and first_data is None and header is None:
            skip = index + 1  # PTS: the point count
            continue
        first_data = text
        break
    if first_data is None:
        raise InputError(f"{source}: contains no points")
    delimiter = "," if "," in first_data else (";" if ";" in first_data else None)
    try:
        table = np.loadtxt(path, delimiter=delimiter, skiprows=skip, comments=("#", "//"), ndmin=2,
                           dtype=np.float64, encoding="utf-8")
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: malformed point text: {exc}") from exc
    except OSError as exc:
        raise InputError(f"{source}: cannot read: {exc.strerror or exc}") from exc
    if table.size == 0:
        raise InputError(f"{source}: contains no points")
    if header is not None:
        if len(header) != table.shape[1]:
            raise InputError(f"{source}: the header names {len(header)} columns but rows have {table.shape[1]}")
        try:
            return SplatCloud.from_dict({name: table[:, i] for i, name in enumerate(header)})
        except InputError as exc:   # from_dict's message, with the file named: attributes kept
            raise InputError(f"{source}: {exc}", **exc.context()) from exc
    return _by_count(table, source)


def _split(text: str) -> list[str]:
    if "," in text:
        return [w.strip() for w in text.split(",")]
    if ";" in text:
        return [w.strip() for w in text.split(";")]
    return text.split()


def _by_count(table: np.ndarray, source: str) -> SplatCloud:
    columns = table.shape[1]
    xyz = table[:, :3]
    if columns == 3:
        return SplatCloud(positions=xyz)
    if columns == 4:
        return SplatCloud(positions=xyz)
    if columns == 6:
        rest = table[:, 3:6]
        length = np.linalg.norm(rest, axis=1)
        finite = np.isfinite(length)
        if finite.any() and np.all(np.abs(length[finite] - 1.0) < 1e-2):
            return SplatCloud(positions=xyz, normals=rest)
        return SplatCloud.from_arrays(xyz, colors=rest)
    if columns == 7:
        return SplatCloud.from_arrays(xyz, colors=table[:, 4:7])
    if columns == 9:
        return SplatCloud.from_arrays(xyz, table[:, 3:6], table[:, 6:9])
    raise InputError(f"{source}: {columns} columns and no header row; without a header a point text file "
                     "has 3 (x y z), 4 (x y z intensity), 6 (x y z nx ny nz or x y z r g b), 7 (x y z "
                     "intensity r g b) or 9 (x y z nx ny nz r g b) columns")
