"""surfsplat: high-quality surface splatting of point clouds and surfel models.

Quick start::

    import surfsplat
    frame = surfsplat.render("bunny.ply", technique="ewa", width=800, height=800)
    frame.save("bunny.png")

The package is layered (``docs/architecture.md``): ``io``, ``geometry``, ``hierarchy`` and
``render`` below :mod:`surfsplat.api`, the one orchestrator; the command line
(``surfsplat.cli``) and the viewer (``surfsplat.viewer``) above it.
"""

from .api import CameraSpec, RenderResult, SourceOptions, as_splats, auto_camera, load_model, render, render_mesh
from .camera import Camera
from .cloud import SplatCloud
from .errors import InputError, RenderError, SurfsplatError
from .geometry.phong import phong_splats
from .geometry.preprocess import PreprocessReport, preprocess
from .hierarchy import build_hierarchy, load_hierarchy
from .io import load
from .lighting import Lights
from .rendering.frame import Frame
from .rendering.options import FilterOptions, KernelOptions, RenderOptions, VisibilityOptions
from .rendering.renderer import default_renderer, reset_default_renderer
from .scenes import demo_scene
from .version import __version__
from .viewer import MotionOptions, view

__all__ = ["Camera", "CameraSpec", "FilterOptions", "Frame", "InputError", "KernelOptions", "Lights",
           "MotionOptions", "PreprocessReport", "RenderError", "RenderOptions", "RenderResult", "SourceOptions", "SplatCloud", "SurfsplatError",
           "VisibilityOptions", "as_splats", "auto_camera", "build_hierarchy", "default_renderer", "demo_scene",
           "load", "load_hierarchy", "load_model", "phong_splats", "preprocess", "render", "render_mesh",
           "reset_default_renderer", "view", "__version__"]
