"""Inputs a hostile user would try, through the real command line (``python -m surfsplat`` in a
child process): each gives a clear error naming the file and the problem, or a right answer.

- a zip bomb posing as a hierarchy (``.npz``): refused from the sizes its zip directory declares,
  before anything is inflated, the child's peak memory measured;
- coordinates and splat radii near 1e30: ``info`` prints their exact (float64) radii, spacing and
  bounds, never ``inf``;
- normals of length 1e20: normalized in float64 (their float32 squares overflow), not zeroed;
- a mesh with one vertex at 1e30: beyond the float32 mesh renderer's limit
  (:data:`~surfsplat.cloud.MAX_COORDINATE`), refused by ``render --mesh`` and by the splat path,
  never a blank picture.
"""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys
import warnings
import zipfile

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from surfsplat import InputError, SplatCloud
from surfsplat.cloud import MAX_COORDINATE
from surfsplat.io import load
from surfsplat.io.npz import MAX_INFLATION, read_npz

#: Run the command line in a child and report its peak resident memory (bytes) on the last line
#: of stderr: ``python -c RUNNER ARGS...``. The peak is the kernel's high-water mark of this
#: process's own memory (``VmHWM``); ``resource.getrusage``'s ``ru_maxrss``, the fallback where
#: /proc is missing, keeps across ``exec`` the peak of the process that forked it (pytest's).
RUNNER = """
import resource, runpy, sys
sys.argv = ["surfsplat", *sys.argv[1:]]
try:
    runpy.run_module("surfsplat", run_name="__main__")
    status = 0
except SystemExit as exc:
    status = exc.code if isinstance(exc.code, int) else 1
try:
    with open("/proc/self/status") as stream:
        peak = next(int(line.split()[1]) for line in stream if line.startswith("VmHWM:")) * 1024
except (OSError, StopIteration):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
sys.stderr.write(f"\\nPEAK_RSS {peak}\\n")
sys.exit(status)
"""


def cli(*argv, timeout: float = 300) -> tuple[int, str, str, int]:
    """``surfsplat ARGV`` in a child process: (exit status, stdout, stderr, peak memory in bytes)."""
    env = dict(os.environ)
    src = os.path.join(os.path.dirname(__file__), os.pardir, "src")
    env["PYTHONPATH"] = os.path.abspath(src) + os.pathsep + env.get("PYTHONPATH", "")
    done = subprocess.run([sys.executable, "-c", RUNNER, "-q", *map(str, argv)], capture_output=True, text=True,
                          timeout=timeout, env=env, stdin=subprocess.DEVNULL, check=False)
    err, _, peak = done.stderr.rpartition("PEAK_RSS ")
    return done.returncode, done.stdout, err, int(peak)


def clear_error(status: int, err: str, path) -> None:
    """The command failed with one ``surfsplat: error:`` line naming ``path``, no traceback."""
    assert status == 2, err
    assert f"surfsplat: error: {path}" in err, err
    assert "Traceback" not in err and "overflow" not in err, err


def zip_bomb(path, inflated: int):
    """An ``.npz`` whose one member, ``point_positions.npy``, declares ``inflated`` bytes of float32
    zeros, deflated (1000 to 1), written in chunks (the bomb never sits in this process's memory)."""
    header = io.BytesIO()
    rows = inflated // 12
    np.lib.format.write_array_header_1_0(header, {"descr": "<f4", "fortran_order": False, "shape": (rows, 3)})
    chunk = bytes(1 << 24)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as archive, \
            archive.open("point_positions.npy", "w", force_zip64=True) as member:
        member.write(header.getvalue())
        left = rows * 12
        while left:
            member.write(chunk[:min(left, len(chunk))])
            left -= min(left, len(chunk))
    return path


def write_ply(path, columns: dict[str, np.ndarray], faces=None):
    """A binary PLY of float64 vertex ``columns`` (and triangles ``faces``)."""
    n = len(next(iter(columns.values())))
    vertex = np.zeros(n, dtype=[(name, "f8") for name in columns])
    for name, values in columns.items():
        vertex[name] = values
    elements = [PlyElement.describe(vertex, "vertex")]
    if faces is not None:
        face = np.zeros(len(faces), dtype=[("vertex_indices", "i4", (3,))])
        face["vertex_indices"] = faces
        elements.append(PlyElement.describe(face, "face"))
    PlyData(elements).write(str(path))
    return path


def grid(n: int = 12) -> np.ndarray:
    """(n*n, 3) points of a regular grid on [-1, 1]^2 at z = 0."""
    g = np.stack(np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n)), -1).reshape(-1, 2)
    return np.c_[g, np.zeros(len(g))]


