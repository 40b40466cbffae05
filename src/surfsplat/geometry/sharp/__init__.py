"""Sharp features: where the clip lines of splats come from.

Zwicker et al. 2004, section 5 (figure 4): a sharp edge is represented by
*clip lines* in the tangent planes of the splats next to it, "computed by
intersecting the tangent planes of adjacent reconstruction kernels on either
side of a feature". We store a clip line as Botsch et al. 2004, section 4
do: ``(a, b, c)`` in the splat's normalized coordinates ``(s, t)`` (the point
``p + s u + t v``, see :mod:`surfsplat.cloud`), the point kept where
``a s + b t + c >= 0``. Up to two lines per splat: one at an edge, two at a
corner (Zwicker 2004, figure 5).

Both sources reduce to the same algebra (:mod:`.lines`): the plane on the
other side of the feature is a half-space that contains the splat's own side;
a line is only stored where it crosses the splat (``|c| < 1``): one farther
out cuts nothing, and one that would cut the whole splat (the center far on
the wrong side) would punch a hole.

* :mod:`.mesh` -- :func:`mesh_clip_lines`: samples of a triangle mesh, with
  exact planes of the mesh's faces across edges whose dihedral angle exceeds
  the threshold (used by :func:`surfsplat.geometry.sampling.sample_mesh`).
* :mod:`.points` -- :func:`detect_sharp_features` and
  :func:`feature_clip_lines`: raw points. Where a neighbourhood's normals
  spread, it is split into up to three planar groups (:mod:`.planes`), a
  least-squares plane is fitted to each, and planes more than the threshold
  apart are the faces on either side of an edge or corner (used by
  :func:`surfsplat.geometry.preprocess.preprocess`).
"""

from .lines import check_sharp_angle, lines_from_halfspaces, pack_lines
from .mesh import MeshFeatures, mesh_clip_lines, mesh_features
from .points import SHARP_NEIGHBOURS, SharpFeatures, detect_sharp_features, feature_clip_lines

__all__ = [
    "check_sharp_angle",
    "lines_from_halfspaces",
    "pack_lines",
    "MeshFeatures",
    "mesh_features",
    "mesh_clip_lines",
    "SHARP_NEIGHBOURS",
    "SharpFeatures",
    "detect_sharp_features",
    "feature_clip_lines",
]
