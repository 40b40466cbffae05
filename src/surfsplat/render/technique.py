"""The technique interface: what a rendering technique tells the renderer.

A technique is a small module (``ewa.py``, ``flat.py``, ...) that builds a
:class:`Technique`: its shader files, whether it blends (three passes:
visibility, accumulation, normalization) or draws opaque (one pass), the splat
attributes it reads and its uniforms from the render options. Techniques are
found by name in :data:`TECHNIQUES`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..errors import InputError
from ..reference import prefilter_variance


@dataclass(frozen=True)
class Technique:
    """A rendering technique.

    Attributes:
        name: the name users pass (``--technique NAME``).
        vertex, fragment: shader files in ``glsl/``.
        blended: True for the three-pass pipeline, False for one opaque pass.
        attributes: splat attributes the vertex shader reads (``in_<name>``).
        uniforms: options -> uniform values, called per frame.
        description: one line for help texts.
    """

    name: str
    vertex: str
    fragment: str
    blended: bool
    attributes: tuple[str, ...] = ("position", "normal", "color", "u", "v", "clip0", "clip1", "normal_field")
    uniforms: Callable[["RenderOptions"], dict] = field(default=lambda options: {})
    description: str = ""


@dataclass(frozen=True)
class RenderOptions:
    """Options shared by the techniques (each reads the ones it uses).

    Attributes:
        cutoff: EWA cutoff c of the kernel exponent (Guennebaud 2003, sec. 6).
        prefilter: apply the one-pixel EWA prefilter H = I.
        depth_epsilon: visibility-pass offset along the viewing rays, in units
            of each splat's largest semi-axis (Guennebaud 2003, sec. 5).
        cull_backfaces: drop splats whose normal faces away from the eye. Only
            for closed models with outward normals; it avoids blending across
            silhouette edges within depth_epsilon (default off: two-sided).
            Splats with a normal field are dropped only when no normal of the
            field faces the eye (Botsch 2004, sec. 4.1).
        deferred: blend the splats' albedo and normals and light each pixel
            once from the blended normal (Zwicker et al. 2001; Botsch 2004, fig. 7)
            instead of lighting each splat; any technique.
        kernel: the ``blend`` technique's kernel (Pajarola 2003, sec. 4.2):
            "pajarola" ``psi_E(r) = exp(-a (r / b)^n)`` (EQ 12) or "gaussian"
            ``psi_G(r) = exp(-r^2 / (2 sigma^2))`` (EQ 11), r in [0, b] across the
            ellipse (the kernel is cut at the ellipse, r = b).
        kernel_a, kernel_b, kernel_n: a, b, n of psi_E (the paper's 6, 1.5, 3).
        kernel_sigma: sigma of psi_G, in the units of b.
    """

    cutoff: float = 1.0
    prefilter: bool = True
    depth_epsilon: float = 1.0
    cull_backfaces: bool = False
    deferred: bool = False
    kernel: str = "pajarola"
    kernel_a: float = 6.0
    kernel_b: float = 1.5
    kernel_n: float = 3.0
    kernel_sigma: float = 0.5

    def __post_init__(self) -> None:
        if not (self.cutoff > 0):
            raise InputError(f"cutoff must be positive, got {self.cutoff}")
        if not (self.depth_epsilon >= 0):
            raise InputError(f"depth epsilon must be non-negative, got {self.depth_epsilon}")
        if self.kernel not in KERNELS:
            raise InputError(f"unknown kernel {self.kernel!r}; choose one of {', '.join(KERNELS)}")
        for name in ("kernel_a", "kernel_b", "kernel_n", "kernel_sigma"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 < value < float("inf")):
                raise InputError(f"{name.replace('_', ' ')} must be a positive number, got {value!r}")
        a, _ = self.blend_kernel()
        if a > MAX_KERNEL_EXPONENT:
            # exp(-a) at the rim would underflow float32: pixels only that splat covers get no weight (holes)
            raise InputError(f"blend kernel too narrow: exp(-{a:.4g}) at the splat's rim underflows; keep "
                             f"a <= {MAX_KERNEL_EXPONENT:g} (gaussian: sigma >= b / {(2 * MAX_KERNEL_EXPONENT) ** 0.5:.3g})")

    def blend_kernel(self) -> tuple[float, float]:
        """``(a', n')`` with the kernel weight ``exp(-a' rho^n')`` at normalized radius rho = r / b."""
        if self.kernel == "gaussian":
            # Pajarola 2003, EQ 11 with r = b rho
            return self.kernel_b ** 2 / (2.0 * self.kernel_sigma ** 2), 2.0
        return float(self.kernel_a), float(self.kernel_n)   # EQ 12


#: Largest exponent a' of a blend kernel exp(-a' rho^n): its weight at the rim, exp(-80) = 1.8e-35,
#: is still a normal float32 (the accumulation targets' precision).
MAX_KERNEL_EXPONENT = 80.0

#: Kernels of the ``blend`` technique (RenderOptions.kernel).
KERNELS = ("pajarola", "gaussian")


def filter_uniforms(options: RenderOptions) -> dict:
    """Uniforms of the EWA-filtered techniques: cutoff c and prefilter variance (pixels^2)."""
    return {"u_cutoff": options.cutoff, "u_prefilter": prefilter_variance(options.prefilter)}


TECHNIQUES: dict[str, Technique] = {}


def register(technique: Technique) -> Technique:
    """Add a technique to the registry (by its name) and return it."""
    TECHNIQUES[technique.name] = technique
    return technique


def get_technique(name: str) -> Technique:
    """The technique called ``name``; InputError listing the known ones otherwise."""
    from . import blend, ewa, flat, perspective, phong  # noqa: F401  (modules register themselves)

    try:
        return TECHNIQUES[name]
    except KeyError:
        raise InputError(f"unknown technique {name!r}; choose one of {', '.join(sorted(TECHNIQUES))}") from None
