"""surfsplat: high-quality surface splatting of point clouds and surfel models.

Quick start::

    import surfsplat
    frame = surfsplat.render("bunny.ply", technique="ewa", width=800, height=800)
    frame.save("bunny.png")
"""

from .api import as_splats, auto_camera, render, render_mesh
from .camera import Camera
from .cloud import SplatCloud
from .errors import InputError, RenderError, SurfsplatError
from .lighting import Lights
from .render.frame import Frame
from .render.technique import RenderOptions
from .scenes import demo_scene
from .viewer import view

__version__ = "0.1.0"


def load(path) -> SplatCloud:
    """Read a point cloud, splat model or triangle mesh (PLY, OBJ, LAS) into a SplatCloud."""
    from .io import load as _load

    return _load(path)


def preprocess(cloud: SplatCloud, **kwargs) -> SplatCloud:
    """Estimate normals and splat ellipses; see :func:`surfsplat.geometry.preprocess.preprocess`."""
    from .geometry.preprocess import preprocess as _preprocess

    return _preprocess(cloud, **kwargs)


def phong_splats(cloud: SplatCloud, error: float | None = None, **kwargs) -> SplatCloud:
    """Phong splats with linear normal fields; see :func:`surfsplat.geometry.phong.phong_splats`."""
    from .geometry.phong import phong_splats as _phong_splats

    return _phong_splats(cloud, error, **kwargs)


def build_hierarchy(cloud: SplatCloud, leaf_capacity: int = 8, **kwargs):
    """The point-octree LOD hierarchy; see :func:`surfsplat.hierarchy.build_hierarchy`."""
    from .hierarchy import build_hierarchy as _build_hierarchy

    return _build_hierarchy(cloud, leaf_capacity, **kwargs)


__all__ = ["Camera", "Frame", "InputError", "Lights", "RenderError", "RenderOptions", "SplatCloud",
           "SurfsplatError", "as_splats", "auto_camera", "build_hierarchy", "demo_scene", "load", "phong_splats",
           "preprocess", "render", "render_mesh", "view", "__version__"]
