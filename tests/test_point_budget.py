"""Point budget (Potree's priority: refine the largest node on screen first until N splats)."""

from __future__ import annotations

import surfsplat
import numpy as np
import pytest

from surfsplat import pipeline
from surfsplat.errors import InputError
from surfsplat.hierarchy import build_hierarchy, select
from surfsplat.hierarchy.lod import projected_size
from surfsplat.metrics import psnr
from surfsplat.scenes import demo_scene


@pytest.fixture(scope="module")
def torus():
    h = build_hierarchy(demo_scene("torus"))
    # close and oblique: the near side's nodes project much larger than the far side's
    camera = pipeline.auto_camera(h.points, 160, 120)
    eye, target = np.asarray(camera.eye), np.asarray(camera.target)
    return h, camera.__class__(eye=tuple(target + 0.6 * (eye - target)), target=camera.target, up=camera.up,
                               fov=camera.fov, width=160, height=120)


def _drawn_depth(h, selection) -> np.ndarray:
    """(P,) depth of the drawn splat standing for each original point (the point itself: levels);
    -1 where none does."""
    nodes = selection.node_indices()
    depth = np.full(len(h.points), -1, dtype=np.int64)
    for start, count, d in zip(h.node_point_start[nodes], h.node_point_count[nodes], h.node_depth[nodes]):
        depth[start:start + count] = d
    for start, count in zip(selection.point_start, selection.point_count):
        depth[start:start + count] = h.levels
    return depth


def _coverage(h, selection) -> np.ndarray:
    """(P,) how many drawn splats stand for each original point (a node for its range)."""
    nodes = selection.node_indices()
    start = np.concatenate([h.node_point_start[nodes], selection.point_start])
    count = np.concatenate([h.node_point_count[nodes], selection.point_count])
    delta = np.zeros(len(h.points) + 1, dtype=np.int64)
    np.add.at(delta, start, 1)
    np.add.at(delta, start + count, -1)
    return np.cumsum(delta)[:-1]


def test_budget_is_never_exceeded_and_cuts_are_nested(torus):
    h, camera = torus
    full = select(h, camera, 0.5)
    previous = np.full(len(h.points), -1)
    for n in (1, 7, 50, 400, 3000, len(full) - 1):
        s = select(h, camera, 0.5, point_budget=n)
        assert 1 <= len(s) <= n
        assert len(h.splats(s)) == len(s)
        depth = _drawn_depth(h, s)
        both = (depth >= 0) & (previous >= 0)
        assert (depth[both] >= previous[both]).all()   # a larger budget only refines: nothing coarsens
        previous = depth
        # no hole: every point the full cut draws has exactly one drawn ancestor (or itself)
        covered = _coverage(h, s)
        assert covered.max() == 1
        assert (covered[_coverage(h, full) == 1] == 1).all()


def test_budget_at_or_above_the_cut_is_the_cut(torus):
    h, camera = torus
    for tol in (0.0, 2.0):
        full = select(h, camera, tol)
        for n in (len(full), len(full) + 1, 10**9):
            s = select(h, camera, tol, point_budget=n)
            for a, b in zip(s.nodes + s.leaves, full.nodes + full.leaves):
                np.testing.assert_array_equal(a, b)


def test_largest_nodes_are_refined_first(torus):
    """Potree's priority: the refined nodes project larger than the drawn ones left unrefined."""
    h, camera = torus
    s = select(h, camera, 0.0, point_budget=2000)
    drawn = s.node_indices()
    lod_parent = h._cache["lod"].parent
    refined = np.unique(lod_parent[drawn])
    size_refined, size_drawn = projected_size(h, camera, refined), projected_size(h, camera, drawn)
    assert np.isfinite(size_drawn).all()
    assert np.median(size_refined) > 2 * np.median(size_drawn)
    # the cut is not uniform: drawn nodes are deeper where the torus is nearer (larger on screen)
    depth = h.node_depth[drawn]
    assert depth.max() - depth.min() >= 2
    eye = np.asarray(camera.eye)
    dist = np.linalg.norm(h.node_positions[drawn] - eye, axis=1)
    assert np.corrcoef(depth, dist)[0, 1] < -0.3


def test_quality_grows_with_the_budget_and_the_api(torus, gl_renderer):
    h, camera = torus
    reference = (surfsplat.prepare(h, lod=surfsplat.LodOptions(tolerance=0.0)).render(camera).frame.image()
                 .astype(np.float32) / 255)
    scores, counts = [], []
    for n in (300, 3000, 30000):
        result = surfsplat.prepare(h, lod=surfsplat.LodOptions(tolerance=0.0, point_budget=n)).render(camera)
        assert result.splats <= n
        counts.append(result.splats)
        scores.append(psnr(result.frame.image().astype(np.float32) / 255, reference))
    assert counts == sorted(counts)
    assert scores[0] < scores[1] < scores[2]
    assert scores[2] > 30.0


def test_bad_budgets_are_clear_errors(torus):
    h, camera = torus
    for bad in (0, -3, 2.5, "10", True):
        with pytest.raises(InputError, match="point budget"):
            select(h, camera, 1.0, point_budget=bad)


@pytest.mark.gl
def test_cli_point_budget(tmp_path):
    from surfsplat.cli import main

    out = tmp_path / "b.png"
    assert main(["-q", "demo", "-o", str(out), "--width", "96", "--height", "96", "--point-budget", "500"]) in (0, None)
    assert out.exists()
