"""Procedural demo scenes: splat models with exact normals and covering splats.

Every scene is a ready-to-render SplatCloud (no preprocessing needed) built
from an analytic surface, so renderings can be held against exact ground truth.
"""

from __future__ import annotations

import numpy as np

from .cloud import NO_CLIP, SplatCloud
from .errors import InputError
from .frames import tangent_frame

GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def checker_color(s: np.ndarray, t: np.ndarray, squares: float,
                  dark=(0.1, 0.1, 0.12), light=(0.95, 0.9, 0.8)) -> np.ndarray:
    """(N, 3) checkerboard colors at texture coordinates (s, t) in [0, 1] with ``squares`` per side."""
    odd = (np.floor(s * squares) + np.floor(t * squares)) % 2 == 1
    return np.where(odd[:, None], np.asarray(light, np.float32), np.asarray(dark, np.float32)).astype(np.float32)


def sphere(n: int = 100_000, radius: float = 1.0, center=(0.0, 0.0, 0.0), color=None,
           coverage: float = 1.0) -> SplatCloud:
    """A sphere of ``n`` circular splats on a Fibonacci spiral (near-hexagonal spacing).

    Splat radius = ``coverage * sqrt(area per point)``: 1.6x the covering radius
    of a hexagonal lattice of the same density at ``coverage`` = 1.
    ``color``: None (0.8 gray), an RGB triple, or "bands" for latitude bands.
    """
    if n < 4:
        raise InputError("a sphere needs at least 4 points")
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = i * GOLDEN_ANGLE
    normals = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    positions = np.asarray(center) + radius * normals
    splat_r = coverage * radius * np.sqrt(4.0 * np.pi / n)
    t1, t2 = tangent_frame(normals)
    colors = None
    if isinstance(color, str) and color == "bands":
        colors = checker_color(np.arccos(z) / np.pi, np.zeros(n), 8, (0.85, 0.3, 0.2), (0.9, 0.85, 0.7))
    elif color is not None:
        colors = np.broadcast_to(np.asarray(color, np.float32), (n, 3))
    return SplatCloud(positions, normals, colors, t1 * splat_r, t2 * splat_r)


def checkerboard(n_side: int = 400, size: float = 2.0, squares: int = 8, coverage: float = 1.0) -> SplatCloud:
    """A square plane (z = 0, side ``size``) of n_side^2 splats on a grid, colored by a checkerboard.

    Splat radius = ``coverage * spacing / sqrt(2) * 1.1``: the grid cells are covered.
    """
    if n_side < 2:
        raise InputError("the checkerboard needs at least 2 points per side")
    s = (np.arange(n_side) + 0.5) / n_side
    ss, tt = (a.ravel() for a in np.meshgrid(s, s))
    positions = np.stack([(ss - 0.5) * size, (tt - 0.5) * size, np.zeros_like(ss)], axis=1)
    count = len(ss)
    spacing = size / n_side
    radius = coverage * 1.1 * spacing / np.sqrt(2.0)
    normals = np.tile([0.0, 0.0, 1.0], (count, 1))
    u = np.tile([radius, 0.0, 0.0], (count, 1))
    v = np.tile([0.0, radius, 0.0], (count, 1))
    return SplatCloud(positions, normals, checker_color(ss, tt, squares), u, v)


def torus(n_major: int = 400, n_minor: int = 160, major: float = 1.0, minor: float = 0.4,
          stripes: int = 12) -> SplatCloud:
    """A torus around the z axis with elliptical splats covering its (theta, phi) grid cells.

    Each splat's semi-axes are the local cell sizes / sqrt(2) (which covers the
    cell exactly) times 1.15 for curvature; colored in stripes around the tube.
    """
    if n_major < 3 or n_minor < 3 or not (0 < minor < major):
        raise InputError("torus needs n_major, n_minor >= 3 and 0 < minor < major")
    theta_grid, phi_grid = np.meshgrid(np.arange(n_major) * 2 * np.pi / n_major,
                                       np.arange(n_minor) * 2 * np.pi / n_minor)
    theta, phi = theta_grid.ravel(), phi_grid.ravel()
    ring = major + minor * np.cos(phi)
    positions = np.stack([ring * np.cos(theta), ring * np.sin(theta), minor * np.sin(phi)], axis=1)
    normals = np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)], axis=1)
    along_theta = np.stack([-np.sin(theta), np.cos(theta), np.zeros_like(theta)], axis=1)
    along_phi = np.cross(normals, along_theta)
    scale = 1.15 / np.sqrt(2.0)
    u = along_theta * (scale * ring * 2 * np.pi / n_major)[:, None]
    v = along_phi * (scale * minor * 2 * np.pi / n_minor)
    colors = checker_color(theta / (2 * np.pi), np.zeros_like(theta), stripes, (0.2, 0.45, 0.8), (0.95, 0.75, 0.3))
    return SplatCloud(positions, normals, colors, u, v)


