"""The technique interface: what a rendering technique tells the renderer.

A technique is a small module (``ewa.py``, ``flat.py``, ...) that defines a
:class:`Technique` constant: its shader files, whether it blends (three passes:
visibility, accumulation, normalization) or draws opaque (one pass), the splat
attributes it reads, its uniforms from the render options, and its capabilities:
whether small splats may be drawn as GL_POINTS and how their window box is bounded,
whether its first pass may run as compute shaders, whether it supports edge
coverage and whether its footprints have a filter fringe. The renderer plans each
frame's passes from these declarations alone (:mod:`surfsplat.rendering.passes`),
never from the shader files' names. The table of techniques by name is
:data:`surfsplat.rendering.techniques.TECHNIQUES`; this module imports none of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Literal, get_args

from ..errors import InputError
from ..reference import prefilter_variance
from .options import RenderOptions

#: How a technique's vertex shader bounds a small splat's window box when it emits it as one GL_POINTS
#: point (``glsl/splat_primitive.glsl``, ``POINT_PRIMITIVE``), which sets the largest splat drawn as a
#: point (``passes.point_scale``): "disk": the box of the splat's disk (``disk_vertex.glsl``);
#: "filtered_disk": that box grown by the EWA prefilter (Guennebaud 2003, eq. 6: ``+ 2 sqrt(2 c h)``
#: pixels, from ``RenderOptions.filter``); "adaptive": a round point of diameter ``2 r f / z`` clamped
#: from below by ``Technique.min_point_px`` output pixels (``points.vert``).
PointFootprint = Literal["disk", "filtered_disk", "adaptive"]
POINT_FOOTPRINTS: tuple[str, ...] = get_args(PointFootprint)


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
        point_footprint: None: every splat is an instanced quad; else the vertex shader
            emits small splats as GL_POINTS (it includes ``splat_primitive.glsl`` and
            honours ``POINT_PRIMITIVE``) and this names how their box is bounded
            (:data:`PointFootprint`).
        min_point_px: the smallest point diameter, output pixels ("adaptive" footprints:
            the clamp of ``points.vert``); 0 otherwise.
        compute_visibility: blended only: the small splats' visibility pass may run as
            compute shaders (``visibility.comp``): the technique's visibility pass is the
            shared ray-cast disk of ``splat_fragment.glsl`` (depth offset by epsilon).
        compute_opaque: opaque only: the small splats' nearest disk may be computed and
            their fragment written by ``opaque_resolve.frag``, which writes what ``flat.frag``
            does (a lit disk at its exact depth); only a technique drawing exactly that may say so.
        edge_coverage: blended only: the accumulation pass writes the splats' pixel coverage
            (``EDGE_COVERAGE``, ``VisibilityOptions.edge_coverage``) through ``splat_fragment.glsl``.
        edge_fringe: the footprints reach beyond the splat's disk (the EWA prefilter's fringe):
            with edge coverage, pixels beyond a silhouette take the disks' distances there
            (``u_edge_fringe`` of ``normalize.frag``).
        hiz_cull: blended only: the accumulation pass's vertex shader drops a splat that lies behind the
            blocks of the visibility record its box touches (it includes ``hiz.glsl`` and honours
            ``HIZ_BLOCK``; ``passes.HizPass``), every fragment of which its fragment shader would discard.
    """

    name: str
    vertex: str
    fragment: str
    blended: bool
    attributes: tuple[str, ...] = ("position", "normal", "color", "u", "v", "clip0", "clip1", "normal_field")
    uniforms: Callable[[RenderOptions], dict] = field(default=lambda options: {})
    optional_uniforms: frozenset[str] = frozenset()
    description: str = ""
    point_footprint: PointFootprint | None = None
    min_point_px: float = 0.0
    compute_visibility: bool = False
    compute_opaque: bool = False
    edge_coverage: bool = False
    edge_fringe: bool = False
    hiz_cull: bool = False

    def __post_init__(self) -> None:
        where = f"technique {self.name!r}"
        if self.point_footprint is not None and self.point_footprint not in POINT_FOOTPRINTS:
            raise InputError(f"{where}: point_footprint must be None or one of {', '.join(POINT_FOOTPRINTS)}, "
                             f"got {self.point_footprint!r}")
        if not (self.min_point_px >= 0.0 and self.min_point_px < float("inf")):
            raise InputError(f"{where}: min_point_px must be a finite number >= 0, got {self.min_point_px!r}")
        blended_only = [name for name in ("compute_visibility", "edge_coverage", "hiz_cull") if getattr(self, name)]
        if blended_only and not self.blended:
            raise InputError(f"{where}: {' and '.join(blended_only)} need a blended technique (the visibility "
                             f"and accumulation passes)")
        if self.compute_opaque and self.blended:
            raise InputError(f"{where}: compute_opaque is the one pass of an opaque technique; a blended one "
                             f"declares compute_visibility")


def filter_uniforms(options: RenderOptions) -> dict:
    """Uniforms of the EWA-filtered techniques: cutoff c and prefilter variance (pixels^2)."""
    return {"u_cutoff": options.filter.cutoff, "u_prefilter": prefilter_variance(options.filter.prefilter)}
