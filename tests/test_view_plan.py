"""The view plan (surfsplat.pipeline): one definition of a view that every door consumes."""

from __future__ import annotations

import importlib
from importlib import resources

import numpy as np
import pytest
import trimesh

import surfsplat
from surfsplat import defaults, pipeline
from surfsplat.cli import build_parser
from surfsplat.errors import InputError
from surfsplat.hierarchy import build_hierarchy
from surfsplat.pipeline import LodOptions, SourceOptions, View, as_model, lod_strategy
from surfsplat.pipeline.models import ChunkedModel, CloudModel, HierarchyModel, MeshModel
from surfsplat.scenes import demo_scene


@pytest.fixture(scope="module")
def torus():
    return demo_scene("torus")


def test_the_subpackage_is_not_shadowed_by_the_function():
    module = importlib.import_module("surfsplat.rendering.renderer")
    import surfsplat.rendering.renderer as by_import
    assert by_import is module and surfsplat.rendering.renderer.Renderer is module.Renderer
    assert callable(surfsplat.render) and not hasattr(surfsplat.render, "renderer")


def test_the_public_names_resolve_and_the_package_is_typed():
    assert len(set(surfsplat.__all__)) == len(surfsplat.__all__)
    for name in surfsplat.__all__:
        assert hasattr(surfsplat, name), name
    for option_type in ("RenderOptions", "SourceOptions", "LodOptions", "CameraSpec", "Lights", "ColorOptions",
                        "Hierarchy", "Mesh", "EmptyFrameWarning", "TechniqueName", "LodShading", "LodMode"):
        assert option_type in surfsplat.__all__
    assert resources.files("surfsplat").joinpath("py.typed").is_file()


def test_a_prepared_view_draws_what_render_draws(torus, gl_renderer):
    view = surfsplat.prepare(torus)
    camera = view.camera(None, 96, 96)
    for technique in ("ewa", "flat"):
        once = surfsplat.render(torus, camera, technique=technique).color
        np.testing.assert_array_equal(view.render(camera, technique=technique).frame.color, once)
    # a CameraSpec is resolved against the model about its up axis, as render resolves it
    spec = surfsplat.CameraSpec(fov=30.0)
    np.testing.assert_array_equal(view.render(spec, width=80, height=64).frame.color,
                                  surfsplat.render(torus, spec, width=80, height=64).color)


def test_a_mesh_is_sampled_once_per_view_and_load_model_draws_what_render_draws(tmp_path, gl_renderer):
    path = tmp_path / "ball.ply"
    trimesh.creation.icosphere(subdivisions=3).export(path)
    view = surfsplat.prepare(str(path))
    assert isinstance(view.model, MeshModel)
    first = view.render(None, width=64, height=64)
    sampled = view.sample()
    view.render(surfsplat.CameraSpec(eye=(0.0, 0.0, 4.0)), width=64, height=64)
    assert view.sample() is sampled   # not sampled again for the second camera
    direct = surfsplat.render(str(path), width=64, height=64)
    np.testing.assert_array_equal(first.frame.color, direct.color)
    loaded = surfsplat.load_model(str(path))
    assert isinstance(loaded, surfsplat.Mesh)
    np.testing.assert_array_equal(surfsplat.render(loaded, width=64, height=64).color, direct.color)
    # the points of the file are another thing, and say so by their name
    assert isinstance(surfsplat.load_points(str(path)), surfsplat.SplatCloud)


def test_model_kinds_answer_one_protocol(torus):
    h = build_hierarchy(torus)
    cloud, tree = as_model(torus), as_model(h)
    assert isinstance(cloud, CloudModel) and isinstance(tree, HierarchyModel)
    assert as_model(cloud) is cloud
    for model in (cloud, tree):
        lo, hi = model.bounds()
        assert np.all(hi > lo) and len(model.points()) == len(torus)
    camera = pipeline.resolve_camera(torus, None, 64, 64)
    splats, selection = tree.cut(camera, 2.0)
    assert selection is not None and 0 < len(splats) < len(torus)
    assert cloud.cut(camera, 2.0) == (torus, None)
    assert isinstance(cloud.tree(), HierarchyModel)
    with pytest.raises(InputError, match="expected a SplatCloud"):
        as_model(np.zeros(3))


def test_lod_strategy_is_one_rule(torus):
    cloud, tree = as_model(torus), as_model(build_hierarchy(torus))
    assert lod_strategy(cloud, LodOptions(), False, interactive=True) == "none"
    assert lod_strategy(cloud, LodOptions(tolerance="auto"), False, interactive=False) == "none"
    assert lod_strategy(cloud, LodOptions(tolerance=2.0), False, interactive=False) == "cpu"
    assert lod_strategy(tree, LodOptions(), False, interactive=False) == "cpu"
    assert lod_strategy(tree, LodOptions(), False, interactive=True) == "gpu"
    assert lod_strategy(tree, LodOptions(point_budget=1000), False, interactive=True) == "cpu"
    assert lod_strategy(tree, LodOptions(), True, interactive=True) == "cpu"   # hybrid points
    assert lod_strategy(tree, LodOptions(mode="cpu"), False, interactive=True) == "cpu"
    assert lod_strategy(tree, LodOptions(mode="gpu"), False, interactive=False) == "gpu"
    with pytest.raises(InputError, match="point budget and hybrid points"):
        lod_strategy(tree, LodOptions(mode="gpu", point_budget=10), True, interactive=True)
    chunked = ChunkedModel.__new__(ChunkedModel)   # only its kind matters to the rule
    assert lod_strategy(chunked, LodOptions(), False, interactive=True) == "cpu"
    with pytest.raises(InputError, match="chunked hierarchy"):
        lod_strategy(chunked, LodOptions(mode="gpu"), False, interactive=True)