def grid_faces(n: int = 12) -> np.ndarray:
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    return np.concatenate([np.c_[a, a + 1, a + n + 1], np.c_[a, a + n + 1, a + n]])


# -- 1. zip bombs -----------------------------------------------------------------------------------


def test_zip_bomb_hierarchy_is_refused_before_inflating(tmp_path):
    path = zip_bomb(tmp_path / "bomb.npz", 1 << 30)   # 1 GiB of zeros in about 1 MB
    assert path.stat().st_size < (1 << 30) // 200
    status, _, err, peak = cli("info", path)
    clear_error(status, err, path)
    assert re.search(r"the archive inflates to 1,073,741,\d{3} bytes", err) and "zip bomb" in err
    assert peak < 500 << 20, f"peak memory {peak / 2**20:.0f} MiB"


def test_npz_reader_limit_is_a_ratio_of_the_file_size(tmp_path):
    """Below the limit an archive reads exactly; the limit is MAX_INFLATION times the file's size
    (at least 64 MiB), so a bomb just over 64 MiB is refused while real compressed data pass."""
    rng = np.random.default_rng(1)
    data = {"a": rng.normal(size=(1000, 3)).astype(np.float32), "b": np.arange(7, dtype=np.int64),
            "s": np.array("text")}
    np.savez_compressed(tmp_path / "ok.npz", **data)
    back = read_npz(tmp_path / "ok.npz")
    assert set(back) == set(data) and all(np.array_equal(back[k], data[k]) for k in data)
    assert back["s"].shape == () and back["a"].flags.c_contiguous
    bomb = zip_bomb(tmp_path / "small_bomb.npz", (64 << 20) + 120)
    assert bomb.stat().st_size * MAX_INFLATION < 64 << 20
    with pytest.raises(InputError, match=r"small_bomb\.npz: the archive inflates to") as caught:
        read_npz(bomb)
    assert caught.value.file == str(bomb)


def test_chunked_node_files_refuse_a_zip_bomb(tmp_path):
    """A chunked hierarchy's per-cell ``nodes.npz`` is read through the same checks."""
    from surfsplat.hierarchy.chunked.layout import read_nodes

    bomb = zip_bomb(tmp_path / "nodes.npz", 256 << 20)
    with pytest.raises(InputError, match=r"nodes\.npz: corrupt chunk file: the archive inflates to") as caught:
        read_nodes(bomb)
    assert caught.value.file == str(bomb)


# -- 2. coordinates and radii near 1e30 --------------------------------------------------------------


def numbers(line: str) -> np.ndarray:
    """The numbers of an ``info`` line (brackets and words dropped)."""
    words = line.replace("[", " ").replace("]", " ").replace("(", " ").replace(")", " ").split()
    out = []
    for word in words:
        try:
            out.append(float(word))
        except ValueError:
            pass
    return np.array(out)


def test_info_on_coordinates_and_radii_near_1e30_prints_the_right_finite_numbers(tmp_path):
    """A grid 2e30 wide of splats of radius 1e29: the float32 squares of the axes (1e58) overflow;
    the radii, spacing and bounds printed are the exact finite values (computed in float64)."""
    p = grid() * 1e30
    n = len(p)
    columns = {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2], "nx": np.zeros(n), "ny": np.zeros(n), "nz": np.ones(n),
               "radius": np.full(n, 1e29)}
    path = write_ply(tmp_path / "vast.ply", columns)
    status, out, err, _ = cli("info", path)
    assert status == 0, err
    assert not re.search(r"\b(inf|nan)\b", out + err), out + err
    lines = {line.split(":")[0]: line for line in out.splitlines()}
    assert np.allclose(numbers(lines["splat radius"]), 1e29, rtol=1e-3), lines["splat radius"]
    spacing = numbers(lines["neighbour spacing"])[:4]          # min, median, mean, max
    assert np.allclose(spacing, 2e30 / 11, rtol=1e-3), lines["neighbour spacing"]
    assert np.allclose(numbers(lines["bounds"]), [-1e30, -1e30, 0, 1e30, 1e30, 0], rtol=1e-3, atol=1e26)


