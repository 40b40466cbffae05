"""Checking a PLY file's header against its body before anything is allocated.

A PLY header declares how many records each element has; a reader that trusts it allocates whatever it
says (a header declaring 2**40 vertices asks for terabytes), and a header that declares fewer records
than the body holds silently drops the rest. :func:`check_body` compares the declared counts with the
real size of the body:

- binary: the declared records need at least ``count * record size`` bytes (list properties counted
  empty); fewer bytes -> InputError (truncated file, or counts too large). Without list properties the
  size is exact: a body longer than declared by one record or more -> InputError (the counts are too
  small). A binary body that reads as ascii numbers -> InputError (an ascii file labelled binary).
  :func:`check_consumed` does the exact check after parsing for files with list properties.
- ascii: the body must have exactly as many non-blank lines as the declared records.

Headers this module does not understand are left to plyfile, which reports the problem.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, file_reader

#: PLY scalar type names -> size in bytes.
TYPE_SIZES = {
    "char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2, "uint16": 2,
    "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8,
}
_HEADER_LIMIT = 1 << 20
_ASCII_BYTES = re.compile(rb"^[0-9eEnaifNAIF+\-. \t\r\n]*$")


@dataclass
class PlyLayout:
    """A parsed PLY header: ``format`` ("ascii", "binary_little_endian", ...), ``body`` (offset of the
    first byte after the header), ``size`` (file size), ``elements``: ``[(name, count, props)]``, each
    prop ``(name, type)`` or ``(name, count type, item type)`` for a list."""

    format: str
    body: int
    size: int
    elements: list[tuple[str, int, list[tuple[str, ...]]]]


@file_reader
def read_layout(path: Path) -> PlyLayout | None:
    """The header of ``path``, or None when it is not a PLY header this module understands."""
    with open(path, "rb") as stream:
        head = stream.read(_HEADER_LIMIT)
    match = re.search(rb"(^|\n)end_header[ \t]*\r?\n", head)
    if match is None or not head.startswith(b"ply"):
        return None
    try:
        lines = head[:match.start()].decode("ascii").splitlines()
    except UnicodeDecodeError:
        return None
    header = [line.split() for line in lines]
    if len(header) < 2 or header[0] != ["ply"] or len(header[1]) != 3 or header[1][0] != "format":
        return None
    elements: list[tuple[str, int, list[tuple[str, ...]]]] = []
    for words in header[2:]:
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and len(words) == 3 and words[1] in TYPE_SIZES:
            elements[-1][2].append((words[2], words[1]))
        elif (words[0] == "property" and elements and len(words) == 5 and words[1] == "list"
              and words[2] in TYPE_SIZES and words[3] in TYPE_SIZES):
            elements[-1][2].append((words[4], words[2], words[3]))
        else:
            return None
    return PlyLayout(header[1][1], match.end(), os.stat(path).st_size, elements)


def _record(props: list[tuple[str, ...]]) -> int:
    """Bytes of one binary record with every list empty."""
    return sum(TYPE_SIZES[p[1]] for p in props)


def _declared(layout: PlyLayout) -> str:
    return ", ".join(f"{count} {name}" for name, count, _ in layout.elements) or "no elements"


@file_reader
def check_body(path: Path, source: str) -> PlyLayout | None:
    """Raise InputError naming ``source`` when the body cannot hold what the header declares (see the
    module docstring); return the layout (None for a header left to plyfile)."""
    layout = read_layout(path)
    if layout is None:
        return None
    available = layout.size - layout.body
    if layout.format.startswith("binary"):
        minimum = sum(count * _record(props) for _, count, props in layout.elements)
        if available > 0:
            with open(path, "rb") as stream:
                stream.seek(layout.body)
                sample = stream.read(4096)
            first = next((props for _, count, props in layout.elements if count), None)
            line = sample.split(b"\n", 1)[0].split()
            if (b"\n" in sample and _ASCII_BYTES.match(sample) and first is not None
                    and len(line) >= len(first)):
                raise InputError(f"{source}: malformed PLY file: the header says {layout.format} "
                                 "but the body is ascii text; fix the 'format' line of the header")
        if minimum > available:
            raise InputError(f"{source}: malformed PLY file: the header declares {_declared(layout)} records, "
                             "which need at "
                             f"least {minimum:,} bytes, but only {available:,} bytes follow the header "
                             "(truncated file, or wrong counts in the header)")
        lists = any(len(p) == 3 for _, _, props in layout.elements for p in props)
        if not lists:
            _check_extra(layout, available - minimum, source)
    elif layout.format == "ascii":
        with open(path, "rb") as stream:
            stream.seek(layout.body)
            body = stream.read().strip()
        lines = body.count(b"\n") + 1 if body else 0
        lines -= len(re.findall(rb"\n[ \t\r]*(?=\n)", body))
        rows = sum(count for _, count, _ in layout.elements)
        if lines != rows:
            problem = ("too few, early end-of-file: truncated file, or counts too large" if lines < rows
                       else "more than declared: the counts in the header are too small")
            raise InputError(f"{source}: malformed PLY file: the header declares {_declared(layout)} records "
                             f"({rows:,} lines) "
                             f"but the body has {lines:,} lines ({problem})")
    return layout


def _check_extra(layout: PlyLayout, extra: int, source: str) -> None:
    """InputError when ``extra`` bytes after the declared binary records hold one more record or more."""
    last = next((e for e in reversed(layout.elements) if _record(e[2])), None)
    if last is not None and extra >= _record(last[2]):
        raise InputError(f"{source}: malformed PLY file: {extra:,} bytes follow the {_declared(layout)} records "
                         "the header "
                         f"declares (room for {extra // _record(last[2]):,} more '{last[0]}' records): "
                         "the counts in the header are too small")


def check_consumed(layout: PlyLayout | None, elements: dict[str, np.ndarray], source: str) -> None:
    """After parsing a binary file with list properties: InputError when the body holds one record or
    more beyond what was read (the header declares too few)."""
    if layout is None or not layout.format.startswith("binary"):
        return
    if not any(len(p) == 3 for _, _, props in layout.elements for p in props):
        return
    used = 0
    for name, count, props in layout.elements:
        used += count * _record(props)
        data = elements.get(name)
        for prop in props:
            if len(prop) != 3 or data is None or prop[0] not in (data.dtype.names or ()):
                continue
            column = data[prop[0]]
            items = (sum(len(x) for x in column) if column.dtype == object else int(np.asarray(column).size))
            used += items * TYPE_SIZES[prop[2]]
    _check_extra(layout, layout.size - layout.body - used, source)


__all__ = ["PlyLayout", "read_layout", "check_body", "check_consumed", "TYPE_SIZES"]
