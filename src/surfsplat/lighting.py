"""Lighting model: directional lights, two-sided Blinn-Phong.

``c = albedo * (ka + kd * sum_l max(0, n.l)) + ks * sum_l max(0, n.h)^s`` with
``l`` the unit world direction toward each light, ``h = normalize(l + v)``,
``v`` the unit direction toward the eye; normals facing away from the viewer
are flipped first. No gamma; the result is clamped to [0, 1] on output.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError

#: Largest number of directional lights. The shaders get it as the macro MAX_LIGHTS
#: (``render.shaders.SHARED_DEFINES``): ``uniform vec3 u_light_dirs[MAX_LIGHTS]``.
MAX_LIGHTS = 4


@dataclass(frozen=True)
class Lights:
    """Directional lights and the Blinn-Phong material.

    Attributes:
        directions: world-space directions toward the lights, shape (L, 3) with
            L <= 4, or None for a headlight (from the target toward the eye).
        ambient, diffuse, specular: ka, kd, ks (unitless).
        shininess: Blinn-Phong exponent s.
        enabled: False renders unlit albedo.
    """

    directions: tuple | None = None
    ambient: float = 0.2
    diffuse: float = 0.8
    specular: float = 0.2
    shininess: float = 32.0
    enabled: bool = True

    def __post_init__(self) -> None:
        if self.directions is not None:
            d = np.asarray(self.directions, dtype=np.float64).reshape(-1, 3) if np.size(self.directions) else None
            if d is None or not (1 <= len(d) <= MAX_LIGHTS):
                raise InputError(f"between 1 and {MAX_LIGHTS} light directions are needed")
            if not np.isfinite(d).all():
                raise InputError(f"light directions must be finite and non-zero, got {self.directions!r}")
            d = d / np.maximum(np.abs(d).max(axis=1, keepdims=True), 1e-300)   # no overflow in the norm
            length = np.linalg.norm(d, axis=1)
            if (length <= 0).any():
                raise InputError(f"light directions must be finite and non-zero, got {self.directions!r}")
            object.__setattr__(self, "directions", tuple(map(tuple, d / length[:, None])))
        for name in ("ambient", "diffuse", "specular", "shininess"):
            value = float(getattr(self, name))
            if not np.isfinite(value) or value < 0:
                raise InputError(f"light {name} must be a finite non-negative number, got {value}")

    def world_directions(self, camera) -> np.ndarray:
        """(L, 3) float64 unit world directions toward the lights for this camera."""
        if self.directions is None:
            return camera.light_direction[None, :]
        return np.asarray(self.directions, dtype=np.float64)
