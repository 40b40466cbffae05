"""Render options, typed by concern: the EWA filter, visibility splatting, the blend kernel.

Every technique reads the groups it uses (see each technique's module):
``ewa`` and ``perspective`` read :class:`FilterOptions`, ``phong`` its cutoff,
``blend`` :class:`KernelOptions`; all blended techniques read
:class:`VisibilityOptions`, and every technique ``deferred``.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Literal, get_args

from ..errors import InputError

#: Names of the rendering techniques (``render.techniques.TECHNIQUES`` holds one of each).
TechniqueName = Literal["ewa", "perspective", "phong", "blend", "flat", "points"]

#: Names of the ``blend`` technique's kernels (:attr:`KernelOptions.name`).
KernelName = Literal["pajarola", "gaussian"]

#: Kernels of the ``blend`` technique (:attr:`KernelOptions.name`).
KERNELS: tuple[str, ...] = get_args(KernelName)

#: Largest exponent a' of a blend kernel exp(-a' rho^n): its weight at the rim, exp(-80) = 1.8e-35,
#: is still a normal float32 (the accumulation targets' precision).
MAX_KERNEL_EXPONENT = 80.0
#: Smallest EWA cutoff c: below it the kernel is flat across the ellipse (exp(-c) ~ 1) and the
#: reconstruction variance 1 / (2c) of an image-filling splat nears float32's range.
MIN_CUTOFF = 1e-3
#: Largest visibility depth epsilon, in splat radii: far beyond any use, well inside float32.
MAX_DEPTH_EPSILON = 1e6
#: Largest exponent n of the pajarola kernel (the paper's 3; beyond ~100 it is a box already).
MAX_KERNEL_N = 1e3


def _is_number(value) -> bool:
    """A real number (not a bool, not a string), finite."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True)
class FilterOptions:
    """The EWA resampling filter of ``ewa`` and ``perspective`` (Guennebaud 2003, sec. 6; Zwicker 2004).

    Attributes:
        prefilter: apply the one-pixel EWA prefilter ``H = I`` (variance 1 pixel^2);
            off, a 1e-4 pixel^2 regularizer keeps edge-on splats invertible.
        cutoff: c, unitless: the kernel is cut where ``0.5 x^T V^-1 x = c``
            (the splat's ellipse is the contour of the reconstruction kernel at
            c); ``phong`` uses it as its Gaussian's exponent ``exp(-c r^2)``, r
            in splat radii.
    """

    prefilter: bool = True
    cutoff: float = 1.0

    def __post_init__(self) -> None:
        # the weight at the ellipse's rim is exp(-c): above MAX_KERNEL_EXPONENT it underflows float32
        if not (_is_number(self.cutoff) and MIN_CUTOFF <= self.cutoff <= MAX_KERNEL_EXPONENT):
            raise InputError(f"cutoff must be a number in [{MIN_CUTOFF:g}, {MAX_KERNEL_EXPONENT:g}], "
                             f"got {self.cutoff!r}", argument="cutoff")


