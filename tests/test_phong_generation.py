"""Phong splat generation (Botsch, Spernat & Kobbelt 2004, sec. 3): cover, error bound, normal fields.

Every property is checked against the samples themselves with an independent brute-force
cover test (a k-d tree over the samples, each splat's elliptical cylinder offset by +-eps),
against analytic surfaces (sphere, cylinder, plane) for the normal fields and the axes, and
against the exact faces of a cube and a CAD part for the clip lines.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from surfsplat import InputError, SplatCloud, progress, reference, scenes
from surfsplat.cloud import NO_CLIP
from surfsplat.geometry.phong import _solve_least_norm, phong_coverage, phong_fit, phong_splats
from surfsplat.geometry.sampling import sample_mesh
from surfsplat.io import Mesh, load, load_mesh

SHARP = 30.0


# -- surfaces ------------------------------------------------------------------------------------------


def sphere_samples(n=20_000, radius=1.0, colors=None) -> SplatCloud:
    """Fibonacci sphere samples with exact outward normals."""
    c = scenes.sphere(n, radius=radius, color=colors)
    return SplatCloud(c.positions, c.normals, c.colors)


def torus_samples() -> SplatCloud:
    """A (theta, phi) grid on a torus (R 1, r 0.4), exact normals: 16,000 samples."""
    c = scenes.torus(200, 80)
    return SplatCloud(c.positions, c.normals)


def noisy_plane(n=20_000, sigma=1e-3, seed=0) -> SplatCloud:
    """Random samples of the unit square z = 0 with Gaussian height noise, positions only."""
    rng = np.random.default_rng(seed)
    p = np.column_stack([rng.random(n), rng.random(n), rng.normal(0.0, sigma, n)])
    return SplatCloud(p.astype(np.float32))


def cylinder(n=20_000, radius=1.0, length=4.0, seed=0) -> SplatCloud:
    """Random samples of the cylinder x^2 + y^2 = radius^2, |z| <= length / 2, exact normals."""
    rng = np.random.default_rng(seed)
    phi = rng.uniform(0, 2 * np.pi, n)
    normal = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(n)])
    p = radius * normal + np.column_stack([np.zeros(n), np.zeros(n), rng.uniform(-length / 2, length / 2, n)])
    return SplatCloud(p.astype(np.float32), normal.astype(np.float32))


def bunny(shared_data) -> SplatCloud:
    path = shared_data / "bunny.ply"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")    # 1,113 unused vertices are dropped
        return load(path)


# -- independent checks --------------------------------------------------------------------------------


def splat_frames(splats: SplatCloud):
    """Centers, axes, unit plane normals (u x v) and the largest semi-axis, float64."""
    c = splats.positions.astype(np.float64)
    u = splats.u.astype(np.float64)
    v = splats.v.astype(np.float64)
    n = np.cross(u, v)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return c, u, v, n, np.sqrt(np.maximum((u * u).sum(1), (v * v).sum(1)))


def claims(points: np.ndarray, splats: SplatCloud, eps: float, line_margin: float = -1e-5):
    """All (splat, sample) pairs where the sample lies in the splat's elliptical cylinder
    (ellipse, +-eps) on the kept side of its clip lines (``a s + b t + c >= line_margin``).
    Returns (splat ids, sample ids, s, t, plane distance), brute force over a k-d tree."""
    c, u, v, n, r = splat_frames(splats)
    hits = cKDTree(points).query_ball_point(c, r + eps, workers=-1)
    j = np.repeat(np.arange(len(c)), [len(h) for h in hits])
    i = np.concatenate([np.asarray(h, dtype=np.int64) for h in hits])
    d = points[i] - c[j]
    s = (d * u[j]).sum(1) / (u[j] * u[j]).sum(1)
    t = (d * v[j]).sum(1) / (v[j] * v[j]).sum(1)
    h = (d * n[j]).sum(1)
    inside = (s * s + t * t <= 1.0) & (np.abs(h) <= eps)
    if splats.clip_lines is not None:
        lines = splats.clip_lines[j].astype(np.float64)
        inside &= (lines[:, :, 0] * s[:, None] + lines[:, :, 1] * t[:, None] + lines[:, :, 2] >= line_margin).all(1)
    return j[inside], i[inside], s[inside], t[inside], h[inside]


def assert_covers(cloud: SplatCloud, result, eps: float):
    """Every sample is covered; the samples each splat was fitted to are inside it, within eps."""
    points = cloud.validated().positions.astype(np.float64)
    splats = result.splats
    _, i, _, _, _ = claims(points, splats, eps)
    covered = np.zeros(len(points), dtype=bool)
    covered[i] = True
    assert covered.all(), f"{(~covered).sum()} of {len(points)} samples are not covered"
    # error bound: the covered set P_j of every splat lies in its cylinder
    c, u, v, n, _ = splat_frames(splats)
    j = np.repeat(np.arange(len(c)), np.diff(result.member_ptr))
    d = points[result.member_idx] - c[j]
    h = np.abs((d * n[j]).sum(1))
    q = ((d * u[j]).sum(1) / (u[j] * u[j]).sum(1)) ** 2 + ((d * v[j]).sum(1) / (v[j] * v[j]).sum(1)) ** 2
    assert h.max() <= eps, h.max() / eps
    assert q.max() <= 1.0, q.max()
    assert np.bincount(result.member_idx, minlength=len(points)).min() >= 1


def angle(a, b):
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1.0, 1.0)))


# -- cover and error bound ------------------------------------------------------------------------------


@pytest.mark.parametrize("name, eps, most", [("sphere", 1e-3, 0.1), ("torus", 4e-3, 0.1),
                                             ("noisy plane", 5e-3, 0.01)])
def test_every_sample_covered_within_the_error(name, eps, most):
    """Sphere and torus with exact normals, a noisy plane without normals (estimated here):
    every sample in some splat's cylinder (ellipse, +-eps), every splat's own samples within
    eps of its plane, and far fewer splats than samples."""
    cloud = {"sphere": sphere_samples, "torus": torus_samples, "noisy plane": noisy_plane}[name]()
    result = phong_fit(cloud, eps)
    assert result.error == eps and result.samples == len(cloud)
    assert_covers(cloud, result, eps)
    splats = result.splats
    assert splats.has_splats and splats.normal_field is not None and splats.clip_lines is None
    assert len(splats) < most * len(cloud), (len(splats), len(cloud))
    # u, v span the plane: orthogonal; the stored center normal is near the plane normal
    c, u, v, n, _ = splat_frames(splats)
    assert np.abs((u * v).sum(1)).max() < 1e-5 * np.linalg.norm(u, axis=1).max() ** 2
    assert angle(splats.normals.astype(np.float64), n).max() < 30.0


def test_bunny_covered(shared_data):
    """The Stanford bunny's 34,834 vertices (area-weighted mesh normals), eps = 1e-4 of ~0.2."""
    cloud = bunny(shared_data)
    eps = 1e-4
    result = phong_fit(cloud, eps)
    assert_covers(cloud, result, eps)
    assert len(result.splats) < 0.25 * len(cloud)
    # consistently oriented, like the samples: splat plane normals agree with their samples'
    c, u, v, n, _ = splat_frames(result.splats)
    j = np.repeat(np.arange(len(c)), np.diff(result.member_ptr))
    agree = (cloud.normals[result.member_idx] * n[j]).sum(1) > 0
    assert agree.mean() > 0.99


