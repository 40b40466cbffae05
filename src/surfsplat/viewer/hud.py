"""The viewer's heads-up display: text rendered by Pillow into RGBA textures, drawn over the image.

Text is rasterized on the CPU (Pillow's default font) only when it changes; the
status line's numbers change at most twice a second (the frame counter's
update interval), so the upload costs nothing per frame. Each panel is one
alpha-blended quad; its shaders are ``glsl/hud.vert`` and ``glsl/hud.frag``.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import cast

import moderngl
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ..rendering.shaders import build_program

#: Panel colors: white text on a translucent dark panel, readable on any background.
TEXT_RGB = (1.0, 1.0, 1.0)
PANEL_RGBA = (0.08, 0.08, 0.1, 0.62)


#: The viewer's own shader files; the renderer's ``glsl/`` folder is searched after it.
VIEWER_GLSL = Path(__file__).resolve().parent / "glsl"


def viewer_program(ctx: moderngl.Context, vertex: str, fragment: str) -> moderngl.Program:
    """Build a program from shader files of the viewer's ``glsl/`` folder, or else the renderer's
    (shared snippets are not copied); a compile error names the file and line."""
    return build_program(ctx, vertex, fragment, search_path=(VIEWER_GLSL,)).program


@lru_cache(maxsize=8)
def _font(size_px: int):
    try:
        return ImageFont.load_default(size=size_px)  # scalable font: Pillow >= 10.1 with FreeType
    except TypeError:
        return ImageFont.load_default()  # older Pillow: the fixed bitmap font


def render_text(text: str, size_px: int = 14, padding_px: int = 6) -> np.ndarray:
    """Rasterize ``text`` on a translucent panel.

    Lines are separated by newlines; tabs separate columns, which are aligned across
    lines (the font is proportional, so spaces cannot align them).

    Returns (H, W, 4) uint8 premultiplied RGBA, row 0 at the top; H and W in
    pixels follow from the text's extent plus ``padding_px`` on every side.
    """
    font = _font(int(size_px))
    rows = [line.split("\t") for line in (text or " ").split("\n")]
    probe = ImageDraw.Draw(Image.new("L", (1, 1)))
    top, bottom = probe.textbbox((0, 0), "Ag|", font=font)[1::2]
    line_px = int(bottom) + max(2, size_px // 4)  # baseline-to-baseline step
    gap = size_px  # between columns
    columns = max(len(row) for row in rows)
    widths = [max((probe.textlength(row[c], font=font) for row in rows if len(row) > c), default=0.0)
              for c in range(columns)]
    starts = [padding_px + sum(widths[:c]) + gap * c for c in range(columns)]
    width = int(math.ceil(starts[-1] + widths[-1])) + padding_px
    height = line_px * (len(rows) - 1) + int(bottom) + 2 * padding_px
    mask = Image.new("L", (max(width, 1), max(height, 1)), 0)
    draw = ImageDraw.Draw(mask)
    for i, row in enumerate(rows):
        for c, cell in enumerate(row):
            draw.text((starts[c], padding_px + i * line_px), cell, fill=255, font=font)
    coverage = np.asarray(mask, dtype=np.float32)[..., None] / 255.0
    panel_rgb, panel_a = np.asarray(PANEL_RGBA[:3], np.float32), np.float32(PANEL_RGBA[3])
    # text over the panel, premultiplied: rgb = text*cov + panel*a*(1-cov), a = cov + a*(1-cov)
    rgb = np.asarray(TEXT_RGB, np.float32) * coverage + panel_rgb * panel_a * (1.0 - coverage)
    alpha = coverage + panel_a * (1.0 - coverage)
    rgba = np.concatenate([rgb, alpha], axis=2)
    return np.round(rgba * 255.0).astype(np.uint8)


class TextPanel:
    """One block of text drawn as an alpha-blended quad; re-rasterized only when its text changes."""

    def __init__(self, ctx: moderngl.Context, program: moderngl.Program, size_px: int = 14):
        self.ctx, self.program, self.size_px = ctx, program, size_px
        self.text: str | None = None
        self.texture: moderngl.Texture | None = None
        self.uploads = 0  # how often the texture was rebuilt (tests hold this down)
        self._vao = ctx.vertex_array(program, [])

    def set_text(self, text: str, size_px: int | None = None) -> None:
        """Show ``text`` from now on (no work when neither it nor the size changed)."""
        size_px = self.size_px if size_px is None else int(size_px)
        if text == self.text and size_px == self.size_px and self.texture is not None:
            return
        self.text, self.size_px = text, size_px
        image = render_text(text, size_px, padding_px=max(4, size_px // 2))
        h, w = image.shape[:2]
        if self.texture is None or self.texture.size != (w, h):
            if self.texture is not None:
                self.texture.release()
            self.texture = self.ctx.texture((w, h), 4)
            self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)  # drawn 1:1 on whole pixels
        self.texture.write(np.ascontiguousarray(image[::-1]).tobytes())  # GL rows start at the bottom
        self.uploads += 1

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the panel in pixels, (0, 0) before any text."""
        return self.texture.size if self.texture is not None else (0, 0)

    def _uniform(self, name: str) -> moderngl.Uniform:
        return cast(moderngl.Uniform, self.program[name])   # moderngl types program members as a union

    def draw(self, viewport: tuple[int, int], x_px: int, y_px: int) -> None:
        """Draw the panel with its top-left corner ``(x_px, y_px)`` pixels from the top-left of
        the current framebuffer, whose size is ``viewport`` (width, height) pixels."""
        if self.texture is None or not self.text:
            return
        w, h = self.texture.size
        top = viewport[1] - y_px
        self._uniform("u_rect").value = (float(x_px), float(top - h), float(x_px + w), float(top))
        self._uniform("u_viewport").value = (float(viewport[0]), float(viewport[1]))
        self._uniform("u_text").value = 0
        self.texture.use(location=0)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_equation = moderngl.FUNC_ADD  # type: ignore[assignment]  # moderngl's stub wants a pair
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        self._vao.render(moderngl.TRIANGLE_STRIP, vertices=4)
        self.ctx.disable(moderngl.BLEND)

    def release(self) -> None:
        """Free the texture and vertex array."""
        if self.texture is not None:
            self.texture.release()
            self.texture = None
        self._vao.release()


class Hud:
    """The status panel (top left) and the help panel below it (toggled by H).

    ``scale``: the window's content scale (HiDPI), multiplying font size and margins.
    """

    def __init__(self, ctx: moderngl.Context, scale: float = 1.0, font_px: int = 14):
        self.ctx = ctx
        self.program = viewer_program(ctx, "hud.vert", "hud.frag")
        self.scale = scale
        self.font_px = font_px
        self.status = TextPanel(ctx, self.program, self._px())
        self.help = TextPanel(ctx, self.program, self._px())
        self.show_help = False

    def _px(self) -> int:
        return max(8, int(round(self.font_px * self.scale)))

    def update(self, status: str, help_text: str) -> None:
        """Set the panels' texts (cheap when unchanged)."""
        self.status.set_text(status, self._px())
        if self.show_help:
            self.help.set_text(help_text, self._px())

    def draw(self, viewport: tuple[int, int]) -> None:
        """Draw the panels into the current framebuffer of size ``viewport`` (pixels)."""
        margin = int(round(10 * self.scale))
        self.status.draw(viewport, margin, margin)
        if self.show_help:
            self.help.draw(viewport, margin, 2 * margin + self.status.size[1])

    def release(self) -> None:
        """Free the GPU resources."""
        self.status.release()
        self.help.release()
