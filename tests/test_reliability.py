"""Reliability (no traceback, no hang, no lost file, no silently wrong picture): every fault a
fuzz run found, reproduced with a small generated file, and a small seeded fuzz of the readers."""

from __future__ import annotations

import io
import os
import resource
import signal
import struct
import threading
import zipfile

import numpy as np
import pytest

from surfsplat import InputError, SplatCloud, scenes
from surfsplat.cli import main
from surfsplat.hierarchy import Hierarchy, build_hierarchy, load_hierarchy, save_hierarchy
from surfsplat.io import npz as npz_reader
from surfsplat.io import Mesh, load, load_input, load_mesh, save_ply


# -- helpers ---------------------------------------------------------------------------------------


def ply_header(fmt: str, n: int, faces: int | None = None) -> bytes:
    text = f"ply\nformat {fmt} 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
    if faces is not None:
        text += f"element face {faces}\nproperty list uchar int vertex_indices\n"
    return (text + "end_header\n").encode("ascii")


def binary_ply(n: int = 20, declared: int | None = None, seed: int = 0) -> bytes:
    xyz = np.random.default_rng(seed).random((n, 3)).astype("<f4")
    return ply_header("binary_little_endian", n if declared is None else declared) + xyz.tobytes()


def small_las(path, n: int = 50, rgb: np.ndarray | None = None, version: str = "1.2"):
    """A small LAS file of ``n`` random points (laspy: the test skips without it)."""
    laspy = pytest.importorskip("laspy")
    header = laspy.LasHeader(point_format=2, version=version)
    header.scales = np.array([0.001, 0.001, 0.001])
    las = laspy.LasData(header)
    rng = np.random.default_rng(1)
    las.x, las.y, las.z = (rng.random(n) for _ in range(3))
    if rgb is not None:
        las.red, las.green, las.blue = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    las.write(str(path))
    return path


def small_hierarchy() -> Hierarchy:
    return build_hierarchy(scenes.sphere(400, coverage=1.2))


def npy_bytes(array: np.ndarray, shape: tuple | None = None) -> bytes:
    """``array`` as .npy bytes, optionally with a lying ``shape`` in the header."""
    stream = io.BytesIO()
    np.save(stream, array)
    data = stream.getvalue()
    if shape is not None:
        old = repr(array.shape).encode()
        new = repr(shape).encode()
        header_len = struct.unpack_from("<H", data, 8)[0]
        header = data[10:10 + header_len].replace(old, new)
        header = header.rstrip(b" \n")
        pad = (64 - (10 + len(header) + 1) % 64) % 64
        header = header + b" " * pad + b"\n"
        data = data[:8] + struct.pack("<H", len(header)) + header + data[10 + header_len:]
    return data


def no_temp_files(folder) -> bool:
    return not [p for p in os.listdir(folder) if p.endswith(".tmp")]


# -- sizes declared in headers -------------------------------------------------------------------


@pytest.mark.parametrize("count", [2**31, 2**35, 2**40])
def test_ply_binary_huge_vertex_count(tmp_path, count):
    path = tmp_path / "huge.ply"
    path.write_bytes(binary_ply(20, declared=count))
    with pytest.raises(InputError, match=r"huge\.ply: .*declares .* but only 240 bytes follow"):
        load(path)


def test_ply_ascii_huge_vertex_count(tmp_path):
    path = tmp_path / "huge.ply"
    path.write_bytes(ply_header("ascii", 2**40) + b"0 0 0\n1 1 1\n")
    with pytest.raises(InputError, match=r"huge\.ply: .*body has 2 lines"):
        load(path)


def test_ply_binary_huge_face_count(tmp_path):
    path = tmp_path / "faces.ply"
    path.write_bytes(ply_header("binary_little_endian", 3, faces=2**40) + np.zeros(9, "<f4").tobytes())
    with pytest.raises(InputError, match=r"faces\.ply: .*declares 3 vertex, 1099511627776 face"):
        load_input(path)


def test_ply_header_declares_half_the_vertices(tmp_path):
    path = tmp_path / "half.ply"
    path.write_bytes(binary_ply(20, declared=10))
    with pytest.raises(InputError, match=r"half\.ply: .*room for 10 more 'vertex' records"):
        load(path)
    ascii = tmp_path / "half_ascii.ply"
    ascii.write_bytes(ply_header("ascii", 2) + b"0 0 0\n1 1 1\n2 2 2\n3 3 3\n")
    with pytest.raises(InputError, match=r"half_ascii\.ply: .*more than declared"):
        load(ascii)


