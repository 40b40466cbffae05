"""E57 input (surfsplat.io.e57): scans with poses, colors, intensity, invalid points, damaged files."""

from __future__ import annotations

import re
import struct
import sys

import numpy as np
import pytest
from PIL import Image
from scipy.spatial.transform import Rotation

from surfsplat.pipeline import natural_up
from surfsplat.cli import main
from surfsplat.errors import InputError
from surfsplat.io import load
from surfsplat.io.e57 import quaternion_matrix, spherical_to_cartesian

#: Why the tests that write E57 files skip without pye57 (the others run: pose math, the missing-extra message).
PYE57_NEEDED = "writing E57 files needs pye57 (the e57 extra)"

#: Two scans of the same 24 x 24 grid in their own z = 0 plane: scan 0 red, turned 30 degrees about z and moved to
#: x = -1.2; scan 1 blue, turned by a general rotation (w x y z) and moved to x = +1.2.
POSES = [(np.array([np.cos(np.pi / 12), 0.0, 0.0, np.sin(np.pi / 12)]), np.array([-1.2, 0.0, 0.0])),
         (np.array([0.9, 0.1, -0.2, 0.3]) / np.linalg.norm([0.9, 0.1, -0.2, 0.3]), np.array([1.2, 0.05, 0.1]))]
COLORS = [(230, None, 10), (15, None, 220)]   # green: random in 0..59


def grid(n: int = 24) -> np.ndarray:
    s = np.linspace(-0.5, 0.5, n)
    x, y = np.meshgrid(s, s)
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(n * n)])


def write_two_scans(path, *, invalid_every: int = 0) -> list[dict]:
    """An E57 file of the two scans of :data:`POSES` (pye57; the test skips without it); returns what each
    scan holds."""
    pye57 = pytest.importorskip("pye57", reason=PYE57_NEEDED)
    rng = np.random.default_rng(7)
    scans = []
    with pye57.E57(str(path), mode="w") as e57:
        for (rotation, translation), color in zip(POSES, COLORS):
            local = grid()
            n = len(local)
            data = {"cartesianX": local[:, 0], "cartesianY": local[:, 1], "cartesianZ": local[:, 2],
                    "intensity": rng.uniform(0.0, 4000.0, n).astype(np.float32),
                    "colorRed": np.full(n, color[0], np.uint8), "colorGreen": rng.integers(0, 60, n).astype(np.uint8),
                    "colorBlue": np.full(n, color[2], np.uint8)}
            if invalid_every:
                data["cartesianInvalidState"] = np.where(np.arange(n) % invalid_every == 0, 2, 0).astype(np.int8)
            e57.write_scan_raw(data, rotation=rotation, translation=translation)
            scans.append(data)
    return scans


@pytest.fixture(scope="module")
def two_scans(tmp_path_factory):
    path = tmp_path_factory.mktemp("e57") / "two.e57"
    return path, write_two_scans(path)


def expected_positions(scans, keep=None) -> np.ndarray:
    """Each scan's local points (float32, as stored) moved by its pose, rotated with scipy's quaternions."""
    out = []
    for (q, t), data in zip(POSES, scans):
        local = np.column_stack([data[f"cartesian{c}"] for c in "XYZ"]).astype(np.float32).astype(np.float64)
        world = Rotation.from_quat([q[1], q[2], q[3], q[0]]).apply(local) + t   # scipy: x y z w
        out.append(world if keep is None else world[keep(data)])
    return np.concatenate(out)


def test_two_scans_with_poses_colors_and_intensity(two_scans):
    path, scans = two_scans
    cloud = load(path)
    assert len(cloud) == 2 * 24 * 24
    np.testing.assert_allclose(cloud.positions, expected_positions(scans), atol=2e-6)
    rgb = np.concatenate([np.column_stack([d["colorRed"], d["colorGreen"], d["colorBlue"]]) for d in scans])
    np.testing.assert_array_equal(cloud.colors, (rgb / 255.0).astype(np.float32))
    intensity = np.concatenate([d["intensity"] for d in scans])
    assert cloud.attributes["intensity"].dtype == np.float32
    np.testing.assert_allclose(cloud.attributes["intensity"], intensity, rtol=1e-6)
    np.testing.assert_array_equal(cloud.attributes["scan"], np.repeat([0, 1], 24 * 24))
    assert cloud.normals is None   # raw points: preprocessing estimates normals
    assert natural_up(path) == (0.0, 0.0, 1.0)   # scanners are z-up: framed like LiDAR


