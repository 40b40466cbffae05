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
        raise InputError(f"{name} must be 3 finite numbers, got {value!r}", argument=name)
    return arr


def direction_vector(value, name: str) -> np.ndarray:
    """``value`` as 3 finite float64 numbers (InputError else) giving a direction: one whose largest
    component lies beyond 2^+-64 is multiplied by a power of two (exact, the same direction) to about
    1, so that its norm and cross products stay finite (an ``--up 1e308 -1 -1`` would overflow)."""
    arr = _vec3(value, name)
    largest = float(np.abs(arr).max())
    if largest > 2.0 ** 64 or 0.0 < largest < 2.0 ** -64:
        arr = arr * 2.0 ** -np.round(np.log2(largest))
    return arr


#: Smallest vertical field of view, degrees (a telephoto of 0.001 degrees still keeps the focal
#: length, in pixels, far inside float32).
MIN_FOV = 1e-3
#: Largest image side, pixels: rendered in tiles (``render/tiles.py``); the frame's arrays take
#: about 24 bytes a pixel in memory (a 32768 x 32768 frame: 26 GB).
MAX_IMAGE_SIDE = 32768


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
        eye, target, up = _vec3(self.eye, "eye"), _vec3(self.target, "target"), direction_vector(self.up, "up")
        if np.linalg.norm(eye - target) <= 0:
            raise InputError("camera eye and target must differ", argument="target")
        forward = (target - eye) / np.linalg.norm(target - eye)
        if np.linalg.norm(np.cross(forward, up)) < 1e-9 * max(float(np.linalg.norm(up)), 1e-30):
            raise InputError("camera up vector must not be parallel to the viewing direction (or zero)", argument="up")
        if not (MIN_FOV <= float(self.fov) < 180.0):
            raise InputError(f"field of view must be in [{MIN_FOV:g}, 180) degrees, got {self.fov}", argument="fov")
        if not (1 <= int(self.width) <= MAX_IMAGE_SIDE and 1 <= int(self.height) <= MAX_IMAGE_SIDE):
            raise InputError(f"image size must be within 1..{MAX_IMAGE_SIDE} pixels, got {self.width}x{self.height}",
                             argument="width" if not 1 <= int(self.width) <= MAX_IMAGE_SIDE else "height")
        if self.near is not None and self.far is not None and not (0 < self.near < self.far):
            raise InputError(f"need 0 < near < far, got near={self.near}, far={self.far}",
                             argument="near" if not 0 < self.near else "far")
        object.__setattr__(self, "eye", tuple(map(float, eye)))
        object.__setattr__(self, "target", tuple(map(float, target)))
        object.__setattr__(self, "up", tuple(map(float, up)))
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

    def translated(self, offset) -> "Camera":
        """The same view with eye and target moved by ``offset`` (3 numbers, model units), in float64.

        ``camera.translated(-origin)`` is the camera in the local frame of a cloud whose world
        coordinates are ``origin + positions``: the image, near/far and depth are unchanged, and
        the renderer composes its float32 transform from small numbers only.
        """
        d = _vec3(offset, "offset")
        if not d.any():
            return self
        eye, target = np.asarray(self.eye) + d, np.asarray(self.target) + d
        return replace(self, eye=tuple(eye), target=tuple(target))

    def scaled(self, factor: float) -> "Camera":
        """The same view of a model scaled by ``factor`` (> 0) about the origin: eye, target, near
        and far times ``factor`` (a power of two keeps every float32 computed from it exact)."""
        if not (np.isfinite(factor) and factor > 0):
            raise InputError(f"camera scale factor must be a positive number, got {factor!r}", argument="factor")
        if factor == 1.0:
            return self
        scale = lambda x: None if x is None else float(x) * factor  # noqa: E731
        return replace(self, eye=tuple(np.asarray(self.eye) * factor), target=tuple(np.asarray(self.target) * factor),
                       near=scale(self.near), far=scale(self.far))

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


def rotate(v: np.ndarray, axis: np.ndarray, angle_deg: float) -> np.ndarray:
    """``v`` rotated by ``angle_deg`` degrees about the unit ``axis`` (right-handed; Rodrigues)."""
    a = np.radians(angle_deg)
    return v * np.cos(a) + np.cross(axis, v) * np.sin(a) + axis * (axis @ v) * (1.0 - np.cos(a))