def test_radii_stay_finite_where_float32_squares_overflow():
    """Splats of radius 3e19 (their axes' float32 squares, 9e38, overflow): the radii are the right
    finite numbers; as they were, inf radii also made the renderer's scale (from the largest
    radius) unusable."""
    p = grid() * 1e20
    n = len(p)
    cloud = SplatCloud.from_arrays(p, np.tile([0.0, 0.0, 1.0], (n, 1)), radius=np.full(n, 3e19))
    with np.errstate(over="ignore"):
        assert not np.isfinite(np.linalg.norm(cloud.u, axis=1)).any()   # the float32 way overflows
    assert cloud.radii.dtype == np.float32 and np.allclose(cloud.radii, 3e19, rtol=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")   # nothing dropped, no overflow warning
        assert len(cloud.validated("far")) == n


# -- 3. normals of length 1e20 ------------------------------------------------------------------------


def test_preprocess_normalizes_normals_of_length_1e20(tmp_path):
    rng = np.random.default_rng(3)
    p = grid(20)
    p[:, 2] = 0.01 * rng.normal(size=len(p))
    direction = rng.normal(size=(len(p), 3))
    direction[:, 2] = np.abs(direction[:, 2]) + 3   # roughly up, each its own direction
    unit = direction / np.linalg.norm(direction, axis=1, keepdims=True)
    given = unit * 1e20
    given[5] = 0.0            # a zero normal: dropped and counted
    given[9] = np.nan         # a NaN one: dropped and counted
    tiny = unit[11] * 1e-30   # underflows float32 squares: normalizes all the same
    given[11] = tiny
    columns = {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2], "nx": given[:, 0], "ny": given[:, 1], "nz": given[:, 2]}
    source = write_ply(tmp_path / "long_normals.ply", columns)
    out = tmp_path / "splats.ply"
    status, _, err, _ = cli("preprocess", source, "-o", out)
    assert status == 0, err
    assert "dropped 2 of 400 points (2 with zero-length or non-finite normals)" in err, err
    splats = load(out)
    assert len(splats) == len(p) - 2
    keep = np.setdiff1d(np.arange(len(p)), [5, 9])
    assert np.allclose(np.linalg.norm(splats.normals, axis=1), 1.0, atol=1e-6)
    order = np.lexsort(splats.positions.T[::-1])
    expected = np.lexsort(p[keep].astype(np.float32).T[::-1])
    # given normals are kept (not re-estimated): each splat's normal is its point's direction
    assert np.abs(splats.normals[order] - unit[keep][expected]).max() < 1e-5


# -- 4. a mesh with one vertex at 1e30 ------------------------------------------------------------------


@pytest.mark.parametrize("mode", [["--mesh"], []], ids=["mesh", "splats"])
def test_render_refuses_a_mesh_vertex_at_1e30(tmp_path, mode):
    v = grid()
    v[-1] = 1e30
    path = write_ply(tmp_path / "far_vertex.ply", {"x": v[:, 0], "y": v[:, 1], "z": v[:, 2]}, grid_faces())
    out = tmp_path / "out.png"
    status, _, err, _ = cli("render", path, *mode, "-o", out, "--width", 64, "--height", 64)
    clear_error(status, err, path)
    assert f"farther than {MAX_COORDINATE:.0e}" in err and "vertex 143" in err
    assert not out.exists()


def test_mesh_renderer_limit_is_where_its_pictures_go_blank(tmp_path):
    """The same bent sheet scaled to 1e17 renders as at scale 1 (the limit is not too strict); at
    1e20 (float32 squares overflow: the picture came out blank) it is refused naming the file."""
    v = grid()
    v[:, 2] = 0.3 * v[:, 0] ** 2
    covered = {}
    for scale in (1.0, 1e17):
        path = write_ply(tmp_path / f"sheet_{scale:g}.ply", {k: v[:, i] * scale for i, k in enumerate("xyz")},
                         grid_faces())
        status, _, err, _ = cli("render", path, "--mesh", "-o", tmp_path / f"{scale:g}.png", "--width", 64,
                                "--height", 64)
        assert status == 0, err
        from PIL import Image
        covered[scale] = (np.asarray(Image.open(tmp_path / f"{scale:g}.png")) < 250).any(axis=2)
    assert covered[1.0].mean() > 0.3 and np.array_equal(covered[1.0], covered[1e17])
    path = write_ply(tmp_path / "sheet_1e20.ply", {k: v[:, i] * 1e20 for i, k in enumerate("xyz")}, grid_faces())
    status, _, err, _ = cli("render", path, "--mesh", "-o", tmp_path / "1e20.png", "--width", 64, "--height", 64)
    clear_error(status, err, path)
    assert "144 of 144 mesh vertices lie farther than 1e+18" in err


def test_mesh_whose_far_vertices_collapse_every_face_on_welding(tmp_path):
    """A vertex at 1e9 with the rest within 1: inside float32's range, but welding at 1e-6 of the
    diagonal merges the whole grid; a clear error, not "mesh has no faces"."""
    v = grid()
    v[-1] = 1e9
    path = write_ply(tmp_path / "stray.ply", {"x": v[:, 0], "y": v[:, 1], "z": v[:, 2]}, grid_faces())
    status, _, err, _ = cli("render", path, "-o", tmp_path / "out.png", "--width", 64, "--height", 64)
    clear_error(status, err, path)
    assert "collapses every face" in err and "far-off vertices" in err
