"""Pinhole camera: OpenGL look-at, vertical field of view, pixel grid.

Conventions (DESIGN.md): right-handed world, camera looks down its -z axis;
pixel centers at half-integers; window coordinates have y up with the
principal point at the image center; saved images have row 0 at the top.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .errors import InputError


def _vec3(value, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.isfinite(arr).all():
        raise InputError(f"{name} must be 3 finite numbers, got {value!r}")
    return arr


@dataclass(frozen=True)
class Camera:
    """A perspective camera.

    Attributes:
        eye, target, up: world-space look-at vectors (model units).
        fov: vertical field of view in degrees, in (0, 180).
        width, height: image size in pixels.
        near, far: clip distances along the view axis, model units; None means
            "set from the model's bounds" when rendering (see ``with_clip_from_bounds``).
    """

    eye: tuple = (0.0, 0.0, 3.0)
    target: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 40.0
    width: int = 512
    height: int = 512
    near: float | None = None
    far: float | None = None

    def __post_init__(self) -> None:
        eye, target, up = _vec3(self.eye, "eye"), _vec3(self.target, "target"), _vec3(self.up, "up")
        if np.linalg.norm(eye - target) <= 0:
            raise InputError("camera eye and target must differ")
        forward = (target - eye) / np.linalg.norm(target - eye)
        if np.linalg.norm(np.cross(forward, up)) < 1e-9 * max(np.linalg.norm(up), 1e-30):
            raise InputError("camera up vector must not be parallel to the viewing direction (or zero)")
        if not (0.0 < float(self.fov) < 180.0):
            raise InputError(f"field of view must be in (0, 180) degrees, got {self.fov}")
        if int(self.width) < 1 or int(self.height) < 1 or int(self.width) > 16384 or int(self.height) > 16384:
            raise InputError(f"image size must be within 1..16384 pixels, got {self.width}x{self.height}")
        if self.near is not None and self.far is not None and not (0 < self.near < self.far):
            raise InputError(f"need 0 < near < far, got near={self.near}, far={self.far}")
        object.__setattr__(self, "eye", tuple(eye))
        object.__setattr__(self, "target", tuple(target))
        object.__setattr__(self, "up", tuple(up))
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))

    # -- derived matrices ---------------------------------------------------

    @property
    def view_matrix(self) -> np.ndarray:
        """4x4 float64 world-to-camera matrix (gluLookAt)."""
        eye, target, up = (np.asarray(x) for x in (self.eye, self.target, self.up))
        f = target - eye
        f /= np.linalg.norm(f)
        s = np.cross(f, up)
        s /= np.linalg.norm(s)
        u = np.cross(s, f)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = s, u, -f
        m[:3, 3] = -m[:3, :3] @ eye
        return m

    @property
    def focal_px(self) -> float:
        """Focal length in pixels: (height / 2) / tan(fov / 2)."""
        return 0.5 * self.height / np.tan(np.radians(self.fov) / 2.0)

    @property
    def principal_point(self) -> tuple[float, float]:
        """Image center in window pixels (x right, y up)."""
        return 0.5 * self.width, 0.5 * self.height

    @property
    def light_direction(self) -> np.ndarray:
        """Unit world direction from the target toward the eye (the default headlight)."""
        d = np.asarray(self.eye) - np.asarray(self.target)
        return d / np.linalg.norm(d)

    def resized(self, width: int, height: int) -> "Camera":
        """The same camera with another image size."""
        return replace(self, width=width, height=height)

    def with_clip_from_bounds(self, lo: np.ndarray, hi: np.ndarray, margin: float = 0.0) -> "Camera":
        """Set near/far (where None) so the box [lo, hi], grown by ``margin``, lies between them.

        Near is at least 1e-4 of the box's diagonal so depth keeps its precision
        even with the eye inside the model.
        """
        lo = np.asarray(lo, dtype=np.float64) - margin
        hi = np.asarray(hi, dtype=np.float64) + margin
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        depth = -(self.view_matrix[:3, :3] @ corners.T + self.view_matrix[:3, 3:4])[2]
        diag = float(np.linalg.norm(hi - lo)) or 1.0
        far = self.far if self.far is not None else max(float(depth.max()) * 1.01, diag * 1e-3)
        near = self.near if self.near is not None else max(float(depth.min()) * 0.99, far * 1e-4, diag * 1e-4)
        near = min(near, far * 0.5)
        return replace(self, near=near, far=far)


def frame_bounds(lo, hi, *, width: int = 512, height: int = 512, fov: float = 40.0,
                 direction=(0.4, 0.35, 1.0), up=(0.0, 1.0, 0.0), fill: float = 0.9,
                 margin: float = 0.0, radius: float | None = None) -> Camera:
    """A camera that frames the box [lo, hi] (model units) from ``direction``.

    The eye looks at the box center from ``direction`` (world, toward the eye)
    at the distance where a sphere around the center fills ``fill`` of the
    smaller field of view; the sphere's ``radius`` defaults to the box's half
    diagonal (pass the points' largest distance to the center for a tighter
    view). near/far enclose the box (grown by ``margin``).
    """
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    center = 0.5 * (lo + hi)
    if radius is None or not radius > 0:
        radius = 0.5 * float(np.linalg.norm(hi - lo)) or 1.0
    d = _vec3(direction, "direction")
    d /= np.linalg.norm(d)
    half_v = np.radians(fov) / 2.0
    half_h = np.arctan(np.tan(half_v) * width / height)
    half = min(half_v, half_h)
    dist = radius / np.sin(half) / fill
    if np.linalg.norm(np.cross(d, up)) < 1e-6:
        up = (0.0, 0.0, 1.0) if abs(d[2]) < 0.9 else (0.0, 1.0, 0.0)
    cam = Camera(eye=tuple(center + dist * d), target=tuple(center), up=tuple(up), fov=fov, width=width, height=height)
    return cam.with_clip_from_bounds(lo, hi, margin)