def test_invalid_points_are_dropped(tmp_path):
    path = tmp_path / "holes.e57"
    scans = write_two_scans(path, invalid_every=3)
    cloud = load(path)
    keep = lambda data: data["cartesianInvalidState"] == 0  # noqa: E731
    assert len(cloud) == sum(int(keep(d).sum()) for d in scans)
    np.testing.assert_allclose(cloud.positions, expected_positions(scans, keep), atol=2e-6)
    intensity = np.concatenate([d["intensity"][keep(d)] for d in scans])
    np.testing.assert_allclose(cloud.attributes["intensity"], intensity, rtol=1e-6)


def test_pose_and_spherical_math():
    rng = np.random.default_rng(3)
    for q in rng.normal(size=(5, 4)):
        expected = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()
        np.testing.assert_allclose(quaternion_matrix(q * 3.0), expected, atol=1e-12)   # normalized first
    with pytest.raises(InputError, match="not a rotation"):
        quaternion_matrix([0, 0, 0, 0])
    rae = np.array([[2.0, np.pi / 2, 0.0], [2.0, 0.0, np.pi / 2], [1.0, np.pi / 4, np.pi / 6], [3.0, np.pi, 0.0]])
    expected = np.array([[0, 2, 0], [0, 0, 2], [np.cos(np.pi / 6) / np.sqrt(2)] * 2 + [0.5], [-3, 0, 0]])
    np.testing.assert_allclose(spherical_to_cartesian(rae), expected, atol=1e-12)
    assert np.allclose(np.linalg.norm(spherical_to_cartesian(rae), axis=1), rae[:, 0])


def test_missing_pye57_names_the_extra(tmp_path, monkeypatch):
    # a file with a consistent 48-byte header (signature, version 1, its own length, 1024-byte pages) and no
    # scans: written without pye57, so this runs where the extra is absent
    path = tmp_path / "two.e57"
    path.write_bytes(struct.pack("<8sIIQQQQ", b"ASTM-E57", 1, 0, 1024, 48, 0, 1024).ljust(1024, b"\0"))
    monkeypatch.setitem(sys.modules, "pye57", None)   # `import pye57` now fails
    with pytest.raises(InputError, match=r"two\.e57: reading E57 files needs pye57.*\.\[e57\]"):
        load(path)


# -- damaged files -------------------------------------------------------------------------------------------

def _crc32c_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ (0x82F63B78 if crc & 1 else 0)
        table.append(crc)
    return table


CRC_TABLE = _crc32c_table()