def fit_basis(direction, up) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The view basis :func:`fit_points` frames in: ``(direction, up, right, screen_up)``, float64 world
    vectors; ``direction`` (toward the eye) and ``right`` and ``screen_up`` unit, ``up`` as given or, where
    the direction runs along it, replaced by +z (or +y for a direction near z)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    up = direction_vector(up, "up")
    if np.linalg.norm(np.cross(d, up)) < 1e-6 * np.linalg.norm(up):
        up = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    right = np.cross(-d, up)
    right /= np.linalg.norm(right)
    return d, up, right, np.cross(right, -d)


def fit_points(points, *, direction, up=(0.0, 1.0, 0.0), fov: float = 40.0, width: int = 512, height: int = 512,
               fill: float = 0.9, margin: float = 0.0) -> Camera:
    """A camera looking along ``-direction`` whose image the points' projections fill tightly.

    For a fixed viewing direction, the eye distance D and the target's offset (cx, cy) across
    the view are chosen so every point (grown by ``margin``, model units) projects inside
    ``fill`` of the image's half-extent on both axes, with the projected extremes centered:
    a point at lateral offset x and depth z toward the eye needs |x - cx| + margin <=
    t (D - z), t = fill * tan(half field of view); D is the smallest distance satisfying all
    of them (a closed form: the two extremes on each axis balance). The image's limiting
    side is then filled to ``fill`` (0.9: 90%). near/far enclose the points.

    Args:
        points: (N, 3) world positions (model units), N >= 1.
        direction: world vector from the model toward the eye.
        up: world up vector. fov: vertical field of view, degrees. width, height: pixels.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    d, up, right, screen_up = fit_basis(_vec3(direction, "direction"), up)
    lo, hi = p.min(axis=0), p.max(axis=0)
    center = 0.5 * (lo + hi)
    q = p - center
    x, y, z = q @ right, q @ screen_up, q @ d
    half_v = np.radians(fov) / 2.0
    ty = fill * np.tan(half_v)
    tx = fill * np.tan(half_v) * width / height
    offsets, distances = [], []
    for lateral, t in ((x, tx), (y, ty)):
        a = float(np.max(z + (lateral + margin) / t))   # the extreme on the + side sets D >= a - c / t
        b = float(np.max(z + (margin - lateral) / t))   # the - side: D >= b + c / t
        offsets.append(0.5 * t * (a - b))
        distances.append(0.5 * (a + b))
    extent = float(np.linalg.norm(hi - lo)) or 1.0
    dist = max(max(distances), float(z.max()) + margin + 1e-3 * extent)
    for axis, lateral in enumerate((x, y)):
        if distances[axis] < dist:   # not the limiting side: center its projected extremes at this distance
            offsets[axis] = centering_offset(lateral, dist - z, margin)
    target = center + offsets[0] * right + offsets[1] * screen_up
    cam = Camera(eye=tuple(target + dist * d), target=tuple(target), up=tuple(up), fov=fov, width=width,
                 height=height)
    return cam.with_clip_from_bounds(lo, hi, margin)


def centering_offset(lateral: np.ndarray, depth: np.ndarray, margin: float) -> float:
    """The offset c with max((x + m - c) / d) = -min((x - m - c) / d): projected extremes symmetric
    about the image center (bisection; the difference decreases monotonically in c). ``lateral``: the
    points' screen-axis coordinates, ``depth``: their distances along the view, ``margin``: model units;
    returns c in model units (used by :func:`fit_points` and the web page's fit)."""
    lo, hi = float(lateral.min()) - margin, float(lateral.max()) + margin
    for _ in range(60):
        c = 0.5 * (lo + hi)
        if np.max((lateral + margin - c) / depth) + np.min((lateral - margin - c) / depth) > 0:
            lo = c
        else:
            hi = c
    return 0.5 * (lo + hi)


def camera_flags(camera: Camera) -> str:
    """The command-line flags that reproduce ``camera``: ``--eye X Y Z --target X Y Z --up X Y Z
    --fov F --width W --height H`` (10 significant digits: georeferenced coordinates keep their cm)."""
    def vec(v) -> str:
        # positional, never an exponent: argparse takes "-1e-05" for an option, "-0.00001" for a number
        return " ".join(np.format_float_positional(float(x), precision=10, unique=True, fractional=False, trim="-")
                        for x in v)

    return (f"--eye {vec(camera.eye)} --target {vec(camera.target)} --up {vec(camera.up)} "
            f"--fov {np.format_float_positional(float(camera.fov), precision=10, fractional=False, trim='-')} "
            f"--width {camera.width} --height {camera.height}")
