"""Geometry processing: neighbours, normals, splat shapes, preprocessing, mesh sampling."""

from .neighbors import knn, spatial_order
from .normals import estimate_normals, orient_normals, orient_towards
from .preprocess import neighbour_spacing, preprocess
from .splats import circular_splats, elliptical_splats, fallback_radius, tangent_frame

__all__ = [
    "knn",
    "spatial_order",
    "estimate_normals",
    "orient_normals",
    "orient_towards",
    "tangent_frame",
    "circular_splats",
    "elliptical_splats",
    "fallback_radius",
    "preprocess",
    "neighbour_spacing",
]

# mesh sampling (geometry/sampling.py)
from .sampling import sample_mesh  # noqa: E402

__all__ += ["sample_mesh"]

# Phong splat generation (geometry/phong.py)
from .phong import phong_splats  # noqa: E402

__all__ += ["phong_splats"]
