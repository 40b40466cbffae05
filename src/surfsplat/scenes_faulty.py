"""Raw point clouds with the faults of real scans, on a known surface (tests and benchmarks).

Every generator returns a :class:`FaultyCloud`: raw points (positions, colors; no normals, no
splat axes: :func:`surfsplat.preprocess` must size them) whose true surface is the square
``[0, side] x [0, side]`` of the plane ``z = 0``, plus the faults of one kind of real input:

* :func:`stray_points`: single points floating off the surface (photogrammetric noise, multipath),
* :func:`stray_clusters`: small isolated groups of points (floaters of a photogrammetric scan),
* :func:`scan_lines`: airborne-LiDAR-like scan lines, points much denser along a line than across,
* :func:`tree`: a noisy volume of random points above the plane (vegetation),
* :func:`duplicates`: points stored twice or more (mesh vertices at texture seams, merged scans),
* :func:`faulty_scan`: all of them at once,
* :func:`aerial`: an airborne scan of a block: ground, gable roofs and trees, with LAS-like
  ``classification`` and ``intensity`` attributes (its surfaces are the ground and the roofs).

The surface is sampled uniformly at random (the hardest case for hole-free splats) or on a
jittered grid; ``spacing`` is the nominal sample spacing ``1 / sqrt(density)`` (model units).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cloud import SplatCloud
from .errors import InputError

#: Color of the surface samples (a light stone) and of the faults (dark: they show up as stains).
SURFACE_COLOR = (0.85, 0.8, 0.7)
FAULT_COLOR = (0.15, 0.15, 0.15)


@dataclass(frozen=True)
class FaultyCloud:
    """Raw points on the square ``[0, side]^2`` of the plane ``z = 0`` plus faults.

    Attributes:
        cloud: the raw points (positions and colors only), float32, model units.
        surface: (N,) bool, True for the samples of the plane (faults are False; a duplicate of a
            surface sample is a surface sample).
        side: side of the square footprint of the plane, model units.
        spacing: nominal sample spacing of the plane, ``1 / sqrt(samples per unit area)``
            (for scan lines: the spacing along a line), model units.
        name: a short label for tables.
        duplicates: how many points are copies (exact or within ``1e-6 * spacing``) of an earlier one.
    """

    cloud: SplatCloud
    surface: np.ndarray
    side: float
    spacing: float
    name: str
    duplicates: int = 0


def _plane(n: int, side: float, rng, sampling: str) -> np.ndarray:
    """(n', 3) float64 samples of the square, uniform random or on a jittered grid (n' ~ n)."""
    if sampling == "random":
        xy = rng.uniform(0.0, side, size=(n, 2))
    elif sampling == "jittered":
        m = max(2, int(round(np.sqrt(n))))
        step = side / m
        g = (np.arange(m) + 0.5) * step
        x, y = np.meshgrid(g, g)
        xy = np.stack([x.ravel(), y.ravel()], axis=1) + rng.uniform(-0.3, 0.3, size=(m * m, 2)) * step
    else:
        raise InputError(f"sampling must be 'random' or 'jittered', got {sampling!r}")
    return np.column_stack([xy, np.zeros(len(xy))])


def _assemble(parts: list[tuple[np.ndarray, bool]], side: float, spacing: float, name: str,
              rng, duplicates: int = 0) -> FaultyCloud:
    """Shuffle the (points, is_surface) parts into one FaultyCloud (faults spread through the file order)."""
    pts = np.concatenate([p for p, _ in parts])
    surface = np.concatenate([np.full(len(p), s) for p, s in parts])
    order = rng.permutation(len(pts))
    pts, surface = pts[order], surface[order]
    colors = np.where(surface[:, None], np.asarray(SURFACE_COLOR, np.float32), np.asarray(FAULT_COLOR, np.float32))
    return FaultyCloud(SplatCloud(pts.astype(np.float32), colors=colors), surface, float(side), float(spacing), name,
                       int(duplicates))


def _check(n: int, side: float) -> None:
    if n < 16:
        raise InputError(f"need at least 16 surface samples, got {n}")
    if not side > 0:
        raise InputError(f"side must be > 0, got {side}")


def _off_surface(m: int, side: float, spacing: float, rng, lo: float = 3.0) -> np.ndarray:
    """(m, 3) points over the footprint at heights between ``lo`` spacings and a fifth of the side, above or below."""
    xy = rng.uniform(0.0, side, size=(m, 2))
    hi = max(lo * spacing * 2, 0.2 * side)
    z = rng.uniform(lo * spacing, hi, size=m) * rng.choice([-1.0, 1.0], size=m)
    return np.column_stack([xy, z])


def stray_points(n: int = 20_000, fraction: float = 0.01, side: float = 1.0, seed: int = 0,
                 sampling: str = "random") -> FaultyCloud:
    """A plane of ``n`` samples plus ``fraction * n`` single stray points.

    Stray points are uniform over the footprint at heights of 3 spacings to ``side / 5`` above or
    below the plane: each is alone, its neighbours are all on the plane, far away.
    """
    _check(n, side)
    rng = np.random.default_rng(seed)
    plane = _plane(n, side, rng, sampling)
    spacing = side / np.sqrt(len(plane))
    stray = _off_surface(int(round(fraction * n)), side, spacing, rng)
    return _assemble([(plane, True), (stray, False)], side, spacing, f"stray points {fraction:.0%}", rng)


def stray_clusters(n: int = 20_000, clusters: int = 40, size: int = 3, side: float = 1.0, seed: int = 0,
                   sampling: str = "random") -> FaultyCloud:
    """A plane of ``n`` samples plus ``clusters`` isolated groups of ``size`` points.

    The points of a group lie within half a spacing of each other (a floater of a
    photogrammetric scan); groups float 3 spacings to ``side / 5`` off the plane.
    """
    _check(n, side)
    if size < 1:
        raise InputError(f"size must be >= 1, got {size}")
    rng = np.random.default_rng(seed)
    plane = _plane(n, side, rng, sampling)
    spacing = side / np.sqrt(len(plane))
    centers = _off_surface(clusters, side, spacing, rng)
    groups = np.repeat(centers, size, axis=0) + rng.uniform(-0.25, 0.25, size=(clusters * size, 3)) * spacing
    return _assemble([(plane, True), (groups, False)], side, spacing, f"clusters of {size}", rng)


def scan_lines(lines: int = 40, ratio: float = 5.0, side: float = 1.0, seed: int = 0, noise: float = 0.02,
               wobble: float = 0.1) -> FaultyCloud:
    """Airborne-LiDAR-like scan lines: ``lines`` lines across the square, ``ratio`` times denser along than across.

    Lines run along x, ``side / lines`` apart in y; along a line the points are ``spacing =
    side / lines / ratio`` apart (jittered by a tenth of that). Each line wobbles in y by
    ``wobble`` line gaps (a slow sine, as a swinging mirror draws it) and every point has
    Gaussian height noise of ``noise`` spacings.
    """
    if lines < 2 or not ratio >= 1:
        raise InputError(f"need lines >= 2 and ratio >= 1, got {lines}, {ratio}")
    rng = np.random.default_rng(seed)
    gap = side / lines
    spacing = gap / ratio
    per_line = int(np.floor(side / spacing))
    x = (np.arange(per_line) + 0.5) * spacing
    rows = []
    for j in range(lines):  # one row of points per scan line (few lines: not a per-point loop)
        xj = x + rng.uniform(-0.1, 0.1, size=per_line) * spacing
        phase = rng.uniform(0, 2 * np.pi)
        yj = (j + 0.5) * gap + wobble * gap * np.sin(2 * np.pi * xj / side + phase)
        rows.append(np.column_stack([xj, yj, rng.normal(scale=noise * spacing, size=per_line)]))
    plane = np.concatenate(rows)
    return _assemble([(plane, True)], side, spacing, f"scan lines {ratio:g}:1", rng)


def tree(n: int = 20_000, crown: int = 3_000, side: float = 1.0, seed: int = 0,
         sampling: str = "random") -> FaultyCloud:
    """A plane of ``n`` samples plus a noisy 'tree': ``crown`` random points filling a ball above it.

    The ball (radius ``side / 6``) is centered over the middle of the square, its bottom 5
    spacings above the plane; a trunk of ``crown // 20`` points (a noisy vertical line) joins it
    to the ground. Neither is a surface: the points of a neighbourhood there are not planar.
    """
    _check(n, side)
    rng = np.random.default_rng(seed)
    plane = _plane(n, side, rng, sampling)
    spacing = side / np.sqrt(len(plane))
    radius = side / 6
    d = rng.normal(size=(crown, 3))
    d *= (radius * rng.uniform(size=crown) ** (1 / 3) / np.linalg.norm(d, axis=1))[:, None]
    ball = d + np.array([side / 2, side / 2, radius + 5 * spacing])
    m = max(2, crown // 20)
    trunk = np.column_stack([side / 2 + rng.normal(scale=0.5 * spacing, size=m),
                             side / 2 + rng.normal(scale=0.5 * spacing, size=m),
                             rng.uniform(spacing, 5 * spacing, size=m)])
    return _assemble([(plane, True), (ball, False), (trunk, False)], side, spacing, "tree over a plane", rng)


def duplicates(n: int = 20_000, fraction: float = 0.2, side: float = 1.0, seed: int = 0,
               sampling: str = "random", near: float = 1e-6) -> FaultyCloud:
    """A plane of ``n`` samples, ``fraction`` of them stored two to four times.

    Half the copies are exact; the other half are moved by up to ``near`` spacings (float
    rounding of a merged scan). All count as duplicates (``FaultyCloud.duplicates``).
    """
    _check(n, side)
    rng = np.random.default_rng(seed)
    plane = _plane(n, side, rng, sampling)
    spacing = side / np.sqrt(len(plane))
    chosen = rng.choice(len(plane), size=int(round(fraction * len(plane))), replace=False)
    copies = np.repeat(chosen, rng.integers(1, 4, size=len(chosen)))
    extra = plane[copies].copy()
    moved = rng.uniform(size=len(extra)) < 0.5
    extra[moved, :2] += rng.uniform(-near, near, size=(int(moved.sum()), 2)) * spacing / np.sqrt(2)
    return _assemble([(plane, True), (extra, True)], side, spacing, f"duplicates {fraction:.0%}", rng, len(extra))


def faulty_scan(lines: int = 60, ratio: float = 5.0, side: float = 1.0, seed: int = 0) -> FaultyCloud:
    """Everything at once on scan lines: 1 % stray points, clusters of 3, a tree, 10 % duplicated points."""
    base = scan_lines(lines, ratio, side, seed)
    rng = np.random.default_rng(seed + 1)
    pts = base.cloud.positions.astype(np.float64)
    spacing = base.spacing
    n = len(pts)
    gap = side / lines
    stray = _off_surface(n // 100, side, gap, rng)
    centers = _off_surface(max(1, n // 1000), side, gap, rng)
    groups = np.repeat(centers, 3, axis=0) + rng.uniform(-0.25, 0.25, size=(3 * len(centers), 3)) * gap
    d = rng.normal(size=(n // 20, 3))
    radius = side / 8
    d *= (radius * rng.uniform(size=len(d)) ** (1 / 3) / np.linalg.norm(d, axis=1))[:, None]
    ball = d + np.array([side / 3, side / 3, radius + 3 * gap])
    copies = pts[rng.choice(n, size=n // 10, replace=False)]
    return _assemble([(pts, True), (copies, True), (stray, False), (groups, False), (ball, False)], side, spacing,
                     f"faulty scan lines {ratio:g}:1", rng, len(copies))


#: ASPRS LAS classes of :func:`aerial`'s points, and their colors.
GROUND, HIGH_VEGETATION, BUILDING = 2, 5, 6
AERIAL_COLORS = {GROUND: SURFACE_COLOR, BUILDING: (0.72, 0.36, 0.3), HIGH_VEGETATION: (0.25, 0.5, 0.2)}


def aerial(n: int = 40_000, houses: int = 6, trees: int = 8, side: float = 100.0, seed: int = 0) -> FaultyCloud:
    """An airborne LiDAR block: ``n`` ground samples on ``[0, side]^2`` (z = 0), ``houses`` gable
    roofs and ``trees`` trees, one per cell of a 4 x 4 grid (so at most 16 of them together).

    A house cell holds a roof of 0.5 x 0.36 cells, eaves at 0.16 cells, 30 degree slopes, sampled as
    densely as the ground (per true area), and walls at half that density; the ground under a roof
    is not seen (no samples). A
    tree is a ball crown of radius 0.12 cells (random points in its volume, as many as its surface
    would get) on a trunk, over ground that stays sampled (the beams pass between the leaves).
    Attributes: ``classification`` (uint8, ASPRS: 2 ground, 6 building, 5 high vegetation) and
    ``intensity`` (uint16: 800, 2000, 400 with 10 % noise); colors by class (:data:`AERIAL_COLORS`).
    ``surface`` marks the ground and roof samples; ``spacing`` is the ground's. Model units.
    """
    if not (houses >= 0 and trees >= 0 and houses + trees <= 16):
        raise InputError(f"houses + trees must be within 0..16 (one per cell of a 4 x 4 grid), got {houses} + {trees}")
    _check(n, side)
    rng = np.random.default_rng(seed)
    spacing = side / np.sqrt(n)
    cell = side / 4.0
    order = rng.permutation(16)
    corners = np.column_stack([order % 4, order // 4]).astype(np.float64) * cell
    house_at, tree_at = corners[:houses] + cell / 2, corners[houses:houses + trees] + cell / 2
    half_w, half_d, eave, slope = 0.25 * cell, 0.18 * cell, 0.16 * cell, np.radians(30.0)
    ground = rng.uniform(0.0, side, size=(n, 2))
    under = np.zeros(n, dtype=bool)
    for c in house_at:
        under |= (np.abs(ground[:, 0] - c[0]) <= half_w) & (np.abs(ground[:, 1] - c[1]) <= half_d)
    ground = np.column_stack([ground[~under], np.zeros(int((~under).sum()))])
    # roofs: two planes meeting at a ridge along x, z falling with |y - center| at the slope
    per_roof = int(round(2 * half_w * 2 * half_d / np.cos(slope) / spacing ** 2))
    xy = rng.uniform(-1.0, 1.0, size=(houses, per_roof, 2)) * (half_w, half_d)
    z = eave + (half_d - np.abs(xy[..., 1])) * np.tan(slope)
    roofs = np.concatenate([xy + house_at[:, None, :], z[..., None]], axis=2).reshape(-1, 3)
    # walls (seen at grazing angles: half the ground's density), up to the eaves (and the gables)
    perimeter = 4 * (half_w + half_d)
    per_wall = int(round(0.5 * perimeter * eave / spacing ** 2))
    t = rng.uniform(0.0, perimeter, size=(houses, per_wall))
    along = np.select([t < 2 * half_w, t < 2 * half_w + 2 * half_d, t < 4 * half_w + 2 * half_d],
                      [t - half_w, half_w, 3 * half_w + 2 * half_d - t], -half_w)
    across = np.select([t < 2 * half_w, t < 2 * half_w + 2 * half_d, t < 4 * half_w + 2 * half_d],
                       [-half_d, t - 2 * half_w - half_d, half_d], 4 * half_w + 3 * half_d - t)
    top = eave + np.where(np.abs(along) >= half_w, (half_d - np.abs(across)) * np.tan(slope), 0.0)
    walls = np.stack([along, across, rng.uniform(size=(houses, per_wall)) * top], axis=2)
    walls[..., :2] += house_at[:, None, :]
    roofs = np.concatenate([roofs, walls.reshape(-1, 3)])
    radius = 0.12 * cell
    per_crown = int(round(4 * np.pi * radius ** 2 / spacing ** 2))
    d = rng.normal(size=(trees, per_crown, 3))
    d *= (radius * rng.uniform(size=(trees, per_crown, 1)) ** (1 / 3) / np.linalg.norm(d, axis=2, keepdims=True))
    crown_z = eave + 1.2 * radius
    crowns = (d + np.column_stack([tree_at, np.full(trees, crown_z)])[:, None, :]).reshape(-1, 3)
    per_trunk = max(2, per_crown // 20)
    trunk_xy = np.repeat(tree_at, per_trunk, axis=0) + rng.normal(scale=0.5 * spacing, size=(trees * per_trunk, 2))
    trunks = np.concatenate([trunk_xy, rng.uniform(0.0, crown_z - radius, size=(trees * per_trunk, 1))], axis=1)
    pts = np.concatenate([ground, roofs, crowns, trunks])
    cls = np.repeat(np.array([GROUND, BUILDING, HIGH_VEGETATION, HIGH_VEGETATION], dtype=np.uint8),
                    [len(ground), len(roofs), len(crowns), len(trunks)])
    order = rng.permutation(len(pts))
    pts, cls = pts[order], cls[order]
    base = np.select([cls == GROUND, cls == BUILDING], [800.0, 2000.0], 400.0)
    intensity = np.clip(base * (1.0 + 0.1 * rng.normal(size=len(pts))), 0, 65535).astype(np.uint16)
    palette = np.zeros((256, 3), dtype=np.float32)
    for code, color in AERIAL_COLORS.items():
        palette[code] = color
    cloud = SplatCloud(pts.astype(np.float32), colors=palette[cls],
                       attributes={"classification": cls, "intensity": intensity})
    return FaultyCloud(cloud, cls != HIGH_VEGETATION, float(side), float(spacing), "aerial block")
