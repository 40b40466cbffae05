"""The frame's uniform blocks: std140 layouts read from the GLSL files, one buffer written once per frame.

``camera.glsl`` declares the block ``Camera`` (view matrix, tile, viewport, near/far, focal length),
``lighting.glsl`` the block ``Lighting`` (lights and material) and ``frame_options.glsl`` the block
``Options`` (the visibility and deferred options, the sub-pixel factor), all ``layout(std140)``. Every
program of a frame that includes them reads the same buffer: the renderer binds each block of a
program it builds to its binding point (:data:`FRAME_BLOCKS`) once, and per frame writes the values
into one buffer and binds its ranges (:class:`FrameBlocks`), instead of setting these uniforms on
each program. The GLSL files stay the one source: the members, their order and types are parsed from
the block declarations (:func:`block_layout`) and laid out by the std140 rules (OpenGL 4.6 core
profile, sec. 7.6.2.2); a program's own block size is checked against the layout.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import moderngl
import numpy as np

from ..errors import RenderError
from .shaders import BLOCK_MEMBER, SHARED_DEFINES, STD140_BLOCK, read_source

#: Uniform blocks of a frame: block name -> (the GLSL file declaring it, its binding point).
FRAME_BLOCKS: dict[str, tuple[str, int]] = {"Camera": ("camera.glsl", 0), "Lighting": ("lighting.glsl", 1),
                                            "Options": ("frame_options.glsl", 2)}

#: std140 scalar and vector types: (NumPy dtype of a component, components, base alignment in bytes).
#: A bool is a 32-bit integer (0 or 1); a mat4 is four vec4 columns (column-major).
_TYPES = {"float": ("<f4", 1, 4), "int": ("<i4", 1, 4), "uint": ("<u4", 1, 4), "bool": ("<u4", 1, 4),
          "vec2": ("<f4", 2, 8), "vec3": ("<f4", 3, 16), "vec4": ("<f4", 4, 16), "mat4": ("<f4", 16, 16)}
_COMMENTS = re.compile(r"//[^\n]*|/\*.*?\*/", re.DOTALL)


def _align(offset: int, alignment: int) -> int:
    return -(-offset // alignment) * alignment


@dataclass(frozen=True)
class Member:
    """A member of a std140 block: its GLSL type, array length (None: no array), byte offset."""

    name: str
    type: str
    length: int | None
    offset: int

    def write(self, data: np.ndarray, value) -> None:
        """Write ``value`` (a number, a sequence of components; a column-major mat4 as 16 numbers; an
        array as a sequence of such) into the block's bytes ``data``."""
        dtype, components, _ = _TYPES[self.type]
        stride = 16 if (self.length is not None or self.type == "mat4") else 0
        rows = 1 if self.length is None else self.length
        width = 4 if self.type == "mat4" else components   # per row: a mat4's column, an element
        values = np.asarray(value, dtype=np.float64).reshape(-1)
        expected = rows * (16 if self.type == "mat4" else components)
        if values.size != expected:
            raise RenderError(f"uniform {self.name} ({self.type}{'' if self.length is None else f'[{self.length}]'}) "
                              f"takes {expected} numbers, got {values.size}")
        values = values.astype(dtype)
        if not stride:
            data[self.offset:self.offset + 4 * components] = values.view(np.uint8)
            return
        per = values.reshape(-1, width)
        for i, row in enumerate(per):   # at most MAX_LIGHTS or 4 rows
            start = self.offset + i * stride
            data[start:start + 4 * width] = row.view(np.uint8)


@dataclass(frozen=True)
class BlockLayout:
    """The std140 layout of a uniform block: its members in order and its size in bytes."""

    name: str
    members: tuple[Member, ...]
    size: int

    @property
    def names(self) -> frozenset[str]:
        """The members' names."""
        return frozenset(m.name for m in self.members)

    def pack(self, values: dict) -> bytes:
        """The block's bytes for ``values`` (member name -> value; every member needed)."""
        missing = sorted(self.names - set(values))
        if missing:
            raise RenderError(f"uniform block {self.name} needs {', '.join(missing)}")
        data = np.zeros(self.size, np.uint8)
        for member in self.members:
            member.write(data, values[member.name])
        return data.tobytes()


