"""NumPy reference of every per-splat formula the shaders evaluate.

Vectorized over splats (leading axis N) and pixels. Tests hold the GPU's
output against these functions; the GLSL in ``rendering/glsl`` mirrors them
line by line. Units: camera space in model units (camera looks down -z),
window coordinates in pixels with y up and pixel centers at half-integers.

The formulas of the ``ewa`` technique and of the lighting are written against the array namespace
(:mod:`surfsplat.arrays`): given PyTorch tensors they run on PyTorch, which is how the differentiable
renderer (:mod:`surfsplat.diff`) evaluates them, so the two cannot drift apart. Their ``camera``-free
forms (``transform_points``, ``project_points``, ``jacobian``, ...) take the focal length and the
principal point as numbers or tensors; the forms taking a :class:`Camera` are NumPy.
"""

from __future__ import annotations

from contextlib import nullcontext
from typing import Any

import numpy as np

from .arrays import array_namespace, as_float, det2, dot, inv2, matrix2, norm, unstack
from .arrays import cross as _cross
from .camera import Camera
from .lighting import Lights
# the edge-coverage formulas, re-exported: reference.disk_coverage, reference.edge_alpha, ...
from .reference_edges import (
    COVER_SHARPNESS as COVER_SHARPNESS,
    DISTANCE_SHARPNESS as DISTANCE_SHARPNESS,
    COVER_REACH as COVER_REACH,
    RIM_SQUEEZE as RIM_SQUEEZE,
    RIM_SQUEEZE_FALLOFF as RIM_SQUEEZE_FALLOFF,
    halfplane_coverage as halfplane_coverage,
    rim_jacobian as rim_jacobian,
    disk_coverage as disk_coverage,
    rim_coverage as rim_coverage,
    soft_maxima as soft_maxima,
    soft_maximum_terms as soft_maximum_terms,
    edge_alpha as edge_alpha,
)


def _errstate(xp) -> Any:
    """NumPy's floating-point error state silenced (division by zero, invalid), a no-op elsewhere."""
    return np.errstate(divide="ignore", invalid="ignore") if xp is np else nullcontext()


def transform_points(rotation, translation, points):
    """(N, 3) points -> ``rotation @ p + translation`` (world to camera space with the view matrix's parts)."""
    xp = array_namespace(rotation, translation, points)
    return points @ xp.swapaxes(rotation, 0, 1) + translation


def to_camera(camera: Camera, points: np.ndarray) -> np.ndarray:
    """(N, 3) world points -> (N, 3) camera-space points."""
    m = camera.view_matrix
    return transform_points(m[:3, :3], m[:3, 3], np.asarray(points, dtype=np.float64))


def to_camera_dir(camera: Camera, vectors: np.ndarray) -> np.ndarray:
    """(N, 3) world vectors (normals, tangent axes) -> camera space (no translation)."""
    return np.asarray(vectors, dtype=np.float64) @ camera.view_matrix[:3, :3].T


def project_points(p_cam, focal, principal) -> Any:
    """(N, 3) camera-space points -> (N, 2) window pixel coordinates (x right, y up).

    ``focal``: focal length in pixels; ``principal``: (cx, cy) window pixels.
    """
    xp = array_namespace(p_cam, focal)
    z = -p_cam[..., 2]
    return xp.stack([principal[0] + focal * p_cam[..., 0] / z, principal[1] + focal * p_cam[..., 1] / z], axis=-1)


def project(camera: Camera, p_cam: np.ndarray) -> np.ndarray:
    """(N, 3) camera-space points -> (N, 2) window pixel coordinates (x right, y up)."""
    return project_points(p_cam, camera.focal_px, camera.principal_point)


def rays_through(pixels, focal, principal) -> Any:
    """(..., 2) window pixel coordinates -> (..., 3) camera-space ray directions with z = -1."""
    xp = array_namespace(pixels, focal)
    x = (pixels[..., 0] - principal[0]) / focal
    y = (pixels[..., 1] - principal[1]) / focal
    return xp.stack([x, y, -xp.ones_like(x)], axis=-1)


def pixel_rays(camera: Camera, pixels: np.ndarray) -> np.ndarray:
    """(..., 2) window pixel coordinates -> (..., 3) camera-space ray directions with z = -1."""
    return rays_through(np.asarray(pixels, dtype=np.float64), camera.focal_px, camera.principal_point)


def pixel_centers(camera: Camera) -> np.ndarray:
    """(H, W, 2) window coordinates of the pixel centers, row 0 at the top of the image."""
    x = np.arange(camera.width) + 0.5
    y = camera.height - (np.arange(camera.height) + 0.5)
    return np.stack(np.meshgrid(x, y), axis=-1)


def jacobian(focal, p_cam, u_cam, v_cam) -> Any:
    """(N, 2, 2) Jacobian of the projection at the splat center w.r.t. normalized (s, t).

    Columns are d(pixel)/ds and d(pixel)/dt for the point ``p + s u + t v``; ``focal`` in pixels.
    Guennebaud 2003, eq. 8 (with eta = focal / z), in window pixels, y up.
    """
    xp = array_namespace(p_cam, u_cam, v_cam, focal)
    z = -p_cam[:, 2:3]
    # d/ds [f X / z] with dz/ds = -u_z
    du = focal * (u_cam[:, :2] * z + p_cam[:, :2] * u_cam[:, 2:3]) / z**2
    dv = focal * (v_cam[:, :2] * z + p_cam[:, :2] * v_cam[:, 2:3]) / z**2
    return xp.stack([du, dv], axis=-1)


def ewa_jacobian(camera: Camera, p_cam: np.ndarray, u_cam: np.ndarray, v_cam: np.ndarray) -> np.ndarray:
    """(N, 2, 2) Jacobian of the projection at the splat center w.r.t. normalized (s, t).

    Columns are d(pixel)/ds and d(pixel)/dt for the point ``p + s u + t v``.
    Guennebaud 2003, eq. 8 (with eta = focal / z), in window pixels, y up.
    """
    return jacobian(camera.focal_px, *(np.asarray(a, dtype=np.float64) for a in (p_cam, u_cam, v_cam)))


