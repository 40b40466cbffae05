"""Fast paths of preprocessing give the results of the general ones, bit for bit.

``kth_distance`` (the k-th neighbour distance that sizes the circles of mesh samples) against the
last column of ``knn``'s distances (a SciPy cKDTree query of k + 1 points, the point dropped), on
random, clustered, duplicated, planar, collinear and minimal clouds.
"""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat import InputError
from surfsplat.geometry.neighbors import knn, kth_distance
from surfsplat.geometry.splats import circular_splats


def _clouds():
    rng = np.random.default_rng(3)
    random = rng.normal(size=(5000, 3))
    dup = np.repeat(rng.normal(size=(400, 3)), 5, axis=0)             # 5 coincident copies of each point
    many = np.repeat(rng.normal(size=(30, 3)), 12, axis=0)            # more copies than k + 1
    planar = np.column_stack([rng.random((3000, 2)), np.zeros(3000)])
    grid = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0), [0.0]), axis=-1).reshape(-1, 3)  # ties
    line = np.outer(rng.random(2000), [1.0, 2.0, -0.5])              # collinear
    same = np.zeros((50, 3))                                          # all one point
    # a dense cluster and sparse points far beyond twice the median k-th distance (queried again)
    clustered = np.concatenate([1e-3 * rng.normal(size=(4000, 3)), rng.normal(size=(600, 3))])
    return {"clustered": clustered, "random": random, "duplicates": dup, "many duplicates": many,
            "planar": planar, "grid": grid, "collinear": line, "coincident": same}


@pytest.mark.parametrize("name", list(_clouds()))
@pytest.mark.parametrize("k", [1, 8, 12])
def test_kth_distance_equals_the_last_knn_distance(name, k):
    pts = _clouds()[name]
    np.testing.assert_array_equal(kth_distance(pts, k), knn(pts, k)[0][:, -1])


def test_kth_distance_with_the_fewest_points_and_float32_input():
    pts = np.random.default_rng(5).random((9, 3)).astype(np.float32)
    np.testing.assert_array_equal(kth_distance(pts, 8), knn(pts, 8)[0][:, -1])
    brute = np.sort(np.linalg.norm(pts[:, None].astype(np.float64) - pts[None], axis=2), axis=1)[:, -1]
    np.testing.assert_allclose(kth_distance(pts, 8), brute, rtol=1e-6)
    with pytest.raises(InputError, match="k \\+ 1"):
        kth_distance(pts, 9)
    with pytest.raises(InputError, match="positive integer"):
        kth_distance(pts, 0)


def test_circles_from_kth_distance_equal_circles_from_knn():
    rng = np.random.default_rng(7)
    pts = np.column_stack([rng.random((4000, 2)), 0.01 * rng.random(4000)])
    pts[:40] = pts[40:80]                                            # some duplicates
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    u0, v0 = circular_splats(normals, knn(pts, 8)[0])
    u1, v1 = circular_splats(normals, kth_distance(pts, 8)[:, None])
    np.testing.assert_array_equal(u0, u1)
    np.testing.assert_array_equal(v0, v1)


def test_clip_lines_searched_in_spatial_order_are_the_same():
    import trimesh

    from surfsplat.geometry.neighbors import spatial_order
    from surfsplat.geometry.sampling import _circles, _samples
    from surfsplat.geometry.sharp import mesh_clip_lines
    from surfsplat.io import Mesh

    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    mesh = Mesh(box.vertices, box.faces[2:])                           # open: one side has a hole
    cloud, face, _ = _samples(mesh, 20_000, 4, False, None, "box")
    splats = _circles(cloud, 8, "box")
    order = spatial_order(splats.positions)
    plain = mesh_clip_lines(mesh, face, splats.positions, splats.u, splats.v, 30.0, boundaries=True)
    fast = mesh_clip_lines(mesh, face, splats.positions, splats.u, splats.v, 30.0, boundaries=True, order=order)
    assert (plain[:, 0, 2] != 1.0).sum() > 1000                        # many splats are clipped
    np.testing.assert_array_equal(plain, fast)
    np.testing.assert_array_equal(_circles(cloud, 8, "box", order).u, splats.u)
