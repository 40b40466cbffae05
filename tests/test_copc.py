"""COPC export (io/copc.py): laspy's CopcReader and plain LAZ reader read every point back (positions within
the quantization step, colours, splat extra bytes and attributes exact), the hierarchy is a consistent octree
of spatially spread levels, a box query returns exactly the points inside it, the command and the API
write it, and a model read back from the COPC renders as the original."""

from __future__ import annotations

import struct

import numpy as np
import pytest

laspy = pytest.importorskip("laspy")
lazrs = pytest.importorskip("lazrs")

import surfsplat  # noqa: E402
from surfsplat.cli import main  # noqa: E402
from surfsplat.cloud import SplatCloud  # noqa: E402
from surfsplat.errors import InputError  # noqa: E402
from surfsplat.io import load  # noqa: E402
from surfsplat.io.copc import RELATIVE_STEP, SPLAT_DIMENSIONS, octree_nodes, write_copc  # noqa: E402
from surfsplat.metrics import psnr  # noqa: E402
from surfsplat.pipeline import View  # noqa: E402
from surfsplat.scenes import torus  # noqa: E402

#: Small nodes so that a test cloud makes a tree of several levels.
GRID, LEAF = 8, 300


def georeferenced_cloud(n: int = 20_000, seed: int = 0) -> SplatCloud:
    """Splats on a wavy 40 m x 30 m terrain at UTM-like coordinates, with colours and attributes
    (an ``id`` to match the points read back)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform([0, 0], [40, 30], size=(n, 2))
    z = 2.0 * np.sin(xy[:, 0] / 5) * np.cos(xy[:, 1] / 7)
    world = np.column_stack([xy + [512_000.0, 4_100_000.0], z + 150.0])
    normals = rng.normal(size=(n, 3)).astype(np.float32)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    u = np.cross(normals, [0.0, 0.0, 1.0]).astype(np.float32) * 0.1
    v = np.cross(normals, u).astype(np.float32)
    attributes = {"id": np.arange(n, dtype=np.uint32),
                  "intensity": rng.integers(0, 65535, n).astype(np.uint16),
                  "classification": rng.integers(0, 20, n).astype(np.uint8),
                  "confidence": rng.uniform(0, 1, n).astype(np.float32)}
    return SplatCloud(positions=world, normals=normals, colors=rng.uniform(0, 1, (n, 3)), u=u, v=v,
                      attributes=attributes, up=(0.0, 0.0, 1.0))


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    cloud = georeferenced_cloud()
    path = tmp_path_factory.mktemp("copc") / "terrain.copc.laz"
    return cloud, path, write_copc(cloud, path, grid=GRID, leaf_points=LEAF)


def by_id(points) -> np.ndarray:
    return np.argsort(np.asarray(points["id"]))


def test_copc_reader_reads_every_point_back(written):
    cloud, path, result = written
    world = cloud.origin + cloud.positions.astype(np.float64)
    diagonal = np.linalg.norm(world.max(axis=0) - world.min(axis=0))
    assert result.scale <= RELATIVE_STEP * diagonal and result.levels >= 3 and result.nodes > 10
    with laspy.CopcReader.open(path) as reader:
        assert reader.header.point_format.id == 7 and str(reader.header.version) == "1.4"
        points = reader.query()
    assert len(points) == len(cloud)
    order = by_id(points)
    np.testing.assert_array_equal(np.asarray(points["id"])[order], np.arange(len(cloud)))
    xyz = np.column_stack([np.asarray(points.x), np.asarray(points.y), np.asarray(points.z)])[order]
    assert np.abs(xyz - world).max() <= 0.5 * result.scale * (1 + 1e-6)
    rgb = np.column_stack([points["red"], points["green"], points["blue"]])[order]
    np.testing.assert_array_equal(rgb, np.round(cloud.colors * 65535).astype(np.uint16))
    for prefix, values in (("n", cloud.normals), ("u", cloud.u), ("v", cloud.v)):
        for axis, c in enumerate("xyz"):
            np.testing.assert_array_equal(np.asarray(points[prefix + c])[order], values[:, axis])
    for name, values in cloud.attributes.items():
        np.testing.assert_array_equal(np.asarray(points[name])[order], values)


def test_the_hierarchy_is_a_consistent_octree_of_spread_levels(written):
    cloud, path, result = written
    with laspy.CopcReader.open(path) as reader:
        info, header, entries = reader.copc_info, reader.header, list(reader.root_page.entries.values())
        laszip = reader.laszip_vlr.record_data
        data = path.read_bytes()
    assert info.hierarchy_root_offset > header.offset_to_point_data and info.hierarchy_root_size == 32 * len(entries)
    # the info VLR is the first one: right after the 375-byte header, user "copc", record 1, 160 bytes
    assert struct.unpack_from("<16sHH", data, 375 + 2) == (b"copc".ljust(16, b"\0"), 1, 160)
    assert lazrs.LazVlr(laszip).uses_variable_size_chunks()
    assert sum(e.point_count for e in entries) == len(cloud) and len(entries) == result.nodes
    keys = {(e.key.level, e.key.x, e.key.y, e.key.z) for e in entries}
    assert all(level == 0 or (level - 1, x >> 1, y >> 1, z >> 1) in keys for level, x, y, z in keys)
    # the chunks tile the point data in order, after the 8-byte offset to the chunk table
    chunks = sorted((e.offset, e.byte_size) for e in entries)
    assert chunks[0][0] == header.offset_to_point_data + 8
    assert all(a + size == b for (a, size), (b, _) in zip(chunks, chunks[1:]))
    low = info.center - info.halfsize
    for e in entries:
        raw = np.zeros(e.point_count * header.point_format.size, np.uint8)
        lazrs.decompress_points_with_chunk_table(data[e.offset:e.offset + e.byte_size], laszip, raw,
                                                 [(e.point_count, e.byte_size)])
        node = laspy.PackedPointRecord.from_buffer(raw, header.point_format)
        xyz = np.column_stack([node["X"], node["Y"], node["Z"]]) * header.scales + header.offsets
        side = 2 * info.halfsize / 2 ** e.key.level
        corner = low + np.array([e.key.x, e.key.y, e.key.z]) * side
        # strictly inside: node faces lie half a step between stored positions, so no rounding moves a point out
        assert ((xyz > corner) & (xyz < corner + side)).all(), e
        if e.point_count > LEAF:   # a node that was subsampled: at most one point per cell of its grid
            cells = np.floor((xyz - corner) / side * GRID).astype(np.int64)
            assert len(np.unique(cells, axis=0)) == e.point_count, e
    assert info.spacing == pytest.approx(2 * info.halfsize / GRID)


def test_a_box_query_returns_exactly_the_points_inside(written):
    cloud, path, result = written
    with laspy.CopcReader.open(path) as reader:
        every = reader.query()
        xyz = np.column_stack([every.x, every.y, every.z])
        ids = np.asarray(every["id"])
        rng = np.random.default_rng(1)
        for _ in range(3):
            a, b = rng.uniform(reader.header.mins, reader.header.maxs, size=(2, 3))
            mins, maxs = np.minimum(a, b), np.maximum(a, b)
            inside = laspy.copc.Bounds(mins, maxs)
            box = reader.query(inside)
            expected = ids[((xyz >= mins) & (xyz <= maxs)).all(axis=1)]
            assert len(expected) > 0
            np.testing.assert_array_equal(np.sort(np.asarray(box["id"])), np.sort(expected))
        coarse = reader.query(level=range(0, 2))
        assert 0 < len(coarse) < len(cloud)


def test_a_plain_laz_reader_and_the_las_loader_read_it(written):
    cloud, path, _ = written
    las = laspy.read(path)
    assert len(las.points) == len(cloud)
    order = np.argsort(np.asarray(las["id"]))
    np.testing.assert_array_equal(np.asarray(las["intensity"])[order], cloud.attributes["intensity"])
    back = load(path)
    assert back.has_splats and back.up == cloud.up and set(SPLAT_DIMENSIONS).isdisjoint(back.attributes)
    order = np.argsort(back.attributes["id"])
    np.testing.assert_array_equal(back.normals[order], cloud.normals)
    np.testing.assert_array_equal(back.u[order], cloud.u)
    np.testing.assert_allclose(back.colors[order], cloud.colors, atol=1 / 65535)


def test_octree_levels_place_every_point_once():
    t = np.random.default_rng(2).uniform(size=(5000, 3))
    level, key = octree_nodes(t, grid=4, leaf_points=100)
    assert (level >= 0).all() and level.max() >= 2
    cells = 2 ** level[:, None]
    np.testing.assert_array_equal(key, np.floor(t * cells))   # each point is inside its node
    root = level == 0
    assert root.sum() == 64   # one point per cell of the 4 x 4 x 4 grid of the root (uniform points fill it)


def test_a_single_point_and_a_flat_cloud(tmp_path):
    for name, positions in (("one", [[1.0, 2.0, 3.0]]), ("flat", np.c_[np.random.default_rng(3).uniform(size=(500, 2)),
                                                                        np.zeros(500)])):
        path = tmp_path / f"{name}.copc.laz"
        write_copc(SplatCloud(positions=np.asarray(positions, np.float32)), path, grid=4, leaf_points=10)
        with laspy.CopcReader.open(path) as reader:
            points = reader.query()
            assert reader.header.point_format.id == 6   # no colours
        xyz = np.column_stack([points.x, points.y, points.z])
        assert np.abs(np.sort(xyz, axis=0) - np.sort(np.asarray(positions), axis=0)).max() < 1e-5


def test_bad_input_is_refused_clearly(tmp_path):
    with pytest.raises(InputError, match="no points"):
        write_copc(SplatCloud(positions=np.zeros((0, 3), np.float32)), tmp_path / "e.copc.laz")
    out = tmp_path / "x.copc.laz"
    out.write_bytes(b"mine")
    with pytest.raises(InputError, match="exists"):
        write_copc(torus(8, 4), out, overwrite=False)
    assert out.read_bytes() == b"mine"
    with pytest.raises(InputError, match="export format"):
        surfsplat.export(torus(8, 4), tmp_path / "a.laz", format="e57")
    with pytest.raises(InputError, match="--force"):   # a file surfsplat did not write
        surfsplat.export(torus(8, 4), out)
    assert out.read_bytes() == b"mine"
    with pytest.raises(InputError, match="folder .* does not exist"):
        write_copc(torus(8, 4), tmp_path / "no" / "x.copc.laz")


def test_export_command_and_api_write_copc(tmp_path, capsys):
    out = tmp_path / "torus.copc.laz"
    assert main(["export", "demo:torus", "-o", str(out), "-q"]) == 0   # implied by the name
    assert main(["export", "demo:torus", "-o", str(out), "-q"]) == 0   # ours: replaced
    other = tmp_path / "torus.laz"
    assert main(["export", "demo:torus", "-o", str(other), "--format", "copc", "-q"]) == 0
    for path in (out, other):
        with laspy.CopcReader.open(path) as reader:
            assert len(reader.query()) == reader.header.point_count > 0
    result = surfsplat.export(torus(32, 16), tmp_path / "api.copc.laz")
    assert result.splats == 32 * 16 and result.bytes == (tmp_path / "api.copc.laz").stat().st_size
    assert result.files == (tmp_path / "api.copc.laz",)


@pytest.mark.gl
def test_a_model_read_back_from_copc_renders_as_the_original(tmp_path):
    cloud = torus(96, 48)
    path = tmp_path / "torus.copc.laz"
    surfsplat.export(cloud, path, format="copc")
    view = View(cloud)
    camera = view.camera(None, 256, 256)
    a = view.render(camera).frame.image() / 255.0
    b = View(str(path)).render(camera).frame.image() / 255.0
    # measured: 75 dB (positions rounded to 1e-5 of the diagonal, 16-bit colours; 46 dB at 1e-4)
    assert psnr(b, a) > 60.0


def test_a_lidar_file_keeps_its_dimensions(shared_data, tmp_path):
    source = shared_data / "simple.las"
    original = laspy.read(source)
    path = tmp_path / "simple.copc.laz"
    write_copc(load(source), path)
    copy = laspy.read(path)
    assert len(copy.points) == len(original.points)
    assert list(copy.header.number_of_points_by_return[:5]) == list(original.header.number_of_points_by_return[:5])
    key = lambda las: np.lexsort((np.asarray(las.X), np.asarray(las.Y), np.asarray(las.gps_time)))  # noqa: E731
    a, b = key(original), key(copy)
    np.testing.assert_allclose(np.asarray(copy.x)[b], np.asarray(original.x)[a], atol=0.5 * copy.header.scales[0])
    for name in ("intensity", "classification", "return_number", "number_of_returns", "gps_time", "point_source_id"):
        np.testing.assert_array_equal(np.asarray(copy[name])[b], np.asarray(original[name])[a], err_msg=name)