FACE_COLORS = np.array([[0.85, 0.25, 0.2], [0.2, 0.7, 0.3], [0.25, 0.4, 0.85],
                        [0.9, 0.75, 0.2], [0.7, 0.3, 0.75], [0.2, 0.75, 0.8]], dtype=np.float32)


def cube(n_side: int = 120, size: float = 1.0, texture: bool = True, coverage: float = 1.0) -> SplatCloud:
    """An axis-aligned cube (edge ``size``, centered at the origin) of 6 n_side^2 splats with exact clip lines.

    Each face is a grid of circular splats (radius as in :func:`checkerboard`).
    A splat that reaches over an edge gets the clip line of the neighbouring
    face's plane, two at a corner (Zwicker 2004, sec. 5 and figure 5), in the
    convention of Botsch 2004: the part of the splat outside the cube, where
    ``a s + b t + c < 0``, is cut away. ``texture``: a checkerboard of
    per-face colors (else one flat color per face, see :data:`FACE_COLORS`).
    """
    if n_side < 2:
        raise InputError("the cube needs at least 2 points per face side")
    h = 0.5 * size
    spacing = size / n_side
    radius = coverage * 1.1 * spacing / np.sqrt(2.0)
    g = (np.arange(n_side) + 0.5) * spacing - h
    ga, gb = (x.ravel() for x in np.meshgrid(g, g))
    axes = np.eye(3)
    positions, normals, u, v, colors, lines = [], [], [], [], [], []
    for face in range(6):  # six faces, not a loop over points
        k, sign = face // 2, 1.0 - 2.0 * (face % 2)
        n = axes[k] * sign
        e1, e2 = axes[(k + 1) % 3], axes[(k + 2) % 3]
        if sign < 0:
            e1, e2 = e2, e1  # keep e1 x e2 = n
        count = len(ga)
        positions.append(h * n + ga[:, None] * e1 + gb[:, None] * e2)
        normals.append(np.tile(n, (count, 1)))
        u.append(np.tile(e1 * radius, (count, 1)))
        v.append(np.tile(e2 * radius, (count, 1)))
        base = FACE_COLORS[face]
        if texture:
            colors.append(checker_color((ga + h) / size, (gb + h) / size, 6, base * 0.45, 0.55 + base * 0.45))
        else:
            colors.append(np.tile(base, (count, 1)))
        # the neighbouring faces' planes: along +-e1 (coordinate ga) and +-e2 (coordinate gb);
        # inside is coord * side <= h, i.e. (h - side coord) - s side r [- t side r] >= 0
        face_lines = np.tile(NO_CLIP, (count, 2, 1))
        used = np.zeros(count, dtype=int)
        for coord, column in ((ga, 0), (gb, 1)):
            for side in (1.0, -1.0):
                crosses = h - side * coord < radius
                line = np.zeros((count, 3))
                line[:, column] = -side * radius / radius  # (s, t) are in units of the radius
                line[:, 2] = (h - side * coord) / radius
                rows = np.flatnonzero(crosses)
                face_lines[rows, used[rows]] = line[rows]
                used[rows] += 1
        lines.append(face_lines)
    return SplatCloud(np.concatenate(positions), np.concatenate(normals), np.concatenate(colors),
                      np.concatenate(u), np.concatenate(v), clip_lines=np.concatenate(lines))


def _add_clip_line(lines: np.ndarray, used: np.ndarray, rows: np.ndarray, line: np.ndarray) -> None:
    """Store ``line`` (len(rows), 3) in the next free of the two clip-line slots of ``rows``."""
    free = used[rows] < 2
    rows, line = rows[free], line[free]
    lines[rows, used[rows]] = line
    used[rows] += 1