def block_layout(name: str, source: str) -> BlockLayout:
    """The std140 layout of the block ``name`` declared in a GLSL ``source``
    (``layout(std140) uniform NAME { TYPE member; TYPE member[LENGTH]; ... };``, the length a number
    or a shared constant of ``shaders.SHARED_DEFINES``)."""
    blocks = {m.group(1): m.group(2) for m in STD140_BLOCK.finditer(_COMMENTS.sub(" ", source))}
    if name not in blocks:
        raise RenderError(f"no layout(std140) uniform block {name} in the shader source")
    members, offset = [], 0
    for declaration in blocks[name].split(";"):
        if not declaration.strip():
            continue
        match = BLOCK_MEMBER.match(declaration)
        if not match or match.group(1) not in _TYPES:
            raise RenderError(f"uniform block {name}: cannot lay out {declaration.strip()!r} "
                              f"(types: {', '.join(_TYPES)})")
        kind, member, length = match.groups()
        if length is not None:
            length = int(SHARED_DEFINES.get(length, length))
        _, components, alignment = _TYPES[kind]
        if length is not None or kind == "mat4":   # arrays and matrices: vec4-aligned rows
            alignment, size = 16, 16 * (length or 1) * (4 if kind == "mat4" else 1)
        else:
            size = 4 * components
        offset = _align(offset, alignment)
        members.append(Member(member, kind, length, offset))
        offset += size
    return BlockLayout(name, tuple(members), _align(offset, 16))


class FrameBlocks:
    """The frame's uniform blocks (:data:`FRAME_BLOCKS`) in one buffer of a context.

    Args:
        ctx: the context.
        search_path: folders searched for the GLSL files before the package's ``glsl/`` (as the
            renderer's programs are composed).
    """

    def __init__(self, ctx: moderngl.Context, search_path: Sequence[Path] = ()):
        self.ctx = ctx
        self.layouts = {name: block_layout(name, read_source(file, search_path))
                        for name, (file, _) in FRAME_BLOCKS.items()}
        alignment = int(ctx.info.get("GL_UNIFORM_BUFFER_OFFSET_ALIGNMENT", 256))
        self.offsets, end = {}, 0
        for name, layout in self.layouts.items():
            self.offsets[name] = end
            end = _align(end + layout.size, alignment)
        self.buffer = ctx.buffer(reserve=end)
        self.members = frozenset().union(*(layout.names for layout in self.layouts.values()))

    def attach(self, program: moderngl.Program | moderngl.ComputeShader) -> None:
        """Bind the frame blocks ``program`` uses to their binding points (once per program);
        RenderError where its block's size differs from the layout (a declaration this module cannot
        lay out as the driver does)."""
        for name, (_, binding) in FRAME_BLOCKS.items():
            if name in program:
                block = program[name]
                if block.size != self.layouts[name].size:
                    raise RenderError(f"uniform block {name}: the driver lays out {block.size} bytes, "
                                      f"the std140 layout {self.layouts[name].size}")
                block.binding = binding

    def bind(self, values: dict) -> None:
        """Write the blocks from ``values`` (member name -> value, e.g. ``Renderer.frame_uniforms``;
        other names are ignored) and bind them: each block whose members are all given (a block none
        of whose members is given is left as it is)."""
        for name, layout in self.layouts.items():
            if not layout.names & set(values):
                continue
            self.buffer.write(layout.pack(values), offset=self.offsets[name])
            self.buffer.bind_to_uniform_block(FRAME_BLOCKS[name][1], offset=self.offsets[name], size=layout.size)

    def release(self) -> None:
        """Free the buffer."""
        self.buffer.release()