def test_fewer_splats_for_larger_error():
    """Monotone: a larger tolerance gives fewer (larger) splats; on the unit sphere the bare
    ellipses (margin 0) have the radius of the least-squares plane's bound sqrt(4 R eps) (sag
    r^2 / 2R, split in half) and are the smallest enclosing ones: each touches a sample."""
    cloud = sphere_samples()
    counts, radii = [], []
    for eps in (1e-3, 4e-3, 1.6e-2):
        result = phong_fit(cloud, eps, margin=0.0)
        splats = result.splats
        counts.append(len(splats))
        c, u, v, n, _ = splat_frames(splats)
        j = np.repeat(np.arange(len(c)), np.diff(result.member_ptr))
        d = cloud.positions[result.member_idx] - c[j]
        q = ((d * u[j]).sum(1) / (u[j] * u[j]).sum(1)) ** 2 + ((d * v[j]).sum(1) / (v[j] * v[j]).sum(1)) ** 2
        farthest = np.maximum.reduceat(q, result.member_ptr[:-1])
        assert farthest.max() <= 1.0 and np.median(farthest) > 0.999, np.percentile(farthest, [0, 50])
        radii.append(float(np.median(np.sqrt(np.linalg.norm(splats.u, axis=1) * np.linalg.norm(splats.v, axis=1)))))
        assert 0.6 * np.sqrt(4 * eps) < radii[-1] < 1.05 * np.sqrt(4 * eps), (eps, radii[-1])
    assert counts[0] > 2 * counts[1] > 4 * counts[2], counts
    assert counts[0] < 0.1 * len(cloud)


