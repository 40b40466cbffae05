"""Cameras of a view: the automatic framing, camera specs resolved against a model, and the one
place where near/far are set from a model's bounds and a world camera is moved into the frame of
the splats it draws (:func:`local_camera`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import defaults
from ..camera import MIN_FOV, Camera, direction_vector, fit_points, rotate
from ..cloud import SplatCloud
from ..errors import InputError
from ..viewpoint import choose_direction
from .models import Model, as_model

#: Default viewing direction (toward the eye) for a y-up world: front, a little right and above.
DEFAULT_DIRECTION = (0.4, 0.35, 1.0)

#: Points used to fit the automatic view (a regular subsample of larger clouds).
FIT_SAMPLE = 200_000
#: A model whose extent along up is below this fraction of its horizontal extent (terrain, an
#: aerial survey) is looked at from about 45 degrees above instead of from the front.
FLAT_MODEL_RATIO = 0.2


def default_direction(cloud: SplatCloud, up) -> np.ndarray:
    """The automatic viewing direction (toward the eye): front, a little right and above relative to
    ``up``, unless that view looks at one face of the model head-on and another shows clearly more
    (:func:`surfsplat.viewpoint.choose_direction`: viewpoint entropy); flat models
    (:data:`FLAT_MODEL_RATIO`: terrain, whose ground is one face by nature) from about 45 degrees above."""
    up = direction_vector(up, "up")
    up = up / np.linalg.norm(up)
    lo, hi = cloud.bounds()
    extent = np.asarray(hi, dtype=np.float64) - lo
    along = abs(float(extent @ up))
    across = float(np.linalg.norm(extent - (extent @ up) * up))
    x, y, z = DEFAULT_DIRECTION
    flat = along < FLAT_MODEL_RATIO * across
    if flat:
        y = 1.2   # about 45 degrees above the horizon
    # the y-up direction turned so +y goes to up: about y x up, or half a turn about x for -y
    direction = np.array([x, y, z])
    axis = np.cross([0.0, 1.0, 0.0], up)
    if np.linalg.norm(axis) < 1e-12:
        direction = direction if up[1] > 0 else rotate(direction, np.array([1.0, 0.0, 0.0]), 180.0)
    else:
        angle = np.degrees(np.arctan2(np.linalg.norm(axis), up[1]))
        direction = rotate(direction, axis / np.linalg.norm(axis), angle)
    return direction if flat else choose_direction(cloud, up, direction).direction


def auto_camera(cloud: SplatCloud, width: int = defaults.API_IMAGE_SIZE, height: int = defaults.API_IMAGE_SIZE,
                fov: float = defaults.FOV,
                direction=None, up=(0.0, 1.0, 0.0)) -> Camera:
    """A camera framing the whole cloud from ``direction`` (world, toward the eye).

    The splat centers' projections (grown by the 99th percentile splat radius) fill 90% of the
    image's limiting side, centered (:func:`surfsplat.camera.fit_points`); near/far enclose the
    splats. Without a direction: :func:`default_direction` (so ``up=(0, 0, 1)`` suits z-up
    data such as LiDAR).
    """
    points, direction, up, margin = auto_fit_inputs(cloud, up, direction)
    camera = fit_points(points, direction=direction, up=up, fov=fov, width=width, height=height, margin=margin)
    return clipped_to(replace(camera, near=None, far=None), cloud)   # near/far from every splat, not the subsample


def auto_fit_inputs(cloud: SplatCloud, up=(0.0, 1.0, 0.0), direction=None) -> tuple[np.ndarray, np.ndarray,
                                                                                      np.ndarray, float]:
    """What :func:`auto_camera` fits for any image size: the points (float64 world positions, a regular
    subsample of :data:`FIT_SAMPLE` of larger clouds), the direction toward the eye
    (:func:`default_direction` where None), the up vector and the margin (the 99th percentile splat
    radius, model units). The browser viewer exports these to frame its page as ``surfsplat render`` does."""
    up = direction_vector(up, "up")
    if not np.abs(up).max() > 0:
        raise InputError(f"up must be a finite non-zero vector, got {tuple(up)!r}")
    if direction is None:
        direction = default_direction(cloud, up)
    step = max(1, len(cloud) // FIT_SAMPLE)
    margin = float(np.percentile(cloud.radii, 99)) if cloud.u is not None else 0.0
    # world positions in float64: the camera is composed where the data sit, whatever their offset
    return cloud.positions[::step].astype(np.float64) + cloud.origin, np.asarray(direction, np.float64), up, margin


@dataclass(frozen=True)
class CameraSpec:
    """A camera described before the model is known; :meth:`camera_for` resolves it.

    Attributes:
        eye: camera position (world units), or None to frame the model automatically
            (:func:`auto_camera`).
        target: point looked at (world units); None: the model's bounding-box center.
            Needs ``eye``.
        up: world up vector (also the axis the viewer orbits about); None: the data's own
            (:func:`natural_up` of the source: +z for LAS/LAZ, else +y).
        fov: vertical field of view, degrees, in (0, 180).
    """

    eye: tuple[float, float, float] | None = None
    target: tuple[float, float, float] | None = None
    up: tuple[float, float, float] | None = None
    fov: float = defaults.FOV

    def __post_init__(self) -> None:
        if self.target is not None and self.eye is None:
            raise InputError("--target needs --eye (without camera flags the model is framed automatically)")
        if not (MIN_FOV <= float(self.fov) < 180.0):
            raise InputError(f"--fov must be in [{MIN_FOV:g}, 180) degrees, got {self.fov:g}")

    def camera_for(self, cloud: SplatCloud, width: int, height: int, default_up=(0.0, 1.0, 0.0)) -> Camera:
        """The camera for a model whose splats (or points) are ``cloud``, at ``width`` x ``height`` pixels;
        near/far enclose the model. ``default_up`` stands in for ``up`` None."""
        up = tuple(self.up) if self.up is not None else tuple(default_up)
        if self.eye is None:
            return auto_camera(cloud, width, height, self.fov, up=up)
        lo, hi = cloud.bounds()
        target = self.target if self.target is not None else 0.5 * (lo + hi)
        if self.up is None:
            up = up_across(np.asarray(target, dtype=np.float64) - np.asarray(self.eye, dtype=np.float64), up)
        return clipped_to(Camera(eye=tuple(self.eye), target=tuple(target), up=up, fov=self.fov, width=width,
                                 height=height), cloud)


def up_across(view, up) -> tuple[float, float, float]:
    """``up``, or where the ``view`` direction runs along it (within about 1 degree: a data's up,
    stored or guessed, that the caller's camera looks along) the other common up axis (+y for +z,
    else +z), so that a placed camera without an up is always valid."""
    view = np.asarray(view, dtype=np.float64)
    u = np.asarray(direction_vector(up, "up"), dtype=np.float64)
    length = float(np.linalg.norm(view))
    if length == 0 or abs(float(view @ u)) < 0.9998 * length * float(np.linalg.norm(u)):
        return tuple(up)
    return (0.0, 1.0, 0.0) if abs(u[2]) > max(abs(u[0]), abs(u[1])) else (0.0, 0.0, 1.0)


def resolve_camera(model: Model, camera: Camera | CameraSpec | None, width: int, height: int, *,
                   default_up=(0.0, 1.0, 0.0)) -> Camera:
    """A Camera as it is; a CameraSpec (None: automatic framing) resolved against the model at
    ``width`` x ``height`` pixels, with ``default_up`` (see :func:`natural_up`) where it has no up."""
    if isinstance(camera, Camera):
        return camera
    return (camera or CameraSpec()).camera_for(as_model(model).points(), width, height, default_up)


def local_camera(splats: SplatCloud, camera: Camera) -> Camera:
    """The world ``camera`` in the local frame of ``splats`` (what the renderer draws them with):
    near/far set from their world bounds where None (grown by the largest splat radius), then eye
    and target moved by ``-splats.origin`` in float64. The GPU then only sees coordinates of the
    size of the model, wherever it sits (positions relative to a float64 origin, see
    :class:`~surfsplat.cloud.SplatCloud`)."""
    return clipped_to(camera, splats).translated(-splats.origin)


def clipped_to(camera: Camera, splats: SplatCloud) -> Camera:
    """``camera`` (world) with near/far, where None, enclosing the world bounds of ``splats`` grown by
    their largest radius (model units): the one rule every view's clip planes follow."""
    if camera.near is not None and camera.far is not None:
        return camera
    margin = float(splats.radii.max()) if splats.u is not None and len(splats) else 0.0
    return camera.with_clip_from_bounds(*splats.bounds(), margin=margin)
