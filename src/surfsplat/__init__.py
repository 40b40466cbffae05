"""surfsplat: high-quality surface splatting of point clouds and surfel models.

Quick start::

    import surfsplat
    frame = surfsplat.render("bunny.ply", technique="ewa", width=800, height=800)
    frame.save("bunny.png")

    cloud = surfsplat.load_points("scan.ply")       # the points of any file (a mesh's vertices)
    model = surfsplat.load_model("part.stl")        # what render draws (a mesh: its surface, sampled)

    view = surfsplat.prepare("scan.ply")            # load once ...
    for camera in cameras:                          # ... render many cameras
        frame = view.render(camera).frame

The package is layered (``docs/architecture.md``): ``io``, ``geometry``, ``hierarchy`` and
``rendering`` below the view plan (:mod:`surfsplat.pipeline`), which :mod:`surfsplat.api`, the
command line (``surfsplat.cli``), the viewer (``surfsplat.viewer``) and the notebook widget drive.
"""

from .api import fit, load_model, orbit_cameras, prepare, render, render_mesh
from .camera import Camera
from .cloud import SplatCloud
from .colors import ColorOptions
from .errors import EmptyFrameWarning, InputError, RenderError, SurfsplatError
from .geometry.phong import phong_splats
from .geometry.preprocess import PreprocessReport, preprocess
from .geometry.robust import OutlierAction
from .hierarchy import Hierarchy, LodShading, build_hierarchy, load_hierarchy, save_hierarchy
from .io import Mesh, save_ply
from .io import load as load_points
from .lighting import Lights
from .pipeline import CameraSpec, LodMode, LodOptions, RenderResult, SourceOptions, View, auto_camera
from .rendering.frame import Frame
from .rendering.options import (EdlOptions, FilterOptions, KernelOptions, RenderOptions, TechniqueName,
                                VisibilityOptions)
from .rendering.renderer import default_renderer, reset_default_renderer
from .scenes import demo_scene
from .version import __version__
from .viewer import MotionOptions, view
from .web import export

__all__ = [
    # rendering
    "render", "prepare", "View", "RenderResult", "render_mesh", "view", "orbit_cameras", "Frame", "export",
    # fitting splats to images (the extra diff)
    "fit",
    # options users build
    "Camera", "CameraSpec", "Lights", "RenderOptions", "FilterOptions", "VisibilityOptions", "KernelOptions",
    "EdlOptions", "SourceOptions", "LodOptions", "ColorOptions", "MotionOptions",
    # the literal types of those options
    "TechniqueName", "LodShading", "LodMode", "OutlierAction",
    # data
    "SplatCloud", "Mesh", "Hierarchy", "load_points", "load_model", "save_ply", "preprocess", "PreprocessReport",
    "phong_splats", "build_hierarchy", "load_hierarchy", "save_hierarchy", "demo_scene", "auto_camera",
    # errors and warnings
    "SurfsplatError", "InputError", "RenderError", "EmptyFrameWarning",
    # the shared OpenGL renderer
    "default_renderer", "reset_default_renderer",
    "__version__",
]
