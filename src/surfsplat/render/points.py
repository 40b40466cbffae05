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

Design: instanced quads, not ``GL_POINTS`` with ``gl_PointSize``.

* Tiles: OpenGL clips a point by its center, so a wide point whose center lies in the next tile
  is dropped from this one (a seam along every tile border), and ``GL_POINT_SIZE_RANGE`` caps
  the size (64 px times K = 8 exceeds many drivers' limit). A quad is clipped to the tile like
  any triangle, and each tile evaluates the same full-image test (``FRAG_PX``): tiled and untiled
  images are identical bit for bit (``tests/test_points.py``).
* Speed, measured on Mesa llvmpipe (LLVM 15, 2 cores), 1M random points in a 1024 x 1024 view,
  mean of 3 frames: ~1.6 px points, quads 1337 ms per frame (the whole ``Renderer.draw``, with
  its clears and normalization pass) against 508 ms for a bare GL_POINTS draw; ~4.8 px points,
  1348 ms against 796 ms. GL_POINTS is 1.7-2.6x faster there (llvmpipe rasterizes a point as
  one primitive, a quad as two triangles); it is the way to go for a window drawing one tile
  (with a viewport enlarged by the largest radius and a scissor it could tile too), not measured
  on a GPU.
* It reuses the renderer's instanced quad path unchanged (one draw call per pass).
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
    description="screen-aligned round points, size from the splat radius (LiDAR; Potree's adaptive size)",
)