def test_surface_between_samples_is_covered():
    """The bare smallest enclosing ellipses (margin 0) cover the samples but leave holes between
    them; the default surface margin closes them (random samples, random surface points)."""
    rng = np.random.default_rng(7)
    p = rng.normal(size=(20_000, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    cloud = SplatCloud(p.astype(np.float32), p.astype(np.float32))
    q = rng.normal(size=(100_000, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    bare = phong_splats(cloud, 2e-3, margin=0.0)
    full = phong_splats(cloud, 2e-3)
    assert len(bare) == len(full)
    assert np.isinf(phong_coverage(q, bare)).mean() > 0.01
    assert np.isinf(phong_coverage(q, full)).mean() < 1e-4


def test_coverage_helper_agrees():
    """phong_coverage (the library's check) against the brute force here."""
    cloud = torus_samples()
    eps = 2e-3
    splats = phong_splats(cloud, eps)
    points = cloud.positions.astype(np.float64)
    dist = phong_coverage(points, splats)
    assert (dist <= eps).all()
    # shrunk splats leave samples uncovered, in both checks
    small = splats.replace(u=splats.u * 0.7, v=splats.v * 0.7)
    _, i, _, _, _ = claims(points, small, eps)
    mine = np.zeros(len(points), dtype=bool)
    mine[i] = True
    np.testing.assert_array_equal(phong_coverage(points, small) <= eps, mine)
    assert (~mine).sum() > 100


# -- normal fields (eq. 2-4) -------------------------------------------------------------------------------


def test_normal_field_on_a_sphere():
    """Sphere of radius R: the normal at in-plane offset d is tilted by ~d / R, so alpha = |u| / R
    and beta = |v| / R (positive: normals spread outward), and the interpolated normal at the
    samples matches the sphere's far better than the constant one."""
    radius = 2.0
    cloud = sphere_samples(20_000, radius=radius)
    result = phong_fit(cloud, 2e-3)
    splats = result.splats
    lu = np.linalg.norm(splats.u, axis=1)
    lv = np.linalg.norm(splats.v, axis=1)
    np.testing.assert_allclose(splats.normal_field[:, 0], lu / radius, rtol=0.02)
    np.testing.assert_allclose(splats.normal_field[:, 1], lv / radius, rtol=0.02)
    # the field at each splat's samples, at their (s, t)
    c, u, v, n, _ = splat_frames(splats)
    j = np.repeat(np.arange(len(c)), np.diff(result.member_ptr))
    p = cloud.positions[result.member_idx].astype(np.float64)
    d = p - c[j]
    st = np.stack([(d * u[j]).sum(1) / lu[j] ** 2, (d * v[j]).sum(1) / lv[j] ** 2], axis=1)[:, None, :]
    field = reference.field_normals(splats.normals[j].astype(np.float64), u[j], v[j],
                                    splats.normal_field[j].astype(np.float64), st)[:, 0]
    truth = p / np.linalg.norm(p, axis=1, keepdims=True)
    err_field = angle(field, truth).mean()
    err_const = angle(splats.normals[j].astype(np.float64), truth).mean()
    assert err_const > 0.5                       # degrees: the splats are large enough to matter
    assert err_field < 0.05 * err_const, (err_field, err_const)
    # the center normal is the sphere's normal at the center (on the least-squares plane)
    np.testing.assert_allclose(angle(splats.normals.astype(np.float64), c), 0.0, atol=0.05)


def test_plane_has_constant_field():
    """An exact plane with exact normals: alpha = beta = 0, normals = the plane's."""
    rng = np.random.default_rng(3)
    p = np.column_stack([rng.random(10_000), rng.random(10_000), np.full(10_000, 0.25)])
    cloud = SplatCloud(p.astype(np.float32), np.tile(np.float32([0, 0, 1]), (10_000, 1)))
    result = phong_fit(cloud, 1e-4)
    splats = result.splats
    assert np.abs(splats.normal_field).max() < 1e-6
    np.testing.assert_allclose(splats.normals, np.tile([0, 0, 1], (len(splats), 1)), atol=1e-6)
    _, _, _, n, _ = splat_frames(splats)
    np.testing.assert_allclose(n, np.tile([0, 0, 1], (len(splats), 1)), atol=1e-6)
    assert_covers(cloud, result, 1e-4)


def test_single_sample_splats_are_least_norm():
    """A tolerance no 4 samples of a sphere meet: every splat holds one sample; its
    system (eq. 3) is singular and the least-norm solution is alpha = beta = 0 with the
    sample's own normal."""
    cloud = sphere_samples(2_000)
    result = phong_fit(cloud, 1e-12)
    assert len(result.splats) == len(cloud)
    assert (np.diff(result.member_ptr) == 1).all()
    splats = result.splats
    assert np.abs(splats.normal_field).max() == 0.0
    np.testing.assert_allclose(splats.normals, cloud.normals[result.member_idx], atol=1e-6)
    np.testing.assert_allclose(splats.positions, cloud.positions[result.member_idx], atol=1e-7)
    assert (np.linalg.norm(splats.u, axis=1) > 0).all()


def test_least_norm_solver_matches_pseudo_inverse():
    """Eq. 3-4 normal equations [[n, sum s], [sum s, sum s^2]]: regular ones solved exactly,
    singular ones (all s_i equal, or no sample) by the pseudo-inverse (Golub & Van Loan)."""
    rng = np.random.default_rng(0)
    cases = []
    for s_values in ([0.3, -0.5, 0.9], [0.4, 0.4, 0.4], [0.0], [-0.7], []):
        s = np.asarray(s_values)
        x = rng.normal(size=len(s))
        g = np.array([[len(s), s.sum()], [s.sum(), (s * s).sum()]])
        r = np.array([x.sum(), (x * s).sum()])
        cases.append((g, r))
    g = np.array([c[0] for c in cases])
    r = np.array([c[1] for c in cases])
    x0, x1 = _solve_least_norm(g[:, 0, 0], g[:, 0, 1], g[:, 1, 1], r[:, 0], r[:, 1])
    for (gi, ri), a, b in zip(cases, x0, x1):
        np.testing.assert_allclose([a, b], np.linalg.pinv(gi) @ ri, atol=1e-12)


# -- axes, colors ------------------------------------------------------------------------------------------


def test_cylinder_axes_follow_the_principal_directions():
    """On a cylinder (radius 1) the normals vary only around it: one axis along the cylinder's
    axis, the other around it with alpha = |u| / R; splats stretch along the flat direction."""
    cloud = cylinder()
    splats = phong_splats(cloud, 1e-3)
    inner = np.abs(splats.positions[:, 2]) < 1.5
    u_hat = splats.u / np.linalg.norm(splats.u, axis=1, keepdims=True)
    v_hat = splats.v / np.linalg.norm(splats.v, axis=1, keepdims=True)
    along = np.maximum(np.abs(u_hat[:, 2]), np.abs(v_hat[:, 2]))[inner]
    assert (along > 0.99).mean() > 0.95, np.percentile(along, [5, 50])
    # u (largest normal variation) goes around the cylinder, v along it
    assert (np.abs(u_hat[inner, 2]) < 0.1).mean() > 0.95
    lu = np.linalg.norm(splats.u, axis=1)[inner]
    lv = np.linalg.norm(splats.v, axis=1)[inner]
    np.testing.assert_allclose(np.median(splats.normal_field[inner, 0] / lu), 1.0, rtol=0.02)
    assert np.abs(splats.normal_field[inner, 1]).max() < 0.02 * lv.max()
    assert np.median(lv / lu) > 1.5


def test_colors_are_the_mean_of_the_covered_samples():
    cloud = sphere_samples(10_000, colors="bands")
    result = phong_fit(cloud, 1e-3)
    j = np.repeat(np.arange(len(result.splats)), np.diff(result.member_ptr))
    mean = np.stack([np.bincount(j, weights=cloud.colors[result.member_idx, c]) for c in range(3)], axis=1)
    mean /= np.diff(result.member_ptr)[:, None]
    np.testing.assert_allclose(result.splats.colors, mean, atol=1e-6)
    assert phong_splats(sphere_samples(2_000), 1e-3).colors is None


# -- count mode ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("target", [300, 2000])
def test_count_reaches_the_target(target):
    """count=N: the tolerance is searched until the pipeline gives N splats within a few percent."""
    cloud = sphere_samples(20_000)
    result = phong_fit(cloud, count=target)
    assert abs(len(result.splats) - target) <= 0.05 * target, len(result.splats)
    assert_covers(cloud, result, result.error)
    # the tolerance found gives that count in error mode too
    assert len(phong_splats(cloud, result.error)) == len(result.splats)


# -- arguments -------------------------------------------------------------------------------------------


def test_bad_arguments_are_input_errors():
    cloud = sphere_samples(500)
    cases = [
        (dict(), "exactly one of error"),
        (dict(error=1e-3, count=10), "exactly one of error"),
        (dict(error=-1e-3), "error must be a positive"),
        (dict(error=0.0), "error must be a positive"),
        (dict(error=float("nan")), "error must be a positive"),
        (dict(error="small"), "error must be a positive"),
        (dict(count=0), "count must be a positive integer"),
        (dict(count=2.5), "count must be a positive integer"),
        (dict(count=501), r"count must be at most the number of samples \(500\)"),
        (dict(error=1e-3, k=0), "k must be a positive integer"),
        (dict(error=1e-3, relax=-1), "relax must be a non-negative integer"),
        (dict(error=1e-3, margin=-0.5), "margin must be a non-negative finite factor"),
        (dict(error=1e-3, sharp_angle=200), "sharp_angle must be an angle in degrees strictly between 0 and 180"),
    ]
    for kwargs, message in cases:
        error = kwargs.pop("error", None)
        with pytest.raises(InputError, match=message):
            phong_splats(cloud, error, **kwargs)
    with pytest.raises(InputError, match="contains no points"):
        phong_splats(SplatCloud(np.zeros((0, 3), np.float32)), 1e-3)
    with pytest.raises(InputError, match="no valid points"):
        phong_splats(SplatCloud(np.full((3, 3), np.nan, np.float32)), 1e-3)


def test_progress_on_stderr(capsys):
    phong_splats(sphere_samples(2_000), 1e-3, progress=True)
    err = capsys.readouterr().err
    assert "greedy cover" in err and "Phong splats for 2,000 samples" in err
    phong_splats(sphere_samples(2_000), 1e-3)
    assert capsys.readouterr().err == ""
    assert not progress._enabled


# -- sharp edges -------------------------------------------------------------------------------------------


ROTATION = Rotation.from_euler("xyz", [23.0, -41.0, 67.0], degrees=True).as_matrix()


def clipped_outside_cube(splats: SplatCloud, rotation=np.eye(3), grid=41):
    """Per splat, over a grid of its (s, t) disk: the fraction of the kept part outside its cube
    face (beyond an edge by more than 1e-3) and of the face part inside that is cut away."""
    c, u, v, n, _ = splat_frames(splats)
    g = np.linspace(-1, 1, grid)
    s, t = (x.ravel() for x in np.meshgrid(g, g))
    disk = s * s + t * t <= 1
    s, t = s[disk], t[disk]
    points = (c[:, None, :] + s[None, :, None] * u[:, None, :] + t[None, :, None] * v[:, None, :]) @ rotation
    lines = splats.clip_lines.astype(np.float64)
    kept = (lines[:, None, :, 0] * s[None, :, None] + lines[:, None, :, 1] * t[None, :, None]
            + lines[:, None, :, 2] >= 0).all(axis=2)
    axis = np.abs(n @ rotation).argmax(axis=1)
    others = np.abs(points).copy()
    others[np.arange(len(c)), :, axis] = 0.0
    beyond = others.max(axis=2) > 0.5 + 1e-3
    within = others.max(axis=2) < 0.5 - 1e-3
    leak = (kept & beyond).sum(1) / len(s)
    overcut = (~kept & within).sum(1) / len(s)
    return leak, overcut, beyond.any(axis=1)


@pytest.fixture(scope="module")
def rotated_cube_samples() -> SplatCloud:
    """20 k samples of the unit cube rotated by ROTATION, with sample_mesh's exact clip lines
    (sharp_angle 30); shared by the mesh and raw cases below."""
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    return sample_mesh(Mesh(box.vertices @ ROTATION.T, box.faces), 20_000, seed=1, sharp_angle=SHARP)


@pytest.mark.parametrize("source", ["scene", "mesh", "raw"])
def test_cube_edges_clip_the_splats(source, request):
    """The cube with sharp_angle 30: from the procedural cube (exact clip lines on its samples),
    from mesh samples of a rotated cube (sample_mesh's exact lines), and from those positions
    alone (normals estimated, edges detected). Every splat that reaches over an edge is cut there:
    no kept part of any splat lies off its face, almost none of the face is cut away, samples of
    other faces are not claimed, and every sample is covered."""
    if source == "scene":
        cloud, rotation = scenes.cube(n_side=40, texture=False), np.eye(3)
    else:
        cloud, rotation = request.getfixturevalue("rotated_cube_samples"), ROTATION
        if source == "raw":
            cloud = SplatCloud(cloud.positions)
    eps = 1e-3
    result = phong_fit(cloud, eps, sharp_angle=SHARP)
    splats = result.splats
    assert splats.clip_lines is not None
    leak, overcut, crosses = clipped_outside_cube(splats, rotation)
    assert crosses.sum() > 0.3 * len(splats)          # splats on planar faces grow to the edges
    assert leak.max() == 0.0, leak.max()
    assert overcut.mean() < 0.01 and overcut.max() < 0.1, (overcut.mean(), overcut.max())
    used = (np.abs(splats.clip_lines - NO_CLIP) > 0).any(axis=2)
    assert used.any(axis=1)[crosses].all() and used.all(axis=1).sum() > 4
    # no sample of another face (normal off by the sharp angle) is claimed; all are covered
    points = cloud.validated().positions.astype(np.float64)
    face_normal = np.eye(3)[np.abs(points @ rotation).argmax(axis=1)]
    _, _, _, n, _ = splat_frames(splats)
    j, i, _, _, _ = claims(points, splats, eps, line_margin=1e-3)
    assert (np.abs((face_normal[i] @ rotation.T * n[j]).sum(1)) > 0.99).all()
    assert_covers(cloud, result, eps)


@pytest.fixture(scope="module")
def cad_part(shared_data) -> tuple[Mesh, SplatCloud]:
    """The CAD part (featuretype.ply) and 15 k samples with clip lines at its sharp edges
    (sharp_angle 30), shared by both cases of test_cad_part_edges."""
    path = shared_data / "featuretype.ply"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    mesh = load_mesh(path)
    return mesh, sample_mesh(mesh, 15_000, seed=0, sharp_angle=SHARP)


@pytest.mark.parametrize("with_lines", [True, False])
def test_cad_part_edges(cad_part, with_lines):
    """The CAD part (featuretype.ply: steps, holes, chamfers), 15 k samples with sharp_angle 30:
    with the samples' exact lines from the mesh, or edges detected from the samples. Every sample
    covered; no splat cuts away its own samples; splats do not grow across edges (their samples
    share a face normal); samples of other faces claimed by a splat are far fewer than without
    the lines (measured, mesh lines / detected edges: 13 / 17 claimed with the lines, 489 / 335
    without)."""
    mesh, cloud = cad_part
    if not with_lines:
        cloud = SplatCloud(cloud.positions, cloud.normals)
    lo, hi = mesh.bounds()
    eps = 1e-3 * float(np.linalg.norm(hi - lo))
    result = phong_fit(cloud, eps, sharp_angle=SHARP)
    splats = result.splats
    assert_covers(cloud, result, eps)
    used = (np.abs(splats.clip_lines - NO_CLIP) > 0).any(axis=2).any(axis=1)
    assert 0.2 < used.mean() < 0.9, used.mean()
    points = cloud.positions.astype(np.float64)
    normals = cloud.normals.astype(np.float64)
    c, u, v, n, _ = splat_frames(splats)
    # own samples on the kept side of the lines
    j = np.repeat(np.arange(len(c)), np.diff(result.member_ptr))
    d = points[result.member_idx] - c[j]
    s = (d * u[j]).sum(1) / (u[j] * u[j]).sum(1)
    t = (d * v[j]).sum(1) / (v[j] * v[j]).sum(1)
    lines = splats.clip_lines[j].astype(np.float64)
    assert (lines[:, :, 0] * s[:, None] + lines[:, :, 1] * t[:, None] + lines[:, :, 2]).min() > -1e-5
    # grown over one side only (normals within the angle of the seed's): the samples' normals
    # stay near the plane's (re-fitted planes may tilt a little)
    tilt = angle(normals[result.member_idx], n[j])
    assert np.percentile(tilt, 99.9) < SHARP and tilt.max() < SHARP + 10.0, np.percentile(tilt, [99.9, 100])

    def other_face(model):
        j, i, _, _, _ = claims(points, model, eps, line_margin=1e-3)
        return int(((normals[i] * n[j]).sum(1) <= np.cos(np.radians(SHARP))).sum())

    clipped, unclipped = other_face(splats), other_face(splats.replace(clip_lines=None))
    assert unclipped > 100 and clipped < 0.1 * unclipped, (clipped, unclipped)
