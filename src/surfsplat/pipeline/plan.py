"""The view plan: from (source, camera or camera spec, options) to what is drawn.

:class:`View` loads a source once (sampled, preprocessed, coloured) and renders it for any number
of cameras; every door (:func:`surfsplat.render`, each CLI command, the viewer, the notebook
widget, turntables and batches) drives one. Each decision about a view is made by one function
(``docs/architecture.md``): the camera and its near/far (:mod:`~surfsplat.pipeline.framing`),
automatic culling (:meth:`View.culls`), hybrid drawing (:func:`~surfsplat.pipeline.lod.hybrid_default`),
the level-of-detail strategy and tolerance (:func:`~surfsplat.pipeline.lod.lod_strategy`,
:func:`~surfsplat.pipeline.lod.cut_tolerance`), the background (:func:`check_background`) and the
image size (:func:`check_image_size`).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, replace

import numpy as np

from .. import defaults, progress
from ..camera import Camera, camera_flags
from ..camera_path import orbit_cameras
from ..errors import EmptyFrameWarning, InputError
from ..geometry.closed import automatic_culling
from ..hierarchy import Selection
from ..hierarchy.sequential import SequentialLayout, sequential_layout
from ..lighting import Lights
from ..rendering.frame import Frame, check_background
from ..rendering.lod_auto import auto_merged
from ..rendering.options import RenderOptions, TechniqueName
from ..rendering.renderer import default_renderer
from ..rendering.sequential import render_sequential
from ..rendering.tiles import check_supersample
from ..rendering.techniques import get_technique
from ..io.image_maps import normals_from_depth
from .framing import CameraSpec, local_camera, resolve_camera
from .lod import cut_tolerance, hybrid_default, hybrid_splats, lod_strategy
from .models import Model, as_model
from .options import LOD_AUTO, LodOptions, SourceOptions
from .sources import check_source, read_source, source_name, up_of

#: A frame covering less than this fraction of the pixels the model's bounds project to warns.
MIN_COVERAGE = 0.01


def check_image_size(width, height, limit: int = defaults.MAX_IMAGE_SIDE, what: str = "image") -> tuple[int, int]:
    """``(width, height)`` as integers in 1..``limit`` pixels; InputError naming them otherwise."""
    ok = all(isinstance(x, (int, np.integer)) and not isinstance(x, bool) and 1 <= x <= limit for x in (width, height))
    if not ok:
        raise InputError(f"{what} size must be whole numbers of pixels in 1..{limit}, got {width!r} x {height!r}")
    return int(width), int(height)


def check_render_args(*, technique="ewa", width=defaults.API_IMAGE_SIZE, height=defaults.API_IMAGE_SIZE,
                      background=defaults.BACKGROUND, options=None, supersample=1, lights=None) -> None:
    """Every argument of a render checked before any file is read (InputError naming the first bad
    one): a known technique, the image size, the background, the supersampling factor, the types of
    the options and lights."""
    get_technique(technique)
    check_image_size(width, height)
    check_background(background)
    check_supersample(supersample)
    if options is not None and not isinstance(options, RenderOptions):
        raise InputError(f"options must be a RenderOptions, got {type(options).__name__}")
    if lights is not None and not isinstance(lights, Lights):
        raise InputError(f"lights must be a Lights, got {type(lights).__name__}")


@dataclass(frozen=True)
class RenderResult:
    """A rendered view and what was drawn.

    Attributes:
        frame: the image, depth and weight.
        splats: number of splats drawn.
        selection: the LOD selection (a hierarchy's cut), or None for a plain cloud.
        seconds: wall-clock time of merging or selection, upload, drawing and read-back.
        merged_from: the cloud's splats when ``LodOptions(tolerance="auto")`` merged them per half pixel
            (:func:`~surfsplat.rendering.lod_auto.merge_in_pixels`), else None.
        gpu_lod_tolerance: the tolerance (pixels) of a cut made on the GPU (``splats``: the entries
            handed to it, each kept or dropped by its vertex shader), else None.
    """

    frame: Frame
    splats: int
    selection: Selection | None = None
    seconds: float = 0.0
    merged_from: int | None = None
    gpu_lod_tolerance: float | None = None

    def describe(self) -> str:
        """One line: what was drawn ('1,234 splats' or the LOD cut's counts)."""
        s = self.selection
        if self.gpu_lod_tolerance is not None:
            return f"the GPU LOD cut (tolerance {self.gpu_lod_tolerance:g} px) of {self.splats:,} entries"
        if s is None and self.merged_from is not None:
            return f"{self.splats:,} splats (merged per half pixel from {self.merged_from:,})"
        if s is None:
            return f"{self.splats:,} splats"
        budget = getattr(s, "budget_priority", None)   # a chunked model's budget: where its priority order stopped
        return (f"{self.splats:,} LOD splats (tolerance {s.lod_tolerance:g} px, {s.node_count:,} nodes, "
                f"{s.point_total:,} points{'' if budget is None else f'; budget reached {budget:.3g} px'})")

    def normals(self, space: str = "camera") -> np.ndarray:
        """(H, W, 3) float32 unit normals of the visible surface, computed from the depth map (NaN where
        empty; :func:`surfsplat.io.image_maps.normals_from_depth`), in "camera" or "world" space."""
        return normals_from_depth(self.frame.depth, self.frame.camera, space=space)

    @property
    def coverage(self) -> np.ndarray:
        """(H, W) float32 antialiased coverage in [0, 1]: the fraction of each pixel the surface covers."""
        return self.frame.alpha


class View:
    """A prepared view: a source loaded once (sampled, preprocessed, coloured) and drawn for any
    number of cameras with the same decisions.

    Args:
        source: a SplatCloud (preprocessed if it lacks normals or splat axes), a
            :class:`~surfsplat.hierarchy.Hierarchy`, a :class:`~surfsplat.io.Mesh`, ``"demo:NAME"``,
            a path (a point/splat file, a mesh file, a hierarchy ``.npz`` or a chunked hierarchy
            directory from ``surfsplat build``) or another object :func:`surfsplat.io.objects.from_object`
            reads (an (N, 3) array, a table of columns, trimesh and Open3D objects).
        source_options: how the source becomes splats (:class:`SourceOptions`).
        lod: how the level of detail is chosen (:class:`LodOptions`).
        interactive: the views are a window's or a widget's, many per second (``LodOptions(mode="auto")``
            then cuts on the GPU where it can, :func:`~surfsplat.pipeline.lod.lod_strategy`).

    A mesh's surface is sampled once, for the first camera drawn (or :meth:`sample`); a cloud that
    needs a hierarchy gets it built once.
    """

    def __init__(self, source, *, source_options: SourceOptions | None = None, lod: LodOptions | None = None,
                 interactive: bool = False) -> None:
        if source_options is not None and not isinstance(source_options, SourceOptions):
            raise InputError(f"source_options must be a SourceOptions, got {type(source_options).__name__}")
        if lod is not None and not isinstance(lod, LodOptions):
            raise InputError(f"lod must be a LodOptions, got {type(lod).__name__}")
        self.source_options = source_options or SourceOptions()
        self.lod = lod or LodOptions()
        self.interactive = bool(interactive)
        self.name = source_name(source)
        check_source(source)
        #: Whether non-planar splats are drawn as round points (:func:`hybrid_default`).
        self.hybrid = hybrid_default(source, self.source_options.hybrid)
        read = read_source(source, self.source_options)
        #: The up axis of the data (the world up of automatic cameras and orbits), and why
        #: (:func:`~surfsplat.pipeline.sources.up_of`: stored, the file kind's, or guessed).
        self.up, self.up_reason = up_of(source, read)
        self.model: Model = as_model(read).colored(self.source_options.color, self.up)
        self._told_up = False
        self._drawn: Model | None = None        # the model as splats, oriented outward where closed
        self._facing: tuple | None = None       # (eye, camera) whose facing samples alone _drawn holds, if so
        self._outward = False
        self._tree: Model | None = None         # the hierarchy a cut needs (built once for a cloud)
        self._layout: SequentialLayout | None = None   # the GPU LOD layout of the hierarchy
        self._source = source
        #: The :func:`~surfsplat.rendering.renderer.content_key` of ``source`` (a SplatCloud) where a caller
        #: computed it (:func:`surfsplat.render` checks its last view by it): the renderer then takes it
        #: for the frames that draw that very cloud instead of computing it again.
        self.source_key: tuple | None = None

    # -- cameras -------------------------------------------------------------

    def camera(self, camera: Camera | CameraSpec | None = None, width: int = defaults.API_IMAGE_SIZE,
               height: int = defaults.API_IMAGE_SIZE) -> Camera:
        """A Camera as it is; a :class:`CameraSpec` (None: automatic framing) resolved against the model
        at ``width`` x ``height`` pixels about the data's up axis (:attr:`up`) where it gives none."""
        if not isinstance(camera, (Camera, CameraSpec, type(None))):
            raise InputError(f"camera must be a Camera, a CameraSpec or None, got {type(camera).__name__}")
        if not isinstance(camera, Camera):
            width, height = check_image_size(width, height)
            if (camera is None or camera.up is None) and not self._told_up:
                progress.message(self.up_reason)   # the data's up is used: say which and how to change it
                self._told_up = True
        return resolve_camera(self.model, camera, width, height, default_up=self.up)

    # -- what is drawn ---------------------------------------------------------

    def sample(self, camera: Camera | None = None, image_size: int = defaults.API_IMAGE_SIZE,
               facing: bool | None = None) -> Model:
        """The model as splats, made once: a mesh's surface sampled for ``camera`` (or with the model
        ``image_size`` pixels wide), oriented outward where it samples closed surfaces.

        ``facing=True`` (:meth:`render`, where the view culls back faces and nothing was sampled
        yet): a closed mesh keeps only the samples facing ``camera``'s eye (the others would be
        culled: about half the sampling, sizing, upload and drawing of a single picture). Those serve
        that camera only: asked for another camera (or ``facing=False``), the whole surface is
        sampled once, at the density of that first camera (the same samples as without ``facing``),
        and kept for every later view. ``None``: what is there, where it serves."""
        eye = None if camera is None else tuple(np.asarray(camera.eye, dtype=np.float64).tolist())
        if self._drawn is not None and self._facing is not None and (facing is False or eye != self._facing[0]):
            # the facing samples of another view: the whole surface, at the density of the first view
            camera, self._drawn, self._facing, facing = self._facing[1], None, None, False
        if self._drawn is None:
            facing = bool(facing) and eye is not None and self.model.facing_only()
            surface = self.model.surface(camera, self.source_options, image_size, facing=facing)
            self._drawn, self._outward = surface.outward()
            self._facing = (eye, camera) if facing else None
        return self._drawn

    def _facing_first(self, camera: Camera, options: RenderOptions, technique: TechniqueName) -> bool:
        """Whether :meth:`render` samples only the faces ``camera`` sees (:meth:`sample`'s ``facing``):
        nothing sampled yet, not interactive, a closed mesh, and back faces culled in this view as
        :meth:`culls` would decide (asked, or automatic: seen from outside its bounds by a technique
        with a fringe)."""
        if self._drawn is not None or self.interactive or not self.model.facing_only():
            return False
        asked = options.visibility.cull_backfaces
        if asked is not None:
            return bool(asked)
        return automatic_culling(True, self.model.bounds(), camera.eye, sampled_mesh=True,
                                 fringe=get_technique(technique).edge_fringe)

    def tree(self, camera: Camera | None = None) -> Model:
        """The model as a hierarchy (built once over :meth:`sample` for a cloud: the whole surface of a
        mesh, never a single view's facing samples, as the hierarchy serves every view)."""
        if self._tree is None:
            self._tree = self.sample(camera, facing=False).tree()
        return self._tree

    def culls(self, camera: Camera, options: RenderOptions | None = None, technique: TechniqueName = "ewa") -> bool:
        """Whether back faces are culled for ``camera`` and ``technique``: as ``options`` say, or where
        automatic (``cull_backfaces`` None) as :func:`~surfsplat.geometry.closed.automatic_culling`
        decides for the sampled splats: for a closed mesh's samples seen from outside, drawn by a
        technique whose footprints reach past the disks (``ewa``, ``perspective``: their fringe and
        edge coverage cover the silhouette pixels only back faces covered); never for a point cloud
        (a back-facing splat may be the only one covering a pixel of its front)."""
        asked = (options or RenderOptions()).visibility.cull_backfaces
        if asked is not None:
            return bool(asked)
        drawn = self.sample(camera)
        return automatic_culling(self._outward, drawn.bounds(), camera.eye,
                                 sampled_mesh=bool(getattr(self.model, "closed", False)),
                                 fringe=get_technique(technique).edge_fringe)

    def strategy(self, camera: Camera | None = None) -> str:
        """Where the views are cut (:func:`~surfsplat.pipeline.lod.lod_strategy` of the sampled model)."""
        return lod_strategy(self.sample(camera), self.lod, self.hybrid, interactive=self.interactive)

    # -- drawing ---------------------------------------------------------------

    def render(self, camera: Camera | CameraSpec | None = None, *, technique: TechniqueName = "ewa",
               width: int = defaults.API_IMAGE_SIZE, height: int = defaults.API_IMAGE_SIZE,
               lights: Lights | None = None, background=defaults.BACKGROUND, options: RenderOptions | None = None,
               supersample: int = 1) -> RenderResult:
        """Draw the view of ``camera`` (a CameraSpec or None resolved at ``width`` x ``height``).

        Args:
            technique: "ewa", "perspective", "phong", "blend", "flat" or "points".
            lights: lighting and material; None is a headlight with the default material.
            background: RGB in [0, 1].
            options: :class:`~surfsplat.rendering.options.RenderOptions` (None: the defaults).
            supersample: K in 1..16: K x K sub-pixels per pixel, averaged.
        """
        if isinstance(camera, Camera):
            width, height = camera.width, camera.height
        check_render_args(technique=technique, width=width, height=height, background=background, options=options,
                          supersample=supersample, lights=lights)
        background, options = check_background(background), options or RenderOptions()
        camera = self.camera(camera, width, height)
        drawn = self.sample(camera, facing=self._facing_first(camera, options, technique))
        options = replace(options, visibility=replace(options.visibility,
                                                      cull_backfaces=self.culls(camera, options, technique)))
        strategy = self.strategy(camera)
        start = time.perf_counter()
        merged_from = None
        if strategy == "gpu":
            return self._render_gpu(camera, technique, lights, background, options, supersample)
        selection = None
        if strategy == "cpu":
            cloud, selection = self.tree(camera).cut(camera, cut_tolerance(self.lod, supersample),
                                                     cull_backfaces=bool(options.visibility.cull_backfaces),
                                                     shading=self.lod.shading, point_budget=self.lod.point_budget)
            tree = self.tree(camera)
        else:
            cloud, tree = drawn.points(), drawn
            if self.lod.tolerance == LOD_AUTO and not self.hybrid:   # hybrid points are picked from the cloud's rows
                merged = auto_merged(cloud, local_camera(cloud, camera), supersample)
                merged_from, cloud = (len(cloud) if merged is not cloud else None), merged
        if len(cloud) == 0:
            frame = Frame.empty(camera, background)
        else:
            if self.hybrid:
                cloud = hybrid_splats(tree, cloud, selection, local_camera(cloud, camera))
            frame = default_renderer().render(cloud, camera, technique, lights or Lights(), options, background,
                                              supersample=supersample,   # world camera: the renderer handles the origin
                                              cloud_key=self._drawn_key(cloud))
        result = RenderResult(frame, len(cloud), selection, time.perf_counter() - start, merged_from)
        check_coverage(frame, self.model)
        return result

    def _drawn_key(self, cloud) -> tuple | None:
        """The renderer's content key of ``cloud`` where :attr:`source_key` gives it: ``source`` itself, or
        the splats this view made of it (:meth:`sample`: what ``source`` and the source options determine)."""
        if self.source_key is None:
            return None
        if cloud is self._source:
            return self.source_key
        if self._drawn is not None and cloud is self._drawn.points():
            return ("drawn", self.source_options, None if self._facing is None else self._facing[0]) + self.source_key
        return None

    def _render_gpu(self, camera, technique, lights, background, options, supersample) -> RenderResult:
        """:meth:`render` with the cut chosen per entry by the vertex shader (sequential point trees,
        Dachsbacher 2003; :mod:`surfsplat.rendering.sequential`), the layout made once."""
        start = time.perf_counter()
        if self._layout is None:
            self._layout = sequential_layout(self.tree(camera).data, self.lod.shading)
        tolerance = cut_tolerance(self.lod, supersample)
        frame, given = render_sequential(default_renderer(), self._layout.splats, self._layout.lod, camera, technique,
                                         lights or Lights(), options, background, tolerance, supersample)
        result = RenderResult(frame, given, None, time.perf_counter() - start, gpu_lod_tolerance=float(tolerance))
        check_coverage(frame, self.model)
        return result

    def orbit(self, camera: Camera | CameraSpec | None = None, frames: int = 72, degrees: float = 360.0,
              elevation: float | None = None, *, width: int = defaults.API_IMAGE_SIZE,
              height: int = defaults.API_IMAGE_SIZE) -> list[Camera]:
        """The cameras of a turntable: ``frames`` views ``degrees / frames`` apart about the data's up
        axis (:func:`surfsplat.camera_path.orbit_cameras`), starting from ``camera`` (:meth:`camera`).
        An automatic camera (None, or a CameraSpec without an eye) frames the whole orbit: the target
        at the center of the model's bounds and the eye at the distance where every frame shows every
        splat (so a scan cannot leave the picture in the back views); a placed eye keeps its distance."""
        start = self.camera(camera, width, height)
        placed = isinstance(camera, Camera) or (camera is not None and camera.eye is not None)
        if placed:
            return orbit_cameras(start, frames, degrees, elevation)
        splats = self.sample(start).points()
        margin = float(splats.radii.max()) if splats.u is not None and len(splats) else 0.0
        return orbit_cameras(start, frames, degrees, elevation, points=splats.positions.astype(np.float64)
                             + splats.origin, margin=margin)

    def frames(self, cameras: list[Camera], **render_args):
        """Yield the (H, W, 3) uint8 image of each camera (:meth:`render`'s other arguments), with
        progress per frame (:func:`surfsplat.progress.stage`)."""
        if not cameras:
            return
        with progress.stage(f"rendering {len(cameras)} frames", unit="frames", total=len(cameras)) as done:
            for camera in cameras:
                result = self.render(camera, **render_args)
                done.update()
                yield result.frame.image()


def bounds_pixels(camera: Camera, lo, hi) -> float:
    """Pixels of the image the box [lo, hi] (model units) projects to: the area of its projected
    corners' bounding rectangle clipped to the image; the whole image when the eye is inside or
    beside the box (a corner at or behind the eye); 0 when the box lies behind the eye."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])],
                       dtype=np.float64)
    view = camera.view_matrix
    p = corners @ view[:3, :3].T + view[:3, 3]
    depth = -p[:, 2]
    if (depth <= 0).all():
        return 0.0
    if (depth <= 0).any():
        return float(camera.width * camera.height)
    xy = p[:, :2] / depth[:, None] * camera.focal_px
    x0, y0 = np.clip(xy.min(axis=0) + (camera.width / 2, camera.height / 2), 0, (camera.width, camera.height))
    x1, y1 = np.clip(xy.max(axis=0) + (camera.width / 2, camera.height / 2), 0, (camera.width, camera.height))
    return float((x1 - x0) * (y1 - y0))


def check_coverage(frame: Frame, model, what: str = "the model") -> None:
    """Warn (:class:`~surfsplat.errors.EmptyFrameWarning`) when ``frame`` shows nothing, or less
    than :data:`MIN_COVERAGE` of the pixels the model's bounds project to; the message names the
    bounds and the camera (as flags)."""
    lo, hi = as_model(model).bounds()
    expected = bounds_pixels(frame.camera, lo, hi)
    drawn = int(frame.mask.sum())
    if drawn > 0 and drawn >= MIN_COVERAGE * expected:
        return
    where = (f"{what}'s bounds are min {np.array2string(np.asarray(lo), precision=4)} max "
             f"{np.array2string(np.asarray(hi), precision=4)}; the camera is {camera_flags(frame.camera)}")
    if drawn == 0:
        warnings.warn(f"nothing was drawn: {where}", EmptyFrameWarning, stacklevel=3)
    else:
        warnings.warn(f"only {drawn:,} pixels were drawn, {100 * drawn / expected:.2g}% of the {expected:,.0f} "
                      f"its bounds cover in the image: {where}", EmptyFrameWarning, stacklevel=3)