@dataclass(frozen=True)
class VisibilityOptions:
    """Visibility splatting of the blended techniques (Guennebaud 2003, sec. 5).

    Attributes:
        depth_epsilon: visibility-pass offset along the viewing rays, in units
            of each splat's largest semi-axis (>= 0): splats within it of the
            nearest surface are blended.
        cull_backfaces: drop splats whose normal faces away from the eye. Only
            for closed models with outward normals; it avoids blending across
            silhouette edges within depth_epsilon, and the back side's splats
            that a flat disk pushes past a curved silhouette (drawn as a dark rim
            by two-sided lighting). None (default): automatic
            (:func:`surfsplat.geometry.closed.automatic_culling`): the samples of
            a closed mesh seen from outside are culled by ``ewa`` and
            ``perspective`` (whose fringe and edge coverage cover the silhouette
            pixels only back faces covered), everything else is drawn two-sided
            (a back-facing splat may be the only one covering a pixel of the
            front); closed meshes and clouds are oriented outward, so True keeps
            their visible side.
            Splats with a normal field are dropped only when no normal of the
            field faces the eye (Botsch 2004, sec. 4.1). Hierarchy selections
            use it for normal-cone culling too.
        separate_sides: a pixel blends only the splats seen from the same side
            (front or back of the splat, by its normal) as its nearest splat.
            Without it the back of a hidden wall lying within depth_epsilon
            behind a visible surface (thin walls, pocket walls of CAD parts,
            silhouettes) blends into it as a dark outline; with it models render
            two-sided and clean, as long as the normals are consistently
            oriented (preprocessing orients estimated normals).
        clip_fringe: ``ewa`` and ``perspective`` (whose EWA prefilter widens every
            footprint by about a pixel beyond the splat's disk) drop the fringe where
            it covers no disk or only a farther surface: silhouettes and the crests
            of folds end at the surface instead of a pixel beyond it; inside the
            surface the fringes still blend (texture antialiasing), and a pixel no
            disk covers keeps them where 3 or 4 of its neighbours are covered (the
            one-pixel cracks straight clip lines leave at curved sharp edges). Off:
            the papers' full footprints everywhere.
        edge_coverage: a pixel on the rim of a silhouette over the background is
            composited over it by the fraction of its area the splats' disks (and
            clip lines) cover, to first order in the distance of its center to
            their rims, instead of all (a disk covers its center) or nothing: the
            silhouette is antialiased without supersampling, and ``Frame.alpha``
            is that coverage. Inside the surface and at occlusion edges over
            another surface the coverage stays 1. ``ewa`` and ``perspective``
            reach the pixels beyond the rim with their filter's fringe; ``blend``
            and ``phong`` draw only inside their disks (the rim's inner pixels).
            On by default (``--no-edge-coverage``: all-or-nothing rims, the
            papers'), by measurement against the 4 x 4 mesh at 512 x 512
            (benchmarks/contour_quality.py): better over the whole image for every
            technique and model measured (ewa: +7.1 dB on the bunny, +2.7 on the
            CAD part, +0.9 on a finely detailed surface, smooth parts unchanged),
            for 28-64 % of a point cloud's 512 x 512 frame on llvmpipe (closed
            meshes, culled by default, draw as fast as before). The disk of a splat
            smaller than about a pixel covers less than the union of its
            neighbours, so rims of sub-pixel splats come out a little light
            (measured in tests/test_edges.py).
    """

    depth_epsilon: float = 1.0
    cull_backfaces: bool | None = None
    separate_sides: bool = True
    clip_fringe: bool = True
    edge_coverage: bool = True

    def __post_init__(self) -> None:
        if not (_is_number(self.depth_epsilon) and 0 <= self.depth_epsilon <= MAX_DEPTH_EPSILON):
            raise InputError(f"depth epsilon must be a number in [0, {MAX_DEPTH_EPSILON:g}] (splat radii), "
                             f"got {self.depth_epsilon!r}", argument="depth_epsilon")


@dataclass(frozen=True)
class KernelOptions:
    """The ``blend`` technique's kernel (Pajarola 2003, sec. 4.2), r in [0, b] across the ellipse
    (the kernel is cut at the ellipse, r = b).

    Attributes:
        name: "pajarola": ``psi_E(r) = exp(-a (r / b)^n)`` (EQ 12), or
            "gaussian": ``psi_G(r) = exp(-r^2 / (2 sigma^2))`` (EQ 11).
        a: a of psi_E, unitless (the paper's 6).
        b: b, the kernel radius at the splat's ellipse, in the kernel's units of r (the paper's 1.5).
        n: n of psi_E, unitless exponent (the paper's 3).
        sigma: sigma of psi_G, in the units of b.
    """

    name: KernelName = "pajarola"
    a: float = 6.0
    b: float = 1.5
    n: float = 3.0
    sigma: float = 0.5

    def __post_init__(self) -> None:
        if self.name not in KERNELS:
            raise InputError(f"unknown kernel {self.name!r}; choose one of {', '.join(KERNELS)}", argument="name")
        for name in ("a", "b", "n", "sigma"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 < value < float("inf")):
                raise InputError(f"kernel {name} must be a positive number, got {value!r}", argument=name)
        if self.n > MAX_KERNEL_N:
            raise InputError(f"kernel n must be in (0, {MAX_KERNEL_N:g}], got {self.n!r}", argument="n")
        a, _ = self.exponent()
        if a > MAX_KERNEL_EXPONENT:
            # exp(-a) at the rim would underflow float32: pixels only that splat covers get no weight (holes)
            min_sigma = (2 * MAX_KERNEL_EXPONENT) ** 0.5
            raise InputError(f"blend kernel too narrow: exp(-{a:.4g}) at the splat's rim underflows; keep "
                             f"a <= {MAX_KERNEL_EXPONENT:g} (gaussian: sigma >= b / {min_sigma:.3g})",
                             argument="sigma" if self.name == "gaussian" else "a")

    def exponent(self) -> tuple[float, float]:
        """``(a', n')`` with the kernel weight ``exp(-a' rho^n')`` at normalized radius rho = r / b."""
        if self.name == "gaussian":
            # Pajarola 2003, EQ 11 with r = b rho
            ratio = float(self.b) / float(self.sigma)   # inf for a huge ratio, never OverflowError
            return (ratio * ratio / 2.0 if ratio < 1e150 else float("inf")), 2.0
        return float(self.a), float(self.n)   # EQ 12


