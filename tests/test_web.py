"""The web export without a browser: the web format's round trips (web/format.py), the shaders it ships
(the package's GLSL files composed for GLSL ES 3.00), the page's default view and the command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import surfsplat
from surfsplat.cli import main
from surfsplat.errors import InputError
from surfsplat.metrics import psnr
from surfsplat.pipeline import View
from surfsplat.rendering.options import RenderOptions
from surfsplat.rendering.passes import fill_depth, fill_reach, plan_frame
from surfsplat.rendering.shaders import PASS_ACCUMULATION, PASS_OPAQUE, PASS_VISIBILITY, compose, read_source
from surfsplat.rendering.techniques import TECHNIQUES, get_technique
from surfsplat.scenes import torus
from surfsplat.web import export
from surfsplat.web import format as wf
from surfsplat.web.export import FILES, as_drawn, page_payload, web_order
from surfsplat.web.framing import camera_from_frame, fit_frame
from surfsplat.web.shaders import MAX_PAGE_SUPERSAMPLE, PROGRAMS, WEB_TECHNIQUES, fill_program, shader_bundle


def unit_vectors(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [1, 1, -1e-9]], float)
    v = np.concatenate([v, axes])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_octahedral_normals_round_trip_within_1e_4_rad():
    n = unit_vectors(200_000)
    codes = wf.octahedral_encode(n)
    assert codes.dtype == np.uint16 and codes.shape == (len(n), 2)
    back = wf.octahedral_decode(codes)
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", back, n), -1, 1))
    assert np.allclose(np.linalg.norm(back, axis=1), 1.0)
    # a code step is 2 / 65534 of the octahedron's side
    assert angle.max() < 1e-4
    assert np.abs(back[-7:-1] - n[-7:-1]).max() < 1e-12   # the axes exactly (0 is a code)


def test_positions_round_trip_within_half_a_step_of_the_box():
    rng = np.random.default_rng(1)
    p = rng.uniform(-3, 7, size=(50_000, 3)) * [1.0, 0.01, 100.0]
    lo, hi = p.min(axis=0), p.max(axis=0)
    back = wf.dequantize_unit(wf.quantize_unit(p, lo, hi), lo, hi)
    step = (hi - lo) / 65535.0
    assert (np.abs(back - p) <= 0.5 * step * (1 + 1e-9)).all()
    assert (np.abs(back - p).max(axis=0) > 0.4 * step).all()   # the bound is tight: not a looser encoding


def test_fine_positions_round_trip_within_half_a_24_bit_step_and_keep_the_16_bit_stream_s_meaning():
    rng = np.random.default_rng(4)
    p = rng.uniform(-3, 7, size=(50_000, 3)) * [1.0, 0.01, 100.0]
    lo, hi = p.min(axis=0), p.max(axis=0)
    streams = wf.encode_positions(p, lo, hi, fine=True)
    assert streams["position"].dtype == np.uint16 and streams["position_fine"].dtype == np.uint8
    assert sum(a.nbytes for a in streams.values()) == (2 + 1) * p.size   # 3 bytes a splat more
    back = wf.decode_positions(streams, {"lo": lo, "hi": hi})
    step = (hi - lo) / wf.FINE_LEVELS
    assert (np.abs(back - p) <= 0.5 * step * (1 + 1e-6)).all()
    assert (np.abs(back - p).max(axis=0) > 0.4 * step).all()   # the bound is tight
    # the high 16 bits alone (a reader that knows no position_fine) stay within a 16-bit step
    coarse = wf.decode_positions({"position": streams["position"]}, {"lo": lo, "hi": hi})
    assert (np.abs(coarse - p) <= (hi - lo) / 65535.0 * (1 + 1e-6)).all()


def test_tangent_axes_round_trip():
    n = unit_vectors(20_000, seed=2)
    rng = np.random.default_rng(3)
    b1, b2 = wf.tangent_basis(n)
    assert np.allclose(np.einsum("ij,ij->i", b1, n), 0, atol=1e-12)
    assert np.allclose(np.einsum("ij,ij->i", b2, n), 0, atol=1e-12)
    assert np.allclose(np.cross(b1, b2), n, atol=1e-12)   # right-handed
    a = rng.uniform(0, 2 * np.pi, len(n))
    ru, rv = np.exp(rng.uniform(-8, 1, len(n))), np.exp(rng.uniform(-8, 1, len(n)))
    direction = np.cos(a)[:, None] * b1 + np.sin(a)[:, None] * b2
    u, v = direction * ru[:, None], np.cross(n, direction) * rv[:, None]
    angle, radii, log_range = wf.encode_tangents(n, u, v)
    u2, v2 = wf.decode_tangents(n, angle, radii, log_range)
    # the same ellipse: u up to its sign, lengths within half a step of the log2 range
    sign = np.sign(np.einsum("ij,ij->i", u, u2))
    half_log = 0.5 * (log_range[1] - log_range[0]) / 65535.0
    assert np.abs(np.log2(np.linalg.norm(u2, axis=1) / ru)).max() <= half_log * (1 + 1e-6)
    assert np.abs(np.log2(np.linalg.norm(v2, axis=1) / rv)).max() <= half_log * (1 + 1e-6)
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", u2 * sign[:, None], u) / (ru * np.linalg.norm(u2, axis=1)), -1, 1))
    assert turn.max() <= 0.5 * np.pi / 65536 + 1e-7
    assert np.allclose(np.einsum("ij,ij->i", u2, n), 0, atol=1e-9)
    assert np.allclose(np.einsum("ij,ij->i", u2, v2), 0, atol=1e-9)


def test_encode_is_19_bytes_a_splat_and_decodes():
    cloud = torus(24, 12)
    streams, header = wf.encode(cloud.positions, cloud.normals, cloud.colors, cloud.u, cloud.v)
    assert sum(a.nbytes for a in streams.values()) == wf.BYTES_PER_SPLAT * len(cloud) <= 20 * len(cloud)
    back = wf.decode(streams, header)
    step = np.ptp(cloud.positions, axis=0).max() / 65535
    assert np.abs(back["positions"] - cloud.positions).max() <= 0.5 * step + 1e-7
    assert np.abs(back["colors"] - cloud.colors).max() <= 0.5 / 255 + 1e-7
    assert np.allclose(np.abs(np.einsum("ij,ij->i", back["normals"], cloud.normals)), 1.0, atol=1e-8)


def test_clip_lines_keep_the_same_side_of_each_splat_in_the_frame_of_its_decoded_axes():
    # the codes keep an axis up to its sign: a point p = s u + t v of the splat has (s', t') = (su s, sv t) in
    # the decoded frame, and a s + b t + c must keep its sign there (Zwicker 2004, sec. 5)
    rng = np.random.default_rng(5)
    n = unit_vectors(4_000, seed=6)
    b1, b2 = wf.tangent_basis(n)
    a = rng.uniform(0, 2 * np.pi, len(n))   # half the axes point against their decoded ones
    direction = np.cos(a)[:, None] * b1 + np.sin(a)[:, None] * b2
    u, v = direction * 0.02, np.cross(n, direction) * 0.01
    positions, colors = rng.uniform(-1, 1, (len(n), 3)), rng.uniform(0, 1, (len(n), 3))
    lines = np.zeros((len(n), 2, 3))
    lines[:, :, 2] = 1.0                                  # (0, 0, 1): the whole disk kept
    cut = rng.random(len(n)) < 0.3
    lines[cut] = rng.uniform(-1, 1, (int(cut.sum()), 2, 3))
    streams, header = wf.encode(positions, n, colors, u, v)
    su, sv = wf.axis_signs(streams, header, u, v)
    assert 0.3 < (su < 0).mean() < 0.7 and np.array_equal(su, sv)   # v = n x u flips with u
    rows, codes = wf.encode_clip_lines(lines, su, sv)
    assert np.array_equal(rows, np.flatnonzero(cut)) and rows.dtype == np.uint32 and codes.dtype == np.float16
    decoded = wf.decode_clip_lines(rows, codes, len(n))
    assert not decoded[~cut].any()                        # zero lines: nothing cut, as the page's unbound attributes
    back = wf.decode(streams, header)
    st = rng.uniform(-1, 1, (len(n), 2))
    p = st[:, :1] * u + st[:, 1:] * v
    s2 = np.einsum("ij,ij->i", p, back["u"]) / np.einsum("ij,ij->i", back["u"], back["u"])
    t2 = np.einsum("ij,ij->i", p, back["v"]) / np.einsum("ij,ij->i", back["v"], back["v"])
    for k in range(2):
        side = lines[:, k, 0] * st[:, 0] + lines[:, k, 1] * st[:, 1] + lines[:, k, 2]
        kept = decoded[:, k, 0] * s2 + decoded[:, k, 1] * t2 + decoded[:, k, 2]
        clear = cut & (np.abs(side) > 1e-2)
        assert np.array_equal(side[clear] >= 0, kept[clear] >= 0)
        assert np.abs(kept - side)[cut].max() < 5e-3      # float16 lines, 16-bit axis angles
        unflipped = lines[:, k, 0] * s2 + lines[:, k, 1] * t2 + lines[:, k, 2]
        assert (np.sign(unflipped[clear]) != np.sign(side[clear])).mean() > 0.1   # the flip is needed


def test_phong_splats_keep_their_plane_shading_normal_and_normal_field_through_the_format(phong_sphere, tmp_path):
    cloud = phong_sphere
    drawn = as_drawn(cloud)
    order = web_order(cloud)[0]
    u, v, n, field = (np.asarray(x, np.float64)[order] for x in (cloud.u, cloud.v, cloud.normals, cloud.normal_field))
    du, dv = np.asarray(drawn.u, np.float64), np.asarray(drawn.v, np.float64)
    # the decoded axes span the splat's own plane (4 degrees off the shading normal), up to their signs
    plane = np.cross(u, v) / np.linalg.norm(np.cross(u, v), axis=1, keepdims=True)
    assert np.abs(np.einsum("ij,ij->i", du, plane)).max() < 1e-3 * np.linalg.norm(du, axis=1).min()
    su = np.sign(np.einsum("ij,ij->i", du, u))
    sv = np.sign(np.einsum("ij,ij->i", dv, v))
    assert np.allclose(du * su[:, None], u, atol=2e-4) and np.allclose(dv * sv[:, None], v, atol=2e-4)
    assert (su < 0).any()   # some axes decode flipped: the field must follow them
    # the shading normal is its own (octahedral), not the plane's
    assert np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", drawn.normals, n), -1, 1))).max() < 0.05
    # the field as vectors alpha u_hat, beta v_hat: unchanged by the flips, float16 precision
    unit = lambda a: a / np.linalg.norm(a, axis=1, keepdims=True)   # noqa: E731
    for k, (axis, decoded) in enumerate(((u, du), (v, dv))):
        assert np.allclose(drawn.normal_field[:, k, None] * unit(decoded), field[:, k, None] * unit(axis), atol=1e-3)
    # 8 bytes a splat more, and only for Phong splats; 3 more with 24-bit positions
    result = export(cloud, tmp_path / "phong")
    assert result.bytes == len(cloud) * (19 + 8)
    assert export(cloud.replace(normal_field=None), tmp_path / "plain").bytes == len(cloud) * 19
    assert export(cloud, tmp_path / "phong24", position_bits=24).bytes == len(cloud) * (22 + 8)


def test_a_browser_lod_tree_marks_the_nodes_over_clip_lines_which_a_cut_always_refines():
    import base64

    from surfsplat.hierarchy import build_hierarchy
    from surfsplat.hierarchy.lod import select, sharp_nodes
    from surfsplat.scenes import sphere_cube
    from surfsplat.web.tree import tree_entries, tree_streams
    h = build_hierarchy(sphere_cube(6000))
    clipped = np.any(h.points.clip_lines[:, :, :2] != 0, axis=(1, 2))
    sharp = sharp_nodes(h)
    expected = [clipped[s:s + c].any() for s, c in zip(h.node_point_start, h.node_point_count)]
    assert np.array_equal(sharp, expected) and 0 < sharp.sum() < len(h)
    bits = np.frombuffer(base64.b64decode(tree_streams(h)["sharp"]), np.uint8)
    assert np.array_equal(np.unpackbits(bits, bitorder="little")[:len(h)].astype(bool), sharp)
    # the desktop's cut at a coarse tolerance draws no node over clip lines (the page's rule is the same)
    camera = View(h).camera(None, 160, 120)
    assert not sharp[select(h, camera, 40.0, lod_shading="flat").node_indices()].any()
    # the page's entries: the nodes' lines keep their whole disks, the points keep their own
    entries = tree_entries(h)
    assert np.array_equal(entries.clip_lines[len(h):], h.points.clip_lines)
    assert np.all(entries.clip_lines[:len(h)] == np.array([0.0, 0.0, 1.0], np.float32))


def test_the_page_draws_every_technique_with_the_desktop_s_passes():
    # each technique's programs are its declared files with the desktop's pass ids; the fill pass is the
    # desktop's (passes.FillPass at one sample a pixel), with its depth tolerance in the header
    assert set(WEB_TECHNIQUES) == set(TECHNIQUES)
    for name in WEB_TECHNIQUES:
        technique = get_technique(name)
        steps = ("visibility", "accumulation") if technique.blended else ("",)
        for step in steps:
            program = f"{name}_{step}" if step else name
            vertex, fragment, defines = PROGRAMS[program]
            assert (vertex, fragment) == (technique.vertex, technique.fragment)
            assert defines["PASS"] == {"visibility": PASS_VISIBILITY, "accumulation": PASS_ACCUMULATION,
                                       "": PASS_OPAQUE}[step]
            assert (f"{program}_points" in PROGRAMS) == (technique.point_footprint is not None)
    header, _ = page_payload(torus(16, 8))
    for k in range(1, MAX_PAGE_SUPERSAMPLE + 1):   # one fill program per supersampling, as the desktop's
        for name in WEB_TECHNIQUES:   # every technique's frame: the page runs the one fill of its supersampling
            fill = plan_frame(get_technique(name), RenderOptions(), [(0, 1)], [], supersample=k).get("fill")
            assert PROGRAMS[fill_program(k)][2] == {"FILL_GAP": fill.gap, "FILL_REACH": fill_reach(fill.gap)}
            assert header["fill"][str(k)] == {"gap": fill.gap, "depth": fill_depth(fill.gap),
                                              "program": fill_program(k)}
    assert header["blended"] == [t for t in WEB_TECHNIQUES if get_technique(t).blended]


def test_shaders_js_is_what_the_composer_makes_of_the_current_files(tmp_path):
    export(torus(16, 8), tmp_path / "page")
    text = (tmp_path / "page" / "shaders.js").read_text()
    prefix = "window.SURFSPLAT_SHADERS = "
    assert text.startswith(prefix)
    shipped = json.loads(text[len(prefix):].rstrip().rstrip(";"))
    assert shipped == json.loads(json.dumps(shader_bundle()))
    assert set(shipped["programs"]) == set(PROGRAMS)
    for name, (vertex, fragment, defines) in PROGRAMS.items():
        files = ["<prologue>"]
        vs = compose(vertex, defines, files=files, version="#version 300 es")
        fs = compose(fragment, defines, files=files, version="#version 300 es")
        assert shipped["programs"][name]["vertex"] == vs.text
        assert shipped["programs"][name]["fragment"] == fs.text
        for source in (vs.text, fs.text):
            assert source.startswith("#version 300 es\nprecision highp float;\n")
            assert "#include" not in source
        # every line of every file used is in the shipped sources: a fix to a .glsl file lands in the page
        shipped_lines = set(vs.text.splitlines()) | set(fs.text.splitlines())
        for file in files[1:]:
            own = {line for line in read_source(file).splitlines() if not line.lstrip().startswith("#include")}
            assert own <= shipped_lines | {""}, file


def test_desktop_compositions_are_unchanged_by_the_es_variant():
    text = compose("ewa.frag", {"PASS": 2}).text
    assert text.startswith("#version 330 core\n#define MAX_LIGHTS")
    assert "precision" not in text.splitlines()[1]


@pytest.mark.parametrize("size", [(512, 512), (1024, 768), (300, 900), (97, 31)])
def test_the_page_default_view_is_the_render_default_view(size):
    view = View(torus(40, 20))
    from surfsplat.pipeline.framing import auto_fit_inputs
    from surfsplat.pipeline.models import as_model
    points, direction, up, margin = auto_fit_inputs(as_model(view.model).points(), view.up)
    frame = fit_frame(points, direction, up, margin)
    assert len(frame["hull_x"]) < len(points)
    mine = camera_from_frame(frame, 40.0, *size)
    theirs = view.camera(None, *size)
    assert np.allclose(mine.eye, theirs.eye, rtol=0, atol=1e-12)
    assert np.allclose(mine.target, theirs.target, rtol=0, atol=1e-12)
    assert np.allclose(mine.up, theirs.up)


def test_export_command_writes_replaces_and_refuses(tmp_path, capsys):
    out = tmp_path / "site"
    assert main(["export", "demo:torus", "-o", str(out), "-q"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES)
    page = (out / "index.html").read_text()
    assert '<script src="data.js"></script>' in page and "http" not in page.split("<body>")[1]
    assert main(["export", "demo:torus", "-o", str(out), "-q", "--technique", "points"]) == 0   # ours: replaced
    assert '"technique":"points"' in (out / "data.js").read_text()
    assert main(["export", "demo:torus", "-o", str(out), "-q", "--technique", "perspective", "--supersample", "2"]) == 0
    data = (out / "data.js").read_text()
    assert '"technique":"perspective"' in data and '"supersample":2' in data
    assert main(["export", "demo:torus", "-o", str(out), "-q", "--supersample", "5"]) == 2
    (out / "notes.txt").write_text("mine")
    assert main(["export", "demo:torus", "-o", str(out), "-q"]) == 2
    assert "--force" in capsys.readouterr().err and (out / "notes.txt").exists()
    mine = tmp_path / "mine.html"
    mine.write_text("<html>my page</html>")
    assert main(["export", "demo:torus", "-o", str(mine), "-q"]) == 2
    assert mine.read_text() == "<html>my page</html>"
    assert main(["export", "demo:torus", "-o", str(mine), "-q", "--force", "--technique", "flat"]) == 0
    single = mine.read_text()
    assert "<script src=" not in single and "window.SURFSPLAT_DATA" in single and "window.SURFSPLAT_SHADERS" in single
    assert main(["export", "demo:torus", "-o", str(tmp_path / "x"), "--technique", "sketch"]) == 2
    assert main(["export", str(tmp_path / "missing.ply"), "-o", str(tmp_path / "y")]) == 2
    assert "missing.ply" in capsys.readouterr().err and not (tmp_path / "y").exists()


def test_export_api_checks_its_arguments(tmp_path):
    with pytest.raises(InputError, match="not drawn by the web viewer"):
        surfsplat.export("demo:torus", tmp_path / "a", technique="sketch")
    with pytest.raises(InputError, match="point budget"):
        surfsplat.export("demo:torus", tmp_path / "a", point_budget=0)
    with pytest.raises(InputError, match="supersampling"):
        surfsplat.export("demo:torus", tmp_path / "a", supersample=5)
    assert page_payload(torus(16, 8), supersample=3)[0]["supersample"] == 3
    with pytest.raises(InputError, match="folder .* does not exist"):
        surfsplat.export("demo:torus", tmp_path / "no" / "a")
    result = surfsplat.export(torus(16, 8), tmp_path / "b.html")
    assert result.splats == 16 * 8 and result.bytes == 19 * 16 * 8 and result.files == (tmp_path / "b.html",)


@pytest.mark.gl
def test_quantization_costs_little_against_the_unquantized_render():
    cloud = torus(96, 48)
    streams, header = wf.encode(cloud.positions, cloud.normals, cloud.colors, cloud.u, cloud.v)
    back = wf.decode(streams, header)
    decoded = surfsplat.SplatCloud(back["positions"].astype("f4"), back["normals"].astype("f4"),
                                   back["colors"].astype("f4"), back["u"].astype("f4"), back["v"].astype("f4"))
    view = View(cloud)
    camera = view.camera(None, 256, 256)
    # measured: ewa 47 dB; flat 35.6 dB (an opaque disk's winner flips where two colours meet)
    for technique, least in (("ewa", 44.0), ("flat", 33.0)):
        a = view.render(camera, technique=technique).frame.image() / 255.0
        b = View(decoded).render(camera, technique=technique).frame.image() / 255.0
        assert psnr(b, a) > least, technique


def test_a_path_in_a_file_url_is_quoted(tmp_path):
    from surfsplat.web.browser import file_url
    assert file_url(tmp_path / "a b.html", "?ui=0").endswith("/a%20b.html?ui=0")
    assert Path(tmp_path / "a b.html").resolve().as_uri().startswith("file:///")


def test_a_hierarchy_is_exported_within_the_point_budget(tmp_path):
    cloud = torus(80, 40)
    path = tmp_path / "torus.npz"
    surfsplat.save_hierarchy(surfsplat.build_hierarchy(cloud), path)
    whole = surfsplat.export(path, tmp_path / "whole")
    assert whole.splats == len(cloud)   # within the default budget: the finest level, every point
    cut = surfsplat.export(path, tmp_path / "cut", point_budget=500)
    assert 0 < cut.splats <= 500
    data = (tmp_path / "cut" / "data.js").read_text()
    assert f'"count":{cut.splats}' in data
    cloud_cut = surfsplat.export(cloud, tmp_path / "cloud", point_budget=500)   # a cloud beyond the budget too
    assert 0 < cloud_cut.splats <= 500


def test_the_browser_driver_names_a_missing_browser(tmp_path):
    from surfsplat.web.browser import Browser, BrowserError
    with pytest.raises(BrowserError, match="no such executable"):
        Browser(str(tmp_path / "chromium"))


def _page_header(out):
    text = (out / "data.js").read_text()
    data = json.loads(text[text.index("=") + 1:].rstrip().rstrip(";"))
    return data["header"], data["streams"]


def test_the_page_colours_are_colorize_s_from_compact_attributes(tmp_path):
    import base64

    from surfsplat.colors import colorize
    from surfsplat.web.colors import page_colors
    rng = np.random.default_rng(5)
    base = torus(60, 30)
    n = len(base)
    attributes = {"classification": rng.choice([1, 2, 6, 9, 200], n).astype(np.uint8),
                  "intensity": rng.integers(0, 60_000, n).astype(np.uint16),
                  "gps_time": rng.uniform(1e5, 2e5, n), "nonplanar": np.zeros(n, np.uint8)}
    cloud = base.replace(attributes=attributes)
    header, streams = _page_header(surfsplat.export(cloud, tmp_path / "site").path)
    color = header["color"]
    # the desktop viewer's C cycle: own colours (the page's own), elevation, then the attributes sorted
    assert [m["name"] for m in color["modes"]] == ["elevation", "classification", "gps_time", "intensity"]
    kinds = {name: info["type"] for name, info in color["attributes"].items()}
    assert kinds == {"classification": "u8", "intensity": "u16", "gps_time": "u16"}   # 1 or 2 bytes a splat
    raw = {k: np.frombuffer(base64.b64decode(v), np.uint8 if k in ("color", "attr_classification") else np.uint16)
           for k, v in streams.items()}
    tables = {k: np.frombuffer(base64.b64decode(v), np.uint8).reshape(256, 3) for k, v in color["tables"].items()}
    assert set(tables) == {"asprs", "viridis"}
    positions = wf.decode_positions({"position": raw["position"].reshape(-1, 3)}, header)
    order = np.lexsort(positions.T)   # the page's order to the cloud's: match rows by position
    mine = np.lexsort(wf.decode_positions(wf.encode_positions(cloud.positions, header["lo"], header["hi"]), header).T)
    codes = {k: v[order] for k, v in raw.items() if k.startswith("attr_")}
    for name in ("classification", "intensity", "gps_time", "elevation"):
        page = page_colors({**color, "tables": tables}, codes, positions[order], name)
        desktop = np.rint(colorize(cloud, name, up=View(cloud).up).colors[mine] * 255).astype(int)
        same = (np.abs(page.astype(int) - desktop) <= 1).all(axis=1).mean()
        # integers exactly; a quantized float or position may cross a colormap bin: a few splats differ
        assert same >= (1.0 if name in ("classification", "intensity") else 0.99), name


def test_a_mesh_is_sampled_for_the_page_size_as_render_samples_for_its_size(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    mesh = tmp_path / "sphere.ply"
    trimesh.creation.icosphere(subdivisions=3).export(mesh)
    small = surfsplat.export(mesh, tmp_path / "small", size=(100, 75))
    large = surfsplat.export(mesh, tmp_path / "large", size=(200, 150))
    view = View(mesh)
    assert small.splats == len(view.sample(view.camera(None, 100, 75)).points())
    assert 3.0 < large.splats / small.splats < 5.0   # twice the size: four times the samples
    # back faces culled as the view plan culls them: the closed mesh's samples with ewa only
    header, _ = page_payload(mesh, size=(100, 75))
    camera = view.camera(None, 100, 75)
    assert header["culls"] == {t: view.culls(camera, technique=t) for t in WEB_TECHNIQUES}
    assert header["culls"] == {"ewa": True, "perspective": True, "phong": False, "blend": False, "flat": False,
                               "points": False}
    assert not any(page_payload(torus(40, 16), size=(100, 75))[0]["culls"].values())   # a cloud: two-sided
    with pytest.raises(InputError, match="page size"):
        surfsplat.export(mesh, tmp_path / "bad", size=(0, 10))
    with pytest.raises(InputError, match="memory budget"):
        surfsplat.export(mesh, tmp_path / "bad", browser_lod=True, memory_budget=0.5)
    assert main(["export", str(mesh), "-o", str(tmp_path / "cli"), "--size", "100", "75", "-q"]) == 0
    assert f'"count":{small.splats},' in (tmp_path / "cli" / "data.js").read_text()   # the same sampling
    assert main(["export", str(mesh), "-o", str(tmp_path / "cli2"), "--size", "0", "75"]) == 2


def test_a_chunked_hierarchy_exports_as_a_page_and_a_file_per_cell(tmp_path):
    from surfsplat.hierarchy.chunked import build_chunked, open_chunked
    from surfsplat.io import save_ply
    from surfsplat.web.export import page_payload
    save_ply(torus(60, 30), tmp_path / "torus.ply")
    build_chunked(tmp_path / "torus.ply", tmp_path / "torus.ssh", cell_points=400, scheduler="synchronous")
    model = open_chunked(tmp_path / "torus.ssh")
    result = surfsplat.export(tmp_path / "torus.ssh", tmp_path / "site", browser_lod=True, memory_budget=10**6)
    header, _ = _page_header(result.path)
    streamed = header["lod"]["streamed"]
    assert [c["key"] for c in streamed["cells"]] == [c["key"] for c in model.cells] and len(model.cells) > 3
    assert streamed["memory_budget"] == 10**6 and header["lod"]["nodes"] == len(model.top)
    files = sorted(p.name for p in (result.path / "cells").iterdir())
    assert files == sorted(f"{c['key']}.js" for c in model.cells)
    first = (result.path / "cells" / files[0]).read_text()
    index = [f"{c['key']}.js" for c in model.cells].index(files[0])
    assert first.startswith(f"surfsplatCell({index}, ")
    payload = json.loads(first[first.index(",") + 1:].rstrip().rstrip(";").rstrip(")"))
    h = model.cell(index)
    assert payload["header"]["count"] == len(h) + len(h.points) == streamed["cells"][index]["entries"]
    # every node and point once: the whole model is in the cells
    assert sum(c["entries"] for c in streamed["cells"]) == result.splats - header["count"]
    assert sum(len(model.cell(i).points) for i in range(len(model.cells))) == model.point_count
    with pytest.raises(InputError, match="folder of cell files"):
        surfsplat.export(tmp_path / "torus.ssh", tmp_path / "one.html", browser_lod=True)
    with pytest.raises(InputError, match="folder of cell files"):
        page_payload(tmp_path / "torus.ssh", browser_lod=True)
    assert main(["export", str(tmp_path / "torus.ssh"), "-o", str(result.path), "--browser-lod", "-q"]) == 0   # ours


@pytest.mark.data
def test_the_non_planar_flag_is_exported_one_bit_a_splat_where_the_view_plan_draws_hybrid(shared_data, tmp_path):
    import base64

    from surfsplat.geometry.preprocess import NONPLANAR
    from surfsplat.pipeline import SourceOptions
    from surfsplat.web.export import exported_splats, page_payload, web_order
    source = shared_data / "simple.las"
    header, streams = page_payload(source, size=(320, 240))
    plan = View(source)
    cloud = exported_splats(plan, plan.camera(None, 320, 240), None)
    expected = np.asarray(cloud.attributes[NONPLANAR], bool)[web_order(cloud)[0]]
    bits = np.frombuffer(base64.b64decode(streams["nonplanar"]), np.uint8)
    assert header["hybrid"] and len(bits) == (len(cloud) + 7) // 8
    assert np.array_equal(np.unpackbits(bits, bitorder="little")[:len(cloud)].astype(bool), expected)
    assert 0 < expected.sum() < len(expected)   # vegetation and ground both
    header, streams = page_payload(source, size=(320, 240), source_options=SourceOptions(hybrid=False))
    assert not header["hybrid"] and "nonplanar" not in streams
    header, streams = page_payload(torus(40, 16))   # not LiDAR: no flag
    assert not header["hybrid"] and "nonplanar" not in streams
    for flag, present in (("--hybrid", True), ("--no-hybrid", False)):
        assert main(["export", str(source), "-o", str(tmp_path / flag), flag]) == 0
        assert ('"nonplanar":' in (tmp_path / flag / "data.js").read_text()) == present


def test_a_page_exported_with_24_bit_positions_keeps_them(tmp_path):
    from surfsplat.web.page import as_drawn, web_order
    cloud = torus(60, 30)
    drawn = as_drawn(cloud, fine_positions=True)   # in the page's order
    step = np.ptp(cloud.positions.astype(np.float64), axis=0) / wf.FINE_LEVELS
    err = np.abs(drawn.positions.astype(np.float64) - cloud.positions[web_order(cloud)[0]])
    # half a 24-bit step of the box, and float32's rounding of the result (16-bit codes: 256 times more)
    assert (err <= 0.5 * step + 4e-7).all()
    assert err.max() < np.ptp(cloud.positions, axis=0).max() / 65535 / 8
    coarse = np.abs(as_drawn(cloud).positions.astype(np.float64) - cloud.positions[web_order(cloud)[0]])
    assert coarse.max() > 16 * err.max()   # the default: 16-bit positions
    # from the command line: the page's streams, and a clear error for other precisions
    assert main(["export", "demo:torus", "-o", str(tmp_path / "fine"), "--position-bits", "24"]) == 0
    assert '"position_fine":' in (tmp_path / "fine" / "data.js").read_text()
    assert main(["export", "demo:torus", "-o", str(tmp_path / "coarse")]) == 0
    assert '"position_fine":' not in (tmp_path / "coarse" / "data.js").read_text()
    for bad in (20, 24.0, "24", True, None):
        with pytest.raises(InputError, match="position bits"):
            export(cloud, tmp_path / "bad", position_bits=bad)
