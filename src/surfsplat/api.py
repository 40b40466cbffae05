"""The public functions: one picture (:func:`render`), a prepared view for many cameras
(:func:`prepare`), the mesh ground truth (:func:`render_mesh`) and turntables.

Each of them drives the view plan (:mod:`surfsplat.pipeline`), as the command line, the viewer
and the notebook widget do; none decides anything of its own. Every argument is checked before
any file is read (:func:`check_render_args`).
"""

from __future__ import annotations

from . import defaults, progress
from .camera import Camera
from .camera_path import orbit_cameras
from .cloud import SplatCloud
from .errors import InputError
from .io import Mesh, load_mesh
from .lighting import Lights
from .pipeline import (CameraSpec, LodOptions, SourceOptions, View, check_coverage, check_image_size,
                       check_render_args, check_source, natural_up)
from .pipeline.framing import resolve_camera
from .pipeline.models import as_model
from .rendering.frame import Frame, check_background
from .rendering.mesh import render_mesh as rasterize_mesh
from .rendering.options import RenderOptions, TechniqueName
from .rendering.renderer import content_key, default_renderer
from .rendering.tiles import check_supersample

__all__ = ["fit", "load_model", "orbit_cameras", "prepare", "render", "render_mesh", "turntable_frames"]


def prepare(source, *, source_options: SourceOptions | None = None, lod: LodOptions | None = None) -> View:
    """A :class:`~surfsplat.pipeline.View` of ``source``: loaded once (a mesh sampled for the first
    camera drawn, a cloud's hierarchy built once), then ``view.render(camera, ...)`` for any number of
    cameras, each returning a :class:`~surfsplat.pipeline.RenderResult`. Arguments as :func:`render`."""
    return View(source, source_options=source_options, lod=lod)


#: The last view :func:`render` made of a SplatCloud: ``(cloud, its content key, (source_options, lod), view)``.
_last_view: tuple | None = None


def _view_of(source, source_options: SourceOptions | None, lod: LodOptions | None) -> View:
    """:func:`prepare` of ``source``; for a SplatCloud, the view made by the last call when it was of this
    very cloud holding the same bytes (its :func:`~surfsplat.rendering.renderer.content_key`, which the
    renderer then reuses to find its upload) and the same options: a cloud rendered again and again is
    prepared once (its orientation, up axis, hierarchy), as a :func:`prepare`'d view would be."""
    global _last_view
    if not isinstance(source, SplatCloud):
        return prepare(source, source_options=source_options, lod=lod)
    key, settings = content_key(source), (source_options, lod)
    last = _last_view
    if last is not None and last[0] is source and last[1] == key and last[2] == settings:
        return last[3]
    _last_view = None   # the previous cloud is not kept while this one is prepared
    view = prepare(source, source_options=source_options, lod=lod)
    view.source_key = key
    _last_view = (source, key, settings, view)
    return view


def load_model(source, source_options: SourceOptions | None = None):
    """What :func:`render` draws of ``source``, loaded: a SplatCloud (raw points preprocessed), a
    Hierarchy, a chunked hierarchy or a Mesh (its surface is sampled per view), coloured as
    ``source_options.color`` says. ``render(load_model(p))`` draws what ``render(p)`` draws."""
    return prepare(source, source_options=source_options).model.data


