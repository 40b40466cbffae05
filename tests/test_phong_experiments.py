"""The experiments of Botsch, Spernat & Kobbelt 2004 (Phong splatting, sec. 5-6), held against ground truth.

1. Equal splat count (figure 4). The bunny mesh, densely sampled with interpolated vertex
   normals (the normals its Phong-shaded rendering uses), turned into Phong splats by
   :func:`~surfsplat.geometry.phong.phong_splats`; the same splat set rendered ``flat``
   (opaque disks, per-splat lighting), ``ewa`` (blended, per-splat lighting), ``deferred``
   (``ewa`` blending the normals, lit per pixel) and ``phong`` (the linear normal fields,
   lit per pixel), each compared with the mesh rendered by
   :func:`~surfsplat.rendering.mesh.render_mesh` (same camera and lights, 4x4 supersampled):
   PSNR inside the mesh's eroded silhouette (``psnr_inner``: the headline, splat
   silhouettes are not antialiased) and SSIM. Also standard splats (a random subsample of
   the dense samples, :func:`surfsplat.preprocess`) of the same count.
2. Equal quality (figure 5). The PSNR of Phong splats at a small count, and the counts
   that standard splats need to reach it with ``flat`` and with ``ewa`` (a sweep over
   counts, log-interpolated). The paper: 170k / 33k / 3k.
3. Clip lines (figure 9). The CAD part (featuretype.ply) sampled with clip lines at its
   sharp edges, Phong splats with ``sharp_angle``: the silhouette stays within 1 px of the
   mesh's, the creases stay sharp (the same splats without their lines overhang the
   silhouette and blur the creases), and ``phong`` is closer to the mesh than ``flat``.
4. The sphere. Phong splats of a sphere against the exact ray-cast sphere: the shading
   error of ``phong`` is several times smaller than that of the same splats drawn ``flat``.

``benchmarks/phong_experiments.py`` runs the same experiments at 512 x 512 with more
samples and splats, sweeps the counts for figure 5, times ``phong`` and writes the
pictures ``docs/images/phong_*.png``; the helpers below are shared with it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_render import exact_sphere

from surfsplat.camera import Camera, frame_bounds
from surfsplat.cloud import NO_CLIP, SplatCloud
from surfsplat.geometry.phong import phong_splats
from surfsplat.geometry.preprocess import preprocess
from surfsplat.geometry.sampling import sample_mesh
from surfsplat.io import load_mesh
from surfsplat.io.mesh import Mesh, area_weighted_normals
from surfsplat.lighting import Lights
from surfsplat.metrics import compare, dilate, erode, psnr
from surfsplat.rendering.frame import Frame
from surfsplat.rendering.mesh import render_mesh
from surfsplat.rendering.options import RenderOptions, VisibilityOptions

#: One light with a visible highlight, the same for splats, mesh and exact sphere.
LIGHTS = Lights(directions=((0.5, 0.6, 1.0),), specular=0.5, shininess=40.0)

#: The four rendering modes: name -> (technique, deferred shading).
MODES = {"flat": ("flat", False), "ewa": ("ewa", False), "deferred": ("ewa", True), "phong": ("phong", False)}
#: Modes that do not use the normal field (for standard splats, which have none).
STANDARD_MODES = ("flat", "ewa", "deferred")

#: Dihedral angle (degrees) of the CAD part's sharp edges.
SHARP_ANGLE = 30.0

#: Pixels of the silhouette rim left out of the inner comparisons.
ERODE_PX = 2

#: Test sizes: image side, dense samples, Phong splat count (the benchmark uses more).
TEST_SIZE = 256
TEST_SAMPLES = 100_000
TEST_COUNT = 2_000


# -- inputs ---------------------------------------------------------------------------------------


def with_vertex_normals(mesh: Mesh) -> Mesh:
    """The mesh with vertex normals: its own, or the area-weighted ones that render_mesh uses
    when it has none (so samples and ground truth share the normals)."""
    if mesh.vertex_normals is not None:
        return mesh
    return Mesh(mesh.vertices, mesh.faces, area_weighted_normals(mesh.vertices, mesh.faces), mesh.vertex_colors)


def load_model(folder: Path, name: str) -> Mesh:
    """A shared mesh with vertex normals; skips the test when the file is absent."""
    path = Path(folder) / name
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    return with_vertex_normals(load_mesh(path))


def dense_samples(mesh: Mesh, n: int, seed: int = 0) -> SplatCloud:
    """``n`` uniform samples of the mesh with the interpolated vertex normals (Phong shading's normals)."""
    return sample_mesh(mesh, n, seed=seed, smooth_normals=True)


def standard_splats(samples: SplatCloud, count: int, seed: int = 0) -> SplatCloud:
    """Standard splats: a random subsample of ``count`` samples, preprocessed (8 neighbours, ellipses)."""
    rows = np.sort(np.random.default_rng(seed).choice(len(samples), size=count, replace=False))
    return preprocess(samples.subset(rows), k=8)


def sphere_samples(n: int, seed: int = 0) -> SplatCloud:
    """``n`` uniformly random points of the unit sphere with their exact normals."""
    p = np.random.default_rng(seed).normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return SplatCloud(positions=p.astype(np.float32), normals=p.astype(np.float32))


# -- views and ground truth ----------------------------------------------------------------------


def view_camera(mesh: Mesh, size: int, direction=(0.4, 0.35, 1.0), up=(0.0, 1.0, 0.0), fill: float = 0.9) -> Camera:
    """A square camera framing the mesh's vertices from ``direction`` (near/far around its bounds)."""
    lo, hi = mesh.bounds()
    center = 0.5 * (lo.astype(np.float64) + hi)
    radius = float(np.linalg.norm(mesh.vertices - center, axis=1).max())
    return frame_bounds(lo, hi, width=size, height=size, direction=direction, up=up, radius=radius, fill=fill,
                        margin=0.02 * radius)


def sphere_camera(size: int) -> Camera:
    """The unit sphere seen from the default direction, filling 90 % of the view."""
    return frame_bounds((-1, -1, -1), (1, 1, 1), width=size, height=size, radius=1.0, margin=0.05)


def mesh_truth(renderer, mesh: Mesh, camera: Camera, lights: Lights = LIGHTS) -> Frame:
    """The ground truth: the mesh with interpolated vertex normals, 4 x 4 supersampled."""
    return render_mesh(mesh, camera, lights, supersample=4, smooth=True, renderer=renderer)


def mesh_silhouette(renderer, mesh: Mesh, camera: Camera) -> np.ndarray:
    """(H, W) bool: pixels whose center the mesh covers (the splats' own coverage rule)."""
    return render_mesh(mesh, camera, Lights(enabled=False), supersample=1, renderer=renderer).mask


# -- rendering and measuring ----------------------------------------------------------------------


def render_mode(renderer, splats, camera: Camera, mode: str, lights: Lights = LIGHTS,
                cull_backfaces: bool = False) -> Frame:
    """Render ``splats`` (a SplatCloud or uploaded GpuSplats) in one of :data:`MODES`."""
    technique, deferred = MODES[mode]
    # the papers' EWA splatting (full prefiltered footprints, all-or-nothing rims: no edge coverage), as
    # Botsch 2004 compared against
    options = RenderOptions(visibility=VisibilityOptions(cull_backfaces=cull_backfaces, clip_fringe=False,
                                                         edge_coverage=False), deferred=deferred)
    return renderer.render(splats, camera, technique, lights, options)


def see_through(frame: Frame, truth: Frame, erode_px: int = ERODE_PX, tolerance: float = 0.02) -> int:
    """Pixels inside the truth's eroded silhouette where the splats show nothing or a surface
    behind the mesh's (depth more than ``tolerance`` of the truth's depth further): holes
    between the front splats, through which the back of the model shows."""
    inner = erode(truth.mask, erode_px)
    behind = frame.depth > truth.depth * (1.0 + tolerance)
    return int(np.count_nonzero(inner & (~frame.mask | behind)))


def quality(frame: Frame, truth: Frame) -> dict:
    """:func:`surfsplat.metrics.compare` (PSNR, PSNR inside, SSIM, holes, leaks) plus :func:`see_through`."""
    result = compare(frame, truth, erode_px=ERODE_PX)
    result["see_through"] = see_through(frame, truth)
    return result


def measure_modes(renderer, splats: SplatCloud, camera: Camera, truth: Frame, modes=tuple(MODES)) -> dict:
    """{mode: quality} of one splat set drawn in each of ``modes`` (uploaded once)."""
    gpu = renderer.upload(splats)
    try:
        return {mode: quality(render_mode(renderer, gpu, camera, mode), truth) for mode in modes}
    finally:
        gpu.release()


def count_for_quality(counts, values, target: float) -> float | None:
    """The splat count at which ``values`` (e.g. PSNR, rising with the count) first reach
    ``target``: linear interpolation in ``log(count)`` between the two sweep points around it;
    ``counts[0]`` if the first already reaches it, None if no count does."""
    counts = np.asarray(counts, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    above = np.flatnonzero(values >= target)
    if not len(above):
        return None
    i = int(above[0])
    if i == 0:
        return float(counts[0])
    lo, hi = np.log(counts[i - 1]), np.log(counts[i])
    f = (target - values[i - 1]) / (values[i] - values[i - 1])
    return float(np.exp(lo + f * (hi - lo)))


def shading_rmse(frame: Frame, truth_color: np.ndarray, inner: np.ndarray) -> float:
    """RMSE of the colors (all channels, [0, 1]) over the pixels of ``inner``."""
    diff = frame.color[inner].astype(np.float64) - truth_color[inner]
    return float(np.sqrt(np.mean(diff ** 2)))


def sphere_errors(renderer, splats: SplatCloud, camera: Camera, modes=("flat", "phong"),
                  lights: Lights = LIGHTS) -> dict:
    """{mode: RMSE} of the splats against the exact sphere (4 x 4 supersampled), inside its
    silhouette eroded by :data:`ERODE_PX`; also ``"pixels"``: the size of that region."""
    truth, hit = exact_sphere(camera, lights, supersample=4)
    inner = erode(hit, ERODE_PX)
    out = {mode: shading_rmse(render_mode(renderer, splats, camera, mode, lights), truth, inner) for mode in modes}
    out["pixels"] = int(inner.sum())
    return out


def used_clip_lines(splats: SplatCloud) -> np.ndarray:
    """(N,) bool: the splat has at least one clip line."""
    if splats.clip_lines is None:
        return np.zeros(len(splats), dtype=bool)
    return (np.abs(splats.clip_lines - NO_CLIP) > 0).any(axis=2).any(axis=1)


def crease_band(truth: Frame, inner: np.ndarray, jump: float = 0.15, px: int = 2) -> np.ndarray:
    """(H, W) bool: pixels of ``inner`` within ``px`` pixels of a crease of the truth image
    (a jump of more than ``jump`` in some channel between 4-neighbours)."""
    c = truth.color.astype(np.float64)
    edge = np.zeros(inner.shape, dtype=bool)
    dy = (np.abs(np.diff(c, axis=0)) > jump).any(axis=2)
    dx = (np.abs(np.diff(c, axis=1)) > jump).any(axis=2)
    edge[1:] |= dy
    edge[:-1] |= dy
    edge[:, 1:] |= dx
    edge[:, :-1] |= dx
    return dilate(edge, px) & inner


def edge_measures(frame: Frame, truth: Frame, silhouette: np.ndarray) -> dict:
    """Sharpness of a rendering of the CAD part: ``leaks_1px`` / ``leaks_2px`` (pixels covered
    outside the mesh's pixel-center silhouette grown by 1 / 2 px), ``missing_1px`` (pixels of the
    silhouette shrunk by 1 px left empty), ``psnr_inner`` (inside the silhouette eroded by
    :data:`ERODE_PX`) and ``psnr_creases`` (within 2 px of the truth's creases there)."""
    inner = erode(silhouette, ERODE_PX)
    band = crease_band(truth, inner)
    return {"leaks_1px": int((frame.mask & ~dilate(silhouette, 1)).sum()),
            "leaks_2px": int((frame.mask & ~dilate(silhouette, 2)).sum()),
            "missing_1px": int((erode(silhouette, 1) & ~frame.mask).sum()),
            "psnr_inner": psnr(frame.color, truth.color, inner),
            "psnr_creases": psnr(frame.color, truth.color, band),
            "crease_pixels": int(band.sum())}



def crease_normals(mesh: Mesh, sharp_angle: float = SHARP_ANGLE) -> Mesh:
    """The mesh with smooth normals except across sharp edges (a CAD part's Phong shading).

    Vertices at equal positions are merged; each face corner gets the area-weighted mean
    of the normals of the faces around its vertex whose normals are within ``sharp_angle``
    of its own face's (so curved parts tessellated into facets, like the holes, are shaded
    smoothly, and planar faces meeting at a crease keep their own normal). Returned with
    three vertices per face.
    """
    _, position = np.unique(mesh.vertices, axis=0, return_inverse=True)
    position = position.reshape(-1)
    corners = position[mesh.faces]                                       # (F, 3) merged indices
    a, b, c = (mesh.vertices[mesh.faces[:, k]].astype(np.float64) for k in range(3))
    cross = np.cross(b - a, c - a)                                       # 2 area * unit normal
    unit = cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-30)
    face_of = np.repeat(np.arange(len(mesh.faces)), 3)
    vert = corners.reshape(-1)
    order = np.argsort(vert, kind="stable")
    ptr = np.searchsorted(vert[order], np.arange(vert.max() + 2))
    # pairs (corner, face around the corner's vertex)
    counts = ptr[vert + 1] - ptr[vert]
    corner = np.repeat(np.arange(len(vert)), counts)
    start = np.repeat(ptr[vert], counts)
    offset = np.arange(len(corner)) - np.repeat(np.cumsum(counts) - counts, counts)
    other = face_of[order[start + offset]]
    same = (unit[face_of[corner]] * unit[other]).sum(1) >= np.cos(np.radians(sharp_angle))
    normal = np.zeros((len(vert), 3))
    for axis in range(3):
        normal[:, axis] = np.bincount(corner[same], weights=cross[other[same], axis], minlength=len(vert))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    flat = mesh.faces.reshape(-1)
    colors = None if mesh.vertex_colors is None else mesh.vertex_colors[flat]
    return Mesh(mesh.vertices[flat], np.arange(len(flat)).reshape(-1, 3), normal.astype(np.float32), colors)


def curved_faces(mesh: Mesh, degrees: float = 1.0) -> np.ndarray:
    """(F,) bool: faces whose corner normals differ by more than ``degrees`` (the smooth-shaded,
    curved parts of a CAD part: holes, fillets), not planar faces."""
    n = mesh.vertex_normals[mesh.faces].astype(np.float64)          # (F, 3, 3)
    cos = np.cos(np.radians(degrees))
    return ((n[:, 0] * n[:, 1]).sum(1) < cos) | ((n[:, 1] * n[:, 2]).sum(1) < cos) | \
        ((n[:, 0] * n[:, 2]).sum(1) < cos)


def face_mask(renderer, mesh: Mesh, faces: np.ndarray, camera: Camera) -> np.ndarray:
    """(H, W) bool: pixels whose center shows one of the selected ``faces`` (others occlude)."""
    corners = mesh.faces.reshape(-1)
    flag = np.repeat(faces.astype(np.float32), 3)
    split = Mesh(mesh.vertices[corners], np.arange(len(corners)).reshape(-1, 3),
                 mesh.vertex_normals[corners], np.repeat(flag[:, None], 3, axis=1))
    frame = render_mesh(split, camera, Lights(enabled=False), supersample=1, background=(0, 0, 0),
                        renderer=renderer)
    return frame.mask & (frame.color[..., 0] > 0.5)


def cad_samples(mesh: Mesh, n: int, seed: int = 0) -> SplatCloud:
    """Samples of a CAD part with clip lines at its sharp edges and the crease-smoothed normals."""
    return sample_mesh(mesh, n, seed=seed, sharp_angle=SHARP_ANGLE, smooth_normals=True)


def cad_error(mesh: Mesh, relative: float = 2e-3) -> float:
    """The Phong splats' tolerance for the CAD part: ``relative`` times its bounding box diagonal."""
    lo, hi = mesh.bounds()
    return relative * float(np.linalg.norm(hi.astype(np.float64) - lo))


#: The CAD part's view (z up): from the front left, above, where the light (LIGHTS) lights the
#: top faces without saturating them and puts highlights on the curved cut-outs.
CAD_DIRECTION = (-0.75, -0.5, 0.45)
CAD_UP = (0.0, 0.0, 1.0)


def cad_measures(renderer, splats: SplatCloud, camera: Camera, truth: Frame, silhouette: np.ndarray,
                 curved: np.ndarray, modes=("flat", "ewa", "phong")) -> dict:
    """{(clipped, mode): edge_measures + psnr_curved} of the splats with and without their clip lines.

    Back-faces are culled (the part is closed, its normals point out): two-sided, the splats of
    faces seen from behind lie within the visibility pass's depth epsilon (one splat radius,
    large for Phong splats on planar faces) of the front faces near every edge and get blended
    into them.
    """
    out = {}
    for clipped in (True, False):
        model = splats if clipped else splats.replace(clip_lines=None)
        for mode in modes:
            frame = render_mode(renderer, model, camera, mode, cull_backfaces=True)
            measures = edge_measures(frame, truth, silhouette)
            measures["psnr_curved"] = psnr(frame.color, truth.color, curved)
            measures["frame"] = frame
            out[clipped, mode] = measures
    return out


# == tests ========================================================================================


@pytest.fixture(scope="module")
def bunny(shared_data, gl_renderer) -> dict:
    """The bunny mesh, 100 k dense samples, the 256 x 256 view and its ground truth."""
    mesh = load_model(shared_data, "bunny.ply")
    camera = view_camera(mesh, TEST_SIZE)
    return {"mesh": mesh, "samples": dense_samples(mesh, TEST_SAMPLES), "camera": camera,
            "truth": mesh_truth(gl_renderer, mesh, camera)}


@pytest.fixture(scope="module")
def bunny_phong(bunny) -> SplatCloud:
    """Phong splats of the bunny: TEST_COUNT (2,000) from 100 k samples."""
    return phong_splats(bunny["samples"], count=TEST_COUNT)


@pytest.fixture(scope="module")
def bunny_phong_results(gl_renderer, bunny, bunny_phong) -> dict:
    return measure_modes(gl_renderer, bunny_phong, bunny["camera"], bunny["truth"])


def test_phong_splats_of_the_bunny(bunny, bunny_phong):
    """The splat set of the experiments: the count asked for, normal fields that are not zero,
    far fewer splats than samples."""
    assert abs(len(bunny_phong) - TEST_COUNT) <= 0.05 * TEST_COUNT
    assert bunny_phong.normal_field is not None
    assert np.median(np.abs(bunny_phong.normal_field).max(axis=1)) > 0.05
    assert len(bunny["samples"]) / len(bunny_phong) > 40


def test_equal_count_phong_beats_flat_blended_and_deferred(bunny_phong_results):
    """Figure 4: the same 2,000 Phong splats drawn four ways, against the mesh (256 x 256).

    Measured on llvmpipe (PSNR inside the eroded silhouette / SSIM): flat 21.5 dB / 0.50,
    ewa 25.8 / 0.67, deferred 25.6 / 0.72, phong 28.8 / 0.82. No holes, at most a few
    pixels where the back of the model shows through, no leaks beyond 2 px but a few (<= 6).
    """
    r = bunny_phong_results
    for mode, result in r.items():
        assert result["holes"] <= 5 and result["see_through"] <= 20, (mode, result)
        assert result["leaks"] <= 50, (mode, result)
    phong = r["phong"]["psnr_inner"]
    assert phong > 26.0
    assert phong > r["flat"]["psnr_inner"] + 5.0, r
    assert phong > r["ewa"]["psnr_inner"] + 2.0, r
    assert phong > r["deferred"]["psnr_inner"] + 2.0, r
    assert r["ewa"]["psnr_inner"] > r["flat"]["psnr_inner"] + 2.0, r   # blending: Gouraud-like, better than flat
    assert r["phong"]["ssim"] > max(r[m]["ssim"] for m in STANDARD_MODES) + 0.06, r


def test_equal_count_standard_splats_are_worse_still(gl_renderer, bunny, bunny_phong_results):
    """Standard splats (a random subsample of 2,000 samples, preprocessed) at the same count.

    Measured: flat 13.9 dB, ewa 20.4, deferred 18.6 (phong: 28.8): random samples with
    neighbourhood-sized ellipses need far more splats than fitted ones.
    """
    standard = standard_splats(bunny["samples"], TEST_COUNT)
    r = measure_modes(gl_renderer, standard, bunny["camera"], bunny["truth"], STANDARD_MODES)
    phong = bunny_phong_results["phong"]["psnr_inner"]
    for mode in STANDARD_MODES:
        assert r[mode]["psnr_inner"] < phong - 5.0, (mode, r[mode]["psnr_inner"], phong)
        # the Phong set's geometry drawn the same way is better too
        assert r[mode]["psnr_inner"] < bunny_phong_results[mode]["psnr_inner"], mode


def test_equal_quality_phong_needs_several_times_fewer_splats(gl_renderer, bunny, bunny_phong_results):
    """Figure 5 (the paper: flat 170k, blended 33k, Phong 3k for the same visual quality).

    Standard splats at several times the Phong count still fall short of the 2,000 Phong
    splats' PSNR. Measured on llvmpipe at 256 x 256 (phong: 28.8 dB): ewa 22.4 dB at 3x
    (6,000), 25.4 at 10x (20,000), 28.9 at 30x (60,000); flat 19.5 at 30x and 21.0 at 50x
    (100,000). So ewa needs ~30x the Phong count, flat more than 50x.
    """
    phong = bunny_phong_results["phong"]["psnr_inner"]
    samples, camera, truth = bunny["samples"], bunny["camera"], bunny["truth"]

    def standard(mode, factor):
        splats = standard_splats(samples, factor * TEST_COUNT)
        return measure_modes(gl_renderer, splats, camera, truth, (mode,))[mode]["psnr_inner"]

    assert standard("ewa", 3) < phong - 3.0
    assert standard("ewa", 10) < phong - 1.5
    assert standard("flat", 30) < phong - 5.0
    assert standard("flat", 50) < phong - 4.0


def test_equal_quality_against_the_phong_geometry(gl_renderer, bunny, bunny_phong_results):
    """Figure 5 with the paper's geometry: Phong splats of 3x the count (6,000, the same
    generator) drawn without their normal fields. Flat stays far below the 2,000 Phong splats;
    blending comes close in PSNR but not in structure (SSIM: the highlights).

    Measured at 256 x 256: flat 23.7 dB / SSIM 0.67, ewa 29.4 dB / 0.76, deferred 29.2 / 0.82
    vs phong at 2,000: 28.8 dB / 0.82. With this generator's fitted, hole-free splats ewa
    matches Phong's PSNR at ~2.5x the count (and its SSIM only beyond 30,000): a smaller gap
    than the paper's 11x.
    """
    phong = bunny_phong_results["phong"]
    splats = phong_splats(bunny["samples"], count=3 * TEST_COUNT)
    r = measure_modes(gl_renderer, splats, bunny["camera"], bunny["truth"], ("flat", "ewa"))
    assert r["flat"]["psnr_inner"] < phong["psnr_inner"] - 3.0, (r["flat"], phong)
    assert r["ewa"]["ssim"] < phong["ssim"] - 0.02, (r["ewa"], phong)


def test_count_for_quality_interpolates_in_log_count():
    counts = [1000, 10000, 100000]
    assert count_for_quality(counts, [20.0, 30.0, 40.0], 25.0) == pytest.approx(np.sqrt(1000 * 10000))
    assert count_for_quality(counts, [20.0, 30.0, 40.0], 19.0) == 1000
    assert count_for_quality(counts, [20.0, 30.0, 40.0], 41.0) is None
    assert count_for_quality(counts, [20.0, 30.0, 40.0], 40.0) == pytest.approx(100000)


def test_sphere_phong_shading_error_far_below_flat(renderer):
    """A sphere of 1,000 Phong splats (from 50 k random samples with exact normals) against the
    exact ray-cast sphere (4 x 4 supersampled), RMSE inside the eroded silhouette, 256 x 256.

    Measured on llvmpipe: flat 0.029, ewa 0.011, deferred 0.010, phong 0.0009 (32x below flat).
    """
    splats = phong_splats(sphere_samples(50_000), count=1_000)
    errors = sphere_errors(renderer, splats, sphere_camera(TEST_SIZE), modes=("flat", "ewa", "phong"))
    assert errors["pixels"] > 30_000
    assert errors["phong"] < 0.004, errors
    assert errors["flat"] >= 10.0 * errors["phong"], errors
    assert errors["ewa"] >= 4.0 * errors["phong"], errors


@pytest.fixture(scope="module")
def cad(shared_data, gl_renderer) -> dict:
    """The CAD part with crease-smoothed normals, 60 k samples with clip lines, its Phong
    splats (tolerance 0.2 % of the diagonal, sharp_angle 30), view and ground truth."""
    mesh = crease_normals(load_model(shared_data, "featuretype.ply"))
    samples = cad_samples(mesh, 60_000)
    splats = phong_splats(samples, cad_error(mesh), sharp_angle=SHARP_ANGLE)
    camera = view_camera(mesh, TEST_SIZE, direction=CAD_DIRECTION, up=CAD_UP)
    silhouette = mesh_silhouette(gl_renderer, mesh, camera)
    curved = face_mask(gl_renderer, mesh, curved_faces(mesh), camera) & erode(silhouette, ERODE_PX)
    return {"mesh": mesh, "splats": splats, "camera": camera, "silhouette": silhouette, "curved": curved,
            "truth": mesh_truth(gl_renderer, mesh, camera)}


def test_crease_normals_keep_edges_and_smooth_curves(shared_data):
    """The CAD part's reference normals: planar faces keep their face normal, curved parts
    (the holes and cut-outs, ~23 % of the area) are smooth, no normal crosses a sharp edge."""
    raw = load_model(shared_data, "featuretype.ply")
    mesh = crease_normals(raw)
    face_n = mesh.face_normals().astype(np.float64)
    corner_n = mesh.vertex_normals[mesh.faces].astype(np.float64)
    tilt = np.degrees(np.arccos(np.clip(np.einsum("fj,fkj->fk", face_n, corner_n), -1, 1)))
    assert tilt.max() < SHARP_ANGLE
    curved = curved_faces(mesh)
    area = mesh.face_areas()
    assert 0.1 < area[curved].sum() / area.sum() < 0.4
    assert np.percentile(tilt[~curved], 99) < 1.0


def test_cad_part_phong_splats_with_clip_lines(renderer, cad):
    """Figure 9: the CAD part's Phong splats with clip lines (256 x 256, back-faces culled).

    Measured on llvmpipe (2,496 splats, 85 % with clip lines): the silhouette within 1 px of
    the mesh's (pixels beyond 1 px: flat 0, ewa 1, phong 0; without the lines 246 / 354 / 246);
    40 pixels of the 14,682 in the silhouette shrunk by 1 px left empty (flat, phong); the
    creases sharp (PSNR within 2 px of the truth's creases: flat 20.2 dB, phong 20.2 with the
    lines, 10.3 and 16.4 without); the highlights on the curved parts smoother with the normal
    fields (PSNR there: phong 23.7 dB, flat 22.7; over the whole inside both ~23.5 dB: the
    planar faces, most of the part, are lit alike).
    """
    splats = cad["splats"]
    assert 0.3 < used_clip_lines(splats).mean() < 0.95
    r = cad_measures(renderer, splats, cad["camera"], cad["truth"], cad["silhouette"], cad["curved"])
    area = int(cad["silhouette"].sum())
    for mode in ("flat", "ewa", "phong"):
        clipped, unclipped = r[True, mode], r[False, mode]
        assert np.isfinite(clipped["frame"].color).all()
        assert clipped["leaks_1px"] <= 10, (mode, clipped["leaks_1px"])
        assert clipped["leaks_2px"] <= 2, (mode, clipped["leaks_2px"])
        assert unclipped["leaks_1px"] > 100 + 10 * clipped["leaks_1px"], (mode, unclipped["leaks_1px"])
        assert clipped["missing_1px"] < 0.005 * area, (mode, clipped["missing_1px"])
        assert clipped["psnr_creases"] > unclipped["psnr_creases"] + 2.0, mode
    assert r[True, "flat"]["psnr_creases"] > r[False, "flat"]["psnr_creases"] + 5.0
    assert r[True, "phong"]["psnr_curved"] > r[True, "flat"]["psnr_curved"] + 0.5

