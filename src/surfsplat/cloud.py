"""SplatCloud: the one splat representation every technique renders.

A structure of arrays, float32, one row per splat (DESIGN.md). A splat is an
ellipse in 3D: center ``positions[i]``, unit ``normals[i]`` and two scaled
tangent axes ``u[i]``, ``v[i]`` (orthogonal to the normal; a circular splat of
radius r has |u| = |v| = r). A point of the splat is
``positions + s * u + t * v`` with ``s**2 + t**2 <= 1``: ``(s, t)`` are the
splat's normalized coordinates, used by clip lines and normal fields.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import InputError

#: Albedo used where the input carries no colors (linear RGB in [0, 1]).
DEFAULT_ALBEDO = 0.8

#: A clip line that keeps everything: ``0 s + 0 t + 1 >= 0``.
NO_CLIP = np.array([0.0, 0.0, 1.0], dtype=np.float32)


@dataclass
class SplatCloud:
    """Splats as a structure of float32 arrays.

    Attributes:
        positions: (N, 3) float32, model space: splat centers.
        normals: (N, 3) float32 unit vectors or None (estimated by preprocessing).
        colors: (N, 3) float32 linear RGB in [0, 1] or None (rendered 0.8 gray).
        u, v: (N, 3) float32 scaled tangent axes, model-space units, or None
            (set by preprocessing). Orthogonal to the normal.
        normal_field: (N, 2) float32 ``(alpha, beta)`` of the linear normal
            field ``n(s, t) = n + s * alpha * u_hat + t * beta * v_hat``
            (Botsch 2004, eq. 2, with ``normals`` as the center normal), or None.
        clip_lines: (N, 2, 3) float32 ``(a, b, c)`` in normalized ``(s, t)``
            coordinates; a point is kept where ``a s + b t + c >= 0``. Unused
            lines are ``(0, 0, 1)``. None when no splat is clipped.
    """

    positions: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    u: np.ndarray | None = None
    v: np.ndarray | None = None
    normal_field: np.ndarray | None = None
    clip_lines: np.ndarray | None = None

    _OPTIONAL = ("normals", "colors", "u", "v", "normal_field", "clip_lines")
    _SHAPES = {
        "positions": (3,),
        "normals": (3,),
        "colors": (3,),
        "u": (3,),
        "v": (3,),
        "normal_field": (2,),
        "clip_lines": (2, 3),
    }

    def __post_init__(self) -> None:
        for name, tail in self._SHAPES.items():
            value = getattr(self, name)
            if value is None:
                if name == "positions":
                    raise InputError("positions are required")
                continue
            arr = np.ascontiguousarray(value, dtype=np.float32)
            if name == "clip_lines" and arr.ndim == 2 and arr.shape[1] == 3:
                # one clip line per splat: pad the second with "keep all"
                arr = np.concatenate([arr[:, None, :], np.broadcast_to(NO_CLIP, arr.shape)[:, None, :]], axis=1)
            if arr.ndim != 1 + len(tail) or arr.shape[1:] != tail:
                raise InputError(f"{name} must have shape (N, {', '.join(map(str, tail))}), got {arr.shape}")
            setattr(self, name, arr)
        n = len(self.positions)
        for name in self._OPTIONAL:
            value = getattr(self, name)
            if value is not None and len(value) != n:
                raise InputError(f"{name} has {len(value)} rows but positions has {n}")

    def __len__(self) -> int:
        return len(self.positions)

    def __repr__(self) -> str:
        present = [name for name in self._OPTIONAL if getattr(self, name) is not None]
        return f"SplatCloud({len(self)} splats, with {', '.join(present) or 'positions only'})"

    # -- derived quantities -------------------------------------------------

    @property
    def has_splats(self) -> bool:
        """True when every splat has a normal and tangent axes (ready to render)."""
        return self.normals is not None and self.u is not None and self.v is not None

    @property
    def radii(self) -> np.ndarray:
        """(N,) float32 largest semi-axis of each splat, model units (needs u, v)."""
        if self.u is None or self.v is None:
            raise InputError("this SplatCloud has no splat axes yet; preprocess it first")
        return np.maximum(np.linalg.norm(self.u, axis=1), np.linalg.norm(self.v, axis=1))

    @property
    def albedo(self) -> np.ndarray:
        """(N, 3) float32 colors, or the default 0.8 gray where none are stored."""
        if self.colors is not None:
            return self.colors
        return np.full((len(self), 3), DEFAULT_ALBEDO, dtype=np.float32)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds ``(min, max)`` of the splat centers, model units."""
        return self.positions.min(axis=0), self.positions.max(axis=0)

    def subset(self, index: np.ndarray) -> "SplatCloud":
        """A new SplatCloud with the rows selected by a boolean mask or index array."""
        fields = {name: (None if getattr(self, name) is None else getattr(self, name)[index])
                  for name in ("positions",) + self._OPTIONAL}
        return SplatCloud(**fields)

    def replace(self, **changes) -> "SplatCloud":
        """A copy with some arrays replaced (validated like the constructor)."""
        return dataclasses.replace(self, **changes)

    # -- validation --------------------------------------------------------

    def validated(self, source: str = "input") -> "SplatCloud":
        """Drop invalid rows and report how many, raising if nothing is left.

        Dropped: non-finite positions (or other non-finite arrays), zero-length
        normals, and zero, negative or non-finite splat axes. Normals are
        renormalized and colors clipped to [0, 1]. ``source`` names the file or
        array in messages.
        """
        n = len(self)
        if n == 0:
            raise InputError(f"{source}: contains no points")
        keep = np.isfinite(self.positions).all(axis=1)
        reasons = {"non-finite coordinates": int(n - keep.sum())}
        if self.normals is not None:
            length = np.linalg.norm(self.normals, axis=1)
            bad = ~np.isfinite(length) | (length < 1e-12)
            reasons["zero-length or non-finite normals"] = int((bad & keep).sum())
            keep &= ~bad
        if self.u is not None and self.v is not None:
            lu = np.linalg.norm(self.u, axis=1)
            lv = np.linalg.norm(self.v, axis=1)
            cross = np.linalg.norm(np.cross(self.u, self.v), axis=1)
            bad = ~(np.isfinite(lu) & np.isfinite(lv)) | (lu <= 0) | (lv <= 0) | (cross <= 1e-12 * lu * lv)
            reasons["zero, negative or degenerate splat radii"] = int((bad & keep).sum())
            keep &= ~bad
        for name in ("colors", "normal_field", "clip_lines"):
            value = getattr(self, name)
            if value is not None:
                bad = ~np.isfinite(value.reshape(n, -1)).all(axis=1)
                reasons[f"non-finite {name.replace('_', ' ')}"] = int((bad & keep).sum())
                keep &= ~bad
        dropped = n - int(keep.sum())
        if dropped == n:
            detail = ", ".join(f"{count} with {why}" for why, count in reasons.items() if count)
            raise InputError(f"{source}: no valid points left ({detail})")
        out = self.subset(keep) if dropped else self.replace()
        if dropped:
            detail = ", ".join(f"{count} with {why}" for why, count in reasons.items() if count)
            warnings.warn(f"{source}: dropped {dropped} of {n} points ({detail})", InvalidPointsWarning, stacklevel=2)
        if out.normals is not None:
            # renormalize only rows that are not unit already, so validation is idempotent
            length = np.linalg.norm(out.normals, axis=1, keepdims=True)
            off = np.abs(length[:, 0] - 1.0) > 1e-6
            if off.any():
                out.normals = out.normals.copy()
                out.normals[off] /= length[off]
        if out.colors is not None:
            out.colors = np.clip(out.colors, 0.0, 1.0)
        return out


class InvalidPointsWarning(UserWarning):
    """Some input points were invalid and dropped; the message gives counts."""