def prefilter_variance(prefilter: bool) -> float:
    """Variance of the EWA prefilter ``H = h I`` in pixels^2: 1 (one pixel) when on, and a tiny
    regularizer when off, so an edge-on splat's variance stays invertible."""
    return 1.0 if prefilter else 1e-4


def ewa_variance(jacobian, cutoff: float = 1.0, prefilter: bool = True) -> Any:
    """(N, 2, 2) screen-space resampling variance ``J V_r J^T + H`` in pixels^2.

    Guennebaud 2003, eq. 6. The reconstruction variance in normalized splat
    coordinates is ``V_r = I / (2 c)`` so that the splat's ellipse
    (s^2 + t^2 = 1) is the cutoff isocontour ``0.5 x^T V_r^-1 x = c``.
    ``H = I`` (one pixel) with the prefilter, a tiny regularizer without it.
    """
    xp = array_namespace(jacobian)
    j = as_float(jacobian, xp)
    v = j @ xp.swapaxes(j, -1, -2) / (2.0 * cutoff)
    h = prefilter_variance(prefilter)
    return matrix2(v[..., 0, 0] + h, v[..., 0, 1], v[..., 1, 0], v[..., 1, 1] + h)


def ewa_half_extent(variance, cutoff: float = 1.0) -> Any:
    """(N, 2) half-width and half-height in pixels of the tight box of ``0.5 x^T V^-1 x <= c``."""
    xp = array_namespace(variance)
    return xp.sqrt(2.0 * cutoff * xp.stack([variance[:, 0, 0], variance[:, 1, 1]], axis=-1))


def ewa_scale(variance, jacobian, cutoff: float = 1.0) -> Any:
    """(N,) peak weight ``|J| / (2 c sqrt|V|)`` of the resampling kernel (Guennebaud 2003, eq. 6, times pi / c):
    1 for a magnified splat, its projected area (over pi / c) for a minified one."""
    xp = array_namespace(variance, jacobian)
    return xp.abs(det2(jacobian)) / (2.0 * cutoff * xp.sqrt(det2(variance)))


def ewa_beta(conic, offset) -> Any:
    """``beta = 0.5 x^T V^-1 x`` at pixel offsets ``offset`` (..., 2) for conics ``V^-1`` (..., 2, 2)."""
    return conic_beta(conic[..., 0, 0], 0.5 * (conic[..., 0, 1] + conic[..., 1, 0]), conic[..., 1, 1],
                      offset[..., 0], offset[..., 1])


def conic_beta(xx, xy, yy, dx, dy) -> Any:
    """``beta = 0.5 x^T V^-1 x`` from the entries ``(xx, xy, yy)`` of the symmetric conic ``V^-1`` and the
    offset ``(dx, dy)`` in pixels (the fragment shader's form, ewa.frag)."""
    return 0.5 * (xx * dx * dx + 2.0 * xy * dx * dy + yy * dy * dy)


def ewa_weight(variance, jacobian, offset, cutoff: float = 1.0) -> Any:
    """EWA resampling weight at pixel offsets from the projected center (0 beyond the cutoff).

    ``variance``, ``jacobian``: (N, 2, 2); ``offset``: (N, ..., 2) pixels.
    Guennebaud 2003, eq. 6: ``|J| G_V(x)``, scaled by ``pi / c`` so that a
    magnified splat has peak weight 1 (a constant factor, removed by the
    per-pixel normalization of eq. 18).
    """
    xp = array_namespace(variance, jacobian, offset)
    variance, jacobian, offset = (as_float(a, xp) for a in (variance, jacobian, offset))
    extra = offset.ndim - 2
    inv = inv2(variance)
    inv = inv.reshape(tuple(inv.shape[:1]) + (1,) * extra + (2, 2))
    beta = ewa_beta(inv, offset)
    scale = ewa_scale(variance, jacobian, cutoff)
    w = scale.reshape(tuple(scale.shape) + (1,) * extra) * xp.exp(-beta)
    return xp.where(beta <= cutoff, w, 0.0)


def ray_plane_distance(rays, p_cam, n_cam) -> Any:
    """Ray parameter t where ``t * ray`` meets the plane through p with normal n.

    Rays have z = -1, so t is also the camera-space depth (distance along -z).
    Guennebaud 2003, eq. 10/13. ``rays``: (N, ..., 3); ``p_cam``, ``n_cam``: (N, 3).
    """
    xp = array_namespace(rays, p_cam, n_cam)
    extra = rays.ndim - 2
    p = p_cam.reshape(tuple(p_cam.shape[:1]) + (1,) * extra + (3,))
    n = n_cam.reshape(tuple(n_cam.shape[:1]) + (1,) * extra + (3,))
    with _errstate(xp):
        return xp.sum(n * p, axis=-1) / xp.sum(n * rays, axis=-1)


def splat_coordinates(rays, t, p_cam, u_cam, v_cam) -> Any:
    """Normalized (s, t) coordinates of the ray/plane hit points ``t * ray`` (u and v orthogonal)."""
    xp = array_namespace(rays, t, p_cam, u_cam, v_cam)
    extra = rays.ndim - 2
    shape = tuple(p_cam.shape[:1]) + (1,) * extra + (3,)
    q = t[..., None] * rays - p_cam.reshape(shape)
    u, v = u_cam.reshape(shape), v_cam.reshape(shape)
    return xp.stack([xp.sum(q * u, axis=-1) / xp.sum(u * u, axis=-1),
                     xp.sum(q * v, axis=-1) / xp.sum(v * v, axis=-1)], axis=-1)


def footprint_depth(st, p_cam, u_cam, v_cam) -> Any:
    """Camera-space depth a filter fragment at normalized (s, t) gets: that of the disk point nearest to (s, t)
    (``footprint_depth`` in splat_fragment.glsl; (s, t) beyond the rim are pulled onto it). (M, 2), (M, 3)."""
    xp = array_namespace(st, p_cam, u_cam, v_cam)
    len2 = xp.sum(st * st, axis=-1, keepdims=True)
    st = st / xp.sqrt(xp.where(len2 > 1.0, len2, 1.0))
    return -(p_cam[..., 2] + st[..., 0] * u_cam[..., 2] + st[..., 1] * v_cam[..., 2])