def test_ply_ascii_body_labelled_binary(tmp_path):
    path = tmp_path / "label.ply"
    path.write_bytes(ply_header("binary_little_endian", 2) + b"0.1 0.2 0.3\n1.5 1.5 1.5\n")
    with pytest.raises(InputError, match=r"label\.ply: .*body is ascii text"):
        load(path)


def test_las_point_count_at_maximum(tmp_path):
    path = small_las(tmp_path / "count.las")
    data = bytearray(path.read_bytes())
    data[107:111] = struct.pack("<I", 0xFFFFFFFF)
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"count\.las: .*4,294,967,295 points"):
        load(path)
    path14 = small_las(tmp_path / "count14.las", version="1.4")
    data = bytearray(path14.read_bytes())
    data[247:255] = struct.pack("<Q", 2**63)
    path14.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"count14\.las: .*points"):
        load(path14)


def test_las_huge_vlr_count(tmp_path):
    path = small_las(tmp_path / "vlr.las")
    data = bytearray(path.read_bytes())
    data[100:104] = struct.pack("<I", 0xFFFFFFF0)
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"vlr\.las: .*VLRs"):
        load(path)


def zip_with(path, members: dict[str, bytes], compress=zipfile.ZIP_STORED):
    with zipfile.ZipFile(path, "w", compression=compress) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def test_npz_member_declaring_terabyte_shape(tmp_path):
    path = zip_with(tmp_path / "shape.npz", {"order.npy": npy_bytes(np.arange(10), shape=(2**40,))})
    with pytest.raises(InputError, match=r"shape\.npz: member 'order' declares shape \(1099511627776,\)"):
        load_hierarchy(path)


def test_npz_zip_bomb(tmp_path, monkeypatch):
    path = zip_with(tmp_path / "bomb.npz", {"order.npy": npy_bytes(np.zeros(8 << 20, np.int64))},
                    compress=zipfile.ZIP_DEFLATED)
    assert path.stat().st_size < 1 << 20
    monkeypatch.setattr(npz_reader, "memory_limit", lambda: 16 << 20)
    with pytest.raises(InputError, match=r"bomb\.npz: the archive inflates to 67,108,992 bytes"):
        load_hierarchy(path)


