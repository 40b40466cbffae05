"""Geometry processing: neighbours, normals, splat shapes, preprocessing, mesh sampling, sharp features
and Phong splat generation.

Modules: :mod:`.neighbors` (k-d trees, kNN), :mod:`.normals` (PCA normals, MST orientation),
:mod:`.splats` (circles and ellipses), :mod:`.cells` (Voronoi-cell splats for scan lines),
:mod:`.robust` (duplicates, outliers, size bounds of raw points), :mod:`.preprocess` (points to
splats), :mod:`.sampling` (mesh samples), :mod:`.sharp` (clip lines at sharp features), :mod:`.phong` (Phong splats,
Botsch et al. 2004) and :mod:`.common` (the blocked, threaded loops and small helpers they share).
"""

from ..frames import tangent_frame
from .neighbors import knn, spatial_order
from .normals import estimate_normals, orient_normals, orient_towards
from .phong import phong_splats
from .preprocess import neighbour_spacing, preprocess
from .robust import PreprocessReport
from .sampling import sample_mesh
from .splats import circular_splats, elliptical_splats, fallback_radius

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
    "PreprocessReport",
    "neighbour_spacing",
    "sample_mesh",
    "phong_splats",
]
