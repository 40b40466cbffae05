"""surfsplat: high-quality surface splatting of point clouds and surfel models."""

from .cloud import SplatCloud
from .errors import InputError, RenderError, SurfsplatError

__version__ = "0.1.0"
__all__ = ["SplatCloud", "InputError", "RenderError", "SurfsplatError", "__version__"]
