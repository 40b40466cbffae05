"""Robust splats from raw points: duplicates,
stray points, isolated clusters, scan lines, non-planar 'trees'; sizes bounded, surfaces hole-free,
counts reported. Synthetic faulty clouds from surfsplat.scenes_faulty (a plane z = 0 plus faults)."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from test_preprocess import covered, plane_grid

from surfsplat import InputError, SplatCloud, progress
from surfsplat import scenes_faulty as sf
from surfsplat.camera import Camera
from surfsplat.geometry import knn, preprocess
from surfsplat.geometry.normals import estimate_normals
from surfsplat.geometry.robust import (GLOBAL_CAP, LOCAL_CAP, PreprocessReport, bound_sizes, exact_duplicates,
                                       isolated_clusters, stray_points)
from surfsplat.lighting import Lights
from surfsplat.rendering.options import RenderOptions


def nn_spacing(points: np.ndarray) -> float:
    """Median distance to the nearest other point (model units)."""
    dist, _ = knn(points, 1)
    return float(np.median(dist))


def run(fc: sf.FaultyCloud, **options) -> tuple[SplatCloud, PreprocessReport, np.ndarray]:
    """preprocess with a report; also the surface flag of every output splat."""
    out, report = preprocess(fc.cloud, return_report=True, **options)
    return out, report, fc.surface[report.kept]


def plane_holes(cloud: SplatCloud, fc: sf.FaultyCloud, margin: float, m: int = 160) -> int:
    """Points of a grid on the plane (inside the footprint, ``margin`` from its sides) that no
    splat of a surface sample covers."""
    grid = plane_grid(margin, fc.side - margin, m)
    return int((~covered(cloud, grid, candidates=24)).sum())


def test_defaults_and_option_check():
    assert inspect.signature(preprocess).parameters["outliers"].default == "drop"
    with pytest.raises(InputError, match="outliers"):
        preprocess(np.random.default_rng(0).uniform(size=(50, 3)), outliers="remove")


# -- duplicates ---------------------------------------------------------------------------------------


def test_duplicates_are_merged_counted_and_reported(capsys):
    fc = sf.duplicates(n=4000, fraction=0.2, seed=1)
    plane = int(len(fc.cloud)) - fc.duplicates
    with progress.enabled(True):
        out, report, surface = run(fc)
    assert report.duplicates == fc.duplicates == len(fc.cloud) - len(out)
    assert 0 < report.exact_duplicates < report.duplicates  # half the copies are moved by 1e-6 spacings
    assert len(out) == plane and surface.all()
    assert len(np.unique(out.positions, axis=0)) == len(out)
    assert f"{fc.duplicates:,} duplicate points merged" in capsys.readouterr().err
    # the copies no longer take neighbour slots: the same sizes as the plane without them
    clean = preprocess(fc.cloud.subset(np.sort(report.kept)), merge_duplicates=False)
    np.testing.assert_allclose(out.radii, clean.radii, rtol=1e-5)
    # without merging, duplicates shrink the splats of their neighbourhoods (control)
    assert np.median(preprocess(fc.cloud, merge_duplicates=False).radii) < 0.95 * np.median(out.radii)


def test_merged_points_average_colors_and_normals_and_keep_the_first():
    rng = np.random.default_rng(2)
    p = np.column_stack([rng.uniform(size=(300, 2)), np.zeros(300)]).astype(np.float32)
    colors = np.full((300, 3), 0.5, dtype=np.float32)
    normals = np.tile(np.float32([0, 0, 1]), (300, 1))
    # rows 300, 301: copies of row 7 (exact; and 1e-9 away), red and blue, one normal flipped and tilted
    p = np.concatenate([p, p[[7, 7]] + np.float32([[0, 0, 0], [1e-9, 0, 0]])])
    colors = np.concatenate([colors, [[1, 0, 0], [0, 0, 1]]]).astype(np.float32)
    tilted = np.float32([0.6, 0, 0.8])
    normals = np.concatenate([normals, [-tilted, [0, 0, 1]]]).astype(np.float32)
    out, report = preprocess(SplatCloud(p, normals=normals, colors=colors), return_report=True)
    assert report.duplicates == 2 and len(out) == 300
    np.testing.assert_array_equal(report.kept, np.arange(300))  # the first of each group represents it
    np.testing.assert_allclose(out.colors[7], [0.5, 0.5 / 3, 0.5], atol=1e-6)  # (gray + red + blue) / 3
    mean = np.float32([0, 0, 1]) * 2 + tilted  # the flipped normal turned to the first one's side
    np.testing.assert_allclose(out.normals[7], mean / np.linalg.norm(mean), atol=1e-6)


def test_many_coincident_copies_are_one_point():
    rng = np.random.default_rng(3)
    base = np.column_stack([rng.uniform(size=(200, 2)), np.zeros(200)])
    p = np.concatenate([base, np.repeat(base[:10], 20, axis=0)])  # 21 copies of 10 points (more than k + 1)
    rep = exact_duplicates(p.astype(np.float32))
    assert (rep[200:] == np.repeat(np.arange(10), 20)).all() and (rep[:200] == np.arange(200)).all()
    out, report = preprocess(p, return_report=True)
    assert len(out) == 200 and report.exact_duplicates == 200


def test_signed_zeros_are_the_same_position():
    rng = np.random.default_rng(5)
    base = np.column_stack([rng.uniform(size=(300, 2)), np.zeros(300)]).astype(np.float32)
    negative = base[:100].copy()
    negative[:, 2] = -0.0  # the same points, written with the other zero (as some exporters do)
    rep = exact_duplicates(np.concatenate([base, negative]))
    assert rep is not None and (rep[300:] == np.arange(100)).all() and (rep[:300] == np.arange(300)).all()


def test_near_but_distinct_points_are_not_merged():
    rng = np.random.default_rng(4)
    p = np.column_stack([rng.uniform(size=(500, 2)), np.zeros(500)])
    d8 = np.median(knn(p, 8)[0][:, -1])
    p = np.concatenate([p, p[:5] + [1e-3 * d8, 0, 0]])  # 1e-3 of the spacing: real points, kept
    out, report = preprocess(p, return_report=True)
    assert report.duplicates == 0 and len(out) == 505


# -- stray points and isolated clusters ----------------------------------------------------------------


def test_stray_points_are_flagged_dropped_and_cannot_blow_up_splats():
    fc = sf.stray_points(n=8000, fraction=0.01, seed=5)
    strays = int((~fc.surface).sum())
    spacing = nn_spacing(fc.cloud.positions[fc.surface])
    out, report, surface = run(fc)
    assert report.outliers >= 0.85 * strays  # the rest are near the plane or among other strays
    assert surface.sum() == fc.surface.sum()  # no sample of the plane is lost
    assert len(out) == len(fc.cloud) - report.outliers
    # the largest splat: 120-145 spacings before (a stray's neighbours are all far away); now the
    # strays among other strays are held by the global bound (4 times the median splat)
    assert out.radii.max() <= GLOBAL_CAP * np.median(out.radii) * 1.001
    assert out.radii.max() < 30 * spacing
    assert plane_holes(out, fc, margin=0.03) == 0
    # kept, the strays still cannot exceed the global bound
    kept, rep_keep, _ = run(fc, outliers="keep")
    assert len(kept) == len(fc.cloud) and rep_keep.outliers == report.outliers
    assert kept.radii.max() <= GLOBAL_CAP * np.median(kept.radii) * 1.001


@pytest.mark.parametrize("outliers", ["drop", "cap", "keep"])
def test_clusters_of_three_are_isolated(outliers):
    fc = sf.stray_clusters(n=8000, clusters=30, size=3, seed=6)
    spacing = nn_spacing(fc.cloud.positions[fc.surface])
    out, report, surface = run(fc, outliers=outliers)
    assert report.outlier_clusters >= 25  # clusters near the plane belong to it (and are bounded)
    assert report.outliers >= 3 * 25 and report.outlier_action == outliers
    faults = ~surface
    if outliers == "drop":
        assert len(out) == len(fc.cloud) - report.outliers and faults.sum() <= 90 - report.outliers
    else:
        assert len(out) == len(fc.cloud)
    if outliers == "cap":  # small round splats: one sample of the plane
        assert np.median(out.radii[faults]) < 1.5 * np.median(np.linalg.norm(out.v[surface], axis=1))
    # before: clusters' splats reached 124 spacings
    assert out.radii.max() < (25 if outliers != "keep" else GLOBAL_CAP * 1.001 * np.median(out.radii) / spacing) \
        * spacing
    assert plane_holes(out, fc, margin=0.03) == 0


def test_outlier_functions_on_a_hand_made_cloud():
    rng = np.random.default_rng(7)
    plane = np.column_stack([rng.uniform(size=(3000, 2)), np.zeros(3000)])
    cluster = np.array([[0.5, 0.5, 0.3], [0.501, 0.5, 0.3], [0.5, 0.501, 0.3]])
    single = np.array([[0.2, 0.7, -0.2]])
    p = np.concatenate([plane, cluster, single])
    dist, idx = knn(p, 8)
    iso, count = isolated_clusters(dist, idx)
    assert count == 2 and iso[3000:].all() and not iso[:3000].any()
    assert stray_points(dist, idx)[3000:].all()  # each is also far from its neighbours' spacing
    assert not stray_points(*knn(plane, 8)).any()  # the plane alone: none


# -- scan lines -------------------------------------------------------------------------------------------


def test_scan_lines_get_normals_and_ellipses_from_the_real_across_line_spacing():
    fc = sf.scan_lines(lines=24, ratio=5.0, seed=8)
    gap = fc.side / 24
    # control, what the k-neighbourhood alone gives: normals in the plane (all 8 neighbours on one line)
    dist, idx = knn(fc.cloud.positions, 8)
    assert np.median(np.abs(estimate_normals(fc.cloud.positions, idx)[:, 2])) < 0.2
    out, report, _ = run(fc)
    assert report.linear >= 0.85 * len(out)  # all but the lines' ends
    assert (np.abs(out.normals[:, 2]) > 0.99).mean() > 0.99
    inner = (out.positions[:, 0] > 2 * gap) & (out.positions[:, 0] < fc.side - 2 * gap) \
        & (out.positions[:, 1] > 2 * gap) & (out.positions[:, 1] < fc.side - 2 * gap)
    major = np.linalg.norm(out.u[inner], axis=1)
    minor = np.linalg.norm(out.v[inner], axis=1)
    assert np.median(np.abs(out.u[inner, 1]) / major) > 0.95  # the long axis across the lines
    # across: reaches the next line (no hole), not several lines (no blob); along: a few spacings (no needle)
    assert 0.6 * gap < np.median(major) < 1.5 * gap
    assert fc.spacing < np.median(minor) < 0.5 * gap
    assert plane_holes(out, fc, margin=1.5 * gap) == 0


# -- a noisy tree over a plane -------------------------------------------------------------------------


def test_tree_points_get_small_round_splats_and_the_ground_no_holes():
    fc = sf.tree(n=8000, crown=1500, seed=9)
    out, report, surface = run(fc)
    crown = ~surface
    assert report.volumetric >= 0.6 * crown.sum()
    ground = np.median(out.radii[surface])
    # before: the crown's flat ellipses reached 4.6 times the ground's median splat
    assert out.radii[crown].max() < 3.0 * ground
    assert np.median(out.radii[crown]) < 0.8 * ground
    round_ = np.abs(np.linalg.norm(out.u[crown], axis=1) / np.linalg.norm(out.v[crown], axis=1) - 1) < 1e-4
    assert round_.mean() >= 0.6
    assert plane_holes(out.subset(surface), fc, margin=0.03) == 0


# -- everything at once, rendered ---------------------------------------------------------------------------


def test_faulty_scan_renders_without_holes(renderer):
    fc = sf.faulty_scan(lines=40, seed=10)
    with progress.enabled(False):
        out, report, surface = run(fc)
    assert report.duplicates == fc.duplicates and report.outliers > 0 and report.linear > 0
    assert report.volumetric > 0
    spacing = nn_spacing(np.unique(fc.cloud.positions[fc.surface], axis=0))
    assert out.radii.max() < 25 * spacing
    # top view of the square; count the pixels of the footprint (shrunk by 2 line gaps) left uncovered
    size = 96
    camera = Camera(eye=(0.5, 0.5, 2.2), target=(0.5, 0.5, 0.0), up=(0, 1, 0), fov=28, width=size, height=size)
    frame = renderer.render(out.subset(surface), camera, "ewa", Lights(), RenderOptions())
    world = np.linspace(-1, 1, size) * 2.2 * np.tan(np.radians(14))  # pixel centers, close enough at this size
    x, y = np.meshgrid(0.5 + world, 0.5 - world)
    gap = 2 / 40
    inside = (x > gap) & (x < 1 - gap) & (y > gap) & (y < 1 - gap)
    assert inside.sum() > 0.5 * size * size
    assert (inside & ~frame.mask).sum() == 0


# -- the size bound itself --------------------------------------------------------------------------------


def test_bound_sizes_shrinks_only_outsized_splats():
    rng = np.random.default_rng(11)
    n = 2000
    u = np.zeros((n, 3), dtype=np.float32)
    v = np.zeros((n, 3), dtype=np.float32)
    u[:, 0] = rng.uniform(0.9, 1.1, n)
    v[:, 1] = 0.5
    u[5, 0] = 50.0  # one giant splat
    v[5, 1] = 10.0
    idx = rng.integers(0, n, size=(n, 8))
    capped, bound = bound_sizes(u, v, idx)
    assert capped == 1 and bound == pytest.approx(GLOBAL_CAP * np.median(np.maximum(u[:, 0], 0.5)), rel=0.02)
    assert u[5, 0] <= LOCAL_CAP * 1.1 and v[5, 1] == pytest.approx(10.0 * u[5, 0] / 50.0)  # shape kept


def test_clean_samples_are_left_alone():
    rng = np.random.default_rng(12)
    p = np.column_stack([rng.uniform(size=(20000, 2)), np.zeros(20000)]).astype(np.float32)
    out, report = preprocess(p, return_report=True)
    assert (report.duplicates, report.outliers, report.volumetric) == (0, 0, 0)
    assert report.capped <= 2 and report.linear < 0.01 * len(p)
    assert len(out) == len(p)
