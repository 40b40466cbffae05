"""``surfsplat export``: a static web viewer of any model ``surfsplat render`` draws.

The model is loaded and prepared by the view plan (:class:`surfsplat.pipeline.View`), exactly as a render
does: files read, raw points preprocessed, meshes sampled for the default camera, colours applied,
hierarchies cut (at the default camera within the point budget, else their finest level). Its splats are
quantized into the web format (:mod:`surfsplat.web.format`, 19 bytes a splat) and written with the
viewer's page and scripts: ``index.html``, ``viewer.js``, ``shaders.js`` (the package's GLSL files composed
for GLSL ES 3.00, :mod:`surfsplat.web.shaders`) and ``data.js`` (the streams as base64: a page opened
from ``file://`` may load scripts but may not ``fetch`` files). An output ending in ``.html`` is one
self-contained file. Nothing is fetched from the internet, nothing is built.
"""

from __future__ import annotations

import html
import json
import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from .. import defaults, progress
from ..errors import InputError
from ..io.atomic import atomic_path, check_writable
from ..io.copc import is_surfsplat_copc, write_copc
from ..pipeline import CameraSpec, LodOptions, SourceOptions, View, check_image_size, check_source
from ..rendering.frame import check_background
from ..version import __version__
from . import format as web_format
from .page import DEFAULT_POINT_BUDGET, as_drawn, exported_splats, page_data, web_order
from .shaders import MAX_PAGE_SUPERSAMPLE, WEB_TECHNIQUES, shader_bundle
from .stream import CELLS_FOLDER, stream_data
from .tree import tree_data

__all__ = ["DEFAULT_POINT_BUDGET", "ExportResult", "as_drawn", "export", "exported_splats", "page_data",
           "page_payload", "web_order"]

