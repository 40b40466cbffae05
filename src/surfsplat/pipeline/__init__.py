"""The view plan: one definition of a view that every door consumes (``docs/architecture.md``).

- :mod:`.options`: :class:`SourceOptions` and :class:`LodOptions`, checked when built;
- :mod:`.sources`: reading what a user hands over; the data's up axis;
- :mod:`.models`: the model kinds behind one protocol (:class:`~.models.Model`);
- :mod:`.framing`: cameras, automatic framing, near/far;
- :mod:`.lod`: where and how a view is cut; hybrid drawing;
- :mod:`.plan`: :class:`View`, a prepared view, and the checks of a render's arguments.
"""

from .framing import CameraSpec, auto_camera, clipped_to, local_camera, resolve_camera
from .lod import cut_tolerance, hybrid_applies, hybrid_default, hybrid_splats, lod_strategy
from .models import Model, as_model, lod_splats
from .options import LOD_AUTO, LOD_MODES, LodMode, LodOptions, SourceOptions
from .plan import RenderResult, View, check_coverage, check_image_size, check_render_args
from .sources import (DEMO_PREFIX, as_splats, check_source, is_demo_source, is_hierarchy_file, is_lidar, load_cloud,
                      natural_up, read_source)

__all__ = ["CameraSpec", "DEMO_PREFIX", "LOD_AUTO", "LOD_MODES", "LodMode", "LodOptions", "Model", "RenderResult",
           "SourceOptions", "View", "as_model", "as_splats", "auto_camera", "check_coverage", "check_image_size",
           "check_render_args", "check_source", "clipped_to", "cut_tolerance", "hybrid_applies", "hybrid_default",
           "hybrid_splats", "is_demo_source", "is_hierarchy_file", "is_lidar", "load_cloud", "local_camera",
           "lod_splats", "lod_strategy", "natural_up", "read_source", "resolve_camera"]
