"""Stratified surface samples (surfsplat.geometry.sampling.stratified_barycentrics) and the splat radius
derived from their spacing (spacing_radius), which replaces a neighbour search for sampled meshes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from surfsplat import InputError
from surfsplat.geometry.sampling import (SLIVER_COVERAGE, SPACING_COVERAGE, face_coverage, sample_mesh,
                                         spacing_radius, stratified_barycentrics, surface_splats)
from surfsplat.geometry.splats import CIRCLE_COVERAGE, SAMPLE_COVERAGE
from surfsplat.io import Mesh

#: a smooth mesh's spacing radius, shrunk as its k-neighbour radius was (geometry.splats.SAMPLE_COVERAGE)
SMOOTH = SAMPLE_COVERAGE / CIRCLE_COVERAGE


def fan_square(slivers: int = 40) -> Mesh:
    """The unit square in the z = 0 plane as a fan of ``slivers`` thin triangles from one corner,
    the long thin triangles of a CAD tessellation (aspect ratios up to ~2 slivers)."""
    rim = np.concatenate([np.column_stack([np.ones(slivers // 2 + 1), np.linspace(0, 1, slivers // 2 + 1)]),
                          np.column_stack([np.linspace(1, 0, slivers // 2 + 1)[1:], np.ones(slivers // 2)])])
    vertices = np.column_stack([np.vstack([[0.0, 0.0], rim]), np.zeros(len(rim) + 1)])
    faces = np.column_stack([np.zeros(len(rim) - 1, int), np.arange(1, len(rim)), np.arange(2, len(rim) + 1)])
    return Mesh(vertices, faces)


def grid_square(cells: int = 8) -> Mesh:
    """The unit square as ``cells`` x ``cells`` squares, each cut into two right isosceles triangles."""
    g = np.linspace(0.0, 1.0, cells + 1)
    vertices = np.column_stack([np.repeat(g, cells + 1), np.tile(g, cells + 1), np.zeros((cells + 1) ** 2)])
    i, j = np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij")
    a = (i * (cells + 1) + j).ravel()
    b, c, d = a + cells + 1, a + cells + 2, a + 1
    return Mesh(vertices, np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])]))


def points_of(mesh: Mesh, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    return np.einsum("nk,nkd->nd", bary, mesh.vertices.astype(np.float64)[mesh.faces[face]])


def test_every_face_gets_its_share_within_two_samples():
    mesh = fan_square()
    areas = mesh.face_areas()
    n = 10_007
    face, bary = stratified_barycentrics(areas, n, np.random.default_rng(3))
    assert face.shape == (n,) and bary.shape == (n, 3)
    assert np.all(np.diff(face) >= 0)                                        # sorted by face
    counts = np.bincount(face, minlength=len(areas))
    # the face's stretch of the cumulative area holds whole strata and at most two partial ones (each giving
    # 0 or 1 sample): off by less than 2 (independent samples: by about sqrt(250) = 16)
    assert np.abs(counts - n * areas / areas.sum()).max() < 2.0
    assert bary.min() >= 0.0 and np.allclose(bary.sum(axis=1), 1.0)


def test_stratified_samples_are_uniform_and_even():
    """Counts in a 10 x 10 grid of the square: unbiased (the mean over seeds is the area share) and far
    more even than independent samples (whose counts spread by sqrt(100) = 10)."""
    mesh = fan_square()
    n, cells = 10_000, 10
    grids = []
    for seed in range(8):
        face, bary = stratified_barycentrics(mesh.face_areas(), n, np.random.default_rng(seed))
        p = points_of(mesh, face, bary)
        ij = np.minimum((p[:, :2] * cells).astype(int), cells - 1)
        grids.append(np.bincount(ij[:, 0] * cells + ij[:, 1], minlength=cells * cells))
    grids = np.array(grids, dtype=float)
    expected = n / cells ** 2
    assert abs(grids.mean() - expected) < 1e-9
    # mean over 8 seeds: unbiased within 4 standard errors of independent samples (10 / sqrt(8))
    assert np.abs(grids.mean(axis=0) - expected).max() < 4 * 10 / math.sqrt(8)
    assert grids.std() < 0.5 * math.sqrt(expected)


def test_poisson_coverage_formula():
    """Independent samples of density 1 / s^2 leave exp(-pi c^2) of the plane farther than c s from
    every sample (the void probability of a Poisson process), which spacing_radius documents."""
    mesh = Mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), np.array([[0, 1, 2], [0, 2, 3]]))
    n = 40_000
    p = sample_mesh(mesh, n, seed=5).positions.astype(np.float64)
    g = (np.arange(400) + 0.5) / 400
    q = np.column_stack([np.repeat(g, 400), np.tile(g, 400), np.zeros(400 * 400)])
    inner = (np.abs(q[:, :2] - 0.5) < 0.45).all(axis=1)                      # away from the border
    d = cKDTree(p).query(q[inner])[0]
    for c in (0.6, 0.8, 1.0):
        r = spacing_radius(1.0, n, c)
        assert r == pytest.approx(c * math.sqrt(1.0 / n))
        expected = math.exp(-math.pi * c * c)
        assert (d > r).mean() == pytest.approx(expected, rel=0.1)


def test_slivers_get_the_larger_coverage():
    np.testing.assert_array_equal(face_coverage(fan_square()), SLIVER_COVERAGE)      # sides over heights ~40-80
    np.testing.assert_array_equal(face_coverage(grid_square()), SPACING_COVERAGE)    # right isosceles: 2


@pytest.mark.parametrize("n", [3_000, 40_000])
@pytest.mark.parametrize("kind", ["slivers", "grid"])
def test_spacing_radius_covers_stratified_samples(n, kind):
    """No point of the square is farther than the radius from a sample: a fan of slivers at
    SLIVER_COVERAGE spacings, well-shaped triangles at SPACING_COVERAGE."""
    mesh = fan_square() if kind == "slivers" else grid_square()
    coverage = SLIVER_COVERAGE if kind == "slivers" else SPACING_COVERAGE
    g = (np.arange(500) + 0.5) / 500
    q = np.column_stack([np.repeat(g, 500), np.tile(g, 500), np.zeros(500 * 500)])
    for seed in range(3):
        face, bary = stratified_barycentrics(mesh.face_areas(), n, np.random.default_rng(seed))
        gap = cKDTree(points_of(mesh, face, bary)).query(q)[0].max()
        assert gap <= spacing_radius(1.0, n, coverage)
        assert gap > spacing_radius(1.0, n, 1.0)   # the spacing itself would not do


def test_surface_splats_radius_from_the_spacing():
    mesh = fan_square()
    splats = surface_splats(mesh, 5_000, seed=2, sharp_angle=None)
    radius = SLIVER_COVERAGE * SMOOTH * math.sqrt(1.0 / 5_000)   # a mesh without sharp edges: 0.88 of it
    np.testing.assert_allclose(np.linalg.norm(splats.u, axis=1), radius, rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(splats.v, axis=1), radius, rtol=1e-6)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", splats.u, splats.v)), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.cross(splats.u, splats.v) / radius ** 2, splats.normals, atol=1e-5)
    again = surface_splats(mesh, 5_000, seed=2, sharp_angle=None)
    np.testing.assert_array_equal(again.positions, splats.positions)
    # k: sized by the k-th neighbour (independent samples): radii vary
    by_k = surface_splats(mesh, 5_000, seed=2, sharp_angle=None, k=8)
    r = np.linalg.norm(by_k.u, axis=1)
    assert r.std() > 0.1 * r.mean()
    with pytest.raises(InputError, match="k must be"):
        surface_splats(mesh, 100, k=0)
    grid = surface_splats(grid_square(), 5_000, seed=2, sharp_angle=None)
    np.testing.assert_allclose(np.linalg.norm(grid.u, axis=1), SPACING_COVERAGE * SMOOTH * math.sqrt(1.0 / 5_000),
                               rtol=1e-6)


@pytest.mark.parametrize("shape", ["box", "cylinder"])
def test_clip_lines_skip_splats_far_from_their_faces_sides_exactly(shape):
    """Splats in planar patches farther from their face's sides than their radius are not searched for
    edges (mesh_clip_lines with ``bary``); the clip lines are the same as with the full search."""
    import trimesh

    from surfsplat.geometry import sampling
    from surfsplat.geometry.sharp import mesh_features
    from surfsplat.geometry.sharp.mesh import _far_from_edges, mesh_clip_lines

    made = trimesh.creation.box((2.0, 1.0, 0.5)) if shape == "box" else trimesh.creation.cylinder(0.5, 1.0,
                                                                                                 sections=24)
    mesh = Mesh(made.vertices, made.faces)
    n = 20_000
    cloud, face, bary = sampling._samples(mesh, n, 1, False, None, "test", stratified=True)
    radius = spacing_radius(float(mesh.face_areas().sum()), n, 1.0) * face_coverage(mesh)[face]
    splats = sampling._spaced_circles(cloud, radius, "test")
    feat = mesh_features(mesh, 30.0, boundaries=True)
    far = _far_from_edges(feat, face, bary, radius)
    assert 0.02 < far.mean() < 0.95
    if shape == "cylinder":   # the curved side is always searched
        side = np.abs(cloud.normals[:, 2]) < 0.5
        assert not far[side].any() and far[~side].any()
    full = mesh_clip_lines(mesh, face, splats.positions, splats.u, splats.v, 30.0, features=feat)
    fast = mesh_clip_lines(mesh, face, splats.positions, splats.u, splats.v, 30.0, features=feat, bary=bary)
    np.testing.assert_array_equal(fast, full)
    assert (full[far] == np.array([0, 0, 1], np.float32)).all()    # no line where none was searched
    assert (full[~far] != np.array([0, 0, 1], np.float32)).any()