#: Scale of the (s, t) of a ray meeting a splat's plane behind the eye: far outside the ellipse, in the
#: direction of the plane's horizon the ray points to (``footprint_st`` in splat_fragment.glsl).
HORIZON = 1e6

#: Number of rows of :func:`ray_coefficients`.
RAY_COEFFICIENTS = 15


def ray_coefficients(p_cam, n_cam, u_cam, v_cam) -> Any:
    """(15, N) per-splat coefficients of the ray/splat formulas in flat form (rows): the normal
    ``(n_x, n_y, n_z, n . p)``, the dual axes ``u / u.u`` and ``u . p / u.u`` (4), the same of ``v`` (4), and
    ``(p_z, u_z, v_z)``. With them the per-pixel formulas (:func:`footprint_hits`) are a few products of
    scalars: the same quantities as :func:`ray_plane_distance`, :func:`splat_coordinates` and
    :func:`footprint_depth` (for the rays ``(x, y, -1)``), with each dot product taken once per splat.
    ``p_cam``, ``n_cam``, ``u_cam``, ``v_cam``: (N, 3) camera space."""
    xp = array_namespace(p_cam, n_cam, u_cam, v_cam)
    (px, py, pz), (nx, ny, nz), (ux, uy, uz), (vx, vy, vz) = (unstack(a) for a in (p_cam, n_cam, u_cam, v_cam))
    uu, vv = ux * ux + uy * uy + uz * uz, vx * vx + vy * vy + vz * vz
    return xp.stack([nx, ny, nz, nx * px + ny * py + nz * pz,
                     ux / uu, uy / uu, uz / uu, (ux * px + uy * py + uz * pz) / uu,
                     vx / vv, vy / vv, vz / vv, (vx * px + vy * py + vz * pz) / vv, pz, uz, vz])


def footprint_hits(coefficients, x, y) -> tuple[Any, Any, Any, Any]:
    """``(hit, s, t, z)`` of the rays ``(x, y, -1)`` (camera space, z = -1: ``x = (px - cx) / f``) and the
    splats of :func:`ray_coefficients` rows ``coefficients`` (any sequence of 15 arrays broadcasting with
    ``x``, ``y``): the ray parameter (= depth) of the hit with the plane, its normalized (s, t) (``footprint_st``
    in splat_fragment.glsl: a ray meeting the plane behind the eye, or parallel to it, takes
    ``HORIZON`` times its direction's (s, t)), and the depth a fragment there gets (:func:`footprint_depth`)."""
    xp = array_namespace(x, y, coefficients[0])
    nx, ny, nz, n_p, ux, uy, uz, u_p, vx, vy, vz, v_p, pz, uz_, vz_ = (coefficients[k] for k in range(15))
    with _errstate(xp):
        hit = n_p / (nx * x + ny * y - nz)
    front = hit > 0   # False for NaN; an infinite hit (a ray parallel to the plane) leaves the plane too
    front = front & (hit < float("inf"))
    h = xp.where(front, hit, 0.0)
    s_ray = ux * x + uy * y - uz
    t_ray = vx * x + vy * y - vz
    s = xp.where(front, h * s_ray - u_p, HORIZON * s_ray)
    t = xp.where(front, h * t_ray - v_p, HORIZON * t_ray)
    len2 = s * s + t * t
    shrink = 1.0 / xp.sqrt(xp.where(len2 > 1.0, len2, 1.0))   # beyond the rim: the nearest disk point
    z = -(pz + shrink * (s * uz_ + t * vz_))
    return hit, s, t, z


def window_depth(z: np.ndarray, near: float, far: float) -> np.ndarray:
    """Camera-space depth (model units) -> stored depth in [0, 1], linear between near and far.

    All our shaders write gl_FragDepth themselves, so a linear mapping keeps a
    uniform precision over the whole range instead of OpenGL's 1/z mapping.
    """
    return (np.asarray(z) - near) / (far - near)


def facing_normals(n_cam, p_cam) -> Any:
    """Flip camera-space normals that face away from the eye (two-sided lighting)."""
    xp = array_namespace(n_cam, p_cam)
    flip = xp.sum(n_cam * p_cam, axis=-1, keepdims=True) > 0
    return xp.where(flip, -n_cam, n_cam)


def shade(albedo, n, view, light_dirs, lights: Lights) -> Any:
    """Blinn-Phong color (not clamped) for unit normals ``n`` and unit ``view`` (toward the eye).

    ``albedo``, ``n``, ``view``: (..., 3); ``light_dirs``: (L, 3) unit, same space as ``n``.
    ``c = albedo (ka + kd sum max(0, n.l)) + ks sum max(0, n.h)^s``; normals facing away
    from ``view`` are flipped.
    """
    xp = array_namespace(albedo, n, view, light_dirs)
    if not lights.enabled:
        return as_float(albedo, xp)
    n = xp.where(dot(n, view, keepdims=True) < 0, -n, n)
    diffuse: Any = 0.0
    specular: Any = 0.0
    for l in as_float(light_dirs, xp):  # at most 4 lights, not per point
        nl = dot(n, l)
        diffuse = diffuse + xp.where(nl > 0, nl, 0.0)
        h = view + l
        h = h / xp.clip(norm(h, keepdims=True), 1e-30, None)
        nh = dot(n, h)
        specular = specular + xp.where(nh > 0, nh, 0.0) ** lights.shininess
    return albedo * (lights.ambient + lights.diffuse * diffuse[..., None]) + lights.specular * specular[..., None]


def unit(a) -> Any:
    """Vectors over the last axis scaled to unit length."""
    return a / norm(a, keepdims=True)


def cross(a, b) -> Any:
    """Cross product over the last axis of (..., 3) arrays (NumPy or PyTorch)."""
    return _cross(a, b)


