"""surfsplat.hierarchy: point-octree, conservative LOD splats, storage, view-dependent selection."""

from __future__ import annotations

import warnings
import zipfile
from dataclasses import fields
from typing import get_args

import numpy as np
import pytest

from surfsplat import Camera, InputError, SplatCloud, scenes
from surfsplat.geometry import preprocess
from surfsplat.hierarchy import (CONE_SHADING_MAX_ANGLE, SHADINGS, Hierarchy, LodShading,
                                 Selection, build_hierarchy, load_hierarchy, ranges_to_indices, save_hierarchy,
                                 select)
from surfsplat.hierarchy.storage import COMPACT_VERSION
from surfsplat.hierarchy.nodes import (COVARIANCE_ENTRIES, covariance_about, homogeneous_covariance,
                                       unpack_covariance)

# -- fixtures and helpers ------------------------------------------------------


@pytest.fixture(scope="module")
def sphere_h():
    """20k splats on a unit sphere (exact normals, circular splats)."""
    return build_hierarchy(scenes.sphere(20_000, coverage=1.2))


@pytest.fixture(scope="module")
def torus_h():
    """A colored torus of elliptical splats, leaf capacity 6."""
    return build_hierarchy(scenes.torus(150, 60), leaf_capacity=6)


@pytest.fixture(scope="module")
def bunny_h(shared_data):
    """The Stanford bunny, preprocessed (PCA normals, ellipses)."""
    from surfsplat.io import load

    path = shared_data / "bunny.ply"
    if not path.exists():
        pytest.skip("bunny.ply is absent")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cloud = preprocess(load(path))
    return build_hierarchy(cloud)


def node_levels(h: Hierarchy) -> np.ndarray:
    return np.repeat(np.arange(h.levels), h.level_sizes)


def ancestors(h: Hierarchy) -> np.ndarray:
    """(levels, N) node index of each point's ancestor at each level (-1 below its leaf)."""
    n = len(h.points)
    out = np.full((h.levels, n), -1, dtype=np.int64)
    i = np.arange(n)
    for level in range(h.levels):
        sl = h.level(level)
        start, count = h.node_point_start[sl], h.node_point_count[sl]
        j = np.searchsorted(start, i, side="right") - 1
        inside = (j >= 0) & (i < start[np.maximum(j, 0)] + count[np.maximum(j, 0)])
        out[level, inside] = sl.start + j[inside]
    return out


def node_of_points(h: Hierarchy):
    """(N,) node index of each point's ancestor per level, flattened: (point index, node index) pairs."""
    anc = ancestors(h)
    level, point = np.nonzero(anc >= 0)
    return point, anc[level, point]


