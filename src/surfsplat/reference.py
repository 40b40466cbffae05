"""NumPy reference of every per-splat formula the shaders evaluate.

Vectorized over splats (leading axis N) and pixels. Tests hold the GPU's
output against these functions; the GLSL in ``render/glsl`` mirrors them
line by line. Units: camera space in model units (camera looks down -z),
window coordinates in pixels with y up and pixel centers at half-integers.
"""

from __future__ import annotations

import numpy as np

from .camera import Camera
from .lighting import Lights


def to_camera(camera: Camera, points: np.ndarray) -> np.ndarray:
    """(N, 3) world points -> (N, 3) camera-space points."""
    m = camera.view_matrix
    return np.asarray(points, dtype=np.float64) @ m[:3, :3].T + m[:3, 3]


def to_camera_dir(camera: Camera, vectors: np.ndarray) -> np.ndarray:
    """(N, 3) world vectors (normals, tangent axes) -> camera space (no translation)."""
    return np.asarray(vectors, dtype=np.float64) @ camera.view_matrix[:3, :3].T


def project(camera: Camera, p_cam: np.ndarray) -> np.ndarray:
    """(N, 3) camera-space points -> (N, 2) window pixel coordinates (x right, y up)."""
    cx, cy = camera.principal_point
    z = -p_cam[..., 2]
    return np.stack([cx + camera.focal_px * p_cam[..., 0] / z, cy + camera.focal_px * p_cam[..., 1] / z], axis=-1)


def pixel_rays(camera: Camera, pixels: np.ndarray) -> np.ndarray:
    """(..., 2) window pixel coordinates -> (..., 3) camera-space ray directions with z = -1."""
    cx, cy = camera.principal_point
    f = camera.focal_px
    return np.stack([(pixels[..., 0] - cx) / f, (pixels[..., 1] - cy) / f, -np.ones(pixels.shape[:-1])], axis=-1)


def pixel_centers(camera: Camera) -> np.ndarray:
    """(H, W, 2) window coordinates of the pixel centers, row 0 at the top of the image."""
    x = np.arange(camera.width) + 0.5
    y = camera.height - (np.arange(camera.height) + 0.5)
    return np.stack(np.meshgrid(x, y), axis=-1)


def ewa_jacobian(camera: Camera, p_cam: np.ndarray, u_cam: np.ndarray, v_cam: np.ndarray) -> np.ndarray:
    """(N, 2, 2) Jacobian of the projection at the splat center w.r.t. normalized (s, t).

    Columns are d(pixel)/ds and d(pixel)/dt for the point ``p + s u + t v``.
    Guennebaud 2003, eq. 8 (with eta = focal / z), in window pixels, y up.
    """
    f = camera.focal_px
    z = -p_cam[:, 2:3]
    # d/ds [f X / z] with dz/ds = -u_z
    du = f * (u_cam[:, :2] * z + p_cam[:, :2] * u_cam[:, 2:3]) / z**2
    dv = f * (v_cam[:, :2] * z + p_cam[:, :2] * v_cam[:, 2:3]) / z**2
    return np.stack([du, dv], axis=-1)


def ewa_variance(jacobian: np.ndarray, cutoff: float = 1.0, prefilter: bool = True) -> np.ndarray:
    """(N, 2, 2) screen-space resampling variance ``J V_r J^T + H`` in pixels^2.

    Guennebaud 2003, eq. 6. The reconstruction variance in normalized splat
    coordinates is ``V_r = I / (2 c)`` so that the splat's ellipse
    (s^2 + t^2 = 1) is the cutoff isocontour ``0.5 x^T V_r^-1 x = c``.
    ``H = I`` (one pixel) with the prefilter, a tiny regularizer without it.
    """
    v = jacobian @ np.swapaxes(jacobian, 1, 2) / (2.0 * cutoff)
    h = 1.0 if prefilter else 1e-4
    return v + h * np.eye(2)


def ewa_half_extent(variance: np.ndarray, cutoff: float = 1.0) -> np.ndarray:
    """(N, 2) half-width and half-height in pixels of the tight box of ``0.5 x^T V^-1 x <= c``."""
    return np.sqrt(2.0 * cutoff * np.stack([variance[:, 0, 0], variance[:, 1, 1]], axis=-1))