# -- techniques "phong" and "blend": object-space kernels at the exact ray/splat hit -------------

def plane_normals(normals, u, v) -> Any:
    """(N, 3) unit normals of the splats' planes, ``u x v`` turned to the side of ``normals``.

    The plane is spanned by the axes; ``normals`` is the center shading normal,
    which a Phong splat tilts away from the plane's (Botsch 2004, sec. 3).
    """
    xp = array_namespace(normals, u, v)
    n = unit(_cross(u, v))
    return xp.where(dot(n, normals, keepdims=True) < 0, -n, n)


def field_normals(normals: np.ndarray, u: np.ndarray, v: np.ndarray, normal_field: np.ndarray,
                  st: np.ndarray) -> np.ndarray:
    """Unit normals of linear normal fields at normalized coordinates (Botsch 2004, eq. 2).

    ``n(s, t) = n + s alpha u_hat + t beta v_hat``, normalized. ``normals``, ``u``,
    ``v``: (N, 3); ``normal_field``: (N, 2) (alpha, beta); ``st``: (N, ..., 2).
    """
    extra = st.ndim - 2
    shape = normals.shape[:1] + (1,) * extra + (3,)
    u_hat = (u / np.linalg.norm(u, axis=-1, keepdims=True)) * normal_field[:, :1]
    v_hat = (v / np.linalg.norm(v, axis=-1, keepdims=True)) * normal_field[:, 1:]
    n = normals.reshape(shape) + st[..., :1] * u_hat.reshape(shape) + st[..., 1:] * v_hat.reshape(shape)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def object_space_weight(st: np.ndarray, a: float, n: float) -> np.ndarray:
    """Kernel ``exp(-a rho^n)`` at normalized radius ``rho = |st|``, 0 outside the ellipse.

    Pajarola 2003, EQ 12 with rho = r / b (``n = 2``: the Gaussians of EQ 11 and of
    Botsch 2004's technique, ``a`` = cutoff). ``st``: (..., 2).
    """
    rho = np.sqrt(np.sum(np.asarray(st, dtype=np.float64) ** 2, axis=-1))
    return np.where(rho <= 1.0, np.exp(-a * rho ** n), 0.0)

# -- technique "perspective": perspective accurate splatting (Zwicker et al. 2004) ---------------
#
# Conventions. The paper writes points as row vectors: x = u M (eq. 4). Here M_k maps the
# homogeneous normalized splat coordinates u = (s, t, 1) to homogeneous window pixel offsets
# x = (d_x w, d_y w, w) from the projected splat center c = project(p) (window pixels, y up),
# w = -Z the camera-space depth. Working relative to c keeps every quantity of the size of the
# footprint (no cancellation against the center's absolute pixel position).
#
# The cutoff contour of the reconstruction kernel in normalized coordinates is the splat's own
# ellipse s^2 + t^2 = 1: sec. 4.4's Q_h = [[R_k^-1, 0], [0, -F_g^2]] (the paper prints R_k where
# the contour u R_k^-1 u^T = F_g^2 needs its inverse) with ewa's R_k = V_r = I / (2c) and
# F_g^2 = 2c (the cut 0.5 x^T V_r^-1 x = c) is 2c diag(1, 1, -1), the same conic as
# Q_h = diag(1, 1, -1). Its image is Q'_h = M^-1 Q_h M^-T (sec. 4.3).
# Eq. 11's Q''' is a *conic* matrix (x Q''' x^T = F_g^2 on the contour, F_g^2 = 2c here), so the
# reconstruction variance is R'_k = Q'''^-1 and the resampling variance V = Q'''^-1 + H (eq. 3);
# sec. 6 names (Q''' + H)^-1 the conic of the resampling filter, reading Q''' as the variance.
#
# The shader does not invert M: it uses the dual conic C* = adj(Q'_h) ~ M^T diag(1, 1, -1) M,
# whose last column is the center (eq. 7) and whose entries give the tight box (eq. 8-9) and
# the variance (eq. 11) as sums of positive terms. ``perspective_footprint`` mirrors it.

#: Condition number of the unit-scaled mapping [u/|u|; v/|v|; p/|p|] beyond which a splat is
#: not splatted by its conic but ray-cast (Zwicker 2004, sec. 6 discards it). For orthogonal
#: axes it equals (1 + sin a) / |cos a| with a the angle between the normal and the viewing
#: ray of the center: 1e4 is |cos a| < 2e-4 (within 0.011 degrees of edge-on), where float32
#: loses ~1e-3 of the relative precision of n.p that the footprint's determinant rests on.
PERSPECTIVE_MAX_CONDITION = 1e4

#: A splat whose nearest point is closer than max(near, this fraction of its center depth) is
#: ray-cast (Botsch 2004, eq. 6): its image is not an ellipse (it crosses the plane through the
#: eye, eq. 5: Delta <= 0), is clipped by the near plane, or nearly so (conic blows up as 1/h^2).
#: It, PERSPECTIVE_MAX_CONDITION and EDGE_ON_TOLERANCE reach the shaders as macros of the same
#: names (``render.shaders.SHARED_DEFINES``).
PERSPECTIVE_NEAR_FRACTION = 1e-3

#: A splat with ``|n . p| <= EDGE_ON_TOLERANCE |p|`` (camera space) is seen exactly edge-on
#: through the eye: it covers no area and is culled (``camera_splat`` in splat_vertex.glsl).
EDGE_ON_TOLERANCE = 1e-7

#: Footprint modes of ``perspective_footprint``.
PERSPECTIVE_CULLED, PERSPECTIVE_CONIC, PERSPECTIVE_RAYCAST = 0, 1, 2


