"""The small splats' first pass as compute shaders, where the context has OpenGL 4.3.

Blended techniques: their visibility pass (Guennebaud 2003, sec. 5) keeps per pixel the nearest offset
depth of the disks seen from the front and of those seen from the back. The raster pass draws each splat
as a GL_POINTS point or a quad and keeps the minima by MIN blending (``glsl/visibility.glsl``). Here one
compute invocation per splat runs the same per-splat and per-pixel code (``glsl/visibility.comp``:
``camera_splat``, ``disk_bounds``, ``ray_disk``) over the pixel centers of its disk's box and keeps the
minima by atomic minima of the depths' bits in two r32ui images; the cracks pass takes the smaller of
both records (``glsl/cracks.frag``, ``COMPUTE_VISIBILITY``). The record, and so the picture, is the same
bit for bit.

Opaque techniques declaring ``Technique.compute_opaque`` ("flat"): one compute pass keeps each pixel's
nearest disk depth, a second one the smallest index of the splats at that depth (the one a depth test in
draw order keeps: the splats are drawn in index order), and a full-screen pass
(``glsl/opaque_resolve.frag``) writes that splat's fragment with the depth test against the large splats
drawn before. The picture equals the raster one except where two disks
tie in depth (``tests/test_compute_visibility.py``).

Why: llvmpipe spends most of a GL_POINTS pass per primitive (vertex pipeline, setup, binning, and a
4x4-pixel block shaded for each block a point touches). Measured on the peers' bunny (1M splats,
1024x1024, Morton order, alternated): ewa 666 -> 517 ms per frame, flat 314 -> 227 ms
(``benchmarks/render_passes.py``). Which splats: per frame, the blocks of 4,096 consecutive splats
(``GpuSplats.small_blocks``; the buffers hold radius classes, each in Morton order, so a block is compact)
whose every box is at most :data:`COMPUTE_SPLAT_PX` pixels wide; the others stay raster, where one
invocation would loop over all their pixels while its neighbours idle. Without OpenGL 4.3 (macOS stops
at 4.1) every splat is drawn.
"""

from __future__ import annotations

import moderngl

from .shaders import COMPUTE_GROUP, NO_DEPTH

#: Blocks of splats whose disks' window boxes are all at most this many (sub-)pixels wide
#: (``GpuSplats.small_blocks``, per frame) go through the compute passes. Measured on llvmpipe (the bunny
#: at 1024x1024; CPU time per frame of ewa, with the estimate per model then in use): 1M splats: 16 and
#: 32 alike; 100k splats: 16 best, 32 and 64 slower than raster; 20k splats (large ones): 8-64 alike.
COMPUTE_SPLAT_PX = 16.0

#: Attribute buffers read by ``visibility.comp`` and their shader storage bindings.
COMPUTE_BINDINGS = {"position": 0, "normal": 1, "u": 2, "v": 3, "clip0": 4, "clip1": 5, "normal_field": 6, "lod": 7,
                    "color": 8}

#: Work groups per dispatch (OpenGL guarantees 65535 along x).
MAX_COMPUTE_GROUPS = 65535

#: Texture units of the two images while a full-screen pass reads them (the cracks pass: front and back
#: depths; the opaque resolve: depth and splat); units 0-3 serve the other passes.
IMAGE_UNITS = (4, 5)

#: The define of ``cracks.frag`` that reads the depth images too.
COMPUTE_VISIBILITY_DEFINE = "COMPUTE_VISIBILITY"

#: ``visibility.comp``'s ``COMPUTE_PASS``: the blended techniques' visibility pass; the opaque technique's
#: nearest depth, then the splat drawn there.
COMPUTE_VISIBILITY_PASS, COMPUTE_OPAQUE_DEPTH, COMPUTE_OPAQUE_INDEX = 1, 2, 3

def has_compute(ctx: moderngl.Context) -> bool:
    """Whether the context runs compute shaders with image atomics (OpenGL 4.3)."""
    return ctx.version_code >= 430


def image_targets(ctx: moderngl.Context, size: tuple[int, int]) -> dict:
    """The two r32ui images of a tile's size (``compute_a``, ``compute_b``: front and back depths, or
    depth and splat) and a framebuffer that clears them."""
    a, b = ctx.texture(size, 1, dtype="u4"), ctx.texture(size, 1, dtype="u4")
    return {"compute_a": a, "compute_b": b, "fbo_compute": ctx.framebuffer([a, b])}


def shader_defines(buffers: dict, defines: dict, compute_pass: int = COMPUTE_VISIBILITY_PASS) -> dict:
    """The defines of ``visibility.comp`` (and ``opaque_resolve.frag``) for splats with these attribute
    ``buffers`` and the frame's ``defines`` (e.g. a sequential layout's ``SEQUENTIAL_LOD``): the pass, the
    optional buffers it reads, and the small splats' variant of ``disk_bounds`` (``POINT_PRIMITIVE``)."""
    present = {"HAS_CLIP_LINES": "clip0" in buffers, "HAS_NORMAL_FIELD": "normal_field" in buffers}
    passes = {"COMPUTE_VISIBILITY_PASS": COMPUTE_VISIBILITY_PASS, "COMPUTE_OPAQUE_DEPTH": COMPUTE_OPAQUE_DEPTH,
              "COMPUTE_OPAQUE_INDEX": COMPUTE_OPAQUE_INDEX}
    return ({"POINT_PRIMITIVE": 1, "COMPUTE_PASS": compute_pass} | passes | defines
            | {name: 1 for name, has in present.items() if has})


def begin(targets: dict) -> None:
    """Clear the two images to NO_DEPTH's bits (no splat) and bind them to image units 0 and 1."""
    targets["fbo_compute"].clear(NO_DEPTH, NO_DEPTH, NO_DEPTH, NO_DEPTH)   # the float's bits
    targets["compute_a"].bind_to_image(0, read=True, write=True)
    targets["compute_b"].bind_to_image(1, read=True, write=True)


def bind_buffers(buffers: dict) -> None:
    """Bind the splats' attribute ``buffers`` as shader storage (:data:`COMPUTE_BINDINGS`)."""
    for name, binding in COMPUTE_BINDINGS.items():
        if name in buffers:
            buffers[name].bind_to_storage_buffer(binding)


def dispatch(program: moderngl.ComputeShader, buffers: dict, ranges: list) -> None:
    """Run ``program`` (``visibility.comp``, its frame uniforms set) over the splats of ``ranges``
    (``(first, count)``) read from the attribute ``buffers``."""
    bind_buffers(buffers)
    most = COMPUTE_GROUP * MAX_COMPUTE_GROUPS
    for first, count in ranges:
        for start in range(first, first + count, most):
            n = min(most, first + count - start)
            program["u_first"].value, program["u_count"].value = start, n
            program.run(group_x=-(-n // COMPUTE_GROUP))


def bind_images(ctx: moderngl.Context, targets: dict) -> tuple[int, int]:
    """After the compute passes: wait for the images' writes and bind them as textures
    (:data:`IMAGE_UNITS`, returned)."""
    ctx.memory_barrier()
    targets["compute_a"].use(location=IMAGE_UNITS[0])
    targets["compute_b"].use(location=IMAGE_UNITS[1])
    return IMAGE_UNITS
