"""Ground truth for images: a triangle mesh rendered with the splat renderer's conventions.

DESIGN.md, "How we know it works": the mesh that splats were sampled from,
drawn with the same camera and lighting, is the reference image. Everything a
comparison depends on matches the splat pipeline (renderer.py):

- camera: the same view matrix, focal length and pixel grid (pixel centers at
  half-integers, window y up; ``Frame`` rows run top to bottom); near/far from
  the mesh's bounds where the camera has none (``Camera.with_clip_from_bounds``);
- shading: ``lighting.glsl``'s two-sided Blinn-Phong per pixel, of the
  perspective-correctly interpolated normals of the face's corners (``smooth``:
  the file's normals, or crease-aware ones where it stores none,
  :func:`surfsplat.io.surface.shading_normals`, as surface sampling uses) or
  the face normal, with the vertex colors or the splats' default albedo;
- depth: the splat shaders' linear depth in the z-buffer, and camera-space
  depth (model units along the view axis) in ``Frame.depth``.

Antialiasing is by supersampling: the image is rasterized at ``supersample``
times its size (in tiles that fit the GL limits) and box-averaged in NumPy.
"""

from __future__ import annotations

import moderngl
import numpy as np

from ..camera import Camera
from ..cloud import DEFAULT_ALBEDO
from ..errors import InputError, RenderError
from ..io.mesh import Mesh
from ..io.surface import AUTO, resolve_sharp_angle, shading_normals
from ..lighting import Lights
from .frame import Frame, check_background
from .renderer import OPTIONAL_FRAME_UNIFORMS, Renderer, default_renderer
from .tiles import MAX_TILE, check_supersample, tile_rects, tile_side



def _vertex_data(mesh: Mesh, smooth: bool, sharp_angle) -> tuple[np.ndarray, np.ndarray | None, bool]:
    """Interleaved float32 rows ``(position, normal[, color])`` and the uint32 index
    array: indexed vertices with the stored vertex normals; else three vertices per
    face (None for the indices) with per-corner normals (:func:`shading_normals`), or
    with face normals when ``smooth`` is False."""
    colored = mesh.vertex_colors is not None
    if smooth and mesh.vertex_normals is not None and mesh.corner_normals is None:
        columns = [mesh.vertices, mesh.vertex_normals] + ([mesh.vertex_colors] if colored else [])
        return np.hstack(columns).astype("f4"), mesh.faces.astype("u4"), colored
    corners = mesh.faces.reshape(-1)
    if smooth:
        normals = shading_normals(mesh, sharp_angle).reshape(-1, 3)
    else:
        normals = np.repeat(mesh.face_normals(), 3, axis=0)
    columns = [mesh.vertices[corners], normals]
    if colored:
        columns.append(mesh.vertex_colors[corners])
    return np.hstack(columns).astype("f4"), None, colored