def perspective_mapping(camera: Camera, p_cam: np.ndarray, u_cam: np.ndarray, v_cam: np.ndarray) -> np.ndarray:
    """(N, 3, 3) projective mapping M_k from normalized splat to window pixel coordinates.

    Zwicker 2004, eq. 4 (row-vector convention ``x = (s, t, 1) M_k``) composed with the
    pinhole projection of ``project``: rows are the images of ``u``, ``v`` and ``p``, each
    ``(f X + dx Z, f Y + dy Z, -Z)`` with ``(dx, dy) = project(p) - principal point``, so
    ``x = (d_x w, d_y w, w)`` are homogeneous window pixel *offsets* from ``project(p)``
    (and the row of ``p`` is ``(0, 0, -p_z)``). ``p_cam``, ``u_cam``, ``v_cam``: (N, 3)
    camera space, model units; entries in pixels x model units (first two columns) and
    model units (last column).
    """
    p_cam, u_cam, v_cam = (np.asarray(a, dtype=np.float64) for a in (p_cam, u_cam, v_cam))
    f = camera.focal_px
    delta = f * p_cam[:, :2] / -p_cam[:, 2:3]

    def row(x):
        return np.concatenate([f * x[:, :2] + delta * x[:, 2:3], -x[:, 2:3]], axis=1)

    return np.stack([row(u_cam), row(v_cam), row(p_cam)], axis=1)


def perspective_condition(p_cam: np.ndarray, u_cam: np.ndarray, v_cam: np.ndarray) -> np.ndarray:
    """(N,) condition number of the unit-scaled mapping ``[u/|u|; v/|v|; p/|p|]`` (eq. 4).

    The pixel-unit M_k mixes units (its raw condition number grows with distance and
    splat size, not with degeneracy); scaling its source axes and the camera out leaves the
    camera-space frame, singular exactly when the splat is seen edge-on (Zwicker 2004, sec. 6).
    """
    rows = [np.asarray(a, dtype=np.float64) for a in (u_cam, v_cam, p_cam)]
    frame = np.stack([r / np.linalg.norm(r, axis=1, keepdims=True) for r in rows], axis=1)
    return np.linalg.cond(frame)


