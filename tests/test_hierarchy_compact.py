"""Compact hierarchy files (``save_hierarchy(..., compact=True)``, ``surfsplat build --compact``): the splats
quantized to 19 bytes (surfsplat.io.splat_codec, the web viewer's format), read back by the same
``load_hierarchy`` within the codes' steps, drawn as the full file draws."""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat.cli import main
from surfsplat.errors import InputError
from surfsplat.hierarchy import build_hierarchy, load_hierarchy, save_hierarchy
from surfsplat.hierarchy.storage import COMPACT_VERSION, FORMAT_VERSION, node_covariances
from surfsplat.io.npz import read_npz
from surfsplat.metrics import psnr
from surfsplat.pipeline import View
from surfsplat.scenes import torus


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("compact")
    h = build_hierarchy(torus(160, 64))
    full, compact = folder / "full.npz", folder / "compact.npz"
    save_hierarchy(h, full)
    save_hierarchy(h, compact, compact=True)
    return h, full, compact


def angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Radians between the rows of a and b (float64: float32 arccos near 1 is off by ~3e-4)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))


def test_a_compact_file_loads_as_the_full_one_within_the_codes_steps(files):
    h, full, compact = files
    assert read_npz(full, ("format_version",))["format_version"] == FORMAT_VERSION   # full files: the old version
    assert read_npz(compact, ("format_version",))["format_version"] == COMPACT_VERSION
    assert compact.stat().st_size < 0.5 * full.stat().st_size
    c = load_hierarchy(compact)
    for name in ("order", "level_offsets", "node_point_start", "node_point_count", "node_child_start",
                 "node_child_count"):
        assert getattr(c, name).dtype == np.int64 and np.array_equal(getattr(c, name), getattr(h, name))
    for ours, theirs in ((c.points, h.points), (c.node_splats(lod_shading="flat"), h.node_splats(lod_shading="flat"))):
        box = theirs.positions.max(axis=0) - theirs.positions.min(axis=0)
        # half a step of 2^16 - 1 over the box, and float32
        assert (np.abs(ours.positions - theirs.positions) <= box / 65535 * 0.5 + 1e-6).all()
        assert angle(ours.normals, theirs.normals).max() < 1e-4   # octahedral, 65534 steps
        turn = angle(ours.u, theirs.u)
        assert np.minimum(turn, np.pi - turn).max() < 1e-4   # the axis angle in 2^16 steps of pi (u ~ -u)
        radii = np.linalg.norm(theirs.u, axis=1)
        assert np.allclose(np.linalg.norm(ours.u, axis=1), radii, rtol=1e-3)   # log2 radius, 16 bits
        assert np.abs(ours.colors - theirs.colors).max() <= 0.5 / 255 + 1e-6
    # the covariances summed again over the decoded points, as the build sums them (Pajarola 2003, EQ 2, 4)
    assert np.allclose(node_covariances(h.points.positions, h.origin, h.node_point_start, h.node_child_start,
                                        h.node_child_count, h.level_offsets), h.node_covariance, rtol=1e-12)
    assert np.allclose(c.node_covariance, h.node_covariance, rtol=1e-4, atol=1e-6 * np.abs(h.node_covariance).max())


@pytest.mark.gl
def test_a_compact_file_renders_as_the_full_one(files):
    _, full, compact = files
    view = View(full)
    camera = view.camera(None, 256, 256)
    a = view.render(camera, technique="ewa").frame.image()
    b = View(compact).render(camera, technique="ewa").frame.image()
    assert psnr(a / 255.0, b / 255.0) >= 45.0
    covered = lambda image: image.min(axis=2) < 250   # noqa: E731
    assert abs(int(covered(a).sum()) - int(covered(b).sum())) <= 0.001 * covered(a).sum()   # no hole


def test_phong_splats_are_refused_by_the_compact_layout(tmp_path):
    cloud = torus(40, 16)
    tilted = cloud.normals + 0.2 * cloud.u / np.linalg.norm(cloud.u, axis=1, keepdims=True)
    h = build_hierarchy(cloud.replace(normals=(tilted / np.linalg.norm(tilted, axis=1, keepdims=True))
                                      .astype(np.float32)))
    with pytest.raises(InputError, match="phong.npz.*normal off their plane"):
        save_hierarchy(h, tmp_path / "phong.npz", compact=True)
    assert not (tmp_path / "phong.npz").exists()


def test_build_compact_on_the_command_line(tmp_path, capsys):
    source = tmp_path / "torus.ply"
    from surfsplat.io import save_ply
    save_ply(torus(60, 24), source)
    assert main(["build", str(source), "-o", str(tmp_path / "t.npz"), "--compact"]) == 0
    assert "(compact)" in capsys.readouterr().err
    assert read_npz(tmp_path / "t.npz", ("format_version",))["format_version"] == COMPACT_VERSION
    assert len(load_hierarchy(tmp_path / "t.npz").points) == 60 * 24
    assert main(["info", str(tmp_path / "t.npz")]) == 0
    assert "format 3, compact" in capsys.readouterr().out
    assert main(["build", str(source), "-o", str(tmp_path / "t.ssh"), "--compact", "--chunked"]) != 0


def test_normal_fields_and_clip_lines_keep_their_direction_where_an_axis_decodes_reversed(tmp_path):
    cloud = torus(40, 16)
    rng = np.random.default_rng(3)
    lines = rng.normal(size=(len(cloud), 2, 3)).astype(np.float32)
    field = rng.normal(size=(len(cloud), 2)).astype(np.float32)
    h = build_hierarchy(cloud.replace(clip_lines=lines, normal_field=field))
    save_hierarchy(h, tmp_path / "c.npz", compact=True)
    c = load_hierarchy(tmp_path / "c.npz")

    def unit(a: np.ndarray) -> np.ndarray:
        return a / np.linalg.norm(a, axis=1, keepdims=True)

    def gradient(abc: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """World-space gradient of a s + b t: s = (x - p) . u / |u|^2, t likewise."""
        return (abc[:, :1] * u / np.einsum("ij,ij->i", u, u)[:, None]
                + abc[:, 1:2] * v / np.einsum("ij,ij->i", v, v)[:, None])

    reversed_u = np.einsum("ij,ij->i", c.points.u, h.points.u) < 0
    assert reversed_u.any()   # the codes keep u up to its sign: the case under test occurs
    for ours, theirs in ((c.points, h.points), (c, h)):
        f_ours = ours.normal_field if ours is c.points else c.node_normal_field
        f_theirs = theirs.normal_field if theirs is h.points else h.node_normal_field
        u_ours, v_ours = (ours.u, ours.v) if ours is c.points else (c.node_u, c.node_v)
        u_theirs, v_theirs = (theirs.u, theirs.v) if theirs is h.points else (h.node_u, h.node_v)
        # the field's turn per unit s and t, in world directions (Botsch 2004, eq. 2)
        assert np.allclose(f_ours[:, :1] * unit(u_ours), f_theirs[:, :1] * unit(u_theirs), atol=1e-3)
        assert np.allclose(f_ours[:, 1:] * unit(v_ours), f_theirs[:, 1:] * unit(v_theirs), atol=1e-3)
    for k in range(2):
        assert np.allclose(gradient(c.points.clip_lines[:, k], c.points.u, c.points.v),
                           gradient(h.points.clip_lines[:, k], h.points.u, h.points.v), rtol=1e-2, atol=1e-2)
