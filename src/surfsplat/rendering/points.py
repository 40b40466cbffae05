"""Technique ``points``: screen-aligned round points of adaptive size, opaque, z-buffer only.

For large scans (LiDAR) where splats are overkill: each splat is drawn as a round point facing
the screen, its diameter in pixels the splat's radius (the larger of ``|u|``, ``|v|``, which
preprocessing sets from the local point spacing) projected at the point's depth,
``d = 2 r f / z``, clamped to ``[min, max]`` output pixels (default [1, 64]): Potree's adaptive
point size (M. Schuetz, "Potree: Rendering Large Point Clouds in Web Browsers", TU Wien 2016,
sec. 3.4: the size follows the local spacing, there from the octree level's density, here from
the splat radius). A point covers the pixels whose centers lie within ``d / 2`` of its projected
center, and always the pixel holding the center (``reference.point_footprint``). One opaque pass
with a plain z-buffer at the point's center depth, like ``flat``; lit by the point's normal when
it has one (a zero normal: unlit color); ``deferred`` lights in the normalization pass.
With ``supersample`` K the clamp is in output pixels (K sub-pixels per output pixel).

Primitive (``point_footprint="adaptive"``): small points (a window box of at most 64 sub-pixels) are
drawn as ``GL_POINTS`` and the others as instanced quads (``renderer.point_radius``,
``glsl/splat_primitive.glsl``). A point sits at the centre of its window box clipped to the tile,
so a wide point whose centre lies in the next tile is not lost (OpenGL clips a point by its
centre) and ``GL_POINT_SIZE_RANGE`` never binds; every fragment runs the same full-image test
(``FRAG_PX``), so tiled and untiled images are identical bit for bit (``tests/test_points.py``).
GL_POINTS measured 1.7-2.6x faster than quads on llvmpipe (one primitive instead of two triangles).
"""

from .technique import Technique

#: Default clamp of the point diameter, output pixels (Potree clamps to [minSize, maxSize]).
POINT_SIZE_RANGE = (1.0, 64.0)

POINTS = Technique(
    name="points",
    vertex="points.vert",
    fragment="points.frag",
    blended=False,
    attributes=("position", "normal", "color", "u", "v"),
    uniforms=lambda options: {"u_point_size": POINT_SIZE_RANGE},
    point_footprint="adaptive",   # points.vert: diameter 2 r f / z, clamped
    min_point_px=POINT_SIZE_RANGE[0],
    compute_opaque=False,   # round points facing the eye, not flat.frag's disks
    edge_coverage=False,   # opaque: no accumulation pass writes coverage
    edge_fringe=False,
    description="screen-aligned round points, size from the splat radius (LiDAR; Potree's adaptive size)",
)