def ewa_weight(variance: np.ndarray, jacobian: np.ndarray, offset: np.ndarray, cutoff: float = 1.0) -> np.ndarray:
    """EWA resampling weight at pixel offsets from the projected center (0 beyond the cutoff).

    ``variance``, ``jacobian``: (N, 2, 2); ``offset``: (N, ..., 2) pixels.
    Guennebaud 2003, eq. 6: ``|J| G_V(x)``, scaled by ``pi / c`` so that a
    magnified splat has peak weight 1 (a constant factor, removed by the
    per-pixel normalization of eq. 18).
    """
    inv = np.linalg.inv(variance)
    extra = offset.ndim - 2
    inv = inv.reshape(inv.shape[:1] + (1,) * extra + (2, 2))
    beta = 0.5 * np.einsum("...i,...ij,...j->...", offset, inv, offset)
    scale = np.abs(np.linalg.det(jacobian)) / (2.0 * cutoff * np.sqrt(np.linalg.det(variance)))
    w = scale.reshape(scale.shape + (1,) * extra) * np.exp(-beta)
    return np.where(beta <= cutoff, w, 0.0)


def ray_plane_distance(rays: np.ndarray, p_cam: np.ndarray, n_cam: np.ndarray) -> np.ndarray:
    """Ray parameter t where ``t * ray`` meets the plane through p with normal n.

    Rays have z = -1, so t is also the camera-space depth (distance along -z).
    Guennebaud 2003, eq. 10/13. ``rays``: (N, ..., 3); ``p_cam``, ``n_cam``: (N, 3).
    """
    extra = rays.ndim - 2
    p = p_cam.reshape(p_cam.shape[:1] + (1,) * extra + (3,))
    n = n_cam.reshape(n_cam.shape[:1] + (1,) * extra + (3,))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sum(n * p, axis=-1) / np.sum(n * rays, axis=-1)


def splat_coordinates(rays: np.ndarray, t: np.ndarray, p_cam: np.ndarray, u_cam: np.ndarray,
                      v_cam: np.ndarray) -> np.ndarray:
    """Normalized (s, t) coordinates of the ray/plane hit points ``t * ray`` (u and v orthogonal)."""
    extra = rays.ndim - 2
    shape = p_cam.shape[:1] + (1,) * extra + (3,)
    q = t[..., None] * rays - p_cam.reshape(shape)
    u, v = u_cam.reshape(shape), v_cam.reshape(shape)
    return np.stack([np.sum(q * u, -1) / np.sum(u * u, -1), np.sum(q * v, -1) / np.sum(v * v, -1)], axis=-1)


def window_depth(z: np.ndarray, near: float, far: float) -> np.ndarray:
    """Camera-space depth (model units) -> stored depth in [0, 1], linear between near and far.

    All our shaders write gl_FragDepth themselves, so a linear mapping keeps a
    uniform precision over the whole range instead of OpenGL's 1/z mapping.
    """
    return (np.asarray(z) - near) / (far - near)


def facing_normals(n_cam: np.ndarray, p_cam: np.ndarray) -> np.ndarray:
    """Flip camera-space normals that face away from the eye (two-sided lighting)."""
    flip = np.sum(n_cam * p_cam, axis=-1, keepdims=True) > 0
    return np.where(flip, -n_cam, n_cam)


def shade(albedo: np.ndarray, n: np.ndarray, view: np.ndarray, light_dirs: np.ndarray, lights: Lights) -> np.ndarray:
    """Blinn-Phong color (not clamped) for unit normals ``n`` and unit ``view`` (toward the eye).

    ``albedo``, ``n``, ``view``: (..., 3); ``light_dirs``: (L, 3) unit, same space as ``n``.
    ``c = albedo (ka + kd sum max(0, n.l)) + ks sum max(0, n.h)^s``; normals facing away
    from ``view`` are flipped.
    """
    if not lights.enabled:
        return np.asarray(albedo, dtype=np.float64)
    n = np.where(np.sum(n * view, axis=-1, keepdims=True) < 0, -n, n)
    diffuse = np.zeros(n.shape[:-1])
    specular = np.zeros(n.shape[:-1])
    for l in np.asarray(light_dirs, dtype=np.float64):  # at most 4 lights, not per point
        diffuse += np.maximum(0.0, n @ l)
        h = view + l
        h /= np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-30)
        specular += np.maximum(0.0, np.sum(n * h, axis=-1)) ** lights.shininess
    return albedo * (lights.ambient + lights.diffuse * diffuse[..., None]) + lights.specular * specular[..., None]