@dataclass(frozen=True)
class EdlOptions:
    """Eye-dome lighting (Boucheny 2009), a post pass from the depth alone (:mod:`surfsplat.rendering.edl`).

    Attributes:
        strength: s in ``shade = exp(-s * sum_n max(0, log2 z_p - log2 z_n))``, unitless (> 0);
            the default is Potree's (300 x its strength 1 / 8 neighbours).
        radius_px: r, output pixels (1..64): the 8 neighbours lie at r (cos, sin) of k 45 degrees,
            rounded to whole pixels (Potree's 1.4 gives the 3 x 3 ring).
    """

    strength: float = 37.5
    radius_px: float = 1.4

    def __post_init__(self) -> None:
        if not (isinstance(self.strength, (int, float)) and 0 < self.strength < float("inf")):
            raise InputError(f"EDL strength must be a positive number, got {self.strength!r}", argument="strength")
        if not (isinstance(self.radius_px, (int, float)) and 1 <= self.radius_px <= 64):
            raise InputError(f"EDL radius must be in 1..64 pixels, got {self.radius_px!r}", argument="radius_px")


@dataclass(frozen=True)
class RenderOptions:
    """Options shared by the techniques, by concern (each technique reads the ones it uses).

    Attributes:
        filter: the EWA resampling filter (:class:`FilterOptions`): prefilter and cutoff.
        visibility: visibility splatting (:class:`VisibilityOptions`): depth
            epsilon (splat radii) and back-face culling.
        kernel: the ``blend`` technique's kernel (:class:`KernelOptions`).
        deferred: blend the splats' albedo and normals and light each pixel
            once from the blended normal (Zwicker et al. 2001; Botsch 2004, fig. 7)
            instead of lighting each splat; any technique. Off by default, by
            measurement against the mesh (benchmarks/edge_quality.py): on smooth
            surfaces it is 0.5-1.2 dB better inside the silhouette (the bunny), but
            at creases it lights the average of the two faces' normals where the
            mesh (and per-splat lighting) averages the two lit colours: 3.9 dB worse
            inside the CAD part.
        edl: eye-dome lighting (:class:`EdlOptions`) of the rendered image; None: off.
        fill_holes: fill the holes of up to 3 pixels between the pixels of a front surface in screen space
            after the normalization pass (every technique; :func:`surfsplat.reference.fill_holes`, ``fill.frag``):
            a pixel no splat covers, or whose splats lie behind the surface around it, is filled with the
            depth and color of the front surface where that surface encloses it along 3 of 4 axes
            (horizontal, vertical, the diagonals); the background beyond a silhouette is never enclosed,
            so silhouettes do not grow, and larger holes stay holes.
        compute: draw the small splats' first pass (the blended techniques' visibility, ``flat``'s
            nearest disk) with compute shaders where the context has OpenGL 4.3
            (:mod:`~surfsplat.rendering.compute_visibility`: faster on llvmpipe); False: every splat through
            the raster pipeline. The pictures are the same (``flat``: but where two disks tie in depth).
    """

    filter: FilterOptions = field(default_factory=FilterOptions)
    visibility: VisibilityOptions = field(default_factory=VisibilityOptions)
    kernel: KernelOptions = field(default_factory=KernelOptions)
    deferred: bool = False
    edl: EdlOptions | None = None
    fill_holes: bool = True
    compute: bool = True

    def __post_init__(self) -> None:
        for name in ("fill_holes", "compute"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"render option {name} must be True or False, got {getattr(self, name)!r}",
                                 argument=name)
        if self.edl is not None and not isinstance(self.edl, EdlOptions):
            raise InputError(f"render option edl must be an EdlOptions or None, got {type(self.edl).__name__}",
                             argument="edl")
        for name, kind in (("filter", FilterOptions), ("visibility", VisibilityOptions), ("kernel", KernelOptions)):
            value = getattr(self, name)
            if not isinstance(value, kind):
                raise InputError(f"render option {name} must be a {kind.__name__}, got {type(value).__name__}",
                                 argument=name)