def adjugate3(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) adjugate (transposed cofactor matrix): ``adj(M) = det(M) M^-1``, never divides."""
    c0 = np.cross(m[..., 1, :], m[..., 2, :])
    c1 = np.cross(m[..., 2, :], m[..., 0, :])
    c2 = np.cross(m[..., 0, :], m[..., 1, :])
    return np.stack([c0, c1, c2], axis=-1)


def project_conic(mapping: np.ndarray, conic: np.ndarray | None = None) -> np.ndarray:
    """(N, 3, 3) image ``Q'_h = M^-1 Q_h M^-T`` of the splat-plane conic ``Q_h`` (Zwicker 2004, sec. 4.3).

    ``mapping``: (N, 3, 3) M_k of ``perspective_mapping`` (row convention). ``conic``: (3, 3)
    or (N, 3, 3), default the cutoff contour ``diag(1, 1, -1)`` (s^2 + t^2 = 1). Computed
    with the adjugate (``adj(M) Q_h adj(M)^T = det(M)^2 Q'_h``: the same conic, same sign)
    and scaled to unit Frobenius norm; the conic's interior (the splat) is where
    ``x Q'_h x^T < 0`` for the default conic. Coordinates: window pixel offsets from project(p).
    """
    if conic is None:
        conic = np.diag([1.0, 1.0, -1.0])
    adj = adjugate3(np.asarray(mapping, dtype=np.float64))
    q = adj @ conic @ np.swapaxes(adj, -1, -2)
    return q / np.linalg.norm(q, axis=(-2, -1), keepdims=True)


def _conic_coefficients(conic_h: np.ndarray):
    """A, B, C, D, E, F of eq. 5 from the (N, 3, 3) homogeneous conic of eq. 6."""
    q = np.asarray(conic_h, dtype=np.float64)
    return q[:, 0, 0], q[:, 0, 1], q[:, 1, 1], q[:, 0, 2], q[:, 1, 2], -q[:, 2, 2]


def conic_center(conic_h: np.ndarray) -> np.ndarray:
    """(N, 2) center ``x_t`` of the (N, 3, 3) conics (Zwicker 2004, eq. 7); inf/nan for parabolas."""
    a, b, c, d, e, _ = _conic_coefficients(conic_h)
    delta = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack([(b * e - c * d) / delta, (b * d - a * e) / delta], axis=-1)


def is_ellipse(conic_h: np.ndarray) -> np.ndarray:
    """(N,) bool: the conic is a real ellipse, ``Delta = AC - B^2 > 0`` (Zwicker 2004, sec. 4.2).

    Also requires a non-empty interior: the central level ``F - D x_t - E y_t`` has the sign of A.
    """
    a, b, c, _, _, _ = _conic_coefficients(conic_h)
    delta = a * c - b * b
    _, level = central_conic(conic_h)
    return (delta > 0) & (level * a > 0)


def central_conic(conic_h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Q'', F - D x_t - E y_t)``: (N, 2, 2) central conic matrix and (N,) level (eq. 10).

    The conic is ``(x - x_t) Q'' (x - x_t)^T = F - D x_t - E y_t`` (Zwicker 2004, eq. 10).
    """
    a, b, c, d, e, f = _conic_coefficients(conic_h)
    xt = conic_center(conic_h)
    q2 = np.stack([np.stack([a, b], -1), np.stack([b, c], -1)], -2)
    return q2, f - d * xt[:, 0] - e * xt[:, 1]


def conic_q3(conic_h: np.ndarray, cutoff: float = 1.0) -> np.ndarray:
    """(N, 2, 2) ``Q''' = F_g^2 / (f - d x_t - e y_t) Q''`` (Zwicker 2004, eq. 11), pixels^-2.

    With ``F_g^2 = 2 c`` the contour ``x Q''' x^T = 2c`` is the cut ``0.5 x^T V_r^-1 x = c`` of
    ewa, so ``V_r = Q'''^-1`` (see the section comment on the paper's convention).
    """
    q2, level = central_conic(conic_h)
    return (2.0 * cutoff / level)[:, None, None] * q2


def conic_bounds(conic_h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) ``(lo, hi)``: tight axis-aligned box of the ellipses (Zwicker 2004, eq. 8-9).

    ``x_t -+ sqrt(C (F - D x_t - E y_t) / Delta)``, ``y_t -+ sqrt(A (F - D x_t - E y_t) / Delta)``,
    in the conics' coordinates (window pixel offsets for ``project_conic``'s output).
    """
    a, b, c, _, _, _ = _conic_coefficients(conic_h)
    delta = a * c - b * b
    xt = conic_center(conic_h)
    _, level = central_conic(conic_h)
    half = np.sqrt(np.stack([c * level / delta, a * level / delta], axis=-1))
    return xt - half, xt + half


def perspective_footprint(camera: Camera, p_cam: np.ndarray, n_cam: np.ndarray, u_cam: np.ndarray,
                          v_cam: np.ndarray, cutoff: float = 1.0, prefilter: bool = True,
                          filter_variance: float | None = None) -> dict:
    """Per-splat footprint of technique ``perspective``, as ``perspective.vert`` computes it.

    Inputs (N, 3) camera space, model units (``n_cam`` unit). The dual conic
    ``C* = M^T diag(1, 1, -1) M`` (column convention; ``adj(Q'_h)`` up to a positive factor,
    Zwicker 2004, sec. 4.3) with the rows ``(U, -u_z)``, ``(V, -v_z)``, ``(0, 0, z)`` of M_k gives,
    with ``h = z^2 - u_z^2 - v_z^2 = -C*_33 > 0`` (the image is an ellipse iff h > 0, eq. 5):

    - center (eq. 7): ``x_t = (U u_z + V v_z) / h`` (pixel offset from project(p));
    - shape ``S = x_t x_t^T + (U U^T + V V^T) / h`` (positive terms only): the ellipse is
      ``(x - x_t)^T S^-1 (x - x_t) = 1``, i.e. ``S = F_g^2 Q'''^-1`` (eq. 10-11), and
      ``det S = f^4 ((u x v) . p)^2 / h^3`` in closed form (used as ``det S / tr(S)^2``);
    - resampling variance ``V = S / (2c) + H`` (eq. 3, ``H = I`` with the prefilter, 1e-4 I
      without, or ``filter_variance`` I), pixels^2;
    - weight scale ``sqrt(|V_r| / |V|) = 1 / sqrt(1 + (x + x^2) / (det S / tr(S)^2))``,
      ``x = eta / tr(V_r)``: the reconstruction
      kernel with peak 1 convolved with the unit-mass prefilter, so a magnified splat peaks
      at ~1 and a minified one weighs its projected area (ewa's ``|J| / (2c sqrt|V|)``);
    - box half extents ``sqrt(2c V_xx)``, ``sqrt(2c V_yy)`` around x_t (eq. 8-9 of the cut).

    Returns a dict of arrays: ``mode`` (N,) int (PERSPECTIVE_CULLED / _CONIC / _RAYCAST),
    ``center`` (N, 2) window pixels of the conic's center (project(p) + x_t), ``offset`` (N, 2)
    x_t, ``shape`` (N, 2, 2) S, ``variance`` (N, 2, 2) V, ``scale`` (N,), ``half_extent`` (N, 2)
    pixels, ``condition`` (N,), ``det_variance`` (N,) |V| in pixels^4. Entries of non-conic
    splats are zeros (no NaN).
    """
    p, n, u, v = (np.asarray(a, dtype=np.float64) for a in (p_cam, n_cam, u_cam, v_cam))
    near, far = camera.near, camera.far
    if near is None or far is None:
        raise ValueError("the camera needs near and far set (Camera.with_clip_from_bounds)")
    f = camera.focal_px
    z = -p[:, 2]
    wz = np.stack([u[:, 2], v[:, 2]], axis=-1)
    zext = np.linalg.norm(wz, axis=-1)
    plen = np.linalg.norm(p, axis=-1)
    n_dot_p = np.sum(n * p, axis=-1)
    # camera_splat() in splat_vertex.glsl: outside [near, far] or exactly edge-on
    visible = (z + zext >= near) & (z - zext <= far) & (np.abs(n_dot_p) > EDGE_ON_TOLERANCE * plen)
    cos = np.abs(n_dot_p) / np.maximum(plen, 1e-300)
    sin = np.sqrt(np.maximum(0.0, 1.0 - cos * cos))
    condition = (1.0 + sin) / np.maximum(cos, 1e-300)
    zmin = z - zext
    in_front = zmin >= np.maximum(near, PERSPECTIVE_NEAR_FRACTION * z)
    conic = visible & (condition <= PERSPECTIVE_MAX_CONDITION) & in_front
    mode = np.where(conic, PERSPECTIVE_CONIC, np.where(visible, PERSPECTIVE_RAYCAST, PERSPECTIVE_CULLED))

    zs = np.where(conic, z, 1.0)
    h = np.where(conic, (z - zext) * (z + zext), 1.0)
    delta = f * p[:, :2] / zs[:, None]
    big_u = f * u[:, :2] + delta * u[:, 2:3]
    big_v = f * v[:, :2] + delta * v[:, 2:3]
    offset = (big_u * u[:, 2:3] + big_v * v[:, 2:3]) / h[:, None]  # eq. 7
    outer = lambda a: a[:, :, None] * a[:, None, :]  # noqa: E731
    shape = outer(offset) + (outer(big_u) + outer(big_v)) / h[:, None, None]  # eq. 10-11
    eta = prefilter_variance(prefilter) if filter_variance is None else float(filter_variance)
    variance = shape / (2.0 * cutoff) + eta * np.eye(2)
    # det S / tr(S)^2 from det S = f^4 ((u x v) . p)^2 / h^3 (closed form, scale-free)
    trace_s = np.trace(shape, axis1=1, axis2=2)
    a = f * f * np.sum(np.cross(u, v) * p, axis=-1) / h / trace_s
    det_ratio = a * a / h
    trace_r = trace_s / (2.0 * cutoff)
    det_v = trace_r * (trace_r * det_ratio + eta) + eta**2  # |R'| + eta tr(R') + eta^2
    x = eta / trace_r
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = 1.0 / np.sqrt(1.0 + (x + x * x) / det_ratio)  # sqrt(|R'| / |V|)
    half = np.sqrt(2.0 * cutoff * np.stack([variance[:, 0, 0], variance[:, 1, 1]], axis=-1))
    center = project(camera, np.where(conic[:, None], p, (0.0, 0.0, -1.0))) + offset
    zero = ~conic
    for arr in (offset, center, half):
        arr[zero] = 0.0
    shape[zero], variance[zero] = 0.0, 0.0
    scale = np.where(conic, scale, 0.0)
    return {"mode": mode, "center": center, "offset": offset, "shape": shape, "variance": variance,
            "scale": scale, "half_extent": half, "condition": condition,
            "det_variance": np.where(conic, det_v, 1.0)}


def perspective_weight(camera: Camera, p_cam: np.ndarray, n_cam: np.ndarray, u_cam: np.ndarray,
                       v_cam: np.ndarray, pixels: np.ndarray, cutoff: float = 1.0,
                       prefilter: bool = True) -> np.ndarray:
    """(N, ...) weight of technique ``perspective`` at window pixel positions ``pixels`` (..., 2).

    Conic splats (Zwicker 2004, eq. 3 with R'_k = Q'''^-1, eq. 11): ``scale * exp(-beta)``,
    ``beta = 0.5 (x - x_t)^T V^-1 (x - x_t)``, 0 where ``beta > c``. Ray-cast splats (near
    plane, not an ellipse, ill-conditioned; Botsch 2004, eq. 6): the pixel's ray meets the
    splat plane at (s, t) at depth z; weight ``exp(-c (s^2 + t^2))`` where ``s^2 + t^2 <= 1``
    and ``near <= z <= far``, else 0 (the reconstruction kernel V_r = I / (2c), peak 1).
    Inputs: (N, 3) camera space; see ``perspective_footprint``.
    """
    fp = perspective_footprint(camera, p_cam, n_cam, u_cam, v_cam, cutoff, prefilter)
    pixels = np.asarray(pixels, dtype=np.float64)
    n = len(fp["mode"])
    extra = pixels.ndim - 1
    shape = (n,) + (1,) * extra
    # conic splats
    e = pixels[None] - fp["center"].reshape(shape + (2,))
    var = fp["variance"].copy()
    var[fp["mode"] != PERSPECTIVE_CONIC] = np.eye(2)
    inv = np.linalg.inv(var).reshape(shape + (2, 2))
    beta = 0.5 * np.einsum("...i,...ij,...j->...", e, inv, e)
    w_conic = np.where(beta <= cutoff, fp["scale"].reshape(shape) * np.exp(-beta), 0.0)
    # ray-cast splats
    rays = np.broadcast_to(pixel_rays(camera, pixels)[None], (n,) + pixels.shape[:-1] + (3,))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t = ray_plane_distance(rays, p_cam, n_cam)
        st = splat_coordinates(rays, np.where(np.isfinite(t), t, 0.0), p_cam, u_cam, v_cam)
        r2 = np.sum(st**2, axis=-1)
        hit = (r2 <= 1.0) & (t >= camera.near) & (t <= camera.far)
        w_ray = np.where(hit, np.exp(-cutoff * np.where(hit, r2, 0.0)), 0.0)
    mode = fp["mode"].reshape(shape)
    return np.where(mode == PERSPECTIVE_CONIC, w_conic, np.where(mode == PERSPECTIVE_RAYCAST, w_ray, 0.0))


def clip_keep(st: np.ndarray, clip_lines: np.ndarray) -> np.ndarray:
    """Clip-line test: True where ``a s + b t + c >= 0`` for both lines of each splat.

    ``st``: (N, ..., 2) normalized splat coordinates; ``clip_lines``: (N, 2, 3)
    ``(a, b, c)`` (Botsch 2004, sec. 4; unused lines are (0, 0, 1)).
    """
    extra = st.ndim - 2
    lines = clip_lines.reshape(clip_lines.shape[:1] + (1,) * extra + (2, 3))
    value = lines[..., 0] * st[..., None, 0] + lines[..., 1] * st[..., None, 1] + lines[..., 2]
    return (value >= 0).all(axis=-1)


def point_diameter(camera: Camera, p_cam: np.ndarray, radii: np.ndarray, size_range=(1.0, 64.0),
                   supersample: int = 1) -> np.ndarray:
    """(N,) diameters in window pixels of the ``points`` technique's points: the splat radius projected
    at the point's depth, ``2 r f / z``, clamped to ``size_range`` output pixels (Potree's adaptive point
    size); ``camera`` is the drawn (supersampled) one, K = ``supersample`` sub-pixels per output pixel."""
    d = 2.0 * np.asarray(radii, np.float64) * camera.focal_px / (-p_cam[:, 2])
    return np.clip(d, size_range[0] * supersample, size_range[1] * supersample)


def point_footprint(center: np.ndarray, diameter: float, pixels: np.ndarray) -> np.ndarray:
    """Pixels (..., 2 window coordinates of their centers) a ``points`` point covers: centers within
    ``diameter / 2`` of its projected ``center``, and the pixel holding the center."""
    d = pixels - np.asarray(center, np.float64)
    inside = (d ** 2).sum(axis=-1) <= (0.5 * diameter) ** 2
    return inside | np.all(np.floor(pixels) == np.floor(center), axis=-1)


#: The 4 axes of :func:`fill_holes` (x right, y along the array's rows; the rule is symmetric in both).
FILL_AXES = ((1, 0), (0, 1), (1, 1), (1, -1))


def fill_holes(color: np.ndarray, weight: np.ndarray, depth: np.ndarray, alpha: np.ndarray, focal_px: float,
               gap: int = 3, depth_px: float = 24.0, iterations: int = 1,
               reach: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Screen-space hole filling (``glsl/fill.frag``): ``(color, weight, depth, alpha, filled)`` of an image.

    ``color`` (H, W, C), ``weight`` (H, W; > 0 where covered, < 0 marks a non-finite pixel, left alone),
    ``depth`` (H, W) camera-space depth of the covered pixels, ``alpha`` (H, W), ``focal_px``: focal length
    in the image's pixels; ``gap``: widest gap filled, pixels; ``depth_px``: depth tolerance, pixels: two
    pixels' surfaces are apart where their depths differ by more than ``tau(z) = depth_px z / focal_px``.

    A pixel is covered where it has weight and at least half its area (``alpha`` >= 1/2); one that edge
    coverage leaves partly covered (a rim, or the border of a gap between splats) may itself be a hole, so
    a gap is filled whole, not left as a lighter line. A pixel q lies in front of p when q is covered and p
    is not covered whole (``alpha`` < 1), or ``z_q < z_p - tau(z_p)``. Along each of
    the 4 axes (:data:`FILL_AXES`, both directions) the nearest pixel in front of p within ``gap`` steps is
    looked for; the axis encloses p where both are found at distances adding up to at most ``gap + 1`` and
    lie on one surface (depths within ``tau`` of the nearer: a strip of a farther surface seen between two
    surfaces at different depths, such as the view through a bore past its rim, is no gap).
    Enclosed along exactly 3, the 4th axis must enclose p too within ``reach`` (default ``3 gap``: a
    crack of up to that length, not a slit or bay opening into the background beyond a silhouette).
    Then p takes the inverse-distance weighted mean of color, weight and depth (and alpha 1: enclosed by
    the surface, it is covered whole) of those neighbours of enclosing axes that lie on the front surface (depth within
    ``tau(z_f)`` of the nearest, ``z_f``). Pintus et al. 2011 (enclosure, front neighbours) with the
    bounded gap of Marroquim et al. 2007. ``iterations``: the rule applied that many times, each on the last
    one's image. ``filled``: (H, W) bool, the pixels any iteration filled.
    """
    filled = np.zeros(np.shape(weight), bool)
    for _ in range(int(iterations)):
        color, weight, depth, alpha, once = _fill_once(color, weight, depth, alpha, focal_px, gap, depth_px,
                                                       3 * int(gap) if reach is None else int(reach))
        filled |= once
    return color, weight, depth, alpha, filled


