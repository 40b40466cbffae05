"""GLSL sources from the package's ``glsl/`` folder, with ``#include`` and ``#define`` injection.

A shader file names its stage by its extension-free role; ``#include "x.glsl"``
pulls another file of the folder in (once; cycles raise). Defines are injected
after ``#version`` and followed by a ``#line`` directive so compiler errors
point at the right line of the file.
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources

from ..errors import RenderError

GLSL_VERSION = "#version 330 core"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


@lru_cache(maxsize=None)
def read_glsl(name: str, package: str = __package__) -> str:
    """The text of ``glsl/<name>`` inside ``package`` (default: the renderer's; cached)."""
    try:
        return resources.files(package).joinpath("glsl", name).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RenderError(f"shader file {package}/glsl/{name} is missing from the package") from None


def _expand(name: str, stack: tuple[str, ...], seen: set[str]) -> str:
    if name in stack:
        raise RenderError(f"#include cycle: {' -> '.join(stack + (name,))}")
    if name in seen:
        return ""
    seen.add(name)
    text = read_glsl(name)

    def include(match: re.Match) -> str:
        return _expand(match.group(1), stack + (name,), seen) + "\n"

    return _INCLUDE.sub(include, text)


def build_source(name: str, defines: dict[str, object] | None = None) -> str:
    """The complete source of ``glsl/<name>``: version line, defines, includes expanded."""
    body = _expand(name, (), set())
    lines = [GLSL_VERSION]
    for key, value in sorted((defines or {}).items()):
        if not re.fullmatch(r"[A-Z_][A-Z0-9_]*", key):
            raise RenderError(f"invalid shader define name {key!r}")
        lines.append(f"#define {key} {int(value) if isinstance(value, bool) else value}")
    lines.append("#line 1")
    return "\n".join(lines) + "\n" + body
