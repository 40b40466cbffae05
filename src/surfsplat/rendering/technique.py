"""The technique interface: what a rendering technique tells the renderer.

A technique is a small module (``ewa.py``, ``flat.py``, ...) that defines a
:class:`Technique` constant: its shader files, whether it blends (three passes:
visibility, accumulation, normalization) or draws opaque (one pass), the splat
attributes it reads and its uniforms from the render options. The table of
techniques by name is :data:`surfsplat.rendering.techniques.TECHNIQUES`; this
module imports none of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..reference import prefilter_variance
from .options import RenderOptions


@dataclass(frozen=True)
class Technique:
    """A rendering technique.

    Attributes:
        name: the name users pass (``--technique NAME``), one of ``options.TechniqueName``.
        vertex, fragment: shader files in ``glsl/``.
        blended: True for the three-pass pipeline, False for one opaque pass.
        attributes: splat attributes the vertex shader reads (``in_<name>``).
        uniforms: options -> uniform values, called per frame. Every name must
            be declared by the technique's shaders (``uniform <type> <name>;``)
            or be listed in ``optional_uniforms``: the renderer raises
            RenderError otherwise (a misspelled uniform is never silently dropped).
        optional_uniforms: names of ``uniforms`` (or of the frame-wide ones,
            beyond ``renderer.OPTIONAL_FRAME_UNIFORMS``) that the technique's
            programs may lack; they are skipped where undeclared.
        description: one line for help texts.
    """

    name: str
    vertex: str
    fragment: str
    blended: bool
    attributes: tuple[str, ...] = ("position", "normal", "color", "u", "v", "clip0", "clip1", "normal_field")
    uniforms: Callable[[RenderOptions], dict] = field(default=lambda options: {})
    optional_uniforms: frozenset[str] = frozenset()
    description: str = ""


def filter_uniforms(options: RenderOptions) -> dict:
    """Uniforms of the EWA-filtered techniques: cutoff c and prefilter variance (pixels^2)."""
    return {"u_cutoff": options.filter.cutoff, "u_prefilter": prefilter_variance(options.filter.prefilter)}