def _fill_once(color, weight, depth, alpha, focal_px, gap, depth_px, reach):
    """One iteration of :func:`fill_holes`."""
    steps, found_z, found_c, axis = _enclosure(color, weight, depth, alpha, focal_px, gap, depth_px)
    long_axis = _enclosure(color, weight, depth, alpha, focal_px, reach, depth_px)[3] if reach > gap else axis
    count = axis.sum(axis=0)
    filled = ((count == 4) | ((count == 3) & (long_axis.sum(axis=0) == 4))) & ~(weight < 0) & (gap > 0)
    return _fill_from(color, weight, depth, alpha, focal_px, depth_px, steps, found_z, found_c, axis, filled)


def _enclosure(color, weight, depth, alpha, focal_px, gap, depth_px):
    """Per direction the nearest pixel in front within ``gap`` (steps, depth, channels) and the axes that
    enclose each pixel ((4, H, W) bool)."""
    h, w = weight.shape
    covered = (weight > 0) & (alpha >= 0.5)
    z = np.where(covered, depth, np.inf).astype(np.float64)
    whole = covered & (alpha >= 1.0)
    limit = np.where(whole, z - depth_px * np.where(whole, z, 0.0) / focal_px, np.inf)
    g = int(gap)
    pad = ((g, g), (g, g))
    zp = np.pad(z, pad, constant_values=np.inf)
    channels = np.concatenate([np.asarray(color, np.float64).reshape(h, w, -1), weight[..., None].astype(np.float64),
                               alpha[..., None].astype(np.float64)], axis=-1)
    cp = np.pad(channels, pad + ((0, 0),))
    steps = np.zeros((8, h, w), np.int64)
    found_z = np.full((8, h, w), np.inf)
    found_c = np.zeros((8, h, w, channels.shape[-1]))
    for i, (ax, ay) in enumerate(FILL_AXES):
        for side, sign in enumerate((1, -1)):
            j = 2 * i + side
            for k in range(g, 0, -1):   # the nearest wins: written last
                dx, dy = sign * ax * k, sign * ay * k
                zq = zp[g + dy:g + dy + h, g + dx:g + dx + w]
                hit = zq < limit
                steps[j] = np.where(hit, k, steps[j])
                found_z[j] = np.where(hit, zq, found_z[j])
                found_c[j] = np.where(hit[..., None], cp[g + dy:g + dy + h, g + dx:g + dx + w], found_c[j])
    near = np.minimum(found_z[0::2], found_z[1::2])
    with np.errstate(invalid="ignore"):   # inf - inf where neither side is found
        same = np.abs(found_z[0::2] - found_z[1::2]) <= depth_px * near / focal_px
    axis = (steps[0::2] > 0) & (steps[1::2] > 0) & (steps[0::2] + steps[1::2] <= g + 1) & same   # (4, H, W)
    return steps, found_z, found_c, axis


def _fill_from(color, weight, depth, alpha, focal_px, depth_px, steps, found_z, found_c, axis, filled):
    """The image with the ``filled`` pixels taken from their enclosing axes' front surface."""
    enclosing = np.repeat(axis, 2, axis=0)   # (8, H, W)
    front = np.where(enclosing, found_z, np.inf).min(axis=0)
    with np.errstate(invalid="ignore"):   # inf - inf where nothing encloses the pixel
        use = enclosing & (found_z <= front + depth_px * front / focal_px)
    inv = np.where(use, 1.0 / np.maximum(steps, 1), 0.0)
    total = np.maximum(inv.sum(axis=0), 1e-30)
    mean_c = (inv[..., None] * found_c).sum(axis=0) / total[..., None]
    mean_z = (inv * np.where(use, found_z, 0.0)).sum(axis=0) / total
    out_color = np.where(filled[..., None], mean_c[..., :-2].reshape(np.shape(color)), color)
    out_weight = np.where(filled, mean_c[..., -2], weight)
    out_depth = np.where(filled, mean_z, depth)
    out_alpha = np.where(filled, 1.0, alpha)   # enclosed by the surface: covered whole
    return out_color, out_weight, out_depth, out_alpha, filled