def crc32c(data: bytes) -> int:
    """CRC-32C (Castagnoli), the checksum of every 1020-byte page of an E57 file."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc = CRC_TABLE[(crc ^ byte) & 0xFF] ^ (crc >> 8)
    return crc ^ 0xFFFFFFFF


def edit_xml(raw: bytes, old: bytes | re.Pattern, new: bytes) -> bytes:
    """The E57 file ``raw`` with the first ``old`` (bytes or a pattern) replaced by ``new`` (padded with spaces)
    in its XML section and every page's checksum recomputed: a damaged file that libE57's checksums cannot catch."""
    logical = bytearray(b"".join(raw[p:p + 1020] for p in range(0, len(raw), 1024)))
    xml_offset = struct.unpack_from("<Q", raw, 24)[0]
    xml_start = (xml_offset // 1024) * 1020 + xml_offset % 1024
    if isinstance(old, re.Pattern):
        old = old.search(bytes(logical), xml_start).group(0)
    assert len(new) <= len(old)
    start = logical.index(old, xml_start)
    logical[start:start + len(old)] = new.ljust(len(old))
    pages = [bytes(logical[p:p + 1020]) for p in range(0, len(logical), 1020)]
    return b"".join(page + struct.pack(">I", crc32c(page)) for page in pages)


def test_the_checksum_helper_makes_files_libe57_accepts(two_scans, tmp_path):
    path, _ = two_scans
    raw = path.read_bytes()
    assert crc32c(raw[:1020]) == struct.unpack(">I", raw[1020:1024])[0]
    same = tmp_path / "same.e57"
    same.write_bytes(edit_xml(raw, b'recordCount="576"', b'recordCount="576"'))
    assert len(load(same)) == 2 * 576


def test_spherical_scans_are_converted(two_scans, tmp_path):
    # the first scan's prototype renamed: its x, y, z columns read as range, azimuth, elevation (same stored data)
    path, scans = two_scans
    raw = path.read_bytes()
    old = re.search(rb'<prototype type="Structure">.*?</prototype>', b"".join(
        raw[p:p + 1020] for p in range(0, len(raw), 1024)), re.S).group(0)
    new = re.sub(rb">\s+<", b"><", old)
    for a, b in ((b"cartesianX", b"sphericalRange"), (b"cartesianY", b"sphericalAzimuth"),
                 (b"cartesianZ", b"sphericalElevation")):
        new = new.replace(a, b)
    spherical = tmp_path / "spherical.e57"
    spherical.write_bytes(edit_xml(raw, old, new))
    cloud = load(spherical)
    rae = np.column_stack([scans[0][f"cartesian{c}"] for c in "XYZ"]).astype(np.float32).astype(np.float64)
    q, t = POSES[0]
    local = np.column_stack([rae[:, 0] * np.cos(rae[:, 2]) * np.cos(rae[:, 1]),
                             rae[:, 0] * np.cos(rae[:, 2]) * np.sin(rae[:, 1]), rae[:, 0] * np.sin(rae[:, 2])])
    first = Rotation.from_quat([q[1], q[2], q[3], q[0]]).apply(local) + t
    np.testing.assert_allclose(cloud.positions[:576], first, atol=2e-6)
    np.testing.assert_allclose(cloud.positions[576:], expected_positions(scans)[576:], atol=2e-6)


COUNT = b'recordCount="576">\n        <prototype'


@pytest.mark.parametrize("damage, message", [
    (lambda raw: raw[:47], "not an E57 file"),
    (lambda raw: raw[:len(raw) // 2], "truncated or damaged"),
    (lambda raw: raw + b"\0" * 1024, "truncated or damaged"),
    (lambda raw: b"XXXX" + raw[4:], "not an E57 file"),
    (lambda raw: raw[:3000] + bytes([raw[3000] ^ 0xFF]) + raw[3001:], "checksum"),   # a flipped data byte
    (lambda raw: raw[:-900] + bytes(100) + raw[-800:], "checksum"),                   # zeroed XML bytes
    (lambda raw: edit_xml(raw, b'fileOffset="48"', b'fileOffset="9"'), "ErrorSeekFailed"),
    (lambda raw: edit_xml(raw, COUNT, b'recordCount="999999999999"><prototype'), "memory"),
    (lambda raw: edit_xml(raw, COUNT, b'recordCount="900"><prototype'), "only 576 of its 900 points"),
    (lambda raw: edit_xml(raw, re.compile(rb'<rotation type="Structure">.*?</rotation>', re.S),
                          b'<rotation type="Structure"><w type="Float">0</w></rotation>'), "not a rotation"),
    (lambda raw: edit_xml(raw, b'<prototype type="Structure">', b'<prototype type="Struct">'), "XML"),
])
def test_damaged_files_are_input_errors_naming_the_file(two_scans, tmp_path, damage, message):
    bad = tmp_path / "bad.e57"
    bad.write_bytes(damage(two_scans[0].read_bytes()))
    with pytest.raises(InputError, match=message) as info:
        load(bad)
    assert str(info.value).startswith(f"{bad}: cannot read E57 file")


@pytest.mark.gl
def test_cli_renders_the_scans_where_their_poses_put_them(two_scans, tmp_path, capsys):
    out = tmp_path / "scans.png"
    status = main(["-q", "render", str(two_scans[0]), "-o", str(out), "--width", "128", "--height", "64",
                   "--eye", "0", "0", "4", "--target", "0", "0", "0", "--up", "0", "1", "0", "--fov", "40"])
    assert status == 0, capsys.readouterr().err
    image = np.asarray(Image.open(out).convert("RGB")).astype(float)
    # x = -1.2 and +1.2 project to columns 36 and 92 (23 pixels a model unit at the plane z = 0)
    left, right = image[27:37, 31:41], image[27:37, 87:97]
    covered = lambda part: part[np.abs(part - 255).sum(axis=-1) > 30]   # noqa: E731 (not the white background)
    assert len(covered(left)) == left.shape[0] * left.shape[1]
    assert len(covered(right)) == right.shape[0] * right.shape[1]
    assert np.all(covered(left)[:, 0] > 2 * covered(left)[:, 2] + 20)       # red
    assert np.all(covered(right)[:, 2] > 2 * covered(right)[:, 0] + 20)     # blue
    # nothing between the patches: each reaches at most 0.71 (and a splat) from its center, |x| < 0.2 stays empty
    assert len(covered(image[:, 59:69])) == 0


def test_cli_damaged_file_is_one_line_error(two_scans, tmp_path, capsys):
    bad = tmp_path / "flipped.e57"
    raw = bytearray(two_scans[0].read_bytes())
    raw[5000] ^= 0x55
    bad.write_bytes(bytes(raw))
    assert main(["-q", "render", str(bad), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "cannot read E57 file" in err and "Traceback" not in err