def render(source, camera: Camera | CameraSpec | None = None, *, technique: TechniqueName = "ewa",
           width: int = defaults.API_IMAGE_SIZE, height: int = defaults.API_IMAGE_SIZE, lights: Lights | None = None,
           background=defaults.BACKGROUND, options: RenderOptions | None = None, lod: LodOptions | None = None,
           supersample: int = 1, source_options: SourceOptions | None = None) -> Frame:
    """Render a SplatCloud, a hierarchy, a mesh, a file or a built-in scene to a :class:`Frame`.

    Args:
        source: a SplatCloud (preprocessed if it lacks normals or splat axes), a
            :class:`~surfsplat.hierarchy.Hierarchy`, a :class:`~surfsplat.io.Mesh`,
            ``"demo:NAME"``, or a path: a point/splat file, a mesh file (its surface is
            sampled for the view, see ``source_options``), a hierarchy file (``.npz`` from
            ``surfsplat build``) or a chunked hierarchy directory (``surfsplat build --chunked``:
            only the cells a view needs are read); or an (N, 3) array, a table of columns, a
            trimesh or Open3D object.
        camera: a :class:`Camera`; or a :class:`CameraSpec` (eye, target, up, fov) or None
            (automatic framing about the data's up axis), resolved at ``width`` x ``height`` pixels.
        technique: "ewa" (Guennebaud 2003), "perspective" (Zwicker 2004), "phong"
            (Botsch 2004), "blend" (Pajarola 2003), all three passes; "flat" (opaque disks,
            one pass) or "points" (adaptive round points).
        width, height: image size in pixels when ``camera`` is not a Camera.
        lights: lighting and material; None is a headlight with the default material.
        background: RGB in [0, 1].
        options: :class:`~surfsplat.rendering.options.RenderOptions`: EWA filter, visibility,
            blend kernel, deferred shading (None: the defaults).
        lod: the level of detail (:class:`LodOptions`: tolerance in pixels or "auto", LOD shading,
            point budget, CPU or GPU cut); None: every splat of a cloud, a hierarchy cut at one pixel.
        supersample: K in 1..16: draw K x K sub-pixels per pixel and average them (antialiased
            edges and ``Frame.alpha``; any size is drawn in tiles). The LOD cut is chosen for the
            output pixel, the EWA prefilter acts on the sub-pixels.
        source_options: how the source becomes splats (:class:`SourceOptions`): raw points
            preprocessed (k neighbours, outliers dropped); a mesh's surface sampled 0.75 px apart
            for the view, with crease-aware normals and clip lines at sharp and open edges (or its
            vertices); colours by attribute; hybrid drawing of non-planar points (LiDAR).
    """
    check_render_args(technique=technique, width=width, height=height, background=background, options=options,
                      supersample=supersample, lights=lights)
    return _view_of(source, source_options, lod).render(
        camera, technique=technique, width=width, height=height, lights=lights, background=background,
        options=options, supersample=supersample).frame


def render_mesh(source, camera: Camera | CameraSpec | None = None, *, width: int = defaults.API_IMAGE_SIZE,
                height: int = defaults.API_IMAGE_SIZE, lights: Lights | None = None, background=defaults.BACKGROUND,
                supersample: int = 4, smooth: bool = True) -> Frame:
    """Render a triangle mesh (a :class:`~surfsplat.io.Mesh` or a mesh file): the ground truth.

    Same camera conventions, lighting and linear depth as :func:`render`, per-pixel
    shading of the interpolated vertex normals (``smooth``) or the face normals,
    antialiased by ``supersample`` x ``supersample`` samples per pixel. A CameraSpec or
    None is resolved against the mesh's vertices as :func:`render` resolves it against splats.
    """
    background = check_background(background)
    supersample = check_supersample(supersample)
    if not isinstance(camera, Camera):
        width, height = check_image_size(width, height)
    if isinstance(source, Mesh):
        mesh = source
    else:
        check_source(source)
        with progress.stage(f"loading {source}"):
            mesh = load_mesh(source)
    camera = resolve_camera(as_model(mesh), camera, width, height, default_up=natural_up(source, mesh))
    frame = rasterize_mesh(mesh, camera, lights or Lights(), background=background, supersample=supersample,
                           smooth=smooth, renderer=default_renderer())
    check_coverage(frame, mesh, "the mesh")   # the same warning as a splat render that shows nothing
    return frame


def turntable_frames(view: View, cameras: list[Camera], **render_args):
    """Yield the (H, W, 3) uint8 image of each camera of a prepared ``view`` (:func:`prepare`; the
    other arguments as :meth:`View.render`): a mesh is sampled once, for the first camera; a
    hierarchy is cut per frame. Progress per frame."""
    return view.frames(cameras, **render_args)


def fit(cameras, *, init=None, images=None, device: str | None = None, **options):
    """Fit splats to the images of a camera file by differentiable EWA splatting (needs PyTorch: the extra diff).

    ``cameras``: a COLMAP text model (folder), NeRF ``transforms.json``, OpenCV JSON or surfsplat camera
    list, whose images are found by the cameras' names (:func:`surfsplat.diff.fit.load_views`); ``init``:
    the initial points or splats (a file, an (N, 3) array or a SplatCloud; None: the COLMAP model's
    ``points3D.txt``); ``images``: the images' folder; ``device``: "cpu" (None), "cuda" or "mps";
    ``options``: fields of :class:`surfsplat.diff.fit.FitOptions` (iterations, max_splats, seed, ...).
    Returns a :class:`surfsplat.diff.fit.FitResult`: the splats (colours as seen: render them unlit),
    the loss of every step and the time. :class:`InputError` when PyTorch is missing.
    """
    try:
        import torch  # noqa: F401  (the optional extra diff)
    except ImportError:
        raise InputError("fitting needs PyTorch: pip install 'surfsplat[diff]'") from None
    from .diff.fit import FitOptions, fit_files   # loads PyTorch: only when fitting

    try:
        settings = FitOptions(**options)
    except TypeError as exc:
        raise InputError(f"fit: {exc}") from None
    return fit_files(cameras, init=init, images=images, options=settings, device=device)