def render_mesh(mesh: Mesh, camera: Camera, lights: Lights = Lights(), *, background=(1.0, 1.0, 1.0),
                supersample: int = 4, smooth: bool = True, sharp_angle: float | str | None = AUTO,
                renderer: Renderer | None = None, max_tile: int = MAX_TILE) -> Frame:
    """Render a triangle mesh as the ground-truth image for splat renderings of it.

    Args:
        mesh: the surface (validated here: faces present, finite vertices,
            indices in range). Normals are the mesh's (per vertex, or per
            corner after welding), or crease-aware normals where it has none
            (:func:`surfsplat.io.surface.crease_normals` on the welded
            vertices: angle-weighted face normals, split at edges sharper than
            ``sharp_angle``); vertex colors (linear RGB in [0, 1]) where
            present, else ``cloud.DEFAULT_ALBEDO`` gray.
        camera: the view; near/far None are set from the mesh's bounds.
        lights: lights and material, as for splats (``enabled=False``: unlit colors).
        background: linear RGB in [0, 1] behind the mesh.
        supersample: subsamples per pixel side (1..16): ``supersample**2``
            samples per pixel on a regular grid, box-filtered.
        smooth: shade with interpolated vertex normals (True) or with each
            face's geometric normal (False, flat shading).
        sharp_angle: the crease-aware normals' sharp angle (a mesh without
            stored normals only): degrees in (0, 180); ``"auto"`` (default):
            :func:`surfsplat.io.surface.auto_sharp_angle`, 30 degrees for a mesh
            with creases (CAD parts), None for one without (scans); None:
            smooth everywhere (one angle-weighted normal per vertex).
        renderer: the :class:`~surfsplat.rendering.renderer.Renderer` whose
            OpenGL context draws (default:
            :func:`~surfsplat.rendering.renderer.default_renderer`).
        max_tile: largest tile side in subsample pixels (GPU memory, ~24 bytes a subsample).

    Returns:
        :class:`Frame` with the clip-planed camera and, per pixel (row 0 at the top):
        ``weight``: coverage, the fraction of subsamples the mesh covers (0..1);
        ``color``: the mean color of the covered subsamples (each clamped to
        [0, 1]) composited over ``background`` by coverage;
        ``depth``: the mean camera-space depth of the covered subsamples, model
        units along the view axis, inf where uncovered.

    Raises:
        InputError: not a Mesh, no faces, non-finite vertices, bad indices, a
            bad supersample factor or background.
        RenderError: OpenGL failed.
    """
    if not isinstance(mesh, Mesh):
        raise InputError(f"render_mesh: expected a Mesh, got {type(mesh).__name__}")
    mesh = mesh.validated("render_mesh: mesh")
    supersample = check_supersample(supersample)
    bg = check_background(background)
    if smooth and not mesh.has_normals:
        sharp_angle = resolve_sharp_angle(mesh, sharp_angle, "render_mesh: sharp_angle")
    if renderer is None:
        renderer = default_renderer()
    if camera.near is None or camera.far is None:
        camera = camera.with_clip_from_bounds(*mesh.bounds())
    world_camera, camera = camera, camera.translated(-mesh.origin)   # drawn in the vertices' local frame

    ctx = renderer.ctx
    s = int(supersample)
    tile = tile_side(ctx, s, max_tile)
    width, height = camera.width, camera.height
    big_w, big_h = width * s, height * s
    tile_w, tile_h = min(tile, big_w), min(tile, big_h)

    program = renderer.program("mesh.vert", "mesh.frag")
    uniforms = renderer.frame_uniforms(camera, lights)
    uniforms |= {"u_viewport": (float(big_w), float(big_h)), "u_focal": float(camera.focal_px * s),
                 "u_albedo": (DEFAULT_ALBEDO,) * 3}
    rows, indices, colored = _vertex_data(mesh, smooth, sharp_angle)
    uniforms["u_vertex_colors"] = colored

    # accumulated per output pixel, window orientation (row 0 at the bottom)
    covered = np.zeros((height, width), dtype=np.float64)
    color_sum = np.zeros((height, width, 3), dtype=np.float64)
    depth_sum = np.zeros((height, width), dtype=np.float64)

    resources = []
    try:
        vbo = ctx.buffer(rows)
        resources.append(vbo)
        layout = "3f 3f 3f" if colored else "3f 3f"
        names = ["in_position", "in_normal"] + (["in_color"] if colored else [])
        if indices is None:
            vao = ctx.vertex_array(program, [(vbo, layout, *names)])
        else:
            ibo = ctx.buffer(indices)
            resources.append(ibo)
            vao = ctx.vertex_array(program, [(vbo, layout, *names)], index_buffer=ibo, index_element_size=4)
        resources.append(vao)
        color_rb = ctx.renderbuffer((tile_w, tile_h), 4, dtype="f4")
        depth_rb = ctx.renderbuffer((tile_w, tile_h), 1, dtype="f4")
        zbuffer = ctx.depth_renderbuffer((tile_w, tile_h))
        resources += [color_rb, depth_rb, zbuffer]
        fbo = ctx.framebuffer([color_rb, depth_rb], zbuffer)
        resources.append(fbo)

        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.BLEND)
        ctx.disable(moderngl.CULL_FACE)
        ctx.depth_func = "<"
        fbo.depth_mask = True
        for x0, y0, tw, th in tile_rects(big_w, big_h, tile):
            fbo.viewport = (0, 0, tw, th)
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            own = renderer.bind_frame_uniforms(uniforms | {"u_tile": (float(x0), float(y0), float(tw), float(th))})
            renderer.set_uniforms(program, own, OPTIONAL_FRAME_UNIFORMS)
            vao.render(moderngl.TRIANGLES)
            rgba = np.frombuffer(fbo.read(viewport=(0, 0, tw, th), components=4, attachment=0, dtype="f4"),
                                 dtype="f4").reshape(th // s, s, tw // s, s, 4)
            z = np.frombuffer(fbo.read(viewport=(0, 0, tw, th), components=1, attachment=1, dtype="f4"),
                              dtype="f4").reshape(th // s, s, tw // s, s)
            # uncovered subsamples hold the clear value 0 in every channel
            block = np.s_[y0 // s:(y0 + th) // s, x0 // s:(x0 + tw) // s]
            covered[block] = rgba[..., 3].sum(axis=(1, 3), dtype=np.float64)
            color_sum[block] = rgba[..., :3].sum(axis=(1, 3), dtype=np.float64)
            depth_sum[block] = z.sum(axis=(1, 3), dtype=np.float64)
        error = ctx.error
        if error != "GL_NO_ERROR":
            raise RenderError(f"OpenGL reported {error} while rendering the mesh")
    finally:
        ctx.disable(moderngl.DEPTH_TEST)
        # moderngl re-binds the current framebuffer when creating one: park on
        # one that stays alive before freeing ours (Renderer.park); then free in
        # reverse order: framebuffer, attachments, vertex array, buffers.
        renderer.park()
        for resource in reversed(resources):
            resource.release()

    n = float(s * s)
    weight = covered / n
    color = np.clip(color_sum / n + (1.0 - weight)[..., None] * np.asarray(bg), 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(covered > 0, depth_sum / covered, np.inf)
    return Frame(np.ascontiguousarray(color[::-1], dtype="f4"), np.ascontiguousarray(depth[::-1], dtype="f4"),
                 np.ascontiguousarray(weight[::-1], dtype="f4"), world_camera,
                 alpha=np.ascontiguousarray(weight[::-1], dtype="f4"), background=bg)