#: The files of an exported folder (a folder holding only these, with our index.html, is replaced).
FILES = ("index.html", "viewer.js", "shaders.js", "data.js")
#: The generator tag of the page: what marks a file or folder as an earlier export (replaced without --force).
GENERATOR = "surfsplat export"
#: The page size (CSS pixels) a model is prepared for unless told: the desktop viewer's window. A mesh is
#: sampled as ``surfsplat render --width W --height H`` samples it, a hierarchy cut at that default view.
PAGE_SIZE = defaults.WINDOW_SIZE
#: Bytes of a splat's clip lines on the page: its row (uint32) and two lines of three float16.
CLIP_BYTES = 16
#: What :func:`export` writes: the web viewer, or a COPC file (:mod:`surfsplat.io.copc`).
FORMATS = ("web", "copc")


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export` wrote.

    Attributes:
        path: the folder (or the ``.html`` file).
        splats: splats exported.
        bytes: bytes of the splat streams (``splats * 19``, 3 more a splat with 24-bit positions, 8 more for
            Phong splats' shading normals and normal fields, and 16 for each splat with clip lines).
        seconds: wall-clock time of the whole export.
        files: the files written.
    """

    path: Path
    splats: int
    bytes: int
    seconds: float
    files: tuple[Path, ...]


def _is_export(path: Path) -> bool:
    """Whether ``path`` (a folder or an .html file) was written by :func:`export`."""
    page = path / "index.html" if path.is_dir() else path
    if path.is_dir() and not {p.name for p in path.iterdir()} <= {*FILES, CELLS_FOLDER}:
        return False
    try:
        head = page.read_text(encoding="utf-8", errors="replace")[:2000]
    except OSError:
        return False
    return f'content="{GENERATOR}' in head


def check_export_output(output, force: bool = False) -> tuple[Path, bool]:
    """``(path, single_file)``: where :func:`export` writes (a folder, or one file where the name ends in
    ``.html``), checked before any work. An existing file or non-empty folder that an earlier export did
    not write is refused (InputError) unless ``force``."""
    path = Path(output)
    single = path.suffix.lower() in (".html", ".htm")
    check_writable(path, directory=not single)
    occupied = path.exists() and (not path.is_dir() or any(path.iterdir()))
    if occupied and not force and not _is_export(path):
        what = "folder is not empty" if path.is_dir() else "file exists"
        raise InputError(f"{path}: the {what} and was not written by surfsplat export; pass --force to replace it")
    return path, single


def _script_json(value) -> str:
    """JSON safe inside an HTML ``<script>`` element (no ``</`` closes it)."""
    return json.dumps(value, separators=(",", ":")).replace("</", "<\\/")


def _static(name: str) -> str:
    return resources.files(__package__).joinpath("static").joinpath(name).read_text(encoding="utf-8")


def page_files(header: dict, streams: dict) -> dict[str, str]:
    """The text of each file of an exported folder (:data:`FILES`)."""
    title = html.escape(f"{Path(str(header['name'])).name} - surfsplat")
    scripts = "\n".join(f'<script src="{name}"></script>' for name in ("shaders.js", "data.js", "viewer.js"))
    page = (_static("index.html").replace("{{GENERATOR}}", f"{GENERATOR} {__version__}")
            .replace("{{TITLE}}", title).replace("{{SCRIPTS}}", scripts))
    return {"index.html": page, "viewer.js": _static("viewer.js"),
            "shaders.js": f"window.SURFSPLAT_SHADERS = {_script_json(shader_bundle())};\n",
            "data.js": f"window.SURFSPLAT_DATA = {_script_json({'header': header, 'streams': streams})};\n"}


def single_page(files: dict[str, str]) -> str:
    """One self-contained page: the folder's scripts inlined into its ``index.html``."""
    for name in ("shaders.js", "data.js", "viewer.js"):
        if "</script" in files[name].lower():   # JSON is escaped (_script_json); the viewer has none
            raise InputError(f"{name} cannot be inlined: it contains '</script'")
    inline = "\n".join(f"<script>\n{files[name]}\n</script>" for name in ("shaders.js", "data.js", "viewer.js"))
    scripts = "\n".join(f'<script src="{name}"></script>' for name in ("shaders.js", "data.js", "viewer.js"))
    return files["index.html"].replace(scripts, inline)


def check_page_size(size) -> tuple[int, int]:
    """``(width, height)`` of the page a model is prepared for, checked (InputError) like an image size."""
    if not isinstance(size, (tuple, list)) or len(size) != 2:
        raise InputError(f"page size must be (width, height) in pixels, got {size!r}")
    return check_image_size(size[0], size[1], what="page")


def check_page_args(technique: str, background, point_budget: int | None) -> tuple[float, ...]:
    """The checked background of a page (InputError for a technique the page does not draw, a bad
    background or point budget)."""
    if technique not in WEB_TECHNIQUES:
        raise InputError(f"technique {technique!r} is not drawn by the web viewer; choose one of "
                         f"{', '.join(WEB_TECHNIQUES)}")
    if point_budget is not None and not (isinstance(point_budget, (int, np.integer)) and point_budget >= 1):
        raise InputError(f"point budget must be a whole number >= 1, got {point_budget!r}")
    return tuple(float(c) for c in check_background(background))


def page_payload(source, *, technique: str = "ewa", background=defaults.BACKGROUND,
                 source_options: SourceOptions | None = None, lod: LodOptions | None = None,
                 camera: CameraSpec | None = None, point_budget: int | None = None,
                 browser_lod: bool = False, size=PAGE_SIZE, supersample: int = 1,
                 position_bits: int = 16) -> tuple[dict, dict]:
    """The header and the base64 streams of a page showing ``source`` (:func:`export`'s arguments): the
    model prepared by the view plan for the page's ``size``, cut within the budget (or with ``browser_lod``
    its whole hierarchy, :mod:`surfsplat.web.tree`), quantized (what ``data.js`` holds). A chunked
    hierarchy with ``browser_lod`` streams its cells from files: only :func:`export` writes it."""
    header, streams, files = _payload(source, technique, background, source_options, lod, camera, point_budget,
                                      browser_lod, size, None, supersample, position_bits)
    if files:
        raise InputError(f"{header['name']}: a chunked hierarchy streamed to the page needs a folder of cell files: "
                         "export it (surfsplat export --browser-lod), or without browser LOD")
    return header, streams


def _payload(source, technique, background, source_options, lod, camera, point_budget, browser_lod, size,
             memory_budget, supersample=1, position_bits=16) -> tuple[dict, dict, dict[str, str]]:
    """:func:`page_payload`'s header and streams, and the cell files of a streamed chunked hierarchy."""
    background = check_page_args(technique, background, point_budget)
    if not (isinstance(supersample, (int, np.integer)) and 1 <= supersample <= MAX_PAGE_SUPERSAMPLE):
        raise InputError(f"the page's supersampling must be a whole number of sub-pixels from 1 to "
                         f"{MAX_PAGE_SUPERSAMPLE}, got {supersample!r}")
    if not isinstance(position_bits, (int, np.integer)) or isinstance(position_bits, bool) \
            or position_bits not in web_format.POSITION_BITS:
        raise InputError(f"the page's position bits must be one of {', '.join(map(str, web_format.POSITION_BITS))}, "
                         f"got {position_bits!r}")
    fine = position_bits == 24
    width, height = check_page_size(size)
    check_source(source)
    plan = View(source, source_options=source_options, lod=lod)
    view_camera = plan.camera(camera, width, height)
    with progress.stage("exporting for the web"):
        if browser_lod:
            if not plan.tree(view_camera).in_memory:
                header, streams, files = stream_data(plan, view_camera, technique, background, plan.name,
                                                     point_budget, memory_budget)
            else:
                header, streams = tree_data(plan, view_camera, technique, background, plan.name, point_budget,
                                            fine)
                files = {}
        else:
            cloud = exported_splats(plan, view_camera, point_budget)
            header, streams = page_data(plan, view_camera, cloud, technique, background, plan.name,
                                        fine_positions=fine)
            files = {}
    header["supersample"] = int(supersample)
    return header, streams, files


def export(source, output, *, technique: str = "ewa", background=defaults.BACKGROUND,
           source_options: SourceOptions | None = None, lod: LodOptions | None = None,
           camera: CameraSpec | None = None, point_budget: int | None = None, browser_lod: bool = False,
           force: bool = False, format: str | None = None, size=PAGE_SIZE, supersample: int = 1,
           memory_budget: int | None = None, position_bits: int = 16) -> ExportResult:
    """Write a static web viewer of ``source`` to ``output``: a folder (``index.html``, ``viewer.js``,
    ``shaders.js``, ``data.js``), or one self-contained file where ``output`` ends in ``.html``.

    Args:
        source: anything :func:`surfsplat.render` takes (a file, ``demo:NAME``, a SplatCloud, a Mesh,
            a hierarchy), prepared by :class:`~surfsplat.pipeline.View` as a render prepares it.
        technique: the page's first technique, one of :data:`~surfsplat.web.shaders.WEB_TECHNIQUES` (every
            technique of ``surfsplat render``; switchable on the page).
        background: the page's first background, RGB in [0, 1].
        source_options, lod: as :func:`surfsplat.render` takes them.
        camera: the view a mesh is sampled for and a hierarchy cut at (None: the automatic one of
            ``surfsplat render`` at ``size``). The page opens at its own default view.
        point_budget: at most this many splats from a hierarchy or a cloud (default 5,000,000); with
            ``browser_lod`` the page's first budget (default 1,000,000, changed on the page).
        browser_lod: export the whole hierarchy (a cloud's built) and let the page cut it per view: a
            point budget in Potree's priority, refined when the camera stops (:mod:`surfsplat.web.tree`).
            A chunked hierarchy is written as a folder of cell files that the page loads on demand
            (:mod:`surfsplat.web.stream`), from a static web server or from ``file://``.
        memory_budget: with a streamed chunked hierarchy, the page's first budget (bytes of loaded
            cells' GPU arrays; default :data:`~surfsplat.web.stream.DEFAULT_MEMORY_BUDGET`).
        force: replace an existing file or non-empty folder that an earlier export did not write.
        format: "web" or "copc" (None: "copc" where ``output`` ends in ``.copc.laz``, else "web"): a COPC
            file (LAS 1.4 octree, :func:`surfsplat.io.copc.write_copc`) of the splats a page would draw.
        size: ``(width, height)``, the page size in CSS pixels the model is prepared for (default
            :data:`PAGE_SIZE`): a mesh is sampled for the default view at that size, as ``surfsplat render``
            at that size samples it (the density the page can show), a hierarchy cut there.
        supersample: K, the page's first supersampling (1 to 4; ``?supersample=K`` changes it): every pass
            drawn on K x K sub-pixels a pixel and reduced, as ``surfsplat render --supersample K`` draws.
        position_bits: 16 (19 bytes a splat) or 24 (22 bytes a splat: a ``position_fine`` stream): the
            centres' precision within the model's box. 16 bits lose nothing against the mesh that matters;
            24 bits draw the desktop's very silhouette pixels (the bunny at 1024 x 768 against
            ``surfsplat render``: 71-85 dB for every technique, 49-67 dB with 16 bits). Streamed chunked
            cells keep 16.

    Returns:
        :class:`ExportResult` (for COPC, ``bytes`` is the size of the file).
    """
    start = time.perf_counter()
    format = format or ("copc" if str(output).lower().endswith(".copc.laz") else "web")
    if format not in FORMATS:
        raise InputError(f"export format {format!r} is not one of {', '.join(FORMATS)}")
    check_page_args(technique, background, point_budget)
    size = check_page_size(size)
    if memory_budget is not None and not (isinstance(memory_budget, (int, np.integer)) and memory_budget >= 1):
        raise InputError(f"memory budget must be a whole number of bytes >= 1, got {memory_budget!r}")
    if format == "copc":
        return _export_copc(source, output, source_options, lod, camera, point_budget, force, start, size)
    path, single = check_export_output(output, force)
    header, streams, cells = _payload(source, technique, background, source_options, lod, camera, point_budget,
                                      browser_lod, size, memory_budget, supersample, position_bits)
    files = page_files(header, streams)
    if cells and single:
        raise InputError(f"{path}: a chunked hierarchy streamed to the page is a folder of cell files; "
                         "name a folder, not an .html file")
    files.update(cells)
    written: list[Path] = []
    if single:
        with atomic_path(path) as temp:
            Path(temp).write_text(single_page(files), encoding="utf-8")
        written.append(path)
    else:
        with atomic_path(path, directory=True) as temp:
            Path(temp).chmod(0o755)   # a web server's user reads it (mkdtemp makes it the owner's alone)
            for name, text in files.items():
                target = Path(temp) / name
                if not target.parent.is_dir():
                    target.parent.mkdir(parents=True)
                    target.parent.chmod(0o755)
                target.write_text(text, encoding="utf-8")
        written.extend(path / name for name in files)
    streamed = sum(int(c["entries"]) for c in header["lod"]["streamed"]["cells"]) if cells else 0
    count = int(header["count"]) + streamed
    # streamed cells keep 16-bit positions (stream.py)
    per_splat = (web_format.BYTES_PER_SPLAT + (web_format.FINE_BYTES if "position_fine" in streams else 0)
                 + (web_format.FIELD_BYTES if header.get("normal_fields") else 0))
    size_bytes = (int(header["count"]) * per_splat + streamed * web_format.BYTES_PER_SPLAT
                  + int(header.get("clip_lines", 0)) * CLIP_BYTES)
    return ExportResult(path, count, size_bytes, time.perf_counter() - start, tuple(written))


def _export_copc(source, output, source_options, lod, camera, point_budget, force, start, size) -> ExportResult:
    """:func:`export` to a COPC file: the splats a page would draw, written by :func:`write_copc`. An existing
    file is replaced only where surfsplat wrote it or with ``force``."""
    path = check_writable(output)
    if path.exists() and not force and not is_surfsplat_copc(path):
        raise InputError(f"{path}: the file exists and was not written by surfsplat export; pass --force to "
                         "replace it")
    check_source(source)
    plan = View(source, source_options=source_options, lod=lod)
    view_camera = plan.camera(camera, *size)
    with progress.stage("exporting to COPC"):
        result = write_copc(exported_splats(plan, view_camera, point_budget), path)
    return ExportResult(path, result.points, result.bytes, time.perf_counter() - start, (path,))
