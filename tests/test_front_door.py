"""What a newcomer meets first at the command line: outputs replaced (atomically) on a second run,
inputs never overwritten, short usage errors with suggestions, and misspelt colour options refused
before any file is read."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from PIL import Image

from surfsplat import SplatCloud
from surfsplat.cli import main
from surfsplat.colors import ColorOptions, attribute_values, check_color_source, check_colormap
from surfsplat.errors import InputError
from surfsplat.io import save_ply
from surfsplat.io.atomic import atomic_path, same_file


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main(["-q", *map(str, argv)])
    out, err = capsys.readouterr()
    return status, out, err


def sphere_points(n: int = 800, seed: int = 0) -> SplatCloud:
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return SplatCloud(p / np.linalg.norm(p, axis=1, keepdims=True))


def leftovers(folder) -> list[str]:
    """Hidden temporary files or folders the atomic writes may have left."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


# -- outputs replaced, inputs refused ----------------------------------------------------------

@pytest.mark.gl   # renders through the command line
def test_demo_twice_replaces_its_output(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert run(capsys, "demo", "-o", "demo.png", "--width", 32, "--height", 24)[0] == 0
    first = (tmp_path / "demo.png").stat().st_ino
    status, _, err = run(capsys, "demo", "-o", "demo.png", "--width", 40, "--height", 20)
    assert status == 0, err
    with Image.open(tmp_path / "demo.png") as image:
        assert image.size == (40, 20)   # the second picture, not the first
    assert (tmp_path / "demo.png").stat().st_ino != first   # a new file renamed over the old one
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("link", ["same", "hard link", "symbolic link"])
def test_an_output_that_is_an_input_is_refused(tmp_path, capsys, link):
    source = save_ply(sphere_points(), tmp_path / "points.ply")
    before = source.read_bytes()
    out = {"same": source, "hard link": tmp_path / "hard.ply", "symbolic link": tmp_path / "sym.ply"}[link]
    if link == "hard link":
        os.link(source, out)
    elif link == "symbolic link":
        out.symlink_to(source)
    assert same_file(out, source)
    status, _, err = run(capsys, "preprocess", source, "-o", out)
    assert status == 2 and "refusing to overwrite the input file" in err and "Traceback" not in err
    assert source.read_bytes() == before
    assert run(capsys, "preprocess", source, "-o", out, "--force")[0] == 2   # --force changes nothing
    assert source.read_bytes() == before


def test_input_flags_count_as_inputs(tmp_path, capsys):
    """--camera and --path files are inputs too: an output naming them is refused before any work."""
    cam = tmp_path / "cam.json"
    assert run(capsys, "demo", "-o", tmp_path / "a.png", "--width", 16, "--height", 16, "--save-camera", cam)[0] == 0
    before = cam.read_bytes()
    status, _, err = run(capsys, "demo", "-o", tmp_path / "b.png", "--camera", cam, "--save-camera", cam)
    assert status == 2 and "refusing to overwrite the input file" in err
    status, _, err = run(capsys, "turntable", "demo:sphere", "-o", cam.with_suffix(".gif"), "--path", cam,
                         "--frames", 2)
    assert status == 0 or "key views" in err   # one key view: a path needs two (not an output problem)
    assert cam.read_bytes() == before
    status, _, err = run(capsys, "demo", "-o", tmp_path / "c.png", "--save-camera", tmp_path / "c.png")
    assert status == 2 and "same file" in err


def test_the_viewer_refuses_to_record_over_its_input_before_opening_a_window(tmp_path, capsys):
    source = save_ply(sphere_points(), tmp_path / "points.ply")
    before = source.read_bytes()
    for flag in ("--screenshot", "--record"):
        status, _, err = run(capsys, "view", source, flag, source)
        assert status == 2 and "refusing to overwrite the input file" in err, err
    assert source.read_bytes() == before


def test_an_interrupted_write_leaves_the_old_file(tmp_path):
    path = tmp_path / "out.bin"
    path.write_bytes(b"old and complete")
    for failure in (OSError(28, "No space left on device"), KeyboardInterrupt()):
        with pytest.raises((InputError, KeyboardInterrupt)):
            with atomic_path(path) as temp:
                temp.write_bytes(b"new but half")
                raise failure
        assert path.read_bytes() == b"old and complete"
        assert leftovers(tmp_path) == []
    with atomic_path(path) as temp:
        temp.write_bytes(b"new")
    assert path.read_bytes() == b"new" and leftovers(tmp_path) == []


@pytest.mark.gl   # renders through the command line
def test_a_failing_image_writer_in_the_cli_leaves_the_old_image(tmp_path, capsys, monkeypatch):
    out = tmp_path / "demo.png"
    assert run(capsys, "demo", "-o", out, "--width", 16, "--height", 16)[0] == 0
    before = out.read_bytes()

    def disk_full(self, fp, *args, **kwargs):
        with open(fp, "wb") as handle:
            handle.write(b"\x89PNG half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Image.Image, "save", disk_full)
    status, _, err = run(capsys, "demo", "-o", out, "--width", 24, "--height", 24)
    assert status == 2 and "demo.png" in err and "No space left" in err and "Traceback" not in err
    assert out.read_bytes() == before and leftovers(tmp_path) == []


def test_folders_are_replaced_whole_or_not_at_all(tmp_path):
    folder = tmp_path / "model.ssh"
    folder.mkdir()
    (folder / "old.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(folder, directory=True) as temp:
            (temp / "new.txt").write_text("new")
            raise RuntimeError("a cell task failed")
    assert sorted(p.name for p in folder.iterdir()) == ["old.txt"] and leftovers(tmp_path) == []
    with atomic_path(folder, directory=True) as temp:
        (temp / "new.txt").write_text("new")
    assert sorted(p.name for p in folder.iterdir()) == ["new.txt"] and leftovers(tmp_path) == []


def test_a_chunked_build_never_replaces_a_foreign_folder(tmp_path, capsys):
    source = save_ply(sphere_points(), tmp_path / "points.ply")
    folder = tmp_path / "photos"
    folder.mkdir()
    (folder / "holiday.jpg").write_bytes(b"precious")
    status, _, err = run(capsys, "build", source, "-o", folder, "--chunked")
    assert status == 2 and "not a chunked hierarchy" in err
    assert (folder / "holiday.jpg").read_bytes() == b"precious"
    tiles = tmp_path / "tiles"
    tiles.mkdir()
    status, _, err = run(capsys, "build", tiles, "-o", tiles, "--chunked")
    assert status == 2 and "input" in err


# -- short usage errors with suggestions --------------------------------------------------------

def usage_error(capsys, *argv) -> list[str]:
    """The stderr lines of a command line that must be a usage error (exit status 2)."""
    assert main([*map(str, argv)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    return err.splitlines()


def test_a_bad_value_prints_the_short_usage_and_the_error(capsys):
    lines = usage_error(capsys, "render", "in.ply", "-o", "out.png", "--fov", "wide")
    assert len(lines) <= 4, lines
    assert lines[0] == "usage: surfsplat render INPUT... -o OUTPUT [options]"
    assert lines[1].startswith("surfsplat render: error: argument --fov:") and "'wide'" in lines[1]
    assert "see `surfsplat render --help`" in lines[-1]


@pytest.mark.parametrize("argv, hint", [
    (["render", "in.ply", "-o", "out.png", "--techniqe", "ewa"], "did you mean --technique?"),
    (["render", "in.ply", "-o", "out.png", "--technique", "ewq"], "did you mean 'ewa'?"),
    (["rendr", "in.ply", "-o", "out.png"], "did you mean 'render'?"),
    (["build", "in.ply", "-o", "m.npz", "--leaf-capacty", "4"], "did you mean --leaf-capacity?"),
    (["demo", "--scene", "tours"], "did you mean 'torus'?"),
    (["view", "in.ply", "--lod-mode", "gpus"], "did you mean 'gpu'?"),
    (["sample", "m.ply", "-n", "5", "-o", "s.ply", "--smoth-normals"], "did you mean --smooth-normals?"),
])
def test_misspellings_get_a_suggestion(capsys, argv, hint):
    lines = usage_error(capsys, *argv)
    assert len(lines) <= 4, lines
    assert lines[0].startswith("usage: surfsplat ")
    assert hint in "\n".join(lines)


def test_no_suggestion_for_nothing_close(capsys):
    lines = usage_error(capsys, "render", "in.ply", "-o", "out.png", "--zzzzzz")
    assert "unrecognized arguments: --zzzzzz" in lines[1] and "did you mean" not in "\n".join(lines)
    lines = usage_error(capsys, "render", "in.ply")
    assert lines[1] == "surfsplat render: error: the following arguments are required: -o/--output"


def test_help_is_still_the_full_help(capsys):
    assert main(["render", "--help"]) == 0
    out = capsys.readouterr().out
    assert "--technique" in out and "--colormap" in out and len(out.splitlines()) > 50


# -- colour options checked early -------------------------------------------------------------------

def test_a_colormap_typo_fails_before_anything_is_read(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    import matplotlib

    _ = list(matplotlib.colormaps)   # imported once (the test times the check, not the import)
    big = save_ply(sphere_points(400_000), tmp_path / "big.ply")   # seconds to load and preprocess
    start = time.perf_counter()
    status = main(["render", str(big), "-o", str(tmp_path / "x.png"), "--color-by", "elevation",
                   "--colormap", "virdis"])
    seconds = time.perf_counter() - start
    err = capsys.readouterr().err
    assert status == 2 and seconds < 1.0, seconds
    assert "did you mean 'viridis'?" in err and "loading" not in err and len(err.splitlines()) <= 4
    assert not (tmp_path / "x.png").exists()
    small = save_ply(sphere_points(300), tmp_path / "small.ply")   # the control: this one is read
    assert main(["render", str(small), "-o", str(tmp_path / "x.png"), "--color-by", "nope"]) == 2
    err = capsys.readouterr().err
    assert "loading" in err and "no attribute 'nope'" in err


def test_colormap_names_are_checked_by_color_options():
    assert check_colormap("asprs") == "asprs" and check_colormap("ASPRS") == "ASPRS"
    ColorOptions("classification", "asprs")
    pytest.importorskip("matplotlib")
    for name in ("viridis", "turbo", "Greys"):
        assert ColorOptions("elevation", name).colormap == name
    with pytest.raises(InputError, match="did you mean 'viridis'"):
        ColorOptions("elevation", "Viridis")   # matplotlib's names are case-sensitive
    with pytest.raises(InputError, match="unknown colormap 'no-such-map'"):
        ColorOptions("elevation", "no-such-map")


def test_without_matplotlib_only_the_built_in_palette(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "matplotlib", None)   # import matplotlib -> ImportError
    assert check_colormap("asprs") == "asprs"
    with pytest.raises(InputError, match="needs matplotlib"):
        ColorOptions("intensity", "viridis")
    with pytest.raises(InputError, match="use 'asprs'"):
        check_colormap("aprs")


def test_check_color_source_agrees_with_colouring():
    rng = np.random.default_rng(3)
    cloud = SplatCloud(rng.normal(size=(50, 3)), attributes={"intensity": rng.uniform(size=50),
                                                             "classification": np.full(50, 2, np.uint8)})
    for by in ("intensity", "Intensity", "classification", "elevation", "ELEVATION", "intensty", "gps_time"):
        try:
            attribute_values(cloud, by)
            known = True
        except InputError:
            known = False
        if known:
            check_color_source(cloud, ColorOptions(by))
        else:
            with pytest.raises(InputError, match=f"no attribute '{by}'"):
                check_color_source(cloud, ColorOptions(by))
    with pytest.raises(InputError, match="did you mean 'intensity'"):
        check_color_source(cloud, ColorOptions("intensty"))
    check_color_source(cloud, None)
    check_color_source(SplatCloud(cloud.positions), ColorOptions("nonplanar"), added=("nonplanar",))
    with pytest.raises(InputError, match="available: elevation$"):
        check_color_source(SplatCloud(cloud.positions), ColorOptions("nonplanar"))


def test_check_color_source_reads_source_options_and_hierarchies():
    from surfsplat import scenes
    from surfsplat.api import SourceOptions
    from surfsplat.hierarchy import build_hierarchy

    cloud = scenes.sphere(300)
    cloud = cloud.replace(attributes={"confidence": np.linspace(0, 1, len(cloud), dtype=np.float32)})
    check_color_source(cloud, SourceOptions(color=ColorOptions("confidence")))
    with pytest.raises(InputError, match="did you mean 'confidence'"):
        check_color_source(cloud, SourceOptions(color=ColorOptions("confidance")))
    hierarchy = build_hierarchy(cloud)
    check_color_source(hierarchy, ColorOptions("confidence"))
    with pytest.raises(InputError, match="available: elevation, confidence"):
        check_color_source(hierarchy, ColorOptions("intensity"))
