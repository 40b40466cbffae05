"""The high-level Python API: load, preprocess, frame and render in one call each."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from .camera import Camera, frame_bounds
from .cloud import SplatCloud
from .errors import InputError
from .lighting import Lights
from .render.frame import Frame
from .render.technique import RenderOptions

_renderer = None


def default_renderer():
    """The process-wide headless :class:`~surfsplat.render.renderer.Renderer` (created on first use)."""
    global _renderer
    if _renderer is None:
        from .render.renderer import Renderer

        _renderer = Renderer()
    return _renderer


#: Default viewing direction (toward the eye) for a y-up world: front, a little right and above.
DEFAULT_DIRECTION = (0.4, 0.35, 1.0)


def _rotate_y_to(up) -> np.ndarray:
    """3x3 rotation taking +y to the unit vector ``up`` (Rodrigues; 180 degrees about x for -y)."""
    up = np.asarray(up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    y = np.array([0.0, 1.0, 0.0])
    axis = np.cross(y, up)
    s, c = np.linalg.norm(axis), float(y @ up)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def auto_camera(cloud: SplatCloud, width: int = 512, height: int = 512, fov: float = 40.0,
                direction=None, up=(0.0, 1.0, 0.0)) -> Camera:
    """A camera framing the whole cloud from ``direction`` (world, toward the eye).

    The bounding sphere of the splat centers (around the bounds' center) fills
    90% of the smaller field of view; near/far enclose the splats. Without a
    direction the view is from the front, a little right and above, relative
    to ``up`` (so ``up=(0, 0, 1)`` suits z-up data such as LiDAR).
    """
    if np.linalg.norm(np.asarray(up, dtype=float)) == 0 or not np.isfinite(up).all():
        raise InputError(f"up must be a finite non-zero vector, got {up!r}")
    if direction is None:
        direction = _rotate_y_to(up) @ np.asarray(DEFAULT_DIRECTION)
    lo, hi = cloud.bounds()
    center = 0.5 * (lo + hi)
    radius = float(np.sqrt(np.max(np.sum((cloud.positions - center) ** 2, axis=1))))
    margin = float(cloud.radii.max()) if cloud.u is not None else 0.0
    return frame_bounds(lo, hi, width=width, height=height, fov=fov, direction=direction, up=up,
                        radius=radius + margin, margin=margin)


def as_splats(source: SplatCloud | str | Path, *, k: int = 8) -> SplatCloud:
    """A render-ready SplatCloud from a cloud or a file, preprocessed (k neighbours) if needed."""
    if isinstance(source, (str, Path)):
        from .io import load

        source = load(source)
    if not isinstance(source, SplatCloud):
        raise InputError(f"expected a SplatCloud or a file path, got {type(source).__name__}")
    if not source.has_splats:
        from .geometry.preprocess import preprocess

        source = preprocess(source, k=k)
    return source


def render_options(**options) -> RenderOptions:
    """RenderOptions from keyword arguments, with a clear error for an unknown name."""
    known = {f.name for f in dataclasses.fields(RenderOptions)}
    unknown = sorted(set(options) - known)
    if unknown:
        raise InputError(f"unknown render option {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    return RenderOptions(**options)


#: LOD screen tolerance tau (pixels) used when a hierarchy is rendered without one.
DEFAULT_LOD_TOLERANCE = 1.0

#: Suffix of hierarchy files (``surfsplat build``).
HIERARCHY_SUFFIX = ".npz"


def is_hierarchy_file(source) -> bool:
    """True for a path naming a hierarchy file (``.npz``, written by ``surfsplat build``)."""
    return isinstance(source, (str, Path)) and Path(source).suffix.lower() == HIERARCHY_SUFFIX


def load_model(source, *, k: int = 8):
    """A Hierarchy for a hierarchy file (``.npz``, ``surfsplat build``) or a Hierarchy;
    else a render-ready SplatCloud (see :func:`as_splats`)."""
    from .hierarchy import Hierarchy, load_hierarchy

    if isinstance(source, Hierarchy):
        return source
    if is_hierarchy_file(source):
        return load_hierarchy(source)
    return as_splats(source, k=k)


def as_hierarchy(model):
    """A Hierarchy as it is, or the point-octree built over a render-ready SplatCloud."""
    from .hierarchy import Hierarchy, build_hierarchy

    return model if isinstance(model, Hierarchy) else build_hierarchy(model)


def model_points(model) -> SplatCloud:
    """The original splats of a model: a SplatCloud itself, a Hierarchy's points (for framing)."""
    from .hierarchy import Hierarchy

    return model.points if isinstance(model, Hierarchy) else model


def lod_splats(hierarchy, camera: Camera, tolerance_px: float = DEFAULT_LOD_TOLERANCE, *,
               cull_backfaces: bool = False, shading: str = "fit"):
    """The splats of a hierarchy to draw for a view, and the selection (Pajarola 2003, sec. 5.1).

    Nodes whose projected ellipse is at most ``tolerance_px`` pixels wide are
    drawn as one splat, others are refined; nodes outside the view frustum (and
    with ``cull_backfaces`` those whose normal cone faces away) are dropped with
    their subtrees. ``shading`` is the normal field of node splats: "fit"
    (least-squares linear field), "cone" (Pajarola 2003, fig. 14) or "flat".

    Returns:
        (SplatCloud, :class:`~surfsplat.hierarchy.Selection`).
    """
    from .hierarchy import select

    selection = select(hierarchy, camera, tolerance_px, cull_backfaces=cull_backfaces, shading=shading)
    return hierarchy.splats(selection), selection


def view_splats(model, camera: Camera, lod_tolerance: float | None = None, *, cull_backfaces: bool = False,
                shading: str = "fit"):
    """The splats to draw for a view: a SplatCloud as it is, or a Hierarchy's LOD cut (:func:`lod_splats`,
    tolerance :data:`DEFAULT_LOD_TOLERANCE` when None). Returns (SplatCloud, Selection or None)."""
    from .hierarchy import Hierarchy

    if not isinstance(model, Hierarchy):
        return model, None
    tau = DEFAULT_LOD_TOLERANCE if lod_tolerance is None else lod_tolerance
    return lod_splats(model, camera, tau, cull_backfaces=cull_backfaces, shading=shading)


def render(source, camera: Camera | None = None, *, technique: str = "ewa",
           width: int = 512, height: int = 512, lights: Lights | None = None, background=(1.0, 1.0, 1.0),
           lod_tolerance: float | None = None, lod_shading: str = "fit", k: int = 8, **options) -> Frame:
    """Render a SplatCloud, a hierarchy or a file to a :class:`Frame`.

    Args:
        source: a SplatCloud (preprocessed if it lacks normals or splat axes), a
            :class:`~surfsplat.hierarchy.Hierarchy`, or a path: a point/splat/mesh
            file or a hierarchy file (``.npz`` from ``surfsplat build``).
        camera: the view; None frames the model automatically at ``width`` x ``height``.
        technique: "ewa" (Guennebaud 2003), "perspective" (Zwicker 2004), "phong"
            (Botsch 2004), "blend" (Pajarola 2003), all three passes, or "flat"
            (opaque disks, one pass).
        lights: lighting and material; None is a headlight with the default material.
        background: RGB in [0, 1].
        lod_tolerance: LOD screen tolerance tau in pixels (see :func:`lod_splats`).
            Hierarchies default to :data:`DEFAULT_LOD_TOLERANCE`; a cloud given a
            tolerance is turned into a hierarchy first (``surfsplat build`` saves one).
        lod_shading: normal field of coarse LOD splats: "fit", "cone" or "flat".
        k: neighbours for preprocessing when needed.
        **options: fields of :class:`~surfsplat.render.technique.RenderOptions`:
            prefilter, cutoff, depth_epsilon, cull_backfaces, deferred, kernel,
            kernel_a, kernel_b, kernel_n, kernel_sigma.
    """
    render_settings = render_options(**options)
    background = tuple(float(x) for x in np.asarray(background, dtype=float).reshape(-1))
    if len(background) != 3 or not all(0.0 <= x <= 1.0 for x in background):
        raise InputError(f"background must be 3 numbers in [0, 1], got {background}")
    model = load_model(source, k=k)
    if lod_tolerance is not None:
        model = as_hierarchy(model)
    if camera is None:
        camera = auto_camera(model_points(model), width, height)
    cloud, _ = view_splats(model, camera, lod_tolerance, cull_backfaces=render_settings.cull_backfaces,
                           shading=lod_shading)
    if len(cloud) == 0:
        return Frame.empty(camera, background)
    return default_renderer().render(cloud, camera, technique, lights or Lights(), render_settings, background)


def render_mesh(source, camera: Camera | None = None, *, width: int = 512, height: int = 512,
                lights: Lights | None = None, background=(1.0, 1.0, 1.0), supersample: int = 4,
                smooth: bool = True) -> Frame:
    """Render a triangle mesh (a :class:`~surfsplat.io.Mesh` or a PLY/OBJ path): the ground truth.

    Same camera conventions, lighting and linear depth as :func:`render`, per-pixel
    shading of the interpolated vertex normals (``smooth``) or the face normals,
    antialiased by ``supersample`` x ``supersample`` samples per pixel. With no
    camera the mesh's vertices are framed like :func:`auto_camera` frames a cloud.
    """
    from .io import Mesh, load_mesh
    from .render.mesh import render_mesh as _render_mesh

    mesh = source if isinstance(source, Mesh) else load_mesh(source)
    if camera is None:
        camera = auto_camera(SplatCloud(mesh.vertices), width, height)
    return _render_mesh(mesh, camera, lights or Lights(), background=background, supersample=supersample,
                        smooth=smooth, renderer=default_renderer())
