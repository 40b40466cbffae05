"""The differentiable renderer's inputs as PyTorch tensors: splats and a pinhole camera.

Conventions are surfsplat's (:mod:`surfsplat.camera`, :mod:`surfsplat.cloud`): a splat is the ellipse
``p + s u + t v``, ``s^2 + t^2 <= 1`` with scaled tangent axes ``u``, ``v``; the camera is the look-at
camera's view matrix (world to camera, looking down -z), a focal length in pixels, the principal point
at the image centre, window pixels with y up and pixel centres at half-integers.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch

from ..camera import Camera
from ..cloud import DEFAULT_ALBEDO, SplatCloud
from ..errors import InputError


@dataclass
class Splats:
    """Splats as tensors (N rows), any of which may require gradients.

    Attributes:
        positions: (N, 3) centres, world units.
        u, v: (N, 3) scaled tangent axes (the ellipse's semi-axes), world units.
        colors: (N, 3) linear RGB albedo in [0, 1].
        opacity: (N,) in [0, 1] or None (1: every splat opaque, as the OpenGL techniques draw them).
        normals: (N, 3) unit shading normals or None (the plane's normal ``u x v``).
    """

    positions: torch.Tensor
    u: torch.Tensor
    v: torch.Tensor
    colors: torch.Tensor
    opacity: torch.Tensor | None = None
    normals: torch.Tensor | None = None

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @classmethod
    def from_cloud(cls, cloud: SplatCloud, dtype: torch.dtype = torch.float32,
                   device: torch.device | str | None = None) -> "Splats":
        """Tensors of a preprocessed :class:`SplatCloud` (world coordinates: ``origin + positions``)."""
        if cloud.u is None or cloud.v is None:
            raise InputError("the splat cloud has no tangent axes (preprocess it first)")

        def t(a: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.asarray(a, dtype=np.float64), dtype=dtype, device=device)

        colors = cloud.colors if cloud.colors is not None else np.full((len(cloud), 3), DEFAULT_ALBEDO)
        return cls(positions=t(np.asarray(cloud.positions, np.float64) + np.asarray(cloud.origin, np.float64)),
                   u=t(cloud.u), v=t(cloud.v), colors=t(colors),
                   normals=t(cloud.normals) if cloud.normals is not None else None)

    def to_cloud(self) -> SplatCloud:
        """A float32 :class:`SplatCloud` of the splats (opacity as the attribute ``opacity`` when set)."""
        def a(x: torch.Tensor) -> np.ndarray:
            return x.detach().cpu().numpy().astype(np.float64)

        u, v = a(self.u), a(self.v)
        n = a(self.normals) if self.normals is not None else np.cross(u, v)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        attributes = {"opacity": a(self.opacity).astype(np.float32)} if self.opacity is not None else {}
        return SplatCloud(a(self.positions), n, np.clip(a(self.colors), 0.0, 1.0), u, v, attributes=attributes)


def tangent_axes(normals: torch.Tensor, radii: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Circular splats' axes ``(u, v)`` (N, 3) from (N, 3) normals (any length) and (N,) radii, differentiably.

    ``u`` is the normal crossed with the coordinate axis it is least aligned with, so the frame is smooth
    wherever that choice does not switch.
    """
    n = normals / torch.linalg.vector_norm(normals, dim=-1, keepdim=True)
    axis = torch.argmin(n.detach().abs(), dim=-1)
    e = torch.nn.functional.one_hot(axis, 3).to(n.dtype)
    u = torch.linalg.cross(n, e, dim=-1)
    u = u / torch.linalg.vector_norm(u, dim=-1, keepdim=True)
    v = torch.linalg.cross(n, u, dim=-1)
    return u * radii[:, None], v * radii[:, None]


def rotation_from_vector(omega: torch.Tensor) -> torch.Tensor:
    """(3, 3) rotation ``exp([omega]_x)`` of a rotation vector (radians), differentiable everywhere."""
    zero = torch.zeros((), dtype=omega.dtype, device=omega.device)
    k = torch.stack([torch.stack([zero, -omega[2], omega[1]]), torch.stack([omega[2], zero, -omega[0]]),
                     torch.stack([-omega[1], omega[0], zero])])
    return torch.linalg.matrix_exp(k)


@dataclass
class DiffCamera:
    """A pinhole camera as tensors: ``p_cam = rotation @ p + translation``, focal length in pixels.

    Attributes:
        rotation: (3, 3) world-to-camera rotation (rows: the camera's right, up and backward axes).
        translation: (3,) world-to-camera translation, world units.
        focal: () focal length in pixels.
        width, height: image size in pixels.
        near, far: splats whose ellipse lies wholly outside [near, far] (camera depth) are not drawn;
            None: no limit (near: the eye).
    """

    rotation: torch.Tensor
    translation: torch.Tensor
    focal: torch.Tensor
    width: int
    height: int
    near: float | None = None
    far: float | None = None

    @classmethod
    def from_camera(cls, camera: Camera, dtype: torch.dtype = torch.float32,
                    device: torch.device | str | None = None) -> "DiffCamera":
        """The tensors of a :class:`~surfsplat.camera.Camera` (its view matrix and focal length)."""
        m = camera.view_matrix
        return cls(torch.as_tensor(m[:3, :3], dtype=dtype, device=device),
                   torch.as_tensor(m[:3, 3], dtype=dtype, device=device),
                   torch.as_tensor(camera.focal_px, dtype=dtype, device=device),
                   camera.width, camera.height, camera.near, camera.far)

    def moved(self, omega: torch.Tensor, delta: torch.Tensor) -> "DiffCamera":
        """The camera turned by the rotation vector ``omega`` (radians, camera axes) and shifted by ``delta``
        (camera axes, world units): ``p_cam' = exp([omega]) p_cam + delta``. Pose gradients flow to both."""
        r = rotation_from_vector(omega)
        return replace(self, rotation=r @ self.rotation, translation=r @ self.translation + delta)

    @property
    def principal(self) -> tuple[float, float]:
        """Principal point (cx, cy) in window pixels: the image centre."""
        return 0.5 * self.width, 0.5 * self.height