@pytest.mark.parametrize("kwargs, match", [
    (dict(tolerance=-1.0), "LOD tolerance"), (dict(tolerance="fine"), "LOD tolerance"),
    (dict(tolerance=float("nan")), "LOD tolerance"), (dict(shading="smooth"), "LOD shading"),
    (dict(point_budget=0), "point budget"), (dict(mode="fpga"), "LOD mode")])
def test_lod_options_are_checked_when_built(kwargs, match):
    with pytest.raises(InputError, match=match):
        LodOptions(**kwargs)


@pytest.mark.parametrize("kwargs, match", [
    (dict(k=2), "k must be"), (dict(outliers="burn"), "outliers"), (dict(samples=1), "samples"),
    (dict(sharp_angle=200.0), "sharp_angle"), (dict(hybrid="yes"), "hybrid")])
def test_source_options_are_checked_when_built(kwargs, match):
    with pytest.raises(InputError, match=match):
        SourceOptions(**kwargs)


@pytest.mark.parametrize("kwargs, match", [
    (dict(width=0), "image size"), (dict(height=2.5), "image size"), (dict(technique="ewq"), "unknown technique"),
    (dict(background=(2, 0, 0)), "background"), (dict(supersample=0), "supersample"),
    (dict(options="fast"), "options must be"), (dict(lights=(1, 1, 1)), "lights must be")])
def test_render_arguments_are_checked_before_any_file_is_read(kwargs, match, monkeypatch):
    def never(*args, **kw):
        raise AssertionError("the source was read before the arguments were checked")
    monkeypatch.setattr(pipeline.plan, "read_source", never)
    with pytest.raises(InputError, match=match):
        surfsplat.render("demo:torus", **kwargs)


def test_one_background_rule_for_splats_and_the_mesh_ground_truth(tmp_path):
    mesh = tmp_path / "cube.ply"
    trimesh.creation.box().export(mesh)
    for draw in (surfsplat.render, surfsplat.render_mesh):
        with pytest.raises(InputError, match=r"background must be 3 numbers in \[0, 1\]"):
            draw(str(mesh), background=(2.0, 0.0, 0.0))


def test_the_doors_share_the_defaults():
    parser = build_parser()
    render = parser.parse_args(["render", "a.ply", "-o", "a.png"])
    view = parser.parse_args(["view", "a.ply"])
    for args in (render, view):
        assert tuple(args.background) == defaults.BACKGROUND
        assert args.lod_shading == defaults.LOD_SHADING and args.lod_mode == defaults.LOD_MODE
        assert args.lod_tolerance is None and args.point_budget is None and args.fov == defaults.FOV
    assert tuple(view.size) == defaults.WINDOW_SIZE
    assert render.supersample == 1
    parser.parse_args(["render", "a.ply", "-o", "a.png", "--supersample", str(defaults.MAX_SUPERSAMPLE)])
    with pytest.raises(SystemExit):
        parser.parse_args(["render", "a.ply", "-o", "a.png", "--supersample", str(defaults.MAX_SUPERSAMPLE + 1)])
    with pytest.raises(SystemExit):   # the window's tolerance is a positive number of pixels
        parser.parse_args(["view", "a.ply", "--lod-tolerance", "0"])
    from surfsplat.cli.options import IMAGE_SIZE, lod_options
    assert IMAGE_SIZE == defaults.CLI_IMAGE_SIZE
    assert lod_options(render) == LodOptions()


def test_automatic_culling_is_decided_by_the_view(torus):
    view = View(torus)
    outside = view.camera(None, 64, 64)
    assert not view.culls(outside)   # a cloud never automatically: a back-facing splat may fill a hole of the front
    lo, hi = view.model.bounds()
    inside = view.camera(surfsplat.CameraSpec(eye=tuple(0.5 * (lo + hi)), target=tuple(hi)), 64, 64)
    assert not view.culls(inside)
    asked = surfsplat.RenderOptions(visibility=surfsplat.VisibilityOptions(cull_backfaces=True))
    assert view.culls(outside, asked) and view.culls(inside, asked)


def test_a_misspelt_colour_attribute_fails_before_preprocessing(monkeypatch):
    from surfsplat.colors import ColorOptions

    def never(*args, **kw):
        raise AssertionError("preprocessed before the colour attribute was checked")
    monkeypatch.setattr(pipeline.sources, "preprocess", never)
    points = np.random.default_rng(0).random((2000, 3)).astype(np.float32)
    with pytest.raises(InputError, match="no attribute 'intensty'"):
        surfsplat.render(points, source_options=SourceOptions(color=ColorOptions("intensty")))


@pytest.mark.gl
def test_the_mesh_ground_truth_warns_as_a_splat_render_does_when_it_shows_nothing(tmp_path):
    mesh = tmp_path / "cube.ply"
    trimesh.creation.box().export(mesh)
    away = surfsplat.CameraSpec(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 20.0))
    for draw in (surfsplat.render, surfsplat.render_mesh):
        with pytest.warns(surfsplat.EmptyFrameWarning, match="nothing was drawn"):
            draw(str(mesh), away, width=32, height=32)