def sphere_cube(n: int = 150_000, half: float = 0.5, radius: float = 0.65) -> SplatCloud:
    """CSG intersection of a cube (half edge ``half``) and a sphere (``radius``), both centered at 0.

    With half < radius < half * sqrt(2) the six faces are flat disks and the
    cube's edges are rounded by the sphere: flat and curved surfaces meeting at
    sharp circular edges, every splat there clipped by the other surface's
    tangent plane (Zwicker 2004, sec. 5 and figure 8). About ``n`` splats in
    all, with the same density on both surfaces.
    """
    if not (half < radius < half * np.sqrt(2.0)):
        raise InputError("sphere_cube needs half < radius < half * sqrt(2)")
    # sphere part: a Fibonacci sphere at the density of n splats over the whole solid's area
    rho = np.sqrt(radius**2 - half**2)  # radius of each face's disk
    cap = 2 * np.pi * radius * (radius - half)  # area of the sphere beyond one face plane
    area_sphere = 4 * np.pi * radius**2 - 6 * cap
    area_faces = 6 * np.pi * rho**2
    spacing = np.sqrt((area_sphere + area_faces) / n)
    shell = sphere(int(4 * np.pi * radius**2 / spacing**2), radius=radius)
    # Splats whose disks reach into the solid are kept (and clipped), not only those
    # centered inside, so the surface next to a sharp edge is covered too.
    keep = (np.abs(shell.positions) <= half + shell.radii[:, None]).all(axis=1)
    shell = shell.subset(keep)
    # face parts: square grids within the disks, grown by a splat radius likewise
    splat_r = 1.1 * spacing / np.sqrt(2.0)
    g = np.arange(-rho - splat_r, rho + splat_r + spacing, spacing)
    ga, gb = (x.ravel() for x in np.meshgrid(g, g))
    disk = ga**2 + gb**2 <= (rho + splat_r) ** 2
    ga, gb = ga[disk], gb[disk]
    axes = np.eye(3)
    assert shell.normals is not None and shell.u is not None and shell.v is not None
    pos, nor, uu, vv = [shell.positions], [shell.normals], [shell.u], [shell.v]
    for face in range(6):  # six faces, not a loop over points
        k, sign = face // 2, 1.0 - 2.0 * (face % 2)
        nf = axes[k] * sign
        e1, e2 = axes[(k + 1) % 3], axes[(k + 2) % 3]
        if sign < 0:
            e1, e2 = e2, e1
        pos.append(half * nf + ga[:, None] * e1 + gb[:, None] * e2)
        nor.append(np.tile(nf, (len(ga), 1)))
        uu.append(np.tile(e1 * splat_r, (len(ga), 1)))
        vv.append(np.tile(e2 * splat_r, (len(ga), 1)))
    positions, normals, u, v = (np.concatenate(x).astype(np.float64) for x in (pos, nor, uu, vv))
    count, n_shell = len(positions), len(shell)
    lines = np.tile(NO_CLIP, (count, 2, 1)).astype(np.float64)
    used = np.zeros(count, dtype=int)
    r = np.maximum(np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1))
    on_shell = np.arange(count) < n_shell
    # sphere splats: the face planes n.x = half; inside is half - n.(p + s u + t v) >= 0
    for face in range(6):
        nf = axes[face // 2] * (1.0 - 2.0 * (face % 2))
        gap = half - positions @ nf
        rows = np.flatnonzero(on_shell & (gap < r))
        line = np.stack([-(u[rows] @ nf), -(v[rows] @ nf), gap[rows]], axis=1)
        _add_clip_line(lines, used, rows, line)
    # face splats: the sphere's tangent plane at the nearest point b of the face's rim circle;
    # inside is radius^2 - b.(p + s u + t v) >= 0
    face_normal = normals
    in_plane = positions - (positions * face_normal).sum(1, keepdims=True) * face_normal
    dist = np.linalg.norm(in_plane, axis=1)
    rows = np.flatnonzero(~on_shell & (rho - dist < r))
    b = half * face_normal[rows] + rho * in_plane[rows] / np.maximum(dist[rows, None], 1e-12)
    line = np.stack([-(b * u[rows]).sum(1), -(b * v[rows]).sum(1), radius**2 - (b * positions[rows]).sum(1)], axis=1)
    _add_clip_line(lines, used, rows, line)
    shell_color, face_color = np.asarray([0.9, 0.55, 0.2], np.float32), np.asarray([0.35, 0.55, 0.85], np.float32)
    colors = np.where(on_shell[:, None], shell_color, face_color)
    return SplatCloud(positions, normals, colors, u, v, clip_lines=lines)


SCENES = {
    "sphere": lambda: sphere(100_000, color="bands"),
    "checkerboard": checkerboard,
    "torus": torus,
    "cube": cube,
    "csg": sphere_cube,
}


def demo_scene(name: str = "torus") -> SplatCloud:
    """A built-in procedural scene by name: one of :data:`SCENES` (modelled y-up: ``up`` +y)."""
    try:
        return SCENES[name]().replace(up=(0.0, 1.0, 0.0))
    except KeyError:
        raise InputError(f"unknown demo scene {name!r}; choose one of {', '.join(sorted(SCENES))}") from None
