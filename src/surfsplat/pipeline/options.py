"""What a view is made of, before any data is read: how a source becomes splats
(:class:`SourceOptions`) and how its level of detail is chosen (:class:`LodOptions`).

Both check every field when built, so a bad value fails before any loading or preprocessing,
in the Python API as on the command line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, Union

import numpy as np

from .. import defaults
from ..colors import ColorOptions
from ..errors import InputError
from ..geometry.robust import OUTLIER_ACTIONS, OutlierAction
from ..geometry.sampling import DEFAULT_SPACING_PX
from ..hierarchy import SHADINGS, LodShading
from ..hierarchy.lod import check_point_budget
from ..io.surface import AUTO

#: Where a hierarchy's cut is chosen: "cpu" (selected, gathered and uploaded per view), "gpu"
#: (sequential point trees: every node uploaded once, the vertex shader keeps the cut) or "auto"
#: (:func:`surfsplat.pipeline.lod.lod_strategy`).
LodMode = Literal["cpu", "gpu", "auto"]
LOD_MODES: tuple[str, ...] = ("cpu", "gpu", "auto")
#: A tolerance that follows the output resolution (:mod:`surfsplat.rendering.lod_auto`).
LOD_AUTO = "auto"
#: A LOD tolerance: pixels, "auto", or None (every splat of a cloud; a hierarchy at the default).
Tolerance = Union[float, Literal["auto"], None]


def _integer(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


@dataclass(frozen=True)
class SourceOptions:
    """How a source becomes splats: raw points (preprocessed) and meshes (sampled).

    Attributes:
        k: neighbours for preprocessing raw points (>= 3).
        outliers: raw points with no surface neighbourhood of their own (stray points,
            isolated clusters): "drop" (default: the best picture), "cap" their splats, or
            "keep" (:func:`surfsplat.geometry.preprocess.preprocess`).
        vertices: draw a mesh's vertices as points (preprocessed like a scan) instead of
            sampling its surface (the default).
        samples: number of surface samples of a mesh; None: from the view, ``spacing_px``
            apart on screen (:func:`surfsplat.geometry.sampling.samples_for_pixels`, capped at 2M).
        spacing_px: mean on-screen sample spacing, pixels, when ``samples`` is None.
        sharp_angle: dihedral angle (degrees) above which edges are sharp (crease normals, clip
            lines); "auto": 30 for meshes with creases (CAD), none for smooth scans and raw
            points (:func:`surfsplat.io.surface.auto_sharp_angle`); None: no sharp edges. A
            number also detects sharp features in raw points.
        seed: random seed of the samples.
        color: colour the splats by elevation or a per-point attribute
            (:class:`~surfsplat.colors.ColorOptions`); None: their own colours.
        hybrid: draw non-planar neighbourhoods (vegetation, wires) as round points facing the eye
            and planar ones as surface splats, in one frame; None: on for LiDAR files
            (:func:`surfsplat.pipeline.sources.is_lidar`), off otherwise.
    """

    k: int = defaults.K
    outliers: OutlierAction = "drop"
    vertices: bool = False
    samples: int | None = None
    spacing_px: float = DEFAULT_SPACING_PX
    sharp_angle: float | str | None = AUTO
    seed: int = 0
    color: ColorOptions | None = None
    hybrid: bool | None = None

    def __post_init__(self) -> None:
        if self.color is not None and not isinstance(self.color, ColorOptions):
            raise InputError(f"color must be a ColorOptions, got {type(self.color).__name__}")
        if not (_integer(self.k) and self.k >= 3):
            raise InputError(f"k must be an integer >= 3 (neighbours), got {self.k!r}")
        if self.outliers not in OUTLIER_ACTIONS:
            raise InputError(f"outliers must be one of {', '.join(OUTLIER_ACTIONS)}, got {self.outliers!r}")
        if self.samples is not None and not (_integer(self.samples) and self.samples >= 2):
            raise InputError(f"samples must be an integer >= 2, got {self.samples!r}")
        if not (isinstance(self.spacing_px, (int, float)) and math.isfinite(self.spacing_px) and self.spacing_px > 0):
            raise InputError(f"sample spacing must be a positive number of pixels, got {self.spacing_px!r}")
        angle = self.sharp_angle
        if not (angle is None or angle == AUTO or (isinstance(angle, (int, float)) and not isinstance(angle, bool)
                                                   and 0.0 < float(angle) < 180.0)):
            raise InputError(f"sharp_angle must be degrees in (0, 180), 'auto' or None, got {angle!r}")
        if self.hybrid is not None and not isinstance(self.hybrid, (bool, np.bool_)):
            raise InputError(f"hybrid must be True, False or None (automatic), got {self.hybrid!r}")

    @property
    def raw_sharp_angle(self) -> float | None:
        """The sharp-feature angle for raw points: a number given, else none ("auto" decides for meshes)."""
        angle = self.sharp_angle
        return float(angle) if isinstance(angle, (int, float)) and not isinstance(angle, bool) else None


@dataclass(frozen=True)
class LodOptions:
    """How the level of detail of a view is chosen (Pajarola 2003, sec. 5.1; Potree's budget).

    Attributes:
        tolerance: screen tolerance in pixels: hierarchy nodes whose projected ellipse is at most
            this wide are drawn as one splat (a cloud given a tolerance > 0 gets its hierarchy
            built first). None (default): every splat of a cloud, a hierarchy cut at
            :data:`surfsplat.defaults.LOD_TOLERANCE`. "auto": a hierarchy cut at one pixel of the
            drawn grid; a cloud's points merged per half pixel where the view is dense, without a
            hierarchy (:mod:`surfsplat.rendering.lod_auto`).
        shading: normal field of coarse LOD splats: "fit" (least squares), "cone" (Pajarola 2003,
            fig. 14) or "flat".
        point_budget: at most this many splats (>= 1): the cut refined largest node on screen first
            (Potree's priority; a cloud gets its hierarchy built first). None: the whole cut.
        mode: where the cut is chosen: "cpu", "gpu" (sequential point trees, Dachsbacher 2003) or
            "auto" (:func:`surfsplat.pipeline.lod.lod_strategy`: the GPU for interactive views where it
            can, else the CPU).
    """

    tolerance: Tolerance = None
    shading: LodShading = defaults.LOD_SHADING  # type: ignore[assignment]
    point_budget: int | None = None
    mode: LodMode = defaults.LOD_MODE  # type: ignore[assignment]

    def __post_init__(self) -> None:
        t = self.tolerance
        if not (t is None or t == LOD_AUTO or (isinstance(t, (int, float, np.floating)) and not isinstance(t, bool)
                                               and math.isfinite(t) and t >= 0)):
            raise InputError(f"LOD tolerance must be a number of pixels >= 0, 'auto' or None, got {t!r}")
        if self.shading not in SHADINGS:
            raise InputError(f"LOD shading must be one of {', '.join(SHADINGS)}, got {self.shading!r}")
        if self.point_budget is not None:
            check_point_budget(self.point_budget)
        if self.mode not in LOD_MODES:
            raise InputError(f"LOD mode must be one of {', '.join(LOD_MODES)}, got {self.mode!r}")

    @property
    def cuts(self) -> bool:
        """Whether a cloud needs a hierarchy for these options (a tolerance > 0 or a budget)."""
        tolerance = self.tolerance
        return self.point_budget is not None or (isinstance(tolerance, (int, float)) and tolerance > 0)
