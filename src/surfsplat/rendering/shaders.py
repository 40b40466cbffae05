"""GLSL sources composed from ``glsl/`` files: ``#include``, shared ``#define``s and ``#line`` mapping.

Composing a shader file (:func:`compose`) gives one source string:

- line 1 is :data:`GLSL_VERSION`, then the ``#define``s: :data:`SHARED_DEFINES`
  (constants that Python and GLSL share, defined here once), then the caller's
  (e.g. ``PASS``). These lines are the prologue, source string 0.
- ``#include "x.glsl"`` alone on a line pastes in another file of the search
  path (the package's ``glsl/`` folder last), once per composition: a second
  include of the same file is dropped, a cycle raises RenderError.
- Every file gets a number k >= 1 in order of first use (a program's two
  stages share the numbering: :func:`build_program`). A ``#line`` directive
  precedes each file's text and follows each pasted include, so that line L of
  file k is compiled as line ``k * LINE_STRIDE + L`` of source string k: the
  directive is ``#line {k * LINE_STRIDE + L} {k}``. Both carry the file because
  Mesa reports many semantic errors (an undeclared name, a type mismatch) as
  source string 0 whatever ``#line`` said; the line number alone still names
  file and line. :func:`translate_log` rewrites compiler messages
  (``3:30008(12): error``, Mesa; ``ERROR: 3:30008:``, glslang-style drivers;
  ``3(30008) :``, NVIDIA) to ``ewa.vert:8(12): error`` and so on.

:func:`build_program` composes both stages, links them and raises
RenderError with the translated log; it also returns the uniform names the
sources declare (:func:`declared_uniforms`), which the renderer checks uniform
values against.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Iterable, Sequence

import moderngl

from ..errors import RenderError
from ..lighting import MAX_LIGHTS
from ..reference import EDGE_ON_TOLERANCE, PERSPECTIVE_MAX_CONDITION, PERSPECTIVE_NEAR_FRACTION

GLSL_VERSION = "#version 330 core"

#: The version line of compute shaders (``*.comp``), used only where the context has OpenGL 4.3.
COMPUTE_GLSL_VERSION = "#version 430 core"

#: The version line of the GLSL ES 3.00 variant (WebGL2: the browser viewer, :mod:`surfsplat.web`).
GLSL_ES_VERSION = "#version 300 es"

#: The default precisions an ES source declares after its version line: GLSL ES gives fragment
#: shaders no default float precision and samplers only lowp; the desktop's float32 everywhere is highp.
ES_PRECISION = ("precision highp float;", "precision highp int;", "precision highp sampler2D;",
                "precision highp usampler2D;")

#: Invocations per work group of the compute shaders (their ``COMPUTE_GROUP`` macro).
COMPUTE_GROUP = 64

#: Pass ids: the value of a splat program's ``PASS`` macro (renderer.py runs the passes).
#: PASS_OPAQUE: the one pass of an opaque technique; PASS_VISIBILITY: depth only, offset
#: by epsilon; PASS_ACCUMULATION: additive blending of weighted colors, depths, normals.
PASS_OPAQUE, PASS_VISIBILITY, PASS_ACCUMULATION = 0, 1, 2

#: The visibility pass's value where no disk is drawn, larger than any depth (glsl/visibility.glsl).
NO_DEPTH = 1e37
#: The depth the normalization and fill passes give an uncovered pixel (glsl/fill.frag).
FILL_FAR = 1e30

#: Constants shared by Python and GLSL, defined once here and injected as ``#define``
#: into every composed shader; the GLSL files use the macro names.
SHARED_DEFINES: dict[str, int | float] = {
    # lighting.py: largest number of directional lights (size of u_light_dirs)
    "MAX_LIGHTS": MAX_LIGHTS,
    # the pass ids above (#if PASS == PASS_VISIBILITY)
    "PASS_OPAQUE": PASS_OPAQUE,
    "PASS_VISIBILITY": PASS_VISIBILITY,
    "PASS_ACCUMULATION": PASS_ACCUMULATION,
    # reference.py: perspective splats ray-cast beyond this condition number of M_k / this near fraction
    "PERSPECTIVE_MAX_CONDITION": PERSPECTIVE_MAX_CONDITION,
    "PERSPECTIVE_NEAR_FRACTION": PERSPECTIVE_NEAR_FRACTION,
    # reference.py: a splat with |n . p| <= this * |p| is seen edge-on through the eye (culled)
    "EDGE_ON_TOLERANCE": EDGE_ON_TOLERANCE,
    # renderer.py clears the visibility pass's target to it: no disk (glsl/visibility.glsl)
    "NO_DEPTH": NO_DEPTH,
    # normalize.frag and fill.frag: the depth of an uncovered pixel
    "FILL_FAR": FILL_FAR,
}

#: Line numbers of file k are ``k * LINE_STRIDE + line`` (a file may have fewer lines).
LINE_STRIDE = 10000

#: Name of source string 0 in the line map: the version line and the defines.
PROLOGUE = "<prologue>"

_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')
_DEFINE_NAME = re.compile(r"[A-Z_][A-Z0-9_]*")


@lru_cache(maxsize=None)
def read_glsl(name: str, package: str = __package__) -> str:
    """The text of ``glsl/<name>`` inside ``package`` (default: the renderer's; cached)."""
    try:
        return resources.files(package).joinpath("glsl", name).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RenderError(f"shader file {package}/glsl/{name} is missing from the package") from None


def _read(name: str, search_path: Sequence[Path], where: str) -> str:
    """The text of ``name`` from the first folder of ``search_path`` holding it, else the package's."""
    for folder in search_path:
        candidate = Path(folder) / name
        if candidate.is_file():
            return candidate.read_text(encoding="utf-8")
    try:
        return read_glsl(name)
    except RenderError as exc:
        if not search_path:
            raise RenderError(f"{where}{exc}") from None
        folders = ", ".join(str(f) for f in search_path)
        raise RenderError(f"{where}shader file {name} is missing: neither in {folders} nor in the package") from None


@dataclass(frozen=True)
class ComposedSource:
    """One composed shader source and where each of its lines comes from.

    Attributes:
        name: the file composed.
        text: the source to compile.
        files: file name of each source string number (0: :data:`PROLOGUE`);
            shared with the other stage of a program, so it may list files of both.
        origins: per line of ``text`` (index 0 is line 1): ``(file, line)`` in
            that file (1-based), or None for a ``#line`` directive added here.
        uniforms: uniform names the source declares (:func:`declared_uniforms`), with the members
            of its ``layout(std140)`` uniform blocks (:func:`block_members`).
    """

    name: str
    text: str
    files: tuple[str, ...]
    origins: tuple[tuple[str, int] | None, ...]
    uniforms: frozenset[str]

    def origin(self, line: int) -> tuple[str, int] | None:
        """``(file, line)`` of line ``line`` (1-based) of :attr:`text`; None for an added directive."""
        return self.origins[line - 1]


def _define_value(key: str, value) -> str:
    if isinstance(value, bool):
        return str(int(value))
    if isinstance(value, float):
        if value != value or value in (float("inf"), float("-inf")):
            raise RenderError(f"shader define {key} must be finite, got {value}")
        return repr(value)  # always has '.' or 'e': a GLSL float literal
    return str(value)


def prologue(defines: dict[str, object] | None = None, version: str = GLSL_VERSION) -> list[str]:
    """The version line (with :data:`ES_PRECISION` after :data:`GLSL_ES_VERSION`) and the ``#define`` lines:
    :data:`SHARED_DEFINES`, then ``defines`` (sorted)."""
    lines = [version] + (list(ES_PRECISION) if version == GLSL_ES_VERSION else [])
    own = dict(defines or {})
    for key, value in list(SHARED_DEFINES.items()) + sorted(own.items()):
        if not _DEFINE_NAME.fullmatch(key):
            raise RenderError(f"invalid shader define name {key!r}")
        lines.append(f"#define {key} {_define_value(key, value)}")
    clash = sorted(set(own) & set(SHARED_DEFINES))
    if clash:
        raise RenderError(f"shader defines {', '.join(clash)} are shared constants (shaders.SHARED_DEFINES)")
    return lines


def compose(name: str, defines: dict[str, object] | None = None, *, search_path: Sequence[Path] = (),
            files: list[str] | None = None, version: str = GLSL_VERSION) -> ComposedSource:
    """The complete source of shader file ``name``: prologue, includes pasted in, ``#line`` directives.

    Args:
        name: a file of ``search_path`` or of the package's ``glsl/`` folder.
        defines: macro name -> value (bool as 0/1), after :data:`SHARED_DEFINES`.
        search_path: folders searched for files before the package's ``glsl/``.
        files: the source-string numbering to extend (``files[k]`` is file k;
            give both stages of a program the same list); a new one by default.
        version: the ``#version`` line (:data:`COMPUTE_GLSL_VERSION` for compute shaders,
            :data:`GLSL_ES_VERSION` for WebGL2).

    Raises:
        RenderError: a file is missing, an include cycle, a bad define, a file
            of :data:`LINE_STRIDE` lines or more.
    """
    files = [PROLOGUE] if files is None else files
    if not files:
        files.append(PROLOGUE)
    lines = prologue(defines, version)
    origins: list[tuple[str, int] | None] = [(PROLOGUE, i + 1) for i in range(len(lines))]
    seen: set[str] = set()

    def directive(file: str, line: int) -> None:
        k = files.index(file)
        lines.append(f"#line {k * LINE_STRIDE + line} {k}")
        origins.append(None)

    def expand(file: str, stack: tuple[str, ...], where: str) -> None:
        if file in stack:
            raise RenderError(f"#include cycle: {' -> '.join(stack + (file,))}")
        seen.add(file)
        text = _read(file, search_path, where)
        body = text.splitlines()
        if len(body) >= LINE_STRIDE:
            raise RenderError(f"shader file {file} has {len(body)} lines; at most {LINE_STRIDE - 1} are supported")
        if file not in files:
            files.append(file)
        directive(file, 1)
        for number, line in enumerate(body, 1):
            match = _INCLUDE.match(line)
            if match is None:
                lines.append(line)
                origins.append((file, number))
            elif match.group(1) in seen and match.group(1) not in stack + (file,):
                lines.append("")  # included before: the line stays, empty
                origins.append((file, number))
            else:
                expand(match.group(1), stack + (file,), f"{file}:{number}: ")
                directive(file, number + 1)

    expand(name, (), "")
    text = "\n".join(lines) + "\n"
    return ComposedSource(name, text, tuple(files), tuple(origins), declared_uniforms(text) | block_members(text))


def build_source(name: str, defines: dict[str, object] | None = None, *, search_path: Sequence[Path] = ()) -> str:
    """The composed source text of ``name`` (see :func:`compose`)."""
    return compose(name, defines, search_path=search_path).text


_COMMENTS = re.compile(r"//[^\n]*|/\*.*?\*/", re.DOTALL)
_UNIFORM = re.compile(r"\buniform\s+(?:(?:lowp|mediump|highp)\s+)?\w+\s+([^;{}()]+);")
#: A std140 uniform block and its members' text (uniform_blocks.py lays it out).
STD140_BLOCK = re.compile(r"layout\s*\(\s*std140\s*\)\s*uniform\s+(\w+)\s*\{([^}]*)\}\s*;")
#: A member of a block: type, name, array length (a number or a macro).
BLOCK_MEMBER = re.compile(r"^\s*(\w+)\s+(\w+)\s*(?:\[\s*(\w+)\s*\])?\s*$")


def declared_uniforms(source: str) -> frozenset[str]:
    """Names of the uniforms a GLSL source declares (``uniform <type> <name>[, <name>...];``).

    Read from the text, not from the linked program: compilers drop declared
    uniforms that no code path uses, and those are declared all the same.
    Declarations in preprocessor branches not taken count too.
    """
    names = set()
    for match in _UNIFORM.finditer(_COMMENTS.sub(" ", source)):
        for declarator in match.group(1).split(","):
            name = re.match(r"\s*(\w+)", declarator)
            if name:
                names.add(name.group(1))
    return frozenset(names)


def block_members(source: str) -> frozenset[str]:
    """Names of the members of the ``layout(std140)`` uniform blocks a GLSL source declares (set by
    the blocks' buffer, :mod:`~surfsplat.rendering.uniform_blocks`, not per program)."""
    names = set()
    for match in STD140_BLOCK.finditer(_COMMENTS.sub(" ", source)):
        for declaration in match.group(2).split(";"):
            member = BLOCK_MEMBER.match(declaration)
            if member:
                names.add(member.group(2))
    return frozenset(names)


def read_source(name: str, search_path: Sequence[Path] = ()) -> str:
    """The text of shader file ``name`` from the first folder of ``search_path`` holding it, else the
    package's ``glsl/`` (as :func:`compose` reads it, without includes)."""
    return _read(name, search_path, "")


# Message positions: Mesa "S:L(C): error", glslang-style "ERROR: S:L: ...", NVIDIA "S(L) : error".
_POSITION = re.compile(r"^(?P<lead>\s*(?:(?:ERROR|WARNING|error|warning):\s*)?)(?P<src>\d+)"
                       r"(?::(?P<line>\d+)|\((?P<paren>\d+)\))", re.MULTILINE)


def source_location(source: int, line: int, files: Sequence[str]) -> tuple[str, int] | None:
    """``(file, line)`` of a compiler position (source string, line) of a composed source; None
    when it is no position of ours. The line number decides (see the module docstring)."""
    k, local = divmod(line, LINE_STRIDE)
    if k == 0:
        return (files[0], local) if source == 0 and files else None
    if k >= len(files) or local == 0:
        return None
    return files[k], local


def translate_log(log: str, files: Sequence[str]) -> str:
    """A compiler log with positions in composed sources rewritten as ``file:line``."""

    def replace(match: re.Match) -> str:
        line = int(match.group("line") or match.group("paren"))
        where = source_location(int(match.group("src")), line, files)
        if where is None:
            return match.group(0)
        return f"{match.group('lead')}{where[0]}:{where[1]}"

    return _POSITION.sub(replace, log)


@dataclass(frozen=True, eq=False)
class BuiltProgram:
    """A linked program, its files and the uniforms its sources declare.

    Attributes:
        program: the moderngl program.
        name: ``"vertex/fragment"`` file names, for messages.
        uniforms: uniform names declared in either stage (active or not).
    """

    program: moderngl.Program
    name: str
    uniforms: frozenset[str]


def build_program(ctx: moderngl.Context, vertex: str, fragment: str, defines: dict[str, object] | None = None,
                  *, search_path: Sequence[Path] = (), version: str = GLSL_VERSION) -> BuiltProgram:
    """Compose (:func:`compose`, one file numbering for both stages, ``version`` their ``#version`` line),
    compile and link a program.

    Raises:
        RenderError: composing failed, or the driver's log, positions
            translated to ``file:line`` (:func:`translate_log`).
    """
    files = [PROLOGUE]
    vs = compose(vertex, defines, search_path=search_path, files=files, version=version)
    fs = compose(fragment, defines, search_path=search_path, files=files, version=version)
    name = f"{vertex}/{fragment}"
    try:
        program = ctx.program(vertex_shader=vs.text, fragment_shader=fs.text)
    except moderngl.Error as exc:
        raise RenderError(f"shader {name} failed to build: {translate_log(str(exc), files)}") from None
    return BuiltProgram(program, name, vs.uniforms | fs.uniforms)


def build_compute(ctx: moderngl.Context, name: str, defines: dict[str, object] | None = None,
                  *, search_path: Sequence[Path] = ()) -> BuiltProgram:
    """Compose (:func:`compose`, :data:`COMPUTE_GLSL_VERSION`, ``COMPUTE_GROUP`` defined) and compile a
    compute shader (OpenGL 4.3).

    Raises:
        RenderError: composing failed, or the driver's log, positions translated to ``file:line``.
    """
    files = [PROLOGUE]
    source = compose(name, (defines or {}) | {"COMPUTE_GROUP": COMPUTE_GROUP}, search_path=search_path,
                     files=files, version=COMPUTE_GLSL_VERSION)
    try:
        program = ctx.compute_shader(source.text)
    except moderngl.Error as exc:
        raise RenderError(f"shader {name} failed to build: {translate_log(str(exc), files)}") from None
    return BuiltProgram(program, name, source.uniforms)


def undeclared(values: Iterable[str], declared: frozenset[str], optional: Iterable[str] = ()) -> list[str]:
    """The names among ``values`` neither declared nor optional, sorted."""
    return sorted(set(values) - declared - set(optional))
