"""Level of detail of a view: where a cut is chosen (:func:`lod_strategy`, the one rule), what
tolerance it uses (:func:`cut_tolerance`), and the hybrid drawing of non-planar splats."""

from __future__ import annotations

import numpy as np

from .. import defaults
from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError
from ..geometry.preprocess import NONPLANAR
from ..hierarchy import Selection
from ..hierarchy.lod import selection_flags
from ..rendering.hybrid import facing_points
from ..rendering.lod_auto import auto_lod_tolerance
from .models import Model
from .options import LOD_AUTO, LodOptions
from .sources import is_lidar

#: What a view's cut is chosen by: "none" (a cloud drawn whole, or merged per pixel with "auto"),
#: "cpu" (:meth:`Model.cut`) or "gpu" (:mod:`surfsplat.rendering.sequential`).
STRATEGIES = ("none", "cpu", "gpu")


def hybrid_default(source, hybrid: bool | None) -> bool:
    """Whether non-planar splats are drawn as round points: as asked, or (None) for LiDAR files
    (:func:`~surfsplat.pipeline.sources.is_lidar`), whose vegetation and wires have no surface."""
    return is_lidar(source) if hybrid is None else bool(hybrid)


def lod_strategy(model: Model, lod: LodOptions, hybrid: bool, *, interactive: bool) -> str:
    """Where the views of ``model`` are cut (one of :data:`STRATEGIES`): the one rule of every door.

    A model that is no hierarchy and is given no tolerance > 0 and no budget is drawn whole
    ("none"; "auto" merges a cloud's points per pixel instead, without a hierarchy). Otherwise
    ``lod.mode`` decides: "cpu"; "gpu", which draws the tolerance cut of a hierarchy in memory
    (InputError naming what stops it: a point budget, hybrid points, a chunked hierarchy); "auto":
    the GPU for ``interactive`` doors (the viewer: uploaded once, then every frame is cut by the
    vertex shader) where nothing stops it, else the CPU (one picture: uploading every node for
    one frame costs more than gathering its cut)."""
    if not model.is_tree and not lod.cuts and not (lod.tolerance == LOD_AUTO and lod.mode == "gpu"):
        return "none"
    blockers = [what for what, present in (("a point budget", lod.point_budget is not None),
                                           ("hybrid points", hybrid),
                                           ("a chunked hierarchy", not model.in_memory)) if present]
    if lod.mode == "gpu":
        if blockers:
            raise InputError(f"LOD mode 'gpu' draws the tolerance cut of a hierarchy in memory; "
                             f"{' and '.join(blockers)} "
                             f"need LOD mode 'cpu' (or 'auto', which chooses)")
        return "gpu"
    if lod.mode == "auto" and interactive and not blockers:
        return "gpu"
    return "cpu"


def cut_tolerance(lod: LodOptions, supersample: int = 1) -> float:
    """The screen tolerance (output pixels) a hierarchy's cut uses: the one asked for, one pixel of
    the drawn grid for "auto" (:func:`~surfsplat.rendering.lod_auto.auto_lod_tolerance`), else
    :data:`surfsplat.defaults.LOD_TOLERANCE`."""
    if lod.tolerance == LOD_AUTO:
        return auto_lod_tolerance(supersample)
    return defaults.LOD_TOLERANCE if lod.tolerance is None else float(lod.tolerance)


def hybrid_applies(drawn: Model) -> bool:
    """Whether a view drawn hybrid (:func:`hybrid_default`) turns the non-planar splats of ``drawn`` into
    points: a model in memory (a chunked hierarchy is read per view and drawn as splats)."""
    return bool(drawn.in_memory)


def hybrid_splats(drawn: Model, cloud: SplatCloud, selection: Selection | None, camera: Camera) -> SplatCloud:
    """The splats ``cloud`` cut from ``drawn`` with the non-planar ones (the ``nonplanar`` attribute of
    preprocessing) made round points facing the eye of ``camera`` (in the splats' frame) and the
    planar ones left surface splats (:func:`surfsplat.rendering.hybrid.facing_points`). A node splat of
    ``selection`` gets the majority flag of its points. Unchanged when the points carry no such
    attribute (splat files, given normals) or the model is read per view (chunked)."""
    if not hybrid_applies(drawn) or len(cloud) == 0:
        return cloud
    flags = (drawn.points().attributes or {}).get(NONPLANAR)
    if flags is None:
        return cloud
    if selection is not None:
        flags = selection_flags(drawn.data, selection, flags)
    return facing_points(cloud, np.asarray(flags, dtype=bool), camera)