def ellipse_q(h: Hierarchy, node: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Squared normalized radius of points x (K, 3) projected into the ellipses of ``node`` (K,), float64."""
    c = h.node_positions[node].astype(np.float64)
    u = h.node_u[node].astype(np.float64)
    v = h.node_v[node].astype(np.float64)
    d = x - c
    su = np.einsum("ij,ij->i", d, u) / np.einsum("ij,ij->i", u, u)
    sv = np.einsum("ij,ij->i", d, v) / np.einsum("ij,ij->i", v, v)
    return su * su + sv * sv


def projected_size(h: Hierarchy, camera: Camera, node: np.ndarray) -> np.ndarray:
    """The selection's projected diameter (pixels) of nodes, recomputed in float64."""
    dist = np.linalg.norm(h.node_positions[node].astype(np.float64) - np.asarray(camera.eye), axis=1)
    eff = np.maximum(dist - h.node_radius[node], camera.near)
    return camera.focal_px * 2.0 * h.node_extent[node].astype(np.float64) / eff


def in_frustum(camera: Camera, x: np.ndarray) -> np.ndarray:
    """Brute force: points inside the view frustum."""
    m = camera.view_matrix
    pc = x @ m[:3, :3].T + m[:3, 3]
    depth = -pc[:, 2]
    tv = np.tan(np.radians(camera.fov) / 2.0)
    th = tv * camera.width / camera.height
    return ((depth >= camera.near) & (depth <= camera.far) & (np.abs(pc[:, 0]) <= th * depth)
            & (np.abs(pc[:, 1]) <= tv * depth))


def selected_points(h: Hierarchy, sel) -> np.ndarray:
    """Original indices of all points represented by the selection (points and nodes' subtrees)."""
    nodes = sel.node_indices()
    sub = ranges_to_indices(h.node_point_start[nodes], h.node_point_count[nodes])
    return np.concatenate([sel.point_indices(), sub])


# -- build: covariances, ellipses, spheres, cones ---------------------------------


def test_homogeneous_covariance_helpers():
    rng = np.random.default_rng(1)
    p = rng.normal(size=(50, 3)) + 5.0
    packed = homogeneous_covariance(p, origin=(1.0, 2.0, 3.0))
    full = unpack_covariance(packed)
    q = np.concatenate([p - [1.0, 2.0, 3.0], np.ones((50, 1))], axis=1)
    np.testing.assert_allclose(full, q.T @ q, rtol=1e-12)
    assert len(COVARIANCE_ENTRIES) == 10
    # EQ 2: the covariance about the mean from M_bar equals the direct one
    mean = p.mean(axis=0) - [1.0, 2.0, 3.0]
    c6 = covariance_about(packed[None], mean[None])[0]
    direct = (p - p.mean(axis=0)).T @ (p - p.mean(axis=0))
    np.testing.assert_allclose(c6, direct[[0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("name", ["sphere_h", "torus_h"])
def test_summed_covariance_equals_direct(name, request):
    """EQ 4 (summed bottom-up) == EQ 2 computed from each node's points, nodes sampled at every level."""
    h = request.getfixturevalue(name)
    rng = np.random.default_rng(0)
    pos = h.points.positions
    for level in range(h.levels):
        sl = h.level(level)
        nodes = np.arange(sl.start, sl.stop)
        for node in rng.choice(nodes, size=min(12, len(nodes)), replace=False):
            a, k = h.node_point_start[node], h.node_point_count[node]
            direct = homogeneous_covariance(pos[a:a + k], h.origin)
            np.testing.assert_allclose(h.node_covariance[node], direct, rtol=1e-9, atol=1e-9 * k)


def disk_boundary(p, u, v, samples: int = 16):
    """(samples * K, 3) points on the rims p + cos(t) u + sin(t) v of disks."""
    p, u, v = (np.asarray(a, dtype=np.float64) for a in (p, u, v))
    angle = np.linspace(0.0, 2.0 * np.pi, samples, endpoint=False)
    return np.concatenate([p + np.cos(a) * u + np.sin(a) * v for a in angle])


@pytest.mark.parametrize("name", ["sphere_h", "torus_h", "bunny_h"])
def test_ellipses_cover_the_subtree_disks_and_extents_its_points(name, request):
    """Sec. 3.4, fig. 6: a node's ellipse covers the disks of all surfels it stands for (its
    children's disks down to the input splats), so every cut of the tree covers what the input
    covers; the extent ellipse (fig. 6 a, same axes) bounds the points only, and is smaller."""
    h = request.getfixturevalue(name)
    point, node = node_of_points(h)
    pts = h.points
    q = ellipse_q(h, np.tile(node, 16), disk_boundary(pts.positions[point], pts.u[point], pts.v[point]))
    assert q.max() <= 1 + 1e-5
    # the cover is not inflated level over level (covering the children's covers grew the
    # ellipses ~2.5x): the outermost disk of a node reaches close to its rim
    worst = np.full(len(h), 0.0)
    np.maximum.at(worst, np.tile(node, 16), q)
    assert np.median(worst) > 0.7   # squared normalized radius: the worst disk reaches ~0.85 of the rim
    # extent: the points (not their disks) lie inside the ellipse of major semi-axis node_extent
    scale = (h.node_extent / np.linalg.norm(h.node_u, axis=1)).astype(np.float64)
    spread = scale[node] > 0
    qp = ellipse_q(h, node[spread], pts.positions[point[spread]].astype(np.float64)) / scale[node[spread]] ** 2
    assert qp.max() <= 1 + 1e-4
    assert np.all(h.node_extent <= np.linalg.norm(h.node_u, axis=1))
    # axes: orthogonal to the normal and to each other, major first, anisotropy capped
    n = h.node_normals.astype(np.float64)
    u, v = h.node_u.astype(np.float64), h.node_v.astype(np.float64)
    a, b = np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1)
    assert np.abs(np.einsum("ij,ij->i", u, n)).max() <= 1e-5 * a.max()
    assert np.abs(np.einsum("ij,ij->i", u, v) / (a * b)).max() <= 1e-5
    assert np.all(a >= b * (1 - 1e-6)) and np.all(a <= 4.0 * b * (1 + 1e-5))
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)


@pytest.mark.parametrize("name", ["sphere_h", "torus_h", "bunny_h"])
def test_spheres_and_cones_bound_the_subtree(name, request):
    h = request.getfixturevalue(name)
    point, node = node_of_points(h)
    pts = h.points
    d = np.linalg.norm(pts.positions[point].astype(np.float64) - h.node_positions[node], axis=1)
    reach = d + pts.radii[point]
    assert np.all(reach <= h.node_radius[node] * (1 + 1e-5) + 1e-7)
    n = pts.normals[point].astype(np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    c = h.node_normals[node].astype(np.float64)
    angle = np.arctan2(np.linalg.norm(np.cross(n, c), axis=1), np.einsum("ij,ij->i", n, c))
    cone = h.node_cone[node].astype(np.float64)
    assert np.all(angle <= cone + 1e-5)
    assert np.all((h.node_cone < np.pi / 2) | (h.node_cone == np.float32(np.pi)))
    # a leaf of a finely sampled smooth surface has a narrow cone
    assert np.median(h.node_cone[h.is_leaf]) < np.radians(30)


def test_normal_field_on_sphere_matches_curvature(sphere_h):
    """Botsch 2004 eq. 3-4 on a sphere of radius R: alpha = a / R, beta = b / R."""
    h = sphere_h
    a = np.linalg.norm(h.node_u, axis=1)
    b = np.linalg.norm(h.node_v, axis=1)
    count = h.node_point_count
    # nodes of many points covering a moderately curved patch
    ok = (count >= 30) & (a < 0.4) & (h.node_cone < np.pi)
    assert ok.sum() > 30
    alpha, beta = h.node_normal_field[ok].T
    np.testing.assert_allclose(alpha, a[ok], rtol=0.05)
    np.testing.assert_allclose(beta, b[ok], rtol=0.05)
    # the cone variant: tan(theta), capped; flat: zeros
    idx = np.flatnonzero(ok)[:10]
    cone = h.node_normal_fields(idx, "cone")
    np.testing.assert_allclose(cone[:, 0], np.tan(np.minimum(h.node_cone[idx], CONE_SHADING_MAX_ANGLE)), rtol=1e-6)
    assert not h.node_normal_fields(idx, "flat").any()
    with pytest.raises(InputError, match="shading"):
        h.node_normal_fields(idx, "phong")


def test_node_splat_attributes(torus_h):
    h = torus_h
    root = h.points
    np.testing.assert_allclose(h.node_positions[0], root.positions.astype(np.float64).mean(axis=0), atol=1e-6)
    np.testing.assert_allclose(h.node_colors[0], root.colors.astype(np.float64).mean(axis=0), atol=1e-6)
    # the root of a closed torus: normals cancel, a unit normal all the same, a cone of pi
    np.testing.assert_allclose(np.linalg.norm(h.node_normals[0]), 1.0, atol=1e-6)
    assert h.node_cone[0] == np.float32(np.pi)
    leaf = np.flatnonzero(h.is_leaf)[100]
    a, k = h.node_point_start[leaf], h.node_point_count[leaf]
    mean_n = root.normals[a:a + k].astype(np.float64).sum(axis=0)
    np.testing.assert_allclose(h.node_normals[leaf], mean_n / np.linalg.norm(mean_n), atol=1e-6)


# -- build: structure ------------------------------------------------------------


@pytest.mark.parametrize("name", ["sphere_h", "torus_h", "bunny_h"])
def test_structure(name, request):
    h = request.getfixturevalue(name)
    n = len(h.points)
    # levels contiguous; children of a level's nodes tile the next level in order
    assert h.level_offsets[0] == 0 and h.level_offsets[1] == 1 and h.level_offsets[-1] == len(h)
    for level in range(h.levels - 1):
        sl, below = h.level(level), h.level(level + 1)
        inner = np.arange(sl.start, sl.stop)[h.node_child_count[sl] > 0]
        first = h.node_child_start[inner]
        assert first[0] == below.start
        np.testing.assert_array_equal(first[1:], first[:-1] + h.node_child_count[inner][:-1])
        assert first[-1] + h.node_child_count[inner][-1] == below.stop
        # a node's point range is the union of its children's
        parent = np.repeat(inner, h.node_child_count[inner])
        child = np.arange(below.start, below.stop)
        assert np.all(h.node_point_start[child] >= h.node_point_start[parent])
        ends = h.node_point_start + h.node_point_count
        assert np.all(ends[child] <= ends[parent])
        np.testing.assert_array_equal(np.bincount(parent - sl.start, weights=h.node_point_count[child],
                                                  minlength=sl.stop - sl.start)[inner - sl.start],
                                      h.node_point_count[inner])
    assert not np.any(h.node_child_count[h.level(h.levels - 1)])
    # each point in exactly one leaf; leaves respect the capacity
    leaf = h.is_leaf
    covered = np.bincount(ranges_to_indices(h.node_point_start[leaf], h.node_point_count[leaf]), minlength=n)
    assert np.all(covered == 1)
    assert h.node_point_count[leaf].max() <= h.leaf_capacity
    assert np.all(h.node_point_count[~leaf] > h.leaf_capacity)
    assert np.all(h.node_child_count[~leaf] >= 2) and np.all(h.node_child_count <= 8)
    # the points are the original ones, reordered
    assert np.array_equal(np.sort(h.order), np.arange(n))
    assert h.describe()["points"] == n and h.describe()["nodes"] == len(h)


def test_points_are_the_input_reordered():
    cloud = scenes.torus(40, 20)
    h = build_hierarchy(cloud)
    for name in ("positions", "normals", "colors", "u", "v"):
        np.testing.assert_array_equal(getattr(h.points, name), getattr(cloud, name)[h.order])


def test_duplicates_single_point_and_depth_limit():
    rng = np.random.default_rng(3)
    base = scenes.sphere(500)
    # 300 coincident points plus a sphere: the split of the duplicates separates nothing -> one leaf
    idx = np.concatenate([np.zeros(300, dtype=int), np.arange(500)])
    dup = base.subset(idx)
    h = build_hierarchy(dup, leaf_capacity=4)
    leaf = h.is_leaf
    assert h.node_point_count[leaf].max() >= 300
    assert h.levels < 20
    assert np.all(np.bincount(ranges_to_indices(h.node_point_start[leaf], h.node_point_count[leaf])) == 1)
    # all points identical
    same = base.subset(np.zeros(50, dtype=int))
    h = build_hierarchy(same)
    assert len(h) == 1 and h.levels == 1 and h.node_point_count[0] == 50
    # a single point: one leaf whose ellipse covers the point's disk
    one = base.subset(np.array([7]))
    h = build_hierarchy(one)
    assert len(h) == 1 and h.is_leaf[0] and h.node_extent[0] == 0
    np.testing.assert_array_equal(h.node_positions[0], one.positions[0])
    q = ellipse_q(h, np.zeros(16, dtype=int), disk_boundary(one.positions, one.u, one.v))
    assert q.max() <= 1 + 1e-5
    # depth limit
    h = build_hierarchy(scenes.sphere(2000), leaf_capacity=1, max_depth=3)
    assert h.levels == 4
    # points spaced exponentially (very unbalanced splits) stay within max_depth
    x = 2.0 ** -np.arange(60)
    pts = np.stack([x, x * 0.5, x * 0.25], axis=1) + rng.normal(scale=1e-30, size=(60, 3))
    cloud = SplatCloud(pts, np.tile([0.0, 0.0, 1.0], (60, 1)), None, np.tile([1e-3, 0, 0], (60, 1)),
                       np.tile([0, 1e-3, 0], (60, 1)))
    h = build_hierarchy(cloud, leaf_capacity=1, max_depth=10)
    assert h.levels <= 11


def test_build_input_errors():
    with pytest.raises(InputError, match="preprocess"):
        build_hierarchy(SplatCloud(np.zeros((5, 3))))
    with pytest.raises(InputError, match="SplatCloud"):
        build_hierarchy(np.zeros((5, 3)))
    cloud = scenes.sphere(100)
    for bad in (0, -1, 2.5, True):
        with pytest.raises(InputError, match="leaf_capacity"):
            build_hierarchy(cloud, leaf_capacity=bad)
    with pytest.raises(InputError, match="max_depth"):
        build_hierarchy(cloud, max_depth=-1)


# -- storage ---------------------------------------------------------------------


def test_save_load_round_trip(torus_h, tmp_path):
    path = save_hierarchy(torus_h, tmp_path / "torus.npz")
    assert path.exists()
    h = load_hierarchy(path)
    for name, value in torus_h.arrays().items():
        loaded = h.arrays()[name]
        assert loaded.dtype == value.dtype and loaded.shape == value.shape, name
        assert np.array_equal(loaded, value), name
    assert set(h.arrays()) == set(torus_h.arrays())
    assert (h.leaf_capacity, h.max_depth) == (torus_h.leaf_capacity, torus_h.max_depth)
    assert h.describe() == torus_h.describe()
    # replaced by default; overwrite=False refuses
    small = build_hierarchy(scenes.sphere(300))
    save_hierarchy(small, path)
    assert len(load_hierarchy(path).points) == 300
    with pytest.raises(InputError, match="exists"):
        save_hierarchy(torus_h, path, overwrite=False)
    assert len(load_hierarchy(path).points) == 300
    assert [p.name for p in tmp_path.iterdir()] == ["torus.npz"]


def test_load_errors_name_the_file(torus_h, tmp_path):
    missing = tmp_path / "missing.npz"
    with pytest.raises(InputError, match="missing.npz.*no such file"):
        load_hierarchy(missing)
    with pytest.raises(InputError, match="directory"):
        load_hierarchy(tmp_path)
    good = save_hierarchy(torus_h, tmp_path / "good.npz")
    raw = good.read_bytes()
    # truncated
    (tmp_path / "cut.npz").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(InputError, match="cut.npz"):
        load_hierarchy(tmp_path / "cut.npz")
    # random bytes, empty file
    (tmp_path / "noise.npz").write_bytes(np.random.default_rng(0).bytes(1000))
    with pytest.raises(InputError, match="noise.npz.*not an .npz archive"):
        load_hierarchy(tmp_path / "noise.npz")
    (tmp_path / "empty.npz").write_bytes(b"")
    with pytest.raises(InputError, match="empty.npz"):
        load_hierarchy(tmp_path / "empty.npz")
    # a bit flipped inside an array: CRC error
    flipped = bytearray(raw)
    flipped[len(raw) // 3] ^= 0xFF
    (tmp_path / "flip.npz").write_bytes(bytes(flipped))
    with pytest.raises(InputError, match="flip.npz"):
        load_hierarchy(tmp_path / "flip.npz")
    # a foreign npz, a single .npy array
    np.savez(tmp_path / "foreign.npz", a=np.zeros(3))
    with pytest.raises(InputError, match="foreign.npz.*not a surfsplat hierarchy"):
        load_hierarchy(tmp_path / "foreign.npz")
    np.save(tmp_path / "array.npy", np.zeros(3))
    with pytest.raises(InputError, match="array.npy"):
        load_hierarchy(tmp_path / "array.npy")

    def rewrite(name, **changes):
        with zipfile.ZipFile(good) as z, np.load(good) as archive:
            members = {k: archive[k] for k in archive.files}
            assert set(z.namelist()) == {k + ".npy" for k in members}
        members.update(changes)
        for key, value in list(members.items()):
            if value is None:
                del members[key]
        path = tmp_path / name
        with open(path, "wb") as f:
            np.savez(f, **members)
        return path

    with pytest.raises(InputError, match="newer.npz.*version"):
        load_hierarchy(rewrite("newer.npz", format_version=np.array(COMPACT_VERSION + 1)))
    with pytest.raises(InputError, match="nou.npz.*node_u"):
        load_hierarchy(rewrite("nou.npz", node_u=None))
    with pytest.raises(InputError, match="shape.npz.*node_radius"):
        load_hierarchy(rewrite("shape.npz", node_radius=torus_h.node_radius[:-1]))
    with pytest.raises(InputError, match="dtype.npz.*point_u"):
        load_hierarchy(rewrite("dtype.npz", point_u=torus_h.points.u.astype(np.float64)))
    bad = torus_h.node_child_start.copy()
    bad[0] += 5
    with pytest.raises(InputError, match="child.npz.*corrupt"):
        load_hierarchy(rewrite("child.npz", node_child_start=bad))
    nan = torus_h.node_positions.copy()
    nan[3, 1] = np.nan
    with pytest.raises(InputError, match="nan.npz.*non-finite"):
        load_hierarchy(rewrite("nan.npz", node_positions=nan))


# -- selection ---------------------------------------------------------------------


def far_camera(h, distance=3.0, size=256):
    c = Camera(eye=(0.3 * distance, 0.2 * distance, distance), target=(0, 0, 0), width=size, height=size,
               near=0.05, far=100.0)
    return c


def test_lod_tolerance_zero_selects_every_point(torus_h):
    h = torus_h
    cam = far_camera(h, distance=5.0)
    sel = select(h, cam, 0.0, cull_frustum=False)
    assert sel.node_count == 0 and sel.point_total == len(h.points) == len(sel)
    splats = h.splats(sel)
    back = np.empty(len(h.points), dtype=np.int64)
    back[sel.point_indices()] = np.arange(len(sel))
    for name in ("positions", "normals", "colors", "u", "v"):
        np.testing.assert_array_equal(getattr(splats, name)[back], getattr(h.points, name))
    # with frustum culling and the whole model in view, nothing is culled either
    assert select(h, cam, 0.0).point_total == len(h.points)


def test_selection_monotonic_and_within_tolerance(sphere_h):
    h = sphere_h
    cam = far_camera(h, distance=4.0, size=256)
    counts = []
    for lod_tolerance in (0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 64.0):
        sel = select(h, cam, lod_tolerance)
        counts.append(len(sel))
        nodes = sel.node_indices()
        if len(nodes):
            assert projected_size(h, cam, nodes).max() <= lod_tolerance * (1 + 1e-4)
        # parents of selected nodes and of refined leaves were refined: larger than lod_tolerance
        refined = np.concatenate([nodes, np.concatenate(sel.leaves)])
        parent = np.searchsorted(h.node_child_start, refined, side="right") - 1
        parent = parent[refined > 0]
        assert np.all(h.node_child_start[parent] + h.node_child_count[parent] > refined[refined > 0])
        assert np.all(projected_size(h, cam, parent) > lod_tolerance * (1 - 1e-4))
    assert counts == sorted(counts, reverse=True)
    assert counts[0] == len(h.points) and counts[-1] < counts[0] / 5


@pytest.mark.parametrize("lod_tolerance", [1.0, 3.0, 10.0])
def test_selection_covers_every_point_exactly_once(sphere_h, lod_tolerance):
    """Each point is selected itself or through exactly one selected ancestor whose ellipse covers it."""
    h = sphere_h
    cam = far_camera(h, distance=4.0, size=256)
    sel = select(h, cam, lod_tolerance, cull_frustum=False)
    n = len(h.points)
    hits = np.bincount(selected_points(h, sel), minlength=n)
    assert np.all(hits == 1)
    nodes = sel.node_indices()
    point = ranges_to_indices(h.node_point_start[nodes], h.node_point_count[nodes])
    owner = np.repeat(nodes, h.node_point_count[nodes])
    x = h.points.positions[point].astype(np.float64)
    assert np.all(ellipse_q(h, owner, x) <= 1 + 1e-5)
    # and the surface stays close to the splat's plane (a fraction of the splat size)
    normal_distance = np.abs(np.einsum("ij,ij->i", x - h.node_positions[owner], h.node_normals[owner]))
    assert np.all(normal_distance <= 0.5 * np.linalg.norm(h.node_u[owner], axis=1))
    splats = h.splats(sel)
    assert len(splats) == len(sel) and splats.normal_field is not None


def test_bunny_selection_covers(bunny_h):
    h = bunny_h
    lo, hi = h.bounds()
    center = 0.5 * (lo + hi)
    cam = Camera(eye=tuple(center + [0.0, 0.0, 0.5]), target=tuple(center), width=512, height=512)
    for lod_tolerance in (0.0, 2.0, 8.0):
        sel = select(h, cam, lod_tolerance, cull_frustum=False)
        assert np.all(np.bincount(selected_points(h, sel), minlength=len(h.points)) == 1)


def test_frustum_culling(sphere_h):
    h = sphere_h
    # outside, looking away: nothing
    away = Camera(eye=(0, 0, 3), target=(0, 0, 6), width=256, height=256, near=0.1, far=50)
    sel = select(h, away, 0.0)
    assert len(sel) == 0 and sel.culled_frustum >= 1
    # inside the sphere, looking at one side: only what intersects the frustum
    inside = Camera(eye=(0, 0, 0.2), target=(0.3, 0, 1), fov=50, width=320, height=240, near=0.01, far=10)
    sel = select(h, inside, 0.0)
    chosen = np.zeros(len(h.points), dtype=bool)
    chosen[sel.point_indices()] = True
    pts = h.points.positions.astype(np.float64)
    visible = in_frustum(inside, pts)
    assert visible.sum() > 100
    assert np.all(chosen[visible])  # nothing visible is culled
    # points whose disk lies well outside (by the leaf size) are mostly culled
    m = inside.view_matrix
    pc = pts @ m[:3, :3].T + m[:3, 3]
    depth = -pc[:, 2]
    tv = np.tan(np.radians(inside.fov) / 2.0)
    th = tv * inside.width / inside.height
    margin = 0.1
    far_out = (depth < -margin) | (np.abs(pc[:, 0]) - th * depth > margin * np.hypot(1, th)) | (
        np.abs(pc[:, 1]) - tv * depth > margin * np.hypot(1, tv))
    assert far_out.sum() > len(pts) / 2
    assert chosen[far_out].mean() < 0.02
    assert chosen.sum() < 1.5 * visible.sum() + 200
    # the eye inside the model: the root (and every node whose sphere holds the eye) is always refined
    coarse = select(h, inside, 1e9)
    assert coarse.node_count > 0 and 0 not in coarse.node_indices()
    holds_eye = np.linalg.norm(h.node_positions - np.asarray(inside.eye), axis=1) < h.node_radius
    assert not np.any(holds_eye[coarse.node_indices()])


def test_backface_culling_sphere(sphere_h):
    h = sphere_h
    eye = np.array([0.0, 0.5, 3.0])
    cam = Camera(eye=tuple(eye), target=(0, 0, 0), width=256, height=256, near=0.1, far=20)
    sel = select(h, cam, 0.0, cull_backfaces=True)
    pts = h.points.positions.astype(np.float64)
    front = np.einsum("ij,ij->i", h.points.normals, eye - pts) > 0
    chosen = np.zeros(len(pts), dtype=bool)
    chosen[sel.point_indices()] = True
    assert np.all(chosen[front])  # no front-facing point culled
    assert 0.3 < 1 - chosen.mean() < 0.7  # about half culled (seen from 3 radii: 2/3 face away)
    assert chosen.sum() < 1.25 * front.sum()
    assert sel.culled_backface > 0
    # coarser cuts: culled nodes never hide a front-facing point
    for lod_tolerance in (2.0, 8.0):
        sel = select(h, cam, lod_tolerance, cull_backfaces=True)
        covered = np.zeros(len(pts), dtype=bool)
        covered[selected_points(h, sel)] = True
        assert np.all(covered[front])


def test_shading_modes_and_gather(sphere_h):
    h = sphere_h
    cam = far_camera(h, distance=6.0, size=128)
    sel_fit = select(h, cam, 6.0)
    assert sel_fit.node_count > 0
    fit = h.splats(sel_fit)
    cone = h.splats(select(h, cam, 6.0, lod_shading="cone"))
    flat = h.splats(select(h, cam, 6.0, lod_shading="flat"))
    m = sel_fit.node_count
    spread = h.node_point_count[sel_fit.node_indices()] >= 3
    assert spread.mean() > 0.5
    assert np.all(fit.normal_field[:m][spread] > 0)  # a sphere curves away from the normal: alpha, beta > 0
    assert np.all(cone.normal_field[:m][spread] > 0)
    assert flat.normal_field is None  # the sphere's points have no normal field
    assert not fit.normal_field[m:].any()
    np.testing.assert_array_equal(fit.positions, flat.positions)
    with pytest.raises(InputError, match="shading"):
        select(h, cam, 1.0, lod_shading="gouraud")
    with pytest.raises(InputError, match="tolerance"):
        select(h, cam, -1.0)
    with pytest.raises(InputError, match="tolerance"):
        select(h, cam, float("nan"))


def test_gather_keeps_clip_lines_and_normal_fields():
    cube = scenes.cube(20)
    cube = cube.replace(normal_field=np.full((len(cube), 2), 0.25, dtype=np.float32))
    h = build_hierarchy(cube)
    cam = Camera(eye=(2.0, 1.5, 2.5), width=64, height=64)
    sel = select(h, cam, 3.0)
    out = h.splats(sel)
    m = sel.node_count
    assert 0 < m < len(out)
    assert out.clip_lines is not None
    np.testing.assert_array_equal(out.clip_lines[:m], np.tile([[0, 0, 1], [0, 0, 1]], (m, 1, 1)))
    np.testing.assert_array_equal(out.clip_lines[m:], h.points.clip_lines[sel.point_indices()])
    np.testing.assert_array_equal(out.normal_field[m:], 0.25)
    flat = h.splats(select(h, cam, 3.0, lod_shading="flat"))
    assert not flat.normal_field[:m].any() and np.all(flat.normal_field[m:] == 0.25)


def test_camera_without_clip_planes(torus_h):
    cam = Camera(eye=(0, -3, 1), width=128, height=128)  # near/far None: from the bounds
    sel = select(torus_h, cam, lod_tolerance=2.0, lod_shading="cone")
    assert 0 < len(sel) <= len(torus_h.points)
    assert sel.summary()["splats"] == len(sel)
    assert (sel.lod_tolerance, sel.lod_shading, sel.summary()["lod_tolerance"]) == (2.0, "cone", 2.0)


def test_lod_shading_names():
    assert SHADINGS == get_args(LodShading) == ("fit", "cone", "flat")
    assert "lod_shading" in {f.name for f in fields(Selection)}


def test_merged_point_ranges(torus_h):
    sel = select(torus_h, far_camera(torus_h, distance=5.0), 0.0)
    start, count = sel.merged_point_ranges()
    assert len(start) < len(sel.point_start)
    assert np.all(start[1:] > start[:-1] + count[:-1])
    np.testing.assert_array_equal(np.sort(sel.point_indices()), ranges_to_indices(start, count))


@pytest.mark.parametrize("budget", [1, 50, 2000, 10**9])
def test_uniform_cut_covers_each_point_once_within_the_budget(torus_h, budget):
    from surfsplat.hierarchy import uniform_cut

    h = torus_h
    cut = uniform_cut(h, budget)
    assert 1 <= len(cut) <= max(budget, 1)
    owners = np.bincount(ranges_to_indices(h.node_point_start[cut], h.node_point_count[cut]), minlength=len(h.points))
    assert np.all(owners == 1)
    if budget >= len(h):
        assert np.all(h.is_leaf[cut])   # the finest cut: every leaf
    with pytest.raises(InputError, match="budget"):
        uniform_cut(h, 0)


def test_clipped_splats_are_never_merged_into_coarse_nodes():
    """Sharp edges survive any tolerance: nodes over clipped splats are refined down to the points."""
    cube = scenes.cube(30)
    h = build_hierarchy(cube)
    camera = Camera(eye=(2.0, 1.5, 2.5), target=(0, 0, 0), width=256, height=256)
    clipped = np.any(h.points.clip_lines[:, :, :2] != 0, axis=(1, 2))
    sel = select(h, camera, 50.0)
    assert sel.node_count > 0 and len(sel) < 0.5 * len(cube)          # the flat faces do get coarse
    nodes = sel.node_indices()
    inside = ranges_to_indices(h.node_point_start[nodes], h.node_point_count[nodes])
    assert not clipped[inside].any()
    # every clipped point of the visible faces is drawn itself, with its clip lines
    drawn = sel.point_indices()
    assert clipped[drawn].sum() > 0.4 * clipped.sum()
    splats = h.splats(sel)
    assert np.any(splats.clip_lines[:, :, :2] != 0, axis=(1, 2)).sum() == clipped[drawn].sum()