def test_npz_pickled_member_refused(tmp_path):
    stream = io.BytesIO()
    np.save(stream, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    path = zip_with(tmp_path / "pickle.npz", {"order.npy": stream.getvalue()})
    with pytest.raises(InputError, match=r"pickle\.npz: member 'order' holds Python objects"):
        load_hierarchy(path)


# -- what is not a regular file --------------------------------------------------------------------


def test_non_regular_inputs_refused(tmp_path):
    fifo = tmp_path / "pipe.ply"
    os.mkfifo(fifo)
    zero_npz, zero_ply = tmp_path / "zero.npz", tmp_path / "zero.ply"
    zero_npz.symlink_to("/dev/zero")
    zero_ply.symlink_to("/dev/zero")
    folder = tmp_path / "folder.ply"
    folder.mkdir()
    result = {}

    def attempt():
        for name, call in [("fifo", lambda: load(fifo)), ("fifo_npz", lambda: load_hierarchy(fifo)),
                           ("zero_npz", lambda: load_hierarchy(zero_npz)), ("zero_ply", lambda: load(zero_ply)),
                           ("folder", lambda: load_mesh(folder))]:
            try:
                call()
            except InputError as exc:
                result[name] = str(exc)

    worker = threading.Thread(target=attempt, daemon=True)
    worker.start()
    worker.join(10)
    if worker.is_alive():  # unblock a reader stuck on the FIFO before failing
        with open(fifo, "wb"):
            pass
        pytest.fail(f"a reader blocked; done: {sorted(result)}")
    assert "FIFO" in result["fifo"] and "FIFO" in result["fifo_npz"]
    assert "device" in result["zero_npz"] and "device" in result["zero_ply"]
    assert "directory" in result["folder"]


# -- LAZ -------------------------------------------------------------------------------------------


def test_corrupt_laz_is_an_input_error(tmp_path):
    pytest.importorskip("lazrs")
    good = small_las(tmp_path / "good.laz", n=3000)
    assert len(load(good)) > 0
    data = good.read_bytes()
    middle = len(data) // 2
    for k, bad in enumerate([data[:middle] + data[middle - 200:],          # duplicated bytes
                             data[:middle] + bytes(range(256)) * 4 + data[middle:],  # inserted bytes
                             data[:middle]]):                               # truncated
        path = tmp_path / f"bad{k}.laz"
        path.write_bytes(bad)
        try:
            cloud = load(path)
        except InputError as exc:
            assert f"bad{k}.laz" in str(exc)
        else:
            assert isinstance(cloud, SplatCloud)


# -- colours ---------------------------------------------------------------------------------------


def test_las_8bit_colors_with_one_outlier(tmp_path):
    rgb = np.full((50, 3), 200, dtype=np.uint16)
    rgb[7, 0] = 300
    cloud = load(small_las(tmp_path / "colors.las", rgb=rgb))
    assert np.allclose(cloud.colors[0], 200 / 255) and cloud.colors[7, 0] == 1.0
    rgb16 = np.full((50, 3), 40000, dtype=np.uint16)
    cloud = load(small_las(tmp_path / "colors16.las", rgb=rgb16))
    assert np.allclose(cloud.colors, 40000 / 65535)


# -- face indices ----------------------------------------------------------------------------------


@pytest.mark.parametrize("face, problem", [("f 0 1 2", "vertex 0"), ("f 1 2 4", "vertex 4"),
                                           ("f 1/1 2/2 -4/1", "vertex -4")])
def test_obj_face_index_out_of_range(tmp_path, face, problem):
    path = tmp_path / "bad.obj"
    path.write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\n{face}\n")
    for reader in (load, load_mesh, load_input):
        with pytest.raises(InputError, match=rf"bad\.obj: .*{problem}"):
            reader(path)


def test_ply_face_index_out_of_range(tmp_path):
    path = tmp_path / "bad.ply"
    path.write_bytes(ply_header("ascii", 3, faces=1) + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n")
    with pytest.raises(InputError, match=r"bad\.ply: face 0 refers to vertex 3"):
        load_input(path)


# -- outputs ---------------------------------------------------------------------------------------


def with_file_size_limit(limit: int, call):
    """Run ``call`` with RLIMIT_FSIZE set to ``limit`` bytes (SIGXFSZ ignored: writes fail with EFBIG)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    previous = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))
    try:
        return call()
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, previous)


def test_save_ply_failure_keeps_the_old_file(tmp_path):
    path = tmp_path / "out.ply"
    save_ply(SplatCloud(positions=np.ones((5, 3))), path)
    old = path.read_bytes()
    big = SplatCloud(positions=np.random.default_rng(0).random((100_000, 3)))
    with pytest.raises(InputError, match=r"out\.ply: cannot write"):
        with_file_size_limit(64 * 1024, lambda: save_ply(big, path, overwrite=True))
    assert path.read_bytes() == old and no_temp_files(tmp_path)
    with pytest.raises(InputError, match=r"new\.ply: cannot write"):
        with_file_size_limit(64 * 1024, lambda: save_ply(big, tmp_path / "new.ply"))
    assert not (tmp_path / "new.ply").exists() and no_temp_files(tmp_path)


def test_save_hierarchy_failure_keeps_the_old_file(tmp_path):
    hierarchy = small_hierarchy()
    path = tmp_path / "h.npz"
    path.write_bytes(b"old contents")
    with pytest.raises(InputError, match=r"h\.npz: cannot write"):
        with_file_size_limit(4096, lambda: save_hierarchy(hierarchy, path, overwrite=True))
    assert path.read_bytes() == b"old contents" and no_temp_files(tmp_path)
    save_hierarchy(hierarchy, path, overwrite=True)
    assert len(load_hierarchy(path).points) == len(hierarchy.points)


def test_output_hard_link_of_input_refused(tmp_path, capsys):
    source = tmp_path / "in.ply"
    save_ply(scenes.sphere(300, coverage=1.2), source)
    old = source.read_bytes()
    link = tmp_path / "link.ply"
    os.link(source, link)
    for command in (["preprocess"], ["phong", "--count", "50"], ["build"]):
        out = link if command[0] != "build" else tmp_path / "link.npz"
        if command[0] == "build":
            os.link(source, out)
        status = main(["-q", *command, str(source), "-o", str(out), "--force"])
        err = capsys.readouterr().err
        assert status != 0 and "refusing to overwrite" in err, (command, err)
    assert source.read_bytes() == old and link.read_bytes() == old


# -- fuzz ------------------------------------------------------------------------------------------


def seeds(tmp_path) -> dict[str, bytes]:
    """Valid small files of each format, by extension."""
    rng = np.random.default_rng(3)
    mesh_ply = tmp_path / "seed_mesh.ply"
    xyz = rng.random((6, 3)).astype("<f4")
    faces = np.array([[0, 1, 2], [2, 3, 4], [3, 4, 5]])
    body = xyz.tobytes() + b"".join(b"\x03" + f.astype("<i4").tobytes() for f in faces)
    mesh_ply.write_bytes(ply_header("binary_little_endian", 6, faces=3) + body)
    ascii_ply = ply_header("ascii", 4) + b"0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
    obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n"
    las = small_las(tmp_path / "seed.las", n=20, rgb=np.full((20, 3), 100, np.uint16)).read_bytes()
    npz = tmp_path / "seed.npz"
    save_hierarchy(build_hierarchy(scenes.sphere(60, coverage=1.2), leaf_capacity=8), npz)
    return {".ply": binary_ply(12), ".asc.ply": ascii_ply, ".mesh.ply": mesh_ply.read_bytes(),
            ".obj": obj, ".las": las, ".npz": npz.read_bytes()}


def mutate(data: bytes, rng: np.random.Generator) -> bytes:
    data = bytearray(data)
    kind = rng.integers(5)
    if kind == 0:  # byte flips
        for _ in range(int(rng.integers(1, 8))):
            data[int(rng.integers(len(data)))] = int(rng.integers(256))
    elif kind == 1:  # truncation
        data = data[:int(rng.integers(len(data)))]
    elif kind == 2:  # duplicated / inserted bytes
        at = int(rng.integers(len(data)))
        data[at:at] = data[max(0, at - int(rng.integers(1, 64))):at] if rng.random() < 0.5 else rng.bytes(16)
    elif kind == 3:  # header count edits (ascii numbers)
        text = bytes(data)
        digits = [i for i in range(min(len(text), 400)) if chr(text[i]).isdigit()]
        if digits:
            at = digits[int(rng.integers(len(digits)))]
            data[at:at + 1] = str(rng.choice([0, 9, 99999, 2**31, 2**40])).encode()
    else:  # binary count fields (LAS header) / random 4 bytes
        at = int(rng.integers(max(1, min(len(data) - 4, 300))))
        data[at:at + 4] = struct.pack("<I", int(rng.choice([0, 1, 2**31, 0xFFFFFFFF])))
    return bytes(data)


@pytest.mark.filterwarnings("ignore")
def test_fuzz_readers_raise_only_input_error(tmp_path):
    rng = np.random.default_rng(2024)
    files = seeds(tmp_path)
    readers = {".ply": load_input, ".asc.ply": load_input, ".mesh.ply": load_input, ".obj": load_input,
               ".las": load, ".npz": load_hierarchy}
    failures = []
    cases = 0
    for ext, data in files.items():
        for k in range(60):
            path = tmp_path / f"fuzz{k}{ext}"
            path.write_bytes(mutate(data, rng))
            result: dict = {}

            def attempt():
                try:
                    result["value"] = readers[ext](path)
                except InputError:
                    result["value"] = None
                except BaseException as exc:  # noqa: BLE001 - the fuzz records anything else
                    result["error"] = exc

            worker = threading.Thread(target=attempt, daemon=True)
            worker.start()
            worker.join(10)
            cases += 1
            if worker.is_alive():
                failures.append((path.name, "hang"))
            elif "error" in result:
                failures.append((path.name, repr(result["error"])))
            else:
                assert result["value"] is None or isinstance(result["value"], (SplatCloud, Mesh, Hierarchy))
            path.unlink(missing_ok=True)
    assert cases == 360
    assert not failures, failures[:10]
